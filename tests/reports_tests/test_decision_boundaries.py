"""Decision boundaries pinned by hand-built inputs: the position monitor's learned threshold
and confirmation (detectors/builtin/position_monitor.py, docs/detectors.md), the run scoring
(docs/design.md §5, reports/scoring/metrics.py) and the summary and gate counting rules
(reports/scoring/summary.py, reports/scoring/gate.py).

Every input is constructed so the expected value is known without running the code under
test: a residual exactly at the threshold, n − 1 and n confirmation steps, an alarm exactly
at the end of the detection window, a DTP of exactly 1, error rows with alarms.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from detectors.builtin.position_monitor import PositionMonitor
from reports.scoring.gate import evaluate_gate
from reports.scoring.metrics import score_runs
from reports.scoring.summary import summarize
from scenarios.compiled import use_engine
from scenarios.params import ELEVATOR
from scenarios.signals import Signals

ENGINES = ("compiled", "numpy")
TS = 0.01


def signals(rod_com, rod_mon, surface=None, command=None):
    """Signals of hand-made rod acquisitions [mm] (surface in deg; NaN when absent)."""
    rod_com = np.atleast_2d(np.asarray(rod_com, float))
    n, T = rod_com.shape
    nan = np.full((n, T), np.nan)
    return Signals(
        ts=TS, command=np.zeros((n, T)) if command is None else command,
        current=np.zeros((n, T)), rod_com=rod_com,
        rod_mon=np.atleast_2d(np.asarray(rod_mon, float)),
        surface=nan if surface is None else np.atleast_2d(np.asarray(surface, float)),
        pressure=nan,
        schedule={"qbar_pa": np.full(n, 10e3), "alpha_deg": np.full(n, 2.0),
                  "mach": np.full(n, 0.7), "vcas_kt": np.full(n, 300.0),
                  "alt_ft": np.full(n, 28000.0), "mass_t": np.full(n, 180.0),
                  "cg_pct": np.full(n, 30.0)},
        actuator=ELEVATOR, run_ids=np.array([f"r{i}" for i in range(n)]))


# ---- position monitor ---------------------------------------------------------------------
def test_learned_threshold_is_safety_times_the_largest_learning_residual():
    T = 50
    com = np.zeros((2, T))
    mon = np.zeros((2, T))
    mon[0, 10] = 0.12           # COM − MON = −0.12 mm: the largest |residual| of run 0
    mon[1, 30] = -0.2           # +0.2 mm in run 1: the largest of the whole learning set
    surface = np.zeros((2, T))
    surface[1, 5] = 0.5         # r·sin(0.5°) − MON = 1.04720 mm
    det = PositionMonitor(safety=1.7, checks=("com_mon", "surface"), floor_mm=0.05)
    det.fit(signals(com, mon, surface))
    # docs/detectors.md: threshold = safety × its largest fault-free residual over the set
    assert det.thresholds_mm_["com_mon"] == pytest.approx(1.7 * 0.2, rel=1e-12)
    assert det.thresholds_mm_["surface"] == pytest.approx(
        1.7 * 120.0 * np.sin(np.radians(0.5)), rel=1e-12)


def test_learned_threshold_never_falls_below_the_floor():
    com = np.zeros((1, 20))
    mon = np.zeros((1, 20))
    mon[0, 3] = 0.01            # 1.5 × 0.01 = 0.015 mm < floor 0.05 mm
    det = PositionMonitor(safety=1.5, checks=("com_mon",), floor_mm=0.05).fit(signals(com, mon))
    assert det.thresholds_mm_["com_mon"] == 0.05


def _fitted(confirm_s, threshold=0.3):
    """A com_mon-only monitor whose learned threshold is exactly *threshold* mm."""
    com = np.zeros((1, 10))
    mon = np.zeros((1, 10))
    mon[0, 0] = -threshold / 2.0          # largest |COM − MON| = τ/2, × safety 2 = τ
    det = PositionMonitor(safety=2.0, confirm_s=confirm_s, checks=("com_mon",), floor_mm=1e-6)
    det.fit(signals(com, mon))
    return det, det.thresholds_mm_["com_mon"]


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("confirm_s, n", [(0.05, 6), (0.0, 1), (0.1, 11)])
def test_confirmation_needs_n_consecutive_steps_at_or_over_threshold(engine, confirm_s, n):
    # docs/detectors.md: the alarm once the discrepancy has persisted confirm_s, i.e. over
    # n = confirm_s/Ts + 1 consecutive samples (0.05 s at 10 ms: 6 samples)
    det, tau = _fitted(confirm_s)
    T, start = 60, 10
    com = np.zeros((3, T))
    com[0, start:start + n - 1] = tau               # n − 1 steps exactly at the threshold
    com[1, start:start + n] = tau                   # n steps exactly at the threshold
    com[2, start:start + n] = tau * (1 - 1e-9)      # n steps just under it
    with use_engine(engine):
        d = det.detect(signals(com, np.zeros((3, T))))
    assert not d.alarm[0].any()
    assert not d.alarm[2].any()
    first = int(np.argmax(d.alarm[1]))
    assert first == start + n - 1                     # raised on the n-th step
    assert d.alarm[1, first:].all()                   # and latched after the residual falls
    assert not d.alarm[1, :first].any()
    # the normalised residual is |r|/τ: exactly 1 at the threshold
    assert d.residual[1, start] == pytest.approx(1.0, rel=1e-12)


@pytest.mark.parametrize("engine", ENGINES)
def test_an_interrupted_excursion_restarts_the_count(engine):
    det, tau = _fitted(0.05)
    T = 40
    com = np.full((1, T), 0.0)
    com[0, 5:10] = 2 * tau          # 5 steps over
    com[0, 11:16] = 2 * tau         # one step under, then 5 steps over again: no alarm
    with use_engine(engine):
        d = det.detect(signals(com, np.zeros((1, T))))
    assert not d.alarm.any()
    assert d.residual[0, 5] == pytest.approx(2.0, rel=1e-12)


# ---- run scoring (docs/design.md §5) ---------------------------------------------------------
def _score(alarm_steps, onset, T=300, window=None, required=0.5, fault="runaway"):
    alarm = np.zeros((1, T), dtype=bool)
    alarm[0, list(alarm_steps)] = True
    return score_runs(run_id=["r"], fault=[fault], onset_s=[onset], alarm=alarm,
                      residual=alarm.astype(float), ts=TS, required_time_s=[required],
                      window_s=window).iloc[0]


def test_an_alarm_exactly_at_the_end_of_the_window_is_a_detection():
    # onset 1.0 s, window 0.5 s: the window ends at step 150 (1.5 s), inclusive
    row = _score([150], onset=1.0, window=0.5)
    assert row["detected"] and row["delay_s"] == pytest.approx(0.5, abs=1e-12)
    assert row["dtp"] == pytest.approx(1.0, abs=1e-12)       # 0.5 s / 0.5 s required
    row = _score([151], onset=1.0, window=0.5)               # one step later: a miss
    assert not row["detected"] and np.isnan(row["first_alarm_s"])
    assert not row["false_alarm"]


def test_an_onset_between_two_samples():
    # onset 1.005 s: step 100 (1.00 s) is before it, step 101 (1.01 s) after it
    row = _score([100], onset=1.005)
    assert row["false_alarm"] and not row["detected"]
    row = _score([101], onset=1.005)
    assert row["detected"] and not row["false_alarm"]
    assert row["delay_s"] == pytest.approx(0.005, abs=1e-12)
    assert row["dtp"] == pytest.approx(0.01, abs=1e-12)      # 0.005 s / 0.5 s


def test_margin_is_the_largest_residual_before_onset():
    residual = np.zeros((1, 300))
    residual[0, [20, 60, 99]] = [0.4, 0.9, 0.7]
    residual[0, 100:] = 5.0                  # from onset on: not part of the margin
    row = score_runs(run_id=["r"], fault=["runaway"], onset_s=[1.0],
                     alarm=np.zeros((1, 300), bool), residual=residual, ts=TS,
                     required_time_s=[0.5]).iloc[0]
    assert row["margin"] == 0.9


# ---- summary and gate ---------------------------------------------------------------------
def rows(specs):
    """Result rows from (fault, manoeuvre, status, false_alarm, detected, dtp, margin)."""
    out = []
    for i, (fault, man, status, fa, det, dtp, margin) in enumerate(specs):
        out.append({"run_id": f"r{i}", "detector": "d", "fault": fault, "manoeuvre": man,
                    "status": status, "error": "" if status == "ok" else "boom",
                    "false_alarm": fa, "pre_onset_alarm": fa, "detected": det,
                    "first_alarm_s": np.nan, "delay_s": 0.5 * dtp if det else np.nan,
                    "dtp": dtp if det else np.nan, "margin": margin})
    return pd.DataFrame(out)


def _row(summary, fault, manoeuvre):
    sel = summary[(summary.fault == fault) & (summary.manoeuvre == manoeuvre)]
    assert len(sel) == 1
    return sel.iloc[0]


def test_error_rows_are_in_no_rate():
    res = rows([
        ("none", "cruise", "ok", True, False, np.nan, 1.2),
        ("none", "cruise", "ok", False, False, np.nan, 0.3),
        ("none", "cruise", "error", True, False, np.nan, 9.0),     # an error with an alarm
        ("none", "cruise", "timeout", np.nan, np.nan, np.nan, np.nan),
        ("runaway", "cruise", "ok", False, True, 0.4, 0.2),
        ("runaway", "cruise", "ok", False, False, np.nan, 0.1),
        ("runaway", "cruise", "error", True, False, np.nan, 7.0),
    ])
    s = summarize(res)
    ff = _row(s, "none", "cruise")
    assert (ff.n_runs, ff.n_errors, ff.fa_count) == (2, 2, 1)
    assert ff.fa_rate == 0.5                      # 1 of the 2 ok runs, not 2 of 4
    assert ff.worst_margin == 1.2                 # the error row's 9.0 is not scored
    ra = _row(s, "runaway", "cruise")
    assert (ra.n_runs, ra.n_errors, ra.fa_count, ra.md_count) == (2, 1, 0, 1)
    assert ra.md_rate == 0.5 and ra.dtp_within == 0.5
    assert ra.worst_margin == 0.2


def test_worst_margin_is_the_max_and_dtp_exactly_one_is_within():
    res = rows([
        ("runaway", "cruise", "ok", False, True, 1.0, 0.2),       # DTP exactly 1: within
        ("runaway", "cruise", "ok", False, True, 0.5, 0.95),
        ("runaway", "cruise", "ok", False, True, 1.0 + 1e-9, 0.4),  # just over: not within
        ("runaway", "cruise", "ok", False, False, np.nan, 0.3),
    ])
    r = _row(summarize(res), "runaway", "cruise")
    assert r.worst_margin == 0.95                 # max, not the mean 0.4625
    assert r.dtp_within == 0.5                    # 2 within of the 4 scored faulty runs
    assert r.dtp_max == 1.0 + 1e-9 and r.dtp_min == 0.5
    assert r.dtp_mean == pytest.approx((2.0 + 0.5 + 1e-9) / 3, rel=1e-12)   # detected only


def test_gate_dtp_exactly_at_the_limit_passes():
    res = rows([("runaway", "cruise", "ok", False, True, 1.0, 0.1),
                ("none", "cruise", "ok", False, False, np.nan, 0.1)])
    gate = evaluate_gate(summarize(res), max_dtp=1.0)
    dtp = [c for c in gate.checks if c.name == "dtp"]
    assert len(dtp) == 1 and dtp[0].passed and dtp[0].value == 1.0
    res.loc[0, "dtp"] = 1.0 + 1e-9
    assert not evaluate_gate(summarize(res), max_dtp=1.0).passed


def test_misses_of_every_manoeuvre_add_up():
    specs = []
    for man in ("cruise", "nose_up"):
        specs += [("runaway", man, "ok", False, False, np.nan, 0.1)]          # one miss each
        specs += [("runaway", man, "ok", False, True, 0.5, 0.1)] * 9
    specs += [("none", "cruise", "ok", False, False, np.nan, 0.1)]
    s = summarize(rows(specs))
    agg = _row(s, "runaway", "all")
    assert (agg.n_runs, agg.md_count) == (20, 2) and agg.md_rate == 0.1
    assert _row(s, "all-faults", "all").md_count == 2
    # the gate's MD rate per fault type: 2 misses / 20 runs = 10 %, above a 9 % limit
    md = [c for c in evaluate_gate(s, max_md=0.09).checks if c.name == "missed_detection"]
    assert len(md) == 1 and md[0].value == 0.1 and not md[0].passed
    md = [c for c in evaluate_gate(s, max_md=0.1).checks if c.name == "missed_detection"]
    assert md[0].passed


def test_gate_false_alarm_rate_per_finest_row_at_the_limit():
    specs = [("none", "cruise", "ok", i == 0, False, np.nan, 0.1) for i in range(10)]
    s = summarize(rows(specs))
    fa = [c for c in evaluate_gate(s, max_fa=0.1).checks if c.name == "false_alarm"]
    assert len(fa) == 1 and fa[0].value == 0.1 and fa[0].passed      # 1/10 ≤ 10 %
    assert not evaluate_gate(s, max_fa=0.099).passed


# ---- invariants of the summary (hypothesis) -------------------------------------------------
_spec = st.tuples(
    st.sampled_from(["none", "runaway", "solid_jam"]),
    st.sampled_from(["cruise", "nose_up", "turn_coordination"]),
    st.sampled_from(["ok", "ok", "ok", "error"]),
    st.booleans(), st.booleans(),
    st.floats(0.0, 3.0), st.floats(0.0, 2.0),
)


@settings(max_examples=60, deadline=None)
@given(st.lists(_spec, min_size=1, max_size=30))
def test_summary_invariants(specs):
    res = rows(specs)
    s = summarize(res)
    ok = res["status"] == "ok"
    fine = s[(s.fault != "all-faults") & (s.manoeuvre != "all")]
    # every row counted once, scored or as an error
    assert int(fine.n_runs.sum()) == int(ok.sum())
    assert int(fine.n_errors.sum()) == int((~ok).sum())
    for fault, g in fine.groupby("fault"):
        agg = _row(s, fault, "all")
        # the aggregate over manoeuvres adds the counts and takes the max margin
        assert agg.n_runs == g.n_runs.sum() and agg.fa_count == g.fa_count.sum()
        assert agg.md_count == g.md_count.sum()
        if g.worst_margin.notna().any():
            assert agg.worst_margin == g.worst_margin.max()
        sel = res[ok & (res.fault == fault)]
        assert agg.fa_count == int(sel.false_alarm.astype(bool).sum())
        if len(sel):
            assert agg.fa_rate == agg.fa_count / len(sel)
        if fault != "none" and len(sel):
            det = sel.detected.astype(bool)
            assert agg.md_count == int((~det).sum())
            within = int((det & (sel.dtp <= 1.0)).sum())
            assert agg.dtp_within == within / len(sel)
            assert 0.0 <= agg.dtp_within <= 1.0 - agg.md_rate + 1e-12
