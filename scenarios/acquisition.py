"""What the flight control computer acquires and applies, shared by every servo-loop plant.

The batch of open-loop inputs (:class:`Prepared`), the closed-loop result
(:class:`Trajectory`), the per-run sensor errors (:func:`sensor_draws`), the COM acquisition
and the applied current of one FCC period (:func:`acquire_com`, :func:`applied_current`),
and the MON, surface and chamber-pressure acquisitions of a trajectory (:func:`acquire`).
Sensors: docs/physics.md §4; time base: docs/physics.md §2.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .faults import FAULT_DEFAULTS, FaultArrays
from .params import ActuatorParams, SensorParams
from .servo import PlantArrays, aero_force

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



@dataclass(frozen=True)
class Trajectory:
    """Closed-loop result of the time loop (all (n, T))."""

    x: np.ndarray          # true rod position at t_k [mm]
    delta: np.ndarray      # true surface deflection at t_k [rad]
    i_cmd: np.ndarray      # current order computed by the FCC at t_k [mA]
    i_app: np.ndarray      # current flowing over [t_k, t_k+1) [mA]
    y_com: np.ndarray      # COM acquisition at t_k [mm]



def sensor_draws(rngs, T: int, s: SensorParams, dP: float, pressure: bool = True,
                 draw_run=None):
    """The sensor errors of every run of a batch, each stacked over the runs (n, …).

    Run i draws from its own generator ``rngs[i]`` in a fixed order (5 uniforms, then 4·T
    normals: COM, MON, surface, pressure noise), so its draws never depend on the batch; the
    scaling is elementwise. *pressure* False skips the pressure noise (the last T normals
    of the run's sensor stream, which nothing draws after) and returns None for it.
    *draw_run*: a function ``draw_run(rng, uniforms, noise, i)`` that makes run i's draws
    into ``uniforms`` (5,) and ``noise[:, i]`` in this order — the compiled
    :func:`scenarios.compiled.sensor_draws_1`, which :func:`scenarios.simulate.prepare`
    passes with the compiled engine; the same values bit for bit. None: the generator's own
    methods (the reference).
    """
    n = len(rngs)
    rows = 4 if pressure else 3
    u = np.empty((n, 5))
    noise = np.empty((rows, n, T))       # each noise series one contiguous (n, T) block
    if draw_run is not None:
        for i, rng in enumerate(rngs):
            draw_run(rng, u[i], noise, i)
    else:
        for i, rng in enumerate(rngs):
            u[i] = rng.uniform(-1.0, 1.0, size=5)
            for row in noise[:, i]:          # drawn in place, series after series: the same
                rng.standard_normal(out=row)  # normals, in the same order, as one draw of rows·T
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



def quantize(v, q: float):
    """Round to the acquisition step *q*."""
    return q * np.rint(v / q)


def quantize_inplace(v: np.ndarray, q: float) -> None:
    """:func:`quantize` of the float array *v* written into *v* (the same operations)."""
    np.divide(v, q, out=v)
    np.rint(v, out=v)
    np.multiply(v, q, out=v)



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



def chamber_pressure(traj: Trajectory, p: Prepared) -> np.ndarray:
    """Actuator chamber differential (load) pressure [Pa] from the trajectory (docs/physics.md §4).

    Moving rod: ΔP_L = (F_aero + Ka·ẋ|ẋ|)/S; seized rod (solid jam): the valve drives the
    blocked piston to ±ΔP with the pressure gain of :data:`FAULT_DEFAULTS`; disconnected
    rod: no load.
    """
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
    quantize_inplace(mon, sensors.rod_quant_mm)
    surface_deg = np.degrees(traj.delta)
    if act.has_surface_sensor:
        surface = np.add(surface_deg, p.surf_bias[:, None])
        surface += p.surf_noise
        quantize_inplace(surface, sensors.surface_quant_deg)
    else:
        surface = np.broadcast_to(np.nan, surface_deg.shape)
    if pressure_sensor:
        source = p if plant is None else PressureSource(plant, p.faults, p.ts, act)
        pressure = chamber_pressure(traj, source) + p.pres_noise
    else:
        pressure = np.broadcast_to(np.nan, surface_deg.shape)
    return mon, surface_deg, surface, pressure


@dataclass(frozen=True)
class PressureSource:
    """What :func:`chamber_pressure` reads besides the trajectory."""

    plant: PlantArrays
    faults: FaultArrays
    ts: float
    act: ActuatorParams

