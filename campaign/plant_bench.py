"""Cost of the aircraft plant level against the actuator level (``fdd-campaign bench``).

Both levels simulate the same run rows (the aircraft level monitors the left elevator and
adds the rigid-body aircraft, the laws and the six other surfaces' servo-loops), one after
the other in the same process, so the ratio is comparable on a shared machine.
"""

from __future__ import annotations

import time

import pandas as pd

from scenarios.aircraft.data import DEFAULT_MONITORED
from scenarios.plants import simulate


def plant_cost(runs: pd.DataFrame, echo=print) -> dict:
    """Wall time of one vectorised batch of *runs* at each plant level, and their ratio."""
    t0 = time.perf_counter()
    simulate(runs)
    actuator_s = time.perf_counter() - t0
    aircraft_runs = runs.assign(surface=[DEFAULT_MONITORED[s] for s in runs["surface"]])
    t1 = time.perf_counter()
    simulate(aircraft_runs, plant="aircraft")
    aircraft_s = time.perf_counter() - t1
    figures = {"plant_runs": len(runs), "actuator_batch_s": actuator_s,
               "aircraft_batch_s": aircraft_s, "aircraft_over_actuator": aircraft_s / actuator_s}
    echo(f"  plant level cost      : {len(runs)} runs in one process: actuator "
         f"{actuator_s:.2f} s, aircraft {aircraft_s:.2f} s -> aircraft/actuator "
         f"{figures['aircraft_over_actuator']:.1f} x")
    return figures
