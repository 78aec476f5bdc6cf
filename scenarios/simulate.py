"""Simulate a batch of runs: ``simulate(runs) -> (Signals, Truth)``.

``runs`` is a table (pandas DataFrame) with one row per run and the columns of
:data:`RUN_COLUMNS` — exactly the rows of a campaign's run table. The time loop advances
every run of the batch at once (arrays of shape ``(n_runs,)``); everything that does not
depend on the closed loop (orders, noise, fault injection arrays) is prepared before it and
everything that only reads the trajectory (MON, surface and pressure sensors) after it.

Time base (docs/physics.md §2): the FCC runs every Ts. At t_k it acquires the COM rod position,
computes i_k = sat(K·(u_k − y_k), ±i_max) and holds it over the *next* period (one Ts of
transport delay): the current flowing over [t_k, t_k+1) is i_{k−1}. The plant is advanced
over each period with one classical RK4 step (the current is constant within the period,
so the step sees a smooth right-hand side; stops and fault onsets act at step boundaries).
The tests compare it with ``solve_ivp`` at rtol 1e-9 (:mod:`scenarios.reference`).

Determinism: run i draws only from ``SeedSequence(seed, spawn_key=(stream,))`` (columns
``seed`` and ``stream``), spawned into a manoeuvre/turbulence stream and a sensor stream.
A run simulated alone equals the same run inside any batch, bit for bit.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from . import envelope, manoeuvres
from .catalog import FAULTS, MANOEUVRES, SURFACES, suggest
from .faults import (FAULT_DEFAULTS, NEVER, FaultArrays, default_magnitude, fault_arrays,
                     required_magnitude)
from .kernels import integrate_compiled, resolve_engine
from .params import ACTUATORS, SENSORS, TS_S, ActuatorParams, SensorParams
from .servo import PlantArrays, authority_limits, float_step, plant_arrays, rk4_step
from .signals import Signals, Truth

#: Columns of a run row: name → (unit, meaning). The campaign's run table carries them.
RUN_COLUMNS: dict[str, tuple[str, str]] = {
    "run_id": ("-", "identity of the run"),
    "surface": ("-", "controlled surface: " + ", ".join(SURFACES)),
    "manoeuvre": ("-", "fault-free manoeuvre: " + ", ".join(MANOEUVRES)),
    "fault": ("-", "fault type: " + ", ".join(FAULTS)),
    "onset_s": ("s", "fault onset (NaN for a fault-free run)"),
    "magnitude": ("(per fault)", "fault magnitude, see scenarios.faults"),
    "freq_hz": ("Hz", "oscillation frequency of an OFC (NaN otherwise)"),
    "alt_ft": ("ft", "true pressure altitude"),
    "vcas_kt": ("kt", "true calibrated airspeed"),
    "mass_t": ("t", "true mass"),
    "cg_pct": ("% MAC", "true centre of gravity"),
    "d_aero": ("-", "relative aerodynamic-coefficient error ([CHEN] Table 2)"),
    "d_vcas": ("-", "relative VCAS measurement error ([CHEN] Table 2)"),
    "d_alt": ("-", "relative altitude measurement error ([CHEN] Table 2)"),
    "d_mass": ("-", "relative mass estimation error ([CHEN] Table 2)"),
    "d_cg": ("-", "relative CG estimation error ([CHEN] Table 2)"),
    "d_supply": ("-", "relative supply-pressure mismatch (docs/physics.md §6, est.)"),
    "d_kci": ("-", "relative servo-valve gain mismatch (docs/physics.md §6, est.)"),
    "d_hinge": ("-", "relative hinge-moment mismatch (docs/physics.md §6, est.)"),
    "seed": ("-", "campaign seed"),
    "stream": ("-", "run stream index: SeedSequence(seed, spawn_key=(stream,))"),
    "duration_s": ("s", "run duration"),
}

#: Optional columns of a run row (absent or NaN: the default behaviour).
OPTIONAL_RUN_COLUMNS: dict[str, tuple[str, str]] = {
    "manoeuvre_start_s": ("s", "fixed start of the manoeuvre (NaN: sampled per run)"),
}

#: Physical ranges accepted for run rows (inclusive): column → (low, high).
RUN_RANGES: dict[str, tuple[float, float]] = {
    "alt_ft": (0.0, 45000.0),
    "vcas_kt": (80.0, 400.0),
    "mass_t": (50.0, 300.0),
    "cg_pct": (0.0, 60.0),
    "duration_s": (1.0, 3600.0),
    "d_aero": (-0.5, 0.5), "d_vcas": (-0.5, 0.5), "d_alt": (-0.5, 0.5), "d_mass": (-0.5, 0.5),
    "d_cg": (-0.5, 0.5), "d_supply": (-0.5, 0.5), "d_kci": (-0.5, 0.5), "d_hinge": (-0.9, 0.9),
}


class RunSpecError(ValueError):
    """A run table that cannot be simulated; ``errors`` lists every problem found."""

    def __init__(self, errors):
        self.errors = list(errors)
        super().__init__("invalid run table:\n  - " + "\n  - ".join(self.errors))

    def __reduce__(self):
        return (type(self), (self.errors,))


def validate_runs(runs: pd.DataFrame, surfaces: tuple[str, ...] = SURFACES) -> None:
    """Raise :class:`RunSpecError` listing every problem of *runs* (names, ranges, onsets);
    *surfaces* are the allowed surface names (the aircraft plant has its own)."""
    errors = []
    missing = [c for c in RUN_COLUMNS if c not in runs.columns]
    if missing:
        raise RunSpecError([f"missing column(s) {missing}; a run row needs {list(RUN_COLUMNS)}"])
    if len(runs) == 0:
        raise RunSpecError(["the run table is empty"])
    for col, allowed in (("surface", surfaces), ("manoeuvre", MANOEUVRES), ("fault", FAULTS)):
        bad = sorted(set(runs[col].astype(str)) - set(allowed))
        for value in bad:
            errors.append(f"{col}: unknown value {value!r}{suggest(value, allowed)}; "
                          f"allowed: {', '.join(allowed)}")
    for col, (lo, hi) in RUN_RANGES.items():
        v = pd.to_numeric(runs[col], errors="coerce").to_numpy(float)
        bad = ~np.isfinite(v) | (v < lo) | (v > hi)
        if bad.any():
            errors.append(f"{col}: {int(bad.sum())} value(s) outside [{lo:g}, {hi:g}] "
                          f"{RUN_COLUMNS[col][0]} (first: {v[bad][0]!r})")
    if runs["surface"].nunique() > 1 or runs["duration_s"].nunique() > 1:
        errors.append("a batch must share one surface and one duration_s; split it first")
    fault = runs["fault"].astype(str).to_numpy()
    onset = runs["onset_s"].to_numpy(float)
    dur = runs["duration_s"].to_numpy(float)
    faulty = fault != "none"
    bad_onset = faulty & (~np.isfinite(onset) | (onset < 0) | (onset >= dur))
    if bad_onset.any():
        errors.append(f"onset_s: {int(bad_onset.sum())} faulty run(s) with an onset outside "
                      f"[0, duration_s) (first: {onset[bad_onset][0]!r} s)")
    needs = np.array([required_magnitude(f) for f in fault])
    bad_mag = needs & ~np.isfinite(runs["magnitude"].to_numpy(float))
    if bad_mag.any():
        errors.append(f"magnitude: {int(bad_mag.sum())} run(s) of fault types "
                      f"{sorted(set(fault[bad_mag]))} need a finite magnitude")
    ofc = np.char.startswith(fault.astype(str), "ofc")
    freq = runs["freq_hz"].to_numpy(float)
    bad_freq = ofc & ~(np.isfinite(freq) & (freq > 0))
    if bad_freq.any():
        errors.append(f"freq_hz: {int(bad_freq.sum())} OFC run(s) need a positive frequency")
    if "manoeuvre_start_s" in runs.columns:
        start = pd.to_numeric(runs["manoeuvre_start_s"], errors="coerce").to_numpy(float)
        bad_start = ~np.isnan(start) & ~((start >= 0) & (start < dur))
        if bad_start.any():
            errors.append(f"manoeuvre_start_s: {int(bad_start.sum())} run(s) with a start "
                          f"outside [0, duration_s) (first: {start[bad_start][0]!r} s)")
    if errors:
        raise RunSpecError(errors)


@dataclass(frozen=True)
class Prepared:
    """Everything the loop needs, computed before it (shapes (n,) or (n, T))."""

    act: ActuatorParams
    ts: float
    plant: PlantArrays
    order_deg: np.ndarray       # fault-free surface order [deg]
    u: np.ndarray               # fault-free rod order [mm] (the command signal)
    faults: FaultArrays
    com_bias: np.ndarray
    com_scale: np.ndarray
    com_noise: np.ndarray       # (n, T) [mm]
    mon_bias: np.ndarray
    mon_scale: np.ndarray
    mon_noise: np.ndarray
    surf_bias: np.ndarray
    surf_noise: np.ndarray      # (n, T) [deg]
    pres_noise: np.ndarray | None   # (n, T) [Pa]; None when the pressure sensor is off
    flight_true: dict
    schedule: dict


def run_streams(seed, stream) -> tuple[np.random.Generator, np.random.Generator]:
    """The run's manoeuvre/turbulence generator and its sensor generator."""
    ss = np.random.SeedSequence(int(seed), spawn_key=(int(stream),))
    man, sens = ss.spawn(2)
    return np.random.default_rng(man), np.random.default_rng(sens)


def _sensor_draws(rngs, T: int, s: SensorParams, dP: float, pressure: bool = True):
    """The sensor errors of every run of a batch, each stacked over the runs (n, …).

    Run i draws from its own generator ``rngs[i]`` in a fixed order (5 uniforms, then 4·T
    normals: COM, MON, surface, pressure noise), so its draws never depend on the batch; the
    scaling is elementwise. *pressure* False skips the pressure noise (the last T normals
    of the run's sensor stream, which nothing draws after) and returns None for it.
    """
    n = len(rngs)
    rows = 4 if pressure else 3
    u = np.empty((n, 5))
    noise = np.empty((rows, n, T))       # each noise series one contiguous (n, T) block
    buf = np.empty((rows, T))
    for i, rng in enumerate(rngs):
        u[i] = rng.uniform(-1.0, 1.0, size=5)
        rng.standard_normal(out=buf)
        noise[:, i] = buf
    noise[0] *= s.rod_noise_mm           # scaled in place: no second copy of the noise
    noise[1] *= s.rod_noise_mm
    noise[2] *= s.surface_noise_deg
    if pressure:
        noise[3] *= s.pressure_noise_frac    # (noise·frac)·ΔP, in that order
        noise[3] *= dP
    return (
        u[:, 0] * s.rod_bias_mm, u[:, 1] * s.rod_scale, noise[0],
        u[:, 2] * s.rod_bias_mm, u[:, 3] * s.rod_scale, noise[1],
        u[:, 4] * s.surface_bias_deg, noise[2],
        noise[3] if pressure else None,
    )


def flight_of(f: dict) -> tuple[dict, dict]:
    """The true flight condition of each run (Mach, q̄, TAS, trimmed α …) and the scheduling
    data a detector sees (measured/estimated, [CHEN] Table 2), from the run columns *f*
    (float arrays: alt_ft, vcas_kt, mass_t, cg_pct and the d_* deviations)."""
    flight = envelope.flight_condition(f["alt_ft"], f["vcas_kt"], f["mass_t"], f["cg_pct"])
    flight_true = {"alt_ft": f["alt_ft"], "vcas_kt": f["vcas_kt"], "mass_t": f["mass_t"],
                   "cg_pct": f["cg_pct"], **{k: np.asarray(v, float) for k, v in flight.items()}}
    schedule = envelope.measured_schedule(
        f["alt_ft"], f["vcas_kt"], f["mass_t"], f["cg_pct"],
        f["d_alt"], f["d_vcas"], f["d_mass"], f["d_cg"])
    return flight_true, schedule


def prepare(runs: pd.DataFrame, *, ts: float = TS_S, sensors: SensorParams = SENSORS,
            actuators: dict | None = None, orders_deg: np.ndarray | None = None,
            pressure_sensor: bool = True) -> Prepared:
    """Validate *runs* and compute every open-loop input of the batch.

    *orders_deg* (n_runs, n_steps), when given, replaces the manoeuvre-generated surface
    orders [deg] (recorded flight-test orders, or the test signals of the physics checks).
    *pressure_sensor* False leaves ``pres_noise`` None (not drawn; no other draw changes).
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
                         mach=flight_true["mach"], d_aero=f["d_aero"], d_hinge=f["d_hinge"],
                         d_supply=f["d_supply"], d_kci=f["d_kci"])

    t = np.arange(T) * ts
    gens = [run_streams(s, k) for s, k in zip(col["seed"], col["stream"])]
    if orders_deg is None:
        order_deg = manoeuvres.orders_for_runs(
            list(col["manoeuvre"].astype(str)), act.surface, t,
            {k: flight_true[k] for k in ("qbar_pa", "tas_ms", "alt_ft", "alpha_deg", "cg_pct",
                                         "mach")},
            [g[0] for g in gens], act,
            start_s=(runs["manoeuvre_start_s"].to_numpy(float)
                     if "manoeuvre_start_s" in runs.columns else None))
        lo, hi = authority_limits(plant, act)
        order_deg = np.clip(order_deg, lo[:, None], hi[:, None])
    else:
        order_deg = np.asarray(orders_deg, dtype=float)
        if order_deg.shape != (n, T) or not np.isfinite(order_deg).all():
            raise RunSpecError([f"orders_deg must be finite with shape {(n, T)} "
                                f"(runs × duration_s/ts), got {order_deg.shape}"])
    u = act.r_mm * np.sin(np.radians(order_deg))

    stack = _sensor_draws([g[1] for g in gens], T, sensors, act.dP_Pa, pressure=pressure_sensor)

    faults = fault_arrays(col["fault"], col["onset_s"], col["magnitude"], col["freq_hz"],
                          order_deg, act, ts, plant.i_max)
    return Prepared(
        act=act, ts=ts, plant=plant, order_deg=order_deg, u=u, faults=faults,
        com_bias=stack[0], com_scale=stack[1], com_noise=stack[2],
        mon_bias=stack[3], mon_scale=stack[4], mon_noise=stack[5],
        surf_bias=stack[6], surf_noise=stack[7], pres_noise=stack[8],
        flight_true=flight_true, schedule=schedule,
    )


def quantize(v, q: float):
    """Round to the acquisition step *q*."""
    return q * np.rint(v / q)


def _quantize_inplace(v: np.ndarray, q: float) -> None:
    """:func:`quantize` of the float array *v* written into *v* (the same operations)."""
    np.divide(v, q, out=v)
    np.rint(v, out=v)
    np.multiply(v, q, out=v)


@dataclass(frozen=True)
class Trajectory:
    """Closed-loop result of the time loop (all (n, T))."""

    x: np.ndarray          # true rod position at t_k [mm]
    delta: np.ndarray      # true surface deflection at t_k [rad]
    i_cmd: np.ndarray      # current order computed by the FCC at t_k [mA]
    i_app: np.ndarray      # current flowing over [t_k, t_k+1) [mA]
    y_com: np.ndarray      # COM acquisition at t_k [mm]


def acquire_com(x, k: int, p: Prepared, sensors: SensorParams, y_hold):
    """COM acquisition at step k, with the liquid-jam bias and the solid-OFC replacement."""
    fa = p.faults
    y = quantize(x * (1.0 + p.com_scale) + p.com_bias + p.com_noise[:, k], sensors.rod_quant_mm)
    if fa.com_add is not None:
        y = y + fa.com_add[:, k]
    if fa.com_osc is not None:
        y_hold = np.where(k == fa.k_osc, y, y_hold)
        y = np.where(k >= fa.k_osc, y_hold + np.nan_to_num(fa.com_osc[:, k]), y)
    return y, y_hold


def applied_current(i_prev, k: int, p: Prepared):
    """Current flowing over [t_k, t_k+1): the previous order, possibly faulted."""
    fa = p.faults
    i_app = i_prev
    if fa.cur_add is not None:
        i_app = i_app + fa.cur_add[:, k]
    if fa.cur_force is not None:
        force = fa.cur_force[:, k]
        i_app = np.where(np.isfinite(force), force, i_app)
    return i_app


def integrate(p: Prepared, sensors: SensorParams = SENSORS) -> Trajectory:
    """The closed-loop time loop, vectorised over the runs of the batch."""
    n, T = p.u.shape
    pl, fa, act, ts = p.plant, p.faults, p.act, p.ts
    d_min, d_max = np.radians(act.stop_min_deg), np.radians(act.stop_max_deg)
    xs = np.empty((n, T)); ds = np.empty((n, T)); icmd = np.empty((n, T))
    iapp = np.empty((n, T)); ycom = np.empty((n, T))

    x = np.clip(p.u[:, 0].copy(), pl.x_min, pl.x_max)     # trimmed: x(0) = order, i = 0
    delta = np.arcsin(x / pl.r_mm)
    i_prev = np.zeros(n)
    y_hold = np.zeros(n)
    any_jam = bool((fa.k_jam < NEVER).any())
    any_disc = bool((fa.k_disc < NEVER).any())
    loaded = np.ones(n, dtype=bool)
    for k in range(T):
        y, y_hold = acquire_com(x, k, p, sensors, y_hold)
        i_new = np.clip(pl.K * (fa.u_loop[:, k] - y), -pl.i_max, pl.i_max)
        i_app = applied_current(i_prev, k, p)
        xs[:, k] = x; ds[:, k] = delta; icmd[:, k] = i_new; iapp[:, k] = i_app; ycom[:, k] = y
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


def chamber_pressure(traj: Trajectory, p: Prepared) -> np.ndarray:
    """Actuator chamber differential (load) pressure [Pa] from the trajectory (docs/physics.md §4).

    Moving rod: ΔP_L = (F_aero + Ka·ẋ|ẋ|)/S; seized rod (solid jam): the valve drives the
    blocked piston to ±ΔP with the pressure gain of :data:`FAULT_DEFAULTS`; disconnected
    rod: no load.
    """
    from .servo import aero_force

    pl, fa, ts = p.plant, p.faults, p.ts
    T = traj.x.shape[1]
    area = p.act.S_m2                                        # piston area S [m²]
    v = np.diff(traj.x, axis=1, append=traj.x[:, -1:]) / ts  # rod speed [mm/s]
    k = np.arange(T)[None, :]
    f_aero = aero_force(traj.x, _broadcast_plant(pl))
    load = (f_aero + pl.Ka[:, None] * v * np.abs(v)) / area
    supply = (pl.SdP / area)[:, None]                        # true ΔP of each run [Pa]
    blocked = supply * np.clip(traj.i_app / FAULT_DEFAULTS.jam_pressure_gain_mA, -1.0, 1.0)
    load = np.where(k >= fa.k_jam[:, None], blocked, load)
    load = np.where(k >= fa.k_disc[:, None], 0.0, load)
    return load


def _broadcast_plant(pl: PlantArrays) -> PlantArrays:
    """The plant arrays as (n, 1) columns, to evaluate them on (n, T) trajectories."""
    return PlantArrays(**{k: np.asarray(v)[:, None] for k, v in vars(pl).items()})


def acquire(traj, p, act: ActuatorParams, sensors: SensorParams, pressure_sensor: bool,
            plant: PlantArrays | None = None):
    """The MON rod, surface and chamber-pressure acquisitions of a trajectory (docs/physics.md §4).

    *p* carries the per-run sensor errors (``mon_*``, ``surf_*``, ``pres_noise``) and the
    fault arrays; *plant* replaces ``p.plant`` for the pressure (the monitored surface's
    plant at the aircraft level). Returns (mon [mm], true surface [deg], surface sensor
    [deg], pressure [Pa]); absent sensors are all-NaN read-only views (no memory).
    Each acquisition is quantize(x·(1 + s) + b + noise), computed in place in one array.
    """
    mon = np.multiply(traj.x, 1.0 + p.mon_scale[:, None])
    mon += p.mon_bias[:, None]
    mon += p.mon_noise
    _quantize_inplace(mon, sensors.rod_quant_mm)
    surface_deg = np.degrees(traj.delta)
    if act.has_surface_sensor:
        surface = np.add(surface_deg, p.surf_bias[:, None])
        surface += p.surf_noise
        _quantize_inplace(surface, sensors.surface_quant_deg)
    else:
        surface = np.broadcast_to(np.nan, surface_deg.shape)
    if pressure_sensor:
        source = p if plant is None else _PressureSource(plant, p.faults, p.ts, act)
        pressure = chamber_pressure(traj, source) + p.pres_noise
    else:
        pressure = np.broadcast_to(np.nan, surface_deg.shape)
    return mon, surface_deg, surface, pressure


@dataclass(frozen=True)
class _PressureSource:
    """What :func:`chamber_pressure` reads besides the trajectory."""

    plant: PlantArrays
    faults: FaultArrays
    ts: float
    act: ActuatorParams


def simulate(runs: pd.DataFrame, *, ts: float = TS_S, sensors: SensorParams = SENSORS,
             pressure_sensor: bool = False, actuators: dict | None = None,
             orders_deg: np.ndarray | None = None, plant="actuator",
             engine: str | None = None) -> tuple[Signals, Truth]:
    """Simulate every run of *runs* (one surface and duration per call).

    *plant* ``"aircraft"`` simulates the aircraft in the loop
    (:func:`scenarios.aircraft.loop.simulate_aircraft`; the run rows' ``surface`` is then
    the monitored aircraft surface).

    Returns the :class:`Signals` a detector may read and the :class:`Truth` only scoring
    sees. Raises :class:`RunSpecError` (listing every problem) before any work on bad rows.
    *plant* may also be a :class:`scenarios.fmu.FmuPlant`: the actuator plant is then
    advanced by that FMU (:mod:`scenarios.fmu`).
    *engine*: ``"compiled"`` (numba kernels, :mod:`scenarios.kernels`) or ``"numpy"`` (the
    reference :func:`integrate`); default :func:`scenarios.kernels.current_engine`.
    """
    if plant == "aircraft":
        from .aircraft.loop import simulate_aircraft

        if actuators is not None or orders_deg is not None:
            raise ValueError("actuators and orders_deg apply to the actuator plant only; the "
                             "aircraft plant computes its orders with its control laws")
        return simulate_aircraft(runs, ts=ts, sensors=sensors, pressure_sensor=pressure_sensor)
    fmu = None if plant in (None, "actuator") else plant
    if isinstance(fmu, str):
        raise ValueError(f"unknown plant {plant!r}; allowed: actuator, aircraft, or a "
                         "scenarios.fmu.FmuPlant")
    engine = resolve_engine(engine)
    p = prepare(runs, ts=ts, sensors=sensors, actuators=actuators, orders_deg=orders_deg,
                pressure_sensor=pressure_sensor)
    if fmu is not None:
        from .fmu import integrate_fmu

        traj = integrate_fmu(p, sensors, fmu)
    elif engine == "compiled":
        traj = integrate_compiled(p, sensors)
    else:
        traj = integrate(p, sensors)
    act = p.act
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
        flight=p.flight_true,
    )
    return signals, truth


#: Flight point of a single run when none is given (a mid-envelope cruise point).
DEFAULT_POINT = {"alt_ft": 28000.0, "vcas_kt": 300.0, "mass_t": 180.0, "cg_pct": 30.0}


def single_run(surface: str = "elevator", manoeuvre: str = "cruise", fault: str = "none", *,
               seed: int = 0, onset_s: float = 10.0, magnitude: float | None = None,
               freq_hz: float | None = None, duration_s: float = 30.0, **point) -> pd.DataFrame:
    """A one-row run table (defaults: :data:`DEFAULT_POINT`, nominal uncertainties, the
    default fault magnitudes of :mod:`scenarios.faults`)."""
    unknown = sorted(set(point) - set(DEFAULT_POINT) - {c for c in RUN_COLUMNS if c.startswith("d_")})
    if unknown:
        raise ValueError(f"unknown run field(s) {unknown}; allowed: "
                         f"{sorted(DEFAULT_POINT) + [c for c in RUN_COLUMNS if c.startswith('d_')]}")
    act = ACTUATORS.get(surface)
    if act is None:                       # an aircraft surface: its own actuator table
        from .aircraft.data import AIRCRAFT_SURFACES

        if surface in AIRCRAFT_SURFACES:
            from .aircraft.loop import surface_actuator

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
