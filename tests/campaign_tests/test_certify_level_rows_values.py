"""campaign/evidence/certify/levels.py by value: the default levels and their parsing, the
runs and subset-simulation levels a bound needs, and the rows of one detector on the paths a
campaign takes (no finite margin, one run, a pooled count, a mixture with a counted class, a
point estimate and a bound below what the runs carry); docs/evidence.md."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from campaign.evidence.certify.levels import (
    DEFAULT_LEVELS,
    EXTRAPOLATION_DECADES,
    LEVEL_COLUMNS,
    detector_rows,
    level_table,
    parse_levels,
    runs_to_carry,
    sampling_levels_to_reach,
)
from campaign.evidence.rare import P0
from reports.scoring.metrics import upper_bound


def maxima(seed: int, n: int, scale: float) -> np.ndarray:
    """Fault-free margins of *n* runs: the maximum of 100 Gaussian samples × *scale*."""
    return np.random.default_rng(seed).standard_normal((n, 100)).max(axis=1) * scale


def test_the_default_levels_and_a_zero_margin_refused():
    # docs/evidence.md: the curve at margins 0.6 to 1.0 by tenths, 1.0 the false alarm
    assert DEFAULT_LEVELS == (0.6, 0.7, 0.8, 0.9, 1.0)
    assert parse_levels("1, 0.6,0.6") == (0.6, 1.0)
    assert parse_levels("1e-9") == (1e-9,)
    with pytest.raises(ValueError, match="0.0 is not a positive margin"):
        parse_levels("0,1")


def test_the_runs_that_carry_a_bound():
    """n ≥ ln(1 − c)/ln(1 − 10^D·p), at least one run; one run when 10^D·p ≥ 1."""
    assert EXTRAPOLATION_DECADES == 2
    assert runs_to_carry(0.02) == 1 and runs_to_carry(0.01) == 1
    assert runs_to_carry(0.0099) == 1                 # the formula gives 0.65: one run
    assert runs_to_carry(0.005) == 5                  # ln 0.05 / ln 0.5 = 4.32
    want = math.ceil(math.log(0.05) / math.log(1.0 - 1e-4))
    assert runs_to_carry(1e-6) == want == 29956       # about 3/(100 p)


def test_the_levels_of_subset_simulation_to_reach_a_probability():
    """⌈log p / log p0⌉ levels of p0 = 0.1, at least one."""
    assert P0 == 0.1
    assert sampling_levels_to_reach(0.5) == 1
    assert sampling_levels_to_reach(0.1) == 1         # exactly one level (the 1e-9 guard)
    assert sampling_levels_to_reach(0.05) == 2
    assert sampling_levels_to_reach(1e-12) == 12


def test_no_finite_margin_gives_a_row_per_level_saying_so():
    rows = detector_rows("d", [np.nan, np.inf], ["a", "a"], [0.6, 1.0])
    assert [(r["level"], r["method"], r["n_runs"], r["n_exceed"]) for r in rows] == \
        [(0.6, "none", 0, 0), (1.0, "none", 0, 0)]
    assert all(math.isnan(r["p_upper95"]) and r["note"] == "no fault-free run with a finite "
               "margin" for r in rows)


def test_one_finite_margin_is_one_run_counted():
    (row,) = detector_rows("d", [0.7, np.nan], ["a", "a"], [0.5])
    assert (row["method"], row["n_runs"], row["n_exceed"]) == ("mixture", 1, 1)
    assert row["p_upper95"] == pytest.approx(float(upper_bound(1, 1, 0.95)), rel=1e-12)


def test_a_pooled_count_is_reported_as_counted_with_its_count():
    """Two counted manoeuvres of five runs each: the pooled Clopper–Pearson bound of 4 of 10
    is below the mixture of the two, so the row is counted and says how many runs."""
    m = np.array([0.1, 0.6, 0.7, 0.2, 0.9, 0.3, 0.55, 0.4, 0.1, 0.2])
    (row,) = detector_rows("d", m, np.array(["a", "b"] * 5), [0.5])
    assert (row["method"], row["n_exceed"], row["p_estimate"]) == ("counted", 4, 0.4)
    assert row["p_upper95"] == pytest.approx(float(upper_bound(4, 10, 0.95)), rel=1e-12)
    assert row["note"] == "4 of 10 runs at or above 0.5 (exact Clopper–Pearson bound)"


def test_a_mixture_names_its_fitted_and_its_counted_manoeuvres():
    """300 taxi runs (a tail fit) and 10 climb runs (too few: counted) at level 1.0."""
    m = np.concatenate([maxima(3, 300, 1 / 4), maxima(4, 10, 1 / 2)])
    cls = np.array(["taxi"] * 300 + ["climb"] * 10)
    (row,) = detector_rows("d", m, cls, [1.0])
    assert row["method"] == "mixture" and row["tail_class"] == "taxi"
    assert row["note"] == ("mixture of 2 manoeuvres by their shares of the runs; tail fits "
                           "for taxi (largest term first), 1 counted")


def test_an_estimate_below_what_the_runs_carry_is_not_given():
    """No run reaches 1.0: the tail fit's estimate lies below the counting bound / 10², so it
    is left out (NaN) with a note, and its bound, above that limit, is given."""
    (row,) = detector_rows("d", maxima(3, 300, 1 / 8), np.array(["taxi"] * 300), [1.0])
    limit = float(upper_bound(0, 300, 0.95)) / 100.0
    assert row["n_exceed"] == 0 and math.isnan(row["p_estimate"])
    assert limit < row["p_upper95"] == row["p_model_upper95"] < 1e-3
    assert row["note"].endswith(f"; point estimate below the limit {limit:.2g} (not given)")


def test_a_bound_below_what_the_runs_carry_is_raised_to_their_limit():
    """Far below the level, the tail model's bound is more than two decades under the
    counting bound: the row gives the limit of the runs and says what would carry it."""
    (row,) = detector_rows("d", maxima(3, 300, 1 / 16), np.array(["taxi"] * 300), [1.0])
    limit = float(upper_bound(0, 300, 0.95)) / 100.0
    assert row["method"] == "limit of the runs"
    assert row["p_upper95"] == limit and row["p_model_upper95"] < limit
    assert "cannot carry it, the bound given is their limit" in row["note"]


def test_an_empty_table_keeps_its_integer_columns():
    """A campaign without fault-free rows gives an empty table whose counts are still
    integers (the parquet schema of certificate-levels.parquet does not depend on the rows)."""
    table = level_table(pd.DataFrame())
    assert len(table) == 0 and list(table.columns) == list(LEVEL_COLUMNS)
    assert [str(table[c].dtype) for c in ("n_runs", "n_exceed")] == ["int64", "int64"]
