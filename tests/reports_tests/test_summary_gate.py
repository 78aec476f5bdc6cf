"""Summary counts, rates, bounds and DTP statistics; the gate, its JUnit file and the table."""

import pickle
import xml.etree.ElementTree as ET

import numpy as np
import pandas as pd
import pytest

from reports.scoring.gate import Check, GateInputError, GateResult, evaluate_gate, write_junit
from reports.scoring.metrics import ESTIMATE_COLUMNS, RESULT_COLUMNS, upper_bound
from reports.scoring.summary import SUMMARY_COLUMNS, summarize
from reports.render.table import format_table

DET = "position-monitor"
MANOEUVRES = ("cruise", "nose_up", "aoa_protection", "pitch_protection", "yaw_angle_mode",
              "turn_coordination")
# Values computed here are ratios of small integers or numpy reductions of the same numbers;
# 1e-12 relative covers floating-point rounding only.
REL = 1e-12


def fault_free(manoeuvre, n, *, alarms=0, detector=DET, margin=0.5):
    fa = np.zeros(n, dtype=bool)
    fa[:alarms] = True
    return pd.DataFrame({
        "run_id": [f"{detector}-ff-{manoeuvre}-{i}" for i in range(n)],
        "detector": detector, "fault": "none", "manoeuvre": manoeuvre, "status": "ok",
        "error": "", "false_alarm": fa, "pre_onset_alarm": fa, "detected": False,
        "first_alarm_s": np.where(fa, 12.0, np.nan), "delay_s": np.nan, "dtp": np.nan,
        "margin": np.full(n, margin),
    })


def faulty(fault, manoeuvre, dtps, *, pre_onset=(), detector=DET, margin=0.3):
    """One run per entry of ``dtps``; NaN means a miss. Required time 0.5 s, onset 20 s."""
    dtps = np.asarray(dtps, dtype=float)
    n = len(dtps)
    fa = np.zeros(n, dtype=bool)
    fa[list(pre_onset)] = True
    detected = ~np.isnan(dtps)
    return pd.DataFrame({
        "run_id": [f"{detector}-{fault}-{manoeuvre}-{i}" for i in range(n)],
        "detector": detector, "fault": fault, "manoeuvre": manoeuvre, "status": "ok",
        "error": "", "false_alarm": fa, "pre_onset_alarm": fa, "detected": detected,
        "first_alarm_s": np.where(detected, 20.0 + 0.5 * dtps, np.nan),
        "delay_s": 0.5 * dtps, "dtp": dtps, "margin": np.full(n, margin),
    })


def errors(fault, manoeuvre, n, detector=DET):
    return pd.DataFrame({
        "run_id": [f"{detector}-err-{fault}-{manoeuvre}-{i}" for i in range(n)],
        "detector": detector, "fault": fault, "manoeuvre": manoeuvre, "status": "error",
        "error": "RuntimeError: solver diverged", "false_alarm": None,
        "pre_onset_alarm": None, "detected": None, "first_alarm_s": np.nan,
        "delay_s": np.nan, "dtp": np.nan, "margin": np.nan,
    })


def campaign(*extra):
    """1200 clean fault-free runs (200 per manoeuvre, [CHEN] §5.2) and detected faults."""
    parts = [fault_free(m, 200) for m in MANOEUVRES]
    parts.append(faulty("runaway", "cruise", [0.1, 0.2, 0.3, 0.4]))
    parts.append(faulty("runaway", "nose_up", [0.2, 0.6]))
    parts.append(faulty("solid_jam", "cruise", [0.05, 0.05, 0.05]))
    out = pd.concat(parts + list(extra), ignore_index=True)
    # no detector of these rows estimates the fault: no estimation-error samples
    for column in ESTIMATE_COLUMNS:
        if column not in out.columns:
            out[column] = 0 if column == "est_err_n" else np.nan
    out["alarm_steps"] = None          # no first alarms at other scales stored
    return out


def row(summary, fault, manoeuvre, detector=DET):
    sel = summary[(summary.detector == detector) & (summary.fault == fault)
                  & (summary.manoeuvre == manoeuvre)]
    assert len(sel) == 1, (fault, manoeuvre, len(sel))
    return sel.iloc[0]


# ---- summarize ---------------------------------------------------------------------------

def test_summary_columns_rows_and_order():
    s = summarize(campaign())
    assert tuple(s.columns) == SUMMARY_COLUMNS
    keys = list(zip(s.fault, s.manoeuvre))
    # 6 fault-free manoeuvres + all; runaway 2 + all; solid_jam 1 + all; all-faults
    assert len(keys) == 7 + 3 + 2 + 1
    assert keys[:7] == [("none", m) for m in sorted(MANOEUVRES)] + [("none", "all")]
    assert keys[-1] == ("all-faults", "all")
    assert set(RESULT_COLUMNS) <= set(campaign().columns)


def test_summary_fault_free_counts_and_bounds():
    res = campaign()
    res.loc[(res.fault == "none") & (res.manoeuvre == "cruise"), "false_alarm"] = \
        [True, True] + [False] * 198
    s = summarize(res)
    r = row(s, "none", "cruise")
    assert (r.n_runs, r.fa_count) == (200, 2)
    assert r.fa_rate == pytest.approx(2 / 200, rel=REL)
    assert r.fa_upper95 == pytest.approx(upper_bound(2, 200), rel=REL)
    allff = row(s, "none", "all")
    assert (allff.n_runs, allff.fa_count) == (1200, 2)
    assert allff.fa_upper95 == pytest.approx(upper_bound(2, 1200), rel=REL)
    # fault-free rows carry no MD / DTP
    assert allff.md_count == 0 and np.isnan(allff.md_rate) and np.isnan(allff.md_upper95)
    assert np.isnan(allff.dtp_max) and np.isnan(allff.dtp_within)
    clean = row(s, "none", "nose_up")
    assert clean.fa_count == 0
    assert clean.fa_upper95 == pytest.approx(1 - 0.05 ** (1 / 200), rel=1e-10)


def test_summary_dtp_stats_with_misses():
    dtps = [0.1, 0.2, 0.3, 0.4, np.nan, 1.5]  # one miss, one late detection
    s = summarize(pd.concat([fault_free("cruise", 10), faulty("runaway", "cruise", dtps)]))
    r = row(s, "runaway", "cruise")
    detected = np.array([0.1, 0.2, 0.3, 0.4, 1.5])
    assert (r.n_runs, r.md_count) == (6, 1)
    assert r.md_rate == pytest.approx(1 / 6, rel=REL)
    assert r.md_upper95 == pytest.approx(upper_bound(1, 6), rel=REL)
    assert r.dtp_min == pytest.approx(0.1, rel=REL)
    assert r.dtp_max == pytest.approx(1.5, rel=REL)
    assert r.dtp_mean == pytest.approx(detected.mean(), rel=REL)
    assert r.dtp_p95 == pytest.approx(np.percentile(detected, 95), rel=REL)
    # the miss and the late detection are both "not within": 4 of 6
    assert r.dtp_within == pytest.approx(4 / 6, rel=REL)
    assert r.delay_mean_s == pytest.approx(0.5 * detected.mean(), rel=REL)
    # delays in seconds (required time 0.5 s here), over the detected runs only
    assert (r.delay_min_s, r.delay_max_s) == (pytest.approx(0.05, rel=REL),
                                              pytest.approx(0.75, rel=REL))


def test_summary_pre_onset_alarms_and_aggregates():
    res = campaign(faulty("runaway", "cruise", [0.3, np.nan], pre_onset=[1]))
    s = summarize(res)
    rc = row(s, "runaway", "cruise")
    assert (rc.n_runs, rc.fa_count, rc.md_count) == (6, 1, 1)
    ra = row(s, "runaway", "all")
    assert (ra.n_runs, ra.fa_count, ra.md_count) == (8, 1, 1)
    assert ra.dtp_max == pytest.approx(0.6, rel=REL)
    agg = row(s, "all-faults", "all")
    assert (agg.n_runs, agg.fa_count, agg.md_count) == (11, 1, 1)  # 8 runaway + 3 solid
    assert agg.dtp_min == pytest.approx(0.05, rel=REL)
    assert agg.dtp_within == pytest.approx(10 / 11, rel=REL)
    # pre-onset alarms of faulty runs never leak into the fault-free rows
    assert row(s, "none", "all").fa_count == 0


def test_summary_excludes_and_counts_error_rows():
    s = summarize(campaign(errors("none", "cruise", 3), errors("runaway", "cruise", 2)))
    r = row(s, "none", "cruise")
    assert (r.n_runs, r.n_errors, r.fa_count) == (200, 3, 0)
    assert r.fa_upper95 == pytest.approx(upper_bound(0, 200), rel=REL)
    rr = row(s, "runaway", "cruise")
    assert (rr.n_runs, rr.n_errors, rr.md_count) == (4, 2, 0)  # errors are not misses
    assert rr.md_rate == 0.0 and rr.dtp_within == 1.0
    assert row(s, "all-faults", "all").n_errors == 2
    assert row(s, "none", "all").n_errors == 3
    # a group whose runs all failed has no rate: NaN, not 0
    only_err = row(summarize(campaign(errors("hardover", "cruise", 2))), "hardover", "cruise")
    assert only_err.n_runs == 0 and only_err.n_errors == 2
    for rate in ("fa_rate", "md_rate", "md_req_rate", "dtp_within", "fa_upper95", "md_upper95"):
        assert np.isnan(only_err[rate]), rate


def test_summary_several_detectors_and_empty_input():
    res = pd.concat([campaign(), fault_free("cruise", 5, alarms=5, detector="b-det")])
    s = summarize(res)
    assert set(s.detector) == {DET, "b-det"}
    assert row(s, "none", "cruise", "b-det").fa_count == 5
    assert row(s, "none", "cruise").fa_count == 0
    assert "all-faults" not in set(s[s.detector == "b-det"].fault)  # no faulty runs
    empty = summarize(res.iloc[:0])
    assert empty.empty and tuple(empty.columns) == SUMMARY_COLUMNS
    assert empty["n_runs"].dtype == np.int64 and empty["md_req_count"].dtype == np.int64
    assert empty["fa_rate"].dtype == np.float64 and empty["detector"].dtype == object
    with pytest.raises(ValueError, match="dtp"):
        summarize(res.drop(columns=["dtp"]))


def test_detector_variants_sort_by_the_value_of_their_numbers():
    poles = ["0.99", "0.9", "0.6", "0.95", "0.8"]
    res = pd.concat([fault_free("cruise", 2, detector=f"comb[a={a}]") for a in poles])
    order = list(dict.fromkeys(summarize(res).detector))
    assert order == [f"comb[a={a}]" for a in ("0.6", "0.8", "0.9", "0.95", "0.99")]


# ---- gate ----------------------------------------------------------------------------------

def test_gate_passes_on_clean_summary():
    result = evaluate_gate(summarize(campaign()), max_md=0.0, max_dtp=1.0)
    assert result.passed and result.failures == []
    names = {c.name for c in result.checks}
    assert names == {"false_alarm", "missed_detection", "dtp", "errors"}
    # one FA check per finest row: 6 fault-free manoeuvres + 3 fault × manoeuvre rows
    assert sum(c.name == "false_alarm" for c in result.checks) == 9
    assert "gate PASSED" in result.format()


def test_gate_fails_on_one_false_alarm_with_precise_message():
    res = campaign()
    res.loc[(res.fault == "none") & (res.manoeuvre == "cruise"), "false_alarm"] = \
        [True] + [False] * 199
    result = evaluate_gate(summarize(res))
    assert not result.passed
    [fail] = result.failures
    assert (fail.detector, fail.fault, fail.manoeuvre) == (DET, "none", "cruise")
    assert fail.value == pytest.approx(1 / 200, rel=REL) and fail.limit == 0.0
    assert fail.message == ("FAIL false alarms: position-monitor, fault-free cruise: "
                            "1/200 runs (0.50 % > 0.00 %)")
    report = result.format()
    assert "gate FAILED: 1 of" in report and fail.message in report
    # a 1 % allowance accepts the same summary
    assert evaluate_gate(summarize(res), max_fa=0.01).passed


def test_gate_names_the_first_failing_runs_when_given_the_results():
    res = campaign()
    ff = res.index[(res.fault == "none") & (res.manoeuvre == "turn_coordination")]
    res.loc[ff[[3, 10, 11, 40, 41]], "false_alarm"] = True
    [fail] = evaluate_gate(summarize(res), results=res).failures
    # the first three in plan order, and how many more
    assert fail.run_ids == ("position-monitor-ff-turn_coordination-3",
                            "position-monitor-ff-turn_coordination-10",
                            "position-monitor-ff-turn_coordination-11")
    assert fail.message.endswith("runs: position-monitor-ff-turn_coordination-3, "
                                 "position-monitor-ff-turn_coordination-10, "
                                 "position-monitor-ff-turn_coordination-11 and 2 more")
    # passing checks carry no run ids
    assert all(c.run_ids == () for c in evaluate_gate(summarize(res), results=res).checks
               if c.passed)


@pytest.mark.parametrize("done, planned, allow, passed", [
    (2400, 2400, False, True),
    (2399, 2400, False, False),      # one run short is not the campaign
    (600, 2400, True, True),         # explicitly allowed: still says incomplete
])
def test_gate_coverage(done, planned, allow, passed):
    result = evaluate_gate(summarize(campaign()), coverage=(done, planned),
                           allow_incomplete=allow)
    cover = result.checks[0]
    assert cover.name == "coverage" and cover.passed is passed and result.passed is passed
    if done < planned:
        assert f"incomplete: {done} of {planned} runs done" in cover.message
        assert ("--allow-incomplete" in cover.message) is (not allow)
        assert "gate PASSED" not in result.format() or allow


def test_gate_on_a_campaign_with_no_finished_run_fails_in_user_words():
    result = evaluate_gate(pd.DataFrame(), coverage=(0, 2400))
    assert not result.passed
    assert [c.message for c in result.failures] == [
        "FAIL coverage: incomplete: 0 of 2400 runs done; finish the campaign by running the "
        "same 'fdd-campaign run' command again (or gate part of it with --allow-incomplete)",
        "FAIL scored runs: no run has finished yet"]


def test_gate_fails_on_pre_onset_alarm():
    result = evaluate_gate(summarize(campaign(faulty("solid_jam", "nose_up", [0.1],
                                                      pre_onset=[0]))))
    [fail] = result.failures
    assert fail.message == ("FAIL false alarms before onset: position-monitor, solid_jam "
                            "nose_up: 1/1 runs (100.00 % > 0.00 %)")


def test_gate_fails_on_a_miss_only_when_md_is_checked():
    s = summarize(campaign(faulty("runaway", "nose_up", [np.nan])))
    assert evaluate_gate(s).passed  # max_md=None: not a requirement
    result = evaluate_gate(s, max_md=0.0)
    [fail] = result.failures
    assert (fail.name, fail.fault) == ("missed_detection", "runaway")
    assert fail.message == ("FAIL missed detections: position-monitor, runaway: 1/7 runs "
                            "never detected (14.29 % > 0.00 %); misses in: nose_up 1/3")


def test_missed_and_late_are_counted_apart():
    """A run never detected is missed; one detected after its required time (DTP > 1) is
    late; 'MD in T' counts both (not detected within the required time)."""
    s = summarize(campaign(faulty("runaway", "nose_up", [np.nan, 1.0, 1.5, 3.0])))
    r = row(s, "runaway", "all")
    # runaway: 4 + 2 detected in time from campaign() and 4 here = 10 runs
    assert (r.n_runs, r.md_count, r.late_count, r.md_req_count) == (10, 1, 2, 3)
    assert r.md_rate == pytest.approx(1 / 10, rel=REL)
    assert r.md_req_rate == pytest.approx(3 / 10, rel=REL)
    assert r.md_req_upper95 == pytest.approx(upper_bound(np.array([3]), np.array([10]))[0],
                                             rel=REL)
    # DTP exactly 1 is in time; the fault-free rows have no MD of either kind
    assert row(s, "none", "all").md_req_count == 0
    assert np.isnan(row(s, "none", "all").md_req_rate)
    msg = evaluate_gate(s, max_md=0.0).failures[0].message
    assert "1/10 runs never detected" in msg and "2 more detected late (DTP > 1" in msg
    table = format_table(s)
    assert "MD in T (%)" in table and "late" in table
    line = next(x for x in table.splitlines() if x.startswith("runaway"))
    assert " 10.00 " in line and " 30.00 " in line


def test_gate_fails_on_dtp_above_limit():
    s = summarize(campaign(faulty("solid_jam", "nose_up", [1.25])))
    assert evaluate_gate(s, max_dtp=1.5).passed
    result = evaluate_gate(s, max_dtp=1.0)
    [fail] = result.failures
    assert (fail.name, fail.fault, fail.value) == ("dtp", "solid_jam", 1.25)
    assert "max DTP 1.25 > 1 (worst in nose_up)" in fail.message
    [ok] = [c for c in evaluate_gate(s, max_dtp=1.5).checks
            if (c.name, c.fault) == ("dtp", "solid_jam")]
    assert ok.message == ("PASS detection time: position-monitor, solid_jam: max DTP 1.25 ≤ 1.5 "
                          "(worst in nose_up)")


def test_gate_dtp_fails_when_nothing_was_detected():
    s = summarize(pd.concat([fault_free("cruise", 5), faulty("runaway", "cruise", [np.nan])]))
    [fail] = evaluate_gate(s, max_dtp=1.0).failures
    assert "no detected run" in fail.message and "1 of 1 runs missed" in fail.message


def test_gate_fails_on_errors_unless_allowed():
    s = summarize(campaign(errors("runaway", "cruise", 2)))
    result = evaluate_gate(s)
    [fail] = result.failures
    assert fail.name == "errors" and fail.value == 2
    assert "2 run(s) did not finish" in fail.message and "runaway cruise 2" in fail.message
    assert evaluate_gate(s, allow_errors=True).passed


def test_gate_fails_without_scored_runs():
    assert not evaluate_gate(summarize(campaign().iloc[:0])).passed
    only_errors = summarize(errors("none", "cruise", 3))
    assert {c.name for c in evaluate_gate(only_errors, allow_errors=True).failures} == {"runs"}


def test_gate_bad_input_reports_every_problem_and_pickles():
    s = summarize(campaign())
    with pytest.raises(GateInputError) as info:
        evaluate_gate(s.drop(columns=["fa_count"]), max_fa=5, max_dtp=-1)
    err = info.value
    assert len(err.problems) == 3
    assert "fa_count" in str(err) and "0.01 = 1 %" in str(err) and "max_dtp" in str(err)
    back = pickle.loads(pickle.dumps(err))
    assert type(back) is GateInputError and back.problems == err.problems
    result = evaluate_gate(s)
    assert pickle.loads(pickle.dumps(result)) == result


def test_junit_parses_with_failure_count(tmp_path):
    res = campaign(faulty("runaway", "nose_up", [np.nan]))
    res.loc[(res.fault == "none") & (res.manoeuvre == "yaw_angle_mode"), "false_alarm"] = \
        [True] + [False] * 199
    result = evaluate_gate(summarize(res), max_md=0.0, max_dtp=1.0)
    assert len(result.failures) == 2
    path = tmp_path / "gate.xml"
    write_junit(result, path)
    root = ET.parse(path).getroot()
    suite = root.find("testsuite")
    assert int(suite.get("tests")) == len(result.checks)
    assert int(suite.get("failures")) == 2
    cases = suite.findall("testcase")
    assert len(cases) == len(result.checks)
    failures = [f.get("message") for f in suite.iter("failure")]
    assert sorted(failures) == sorted(c.message for c in result.failures)
    assert list(tmp_path.iterdir()) == [path]  # no temporary file left behind
    assert path.read_bytes().startswith(b"<?xml version='1.0' encoding='utf-8'?>")


def test_junit_file_that_cannot_be_replaced_leaves_no_temporary_file(tmp_path):
    result = evaluate_gate(summarize(campaign()))
    target = tmp_path / "gate.xml"
    target.mkdir()                      # os.replace cannot put a file over a directory
    with pytest.raises(OSError):
        write_junit(result, target)
    assert list(tmp_path.iterdir()) == [target] and list(target.iterdir()) == []


def test_gate_result_api():
    ok = Check("x", DET, "none", "cruise", 0.0, 0.0, True, "PASS x")
    bad = Check("y", DET, "none", "cruise", 1.0, 0.0, False, "FAIL y")
    r = GateResult([ok, bad])
    assert not r.passed and r.failures == [bad]
    assert GateResult().passed  # vacuous; evaluate_gate adds a failing check instead


# ---- table ---------------------------------------------------------------------------------

def test_format_table_numbers():
    text = format_table(summarize(campaign(faulty("runaway", "cruise", [np.nan]))))
    assert f"Detector: {DET}" in text
    assert "0/1200, FA ≤ 0.25 %" in text       # 1 - 0.05**(1/1200) = 0.2493 %
    assert "0/200, FA ≤ 1.49 %" in text        # 1 - 0.05**(1/200) = 1.487 %
    lines = text.splitlines()
    runaway = next(line for line in lines if line.startswith("runaway"))
    # 7 runs, 1 miss: MD 14.29 %, one-sided bound 1 - 0.05**... computed by upper_bound
    assert "14.29" in runaway and f"{100 * upper_bound(1, 7):.2f}" in runaway
    assert "0.1/0.3/0.6" in runaway              # Min/Mean/Max DTP over detected runs
    solid = next(line for line in lines if line.startswith("solid_jam"))
    assert "0.05/0.05/0.05" in solid and "100.0" in solid
    assert any(line.startswith("all faults") for line in lines)
    # fixed width: the last column is right-aligned, so header, rule and rows of the fault
    # block end at the same column
    start = next(i for i, line in enumerate(lines) if line.startswith("Fault scenario"))
    block = lines[start:start + 2 + 3]  # header, rule, runaway, solid_jam, all faults
    assert len({len(line) for line in block}) == 1
    assert format_table(summarize(campaign().iloc[:0])) == "no results"


def test_estimation_error_is_pooled_over_samples_and_normalised_by_the_range():
    # two runs of one fault: pooled mean/variance of all samples equal the per-run values
    # combined (N = Σn, mean = Σn·m/N, var = Σn(v + m²)/N − mean²), by hand on raw samples
    a, b = np.array([0.1, 0.3, 0.2]), np.array([-0.2, 0.0])
    rows = pd.DataFrame({
        "run_id": ["r1", "r2", "r3"], "detector": "d", "fault": ["solid_jam", "solid_jam", "none"],
        "manoeuvre": "cruise", "status": "ok", "error": "", "false_alarm": False,
        "pre_onset_alarm": False, "detected": [True, True, False], "first_alarm_s": np.nan,
        "delay_s": [0.1, 0.1, np.nan], "dtp": [0.05, 0.05, np.nan], "margin": 0.5,
        "est_err_n": [3, 2, 0], "est_err_mean_mm": [a.mean(), b.mean(), np.nan],
        "est_err_var_mm2": [a.var(), b.var(), np.nan], "est_range_mm": [60.0, 60.0, np.nan]})
    s = summarize(rows).set_index(["detector", "fault", "manoeuvre"])
    row = s.loc[("d", "solid_jam", "all")]
    pooled = np.concatenate([a, b])
    assert row["est_err_runs"] == 2
    assert row["est_err_mean_mm"] == pytest.approx(pooled.mean(), abs=1e-15)
    assert row["est_err_var_mm2"] == pytest.approx(pooled.var(), rel=1e-12)
    assert row["est_err_mean"] == pytest.approx(pooled.mean() / 60.0, abs=1e-15)
    assert row["est_err_var"] == pytest.approx(pooled.var() / 3600.0, rel=1e-12)
    assert s.loc[("d", "none", "all"), "est_err_runs"] == 0
    assert np.isnan(s.loc[("d", "none", "all"), "est_err_mean_mm"])
    # results written before the columns existed: the statistics are NaN, the rest unchanged
    old = summarize(rows.drop(columns=list(ESTIMATE_COLUMNS)))
    assert old["est_err_mean"].isna().all()
    cols = [c for c in SUMMARY_COLUMNS if not c.startswith("est_err")]
    pd.testing.assert_frame_equal(old[cols], summarize(rows)[cols])
    # scored runs without samples change neither the pooled values nor the run count,
    # whether their statistics read NaN or 0
    extra = rows.iloc[[0, 0]].assign(run_id=["r4", "r5"], est_err_n=0,
                                     est_err_mean_mm=[np.nan, 0.0], est_err_var_mm2=[np.nan, 0.0])
    s4 = summarize(pd.concat([rows, extra], ignore_index=True)).set_index(
        ["detector", "fault", "manoeuvre"])
    est = ["est_err_runs", "est_err_mean_mm", "est_err_var_mm2", "est_err_mean", "est_err_var"]
    assert list(s4.loc[("d", "solid_jam", "all"), est]) == list(row[est])


def test_a_detector_allowance_applies_to_that_detector_only():
    """[requirements] detector_max_fa_rate: a documented allowance for one detector (by
    result name, or by base label for every variant) replaces max_fa for it alone."""
    res = pd.concat([fault_free("turn_coordination", 10, alarms=2, detector="chen-local[solid]"),
                     fault_free("turn_coordination", 10, alarms=0, detector="chen-local[liquid]"),
                     fault_free("turn_coordination", 10, alarms=1)], ignore_index=True)
    summary = summarize(res)
    plain = evaluate_gate(summary)
    assert sorted(c.detector for c in plain.failures) == ["chen-local[solid]", DET]
    allowed = evaluate_gate(summary, detector_max_fa={"chen-local[solid]": 0.2})
    assert [c.detector for c in allowed.failures] == [DET]            # 2/10 ≤ 20 %
    [solid] = [c for c in allowed.checks if c.detector == "chen-local[solid]"
               and c.name == "false_alarm"]
    assert solid.passed and solid.limit == 0.2 and solid.value == pytest.approx(0.2, rel=REL)
    # 2/10 > 10 %: the allowance is a limit, not a waiver
    assert not evaluate_gate(summary, detector_max_fa={"chen-local[solid]": 0.1}).passed
    # a base label covers its variants; the others keep max_fa
    by_base = evaluate_gate(summary, detector_max_fa={"chen-local": 0.2})
    assert [c.detector for c in by_base.failures] == [DET]
    with pytest.raises(GateInputError, match="no detector of these results"):
        evaluate_gate(summary, detector_max_fa={"chen-global": 0.2})
    with pytest.raises(GateInputError, match=r"fraction in \[0, 1\]"):
        evaluate_gate(summary, detector_max_fa={"chen-local[solid]": 20})


# ---- limits, groups without scored runs, the false-alarm probability check ----------------

@pytest.mark.parametrize("limits", [{"max_fa": 1.5}, {"max_md": 1.01}, {"max_fa": -0.01}])
def test_gate_refuses_a_rate_limit_outside_zero_one(limits):
    with pytest.raises(GateInputError, match="fraction in \\[0, 1\\]"):
        evaluate_gate(summarize(campaign()), **limits)


def test_gate_accepts_the_rate_limits_zero_and_one():
    s = summarize(campaign(faulty("runaway", "cruise", [np.nan])))
    assert evaluate_gate(s, max_fa=1.0, max_md=1.0).passed
    assert not evaluate_gate(s, max_fa=0.0, max_md=0.0).passed


def test_gate_skips_rate_checks_of_a_fault_whose_runs_all_failed():
    # every oscillatory run errored: no rate to check (0/0), only the errors check speaks
    s = summarize(campaign(errors("oscillatory", "cruise", 2)))
    result = evaluate_gate(s, max_md=0.0, max_dtp=1.0, allow_errors=True)
    assert result.passed
    assert not [c for c in result.checks if c.fault == "oscillatory"]
    assert {c.fault for c in result.checks if c.name == "missed_detection"} == {
        "runaway", "solid_jam"}


def test_gate_on_an_empty_summary_is_one_failed_runs_check():
    [check] = evaluate_gate(summarize(campaign().iloc[:0])).checks
    # value: runs scored, limit: the least number of scored runs that proves anything
    assert (check.name, check.value, check.limit, check.passed) == ("runs", 0.0, 1.0, False)


def _certificate(**bounds):
    """Certificate rows whose curve bound at margin 1 is the tail fit's (``evt_method``
    "mixture")."""
    return pd.DataFrame([{"detector": d, "level": 0.95, "fa_upper95_cp": cp,
                          "fa_prob_evt_upper95": evt, "evt_method": "mixture",
                          "sampling_upper95": ss}
                         for d, (cp, evt, ss) in bounds.items()])


def test_fa_probability_check_holds_each_detector_to_its_largest_bound():
    from reports.scoring.gate import fa_probability_checks

    cert = _certificate(a=(2.5e-3, 1e-6, np.nan), b=(2.5e-3, np.nan, np.nan),
                        c=(2.5e-3, 1e-6, 3e-6), d=(2.5e-3, None, 4e-7))
    checks = {c.detector: c for c in fa_probability_checks(cert, 2e-6)}
    assert checks["a"].value == 1e-6 and checks["a"].passed and "(tail fit)" in checks["a"].message
    assert checks["b"].value == 2.5e-3 and not checks["b"].passed
    assert "(counting, Clopper–Pearson; no tail fit or sampling)" in checks["b"].message
    assert checks["c"].value == 3e-6 and not checks["c"].passed
    assert "(subset simulation)" in checks["c"].message
    assert checks["d"].value == 4e-7 and checks["d"].passed
    assert checks["a"].message == ("PASS false-alarm probability: a: P(FA per run) ≤ 1e-06 at "
                                   "95 % (tail fit) ≤ 2e-06")
    assert "> 2e-06" in checks["b"].message
    assert all(c.name == "fa_probability" and c.limit == 2e-6 for c in checks.values())
    # a bound equal to the limit passes; the limits 0 and 1 are probabilities
    assert fa_probability_checks(cert, 1e-6)[0].passed
    assert [c.passed for c in fa_probability_checks(cert, 0.0)] == [False] * 4
    assert [c.passed for c in fa_probability_checks(cert, 1.0)] == [True] * 4


@pytest.mark.parametrize("limit", [-1e-9, 1.5, "often", None])
def test_fa_probability_check_refuses_a_limit_that_is_no_probability(limit):
    from reports.scoring.gate import fa_probability_checks

    with pytest.raises(GateInputError, match="max_fa_prob"):
        fa_probability_checks(_certificate(a=(1e-3, 1e-6, np.nan)), limit)
    with pytest.raises(GateInputError, match="lacks column"):
        fa_probability_checks(pd.DataFrame({"detector": ["a"]}), 1e-5)


def test_gate_names_exactly_three_failing_runs_without_a_count_of_more():
    res = campaign()
    ff = res.index[(res.fault == "none") & (res.manoeuvre == "cruise")]
    res.loc[ff[[0, 1, 2]], "false_alarm"] = True
    [fail] = evaluate_gate(summarize(res), results=res).failures
    assert fail.message.endswith("runs: position-monitor-ff-cruise-0, "
                                 "position-monitor-ff-cruise-1, position-monitor-ff-cruise-2")


def test_passing_false_alarm_check_states_its_95_percent_bound():
    checks = evaluate_gate(summarize(campaign())).checks
    cruise = next(c for c in checks if (c.name, c.fault, c.manoeuvre) == ("false_alarm", "none",
                                                                            "cruise"))
    # 0 of 200: upper bound 1 - 0.05^(1/200) = 1.49 %
    assert cruise.message == ("PASS false alarms: position-monitor, fault-free cruise: 0/200 "
                              "runs (0.00 % ≤ 0.00 %; FA ≤ 1.49 % at 95 %)")


def test_run_error_check_names_the_first_error_and_the_other_messages():
    err = errors("runaway", "cruise", 2)
    other = errors("solid_jam", "cruise", 1).assign(error="ValueError: NaN in the state")
    res = campaign(err)
    result = evaluate_gate(summarize(res), results=res)
    [fail] = result.failures
    assert fail.message.endswith("; first: run position-monitor-err-runaway-cruise-0: "
                                 "RuntimeError: solver diverged")
    res2 = campaign(err, other)
    [fail2] = evaluate_gate(summarize(res2), results=res2).failures
    assert fail2.message.endswith("RuntimeError: solver diverged (1 other message(s): "
                                  "fdd-campaign report)")
    [allowed] = [c for c in evaluate_gate(summarize(res), results=res, allow_errors=True).checks
                 if c.name == "errors"]
    assert allowed.passed and allowed.message.startswith("PASS (allowed) run errors: ")


def test_missed_detection_and_dtp_checks_are_in_fault_order_whatever_the_summary_order():
    s = summarize(campaign(faulty("hardover", "cruise", [0.3])))
    for summary in (s, s.iloc[::-1]):
        checks = evaluate_gate(summary, max_md=0.0, max_dtp=1.0).checks
        for name in ("missed_detection", "dtp"):
            assert [c.fault for c in checks if c.name == name] == [
                "hardover", "runaway", "solid_jam"]


def test_gate_refuses_a_zero_dtp_limit_and_a_limit_that_is_no_number():
    s = summarize(campaign())
    with pytest.raises(GateInputError, match="max_dtp must be a positive DTP"):
        evaluate_gate(s, max_dtp=0.0)
    with pytest.raises(GateInputError, match="max_fa must be a number, got 'often'"):
        evaluate_gate(s, max_fa="often")
    with pytest.raises(GateInputError, match=r"max_md must be a number, got \[0.1\]"):
        evaluate_gate(s, max_md=[0.1])
    # every limit is checked, also after one that is no number
    with pytest.raises(GateInputError) as info:
        evaluate_gate(s, max_fa="often", max_dtp=-1.0)
    assert len(info.value.problems) == 2
    # limits are keyword-only: a positional number is never taken for one
    with pytest.raises(TypeError):
        evaluate_gate(s, 0.01)


def test_count_checks_state_value_and_limit():
    s = summarize(campaign())
    [ok] = [c for c in evaluate_gate(s).checks if c.name == "errors"]
    assert (ok.value, ok.limit, ok.passed) == (0.0, 0.0, True)
    s_err = summarize(campaign(errors("runaway", "cruise", 2)))
    [bad] = [c for c in evaluate_gate(s_err).checks if c.name == "errors"]
    assert (bad.value, bad.limit, bad.passed) == (2.0, 0.0, False)
    [runs] = evaluate_gate(summarize(errors("none", "cruise", 3)), allow_errors=True).failures
    assert (runs.name, runs.value, runs.limit) == ("runs", 0.0, 1.0)
    # a summary with aggregate rows only holds no scored run
    [agg] = evaluate_gate(s[s.manoeuvre == "all"]).checks
    assert (agg.name, agg.value, agg.limit, agg.passed) == ("runs", 0.0, 1.0, False)
    assert agg.message == "FAIL scored runs: the summary holds no runs"


def test_gate_names_four_failing_runs_as_three_and_one_more():
    res = campaign()
    ff = res.index[(res.fault == "none") & (res.manoeuvre == "cruise")]
    res.loc[ff[[0, 1, 2, 3]], "false_alarm"] = True
    [fail] = evaluate_gate(summarize(res), results=res).failures
    assert fail.message.endswith("position-monitor-ff-cruise-2 and 1 more")


def test_results_without_error_column_and_summaries_without_late_count():
    res = campaign(errors("runaway", "cruise", 1))
    s = summarize(res)
    [fail] = evaluate_gate(s, results=res.drop(columns=["error"])).failures
    assert "first:" not in fail.message and fail.message.endswith("runaway cruise 1")
    late = summarize(campaign(faulty("runaway", "cruise", [1.5])))
    [md_late] = [c for c in evaluate_gate(late, max_md=0.0).checks if c.fault == "runaway"
                 and c.name == "missed_detection"]
    assert "1 more detected late" in md_late.message
    [md_old] = [c for c in evaluate_gate(late.drop(columns=["late_count"]), max_md=0.0).checks
                if c.fault == "runaway" and c.name == "missed_detection"]
    assert "late" not in md_old.message


def test_dtp_check_of_every_fault_after_one_without_detection():
    s = summarize(campaign(faulty("hardover", "cruise", [np.nan])))
    dtp = [c for c in evaluate_gate(s, max_dtp=1.0).checks if c.name == "dtp"]
    assert [(c.fault, c.passed) for c in dtp] == [("hardover", False), ("runaway", True),
                                                   ("solid_jam", True)]


def test_a_check_is_an_immutable_hashable_value():
    [check] = evaluate_gate(summarize(campaign().iloc[:0])).checks
    assert {check, check} == {check}
    with pytest.raises(AttributeError):
        check.passed = True


def test_checks_come_per_detector_in_name_order_and_one_scored_run_is_enough():
    two = pd.concat([fault_free("cruise", 1, detector="b-monitor"),
                     fault_free("cruise", 1, detector="a-monitor")], ignore_index=True)
    s = summarize(two)
    for summary in (s, s.iloc[::-1]):
        result = evaluate_gate(summary)
        assert result.passed                   # one scored run per detector is a scored run
        assert [c.detector for c in result.checks] == ["a-monitor"] * 2 + ["b-monitor"] * 2


def test_checks_come_with_variant_numbers_by_value():
    """The one detector order (reports.scoring.summary.detector_order): a=0.9 before a=0.95, which
    the text order reverses (']' sorts after '5')."""
    names = ["d[a=0.95]", "d[a=0.9]", "d[a=0.6]"]
    s = summarize(pd.concat([fault_free("cruise", 1, detector=n) for n in names],
                            ignore_index=True))
    order = list(dict.fromkeys(c.detector for c in evaluate_gate(s).checks))
    assert order == ["d[a=0.6]", "d[a=0.9]", "d[a=0.95]"]


def test_a_bound_that_is_not_a_number_reads_n_a():
    s = summarize(campaign()).assign(fa_upper95=np.nan)
    cruise = next(c for c in evaluate_gate(s).checks if (c.name, c.fault, c.manoeuvre) == (
        "false_alarm", "none", "cruise"))
    assert cruise.message.endswith("(0.00 % ≤ 0.00 %; FA ≤ n/a at 95 %)")


def test_one_faulty_run_is_a_rate_and_one_sample_is_a_pooled_error():
    late = faulty("runaway", "cruise", [1.5])       # detected, after the required time
    within = faulty("solid_jam", "cruise", [0.5])   # detected within it
    miss = faulty("hardover", "cruise", [np.nan])
    res = campaign().pipe(lambda c: c[c.fault == "none"])
    res = pd.concat([res, late, within, miss], ignore_index=True)
    for column in ESTIMATE_COLUMNS:
        res[column] = 0 if column == "est_err_n" else np.nan
    res.loc[res.run_id == within.run_id[0], ESTIMATE_COLUMNS] = [1, 0.2, 0.0, 40.0]
    s = summarize(res)
    r_late, r_within = row(s, "runaway", "cruise"), row(s, "solid_jam", "cruise")
    assert (r_late.md_req_rate, r_late.dtp_within) == (1.0, 0.0)
    assert (r_within.md_req_rate, r_within.dtp_within) == (0.0, 1.0)
    assert row(s, "hardover", "cruise").md_rate == 1.0
    # order: fault-free first even before fault names that sort below "none"; a clean index
    assert list(s.fault.drop_duplicates()) == ["none", "hardover", "runaway", "solid_jam",
                                               "all-faults"]
    assert s.index.equals(pd.RangeIndex(len(s)))
    for column in ("n_runs", "n_errors", "fa_count", "md_count", "late_count", "md_req_count",
                   "est_err_runs"):
        assert s[column].dtype == np.int64, column
    # a run that did not finish contributes no estimation samples, whatever its columns hold
    failed = res[res.run_id == within.run_id[0]].assign(run_id="failed", status="error")
    s_failed = summarize(pd.concat([res, failed], ignore_index=True))
    assert row(s_failed, "solid_jam", "cruise").est_err_runs == 1
    assert r_within.est_err_runs == 1 and r_within.est_err_mean_mm == pytest.approx(0.2, rel=REL)
    assert r_within.est_err_mean == pytest.approx(0.2 / 40.0, rel=REL)
    assert r_within.est_err_var_mm2 == pytest.approx(0.0, abs=1e-15)


def test_survival_columns_are_nan_for_fault_free_rows_only():
    from reports.scoring.survival import SURVIVAL_COLUMNS

    s = summarize(campaign())
    assert s.loc[s.fault == "none", list(SURVIVAL_COLUMNS)].isna().all().all()
    # detections in every faulty group: the Kaplan-Meier median delay exists
    assert s.loc[s.fault != "none", "delay_km_median_s"].notna().all()


def test_missed_detection_and_dtp_failures_name_their_runs_to_replay():
    """Given the result rows, a failed MD check names the runs never detected (plan order), a
    failed DTP check the runs above the limit, worst first, and one with no detected run its
    missed runs: each can be replayed with ``fdd-campaign show DIR RUN_ID``."""
    res = campaign(faulty("runaway", "nose_up", [np.nan, 1.5, np.nan, 3.0, 0.2]),
                   faulty("liquid_jam", "cruise", [np.nan, np.nan]))
    gate = evaluate_gate(summarize(res), max_md=0.0, max_dtp=1.0, results=res)
    fails = {(c.name, c.fault): c for c in gate.failures}
    md = fails[("missed_detection", "runaway")]
    assert md.run_ids == ("position-monitor-runaway-nose_up-0",
                          "position-monitor-runaway-nose_up-2")
    assert md.message.endswith("; missed runs: position-monitor-runaway-nose_up-0, "
                               "position-monitor-runaway-nose_up-2")
    dtp = fails[("dtp", "runaway")]
    # DTP 3.0 (run 3) before 1.5 (run 1); 0.2 and the campaign's own runaways are in time
    assert dtp.run_ids == ("position-monitor-runaway-nose_up-3",
                           "position-monitor-runaway-nose_up-1")
    assert "runs above it, worst first: position-monitor-runaway-nose_up-3, " in dtp.message
    none = fails[("dtp", "liquid_jam")]
    assert "no detected run" in none.message
    assert none.run_ids == ("position-monitor-liquid_jam-cruise-0",
                            "position-monitor-liquid_jam-cruise-1")
    # without the result rows the same checks fail, naming no run
    bare = evaluate_gate(summarize(res), max_md=0.0, max_dtp=1.0)
    assert [c.name for c in bare.failures] == [c.name for c in gate.failures]
    assert all(c.run_ids == () for c in bare.checks)
    # passing checks name none
    assert all(c.run_ids == () for c in gate.checks if c.passed)
