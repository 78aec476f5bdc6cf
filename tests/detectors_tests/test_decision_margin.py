"""The decision statistic of a detection (detectors/base.py, Detection.decision): the alarm is
raised where it first reaches 1, and with every threshold of the detector multiplied by s
where it first reaches s, so a run's margin (its largest value before onset) is ≥ s exactly
when the run alarms before onset at threshold × s (docs/design.md §5, Metrics).

Checked against the detectors themselves run again with their thresholds scaled, on
simulated runs that come near their thresholds, for every built-in detector of the actuator
plant; and against the plain confirmation rule on every short pattern."""

from __future__ import annotations

import itertools

import numpy as np
import pandas as pd
import pytest

from detectors import Detection, confirm, decide, detection_problems, windowed_min
from detectors.base import first_steps
from detectors.builtin.chen_local import ChenLocalEstimator
from detectors.builtin.comb_interval import IntervalDetector
from detectors.builtin.position_monitor import PositionMonitor
from reports.scoring.metrics import score_columns
from scenarios.compiled import use_engine
from scenarios.simulate import simulate, single_run

SCALES = (0.8, 1.0, 1.25)


# ---- the rule on every pattern -------------------------------------------------------------
@pytest.mark.parametrize("n", [1, 2, 3, 5])
def test_windowed_min_decides_as_the_confirmation_on_every_7_step_pattern(n):
    """decide(windowed_min(x, n)) = confirm(x ≥ 1, n) for every pattern of 7 samples drawn
    from {0.5, 1 (exactly), 2, NaN}, and at scale s the alarm of confirm(x ≥ s, n) is
    where windowed_min first reaches s."""
    values = (0.5, 1.0, 2.0, np.nan)
    x = np.array(list(itertools.product(values, repeat=7)))
    d = windowed_min(x, n)
    with np.errstate(invalid="ignore"):
        np.testing.assert_array_equal(decide(d), confirm(x >= 1.0, n))
        for s in (0.5, 1.5, 2.0):
            np.testing.assert_array_equal(first_steps(d >= s),
                                          first_steps(confirm(x >= s, n)))
    assert np.isnan(d[:, :n - 1]).all()


def test_a_decision_that_disagrees_with_the_alarm_is_a_breach():
    alarm = np.zeros((2, 6), bool)
    alarm[1, 3:] = True
    decision = np.full((2, 6), 0.5)
    decision[1, 3] = 1.0
    assert detection_problems(Detection(alarm, decision, decision=decision), 2, 6) == []
    late = decision.copy()
    late[1, 3] = 0.99                     # the alarm at step 3, the decision ≥ 1 never
    (msg,) = detection_problems(Detection(alarm, decision, decision=late), 2, 6)
    assert "first alarm step 3, decision ≥ 1 never" in msg and "run 1" in msg
    inf = decision.copy()
    inf[0, 0] = np.inf
    (msg,) = detection_problems(Detection(alarm, decision, decision=inf), 2, 6)
    assert "must not be ±inf" in msg
    (msg,) = detection_problems(Detection(alarm, decision, decision=decision[:, :5]), 2, 6)
    assert "shape of the signals" in msg


# ---- the built-in detectors at scaled thresholds ------------------------------------------
def _runs(manoeuvre, fault, n, **point) -> pd.DataFrame:
    rows = pd.concat([single_run("elevator", manoeuvre, fault, seed=100 + s, duration_s=20.0,
                                 onset_s=8.0 + s, **point) for s in range(n)],
                     ignore_index=True)
    rows["stream"] = np.arange(n)
    rows["run_id"] = [f"{manoeuvre}-{fault}-{i}" for i in range(n)]
    return rows


@pytest.fixture(scope="module")
def runs():
    """Learning runs (cruise, nose-up), and runs to decide on: fault-free pitch protections
    (near the monitor's thresholds), liquid and solid jams, runaways (alarms after onset)."""
    learn = simulate(pd.concat([_runs("cruise", "none", 3), _runs("nose_up", "none", 3)],
                               ignore_index=True))[0]
    rows = pd.concat([_runs("pitch_protection", "none", 3, vcas_kt=182.0, alt_ft=8000.0),
                      _runs("turn_coordination", "liquid_jam", 2),
                      _runs("nose_up", "solid_jam", 2), _runs("cruise", "runaway", 2)],
                     ignore_index=True)
    signals, truth = simulate(rows)
    return learn, signals, truth


def _scaled(det, s):
    """*det* with every learned threshold times *s* (the copy's own dicts)."""
    import copy

    det = copy.deepcopy(det)
    if isinstance(det, PositionMonitor):
        det.thresholds_mm_ = {k: v * s for k, v in det.thresholds_mm_.items()}
    elif isinstance(det, IntervalDetector):
        det.thresholds_ = {k: v * s for k, v in det.thresholds_.items()}
    else:
        det.thresholds_ = {k: v * s for k, v in det.thresholds_.items()}
    return det


DETECTORS = {
    "position-monitor": lambda: PositionMonitor(threshold_method="max"),
    "comb-interval": lambda: IntervalDetector(poles=(0.6, 0.9), threshold_method="max"),
    "chen-local": lambda: ChenLocalEstimator(threshold_method="max"),
}


@pytest.mark.parametrize("engine", ["compiled", "numpy"])
@pytest.mark.parametrize("name", sorted(DETECTORS))
def test_threshold_times_s_alarms_where_the_decision_first_reaches_s(runs, name, engine):
    """For each run and variant: the first alarm of the detector re-run with its thresholds
    times s is the first step where the unscaled decision reaches s; so the margin of
    reports.scoring.metrics.score_columns is ≥ s exactly when that run alarms before onset."""
    learn, signals, truth = runs
    with use_engine(engine):
        det = DETECTORS[name]().fit(learn)
        base = det.detect(signals)
        base = base if isinstance(base, dict) else {name: base}
        assert type(det).capabilities.threshold_scale
        reached_any = False
        for s in SCALES:
            out = _scaled(det, s).detect(signals)
            out = out if isinstance(out, dict) else {name: out}
            for variant, d in base.items():
                assert d.decision is not None, variant
                assert detection_problems(d, signals.n_runs, signals.n_steps) == []
                np.testing.assert_array_equal(first_steps(out[variant].alarm),
                                              first_steps(d.decision >= s), err_msg=variant)
                scored = score_columns(
                    run_id=np.arange(signals.n_runs).astype(str), fault=truth.fault,
                    onset_s=truth.onset_s, alarm=out[variant].alarm,
                    residual=d.margin_statistic, ts=signals.ts,
                    required_time_s=np.ones(signals.n_runs))
                has = np.isfinite(scored["margin"])
                np.testing.assert_array_equal(scored["margin"][has] >= s,
                                              scored["pre_onset_alarm"][has], err_msg=variant)
                reached_any |= bool((first_steps(out[variant].alarm) >= 0).any())
        assert reached_any, "no run alarmed at any scale: the check saw no decision"


def test_margin_is_the_decision_not_the_unconfirmed_residual(runs):
    """A one-sample spike to 3× the threshold, shorter than the confirmation time, moves
    neither the decision nor the alarm: the margin stays that of the confirmed statistic
    (below 1), where the raw residual's would have said 3."""
    learn, signals, _ = runs
    det = PositionMonitor(threshold_method="max", confirm_s=0.05).fit(learn)
    d = det.detect(signals)
    assert (np.nanmax(d.decision, axis=1) <= np.nanmax(d.residual, axis=1)).all()
    i = int(np.argmin(np.nanmax(d.decision, axis=1)))
    res = d.residual.copy()
    res[i, 500] = 3.0
    dec = windowed_min(res, det._n_confirm(signals.ts))
    assert det._n_confirm(signals.ts) == 6                     # 0.05 s at 10 ms, + 1
    assert np.nanmax(dec[i]) == np.nanmax(d.decision[i]) < 1.0
    assert not decide(dec)[i].any()
