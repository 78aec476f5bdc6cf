"""Cost of the aircraft plant level against the actuator level, and of the JSBSim plant
against its flight model alone (``fdd-campaign bench``).

Both levels simulate the same run rows (the aircraft level monitors the left elevator and
adds the rigid-body aircraft, the laws and the six other surfaces' servo-loops), one after
the other in the same process, so the ratio is comparable on a shared machine. The JSBSim
plant (``bench --plant jsbsim``) is timed in CPU seconds of this process against its floor:
the same number of JSBSim FDMs trimmed and stepped as many times with nothing else.
"""

from __future__ import annotations

import time

import numpy as np
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


def _realistic_fault_free(runs: pd.DataFrame) -> pd.DataFrame:
    """*runs* fault-free, each at a realistic [CHEN] Table-1 point in turn (the JSBSim plant
    trims every realistic point; a runaway held for the rest of a run, or a corner of the
    grid outside the realistic envelope, may leave the 737's envelope, and the load is
    there to time the plant, not to find its limits)."""
    from scenarios import envelope

    pts = envelope.realistic_points()
    pts = pts[pts["realistic"]].reset_index(drop=True)
    at = pts.iloc[np.arange(len(runs)) % len(pts)]
    return runs.assign(fault="none", onset_s=np.nan, magnitude=np.nan,
                       **{c: at[c].to_numpy(float) for c in envelope.FLIGHT_COLUMNS})


def jsbsim_cost(runs: pd.DataFrame, echo=print) -> dict:
    """CPU time of *runs* on the JSBSim plant (its blocks of ``batch_runs``, calm air) per run
    and per simulated second, and its floor: JSBSim's 737 alone, one FDM per run trimmed at
    the first run's point (twice: the plant trims a nominal aircraft at the measured point
    for the laws and the true one it flies) and stepped as many times, surfaces held.
    The ratio plant/floor is the cost of everything that is ours (servo-loops, laws,
    sensors, faults, and the per-step Python calls between them and the FDMs)."""
    from scenarios.jsbsim import fdm as F
    from scenarios.jsbsim.loop import JsbsimPlant

    plant = JsbsimPlant(turbulence="none")
    rows = _realistic_fault_free(runs.assign(
        surface=[DEFAULT_MONITORED[s] for s in runs["surface"]]))
    duration = float(rows["duration_s"].iloc[0])
    steps = int(round(duration / TS_S))
    c0 = time.process_time()
    for start in range(0, len(rows), plant.batch_runs):
        plant.simulate(rows.iloc[start:start + plant.batch_runs].reset_index(drop=True))
    plant_s = (time.process_time() - c0) / len(rows)
    model = F.aircraft_model(plant.aircraft)
    c1 = time.process_time()
    for _ in range(len(rows)):
        F.Fdm(model, TS_S).trim(28000.0, 280.0, 47.0, 20.0)
        fdm = F.Fdm(model, TS_S)
        fdm.trim(28000.0, 280.0, 47.0, 20.0)
        for _ in range(steps):
            fdm.set_surfaces(*fdm.trim_surfaces)
            fdm.step()
            fdm.read()
    floor_s = (time.process_time() - c1) / len(rows)
    figures = {"jsbsim_runs": len(rows), "jsbsim_cpu_s_per_run": plant_s,
               "jsbsim_cpu_s_per_simulated_s": plant_s / duration,
               "jsbsim_floor_cpu_s_per_run": floor_s, "jsbsim_over_floor": plant_s / floor_s}
    echo(f"  JSBSim plant          : {len(rows)} runs of {duration:g} s: {plant_s:.2f} CPU-s "
         f"per run ({plant_s / duration * 1000:.1f} ms per simulated s); its 737 alone "
         f"{floor_s:.2f} CPU-s per run -> plant/floor {plant_s / floor_s:.1f} x")
    return figures
