"""What ``scenarios.runs`` accepts as a run row and what it refuses, value by value.

Every plant validates its run table with :func:`scenarios.runs.validate_runs` before any
work (docs/design.md §4): a row outside a physical range, a faulty run without an onset
inside the run, a fault without the magnitude or the OFC frequency it needs, or an unknown
name is refused, every problem listed at once with the count of rows and the first bad
value. The ranges are inclusive at both ends; these tests pin each end from both sides.
"""

from __future__ import annotations

import pickle
import re

import numpy as np
import pandas as pd
import pytest

from scenarios import envelope
from scenarios.runs import (DEFAULT_MANOEUVRE_SET, PLANT_DRAWS, RUN_COLUMNS, RunSpecError,
                            aero_draws, flight_of, manoeuvre_sets, plant_draws, run_streams,
                            validate_runs)

#: The physical ranges a run row is accepted in (inclusive): alt 0-45 000 ft, VCAS 80-400 kt,
#: mass 50-300 t, CG 0-60 % MAC, a run of 1 s to 1 h; relative deviations within ±50 %, the
#: hinge-moment mismatches within ±90 % (wider than any campaign file's half-width,
#: docs/campaign-file.md, so that a replayed run row is never refused for its draws).
RANGES = {
    "alt_ft": (0.0, 45000.0), "vcas_kt": (80.0, 400.0), "mass_t": (50.0, 300.0),
    "cg_pct": (0.0, 60.0), "duration_s": (1.0, 3600.0),
    "d_cx": (-0.5, 0.5), "d_cy": (-0.5, 0.5), "d_cz": (-0.5, 0.5), "d_cl": (-0.5, 0.5),
    "d_cm": (-0.5, 0.5), "d_cn": (-0.5, 0.5), "d_vcas": (-0.5, 0.5), "d_alt": (-0.5, 0.5),
    "d_mass": (-0.5, 0.5), "d_cg": (-0.5, 0.5), "d_supply": (-0.5, 0.5), "d_kci": (-0.5, 0.5),
    "d_ch0": (-0.9, 0.9), "d_cha": (-0.9, 0.9), "d_chd": (-0.9, 0.9),
}
#: A step outside a bound, small against every range and against the +1 a planted change
#: of a bound would add
EPS = 1e-6


def row(**over) -> dict:
    """A valid fault-free run row (nominal draws), with *over* replacing values."""
    base = {"run_id": "r0", "surface": "elevator", "manoeuvre": "cruise", "fault": "none",
            "onset_s": np.nan, "magnitude": np.nan, "freq_hz": np.nan, "alt_ft": 20000.0,
            "vcas_kt": 300.0, "mass_t": 180.0, "cg_pct": 30.0,
            **{c: 0.0 for c in RUN_COLUMNS if c.startswith("d_")},
            "seed": 1, "stream": 0, "duration_s": 30.0}
    base.update(over)
    return base


def table(*rows: dict) -> pd.DataFrame:
    return pd.DataFrame(list(rows) or [row()])


def first_value(error: str) -> float:
    """The first bad value an error message shows, written as a plain float (no NumPy repr)."""
    assert "np." not in error, error
    return float(re.search(r"first: ([-+\w.]+)", error).group(1))


def errors_of(runs: pd.DataFrame) -> list[str]:
    """The problems validate_runs lists for *runs* (empty when it accepts them)."""
    try:
        validate_runs(runs)
    except RunSpecError as exc:
        return exc.errors
    return []


def test_the_ranges_cover_every_numeric_flight_and_draw_column():
    numeric = {c for c in RUN_COLUMNS if c.startswith("d_")} | {"alt_ft", "vcas_kt", "mass_t",
                                                                "cg_pct", "duration_s"}
    assert set(RANGES) == numeric


@pytest.mark.parametrize("column", sorted(RANGES))
def test_each_range_is_inclusive_at_both_ends(column):
    lo, hi = RANGES[column]
    for value in (lo, hi, 0.5 * (lo + hi)):
        assert errors_of(table(row(**{column: value}))) == [], (column, value)
    for value in (lo - EPS, hi + EPS, np.nan, np.inf, -np.inf):
        errs = errors_of(table(row(**{column: value})))
        assert len(errs) == 1 and errs[0].startswith(f"{column}: 1 value(s) out of range; "
                                                     f"allowed: {lo:g} ≤ {column} ≤ {hi:g}"), errs


def test_a_range_message_counts_the_bad_rows_and_shows_the_first_with_its_unit():
    runs = table(row(alt_ft=20000.0), row(alt_ft=50000.0), row(alt_ft=-10.0))
    (err,) = errors_of(runs)
    assert err.startswith("alt_ft: 2 value(s) out of range; allowed: 0 ≤ alt_ft ≤ 45000 ft "
                          "(first: ")
    assert first_value(err) == 50000.0
    # a value that is no number at all is out of range too
    (err,) = errors_of(table(row(vcas_kt="fast")))
    assert err.startswith("vcas_kt: 1 value(s) out of range; allowed: 80 ≤ vcas_kt ≤ 400 kt "
                          "(first: ")
    assert np.isnan(first_value(err))


@pytest.mark.parametrize("column, bad, hint", [
    ("surface", "elevatr", "did you mean 'elevator'"),
    ("manoeuvre", "nose-up", "did you mean 'nose_up'"),
    ("fault", "hardovr", "did you mean 'hardover'"),
])
def test_an_unknown_name_is_refused_with_the_allowed_ones(column, bad, hint):
    errs = errors_of(table(row(**{column: bad}, onset_s=10.0)))
    assert len(errs) == 1
    assert errs[0].startswith(f"{column}: unknown value {bad!r}") and hint in errs[0]
    assert "allowed: " in errs[0]


def test_the_allowed_surfaces_are_the_callers():
    runs = table(row(surface="aileron"))
    assert errors_of(runs) == []
    with pytest.raises(RunSpecError,
                       match="surface: unknown value 'aileron'.*allowed: left, right"):
        validate_runs(runs, surfaces=("left", "right"))
    validate_runs(table(row(surface="left")), surfaces=("left", "right"))


def test_missing_columns_and_an_empty_table_are_refused_first():
    runs = table().drop(columns=["cg_pct", "d_kci"])
    with pytest.raises(RunSpecError) as info:
        validate_runs(runs)
    assert len(info.value.errors) == 1
    assert info.value.errors[0].startswith("missing column(s) ['cg_pct', 'd_kci']")
    with pytest.raises(RunSpecError, match="the run table is empty"):
        validate_runs(table().iloc[:0])


def test_a_batch_shares_one_surface_and_one_duration():
    same = table(row(run_id="a"), row(run_id="b"))
    assert errors_of(same) == []
    for over in ({"surface": "aileron"}, {"duration_s": 40.0}):
        errs = errors_of(table(row(run_id="a"), row(run_id="b", **over)))
        assert errs == ["a batch must share one surface and one duration_s; split it first"]


def test_the_onset_of_a_faulty_run_lies_in_zero_to_the_duration():
    """[0, duration_s): an onset at 0 s is a fault from the first step, one at the duration
    would never act."""
    ok = dict(fault="solid_jam", duration_s=30.0)
    for onset in (0.0, 15.0, 30.0 - EPS):
        assert errors_of(table(row(onset_s=onset, **ok))) == [], onset
    for onset in (-EPS, 30.0, 31.0, np.nan, np.inf):
        errs = errors_of(table(row(onset_s=onset, **ok)))
        assert len(errs) == 1 and errs[0].startswith(
            "onset_s: 1 faulty run(s) with an onset outside [0, duration_s)"), (onset, errs)
    (err,) = errors_of(table(row(onset_s=30.0, **ok), row(onset_s=-2.0, **ok)))
    assert err.startswith("onset_s: 2 faulty run(s) with an onset outside [0, duration_s) "
                          "(first: ") and err.endswith(" s)")
    assert first_value(err) == 30.0
    # a fault-free run has no onset: NaN (or any value) is not looked at
    assert errors_of(table(row(fault="none", onset_s=np.nan),
                           row(fault="none", onset_s=99.0))) == []


@pytest.mark.parametrize("fault", ["runaway", "hardover", "liquid_jam", "ofc_liquid", "ofc_solid"])
def test_a_fault_with_a_magnitude_needs_a_finite_one(fault):
    extra = {"freq_hz": 1.0} if fault.startswith("ofc") else {}
    good = row(fault=fault, onset_s=10.0, magnitude=-1.0, **extra)
    assert errors_of(table(good)) == []
    for mag in (np.nan, np.inf):
        errs = errors_of(table(good, {**good, "magnitude": mag}))
        assert errs == [f"magnitude: 1 run(s) of fault types ['{fault}'] need a finite magnitude"]


@pytest.mark.parametrize("fault", ["none", "solid_jam", "disconnection"])
def test_a_fault_without_a_magnitude_takes_none(fault):
    onset = np.nan if fault == "none" else 10.0
    assert errors_of(table(row(fault=fault, onset_s=onset, magnitude=np.nan))) == []


@pytest.mark.parametrize("fault", ["ofc_liquid", "ofc_solid"])
def test_an_oscillatory_failure_needs_a_positive_frequency(fault):
    base = dict(fault=fault, onset_s=10.0, magnitude=1.0)
    for freq in (1e-3, 1.0, 20.0):
        assert errors_of(table(row(freq_hz=freq, **base))) == [], freq
    for freq in (0.0, -1.0, np.nan, np.inf):
        errs = errors_of(table(row(freq_hz=freq, **base)))
        assert errs == ["freq_hz: 1 OFC run(s) need a positive frequency"], (freq, errs)
    # other faults carry no frequency
    assert errors_of(table(row(fault="runaway", onset_s=10.0, magnitude=2.0, freq_hz=np.nan))) == []


def test_a_fixed_manoeuvre_start_lies_in_zero_to_the_duration():
    for start in (0.0, 12.0, 30.0 - EPS, np.nan):
        assert errors_of(table(row(manoeuvre_start_s=start))) == [], start
    for start in (-EPS, 30.0, 45.0):
        errs = errors_of(table(row(manoeuvre_start_s=start)))
        assert len(errs) == 1 and errs[0].startswith(
            "manoeuvre_start_s: 1 run(s) with a start outside [0, duration_s)"), (start, errs)
    (err,) = errors_of(table(row(manoeuvre_start_s=30.0), row(manoeuvre_start_s=-1.0)))
    assert err.startswith("manoeuvre_start_s: 2 run(s) with a start outside [0, duration_s) "
                          "(first: ") and err.endswith(" s)")
    assert first_value(err) == 30.0


def test_an_unknown_manoeuvre_set_is_refused_with_the_allowed_ones():
    assert errors_of(table(row(manoeuvre_set="stress"), row(manoeuvre_set="normal"))) == []
    errs = errors_of(table(row(manoeuvre_set="stres")))
    assert errs == ["manoeuvre_set: unknown value 'stres' (did you mean 'stress'?); "
                    "allowed: normal, stress"]


def test_every_problem_is_listed_at_once_in_the_error():
    runs = table(row(surface="elevatr", manoeuvre="nose-up", alt_ft=-1.0, fault="ofc_solid",
                     onset_s=40.0, magnitude=np.nan, freq_hz=0.0, manoeuvre_start_s=-1.0,
                     manoeuvre_set="hard"))
    errs = errors_of(runs)
    heads = [e.split(":")[0] for e in errs]
    assert heads == ["surface", "manoeuvre", "alt_ft", "onset_s", "magnitude", "freq_hz",
                     "manoeuvre_start_s", "manoeuvre_set"]
    with pytest.raises(RunSpecError) as info:
        validate_runs(runs)
    assert str(info.value) == "invalid run table:\n  - " + "\n  - ".join(errs)


def test_the_error_survives_pickling_with_its_list():
    """A worker process sends the error back to the parent pickled."""
    err = pickle.loads(pickle.dumps(RunSpecError(["a", "b"])))
    assert isinstance(err, RunSpecError) and err.errors == ["a", "b"]
    assert str(err) == "invalid run table:\n  - a\n  - b"


def test_manoeuvre_set_of_each_row():
    assert manoeuvre_sets(table(row(), row(), row())) == ["normal"] * 3
    assert DEFAULT_MANOEUVRE_SET == "normal"
    runs = table(row(manoeuvre_set="stress"), row(manoeuvre_set="normal"))
    assert manoeuvre_sets(runs) == ["stress", "normal"]


def test_run_streams_are_the_two_children_of_the_run_seed_sequence():
    man, sens = run_streams(np.int64(3), np.float64(9.0))      # table dtypes are accepted
    a, b = np.random.SeedSequence(3, spawn_key=(9,)).spawn(2)
    assert man.integers(2**62) == np.random.default_rng(a).integers(2**62)
    assert sens.integers(2**62) == np.random.default_rng(b).integers(2**62)


def test_flight_of_passes_the_true_point_and_the_measured_schedule():
    f = {c: np.array([0.0, 0.01]) for c in RUN_COLUMNS if c.startswith("d_")}
    f.update(alt_ft=np.array([10000.0, 30000.0]), vcas_kt=np.array([250.0, 300.0]),
             mass_t=np.array([150.0, 200.0]), cg_pct=np.array([25.0, 35.0]),
             d_alt=np.array([0.02, -0.03]), d_vcas=np.array([-0.01, 0.04]),
             d_mass=np.array([0.05, -0.06]), d_cg=np.array([0.07, -0.08]))
    flight, schedule = flight_of(f)
    truth = envelope.flight_condition(f["alt_ft"], f["vcas_kt"], f["mass_t"], f["cg_pct"])
    for key in ("alt_ft", "vcas_kt", "mass_t", "cg_pct"):
        np.testing.assert_array_equal(flight[key], f[key])
    for key, value in truth.items():
        np.testing.assert_array_equal(flight[key], value)
    expected = envelope.measured_schedule(f["alt_ft"], f["vcas_kt"], f["mass_t"], f["cg_pct"],
                                          f["d_alt"], f["d_vcas"], f["d_mass"], f["d_cg"])
    assert set(schedule) == set(expected)
    for key in expected:
        np.testing.assert_array_equal(schedule[key], expected[key])


def test_the_draw_groups_pick_their_columns():
    f = {c: float(i) for i, c in enumerate(RUN_COLUMNS)}
    assert PLANT_DRAWS == ("d_ch0", "d_cha", "d_chd", "d_supply", "d_kci")
    assert plant_draws(f) == {c: f[c] for c in PLANT_DRAWS}
    assert aero_draws(f) == {c: f[f"d_{c}"] for c in ("cx", "cy", "cz", "cl", "cm", "cn")}
