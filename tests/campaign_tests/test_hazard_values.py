"""campaign/evidence/hazard.py by value, on the paths test_hazard.py does not take: the
exposure model at its edges (a probability of 1, a duration of 0), the in-time reading of
the total and of each fault type with its claim, a fault mode of rate 0 in the table, where
the total's rate comes from, and the credit at each pair of neighbouring categories
(docs/evidence.md, "Hazard per flight hour")."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from campaign.evidence.hazard import (
    DEFAULT_FAULT_RATES_PER_FH,
    RATE_GIVEN,
    RATE_PLACEHOLDER,
    credit,
    hazard_table,
    per_hour,
)
from reports.scoring.metrics import upper_bound


def faulty(fault: str, n: int, missed: int = 0, late: int = 0) -> pd.DataFrame:
    """*n* faulty runs of detector "d": the first *missed* never detected, the next *late*
    detected after the required time (DTP 1.5), the others in time (DTP 0.5)."""
    i = np.arange(n)
    detected = i >= missed
    dtp = np.where(~detected, np.nan, np.where(i < missed + late, 1.5, 0.5))
    return pd.DataFrame({"run_id": [f"{fault}-{k}" for k in i], "detector": "d",
                         "fault": fault, "status": "ok", "detected": detected, "dtp": dtp,
                         "false_alarm": False})


def test_the_exposure_model_at_its_edges():
    """λ = −ln(1 − p)/d [1/h]; a run that surely alarms gives an infinite rate, a zero,
    unknown or infinite probability or duration none."""
    assert per_hour(0.5, 2.0) == pytest.approx(math.log(2.0) / 2.0, rel=1e-15)
    assert per_hour(1.0, 2.0) == math.inf
    assert per_hour(1.0 - 1e-12, 1.0) == pytest.approx(-math.log(1e-12), rel=1e-3)
    assert per_hour(0.0, 1.0) == 0.0
    for p, d in ((0.1, 0.0), (0.1, -1.0), (0.1, math.nan), (math.nan, 1.0), (math.inf, 1.0)):
        assert math.isnan(per_hour(p, d)), (p, d)


def test_the_in_time_reading_of_each_fault_and_of_the_total():
    """runaway and solid_jam, 20 runs each at 1e-6/FH: 15 detected late of runaway's, 14
    of solid_jam's (none missed). In time each bound is above 1/2: not shown; so is the
    total's Σ λ_f P_f^up / Σ λ_f with each P_f^up at 1 − 0.05/2 (Bonferroni over two)."""
    results = pd.concat([faulty("runaway", 20, late=15), faulty("solid_jam", 20, late=14)])
    h = hazard_table(results, None, DEFAULT_FAULT_RATES_PER_FH).set_index("fault")
    alone = "met by the fault rate alone (major), no credit"
    for fault, late in (("runaway", 15), ("solid_jam", 14)):
        up = float(upper_bound(late, 20, 0.95))
        r = h.loc[fault]
        assert (r["late_or_missed"], r["events"]) == (late, 0)
        assert r["in_time_per_fh_upper95"] == pytest.approx(1e-6 * up, rel=1e-12)
        assert r["claim_in_time"] == (f"{alone}; not shown: the undetected-probability bound "
                                      f"{up:.3g} is above 0.5")
        assert r["credited_in_time"] == "none" and r["meets_in_time"] == "major"
    joint = [float(upper_bound(late, 20, 0.975)) for late in (15, 14)]
    total = h.loc["all"]
    assert total["late_or_missed"] == 29 and total["rate_per_fh"] == pytest.approx(2e-6)
    assert total["in_time_per_fh_upper95"] == pytest.approx(1e-6 * sum(joint), rel=1e-12)
    p_in = sum(joint) / 2
    assert total["claim_in_time"] == (f"{alone}; not shown: the undetected-probability "
                                      f"bound {p_in:.3g} is above 0.5")
    # none missed: without the late ones the total is shown, and in the category of the
    # rate alone
    up = sum(float(upper_bound(0, 20, 0.975)) for _ in range(2)) * 1e-6
    assert total["per_fh_upper95"] == pytest.approx(up, rel=1e-12)
    assert total["claim"] == (f"{alone}; not shown: with the detector ≤ {up:.3g}/FH, the "
                              "category of the fault rate alone (major)")


def test_a_fault_mode_of_rate_zero_is_never_credited_and_leaves_the_total_alone():
    results = pd.concat([faulty("runaway", 10), faulty("solid_jam", 300)])
    h = hazard_table(results, None, {"runaway": 0.0, "solid_jam": 1e-6}).set_index("fault")
    zero = ("met by the fault rate alone (catastrophic), no credit; fault rate 0 (the mode "
            "cannot occur)")
    r = h.loc["runaway"]
    assert (r["per_fh_upper95"], r["in_time_per_fh_upper95"]) == (0.0, 0.0)
    assert (r["credited"], r["claim"], r["credited_in_time"], r["claim_in_time"]) == \
        ("none", zero, "none", zero)
    assert r["rate_source"] == RATE_GIVEN                       # 0 is not the default
    # the total: Bonferroni over the one type with a positive rate, at 95 % then
    up = 1e-6 * float(upper_bound(0, 300, 0.95))
    t = h.loc["all"]
    assert t["per_fh_upper95"] == pytest.approx(up, rel=1e-12)
    assert t["in_time_per_fh_upper95"] == pytest.approx(up, rel=1e-12)
    assert (t["credited"], t["credited_in_time"]) == ("hazardous", "hazardous")
    assert t["claim"] == (f"credited hazardous: ≤ {up:.3g}/FH with the detector, 1e-06/FH "
                          "(major) without")
    # every rate 0: the total cannot occur either
    only = hazard_table(faulty("runaway", 10), None, {"runaway": 0.0}).set_index("fault")
    assert (only.loc["all", "claim"], only.loc["all", "claim_in_time"]) == (zero, zero)
    assert only.loc["all", "rate_source"] == RATE_GIVEN


@pytest.mark.parametrize("rates, source", [
    ({"runaway": 2e-6, "solid_jam": 3e-6}, RATE_GIVEN),
    ({"runaway": 1e-6, "solid_jam": 3e-6}, f"partly {RATE_PLACEHOLDER} (runaway)"),
    ({"runaway": 1e-6, "solid_jam": 0.0}, RATE_PLACEHOLDER),
    ({"runaway": 1e-6, "solid_jam": 1e-6}, RATE_PLACEHOLDER),
])
def test_where_the_totals_rate_comes_from(rates, source):
    """The total's rate is the file's when every positive rate is, a placeholder when none
    is, and partly a placeholder (naming the fault types) otherwise; a rate of 0 counts for
    neither."""
    results = pd.concat([faulty("runaway", 10), faulty("solid_jam", 10)])
    h = hazard_table(results, None, rates).set_index("fault")
    assert h.loc["all", "rate_source"] == source
    for fault, lam in rates.items():
        want = RATE_PLACEHOLDER if lam == DEFAULT_FAULT_RATES_PER_FH[fault] else RATE_GIVEN
        assert h.loc[fault, "rate_source"] == want


def test_the_credit_at_each_pair_of_neighbouring_categories():
    """A detector is credited the category its bound reaches when the fault rate alone is
    in a less severe one: none → major, major → hazardous, hazardous → catastrophic; the
    main reading's claim never says "in time"."""
    assert credit(300, 0, 0.0099, 1e-3, 9.9e-6) == (
        "major", "credited major: ≤ 9.9e-06/FH with the detector, 0.001/FH (none) without")
    assert credit(300, 0, 0.0099, 1e-6, 9.9e-9)[0] == "hazardous"
    assert credit(300, 0, 0.0099, 1e-7, 9.9e-10) == (
        "catastrophic", "credited catastrophic: ≤ 9.9e-10/FH with the detector, 1e-07/FH "
        "(hazardous) without")
    assert credit(20, 20, 1.0, 1e-3, 1e-3) == ("none", "no credit: detected none of its 20 "
                                                       "runs")
    assert credit(20, 20, 1.0, 1e-3, 1e-3, in_time=True) == (
        "none", "no credit: detected none of its 20 runs in time")
    assert credit(0, 0, math.nan, 1e-6, math.nan) == ("n/a", "no run")


def test_the_false_alarm_row_and_the_level_limits():
    """The fault-free runs' row: k/n and its bound turned into rates per hour (runs of
    36 s, 0.01 h); the level is a confidence strictly between 1/2 and 1."""
    free = pd.DataFrame({"run_id": [f"f{i}" for i in range(40)], "detector": "d",
                         "fault": "none", "status": "ok", "detected": False, "dtp": np.nan,
                         "false_alarm": np.arange(40) < 3})
    plan = pd.DataFrame({"run_id": free["run_id"], "duration_s": 36.0})
    row = hazard_table(free, plan, {}, 0.9).set_index("fault").loc["none"]
    up = float(upper_bound(3, 40, 0.9))
    assert (row["n_runs"], row["events"], row["late_or_missed"]) == (40, 3, 3)
    assert row["p_run"] == 3 / 40 and row["p_run_upper95"] == pytest.approx(up, rel=1e-12)
    assert row["per_fh"] == pytest.approx(-math.log1p(-3 / 40) / 0.01, rel=1e-12)
    assert row["per_fh_upper95"] == pytest.approx(-math.log1p(-up) / 0.01, rel=1e-12)
    assert row["level"] == 0.9
    for level in (0.5, 1.0):
        with pytest.raises(ValueError, match=f"level {level!r} must be a confidence in "
                                             r"\(0.5, 1\)"):
            hazard_table(free, plan, {}, level)
    assert hazard_table(free, plan, {}, 0.5 + 1e-9)["level"].tolist() == [0.5 + 1e-9]


def test_a_fault_detected_only_late_is_credited_nothing_in_time():
    h = hazard_table(faulty("runaway", 10, late=10), None,
                     DEFAULT_FAULT_RATES_PER_FH).set_index("fault")
    for fault in ("runaway", "all"):
        assert h.loc[fault, "claim_in_time"] == ("met by the fault rate alone (major), no "
                                                 "credit; detected none of its 10 runs in "
                                                 "time")
        assert "in time" not in h.loc[fault, "claim"]


def test_one_run_is_a_row_to_judge():
    """A single run is judged (its bound, 0.95, shows nothing); no run is "n/a"."""
    assert credit(1, 0, 0.95, 1e-3, 9.5e-4) == (
        "none", "no credit: not shown: the undetected-probability bound 0.95 is above 0.5")


def test_an_unknown_bound_credits_nothing():
    """A bound with the detector that is not a number reaches no category: nothing is
    credited, whatever the fault rate alone meets."""
    assert credit(10, 0, 0.1, 1e-3, math.nan) == (
        "none", "no credit: not shown: with the detector ≤ nan/FH, the category of the fault "
        "rate alone (none)")
    assert credit(10, 0, 0.1, 1e-6, math.nan)[0] == "none"


def test_a_table_without_ok_runs_is_empty_with_its_integer_columns():
    table = hazard_table(faulty("runaway", 3).assign(status="error"), None,
                         DEFAULT_FAULT_RATES_PER_FH)
    assert table.empty
    for c in ("n_runs", "events", "late_or_missed"):
        assert table[c].dtype == np.int64, c
