"""Cost of the aircraft plant level against the actuator level (``fdd-campaign bench``).

Both levels simulate the same run rows (the aircraft level monitors the left elevator and
adds the rigid-body aircraft, the laws and the six other surfaces' servo-loops), one after
the other in the same process, so the ratio is comparable on a shared machine.
"""

from __future__ import annotations

import time

import pandas as pd

from scenarios.aircraft.data import DEFAULT_MONITORED
from scenarios.plants import get_plant
from scenarios.simulate import TS_S

from ..evaluate import ChunkSettings, simulate_signals


def bench_settings(plant="actuator") -> ChunkSettings:
    """Pipeline settings of the benchmark loads (``fdd-campaign bench``): 100 Hz, no
    pressure sensor, compiled kernels, on *plant* (``"actuator"``, ``"aircraft"`` or a
    :class:`scenarios.fmu.FmuPlant`). Nothing is scored: no required detection time."""
    return ChunkSettings(ts=TS_S, pressure_sensor=False, required_time_s={}, window_s=None,
                         plant=get_plant(plant))


def plant_cost(runs: pd.DataFrame, echo=print) -> dict:
    """Wall time of one vectorised batch of *runs* at each plant level, and their ratio
    (the simulation stage of the pipeline, :func:`campaign.evaluate.simulate_signals`)."""
    t0 = time.perf_counter()
    simulate_signals(runs, bench_settings())
    actuator_s = time.perf_counter() - t0
    aircraft_runs = runs.assign(surface=[DEFAULT_MONITORED[s] for s in runs["surface"]])
    t1 = time.perf_counter()
    simulate_signals(aircraft_runs, bench_settings("aircraft"))
    aircraft_s = time.perf_counter() - t1
    figures = {"plant_runs": len(runs), "actuator_batch_s": actuator_s,
               "aircraft_batch_s": aircraft_s, "aircraft_over_actuator": aircraft_s / actuator_s}
    echo(f"  plant level cost      : {len(runs)} runs in one process: actuator "
         f"{actuator_s:.2f} s, aircraft {aircraft_s:.2f} s -> aircraft/actuator "
         f"{figures['aircraft_over_actuator']:.1f} x")
    return figures
