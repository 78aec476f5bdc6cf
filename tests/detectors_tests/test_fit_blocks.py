"""The built-in detectors' fits reduce their residuals to per-run maxima a block of runs at a
time (detectors.base.per_run_maxima): the learned thresholds must be those of the whole
learning set at once, bit for bit, whatever the block size."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from detectors import base, make_detector
from scenarios.plants import simulate
from scenarios.simulate import single_run


def _learning(surface: str, plant: str, manoeuvres, duration_s: float):
    runs = pd.concat([single_run(surface, m, "none", seed=5, duration_s=duration_s)
                      .assign(stream=j, run_id=f"learn-{j}") for j, m in enumerate(manoeuvres)],
                     ignore_index=True)
    return replace(simulate(runs, plant=plant)[0], classes=np.asarray(list(manoeuvres)))


def test_per_run_maxima_takes_each_runs_maximum_across_uneven_blocks():
    signals = _learning("aileron", "actuator", ("cruise",) * 7, 20.0)
    seen = []

    def statistics(block):
        seen.append(block.n_runs)
        return {"a": block.command, "b": -block.command}

    got = base.per_run_maxima(signals, statistics, block_runs=3)
    assert seen == [3, 3, 1]                       # 7 runs: two full blocks and the rest
    np.testing.assert_array_equal(got["a"], signals.command.max(axis=1))
    np.testing.assert_array_equal(got["b"], (-signals.command).max(axis=1))
    assert base.per_run_maxima(signals, statistics, block_runs=0)["a"].shape == (7,)


@pytest.mark.parametrize("name, surface, plant, threshold_attr", [
    ("position-monitor", "aileron", "actuator", "thresholds_mm_"),
    ("chen-local", "aileron", "actuator", "thresholds_"),
    ("chen-global", "left_inboard_aileron", "aircraft", "threshold_"),
])
def test_a_fit_in_blocks_of_one_run_learns_the_whole_sets_thresholds(
        name, surface, plant, threshold_attr, monkeypatch):
    """Blocks of one run against one block of every run: the same thresholds, to the bit
    (a residual of a run never depends on the runs beside it)."""
    signals = _learning(surface, plant, ("cruise", "nose_up", "turn_coordination"), 20.0)
    learned = {}
    for block in (1, 1000):
        monkeypatch.setattr(base, "FIT_BLOCK_RUNS", block)
        det = make_detector(name, {"threshold_method": "max"}).fit(signals)
        learned[block] = getattr(det, threshold_attr)
    assert learned[1] == learned[1000]
    values = learned[1].values() if isinstance(learned[1], dict) else [learned[1]]
    assert all(np.isfinite(v) and v > 0 for v in values)


class _Recording:
    """The actuator plant, recording how many runs each call simulates."""

    kind = "actuator"
    needs_processes = False

    def __init__(self, **sizes):
        from scenarios.simulate import ActuatorPlant

        self.inner, self.calls = ActuatorPlant(), []
        for name, value in sizes.items():
            setattr(self, name, value)

    def simulate(self, runs, **kw):
        self.calls.append(len(runs))
        return self.inner.simulate(runs, **kw)


@pytest.mark.parametrize("sizes, largest", [
    ({"learning_part_runs": 3, "batch_runs": 5}, 3),   # the learning set's own part size
    ({"batch_runs": 5}, 5),                            # else the plant's simulation blocks
    ({}, 8),                                           # else LEARNING_PART_RUNS (patched)
])
def test_the_learning_set_is_simulated_in_the_plants_parts_with_the_same_signals(
        sizes, largest, monkeypatch):
    from campaign import runner
    from campaign.config import load_config
    from campaign.plan import build_learning_plan
    from campaign.plant_setup import resolve

    monkeypatch.setattr(runner, "LEARNING_PART_RUNS", 8)
    config = load_config("smoke")
    plan = build_learning_plan(resolve(config)).iloc[:11]
    plan = plan.assign(duration_s=20.0)
    settings = replace(runner.settings_of(resolve(config)), plant=_Recording(**sizes))
    parts = runner.simulate_chunks(plan, settings, chunk_size=100)
    whole = replace(settings, plant=_Recording(learning_part_runs=100))
    once = runner.simulate_chunks(plan, whole, chunk_size=100)
    assert settings.plant.calls[0] == largest and sum(settings.plant.calls) == 11
    assert max(settings.plant.calls) == largest
    assert whole.plant.calls == [11]
    np.testing.assert_array_equal(parts.rod_com, once.rod_com)
    np.testing.assert_array_equal(parts.command, once.command)
