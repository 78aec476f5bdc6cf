"""``scenarios.acquisition.sensor_draws`` takes each run's draws from the run's own generator
in a fixed order — 5 uniforms, then the noise series one after the other (COM, MON,
surface, pressure), T normals each — so a run's sensor errors are those of one draw of
5 uniforms and rows·T normals from its stream, whatever the batch."""

from __future__ import annotations

import numpy as np
import pytest

from scenarios.acquisition import sensor_draws
from scenarios.compiled import sensor_draws_1
from scenarios.params import SENSORS


@pytest.mark.parametrize("draw_run", [None, sensor_draws_1])
@pytest.mark.parametrize("pressure", [False, True])
def test_each_run_draws_its_stream_in_the_documented_order(pressure, draw_run):
    T, dP, seeds = 500, 2.1e7, (11, 12, 13)
    got = sensor_draws([np.random.default_rng(s) for s in seeds], T, SENSORS, dP, pressure,
                       draw_run=draw_run)
    rows = 4 if pressure else 3
    for i, seed in enumerate(seeds):
        rng = np.random.default_rng(seed)
        u = rng.uniform(-1.0, 1.0, size=5)
        noise = rng.standard_normal(rows * T).reshape(rows, T)
        want = (u[0] * SENSORS.rod_bias_mm, u[1] * SENSORS.rod_scale,
                noise[0] * SENSORS.rod_noise_mm, u[2] * SENSORS.rod_bias_mm,
                u[3] * SENSORS.rod_scale, noise[1] * SENSORS.rod_noise_mm,
                u[4] * SENSORS.surface_bias_deg, noise[2] * SENSORS.surface_noise_deg,
                noise[3] * SENSORS.pressure_noise_frac * dP if pressure else None)
        for k, (g, w) in enumerate(zip(got, want)):
            if w is None:
                assert g is None
            else:
                np.testing.assert_array_equal(g[i], w, err_msg=f"output {k}, run {i}")


@pytest.mark.parametrize("pressure", [False, True])
def test_compiled_draws_are_numpys_bit_for_bit_over_millions_of_values(pressure):
    """numba draws from the run's own bit generator with NumPy's algorithms
    (:func:`scenarios.compiled.sensor_draws_1`): over 150 runs of 6000 steps (2.7–3.6·10⁶
    normals, so every branch of the ziggurat, its rare tail among them, is taken many times)
    the compiled draws equal the generator's own methods bit for bit, and each generator is
    left in the same state."""
    T, dP, seeds = 6000, 2.1e7, range(9000, 9150)
    gens_np = [np.random.default_rng(s) for s in seeds]
    gens_nb = [np.random.default_rng(s) for s in seeds]
    ref = sensor_draws(gens_np, T, SENSORS, dP, pressure)
    got = sensor_draws(gens_nb, T, SENSORS, dP, pressure, draw_run=sensor_draws_1)
    for k, (g, w) in enumerate(zip(got, ref)):
        if w is None:
            assert g is None
        else:
            np.testing.assert_array_equal(g, w, err_msg=f"output {k}")
    assert [g.bit_generator.state for g in gens_nb] == [g.bit_generator.state for g in gens_np]
    # the ziggurat's tail (|z| > 3.6541528853610088) was drawn: its branch is covered
    assert np.abs(ref[2] / SENSORS.rod_noise_mm).max() > 3.6541528853610088
