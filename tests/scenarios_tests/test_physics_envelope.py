"""docs/physics.md §3, §7 and §8 facts checked over the realistic envelope, not at one point:
the stall-limited runaway end, the floating angle of a freed surface, the trim load of the
aft-loaded aileron, and the longitudinal–lateral coupling of an asymmetric elevator pair.

The expected values are computed here from the equations of docs/physics.md, not from the
plant's own functions.
"""

import dataclasses

import numpy as np
import pandas as pd
import pytest
from scipy.optimize import brentq

from scenarios import envelope
from scenarios.aircraft import lpv
from scenarios.aircraft.data import LAYOUT
from scenarios.params import AILERON, ELEVATOR, SENSORS
from scenarios.simulate import simulate, single_run

TS = 0.01
IDEAL = dataclasses.replace(SENSORS, rod_noise_mm=0.0, rod_quant_mm=1e-9, rod_bias_mm=0.0,
                            rod_scale=0.0, surface_noise_deg=0.0, surface_quant_deg=1e-9,
                            surface_bias_deg=0.0)
ACTS = {"elevator": ELEVATOR, "aileron": AILERON}


@pytest.fixture(scope="module")
def points() -> pd.DataFrame:
    """The 53 realistic flight points of docs/physics.md §6 with their flight condition."""
    pts = envelope.realistic_points()
    pts = pts[pts["realistic"]].reset_index(drop=True)
    fc = envelope.flight_condition(pts["alt_ft"], pts["vcas_kt"], pts["mass_t"], pts["cg_pct"])
    return pts.assign(**{k: np.asarray(v) for k, v in fc.items()})


def _batch(surface, points, fault="none", manoeuvre="cruise", **kw) -> pd.DataFrame:
    rows = [single_run(surface, manoeuvre, fault, seed=5,
                       **{c: float(getattr(p, c))
                          for c in ("alt_ft", "vcas_kt", "mass_t", "cg_pct")},
                       **kw).assign(stream=i, run_id=f"r{i}")
            for i, p in enumerate(points.itertuples())]
    return pd.concat(rows, ignore_index=True)


def _hinge(act, points):
    """(HM at δ = 0 [N·m], ∂HM/∂δ [N·m/rad]) of docs/physics.md §3 at every point."""
    pg = 1.0 / np.sqrt(1.0 - np.minimum(points["mach"].to_numpy(), act.mach_compress_cap) ** 2)
    alpha_s = np.radians(points["alpha_deg"].to_numpy()) * (1.0 - act.downwash)
    qsc = points["qbar_pa"].to_numpy() * act.Sc_m2 * act.cc_m
    return qsc * (act.Ch0 + act.Ch_alpha * pg * alpha_s), qsc * act.Ch_delta * pg


def _float_deg(act, points) -> np.ndarray:
    """δ_f = −(Ch0 + Chα·α_s)/Chδ (Chα, Chδ with their Prandtl–Glauert factor) [deg]."""
    hm0, hmd = _hinge(act, points)
    return np.degrees(-hm0 / hmd)


def _runaway_end_deg(act, points, sign) -> np.ndarray:
    """docs/physics.md §8: a runaway from neutral stops where the opposing hinge-moment force
    reaches the stall force S·ΔP, or at the mechanical stop if that comes first."""
    hm0, hmd = _hinge(act, points)
    r_m, stall = act.r_mm / 1000.0, act.S_m2 * act.dP_Pa
    stop = np.radians(act.stop_max_deg if sign > 0 else act.stop_min_deg)
    out = []
    for h0, hd in zip(hm0, hmd):
        def excess(d):
            return sign * -(h0 + hd * d) / (r_m * np.cos(d)) - stall
        out.append(stop if excess(stop) < 0 else brentq(excess, 0.0, stop, xtol=1e-12))
    return np.degrees(np.array(out))


@pytest.mark.parametrize("surface", ["elevator", "aileron"])
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_runaway_ends_at_stall_force_or_stop_over_the_envelope(points, surface, sign):
    act = ACTS[surface]
    runs = _batch(surface, points, "runaway", onset_s=0.5, magnitude=sign * 10.0,
                  duration_s=8.0)
    _, truth = simulate(runs, orders_deg=np.zeros((len(runs), 800)), sensors=IDEAL)
    expected = _runaway_end_deg(act, points, sign)
    np.testing.assert_allclose(truth.surface_deg[:, -1], expected, atol=0.05)
    # the law bites: at high q̄ the stall force, not the stop, ends the runaway
    stop = act.stop_max_deg if sign > 0 else act.stop_min_deg
    at_stop = np.isclose(expected, stop)
    # measured: elevator 27 (up) / 47 (down), aileron 30 / 9 of the 53 points stall short of
    # the stop, by up to 8.2°, 22.5°, 16.2° and 1.3°
    assert (~at_stop).sum() >= 5 and np.abs(expected - stop).max() > 1.0


@pytest.mark.parametrize("surface", ["elevator", "aileron"])
def test_freed_surface_floats_to_the_zero_hinge_moment_angle_over_the_envelope(points, surface):
    act = ACTS[surface]
    runs = _batch(surface, points, "disconnection", onset_s=1.0, duration_s=6.0)
    _, truth = simulate(runs, orders_deg=np.zeros((len(runs), 600)), sensors=IDEAL)
    np.testing.assert_allclose(truth.surface_deg[:, -1], _float_deg(act, points), atol=0.01)


def test_freed_inboard_aileron_floats_far_from_its_rod_in_cruise(points):
    """[CHEN] §6.2: a disconnection is 21.4 % of the deflection range; the aft-loaded aileron
    (Ch0 < 0) floats trailing edge up, ≥ 15 % of its 50° travel at the median point."""
    runs = _batch("aileron", points, "disconnection", onset_s=5.0, duration_s=20.0)
    _, truth = simulate(runs)
    rod_deg = AILERON.mm_to_deg(truth.rod_mm[:, -300:])
    gap = np.abs(truth.surface_deg[:, -300:] - rod_deg).mean(axis=1)
    assert np.median(gap) >= 0.15 * AILERON.deflection_range_deg, np.median(gap)
    assert (truth.surface_deg[:, -1] < -5.0).all()                   # trailing edge up
    # the elevator (symmetric section, Ch0 = 0) floats with the tail's angle of attack only
    el = _float_deg(ELEVATOR, points)
    assert (el < 0).all() and np.median(el) > -1.5 and el.min() > -2.5


def test_aileron_holds_its_order_against_the_aft_loading(points):
    """docs/physics.md §3: the zero-deflection hinge moment loads the aileron actuator in
    normal flight (15–48 % of S·ΔP at neutral); the proportional loop still has no static
    error while the load stays below the stall force."""
    hm0, _ = _hinge(AILERON, points)
    load = np.abs(hm0) / (AILERON.r_mm / 1000.0) / (AILERON.S_m2 * AILERON.dP_Pa)
    assert 0.1 < load.min() and load.max() < 0.5
    order = np.zeros((len(points), 500))
    order[:, 50:] = 2.0                                       # trailing edge down, against it
    order[:, 250:] = 0.0
    runs = _batch("aileron", points, duration_s=5.0)
    _, truth = simulate(runs, orders_deg=order, sensors=IDEAL)
    np.testing.assert_allclose(truth.surface_deg[:, 240], 2.0, atol=1e-4)
    np.testing.assert_allclose(truth.surface_deg[:, -1], 0.0, atol=1e-4)


def test_asymmetric_elevator_rolls_the_aircraft_with_its_lateral_arm(points):
    """docs/physics.md §7: each elevator's lift increment acts at y_e = 4.1 m from the plane of
    symmetry: Clδ = ∓(y_e/b)·Czδ for the left/right elevator (b = 60.3 m), a trailing-edge-down
    left elevator rolls right wing down; the elevator yaw is 0 (est.)."""
    pts = points
    ctl = lpv.control_derivatives(pts["mach"], pts["cg_pct"])
    j = {name: i for i, name in enumerate(LAYOUT.names)}
    left, right = j["left_elevator"], j["right_elevator"]
    np.testing.assert_allclose(ctl["Cl"][:, left] / ctl["Cz"][:, left], -4.1 / 60.3, rtol=1e-12)
    np.testing.assert_allclose(ctl["Cl"][:, right], -ctl["Cl"][:, left], rtol=1e-12)
    assert (ctl["Cl"][:, left] > 0).all() and (ctl["Cn"][:, left] == 0).all()
    # size: per degree, one elevator rolls about 1.2 times as much as one aileron
    ratio = ctl["Cl"][:, left] / ctl["Cl"][:, j["left_inboard_aileron"]]
    np.testing.assert_allclose(ratio, 1.21, atol=0.01)
    model = lpv.run_models({k: pts[k].to_numpy() for k in
                            ("mass_t", "cg_pct", "mach", "qbar_pa", "tas_ms")}, 0.0)
    assert (model.B[:, lpv.IP, left] > 0).all() and (model.B[:, lpv.IP, right] < 0).all()
    # an aileron also changes lift and pitch: trailing edge down lifts and pitches nose down
    assert (ctl["Cz"][:, j["left_inboard_aileron"]] < 0).all()
    assert (ctl["Cm"][:, j["left_inboard_aileron"]] < 0).all()


def test_left_elevator_runaway_rolls_the_aircraft(tmp_path):
    """`fdd-campaign simulate --plant aircraft --surface left_elevator --fault runaway` moves the
    roll rate p by at least 0.2 °/s against its fault-free twin (same seed, cruise)."""
    from campaign.cli.commands import main

    p = {}
    for fault in ("runaway", "none"):
        out = tmp_path / f"{fault}.parquet"
        assert main(["simulate", "--plant", "aircraft", "--surface", "left_elevator",
                     "--fault", fault, "--out", str(out)]) == 0
        p[fault] = pd.read_parquet(out)["p [deg/s]"].to_numpy()
    assert np.abs(p["runaway"] - p["none"]).max() >= 0.2


def test_a_directory_planned_with_another_model_is_refused_on_resume(tmp_path, capsys):
    """A campaign directory planned under an earlier model version (servo-1, which recorded
    none) is refused with exit 2 and a message naming both versions, not resumed into a mix
    of two models' runs."""
    import json

    import pyarrow.parquet as pq

    from campaign.cli.commands import main
    from campaign.plan import MODEL_VERSION
    from campaign.store.files import METADATA_KEY

    out = tmp_path / "camp"
    assert main(["plan", "smoke", "--out", str(out)]) == 0
    path = out / "plan.parquet"
    table = pq.read_table(path)
    meta = dict(table.schema.metadata)
    stored = json.loads(meta[METADATA_KEY])
    assert stored["model_version"] == MODEL_VERSION
    del stored["model_version"]                       # as written before versions were recorded
    meta[METADATA_KEY] = json.dumps(stored).encode()
    pq.write_table(table.replace_schema_metadata(meta), path)
    capsys.readouterr()
    assert main(["plan", "smoke", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert ("was planned with model servo-1; this fdd-campaign simulates model "
            f"{MODEL_VERSION}") in err
    assert "re-plan into a new --out directory" in err
