"""campaign/evidence/certify/rows.py by value: what certify keeps of hand-made result rows, fed
whole or in batches — the fault-free runs' margins, manoeuvres, durations (from the plan by
``plan_pos``, NaN for a run the plan does not hold) and false-alarm count, the faulty runs'
counts of misses and of misses or late detections (DTP > 1, the boundary itself on time),
and the detectors' order (docs/evidence.md; docs/execution.md, "Memory independent of the
number of runs")."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pandas as pd
import pytest

from campaign.evidence.certify.rows import CERTIFY_COLUMNS, CertifyRows


def rows(**columns) -> pd.DataFrame:
    """Result rows with the columns given (lists of one length)."""
    return pd.DataFrame(columns)


#: Eight result rows of two detectors: four fault-free runs ("a": two ok in cruise and one
#: in nose_up, one failed; "b" one ok), four faulty ones with DTP on both sides of 1.
TABLE = rows(
    run_id=["r0", "r1", "r2", "r3", "r4", "r5", "r6", "r7"],
    detector=["a", "a", "a", "a", "b", "a", "a", "a"],
    fault=["none", "none", "none", "none", "none", "runaway", "runaway", "jam"],
    manoeuvre=["cruise", "nose_up", "cruise", "cruise", "cruise", "cruise", "cruise", "cruise"],
    status=["ok", "ok", "ok", "error", "ok", "ok", "ok", "ok"],
    margin=[0.25, 1.5, 0.75, 9.0, 2.0, 3.0, 4.0, 5.0],
    false_alarm=[False, True, False, True, True, False, False, False],
    detected=[False, False, False, False, False, True, True, False],
    dtp=[np.nan, np.nan, np.nan, np.nan, np.nan, 1.0, 1.0 + 1e-9, np.nan],
)
PLAN = pd.DataFrame({"run_id": ["r0", "r1", "r2", "r3", "r4", "r5", "r6", "r7"],
                     "duration_s": [10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0]})


def test_the_columns_certify_reads():
    assert CERTIFY_COLUMNS == ("fault", "manoeuvre", "status", "margin", "false_alarm",
                               "detected", "dtp")


def test_the_fault_free_ok_runs_of_each_detector_with_their_plan_durations():
    r = CertifyRows.of_table(TABLE, PLAN)
    assert r.free_names() == ["a", "b"] and r.ok_names() == ["a", "b"]
    a = r.free("a")
    # the failed run r3 (margin 9, an alarm) is left out; the plan's durations by run id
    np.testing.assert_array_equal(a.margin, [0.25, 1.5, 0.75])
    assert a.manoeuvre.tolist() == ["cruise", "nose_up", "cruise"]
    np.testing.assert_array_equal(a.duration_s, [10.0, 20.0, 30.0])
    assert a.false_alarms == 1
    with pytest.raises(dataclasses.FrozenInstanceError):     # a detector's runs, read-only
        a.false_alarms = 0
    b = r.free("b")
    assert (b.margin.tolist(), b.manoeuvre.tolist(), b.duration_s.tolist(), b.false_alarms) \
        == ([2.0], ["cruise"], [50.0], 1)


def test_a_faulty_run_detected_at_dtp_1_is_on_time_and_just_after_it_late():
    """docs/evidence.md: late = detected with DTP > 1; a miss counts on both sides."""
    r = CertifyRows.of_table(TABLE, PLAN)
    # runaway: r5 detected at DTP = 1 (on time), r6 at 1 + 1e-9 (late); jam: r7 missed
    assert r.faulty("a") == {"jam": (1, 1, 1), "runaway": (2, 0, 1)}
    assert list(r.faulty("a")) == ["jam", "runaway"]          # fault types sorted
    assert r.faulty("b") == {}                                 # ok runs, none of them faulty
    assert r.faulty("nobody") == {}


def test_without_a_plan_the_durations_are_nan():
    a = CertifyRows.of_table(TABLE).free("a")
    assert np.isnan(a.duration_s).all() and a.duration_s.shape == (3,)


def test_an_empty_table_or_one_without_ok_rows_has_no_detector():
    assert CertifyRows.of_table(TABLE.iloc[:0], PLAN).free_names() == []
    r = CertifyRows.of_table(TABLE[TABLE["status"] != "ok"], PLAN)
    assert r.free_names() == [] and r.ok_names() == []


def test_batches_give_what_the_whole_table_gives_with_durations_by_plan_position():
    """Batches of whole runs in plan order, with the plan's durations by ``plan_pos``; a
    position of −1 (a row the plan does not hold) gets NaN."""
    durations = PLAN["duration_s"].to_numpy()
    batched = CertifyRows(durations)
    pos = np.arange(len(TABLE))
    pos[2] = -1
    table = TABLE.assign(plan_pos=pos)
    for part in (table.iloc[:1], table.iloc[1:3], table.iloc[3:5], table.iloc[5:]):
        batched.add(part)
    a = batched.free("a")
    np.testing.assert_array_equal(a.margin, [0.25, 1.5, 0.75])
    np.testing.assert_array_equal(a.duration_s, [10.0, 20.0, np.nan])
    assert a.manoeuvre.tolist() == ["cruise", "nose_up", "cruise"] and a.false_alarms == 1
    assert batched.faulty("a") == {"jam": (1, 1, 1), "runaway": (2, 0, 1)}
    # read twice: the parts joined once give the same arrays again
    np.testing.assert_array_equal(batched.free("a").margin, [0.25, 1.5, 0.75])
    # a plan-less reader of the same batches has no durations
    plain = CertifyRows()
    plain.add(table)
    assert np.isnan(plain.free("a").duration_s).all()


def test_the_faulty_counts_add_up_over_batches():
    r = CertifyRows()
    for dtp, detected in ((0.5, True), (2.0, True), (np.nan, False), (1.5, True),
                          (np.nan, False)):
        r.add(rows(run_id=["x"], detector=["a"], fault=["runaway"], manoeuvre=["cruise"],
                   status=["ok"], margin=[1.0], false_alarm=[False], detected=[detected],
                   dtp=[dtp]))
    # five runs, two missed, two late
    assert r.faulty("a") == {"runaway": (5, 2, 4)}
    assert r.ok_names() == ["a"] and r.free_names() == []


def test_rows_without_an_alarm_column_have_no_count_and_without_margin_nan():
    """A table of margins alone (a brute-force check of the curve): one class, no alarm
    count; one of alarms alone (the hazard's): no margin."""
    margins = CertifyRows.of_table(rows(detector=["d", "d"], fault=["none", "none"],
                                        status=["ok", "ok"], margin=[0.5, 1.5]))
    d = margins.free("d")
    assert d.false_alarms is None and d.manoeuvre.tolist() == ["", ""]
    np.testing.assert_array_equal(d.margin, [0.5, 1.5])
    alarms = CertifyRows.of_table(rows(detector=["d", "d"], fault=["none", "none"],
                                       status=["ok", "ok"], manoeuvre=["m", "m"],
                                       false_alarm=[True, True]))
    d = alarms.free("d")
    assert d.false_alarms == 2 and np.isnan(d.margin).all()
    # a batch without the alarm column makes the whole count unknown, whatever came before
    mixed = CertifyRows()
    mixed.add(rows(detector=["d"], fault=["none"], status=["ok"], margin=[0.5],
                   false_alarm=[True]))
    assert mixed.free("d").false_alarms == 1
    mixed.add(rows(detector=["d"], fault=["none"], status=["ok"], margin=[0.7]))
    mixed.add(rows(detector=["d"], fault=["none"], status=["ok"], margin=[0.9],
                   false_alarm=[True]))
    assert mixed.free("d").false_alarms is None


def test_manoeuvre_codes_are_shared_between_detectors_and_batches():
    """Each manoeuvre label is stored once as a code; the labels read back are the ones
    written, whichever detector or batch saw a label first."""
    r = CertifyRows()
    r.add(rows(detector=["a", "b"], fault=["none", "none"], status=["ok", "ok"],
               manoeuvre=["m1", "m2"], margin=[0.1, 0.2], false_alarm=[False, False]))
    r.add(rows(detector=["b", "a", "a"], fault=["none"] * 3, status=["ok"] * 3,
               manoeuvre=["m3", "m2", "m1"], margin=[0.3, 0.4, 0.5],
               false_alarm=[False, True, True]))
    assert r.free("a").manoeuvre.tolist() == ["m1", "m2", "m1"]
    assert r.free("b").manoeuvre.tolist() == ["m2", "m3"]
    assert (r.free("a").false_alarms, r.free("b").false_alarms) == (2, 0)
    np.testing.assert_array_equal(r.free("b").margin, [0.2, 0.3])


def test_detectors_in_the_one_order_of_every_output():
    """By name, the numbers in a name by value (reports.scoring.summary.detector_order),
    the fault-free ones apart from those with any ok run."""
    r = CertifyRows.of_table(rows(
        detector=["d[10]", "d[9]", "c", "z"], fault=["none", "none", "none", "jam"],
        status=["ok"] * 4, manoeuvre=["m"] * 4, margin=[0.1] * 4, false_alarm=[False] * 4,
        detected=[True] * 4, dtp=[0.5] * 4))
    assert r.free_names() == ["c", "d[9]", "d[10]"]
    assert r.ok_names() == ["c", "d[9]", "d[10]", "z"]


def test_durations_from_the_plan_by_run_id_nan_for_a_run_it_lacks():
    plan = PLAN[PLAN["run_id"] != "r1"]
    a = CertifyRows.of_table(TABLE, plan).free("a")
    assert a.duration_s[0] == 10.0 and math.isnan(a.duration_s[1]) and a.duration_s[2] == 30.0


@pytest.mark.parametrize("batch_runs", [None, 1])
def test_of_campaign_reads_the_result_batches_with_the_plan_durations(batch_runs):
    """:meth:`CertifyRows.of_campaign` asks for the certify columns with positions, in
    batches of *batch_runs* runs when given, and maps the plan's durations by position."""
    asked = []

    class Campaign:
        def plan_column(self, name):
            assert name == "duration_s"
            return PLAN["duration_s"].to_numpy()

        def result_batches(self, columns, positions, **kwargs):
            asked.append((columns, positions, kwargs))
            table = TABLE.assign(plan_pos=np.arange(len(TABLE)))
            step = kwargs.get("batch_runs", len(TABLE))
            for i in range(0, len(table), step):
                yield table.iloc[i:i + step]

    r = CertifyRows.of_campaign(Campaign(), batch_runs=batch_runs)
    want = {} if batch_runs is None else {"batch_runs": 1}
    assert asked == [(list(CERTIFY_COLUMNS), True, want)]
    np.testing.assert_array_equal(r.free("a").duration_s, [10.0, 20.0, 30.0])
    assert r.faulty("a") == {"jam": (1, 1, 1), "runaway": (2, 0, 1)}
