"""The position monitor (detectors/builtin/position_monitor.py, docs/detectors.md) pinned by value
on hand-built inputs, in both engines and in a few seconds: the nominal servo model and its
band of corner models (servo-valve gain, supply pressure, hinge offset and slope) against the
reference integrator (docs/physics.md §2–3), each check's
residual and its sign, the learned thresholds (``"max"`` and ``"evt"`` with the target shared
by the active checks) and the normalised residual and confirmation of several checks at once.

Expected values come from :func:`scenarios.servo.rod_rate` and
:func:`scenarios.servo.rk4_step` (the rate law and the reference RK4 of the rod: the monitor's
model takes one explicit Euler step by default, Heun's step with ``model_step = "heun"`` and
the RK4 step with ``model_step = "rk4"``),
from the order statistic of docs/thresholds.md and from residuals written out by hand, never
from the method under test.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.stats import binom

from detectors.builtin.position_monitor import PositionMonitor
from scenarios.compiled import BLOCK, use_engine
from scenarios.params import ELEVATOR
from scenarios.servo import plant_arrays, rk4_step, rod_rate
from scenarios.signals import Signals

ENGINES = ("compiled", "numpy")
TS = 0.01
#: flight point of the hand-built runs [Pa, deg, -]: q̄ = 20 kPa loads the rod, so the
#: hinge-moment scale moves the model (docs/physics.md §3)
QBAR, ALPHA, MACH = 20e3, 3.0, 0.7
#: the band of one model: the plain nominal model (every range of the band at 1)
PLAIN = {"hinge_scale": (1.0, 1.0), "kci_scale": (1.0, 1.0), "supply_scale": (1.0, 1.0)}


def signals(rod_com, rod_mon=None, surface=None, command=None, classes=None):
    """Signals of hand-made acquisitions [mm] (surface in deg; NaN when absent)."""
    rod_com = np.atleast_2d(np.asarray(rod_com, float))
    n, T = rod_com.shape
    nan = np.full((n, T), np.nan)
    return Signals(
        ts=TS, command=np.zeros((n, T)) if command is None else np.atleast_2d(command),
        current=np.zeros((n, T)), rod_com=rod_com,
        rod_mon=rod_com.copy() if rod_mon is None else np.atleast_2d(np.asarray(rod_mon, float)),
        surface=nan if surface is None else np.atleast_2d(np.asarray(surface, float)),
        pressure=nan,
        schedule={"qbar_pa": np.full(n, QBAR), "alpha_deg": np.full(n, ALPHA),
                  "mach": np.full(n, MACH), "vcas_kt": np.full(n, 300.0),
                  "alt_ft": np.full(n, 20000.0), "mass_t": np.full(n, 180.0),
                  "cg_pct": np.full(n, 30.0)},
        actuator=ELEVATOR, run_ids=np.array([f"r{i}" for i in range(n)]), classes=classes)


def model_by_hand(u, x0, hinge_scale=1.0, step="euler", corner=None):
    """The nominal loop driven by *u* from *x0* (docs/physics.md §2–3): the output at step k
    is x_k; the current sat(K·(u_k − x_k)) computed at step k is held over the next period,
    so the rod moves under the previous step's current (none before step 1). *step*:
    ``"euler"``, x_{k+1} = clip(x_k + Ts·ẋ(x_k, i_{k−1})), ``"heun"``, x_{k+1} = clip(x_k +
    Ts/2·(ẋ(x_k) + ẋ(x_k + Ts·ẋ(x_k)))), or ``"rk4"``. *corner*: (Kci, S·ΔP, HM(0),
    ∂HM/∂δ) factors of the model instead of *hinge_scale* (docs/physics.md §6; S·ΔP_ref
    stays nominal, §3)."""
    n, T = u.shape
    p = plant_arrays(ELEVATOR, qbar_pa=np.full(n, QBAR), alpha_deg=np.full(n, ALPHA),
                     mach=np.full(n, MACH))
    kci, supply, offset, slope = (1.0, 1.0, hinge_scale, hinge_scale) if corner is None else corner
    p = replace(p, Kci=p.Kci * kci, SdP=p.SdP * supply, hm_0=p.hm_0 * offset,
                hm_delta=p.hm_delta * slope)
    out = np.empty((n, T))
    x, i_prev = np.asarray(x0, float).copy(), np.zeros(n)
    for k in range(T):
        out[:, k] = x
        i_new = np.clip(p.K * (u[:, k] - x), -p.i_max, p.i_max)
        if step == "rk4":
            x = rk4_step(x, i_prev, p, np.ones(n, bool), TS)
        elif step == "heun":
            k1 = rod_rate(x, i_prev, p, np.ones(n, bool))
            k2 = rod_rate(x + TS * k1, i_prev, p, np.ones(n, bool))
            x = np.clip(x + 0.5 * TS * (k1 + k2), p.x_min, p.x_max)
        else:
            x = np.clip(x + TS * rod_rate(x, i_prev, p, np.ones(n, bool)), p.x_min, p.x_max)
        i_prev = i_new
    return out


#: three runs of 12 steps: a large negative order (the current saturates at −i_max), a
#: small positive order, and a large positive one; the rod starts off the order
U = np.zeros((3, 12))
U[0, 1:] = -30.0
U[1, 1:] = 0.4
U[2, 2:] = 25.0
X0 = np.array([1.0, -2.0, 0.5])


def _rod():
    rod = np.tile(X0[:, None], (1, 12))
    rod[:, 5:] += np.array([[-0.5], [0.3], [2.0]])   # the rod leaves the model from step 5
    return rod


# ---- the model and its band --------------------------------------------------------------
@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("step", ["euler", "heun", "rk4"])
def test_model_output_is_the_reference_loop_with_a_one_period_current_delay(engine, step):
    sig = signals(_rod(), command=U)
    got = PositionMonitor.model_output(sig, engine=engine, model_step=step)
    want = model_by_hand(U, X0, step=step)
    # same formulas, the compiled loop in its own order of operations: 1e-12 relative
    assert got == pytest.approx(want, rel=1e-12, abs=1e-12)
    np.testing.assert_array_equal(got[:, :2], np.stack([X0, X0], axis=1))  # no current yet
    assert got[0, -1] < X0[0] - 1.0 and got[2, -1] > X0[2] + 1.0         # both directions


def test_model_plant_scales_both_hinge_moment_terms_only():
    sig = signals(_rod(), command=U)
    nominal = PositionMonitor.model_plant(sig)
    scaled = PositionMonitor.model_plant(sig, 1.6)
    assert np.all(nominal.hm_0 != 0.0) and np.all(nominal.hm_delta != 0.0)
    assert scaled.hm_0 == pytest.approx(1.6 * nominal.hm_0, rel=1e-15)
    assert scaled.hm_delta == pytest.approx(1.6 * nominal.hm_delta, rel=1e-15)
    for name, value in vars(nominal).items():
        if name not in ("hm_0", "hm_delta"):
            np.testing.assert_array_equal(getattr(scaled, name), value, err_msg=name)


def test_model_plant_corner_scales_kci_stall_force_and_each_hinge_term_only():
    # docs/physics.md §6: the plant's d_kci, d_supply, d_ch0/d_cha and d_chd; the supply
    # moves S·ΔP only, S·ΔP_ref stays nominal (docs/physics.md §3, "Limits")
    sig = signals(_rod(), command=U)
    nominal = PositionMonitor.model_plant(sig)
    corner = PositionMonitor.model_plant(sig, corner=(0.95, 1.05, 0.6, 1.6))
    assert corner.Kci == pytest.approx(0.95 * nominal.Kci, rel=1e-15)
    assert corner.SdP == pytest.approx(1.05 * nominal.SdP, rel=1e-15)
    assert corner.hm_0 == pytest.approx(0.6 * nominal.hm_0, rel=1e-15)
    assert corner.hm_delta == pytest.approx(1.6 * nominal.hm_delta, rel=1e-15)
    for name, value in vars(nominal).items():
        if name not in ("Kci", "SdP", "hm_0", "hm_delta"):
            np.testing.assert_array_equal(getattr(corner, name), value, err_msg=name)
    # every factor is applied whatever its value (2 as well as 0.95): none is taken for 1
    double = PositionMonitor.model_plant(sig, corner=(2.0, 2.0, 2.0, 2.0))
    for name in ("Kci", "SdP", "hm_0", "hm_delta"):
        assert getattr(double, name) == pytest.approx(2.0 * getattr(nominal, name), rel=1e-15)


def _corners(hinge_scale, kci=(0.95, 1.05), supply=(0.95, 1.05), band="corners"):
    """The band's corners written out: nominal first, then the slow valve corner (low Kci,
    low S·ΔP) and the fast one, each with the hinge (offset, slope) ends, without repeats."""
    lo, hi = sorted(hinge_scale)
    hinges = ([(lo, lo), (hi, hi)] if band == "paired"
              else [(lo, lo), (lo, hi), (hi, lo), (hi, hi)])
    out = [(1.0, 1.0, 1.0, 1.0)]
    for valve in ((min(kci), min(supply)), (max(kci), max(supply))):
        for h in hinges:
            if (*valve, *h) not in out:
                out.append((*valve, *h))
    return tuple(out)


@pytest.mark.parametrize("params, count", [
    ({}, 9), ({"band": "paired"}, 5), ({"hinge_scale": (1.6, 0.6)}, 9),
    ({"hinge_scale": (1.0, 1.0)}, 3), ({"kci_scale": (1.0, 1.0), "supply_scale": (1.0, 1.0)}, 5),
    (PLAIN, 1), ({**PLAIN, "hinge_scale": (1.0, 2.0)}, 4),
    ({**PLAIN, "hinge_scale": (1.0, 2.0), "band": "paired"}, 2),
    ({**PLAIN, "hinge_scale": (0.5, 0.5)}, 2),
])
def test_band_corners_put_the_nominal_model_first(params, count):
    corners = PositionMonitor(**params).band_corners()
    assert corners[0] == (1.0, 1.0, 1.0, 1.0)
    assert len(corners) == count == len(set(corners))
    assert corners == _corners(params.get("hinge_scale", (0.6, 1.6)),
                               params.get("kci_scale", (0.95, 1.05)),
                               params.get("supply_scale", (0.95, 1.05)),
                               params.get("band", "corners"))


def test_default_band_is_the_nine_corners_of_the_mismatch_the_plant_draws():
    # docs/physics.md §6: Kci and S·ΔP ±5 % (slow and fast valve corners), HM(0) and ∂HM/∂δ
    # each at 0.6 or 1.6 (hinge_scale) independently
    assert PositionMonitor().band_corners() == (
        (1.0, 1.0, 1.0, 1.0),
        (0.95, 0.95, 0.6, 0.6), (0.95, 0.95, 0.6, 1.6), (0.95, 0.95, 1.6, 0.6),
        (0.95, 0.95, 1.6, 1.6),
        (1.05, 1.05, 0.6, 0.6), (1.05, 1.05, 0.6, 1.6), (1.05, 1.05, 1.6, 0.6),
        (1.05, 1.05, 1.6, 1.6))


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("step", ["euler", "heun", "rk4"])
@pytest.mark.parametrize("params", [{}, {"band": "paired"}, {**PLAIN, "hinge_scale": (1.0, 2.0)},
                                    PLAIN, {"hinge_scale": (1.0, 1.0)},
                                    {**PLAIN, "supply_scale": (1.0, 1.05)}])   # two models
def test_model_band_is_the_hull_of_the_corner_models(engine, step, params):
    sig = signals(_rod(), command=U)
    det = PositionMonitor(model_step=step, **params)
    lo, hi = det.model_band(sig, engine=engine)
    corners = _corners(params.get("hinge_scale", (0.6, 1.6)),
                       params.get("kci_scale", (0.95, 1.05)),
                       params.get("supply_scale", (0.95, 1.05)), params.get("band", "corners"))
    outs = [model_by_hand(U, X0, step=step, corner=c) for c in corners]
    assert lo == pytest.approx(np.minimum.reduce(outs), rel=1e-12, abs=1e-12)
    assert hi == pytest.approx(np.maximum.reduce(outs), rel=1e-12, abs=1e-12)
    if params != PLAIN:
        assert np.max(hi - lo) > 1e-3          # the corners move the models apart


@pytest.mark.parametrize("engine", ENGINES)
def test_valve_corners_bound_the_saturated_rod_speed(engine):
    # run 0: the current saturates at −i_max from step 2 on; the rod then moves open-loop
    # at Kci·i_max·sqrt(num/(S·ΔP_ref + Ka·(Kci·i_max)²)) (docs/physics.md §3), slower with
    # the low Kci and S·ΔP, faster with the high ones: the slow and fast corners (hinge
    # moment nominal) straddle the nominal model there
    sig = signals(_rod(), command=U)
    det = PositionMonitor(hinge_scale=(1.0, 1.0))
    lo, hi = det.model_band(sig, engine=engine)
    slow = model_by_hand(U, X0, corner=(0.95, 0.95, 1.0, 1.0))
    fast = model_by_hand(U, X0, corner=(1.05, 1.05, 1.0, 1.0))
    nominal = model_by_hand(U, X0)
    assert np.all(fast[0, 3:] < nominal[0, 3:]) and np.all(nominal[0, 3:] < slow[0, 3:])
    assert lo[0] == pytest.approx(fast[0], rel=1e-12, abs=1e-12)
    assert hi[0] == pytest.approx(slow[0], rel=1e-12, abs=1e-12)


# ---- residuals ---------------------------------------------------------------------------
def test_each_check_residual_by_hand():
    rod = _rod()
    mon = rod - 0.25
    surface = np.full(rod.shape, 1.5)                        # deg
    sig = signals(rod, mon, surface, command=U)
    res = PositionMonitor(**PLAIN).residuals(sig)
    assert set(res) == {"loop", "com_mon", "surface"}
    np.testing.assert_array_equal(res["com_mon"], np.full(rod.shape, 0.25))   # COM − MON
    assert res["surface"] == pytest.approx(ELEVATOR.r_mm * np.sin(np.radians(1.5)) - mon,
                                           rel=1e-15)              # r·sin δ − MON
    assert res["loop"] == pytest.approx(rod - model_by_hand(U, X0), rel=1e-12, abs=1e-12)


def test_loop_residual_is_zero_inside_the_band_and_signed_outside():
    sig = signals(_rod(), command=U)
    det = PositionMonitor(hinge_scale=(0.5, 2.0), checks=("loop",))
    lo, hi = det.model_band(sig, engine="numpy")
    y = np.where(np.arange(12) % 3 == 0, hi + 0.2, np.where(np.arange(12) % 3 == 1, lo - 0.3,
                                                            0.5 * (lo + hi)))
    y[:, 0] = X0                                              # the model starts at y_COM(0)
    sig = signals(y, command=U)
    r = det.residuals(sig)["loop"]
    assert np.all(r[:, 0] == 0.0)
    k = np.arange(1, 12)
    assert r[:, k[k % 3 == 0]] == pytest.approx(0.2, rel=1e-9)
    assert r[:, k[k % 3 == 1]] == pytest.approx(-0.3, rel=1e-9)
    assert np.all(r[:, k[k % 3 == 2]] == 0.0)


def test_a_string_check_and_a_missing_surface_sensor():
    rod = np.zeros((1, 5))
    assert set(PositionMonitor(checks="com_mon").residuals(signals(rod))) == {"com_mon"}
    assert set(PositionMonitor().residuals(signals(rod))) == {"loop", "com_mon"}
    assert set(PositionMonitor().residuals(signals(rod, surface=np.zeros((1, 5))))) == {
        "loop", "com_mon", "surface"}


# ---- fit ---------------------------------------------------------------------------------------
N_LEARN = 40


def _learning(n=N_LEARN, T=20, seed=5):
    """n fault-free runs: rod still at 0 mm, MON off by a different amount in each run, a
    surface sensor off by another; the order holds the rod (loop residual 0)."""
    rng = np.random.default_rng(seed)
    rod = np.zeros((n, T))
    mon = np.zeros((n, T))
    mon[np.arange(n), rng.integers(0, T, n)] = rng.permutation(np.linspace(0.1, 0.5, n))
    surface = np.zeros((n, T))
    surface[np.arange(n), rng.integers(0, T, n)] = rng.permutation(np.linspace(0.2, 1.0, n))
    return signals(rod, mon, surface)


def _per_run_max(sig):
    mon = sig.rod_mon
    surf = ELEVATOR.r_mm * np.sin(np.radians(sig.surface)) - mon
    return {"com_mon": np.abs(mon).max(axis=1), "surface": np.abs(surf).max(axis=1)}


def test_max_rule_threshold_of_every_check():
    sig = _learning()
    det = PositionMonitor(threshold_method="max", safety=1.25, checks=("com_mon", "surface"),
                          floor_mm=0.01).fit(sig)
    want = _per_run_max(sig)
    assert det.thresholds_mm_ == pytest.approx({k: 1.25 * v.max() for k, v in want.items()},
                                               rel=1e-12)
    assert det.learning_runs_ == N_LEARN
    assert not hasattr(det, "calibration_")


def test_evt_threshold_shares_the_target_among_the_active_checks():
    # docs/thresholds.md: each of the m active checks at p = target/m (union bound). With
    # target 0.05 and 40 runs at 60 % confidence the order-statistic rank r is the largest
    # with P(Binomial(40, p) ≥ r) ≥ 0.6: r = 1 (the largest value) at p = 0.025 (two checks)
    # and r = 2 (the second largest) at p = 0.05 (one check)
    assert binom.sf(0, 40, 0.025) >= 0.6 > binom.sf(1, 40, 0.025)
    assert binom.sf(1, 40, 0.05) >= 0.6 > binom.sf(2, 40, 0.05)
    sig = _learning()
    want = _per_run_max(sig)
    common = dict(threshold_method="evt", target_fa_per_run=0.05, threshold_confidence=0.6,
                  floor_mm=0.01)
    two = PositionMonitor(checks=("com_mon", "surface"), **common).fit(sig)
    assert two.thresholds_mm_ == pytest.approx({k: np.sort(v)[-1] for k, v in want.items()},
                                               rel=1e-12)
    assert all(c.supported and c.k == 1 for c in two.calibration_.values())
    one = PositionMonitor(checks=("com_mon",), **common).fit(sig)
    assert one.thresholds_mm_ == pytest.approx({"com_mon": np.sort(want["com_mon"])[-2]},
                                               rel=1e-12)
    assert one.calibration_["com_mon"].k == 2


def test_evt_threshold_never_falls_below_the_floor():
    sig = _learning()
    det = PositionMonitor(checks=("com_mon",), threshold_method="evt", target_fa_per_run=0.05,
                          threshold_confidence=0.6, floor_mm=2.0).fit(sig)
    assert det.thresholds_mm_ == {"com_mon": 2.0}


# ---- decision: several checks, both engines, more runs than one block ---------------------------
def _decision_case():
    """BLOCK + 3 runs of 14 steps: the order holds the rod at 0 (loop residual 0 until the rod
    moves), COM − MON and the surface check each lead at their own steps."""
    n, T = BLOCK + 3, 14
    rod = np.zeros((n, T))
    mon = np.zeros((n, T))
    surface = np.zeros((n, T))
    rod[:, 3] = 0.3                     # COM − MON = 0.3 and the loop sees 0.3 (both checks)
    mon[:, 6] = -0.15                   # COM − MON = 0.15 only
    surface[:, 9] = 0.5                 # r·sin(0.5°) = 1.0472 mm from MON
    rod[-1, 11:] = 0.6                  # the last run (second block): a lasting excursion
    mon[-1, 11:] = 0.6
    return signals(rod, mon, surface)


@pytest.mark.parametrize("engine", ENGINES)
def test_normalised_residual_is_the_largest_check_ratio(engine):
    sig = _decision_case()
    det = PositionMonitor(confirm_s=0.02, **PLAIN)
    det.thresholds_mm_ = {"loop": 0.6, "com_mon": 0.2, "surface": 2.0}
    det.learning_runs_ = 1
    with use_engine(engine):
        d = det.detect(sig)
    s = ELEVATOR.r_mm * np.sin(np.radians(0.5))
    want = np.zeros(14)
    want[3] = max(0.3 / 0.6, 0.3 / 0.2, 0.3 / 2.0)           # the com_mon ratio leads
    want[6] = max(0.15 / 0.2, 0.15 / 2.0)                     # |MON − surface| = 0.15 too
    want[9] = s / 2.0
    for i in (0, BLOCK - 1, BLOCK, BLOCK + 1):
        assert d.residual[i] == pytest.approx(want, rel=1e-12, abs=1e-15), i
        assert not d.alarm[i].any()                        # one step over: no confirmation
    last = d.residual[-1]
    # from step 11: loop |0.6 − model| (the model stays at 0: no order, no error) and the
    # surface |0 − 0.6| over their thresholds; com_mon 0
    assert last[11:] == pytest.approx(np.full(3, max(0.6 / 0.6, 0.6 / 2.0)), rel=1e-12)
    # 0.02 s at 10 ms: 3 consecutive steps at or over 1 (steps 11, 12, 13): the last step
    np.testing.assert_array_equal(d.alarm[-1], np.arange(14) == 13)


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("checks", [("surface",), ("com_mon",), ("loop",)])
def test_a_single_check_decides_alone(engine, checks):
    sig = _decision_case()
    det = PositionMonitor(confirm_s=0.0, checks=checks, **PLAIN)
    det.thresholds_mm_ = {checks[0]: 0.25}
    det.learning_runs_ = 1
    with use_engine(engine):
        d = det.detect(sig)
    s = ELEVATOR.r_mm * np.sin(np.radians(0.5))
    r = {"surface": {6: 0.15, 9: s}, "com_mon": {3: 0.3, 6: 0.15},
         "loop": {3: 0.3}}[checks[0]]
    want = np.zeros(14)
    for k, v in r.items():
        want[k] = v / 0.25
    assert d.residual[0] == pytest.approx(want, rel=1e-12, abs=1e-15)
    first = min(k for k, v in r.items() if v >= 0.25)
    np.testing.assert_array_equal(d.alarm[0], np.arange(14) >= first)   # latched


@pytest.mark.parametrize("engine", ENGINES)
def test_a_nan_acquisition_makes_the_residual_nan(engine):
    sig = _decision_case()
    mon = sig.rod_mon.copy()
    mon[0, 4] = np.nan
    sig = replace(sig, rod_mon=mon)
    det = PositionMonitor(confirm_s=0.0, **PLAIN)
    det.thresholds_mm_ = {"loop": 0.6, "com_mon": 0.2, "surface": 2.0}
    det.learning_runs_ = 1
    with use_engine(engine):
        d = det.detect(sig)
    assert np.isnan(d.residual[0, 4]) and not np.isnan(d.residual[0, 5])
    assert d.residual[0, 3] == pytest.approx(1.5, rel=1e-12)


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("checks", [("loop",), ("loop", "com_mon", "surface")])
def test_a_nan_com_acquisition_makes_the_residual_nan(engine, checks):
    sig = _decision_case()
    rod = sig.rod_com.copy()
    rod[1, 4] = np.nan
    sig = replace(sig, rod_com=rod)
    det = PositionMonitor(confirm_s=0.0, checks=checks, **PLAIN)
    det.thresholds_mm_ = {"loop": 0.6, "com_mon": 0.2, "surface": 2.0}
    det.learning_runs_ = 1
    with use_engine(engine):
        d = det.detect(sig)
    assert np.isnan(d.residual[1, 4]) and not np.isnan(d.residual[1, 3])
    assert not np.isnan(d.residual[0]).any()


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("params", [{"hinge_scale": (0.5, 2.0)}, PLAIN])
def test_loop_decision_away_from_zero_follows_the_band(engine, params):
    # the rod above the band, below it and inside it, with the band far from 0 mm
    det = PositionMonitor(confirm_s=0.0, checks=("loop",), **params)
    det.thresholds_mm_ = {"loop": 0.4}
    det.learning_runs_ = 1
    outs = [model_by_hand(U, X0, corner=c)
            for c in _corners(params["hinge_scale"], params.get("kci_scale", (0.95, 1.05)),
                              params.get("supply_scale", (0.95, 1.05)))]
    lo, hi = np.minimum.reduce(outs), np.maximum.reduce(outs)
    assert np.median(np.abs(hi)) > 1.0                        # the band is mostly away from 0
    k = np.arange(12)
    y = np.where(k % 3 == 0, hi + 0.2, np.where(k % 3 == 1, lo - 0.6, 0.5 * (lo + hi)))
    y[:, 0] = X0
    # the three runs repeated over more runs than one compiled block (BLOCK)
    reps = BLOCK // 3 + 2
    with use_engine(engine):
        d = det.detect(signals(np.tile(y, (reps, 1)), command=np.tile(U, (reps, 1))))
    want = np.where(k % 3 == 0, 0.5, np.where(k % 3 == 1, 1.5, 0.0))
    want[0] = 0.0
    # 0.2 and 0.6 mm over 0.4 mm, after the subtraction of band values of a few mm: 1e-9
    assert d.residual == pytest.approx(np.tile(want, (3 * reps, 1)), rel=1e-9, abs=1e-9)
    np.testing.assert_array_equal(d.alarm, np.tile(k >= 1, (3 * reps, 1)))


@pytest.mark.parametrize("engine", ENGINES)
def test_a_single_step_run_starts_the_model_at_the_rod(engine):
    det = PositionMonitor(confirm_s=0.0, checks=("loop", "com_mon"))
    det.thresholds_mm_ = {"loop": 0.1, "com_mon": 0.1}
    det.learning_runs_ = 1
    # first a run ending with the band at −20 mm, so a band left over from it would show
    far = signals(np.full((2, 2), -20.0), command=np.full((2, 2), -20.0))
    sig = signals(np.full((2, 1), 5.0), np.full((2, 1), 5.0), command=np.zeros((2, 1)))
    with use_engine(engine):
        assert not det.detect(far).alarm.any()
        d = det.detect(sig)
    np.testing.assert_array_equal(d.residual, np.zeros((2, 1)))
    assert not d.alarm.any()


def test_detect_names_the_checks_without_threshold():
    det = PositionMonitor(checks=("com_mon", "loop"))
    det.thresholds_mm_ = {"com_mon": 0.1}
    det.learning_runs_ = 1
    with pytest.raises(ValueError, match=r"no learned threshold for check\(s\) \['loop'\]"):
        det.detect(signals(np.zeros((1, 4))))


def test_a_campaign_accepts_the_monitor_as_an_online_detector():
    from detectors.compat import offline_problems

    # causal (docs/write-a-detector.md, Capabilities): an alarm at step k uses samples up to k
    assert offline_problems({"position-monitor": PositionMonitor.capabilities}) == []
    assert PositionMonitor.capabilities.needs_fit


def test_detect_before_fit_is_refused():
    from detectors.base import NotFittedError

    with pytest.raises(NotFittedError, match=r"PositionMonitor\.detect\(\) called before fit"):
        PositionMonitor().detect(signals(np.zeros((1, 4))))


def test_defaults_are_the_documented_ones():
    # docs/detectors.md parameter table of position-monitor
    assert PositionMonitor().get_params() == {
        "safety": 1.5, "confirm_s": 0.05, "checks": ("loop", "com_mon", "surface"),
        "floor_mm": 0.05, "threshold_method": "evt", "target_fa_per_run": 1e-4,
        "threshold_confidence": 0.95, "threshold_tail": "exponential", "hinge_scale": (0.6, 1.6),
        "model_step": "euler", "kci_scale": (0.95, 1.05), "supply_scale": (0.95, 1.05),
        "band": "corners"}


def test_rate_evaluations_per_step_are_the_band_models_times_the_step_stages():
    """``fdd-campaign bench``'s arithmetic floor: the nine models of the default band, each
    1 (Euler), 2 (Heun) or 4 (RK4) evaluations of the rate law per step; none without the
    loop check, the only check that runs the models."""
    assert [PositionMonitor(model_step=s).rate_evaluations_per_step()
            for s in ("euler", "heun", "rk4")] == [9, 18, 36]
    assert PositionMonitor(hinge_scale=(1.0, 1.0), kci_scale=(1.0, 1.0), supply_scale=(1.0, 1.0),
                           model_step="rk4").rate_evaluations_per_step() == 4
    assert PositionMonitor(checks=("com_mon", "surface")).rate_evaluations_per_step() == 0


def test_coverage_and_capabilities():
    """With the surface check the monitor covers every fault type; without it every one but
    the disconnection (docs/physics.md §5). It fits on the workers and its alarm is a
    decision a trade-off curve may scale."""
    from detectors.base import Coverage
    from scenarios.catalog import FAULT_TYPES

    assert PositionMonitor().coverage() == Coverage(None, "")
    rods_only = PositionMonitor(checks=("loop", "com_mon")).coverage()
    assert rods_only.faults == tuple(f for f in FAULT_TYPES if f != "disconnection")
    assert "disconnection" in rods_only.reason
    caps = PositionMonitor.capabilities
    assert (caps.needs_fit, caps.needs_surface_sensor, caps.causal, caps.fit_concurrently,
            caps.threshold_scale) == (True, False, True, True, True)


def test_the_warm_up_runs_the_decision_on_writable_and_read_only_signals(monkeypatch):
    """detect reads the signals as read-only views (scenarios.compiled.read_only_view), a
    fit's arrays are writable: the warm-up calls the decision kernel on both, so that numba
    compiles (or loads) both signatures before a campaign's first chunk."""
    from conftest import warm_up_writability

    import detectors.builtin.position_monitor as pm

    assert warm_up_writability(monkeypatch, pm, "_decide_block") == [True, False]
