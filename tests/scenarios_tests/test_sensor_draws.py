"""``scenarios.acquisition.sensor_draws`` takes each run's draws from the run's own generator
in a fixed order — 5 uniforms, then the noise series one after the other (COM, MON,
surface, pressure), T normals each — so a run's sensor errors are those of one draw of
5 uniforms and rows·T normals from its stream, whatever the batch."""

from __future__ import annotations

import numpy as np
import pytest

from scenarios.acquisition import sensor_draws
from scenarios.params import SENSORS


@pytest.mark.parametrize("pressure", [False, True])
def test_each_run_draws_its_stream_in_the_documented_order(pressure):
    T, dP, seeds = 500, 2.1e7, (11, 12, 13)
    got = sensor_draws([np.random.default_rng(s) for s in seeds], T, SENSORS, dP, pressure)
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
