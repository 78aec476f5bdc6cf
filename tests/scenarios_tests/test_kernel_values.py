"""What the compiled kernels of scenarios/compiled.py and their NumPy references compute, by
value, against a plain-Python transcription of docs/physics.md (§2 time base, §3 rate law,
hinge moment and stops, §5 faults and the floating surface).

tests/scenarios_tests/test_kernels.py compares the compiled kernels with the NumPy loop bit for bit,
which a factor dropped the same way in both would pass. Here each kernel is compared with the
documented formula evaluated in plain Python floats (``math`` functions, the C library's, as
the kernels call them), on hand-made parameter rows whose every term matters (stall, aiding
cap, the ±0.999 clip, the stops, the damping neighbour), and on short closed-loop batches of
two blocks of runs (:data:`scenarios.compiled.BLOCK` + 2) with every fault path. Short horizons
keep the file at a few seconds.

Tolerances: the plain-Python formulas make the kernels' operations in the kernels' order, so
they agree to the last bit in practice; the assertions allow 1e-12 relative on one evaluation
(a reordering of two roundings) and 1e-9 (mm, mA, rad) on trajectories, where a 1-ulp
difference could only flip the 0.01 mm rod quantum with a probability of about 1e-12 per
sample. Every mutant of a formula changes a value by far more.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from scenarios import compiled as kernels
from scenarios import simulate as sim
from scenarios.faults import NEVER
from scenarios.params import ELEVATOR, SENSORS
from scenarios import servo
from scenarios.servo import PlantArrays, plant_arrays
from scenarios.simulate import prepare, single_run

K, KCI, IMAX, SDP, SDPREF, KA, R, XMIN, XMAX, HMD, HM0 = range(11)

#: A hand-made parameter row (units of scenarios.servo.PlantArrays): every term of the rate
#: law is a sizeable share of the result; at x = −72 mm (sin δ = −0.6) the hinge load is
#: 1.39 × S·ΔP, so an opposing current stalls and an aiding one reaches the 2·S·ΔP cap.
ROW = np.array([1.5, 10.0, 8.0, 1.0e5, 0.9e5, 2.0, 120.0, -100.0, 100.0, -20000.0, 500.0])
#: A lightly loaded row (low q̄): near |x/r| = 0.999 the load is a few % of S·ΔP, so the
#: clipped angle and cos δ change the speed without stalling it.
LIGHT = ROW.copy()
LIGHT[[HMD, HM0]] = (-20.0, 0.5)


# ---- plain-Python transcription of docs/physics.md ---------------------------------------
def rate(x, i, p, loaded, a=None):
    """Rod speed [mm/s], docs/physics.md §3 ([COMB] eq. 2): the hinge moment at
    δ = asin(clip(x/r, ±0.999)) (or *a* when given), F = −HM/(r[m]·cos δ), the numerator
    S·ΔP − sign(i)·F limited to [0, 2·S·ΔP], no motion further into a stop."""
    x, i = float(x), float(i)
    v0 = p[KCI] * i
    if loaded:
        s = min(max(x / p[R], -0.999), 0.999)
        hm = p[HM0] + p[HMD] * (math.asin(s) if a is None else a)
        f = -hm / (p[R] / 1000.0 * math.sqrt(1.0 - s * s))
        ka = p[KA]
    else:
        f, ka = 0.0, 0.0
    sgn = float((i > 0) - (i < 0))
    num = min(max(p[SDP] - sgn * f, 0.0), 2.0 * p[SDP])
    v = v0 * math.sqrt(num / (p[SDPREF] + ka * v0 * v0))
    if (x >= p[XMAX] and v > 0.0) or (x <= p[XMIN] and v < 0.0):
        return 0.0
    return v


def rk4(x, i, p, loaded, h, a=None):
    """Classical RK4 over *h* with *i* held (docs/physics.md §2), the first stage at the
    angle *a* when given; the result inside the stops."""
    k1 = rate(x, i, p, loaded, a)
    k2 = rate(x + 0.5 * h * k1, i, p, loaded)
    k3 = rate(x + 0.5 * h * k2, i, p, loaded)
    k4 = rate(x + h * k3, i, p, loaded)
    return min(max(x + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4), p[XMIN]), p[XMAX])


def float_next(delta, p, h, d_min, d_max):
    """Floating surface over *h* (docs/physics.md §5): sqrt|δ − δ_f| decreases by
    h·c/2, c = sqrt(|∂HM/∂δ| / (Ka·r³·cos³δ)) in SI units, δ_f = −HM0/(∂HM/∂δ)."""
    d_f = -p[HM0] / p[HMD]
    e = delta - d_f
    c = math.sqrt(abs(p[HMD]) / (p[KA] * 1.0e6 * (p[R] / 1000.0) ** 3 * math.cos(delta) ** 3))
    root = max(math.sqrt(abs(e)) - 0.5 * h * c, 0.0)
    return min(max(d_f + math.copysign(root * root, e), d_min), d_max)


def close(got, want, rel=1e-12):
    return got == pytest.approx(want, rel=rel, abs=1e-12)


# ---- scalar plant functions ----------------------------------------------------------------
def test_sign_and_clip():
    assert kernels.sign(2.5) == 1.0 and kernels.sign(-1e-300) == -1.0
    assert kernels.sign(0.0) == 0.0 and math.copysign(1.0, kernels.sign(-0.0)) == -1.0
    assert math.isnan(kernels.sign(math.nan))
    assert kernels.clip(5.0, -1.0, 2.0) == 2.0 and kernels.clip(-5.0, -1.0, 2.0) == -1.0
    assert kernels.clip(0.5, -1.0, 2.0) == 0.5


def as_plant(row):
    """One run of :class:`scenarios.servo.PlantArrays` holding the parameter row *row*."""
    return PlantArrays(**{f: np.array([row[j]]) for j, f in enumerate(kernels.PLANT_FIELDS)})


def _np1(func, *args):
    return float(func(*[np.array([a]) if isinstance(a, (float, bool)) else a for a in args])[0])


#: The scalar plant functions of each engine: the compiled kernels and scenarios.servo.
RATE = {"compiled": kernels.rod_rate_1,
        "numpy": lambda x, i, row, loaded: _np1(servo.rod_rate, float(x), float(i),
                                                as_plant(row), bool(loaded))}
RK4 = {"compiled": kernels.rk4_step_1,
       "numpy": lambda x, i, row, loaded, h: _np1(
           lambda *a: servo.rk4_step(*a, h), float(x), float(i), as_plant(row), bool(loaded))}
FLOAT = {"compiled": kernels.float_step_1,
         "numpy": lambda d, row, h, lo, hi: _np1(
             lambda dd: servo.float_step(dd, as_plant(row), h, lo, hi), float(d))}
ENGINES = ("compiled", "numpy")

X_GRID = (-119.9, -119.89, -100.0, -72.0, -30.0, 0.0, 12.5, 72.0, 100.0, 119.89, 119.9)
I_GRID = (-8.0, -2.5, 0.0, 0.7, 8.0)


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("row", [ROW, LIGHT], ids=["high_load", "light_load"])
@pytest.mark.parametrize("loaded", [True, False])
def test_rate_law_over_the_stroke_equals_the_documented_formula(loaded, row, engine):
    for x in X_GRID:
        for i in I_GRID:
            assert close(RATE[engine](x, i, row, loaded), rate(x, i, row, loaded)), (x, i)


@pytest.mark.parametrize("engine", ENGINES)
def test_rate_law_stall_aiding_cap_and_clip_values(engine):
    rod_rate = RATE[engine]
    v0 = ROW[KCI] * 8.0
    # sin δ = −0.6: F = −(500 − 20000·asin(−0.6))/(0.12·0.8) < −S·ΔP
    f = -(500.0 + 20000.0 * math.asin(0.6)) / (0.12 * 0.8)
    assert f < -ROW[SDP]
    assert rod_rate(-72.0, -8.0, ROW, True) == 0.0            # stalled
    assert rod_rate(-72.0, -0.01, ROW, True) == 0.0           # stalled at any current
    cap = v0 * math.sqrt(2.0 * ROW[SDP] / (ROW[SDPREF] + ROW[KA] * v0 * v0))
    assert close(rod_rate(-72.0, 8.0, ROW, True), cap)         # aiding: capped
    # unloaded: no hinge load, no damping neighbour: Kci·i·sqrt(S·ΔP/S·ΔP_ref)
    for i in (8.0, -0.3):
        v0 = ROW[KCI] * i
        assert close(rod_rate(-72.0, i, ROW, False), v0 * math.sqrt(ROW[SDP] / ROW[SDPREF]))
    # beyond |x/r| = 0.999 the angle is that of the clip, not asin(x/r)
    for x, i in ((119.9, -8.0), (-119.9, 8.0), (119.9, -0.5), (-119.9, 0.5)):
        v = rod_rate(x, i, LIGHT, True)
        assert close(v, rate(x, i, LIGHT, True))
        unclipped = rate(x, i, LIGHT.copy(), True, a=math.asin(x / 120.0))
        assert abs(v - unclipped) > 1e-5 * abs(v), (x, i)   # round-off: 1e-15


@pytest.mark.parametrize("engine", ENGINES)
def test_rate_law_end_stops(engine):
    rod_rate = RATE[engine]
    # at a stop: no motion further into it (however slow), motion away from it unchanged
    for i in (2.0, 0.05):
        assert rod_rate(100.0, i, LIGHT, True) == 0.0
        assert close(rod_rate(100.0, -i, LIGHT, True), rate(99.0, -i, LIGHT, True), rel=1e-3)
        assert rod_rate(-100.0, -i, LIGHT, True) == 0.0
        assert close(rod_rate(-100.0, i, LIGHT, True), rate(-99.0, i, LIGHT, True), rel=1e-3)
        assert rod_rate(100.0, i, LIGHT, False) == 0.0
        assert rod_rate(-100.0, -i, LIGHT, False) == 0.0
        # just inside both stops the rod moves either way
        for x in (99.999, -99.999):
            assert rod_rate(x, i, LIGHT, True) > 0.0
            assert rod_rate(x, -i, LIGHT, True) < 0.0


def test_known_angle_stands_for_asin_only_inside_the_clip():
    bogus = math.asin(30.0 / 120.0) + 0.05
    assert close(kernels.rod_rate_known(30.0, 3.0, ROW, True, True, bogus),
                 rate(30.0, 3.0, ROW, True, a=bogus))
    assert close(kernels.rod_rate_known(30.0, 3.0, ROW, True, False, bogus),
                 rate(30.0, 3.0, ROW, True))
    # outside the clip the given angle is ignored
    assert close(kernels.rod_rate_known(119.9, -3.0, ROW, True, True, bogus),
                 rate(119.9, -3.0, ROW, True))


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("loaded", [True, False])
def test_rk4_step_equals_the_documented_scheme(loaded, engine):
    rk4_step = RK4[engine]
    for x in (-72.0, -30.0, 0.0, 60.0, 99.9):
        for i in (-8.0, -1.0, 0.4, 8.0):
            assert close(rk4_step(x, i, ROW, loaded, 0.01), rk4(x, i, ROW, loaded, 0.01)), (x, i)
    # the new position is held inside the stops
    assert rk4_step(99.9, 8.0, LIGHT, loaded, 0.01) == 100.0
    assert rk4_step(-99.9, -8.0, LIGHT, loaded, 0.01) == -100.0


def test_rk4_step_with_a_known_angle():
    bogus = math.asin(0.25) - 0.03
    assert close(kernels.rk4_step_known(30.0, 3.0, ROW, True, 0.01, True, bogus),
                 rk4(30.0, 3.0, ROW, True, 0.01, a=bogus))


@pytest.mark.parametrize("engine", ENGINES)
def test_float_step_closed_form(engine):
    float_step = FLOAT[engine]
    d_f = -ROW[HM0] / ROW[HMD]                        # 0.025 rad
    for delta in (-0.3, -0.1, 0.02, 0.2, 0.35):
        for h in (0.001, 0.01):
            assert close(float_step(delta, ROW, h, -0.4, 0.4),
                         float_next(delta, ROW, h, -0.4, 0.4)), (delta, h)
    # from 0.2 rad: the surface moves towards δ_f and not past it
    d1 = float_step(0.2, ROW, 0.001, -0.4, 0.4)
    assert d_f < d1 < 0.2
    d1 = float_step(-0.2, ROW, 0.001, -0.4, 0.4)
    assert -0.2 < d1 < d_f
    # close to δ_f the square-root law arrives within the step: exactly δ_f
    assert float_step(d_f + 1e-6, ROW, 0.01, -0.4, 0.4) == d_f
    assert float_step(d_f - 1e-6, ROW, 0.01, -0.4, 0.4) == d_f
    # held inside the stops [rad]
    assert float_step(0.2, ROW, 0.001, -0.4, 0.01) == 0.01
    assert float_step(-0.2, ROW, 0.001, 0.1, 0.4) == 0.1


@pytest.mark.parametrize("row", [ROW, LIGHT], ids=["high_load", "light_load"])
def test_numpy_rod_force_equals_the_documented_formula(row):
    """F_aero = −HM/(r[m]·cos δ), δ from the clipped sine (docs/physics.md §3)."""
    for x in X_GRID:
        s = min(max(x / row[R], -0.999), 0.999)
        f = -(row[HM0] + row[HMD] * math.asin(s)) / (row[R] / 1000.0 * math.sqrt(1.0 - s * s))
        assert close(_np1(servo.aero_force, float(x), as_plant(row)), f), x


# ---- block kernels against the scalar law ----------------------------------------------------
def fields(n=18):
    """Plant rows that differ run by run, ROW-like (even runs) and LIGHT-like (odd runs),
    and the same as (FIELD_ROWS, n) :func:`kernels.plant_fields`."""
    rows = np.array([ROW if r % 2 == 0 else LIGHT for r in range(n)])
    rows[:, HM0] += 30.0 * np.arange(n)
    rows[:, KCI] = 10.0 + 0.5 * np.arange(n)
    rows[:, R] -= 0.003 * np.arange(n)        # every field differs run by run, even r
    out = np.empty((kernels.FIELD_ROWS, n))
    out[:kernels.P_RM] = rows.T
    out[kernels.P_RM] = rows[:, R] / 1000.0
    return rows, out


#: Rod positions [mm] and currents [mA] of a block starting at run 1: the LIGHT-like runs
#: (even t) at and beyond both stops with currents into and away from them and beyond the
#: ±0.999 clip; the ROW-like runs (odd t) stalled, capped and in between.
BLOCK_X = np.array([100.0, -72.0, 100.0, -72.0, -100.0, 0.0, -100.0, 45.0, 119.9, 7.0,
                    -119.9, 30.0, 100.0, -50.0, -100.0, 20.0, 99.0])
BLOCK_I = np.array([0.05, -8.0, -2.0, 8.0, -0.05, -3.0, 2.0, -8.0, -0.5, 9.0, 0.5, 1.0,
                    -0.05, 0.3, 0.05, -0.3, 1.0])
B = BLOCK_X.size


def test_loaded_rates_of_a_block_equal_the_rate_law():
    rows, pf = fields()
    r0, b = 1, B - 1
    out = np.full(B, 7.0)
    kernels.loaded_rates(BLOCK_X, BLOCK_I, pf, r0, b, np.empty(B), np.empty(B), out)
    for t in range(b):
        assert close(out[t], rate(BLOCK_X[t], BLOCK_I[t], rows[r0 + t], True)), t
    assert out[b] == 7.0                                  # only the block is written
    assert out[0] == 0.0 and out[2] < 0.0 and out[4] == 0.0 and out[6] > 0.0   # the stops
    assert -1.0 < out[12] < 0.0 < out[14] < 1.0             # slow, away from them


@pytest.mark.parametrize("reuse", [True, False])
def test_plant_rates_of_a_block_equal_the_rate_law(reuse):
    rows, pf = fields()
    r0, b = 1, B - 1
    loaded = np.array([1.0, 0.0, 1.0, 1.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 1.0, 1.0, 1.0, 0.0,
                       1.0, 1.0, 1.0])
    angle = np.arcsin(np.clip(BLOCK_X / rows[r0:r0 + B, R], -0.999, 0.999)) + 0.01
    out = np.full(B, 7.0)
    kernels.plant_rates(BLOCK_X, BLOCK_I, pf, r0, b, loaded, reuse, angle, np.empty(B),
                        np.empty(B), np.empty(B), out)
    for t in range(b):
        inside = abs(BLOCK_X[t] / rows[r0 + t, R]) <= 0.999
        a = angle[t] if (reuse and inside) else None
        assert close(out[t], rate(BLOCK_X[t], BLOCK_I[t], rows[r0 + t], bool(loaded[t]), a)), t
    assert out[b] == 7.0


# ---- the closed loop (integrate_block) ----------------------------------------------------
N_LOOP = kernels.BLOCK + 2            # two blocks: the second holds two runs
T_LOOP = 100
FAULT_CYCLE = ("none", "runaway", "hardover", "liquid_jam", "solid_jam", "disconnection",
               "ofc_liquid", "ofc_solid", "solid_jam")


#: High q̄ (FL100, 330 kt: hinge loads up to stall) and low q̄ (FL380, 160 kt: the stops
#: reached), alternating run by run.
POINTS = ({"alt_ft": 10000.0, "vcas_kt": 330.0}, {"alt_ft": 38000.0, "vcas_kt": 160.0})


def loop_batch() -> pd.DataFrame:
    """N_LOOP runs at high and low q̄ (:data:`POINTS`), each fault path of docs/physics.md §5 in
    turn (the second solid jam of the cycle the "offset" variant: a jump at onset), onsets
    spread over 0.3–0.6 s, every fault in both blocks."""
    rows = []
    for j in range(N_LOOP):
        slot = (j + 6) % len(FAULT_CYCLE)        # offset jams from run 2 on, so that both
        fault = FAULT_CYCLE[slot]                # ends of the first block hold one
        kw = {}
        if slot == 8:
            kw["magnitude"] = 1.5 if j % 2 else -1.5
        if fault == "hardover":
            kw["magnitude"] = 1.0 if j % 2 else -1.0
        rows.append(single_run("elevator", "cruise", fault, seed=j, onset_s=0.3 + 0.01 * (j % 31),
                               duration_s=T_LOOP * 0.01, **POINTS[j % 2],
                               d_ch0=0.1 * ((j % 5) - 2) / 2, **kw))
    frame = pd.concat(rows, ignore_index=True)
    frame["stream"] = np.arange(N_LOOP)
    frame["run_id"] = [f"v{j}" for j in range(N_LOOP)]
    return frame


def loop_orders() -> np.ndarray:
    """(N_LOOP, T_LOOP) surface orders [deg]: steps of −35° … +22° at 0.05 s, so that the
    rods saturate, load up to stall and some reach a stop, and back by a third at 0.7 s,
    after every onset (a disconnected rod moves unloaded)."""
    level = np.linspace(-35.0, 22.0, N_LOOP)
    t = np.arange(T_LOOP) * 0.01
    ramp = np.clip((t - 0.05) / 0.1, 0.0, 1.0) - np.clip((t - 0.7) / 0.1, 0.0, 1.0) / 3.0
    return level[:, None] * ramp[None, :] + 1.0


def loop_reference(p, rod_quant):
    """The closed loop of docs/physics.md §2 with the fault arrays of §5, run by run in
    plain Python: acquire y_k (scale, bias, noise, quantum; + the liquid-jam bias, or the
    OFC replacement held from its onset), i_k = sat(K·(u_k − y_k)); the current flowing is
    i_{k−1} (+ the liquid OFC, or the hardover where finite); RK4 over Ts, the seized rod
    kept, the disconnected rod unloaded and its surface floating."""
    fa, pl = p.faults, kernels.plant_matrix(p.plant)
    n, T = p.u.shape
    d_min, d_max = math.radians(p.act.stop_min_deg), math.radians(p.act.stop_max_deg)
    out = {name: np.empty((n, T)) for name in ("x", "delta", "i_cmd", "i_app", "y_com")}
    for r in range(n):
        row = pl[r]
        x = min(max(p.u[r, 0], row[XMIN]), row[XMAX])
        delta = math.asin(x / row[R])
        i_prev, y_hold = 0.0, 0.0
        for k in range(T):
            if k == fa.k_jam[r] and fa.jam_offset[r] != 0.0:
                x = min(max(x + fa.jam_offset[r], row[XMIN]), row[XMAX])
                delta = math.asin(x / row[R])
            y = x * (1.0 + p.com_scale[r]) + p.com_bias[r] + p.com_noise[r, k]
            y = rod_quant * float(np.rint(y / rod_quant))
            if fa.com_add is not None:
                y += fa.com_add[r, k]
            if fa.com_osc is not None and k >= fa.k_osc[r]:
                if k == fa.k_osc[r]:
                    y_hold = y
                osc = fa.com_osc[r, k]
                y = y_hold + (0.0 if math.isnan(osc) else osc)
            i_new = min(max(row[K] * (fa.u_loop[r, k] - y), -row[IMAX]), row[IMAX])
            i_app = i_prev
            if fa.cur_add is not None:
                i_app += fa.cur_add[r, k]
            if fa.cur_force is not None and math.isfinite(fa.cur_force[r, k]):
                i_app = fa.cur_force[r, k]
            loaded = k < fa.k_disc[r]
            for name, v in zip(out, (x, delta, i_new, i_app, y)):
                out[name][r, k] = v
            x_next = x if k >= fa.k_jam[r] else rk4(x, i_app, row, loaded, p.ts)
            delta = (math.asin(x_next / row[R]) if loaded
                     else float_next(delta, row, p.ts, d_min, d_max))
            x, i_prev = x_next, i_new
    return out


@pytest.fixture(scope="module")
def loop():
    p = prepare(loop_batch(), orders_deg=loop_orders())
    return p, loop_reference(p, SENSORS.rod_quant_mm)


def test_the_loop_batch_exercises_every_path(loop):
    p, ref = loop
    fa = p.faults
    for arr in (fa.com_add, fa.com_osc, fa.cur_add, fa.cur_force):
        assert arr is not None
    assert (fa.k_jam < NEVER).sum() > 4 and (fa.jam_offset != 0.0).sum() >= 4
    assert (fa.k_disc < NEVER).sum() >= 4 and (fa.k_osc < NEVER).sum() >= 4
    pl = kernels.plant_matrix(p.plant)
    x = ref["x"]
    assert (np.abs(ref["i_cmd"]) == pl[:, [IMAX]]).any()             # saturated currents
    assert (x == pl[:, [XMAX]]).any() or (x == pl[:, [XMIN]]).any()   # a stop reached
    # second block: its runs differ from the first block's
    assert not np.array_equal(x[-1], x[kernels.BLOCK - 1])


@pytest.mark.parametrize("engine", ["compiled", "numpy"])
def test_closed_loop_equals_the_documented_loop(loop, engine):
    p, ref = loop
    got = (kernels.integrate_compiled(p, SENSORS) if engine == "compiled"
           else sim.integrate(p, SENSORS))
    for name, want in ref.items():
        np.testing.assert_allclose(getattr(got, name), want, rtol=0, atol=1e-9, err_msg=name)


@pytest.mark.parametrize("fault", ["none", "runaway", "hardover", "liquid_jam", "solid_jam",
                                   "disconnection", "ofc_liquid", "ofc_solid"])
def test_a_batch_of_one_fault_type_equals_the_documented_loop(fault):
    """A batch holding one fault type beside a fault-free run: the kernel is told which
    optional fault arrays exist (the others are passed empty) and which paths to take. The
    solid jam is the "offset" variant with a jump of exactly 1 mm."""
    rows = [single_run("elevator", "cruise", f, seed=j, onset_s=0.4, duration_s=1.0,
                       **POINTS[j], **({"magnitude": 1.0} if f == "solid_jam" else {}))
            for j, f in enumerate((fault, "none"))]
    runs = pd.concat(rows, ignore_index=True)
    runs["stream"] = [0, 1]
    orders = loop_orders()[[20, 50]]
    p = prepare(runs, orders_deg=orders)
    ref = loop_reference(p, SENSORS.rod_quant_mm)
    got = kernels.integrate_compiled(p, SENSORS)
    for name, want in ref.items():
        np.testing.assert_allclose(getattr(got, name), want, rtol=0, atol=1e-9, err_msg=name)
    if fault != "none":                     # the fault changed the faulty run
        free = loop_reference(prepare(runs.assign(fault="none"), orders_deg=orders),
                              SENSORS.rod_quant_mm)
        assert max(np.abs(free[name][0] - ref[name][0]).max() for name in ref) > 1e-3


def test_fault_onsets_one_step_before_at_and_after(loop):
    p, ref = loop
    fa = p.faults
    got = kernels.integrate_compiled(p, SENSORS)
    for r in np.flatnonzero(fa.k_jam < NEVER):
        k0 = int(fa.k_jam[r])
        jump = got.x[r, k0] - got.x[r, k0 - 1]
        if fa.jam_offset[r] != 0.0:                                   # the offset jump at onset
            assert abs(jump) > 0.5 and np.sign(jump) == np.sign(fa.jam_offset[r])
        assert np.ptp(got.x[r, k0:]) == 0.0                           # seized from onset on
    for r in np.flatnonzero(fa.k_disc < NEVER):
        k0 = int(fa.k_disc[r])
        # the surface leaves the rod's angle from the period after the onset on
        assert got.delta[r, k0] == pytest.approx(math.asin(got.x[r, k0] / p.plant.r_mm[r]),
                                                 abs=1e-15)
        assert abs(got.delta[r, k0 + 2] - math.asin(got.x[r, k0 + 2] / p.plant.r_mm[r])) > 1e-4
    hard = np.flatnonzero(np.isfinite(fa.cur_force).any(axis=1))
    for r in hard:
        k0 = int(np.argmax(np.isfinite(fa.cur_force[r])))
        assert got.i_app[r, k0 - 1] == got.i_cmd[r, k0 - 2]
        assert (got.i_app[r, k0] == fa.cur_force[r, k0]
                and abs(fa.cur_force[r, k0]) == p.plant.i_max[r])


# ---- nominal models of the position monitor ------------------------------------------------
def model_reference(u, x0, row, ts):
    """docs/physics.md §2–3 without faults: out_k = x_k, i_k = sat(K·(u_k − x_k)),
    x_{k+1} = RK4 with i_{k−1} held."""
    out = np.empty(u.shape)
    x, i_prev = x0, 0.0
    for k in range(u.size):
        out[k] = x
        i_new = min(max(row[K] * (u[k] - x), -row[IMAX]), row[IMAX])
        x = rk4(x, i_prev, row, True, ts)
        i_prev = i_new
    return out


def models_of(n, T):
    """(u, x0, three plants): orders [mm] of *n* runs, steps of −24° … +20° over
    *T* steps, starting positions near the first order, three hinge-moment variants."""
    qbar = np.linspace(4e3, 18e3, n)
    base = dict(qbar_pa=qbar, alpha_deg=np.linspace(-1.0, 6.0, n), mach=np.full(n, 0.55))
    plants = [plant_arrays(ELEVATOR, **base, d_chd=d, d_ch0=d) for d in (0.0, -0.4, 0.6)]
    t = np.arange(T) * 0.01
    level = np.linspace(-24.0, 20.0, n)
    u = 120.0 * np.sin(np.radians(level[:, None] * np.clip(t / 0.08, 0, 1)[None, :] + 0.5))
    x0 = u[:, 0] + np.linspace(-0.3, 0.3, n)
    return u, x0, plants


@pytest.fixture(scope="module")
def models():
    u, x0, plants = models_of(kernels.BLOCK + 3, 40)
    n = u.shape[0]
    ref = [np.array([model_reference(u[r], x0[r], kernels.plant_matrix(pl)[r], 0.01)
                     for r in range(n)]) for pl in plants]
    return u, x0, plants, ref


def test_servo_model_equals_the_documented_loop(models):
    u, x0, plants, ref = models
    for pl, want in zip(plants, ref):
        np.testing.assert_allclose(kernels.servo_model(u, x0, pl, 0.01), want, rtol=0, atol=1e-9)
    assert np.ptp(ref[0], axis=1).max() > 20.0                  # large strokes
    assert np.abs(ref[1] - ref[2]).max() > 0.05                 # the hinge moment matters


def test_servo_band_is_the_hull_of_the_documented_models(models):
    u, x0, plants, ref = models
    lo, hi = kernels.servo_band(u, x0, plants, 0.01)
    np.testing.assert_allclose(lo, np.minimum.reduce(ref), rtol=0, atol=1e-9)
    np.testing.assert_allclose(hi, np.maximum.reduce(ref), rtol=0, atol=1e-9)
    # each of the three models is the low and the high one somewhere
    for j in range(3):
        assert (np.abs(lo - ref[j]) < 1e-12).any() and (np.abs(hi - ref[j]) < 1e-12).any()
    lo1, hi1 = kernels.servo_band(u, x0, plants[:1], 0.01)
    np.testing.assert_array_equal(lo1, hi1)


def test_a_band_of_more_models_than_parameter_rows():
    """The band holds any number of models: 13 (more than the 12 parameter rows of a
    model's plant_fields, which a band must not confuse with the model count)."""
    u, x0, _ = models_of(3, 20)
    scales = np.linspace(-0.5, 0.7, 13)
    many = [plant_arrays(ELEVATOR, qbar_pa=np.array([4e3, 1e4, 1.8e4]),
                         alpha_deg=np.array([-1.0, 2.0, 6.0]), mach=np.full(3, 0.55),
                         d_chd=d, d_ch0=d) for d in scales]
    ref = [np.array([model_reference(u[r], x0[r], kernels.plant_matrix(pl)[r], 0.01)
                     for r in range(3)]) for pl in many]
    lo, hi = kernels.servo_band(u, x0, many, 0.01)
    np.testing.assert_allclose(lo, np.minimum.reduce(ref), rtol=0, atol=1e-9)
    np.testing.assert_allclose(hi, np.maximum.reduce(ref), rtol=0, atol=1e-9)


def test_servo_band_propagates_a_nan_model_in_any_position(models):
    u, x0, plants, ref = models
    broken = plant_arrays(ELEVATOR, qbar_pa=np.full(u.shape[0], 9e3),
                          alpha_deg=np.full(u.shape[0], 2.0), mach=np.full(u.shape[0], 0.55))
    broken.hm_0[[1, kernels.BLOCK + 1]] = np.nan
    for order in ([broken, plants[0], plants[1]], [plants[0], broken, plants[1]]):
        lo, hi = kernels.servo_band(u, x0, order, 0.01)
        for r in (1, kernels.BLOCK + 1):
            assert np.isnan(lo[r, 1:]).all() and np.isnan(hi[r, 1:]).all()
        assert not np.isnan(lo[0]).any() and not np.isnan(hi[2]).any()


# ---- a stop reached inside a step ---------------------------------------------------------
def near_stops(rows, ts=0.01):
    """x0 [mm] of two runs with the parameter rows *rows*, each 0.9·Ts·v_sat from a stop
    (run 0 below the upper stop, run 1 above the lower), v_sat the saturated speed there.
    With the current saturated towards the stop, RK4's last stage (x + Ts·k3) lies beyond
    the stop, where the rate law gives 0, while x + Ts·(k1 + 2k2 + 2k3)/6 does not: the step
    ends just inside the stop, not on it (docs/physics.md §3: the stops act on every
    evaluation of the rate law)."""
    x0 = np.empty(2)
    for r, (stop, sgn) in enumerate(((rows[0, XMAX], 1.0), (rows[1, XMIN], -1.0))):
        v = abs(rate(stop - sgn * 0.5, sgn * rows[r, IMAX], rows[r], True))
        x0[r] = stop - sgn * 0.9 * ts * v
    return x0


def test_a_rod_reaching_its_stop_within_a_step_nominal_models():
    pl = plant_arrays(ELEVATOR, qbar_pa=np.full(2, 3e3), alpha_deg=np.zeros(2),
                      mach=np.full(2, 0.4))
    rows = kernels.plant_matrix(pl)
    x0 = near_stops(rows)
    u = np.array([[rows[0, XMAX] + 50.0] * 4, [rows[1, XMIN] - 50.0] * 4])
    assert (rows[:, K] * np.abs(u[:, 0] - x0) > rows[:, IMAX]).all()     # saturated
    ref = np.array([model_reference(u[r], x0[r], rows[r], 0.01) for r in range(2)])
    # step 0 holds i = 0; step 1 runs saturated and ends inside the stop, step 2 on it
    assert ref[0, 1] == x0[0] and rows[0, XMAX] - 0.2 < ref[0, 2] < rows[0, XMAX]
    assert ref[1, 1] == x0[1] and rows[1, XMIN] + 0.2 > ref[1, 2] > rows[1, XMIN]
    assert ref[0, 3] == rows[0, XMAX] and ref[1, 3] == rows[1, XMIN]
    np.testing.assert_allclose(kernels.servo_model(u, x0, pl, 0.01), ref, rtol=0, atol=1e-9)
    lo, hi = kernels.servo_band(u, x0, [pl, pl], 0.01)
    np.testing.assert_allclose(lo, ref, rtol=0, atol=1e-9)
    np.testing.assert_allclose(hi, ref, rtol=0, atol=1e-9)


def test_a_rod_reaching_its_stop_within_a_step_closed_loop():
    runs = pd.concat([single_run("elevator", "cruise", "none", seed=j, duration_s=1.0,
                                 alt_ft=38000.0, vcas_kt=160.0) for j in range(2)],
                     ignore_index=True)
    runs["stream"] = [0, 1]
    rows = kernels.plant_matrix(prepare(runs, orders_deg=np.zeros((2, 100))).plant)
    # from x0 (i ≈ 0 over the first two periods: the order is where the rod is), then an
    # order beyond the stop
    order = np.degrees(np.arcsin(near_stops(rows) / rows[:, R]))[:, None] + np.zeros((2, 100))
    order[0, 1:] = ELEVATOR.stop_max_deg + 5.0
    order[1, 1:] = ELEVATOR.stop_min_deg - 5.0
    p = prepare(runs, orders_deg=order)
    ref = loop_reference(p, SENSORS.rod_quant_mm)
    got = kernels.integrate_compiled(p, SENSORS)
    for name, want in ref.items():
        np.testing.assert_allclose(getattr(got, name), want, rtol=0, atol=1e-9, err_msg=name)
    x_max, x_min = rows[0, XMAX], rows[1, XMIN]
    # the saturated step ends inside the stop, the next on it
    assert x_max - 0.2 < ref["x"][0, 3] < x_max and ref["x"][0, 4] == x_max
    assert x_min + 0.2 > ref["x"][1, 3] > x_min and ref["x"][1, 4] == x_min


# ---- engine selection, parameter layout, warm-up --------------------------------------------
def test_engine_selection():
    assert kernels.HAVE_NUMBA
    assert kernels.check_engine("numpy") == "numpy"
    with pytest.raises(ValueError, match="unknown engine 'jit'; choose one of compiled, numpy"):
        kernels.check_engine("jit")
    assert kernels.current_engine() == "compiled"
    assert kernels.resolve_engine(None) == "compiled"
    assert kernels.resolve_engine("numpy") == "numpy"
    assert kernels.resolve_engine("compiled") == "compiled"
    with pytest.raises(ValueError, match="unknown engine"):
        kernels.resolve_engine("fast")
    with pytest.raises(RuntimeError):
        with kernels.use_engine("numpy"):
            assert kernels.current_engine() == "numpy"
            assert kernels.resolve_engine(None) == "numpy"
            raise RuntimeError
    assert kernels.current_engine() == "compiled"
    with pytest.raises(ValueError, match="unknown engine"):
        with kernels.use_engine("fast"):
            pass


def test_plant_matrix_and_fields_layout():
    pl = plant_arrays(ELEVATOR, qbar_pa=np.array([5e3, 12e3]), alpha_deg=np.array([1.0, 3.0]),
                      mach=np.array([0.4, 0.6]))
    m = kernels.plant_matrix(pl)
    assert m.shape == (2, 11) and m.flags.c_contiguous
    for j, name in enumerate(kernels.PLANT_FIELDS):
        np.testing.assert_array_equal(m[:, j], getattr(pl, name))
    f = kernels.plant_fields(pl)
    assert f.shape == (kernels.FIELD_ROWS, 2) == (12, 2) and f.flags.c_contiguous
    np.testing.assert_array_equal(f[:11], m.T)
    np.testing.assert_array_equal(f[kernels.P_RM], pl.r_mm / 1000.0)
    stack = kernels.band_plants([pl, pl])
    assert stack.shape == (2, 12, 2) and stack.flags.c_contiguous
    np.testing.assert_array_equal(stack[1], f)


def test_register_warmup_and_warm_up(monkeypatch):
    calls, logs = [], []
    monkeypatch.setattr(kernels, "_WARMUPS", [])
    monkeypatch.setattr(kernels, "_CACHED", [])

    def warm():
        calls.append(1)

    kernels.register_warmup(warm, kernels=(kernels.rk4_step_1,))
    kernels.register_warmup(warm, kernels=(kernels.rk4_step_1, kernels.float_step_1))
    assert kernels._WARMUPS == [warm]
    assert kernels._CACHED == [kernels.rk4_step_1, kernels.float_step_1]
    monkeypatch.setattr(kernels, "_cache_is_warm", lambda: False)
    with monkeypatch.context() as m:
        # a clock that reads 100 s, then 102.5 s: the warm-up took 2.5 s
        m.setattr(kernels.time, "perf_counter", iter([100.0, 102.5]).__next__)
        took = kernels.warm_up(logs.append)
    assert calls == [1] and took == 2.5
    assert logs == ["compiling kernels (first use; numba caches them for the next runs)…",
                    "kernels compiled in 2.5 s"]
    monkeypatch.setattr(kernels, "_cache_is_warm", lambda: True)
    kernels.warm_up(logs.append)                # warm: runs the warm-ups, says nothing
    assert calls == [1, 1] and len(logs) == 2
    monkeypatch.setattr(kernels, "_cache_is_warm", lambda: False)
    kernels.warm_up()                           # cold without a log: nothing to say
    assert calls == [1, 1, 1]


def test_cache_state_after_warm_up_and_with_unknown_functions(monkeypatch):
    kernels.warm_up()
    # numba writes each compiled kernel's index beside it: warm now (unless nothing is
    # compiled at all)
    if not __import__("numba").core.config.DISABLE_JIT:
        assert kernels._cache_is_warm()
    # a registered function without numba's cache internals: reported cold, not raised
    monkeypatch.setattr(kernels, "_CACHED", [*kernels._CACHED, object()])
    assert kernels._cache_is_warm() is False
