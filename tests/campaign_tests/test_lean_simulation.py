"""What the simulator and the runner skip or free to save memory changes no result."""

from __future__ import annotations

import numpy as np
import pandas as pd

from campaign.evaluate import _scoring_truth
from scenarios.simulate import simulate, single_run

SIGNALS = ("command", "current", "rod_com", "rod_mon", "surface")


def _runs() -> pd.DataFrame:
    rows = [single_run("elevator", man, f, seed=i, onset_s=5.0, duration_s=20.0)
            for i, (man, f) in enumerate([("cruise", "none"), ("nose_up", "liquid_jam"),
                                          ("cruise", "solid_jam"), ("nose_up", "runaway")])]
    frame = pd.concat(rows, ignore_index=True)
    frame["stream"] = np.arange(len(frame))
    frame["run_id"] = [f"m{i}" for i in range(len(frame))]
    return frame


def test_pressure_noise_is_not_drawn_without_the_sensor_and_nothing_else_moves():
    # the pressure noise is the last draw of a run's sensor stream: skipping it must leave
    # every other signal and the true trajectory equal bit for bit
    runs = _runs()
    with_p, truth_p = simulate(runs, pressure_sensor=True)
    without, truth = simulate(runs, pressure_sensor=False)
    for name in SIGNALS:
        np.testing.assert_array_equal(getattr(without, name), getattr(with_p, name),
                                      err_msg=name)
    np.testing.assert_array_equal(truth.rod_mm, truth_p.rod_mm)
    assert np.isfinite(with_p.pressure).all()
    assert without.pressure.shape == with_p.pressure.shape
    assert np.isnan(without.pressure).all() and not without.has_pressure_sensor
    taken = without.take([1, 3])                       # the all-NaN view indexes like an array
    assert taken.pressure.shape == (2, without.n_steps) and np.isnan(taken.pressure).all()


def test_scoring_truth_keeps_what_scoring_reads():
    _, truth = simulate(_runs())
    lean = _scoring_truth(truth)
    np.testing.assert_array_equal(lean.fault, truth.fault)
    np.testing.assert_array_equal(lean.onset_s, truth.onset_s)
    assert lean.rod_mm.shape == truth.rod_mm.shape and np.isnan(lean.rod_mm).all()
    one = lean.take([2])                               # the run-by-run retry path
    assert list(one.fault) == [truth.fault[2]] and one.onset_s[0] == truth.onset_s[2]
