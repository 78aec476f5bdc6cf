"""The actuator servo-loop plant: ``simulate(runs) -> (Signals, Truth)``.

``runs`` is a table (pandas DataFrame) with one row per run and the columns of
:data:`scenarios.runs.RUN_COLUMNS` — exactly the rows of a campaign's run table. The time
loop advances every run of the batch at once (arrays of shape ``(n_runs,)``); everything that
does not depend on the closed loop (orders, noise, fault injection arrays) is prepared before
it and everything that only reads the trajectory (MON, surface and pressure sensors,
:mod:`scenarios.acquisition`) after it.

Time base (docs/physics.md §2): the FCC runs every Ts. At t_k it acquires the COM rod position,
computes i_k = sat(K·(u_k − y_k), ±i_max) and holds it over the *next* period (one Ts of
transport delay): the current flowing over [t_k, t_k+1) is i_{k−1}. The plant is advanced
over each period with one classical RK4 step (the current is constant within the period,
so the step sees a smooth right-hand side; stops and fault onsets act at step boundaries).
The tests compare it with ``solve_ivp`` at rtol 1e-9 (:mod:`scenarios.reference`).

Determinism: run i draws only from ``SeedSequence(seed, spawn_key=(stream,))`` (columns
``seed`` and ``stream``), spawned into a manoeuvre/turbulence stream and a sensor stream.
A run simulated alone equals the same run inside any batch, bit for bit.

:class:`ActuatorPlant` is this module as a :class:`scenarios.plants.Plant`; an FMU plant
(:mod:`scenarios.fmu`) reuses :func:`simulate` with its own integrator.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from functools import partial
from typing import Callable

import numpy as np
import pandas as pd

from . import manoeuvres
from .acquisition import (Prepared, Trajectory, acquire, acquire_com, applied_current,
                          chamber_pressure, quantize, sensor_draws)
from .aircraft.data import AIRCRAFT_SURFACES, surface_actuator
from .catalog import FAULTS, SURFACES
from .faults import (FAULT_DEFAULTS, NEVER, ROD_MEASUREMENT_FAULTS, default_magnitude,
                     fault_arrays, jam_onset_position, onset_steps)
from .compiled import integrate_compiled, resolve_engine, sensor_draws_1, servo_model
from .params import ACTUATORS, SENSORS, TS_S, ActuatorParams, SensorParams
from .runs import (RUN_COLUMNS, RUN_RANGES, RunSpecError, flight_of, manoeuvre_sets,
                   plant_draws, run_streams, validate_runs)
from .servo import PlantArrays, authority_limits, float_step, plant_arrays, rk4_step
from .signals import SERVO_GROUPS, Signals, Truth

__all__ = ["ActuatorPlant", "DEFAULT_POINT", "Prepared", "RUN_COLUMNS", "RunSpecError",
           "Trajectory", "acquire_com", "applied_current", "chamber_pressure", "integrate",
           "prepare", "quantize", "rod_measurement_fault", "simulate", "single_run"]


def prepare(runs: pd.DataFrame, *, ts: float = TS_S, sensors: SensorParams = SENSORS,
            actuators: dict | None = None, orders_deg: np.ndarray | None = None,
            pressure_sensor: bool = True, engine: str | None = None) -> Prepared:
    """Validate *runs* and compute every open-loop input of the batch.

    *orders_deg* (n_runs, n_steps), when given, replaces the manoeuvre-generated surface
    orders [deg] (recorded flight-test orders, or the test signals of the physics checks).
    *pressure_sensor* False leaves ``pres_noise`` None (not drawn; no other draw changes).
    *engine*: how the per-run draws are made (:func:`scenarios.acquisition.sensor_draws`,
    :func:`scenarios.turbulence.lagged_gust`; the same values with either); default
    :func:`scenarios.compiled.current_engine`.
    """
    validate_runs(runs)
    actuators = actuators or ACTUATORS
    act = actuators[str(runs["surface"].iloc[0])]
    n = len(runs)
    T = int(round(float(runs["duration_s"].iloc[0]) / ts))
    col = {c: runs[c].to_numpy() for c in RUN_COLUMNS}
    f = {c: np.asarray(col[c], dtype=float) for c in RUN_RANGES}

    flight_true, schedule = flight_of(f)
    plant = plant_arrays(act, qbar_pa=flight_true["qbar_pa"], alpha_deg=flight_true["alpha_deg"],
                         mach=flight_true["mach"], **plant_draws(f))

    t = np.arange(T) * ts
    gens = [run_streams(s, k) for s, k in zip(col["seed"], col["stream"])]
    if orders_deg is None:
        params = [manoeuvres.set_params(m) for m in manoeuvre_sets(runs)]
        shortest = max(p.min_duration_s for p in params)
        if T * ts < shortest - 1e-9:       # the manoeuvres' own check, said of the run row
            raise RunSpecError([f"duration_s: {T * ts:g} s is shorter than the {shortest:g} s "
                                "the manoeuvres of the servo-loop plant need "
                                "(ManoeuvreParams.min_duration_s); fix: a duration of at "
                                f"least {shortest:g} s"])
        order_deg = manoeuvres.orders_for_runs(
            list(col["manoeuvre"].astype(str)), act.surface, t,
            {k: flight_true[k] for k in ("qbar_pa", "tas_ms", "alt_ft", "alpha_deg", "cg_pct",
                                         "mach")},
            [g[0] for g in gens], act,
            params=params,
            start_s=(runs["manoeuvre_start_s"].to_numpy(float)
                     if "manoeuvre_start_s" in runs.columns else None), engine=engine)
        lo, hi = authority_limits(plant, act)
        order_deg = np.clip(order_deg, lo[:, None], hi[:, None])
    else:
        order_deg = np.asarray(orders_deg, dtype=float)
        if order_deg.shape != (n, T) or not np.isfinite(order_deg).all():
            raise RunSpecError([f"orders_deg must be finite with shape {(n, T)} "
                                f"(runs × duration_s/ts), got {order_deg.shape}"])
    u = act.deg_to_mm(order_deg)

    stack = sensor_draws([g[1] for g in gens], T, sensors, act.dP_Pa, pressure=pressure_sensor,
                         draw_run=sensor_draws_1 if resolve_engine(engine) == "compiled" else None)

    faults = fault_arrays(col["fault"], col["onset_s"], col["magnitude"], col["freq_hz"],
                          order_deg, act, ts, plant.i_max, command_mm=u)
    return Prepared(
        act=act, ts=ts, plant=plant, order_deg=order_deg, u=u, faults=faults,
        com_bias=stack[0], com_scale=stack[1], com_noise=stack[2],
        mon_bias=stack[3], mon_scale=stack[4], mon_noise=stack[5],
        surf_bias=stack[6], surf_noise=stack[7], pres_noise=stack[8],
        flight_true=flight_true, schedule=schedule,
    )



def integrate(p: Prepared, sensors: SensorParams = SENSORS) -> Trajectory:
    """The closed-loop time loop, vectorised over the runs of the batch."""
    n, T = p.u.shape
    pl, fa, act, ts = p.plant, p.faults, p.act, p.ts
    d_min, d_max = np.radians(act.stop_min_deg), np.radians(act.stop_max_deg)
    xs = np.empty((n, T))
    ds = np.empty((n, T))
    icmd = np.empty((n, T))
    iapp = np.empty((n, T))
    ycom = np.empty((n, T))

    x = np.clip(p.u[:, 0].copy(), pl.x_min, pl.x_max)     # trimmed: x(0) = order, i = 0
    delta = np.arcsin(x / pl.r_mm)
    i_prev = np.zeros(n)
    y_hold = np.zeros(n)
    any_jam = bool((fa.k_jam < NEVER).any())
    any_disc = bool((fa.k_disc < NEVER).any())
    loaded = np.ones(n, dtype=bool)
    for k in range(T):
        if any_jam:   # an "offset" solid jam: the rod jumps at its onset (docs/physics.md §5)
            x_prev, x = x, jam_onset_position(x, k, fa, pl.x_min, pl.x_max)
            if x is not x_prev:
                delta = np.where(x != x_prev, np.arcsin(x / pl.r_mm), delta)
        y, y_hold = acquire_com(x, k, p, sensors, y_hold)
        i_new = np.clip(pl.K * (fa.u_loop[:, k] - y), -pl.i_max, pl.i_max)
        i_app = applied_current(i_prev, k, p)
        xs[:, k] = x
        ds[:, k] = delta
        icmd[:, k] = i_new
        iapp[:, k] = i_app
        ycom[:, k] = y
        if any_disc:
            loaded = k < fa.k_disc
        x_next = rk4_step(x, i_app, pl, loaded, ts)
        if any_jam:
            x_next = np.where(k >= fa.k_jam, x, x_next)
        if any_disc:
            with np.errstate(invalid="ignore", divide="ignore"):
                floating = float_step(delta, pl, ts, d_min, d_max)
            delta = np.where(loaded, np.arcsin(x_next / pl.r_mm), floating)
        else:
            delta = np.arcsin(x_next / pl.r_mm)
        x = x_next
        i_prev = i_new
    return Trajectory(x=xs, delta=ds, i_cmd=icmd, i_app=iapp, y_com=ycom)



def rod_measurement_fault(fault, onset_s, y_com, order_mm, plant, ts: float):
    """The additive fault f [mm] of [CHEN] eq. 4 on the COM rod measurement of each jam run,
    from its onset on: f = y − x, y the COM acquisition of the run, x the rod of the
    *healthy, noise-free* servo-loop driven by the same order (true plant of the run,
    :func:`scenarios.compiled.servo_model`) — [CHEN]'s "fault-free rod sensor output"
    (docs/physics.md §5). For a liquid jam f starts at the bias and fades as the loop
    re-centres the biased measurement on the order; for a solid jam f = y_jam − x follows
    the order away from the stuck measurement.

    fault, onset_s (n,); y_com, order_mm (n, T) [mm]; *plant* the true
    :class:`scenarios.servo.PlantArrays` of the batch. Returns (n, T): NaN before onset
    and for runs of other fault types; None when the batch holds no jam (nothing to
    compute). A fault estimate f̂ built from y with an identity fault-to-estimate gain
    then errs by f̂ − f = (y − x̂) − (y − x) = x − x̂ after onset: the estimator's
    model error alone, sensor noise cancelling.
    """
    fault = np.asarray(fault).astype(str)
    jam = np.flatnonzero(np.isin(fault, ROD_MEASUREMENT_FAULTS))
    if jam.size == 0:
        return None
    y_com = np.asarray(y_com, dtype=float)
    n, T = y_com.shape
    sub = PlantArrays(**{k: np.asarray(v)[jam] for k, v in vars(plant).items()})
    order = np.asarray(order_mm, dtype=float)[jam]
    healthy = servo_model(order, np.clip(order[:, 0], sub.x_min, sub.x_max), sub, ts)
    k0 = onset_steps(np.asarray(onset_s, dtype=float)[jam], ts)
    after = np.arange(T)[None, :] >= k0[:, None]
    out = np.full((n, T), np.nan)
    out[jam] = np.where(after, y_com[jam] - healthy, np.nan)
    return out


#: Closed-loop integrator of a prepared batch: (Prepared, SensorParams) → Trajectory.
Integrator = Callable[[Prepared, SensorParams], Trajectory]


def simulate(runs: pd.DataFrame, *, ts: float = TS_S, sensors: SensorParams = SENSORS,
             pressure_sensor: bool = False, actuators: dict | None = None,
             orders_deg: np.ndarray | None = None, engine: str | None = None,
             integrator: Integrator | None = None,
             timings: dict | None = None) -> tuple[Signals, Truth]:
    """Simulate every run of *runs* on the actuator servo-loop (one surface and duration per
    call).

    Returns the :class:`Signals` a detector may read and the :class:`Truth` only scoring
    sees. Raises :class:`RunSpecError` (listing every problem) before any work on bad rows.
    *engine*: ``"compiled"`` (numba kernels, :mod:`scenarios.compiled`) or ``"numpy"`` (the
    reference :func:`integrate`); default :func:`scenarios.compiled.current_engine`.
    *integrator* replaces the built-in time loop (an FMU plant advances the physical plant
    with its FMU, :mod:`scenarios.fmu`); the FCC, sensors and faults stay the engine's.
    Other plants (the aircraft, an FMU) are reached through :mod:`scenarios.plants`.
    *timings*, a dict, receives the CPU seconds of the calling thread in each stage
    (``"preparation"``, ``"plant"``, ``"sensors and truth"``; added to what it holds), for
    ``fdd-campaign bench``.
    """
    engine = resolve_engine(engine)
    clock = [time.thread_time()]

    def lap(stage):
        if timings is not None:
            now = time.thread_time()
            timings[stage] = timings.get(stage, 0.0) + now - clock[0]
            clock[0] = now

    p = prepare(runs, ts=ts, sensors=sensors, actuators=actuators, orders_deg=orders_deg,
                pressure_sensor=pressure_sensor, engine=engine)
    lap("preparation")
    if integrator is not None:
        traj = integrator(p, sensors)
    elif engine == "compiled":
        traj = integrate_compiled(p, sensors)
    else:
        traj = integrate(p, sensors)
    lap("plant")
    act = p.act
    rod_fault = partial(rod_measurement_fault, runs["fault"].to_numpy(),
                        runs["onset_s"].to_numpy(float), traj.y_com, p.u, p.plant, ts)
    p = replace(p, order_deg=None, com_noise=None)   # read by the time loop only: free them
    mon, surface_deg, surface, pressure = acquire(traj, p, act, sensors, pressure_sensor)
    signals = Signals(
        ts=ts, command=p.u, current=traj.i_cmd, rod_com=traj.y_com, rod_mon=mon,
        surface=surface, pressure=pressure, schedule=p.schedule, actuator=act,
        run_ids=runs["run_id"].astype(str).to_numpy(),
    )
    truth = Truth(
        rod_mm=traj.x, surface_deg=surface_deg, current_mA=traj.i_app,
        fault=runs["fault"].astype(str).to_numpy(),
        onset_s=runs["onset_s"].to_numpy(float), magnitude=runs["magnitude"].to_numpy(float),
        flight=p.flight_true, rod_fault_mm=rod_fault,      # computed when first read
    )
    lap("sensors and truth")
    return signals, truth


def servo_provides(act: ActuatorParams, pressure_sensor: bool) -> frozenset[str]:
    """Signal groups of a servo-loop acquisition of *act* (:data:`scenarios.signals.SERVO_GROUPS`
    always; ``"surface"`` when the surface has a position sensor; ``"pressure"`` when the
    chamber pressure sensor is on)."""
    groups = set(SERVO_GROUPS)
    if act.has_surface_sensor:
        groups.add("surface")
    if pressure_sensor:
        groups.add("pressure")
    return frozenset(groups)


class ServoLoopPlant:
    """What every plant of one surface's servo-loop alone shares (the built-in one and an
    FMU): the run rows name ``elevator`` or ``aileron``, with their actuator tables."""

    @property
    def surfaces(self) -> tuple[str, ...]:
        return SURFACES

    def run_surface(self, surface: str, monitored: str | None = None) -> str:
        """The run rows' ``surface`` for a campaign on *surface* (no monitored surface)."""
        return surface

    def actuator(self, surface: str) -> ActuatorParams:
        return ACTUATORS[surface]

    def provides(self, surface: str, *, pressure_sensor: bool) -> frozenset[str]:
        return servo_provides(self.actuator(surface), pressure_sensor)


@dataclass(frozen=True)
class ActuatorPlant(ServoLoopPlant):
    """The built-in nonlinear servo-loop of one surface, alone (docs/physics.md §3): a
    :class:`scenarios.plants.Plant`."""

    kind = "actuator"
    #: runs on threads: the compiled kernels release the GIL and hold no state
    needs_processes = False
    #: evaluations of the rate law (docs/physics.md §3) per run and step: the rod's RK4
    #: (``fdd-campaign bench``'s arithmetic floor)
    rate_evaluations_per_step = 4

    def check(self, faults=()) -> None:
        """Nothing to check before work: the built-in plant simulates every fault."""

    def simulate(self, runs: pd.DataFrame, *, ts: float = TS_S, sensors: SensorParams = SENSORS,
                 pressure_sensor: bool = False) -> tuple[Signals, Truth]:
        return simulate(runs, ts=ts, sensors=sensors, pressure_sensor=pressure_sensor)


#: Flight point of a single run when none is given (a mid-envelope cruise point).
DEFAULT_POINT = {"alt_ft": 28000.0, "vcas_kt": 300.0, "mass_t": 180.0, "cg_pct": 30.0}


def single_run(surface: str = "elevator", manoeuvre: str = "cruise", fault: str = "none", *,
               seed: int = 0, onset_s: float = 10.0, magnitude: float | None = None,
               freq_hz: float | None = None, duration_s: float = 30.0, **point) -> pd.DataFrame:
    """A one-row run table (defaults: :data:`DEFAULT_POINT`, nominal uncertainties, the
    default fault magnitudes of :mod:`scenarios.faults`)."""
    unknown = sorted(set(point) - set(DEFAULT_POINT)
                     - {c for c in RUN_COLUMNS if c.startswith("d_")})
    if unknown:
        raise ValueError(
            f"unknown run field(s) {unknown}; allowed: "
            f"{sorted(DEFAULT_POINT) + [c for c in RUN_COLUMNS if c.startswith('d_')]}")
    act = ACTUATORS.get(surface)
    if act is None and surface in AIRCRAFT_SURFACES:   # an aircraft surface: its own table
        act = surface_actuator(surface)
    row = {
        "run_id": f"{surface}-{manoeuvre}-{fault}-{seed}", "surface": surface,
        "manoeuvre": manoeuvre, "fault": fault,
        "onset_s": np.nan if fault == "none" else float(onset_s),
        "magnitude": (default_magnitude(fault, act) if act is not None and fault in FAULTS
                      else np.nan) if magnitude is None else float(magnitude),
        "freq_hz": (FAULT_DEFAULTS.ofc_freq_hz if fault.startswith("ofc") else np.nan)
        if freq_hz is None else float(freq_hz),
        **DEFAULT_POINT,
        **{c: 0.0 for c in RUN_COLUMNS if c.startswith("d_")},
        "seed": int(seed), "stream": 0, "duration_s": float(duration_s),
    }
    row.update({k: float(v) for k, v in point.items()})
    return pd.DataFrame([row], columns=list(RUN_COLUMNS))
