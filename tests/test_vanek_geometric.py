"""The vanek-geometric detector ([VANEK] §2, §5) on the aircraft plant level: exact
decoupling of the left elevator, the rudder and the lateral gust on the aircraft model,
sensitivity to the left inboard aileron, isolation in closed-loop simulation."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

from detectors import geometric as geo
from detectors.vanek_geometric import NOMINAL, VanekGeometric, _columns, _point, design_filter
from scenarios.aircraft import lpv
from scenarios.aircraft.data import AIRCRAFT_SENSORS
from scenarios.aircraft.loop import simulate_aircraft
from scenarios.simulate import simulate, single_run

OMEGA = np.logspace(-3, 2, 51)          # rad/s: below the spiral mode to beyond the filter


def _aircraft(point):
    m = lpv.run_models(point, np.zeros(1))
    C = np.eye(lpv.N_STATES)[[lpv.STATES.index(s) for s in ("q", "theta", "beta", "p", "r", "phi")]]
    return m.A[0], m.B[0], C


@pytest.mark.parametrize("vcas, alt", [(NOMINAL.vcas_kt, NOMINAL.alt_ft), (170.0, 23000.0)])
def test_elevator_rudder_and_gust_are_decoupled_aileron_is_seen(vcas, alt):
    point = _point(vcas, alt, 200.0, 30.0)
    gen, _ = design_filter(point, 0.01)
    A, B, C = _aircraft(point)
    i1, i2, _ = _columns()
    aileron = np.abs(gen.fault_to_residual(A, B, C, B[:, [i1]], OMEGA)).max()
    for j in i2 + [lpv.I_GUST_BETA, lpv.I_GUST_ALPHA]:
        leak = np.abs(gen.fault_to_residual(A, B, C, B[:, [j]], OMEGA)).max()
        # exact decoupling: round-off only (model entries O(1), filter gains O(10))
        assert leak < 1e-9 * aileron, (j, leak, aileron)
    assert np.linalg.norm(geo.dc_gain(gen)) > 1e-4
    eig = np.linalg.eigvals(gen.N)
    assert np.all(eig.real < -0.5 + 1e-4) and np.all(np.abs(eig) < 20.0 + 1e-4)


def test_without_gust_decoupling_the_gust_reaches_the_residual():
    point = _point(NOMINAL.vcas_kt, NOMINAL.alt_ft, 200.0, 30.0)
    gen, _ = design_filter(point, 0.01, decouple_gusts=False)
    A, B, C = _aircraft(point)
    i1, i2, _ = _columns()
    aileron = np.abs(gen.fault_to_residual(A, B, C, B[:, [i1]], OMEGA)).max()
    gust = np.abs(gen.fault_to_residual(A, B, C, B[:, [lpv.I_GUST_BETA]], OMEGA)).max()
    assert gust > 1e-3 * aileron          # not decoupled: a sizeable transfer
    for j in i2:
        assert np.abs(gen.fault_to_residual(A, B, C, B[:, [j]], OMEGA)).max() < 1e-9 * aileron
    assert gen.N.shape == (4, 4)          # S* one dimension smaller than with the gust


def test_actuator_level_signals_are_refused():
    sig, _ = simulate(single_run("aileron", "cruise", "none", duration_s=20.0))
    with pytest.raises(ValueError, match='plant = "aircraft"'):
        VanekGeometric().fit(sig)


def test_parameters_are_checked():
    with pytest.raises(ValueError, match="safety"):
        VanekGeometric(safety=1.0).validate_params()
    with pytest.raises(ValueError, match="radius"):
        VanekGeometric(decay=2.0, radius=1.0).validate_params()
    with pytest.raises(ValueError, match="variants"):
        VanekGeometric(variants=("lqr",)).validate_params()


def _rows(surface, fault, seed, vcas, alt, magnitude=None, duration_s=30.0):
    kind = "elevator" if "elevator" in surface else "aileron"
    r = single_run(kind, "cruise", fault, seed=seed, onset_s=10.0, magnitude=magnitude,
                   duration_s=duration_s, vcas_kt=vcas, alt_ft=alt, mass_t=200.0, cg_pct=30.0)
    r["surface"] = surface
    return r


# Closed loop with an inertial reference and sideslip vane 100 times quieter than the default
# sensors: at the default noise the fault-free floor of this residual is a few degrees of
# aileron-equivalent (β noise mostly, docs/vanek-geometric.md), the size of the [VANEK] jam,
# so detection is checked here with quiet sensors; isolation is structural either way.
QUIET = dataclasses.replace(
    AIRCRAFT_SENSORS, **{f: getattr(AIRCRAFT_SENSORS, f) / 100.0 for f in
                         ("rate_noise_deg_s", "attitude_noise_deg", "load_noise_g",
                          "sideslip_noise_deg")})


def _simulate(rows):
    return simulate_aircraft(rows, aircraft_sensors=QUIET)


def _fit(monitored):
    learn = pd.concat([_rows(monitored, "none", 100 + i, v, h)
                       for i, (v, h) in enumerate([(200.0, 26000.0), (240.0, 30000.0),
                                                   (280.0, 33000.0)])], ignore_index=True)
    learn["stream"] = np.arange(len(learn))
    return VanekGeometric().fit(_simulate(learn)[0])


def test_isolation_elevator_runaway_stays_below_threshold():
    det = _fit("left_elevator")
    sig, truth = _simulate(_rows("left_elevator", "runaway", 7, 200.0, 26000.0, magnitude=5.0))
    # the runaway does move the elevator by many degrees (the check is not vacuous)
    assert np.ptp(truth.surfaces_deg["left_elevator"][0]) > 5.0
    for variant, out in det.detect(sig).items():
        # measured: peak 0.42 (LTI), 0.48 (LPV) of the threshold
        assert out.residual.max() < 0.8 and not out.alarm.any(), variant


def test_aileron_faults_cross_the_threshold_after_onset():
    det = _fit("left_inboard_aileron")
    rows = pd.concat([_rows("left_inboard_aileron", "runaway", 8, 250.0, 28000.0, magnitude=5.0),
                      _rows("left_inboard_aileron", "liquid_jam", 9, 170.0, 23000.0)],
                     ignore_index=True)
    rows["stream"] = [0, 1]
    sig, _ = _simulate(rows)
    out = det.detect(sig)
    peaks = {k: d.residual.max(axis=1) for k, d in out.items()}
    # runaway (to the stop): both variants; the small liquid jam (1.3 % of the travel) off the
    # LTI design point: the LPV filter only (measured peaks/threshold: LTI 7.3 / 0.99, LPV
    # 38 / 1.19; thresholds 2.05 ° and 0.38 ° of aileron-equivalent)
    assert out["lti"].alarm[0, -1] and out["lpv"].alarm[:, -1].all(), peaks
    for variant, d in out.items():
        first = np.argmax(d.alarm, axis=1)[d.alarm[:, -1]] * sig.ts
        assert np.all(first > 10.0), (variant, first)          # never before the onset
    # the LPV filter, designed at the measured point, sees both faults more clearly
    assert np.all(peaks["lpv"] > peaks["lti"]), peaks


def test_comparison_command_refuses_a_bad_noise_scale(capsys):
    from detectors.vanek_compare import main

    with pytest.raises(SystemExit) as exc:
        main(["--noise-scale", "0"])
    assert exc.value.code == 2 and "--noise-scale must be > 0" in capsys.readouterr().err


def test_a_campaign_at_the_actuator_level_is_refused_before_it_starts():
    from campaign.config import CampaignConfig, load_config
    from campaign.runner import CampaignSetupError, _check_compatibility, build_detectors

    cfg = load_config("vanek-scenarios")
    _check_compatibility(cfg, build_detectors(cfg))       # aircraft plant: accepted
    actuator = cfg.to_dict()
    actuator["campaign"]["plant"] = "actuator"
    actuator["campaign"].pop("monitored_surface")
    actuator = CampaignConfig.from_dict(actuator)
    with pytest.raises(CampaignSetupError, match='vanek-geometric.*plant = "aircraft"'):
        _check_compatibility(actuator, build_detectors(actuator))


def test_hinf_post_filter_tracks_the_fault_and_keeps_the_decoupling():
    from detectors import vanek_hinf as vh   # the [hinf] extra, part of the [test] extra

    point = _point(NOMINAL.vcas_kt, NOMINAL.alt_ft, 200.0, 30.0)
    gen, _ = design_filter(point, 0.01)
    q = vh.post_filter(gen, vh.sensor_sigmas() * np.sqrt(0.01))
    # every pole slow enough for the bilinear map at Ts = 0.01 s, and stable
    eig = np.linalg.eigvals(q.A)
    assert np.all(eig.real < 0) and np.all(np.abs(eig) < 100.0)
    A, B, C = _aircraft(point)
    Ac, Bc, Cc, Dc = vh.cascade(gen, q)
    i1, i2, _ = _columns()
    n, nc = A.shape[0], Ac.shape[0]
    m = Bc.shape[1] - C.shape[0]                      # known inputs ahead of the outputs

    def transfer(col, w):
        # plant fault column → outputs y → cascade (known inputs zero)
        Acl = np.block([[A, np.zeros((n, nc))], [Bc[:, m:] @ C, Ac]])
        Bcl = np.vstack([B[:, [col]], np.zeros((nc, 1))])
        Ccl = np.hstack([Dc[:, m:] @ C, Cc])
        return Ccl @ np.linalg.solve(1j * w * np.eye(n + nc) - Acl, Bcl)

    dc = abs(transfer(i1, 1e-3)[0, 0])               # the plant has an integrator (θ)
    # the H∞ problem trades tracking for noise: the steady-state gain stays near 1
    # (T_id(0) = 1; measured 0.96) and elevator/rudder stay decoupled through Q
    assert 0.5 < dc < 1.5
    for j in i2:
        assert max(abs(transfer(j, w)[0, 0]) for w in OMEGA) < 1e-9
    assert q.gamma > 0


def test_hinf_variant_needs_its_optional_dependencies(monkeypatch):
    import builtins

    real = builtins.__import__

    def no_control(name, *args, **kwargs):
        if name in ("control", "slycot"):
            raise ImportError(f"No module named {name!r}")
        return real(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_control)
    with pytest.raises(ValueError, match=r"fdd-campaign\[hinf\]"):
        VanekGeometric(variants=("lti", "lti-hinf")).validate_params()


def test_fault_free_residual_floor_at_the_default_sensor_noise():
    # The trimmed runs start at zero rates, sideslip and bank: those outputs enter as
    # measured. Referenced to their first (noisy) sample instead, each run carried a
    # constant offset of one noise sample (σ 0.02 °/s on p, r; 0.1 ° on β) through the
    # filter's large DC gain: fault-free |r̂| of 13–21 ° of aileron-equivalent on these runs.
    # Measured now: 2.3–5.2 ° (LTI and LPV); bound 9 °.
    rows = pd.concat([_rows("left_inboard_aileron", "none", 100 + i, v, h, duration_s=30.0)
                      for i, (v, h) in enumerate([(170.0, 23000.0), (240.0, 30000.0),
                                                  (280.0, 33000.0)])], ignore_index=True)
    rows["stream"] = np.arange(len(rows))
    sig, _ = simulate_aircraft(rows)                       # default aircraft sensors
    for variant, r in VanekGeometric().estimates(sig).items():
        assert np.abs(r).max() < 9.0, (variant, np.abs(r).max(axis=1))


def test_one_step_hinf_filter_gamma_tracking_and_approximate_isolation():
    # [VANEK] §3's one-step H∞ FDI filter (variant "one-step"): γ of the weighted
    # interconnection confirmed by a frequency sweep of the closed loop; the fault is tracked
    # at steady state; elevator and rudder faults are attenuated, not decoupled (contrast
    # with the geometric filter's < 1e-9 in test_elevator_rudder_and_gust_are_decoupled…).
    from detectors.vanek_geometric import one_step_design

    point = _point(NOMINAL.vcas_kt, NOMINAL.alt_ft, 200.0, 30.0)
    f, filt = one_step_design(point, 0.01)
    cl = f.plant.lft(f.full)
    w = np.logspace(-4, 4, 2000)
    resp = cl(1j * w)
    peak = max(np.linalg.svd(resp[:, :, k], compute_uv=False)[0] for k in range(len(w)))
    # the central H∞ filter's closed loop stays below γ (solver tolerance); for this
    # design the bound is nearly reached (measured peak/γ ≈ 1 − 2e-9)
    assert peak <= f.gamma * (1.0 + 1e-6) and peak >= 0.95 * f.gamma
    # fault → f̂ and isolated faults → f̂ through the aircraft model (θ left out)
    A, B, C = _aircraft(point)
    keep = [j for j, s in enumerate(lpv.STATES) if s != "theta"]
    A, B = A[np.ix_(keep, keep)], B[keep]
    names = [lpv.STATES[j] for j in keep]
    C = np.eye(len(keep))[[names.index(o) for o in f.outputs]]
    i1, i2, known = _columns()
    m = len(known)

    def transfer(col, s):
        n, nk = A.shape[0], f.A.shape[0]
        Acl = np.block([[A, np.zeros((n, nk))], [f.B[:, m:] @ C, f.A]])
        Bcl = np.vstack([B[:, [col]], np.zeros((nk, 1))])
        Ccl = np.hstack([f.D[:, m:] @ C, f.C])
        return abs((Ccl @ np.linalg.solve(s * np.eye(n + nk) - Acl, Bcl))[0, 0])

    # steady-state fault gain: the one H∞ problem trades tracking (T_id(0) = 1) against the
    # elevator, rudder and gust rejection; with γ ≈ 0.65 of the weighted fault size the
    # tracking error is of that order: measured 0.37 (the geometric filter + post-filter:
    # 0.96, test_hinf_post_filter_tracks_the_fault_and_keeps_the_decoupling)
    dc = transfer(i1, 1e-4j)
    assert 0.25 < dc < 0.6, dc
    leak = [max(transfer(j, 1j * x) for x in OMEGA) for j in i2]
    assert max(leak) > 1e-3 * dc, leak               # not decoupled
    assert filt.Bd.shape[1] == len(known) + 6        # the detector's inputs, θ ignored
    assert np.all(filt.Bd[:, len(known) + 1] == 0.0)


def test_aileron_runaways_cross_the_threshold_at_the_default_sensor_noise():
    # Default aircraft sensors (not QUIET): the left inboard aileron running away at 5 °/s
    # and at 2 °/s from 10 s. Measured with this learning set: thresholds 7.6 ° (LTI) and
    # 7.8 ° (LPV) of aileron-equivalent; both variants alarm 5.5–9.3 s after onset (the 2 s
    # low-pass and the ramp's time to exceed the floor), never before onset. (With the inputs
    # referenced to their first noisy sample the thresholds were 25 ° and 31 °: no alarm.)
    learn = pd.concat([_rows("left_inboard_aileron", "none", 100 + i, v, h)
                       for i, (v, h) in enumerate([(170.0, 23000.0), (220.0, 20000.0),
                                                   (240.0, 30000.0), (280.0, 33000.0)])],
                      ignore_index=True)
    learn["stream"] = np.arange(len(learn))
    det = VanekGeometric().fit(simulate_aircraft(learn)[0])
    rows = pd.concat([_rows("left_inboard_aileron", "runaway", 10, 170.0, 23000.0, magnitude=5.0),
                      _rows("left_inboard_aileron", "runaway", 11, 280.0, 33000.0, magnitude=2.0)],
                     ignore_index=True)
    rows["stream"] = [0, 1]
    sig, _ = simulate_aircraft(rows)
    for variant, d in det.detect(sig).items():
        assert d.alarm[:, -1].all(), (variant, d.residual.max(axis=1))
        first = np.argmax(d.alarm, axis=1) * sig.ts
        assert np.all(first > 10.0) and np.all(first < 25.0), (variant, first)
