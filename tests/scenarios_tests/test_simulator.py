"""The batch simulator as a whole: accuracy of the fixed-step scheme against a tight
``solve_ivp`` reference (docs/physics.md §2), finite outputs over the whole parametric grid
(docs/physics.md §8), batch invariance and determinism (docs/design.md §9, Non-negotiables), and
clear errors for bad run rows."""

import numpy as np
import pandas as pd
import pytest

from scenarios.catalog import FAULT_TYPES, MANOEUVRES, SURFACES
from scenarios.envelope import grid_points, level_draws
from scenarios.reference import integrate_reference
from scenarios.runs import RUN_RANGES
from scenarios.simulate import RunSpecError, integrate, prepare, simulate, single_run

#: Sensor noise of the rod LVDT, σ [mm] (docs/physics.md §4): the yardstick of the accuracy checks.
ROD_NOISE_MM = 0.03
#: Surface sensor noise, σ [deg] (docs/physics.md §4).
SURFACE_NOISE_DEG = 0.02


def _batch(rows: list[pd.DataFrame]) -> pd.DataFrame:
    return pd.concat(rows, ignore_index=True)


# ---- accuracy of the RK4-per-period scheme (docs/physics.md §2) ----------------------------------
def _accuracy_batch(surface: str) -> pd.DataFrame:
    """Every manoeuvre fault-free, and every fault type on a manoeuvre (round robin), onset
    mid-record; 20 s is the shortest record that holds every whole manoeuvre."""
    cases = [(m, "none") for m in MANOEUVRES]
    cases += [(MANOEUVRES[k % len(MANOEUVRES)], f) for k, f in enumerate(FAULT_TYPES)]
    return _batch([single_run(surface, m, f, seed=3, onset_s=9.0, duration_s=20.0,
                              alt_ft=18000.0, vcas_kt=300.0).assign(stream=k, run_id=f"{m}/{f}")
                   for k, (m, f) in enumerate(cases)])


@pytest.mark.slow
@pytest.mark.parametrize("surface", SURFACES)
def test_fixed_step_scheme_matches_tight_reference(surface):
    runs = _accuracy_batch(surface)
    p = prepare(runs)
    fast = integrate(p)
    ref = integrate_reference(p, rtol=1e-9, atol=1e-10, per_run=False)
    rod_rms = np.sqrt(np.mean((fast.x - ref.x) ** 2, axis=1))
    surf_rms = np.degrees(np.sqrt(np.mean((fast.delta - ref.delta) ** 2, axis=1)))
    worst = runs["run_id"].iloc[int(np.argmax(rod_rms))]
    # docs/physics.md §2: integration error far below the sensor noise — RMS < 0.01 mm, a third of
    # the LVDT σ, on every run; the surface angle likewise under a quarter of its sensor σ.
    assert rod_rms.max() < ROD_NOISE_MM / 3, f"rod RMS error {rod_rms.max():.2e} mm ({worst})"
    assert surf_rms.max() < SURFACE_NOISE_DEG / 4, f"surface RMS error {surf_rms.max():.2e} deg"
    # the comparison is not vacuous: the rod really moved in every run
    assert (np.ptp(ref.x, axis=1) > 0.1).all()


def test_batched_reference_equals_the_per_run_reference():
    runs = _accuracy_batch("elevator").iloc[[6, 10]]   # runaway, disconnection
    p = prepare(runs.assign(duration_s=20.0))
    per_run = integrate_reference(p, per_run=True)
    batched = integrate_reference(p, per_run=False)
    # both meet rtol 1e-9; their difference is a few times that on ~10 mm strokes
    np.testing.assert_allclose(batched.x, per_run.x, rtol=0, atol=1e-6)
    np.testing.assert_allclose(batched.delta, per_run.delta, rtol=0, atol=1e-7)


# ---- the whole parametric grid (docs/physics.md §8) ----------------------------------------------
def _grid_cases() -> pd.DataFrame:
    points = grid_points()
    frames = []
    for level in ("min", "nominal", "max"):
        draws = level_draws(level)
        frames.append(points.assign(level=level, **{k: float(v) for k, v in draws.items()}))
    return pd.concat(frames, ignore_index=True)


@pytest.mark.slow
@pytest.mark.parametrize("surface", SURFACES)
def test_all_324_cases_simulate_every_manoeuvre_with_finite_outputs(surface):
    cases = _grid_cases()
    base = single_run(surface, "cruise", duration_s=20.0).iloc[0].to_dict()
    rows = []
    for i, case in enumerate(cases.itertuples(index=False)):
        for j, manoeuvre in enumerate(MANOEUVRES):
            # every fault type appears on every manoeuvre across the grid (round robin)
            fault = ("none",) + FAULT_TYPES
            f = fault[(i + j) % len(fault)]
            row = dict(base, run_id=f"{i}-{manoeuvre}", manoeuvre=manoeuvre, fault=f,
                       stream=len(rows), alt_ft=case.alt_ft, vcas_kt=case.vcas_kt,
                       mass_t=case.mass_t, cg_pct=case.cg_pct,
                       **{c: getattr(case, c) for c in cases.columns if c.startswith("d_")})
            one = single_run(surface, manoeuvre, f, onset_s=8.0, duration_s=20.0)
            row.update(onset_s=one["onset_s"].iloc[0], magnitude=one["magnitude"].iloc[0],
                       freq_hz=one["freq_hz"].iloc[0])
            rows.append(row)
    runs = pd.DataFrame(rows)
    assert len(runs) == 324 * len(MANOEUVRES)
    signals, truth = simulate(runs)
    for name in ("command", "current", "rod_com", "rod_mon"):
        assert np.isfinite(getattr(signals, name)).all(), name
    assert np.isfinite(truth.rod_mm).all() and np.isfinite(truth.surface_deg).all()
    if surface == "elevator":
        assert np.isfinite(signals.surface).all()
    # surfaces stay within their mechanical stops
    act = signals.actuator
    assert truth.surface_deg.min() >= act.stop_min_deg - 1e-9
    assert truth.surface_deg.max() <= act.stop_max_deg + 1e-9


# ---- batch invariance and determinism (docs/design.md §9, Non-negotiables) -----------------------
def _mixed_batch() -> pd.DataFrame:
    faults = ("none",) + FAULT_TYPES
    rows = []
    for k, fault in enumerate(faults):
        r = single_run("elevator", MANOEUVRES[k % len(MANOEUVRES)], fault, seed=11,
                       onset_s=7.0 + k, duration_s=20.0, alt_ft=8000.0 + 3000.0 * k,
                       d_cz=0.04, d_cm=-0.03, d_ch0=0.1, d_vcas=-0.05)
        rows.append(r.assign(stream=k, run_id=f"r{k}"))
    return _batch(rows)


def _signals_equal(a, b, i=None):
    for name in ("command", "current", "rod_com", "rod_mon", "surface", "pressure"):
        x, y = getattr(a, name), getattr(b, name)
        if i is not None:
            x = x[i:i + 1]
        np.testing.assert_array_equal(x, y, err_msg=name)


def test_a_run_alone_equals_the_same_run_in_any_batch():
    runs = _mixed_batch()
    batch_sig, batch_truth = simulate(runs, pressure_sensor=True)
    for i in range(len(runs)):
        sig, truth = simulate(runs.iloc[[i]], pressure_sensor=True)
        _signals_equal(batch_sig, sig, i)
        np.testing.assert_array_equal(batch_truth.rod_mm[i:i + 1], truth.rod_mm)
        np.testing.assert_array_equal(batch_truth.surface_deg[i:i + 1], truth.surface_deg)
    # and in another order, with other neighbours
    perm = np.array([5, 0, 7, 2])
    sig, _ = simulate(runs.iloc[perm], pressure_sensor=True)
    for j, i in enumerate(perm):
        for name in ("current", "rod_com", "rod_mon", "surface", "pressure"):
            np.testing.assert_array_equal(getattr(sig, name)[j], getattr(batch_sig, name)[i])


def test_same_seed_same_signals_other_seed_other_noise():
    runs = _mixed_batch()
    a, _ = simulate(runs)
    b, _ = simulate(runs)
    _signals_equal(a, b)
    c, _ = simulate(runs.assign(seed=12))
    # other seed: other sensor noise on every run (the noise σ is 0.03 mm, so the COM
    # acquisitions differ at almost every step)
    differs = (c.rod_com != a.rod_com).mean(axis=1)
    assert (differs > 0.5).all()


# ---- bad input ----------------------------------------------------------------------------------
@pytest.mark.parametrize("column,value,expected", [
    ("surface", "elevatr", "did you mean 'elevator'"),
    ("manoeuvre", "nose-up", "did you mean 'nose_up'"),
    ("fault", "solid_jamming", "did you mean 'solid_jam'"),
    ("alt_ft", 60000.0, "alt_ft"),
    ("vcas_kt", 30.0, "vcas_kt"),        # knots expected; 30 is a m/s figure
    ("mass_t", 180000.0, "mass_t"),      # tonnes expected, not kg
    ("d_cm", 5.0, "d_cm"),               # relative, not percent
])
def test_bad_run_values_are_named_with_the_allowed_ones(column, value, expected):
    runs = single_run("elevator", "cruise", "solid_jam", duration_s=20.0)
    runs[column] = value
    with pytest.raises(RunSpecError) as info:
        simulate(runs)
    msg = str(info.value)
    assert expected in msg
    assert "allowed:" in msg
    if column not in ("surface", "manoeuvre", "fault"):
        assert f"out of range; allowed: {RUN_RANGES[column][0]:g} ≤ {column} ≤ " in msg


@pytest.mark.parametrize("column,value,expected", [
    ("seed", -1, "seed: 1 run(s) whose seed is not an integer ≥ 0"),   # SeedSequence refuses it
    ("seed", 2.5, "seed: 1 run(s) whose seed is not an integer ≥ 0"),
    ("duration_s", 19.0, "duration_s: 19 s is shorter than the 20 s"),  # the manoeuvres' minimum
])
def test_a_run_row_the_plant_cannot_simulate_is_refused_as_input(column, value, expected):
    # below the run-table check these fail inside numpy or the manoeuvre generator; said of
    # the run row they are the user's mistake (exit 2), not an internal error
    runs = single_run("elevator", "cruise", "none", duration_s=20.0)
    runs[column] = value
    with pytest.raises(RunSpecError) as info:
        simulate(runs)
    assert expected in str(info.value)


def test_every_problem_is_reported_at_once():
    runs = single_run("elevator", "cruise", "runaway", duration_s=20.0)
    runs["fault"] = "runaways"
    runs["cg_pct"] = -5.0
    with pytest.raises(RunSpecError) as info:
        simulate(runs)
    assert len(info.value.errors) == 2
