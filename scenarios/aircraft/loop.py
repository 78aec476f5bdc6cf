"""The aircraft-level closed loop of a batch of runs: ``simulate_aircraft(runs)``.

Plant: the rigid-body LPV model of :mod:`.lpv` at each run's true flight point, driven by
the seven primary surfaces, each with its own nonlinear servo-loop — the servo plant of
:mod:`scenarios.servo` (``plant_arrays``, ``rk4_step``, ``float_step``) stacked along a
surface axis: the arrays of the loop have shape (7·n,), surface-major (index s·n + i). The
FCC (every Ts, docs/physics.md §2) acquires the aircraft sensors and every COM rod position at t_k,
computes the laws of :mod:`.laws` and every surface's current i = sat(K·(u − y), ±i_max),
held over the next period (one Ts of transport delay, as at the actuator level); the
spoilers follow the roll order of the previous period (fixed coupling, no servo-loop). The
aircraft state advances exactly over the period (linear model), with the surface deflections of
t_k, their motion to t_k+1 as a ramp (first-order hold) and the gust angles of the Dryden
turbulence (:mod:`scenarios.turbulence`).

Sensors: p, q, r, φ, θ, the load factors, the sideslip and the angle of attack, each plus
its white noise (:class:`scenarios.aircraft.data.AircraftSensorParams`). The sideslip is the
*air-relative* angle β_a = β + β_g, what a vane aligned with the local flow (or a sideslip
computed from the side force, which depends on β_a) gives, not the inertial β of the state;
the angle of attack likewise is the air-relative α0 + α + α_g of an α vane (absolute, like
θ: the trimmed α0 plus the perturbation); the rates, attitudes and load factors are
inertial. The yaw law closes on that measured β_a; no law reads α.

The fault of a run (docs/physics.md §5) acts on the *monitored* surface (column ``surface`` of the
run rows, one of :data:`scenarios.aircraft.data.AIRCRAFT_SURFACES`) through the
actuator-level injection arrays (:func:`scenarios.faults.fault_arrays`) and the same COM
acquisition and current functions as :mod:`scenarios.simulate`; the laws see its effect on
the aircraft and move the other surfaces. The monitored surface's signals fill the
actuator-level fields of :class:`Signals` (command, current, rod_com, rod_mon, surface,
pressure), so actuator-level detectors run unchanged; ``Signals.aircraft`` adds the
aircraft sensors and ``Signals.rods`` every surface's COM rod position.

Determinism: run i draws only from its own streams (:func:`scenarios.runs.run_streams`):
the manoeuvre stream gives the pilot inputs then the turbulence; the sensor stream gives the
monitored surface's sensor errors (same draws as at the actuator level), then the other
surfaces' COM errors, then the aircraft sensor noise.
"""

from __future__ import annotations

import types
from dataclasses import dataclass, fields

import numpy as np
import pandas as pd

from .. import compiled as kernels
from ..acquisition import acquire, acquire_com, applied_current, quantize, sensor_draws
from ..atmosphere import G0_MS2
from ..atmosphere import tas_ms as tas_from_mach
from ..faults import FAULT_DEFAULTS, NEVER, fault_arrays, jam_onset_position
from ..manoeuvres import elevator_trim_deg
from ..memory import release_freed_memory
from ..params import ELEVATOR, SENSORS, TS_S, ActuatorParams, SensorParams
from ..runs import (RUN_COLUMNS, RUN_RANGES, aero_draws, flight_of, manoeuvre_sets,
                    plant_draws, run_streams, validate_runs)
from ..servo import PlantArrays, authority_limits, float_step, plant_arrays, rk4_step
from ..signals import AIRCRAFT_SIGNAL_UNITS, SIGNAL_UNITS, Signals, Truth
from ..simulate import rod_measurement_fault, servo_provides, single_run
from ..turbulence import MODERATE, DrydenParams, dryden_gusts
from ..turbulence import level as turbulence_level
from . import kernel, laws, lpv, pilot
from .data import (AIRCRAFT_ACTUATORS, AIRCRAFT_SENSORS, AIRCRAFT_SURFACES, DEFAULT_MONITORED,
                   LAYOUT, AircraftSensorParams, surface_actuator)

#: Sign of the pitch, roll and yaw orders on each surface (array order of LAYOUT).
_PITCH = np.array([1.0 if k == "elevator" else 0.0 for k in LAYOUT.actuator])
_ROLL = laws.ROLL_DISTRIBUTION[:len(LAYOUT.names)]
_YAW = np.array([1.0 if k == "rudder" else 0.0 for k in LAYOUT.actuator])
_ELEVATORS = _PITCH > 0


@dataclass(frozen=True)
class AircraftPrepared:
    """Everything the aircraft loop needs, computed before it."""

    ts: float
    n: int
    T: int
    monitored: int                # index of the monitored surface
    acts: tuple                   # ActuatorParams of each surface
    plant: PlantArrays            # stacked (7·n,)
    plant_m: PlantArrays          # monitored surface (n,)
    lo_deg: np.ndarray            # (7, n) order limits [deg]: electrical limits and hinge
                                  # load ≤ LawParams.hinge_load_limit × stall force
    hi_deg: np.ndarray
    trim_deg: np.ndarray          # (7, n) trimmed deflections
    step_matrix: np.ndarray       # (n, 7, 24) [Φ Γ Γ₁] on [x; u; Δδ] (lpv.discretise_ramp)
    load_matrix: np.ndarray       # (n, 2, 17) load factors [C D] on [x; u]
    gains: laws.Gains
    law_params: laws.LawParams
    nz_c: np.ndarray              # (n, T) pilot orders
    p_c: np.ndarray
    beta_c: np.ndarray
    gust_alpha: np.ndarray        # (n, T) [rad]
    gust_beta: np.ndarray
    com_bias: np.ndarray          # (7·n,)
    com_scale: np.ndarray
    com_noise: np.ndarray         # (7·n, T)
    mon_bias: np.ndarray          # (n,) monitored surface only
    mon_scale: np.ndarray
    mon_noise: np.ndarray
    surf_bias: np.ndarray
    surf_noise: np.ndarray
    pres_noise: np.ndarray
    ac_noise: np.ndarray          # (9, n, T) in SI (rad, rad/s, g)
    faults: object                # FaultArrays of the monitored surface
    ramp_deg: np.ndarray          # (n, T) runaway ramp of the monitored order
    flight_true: dict
    schedule: dict
    airframe: str = "aircraft"    # Signals.airframe: the aircraft flown (design models)


def _stack(plants: list[PlantArrays]) -> PlantArrays:
    return PlantArrays(**{f.name: np.concatenate([getattr(p, f.name) for p in plants])
                          for f in fields(PlantArrays)})


def _aircraft_noise_sigmas(s: AircraftSensorParams) -> np.ndarray:
    """σ of the sensors of :data:`scenarios.signals.AIRCRAFT_SIGNAL_UNITS` (in that order) in
    SI units (rad, rad/s, g)."""
    rate, att = np.radians(s.rate_noise_deg_s), np.radians(s.attitude_noise_deg)
    return np.array([rate, rate, rate, att, att, s.load_noise_g, s.load_noise_g,
                     np.radians(s.sideslip_noise_deg), np.radians(s.aoa_noise_deg)])


def prepare_aircraft(runs: pd.DataFrame, *, ts: float = TS_S, sensors: SensorParams = SENSORS,
                     aircraft_sensors: AircraftSensorParams = AIRCRAFT_SENSORS,
                     turbulence: DrydenParams | None = MODERATE,
                     law_params: laws.LawParams = laws.LAWS) -> AircraftPrepared:
    """Validate *runs* and compute every open-loop input of the batch (*turbulence* None:
    calm air)."""
    validate_runs(runs, surfaces=AIRCRAFT_SURFACES)
    n = len(runs)
    T = int(round(float(runs["duration_s"].iloc[0]) / ts))
    col = {c: runs[c].to_numpy() for c in RUN_COLUMNS}
    f = {c: np.asarray(col[c], dtype=float) for c in RUN_RANGES}
    m_idx = AIRCRAFT_SURFACES.index(str(runs["surface"].iloc[0]))
    acts = tuple(AIRCRAFT_ACTUATORS[k] for k in LAYOUT.actuator)
    act_m = acts[m_idx]

    flight_true, schedule = flight_of(f)
    plants = [plant_arrays(a, qbar_pa=flight_true["qbar_pa"], alpha_deg=flight_true["alpha_deg"],
                           mach=flight_true["mach"], **plant_draws(f)) for a in acts]
    limits = [authority_limits(pl, a.replace(order_load_limit=law_params.hinge_load_limit))
              for pl, a in zip(plants, acts)]
    lo = np.array([lim[0] for lim in limits])
    hi = np.array([lim[1] for lim in limits])
    trim = np.zeros((len(acts), n))
    e_trim = np.array([elevator_trim_deg(a, c, ELEVATOR)
                       for a, c in zip(flight_true["alpha_deg"], f["cg_pct"])])
    trim[_ELEVATORS] = e_trim
    trim = np.clip(trim, lo, hi)

    model = lpv.run_models(flight_true, aero_draws(f))
    phi, gam, ramp = lpv.discretise_ramp(model, ts)
    measured = {"mass_t": schedule["mass_t"], "cg_pct": schedule["cg_pct"],
                "mach": schedule["mach"], "qbar_pa": schedule["qbar_pa"],
                "tas_ms": tas_from_mach(schedule["mach"], schedule["alt_ft"])}
    gains = laws.gains(lpv.run_models(measured, np.zeros(n)), law_params)

    t = np.arange(T) * ts
    gens = [run_streams(s, k) for s, k in zip(col["seed"], col["stream"])]
    nz_c, p_c, beta_c = pilot.inputs_for_runs(
        col["manoeuvre"].astype(str), t, [g[0] for g in gens],
        [pilot.set_params(m) for m in manoeuvre_sets(runs)])
    tas = flight_true["tas_ms"]
    if turbulence is None:
        gusts = np.zeros((n, 3, T))
    else:
        gusts = np.array([dryden_gusts(T, ts, v, h, g[0], turbulence)
                          for v, h, g in zip(tas, f["alt_ft"], gens)])
    gust_alpha = -gusts[:, 2] / tas[:, None]
    gust_beta = -gusts[:, 1] / tas[:, None]

    n_s = len(acts)
    sig = _aircraft_noise_sigmas(aircraft_sensors)
    com_bias = np.empty((n_s, n))
    com_scale = np.empty((n_s, n))
    com_noise = np.empty((n_s, n, T))
    mon = np.empty((3, n))
    mon_noise = np.empty((3, n, T))
    ac_noise = np.empty((len(sig), n, T))
    others = [j for j in range(n_s) if j != m_idx]
    for i, g in enumerate(gens):
        d = [x[0] for x in sensor_draws([g[1]], T, sensors, act_m.dP_Pa)]   # run i's own stream
        com_bias[m_idx, i], com_scale[m_idx, i], com_noise[m_idx, i] = d[0], d[1], d[2]
        mon[:, i] = d[3], d[4], d[6]
        mon_noise[0, i], mon_noise[1, i], mon_noise[2, i] = d[5], d[7], d[8]
        u = g[1].uniform(-1.0, 1.0, size=(len(others), 2))
        z = g[1].standard_normal((len(others), T))
        com_bias[others, i] = u[:, 0] * sensors.rod_bias_mm
        com_scale[others, i] = u[:, 1] * sensors.rod_scale
        com_noise[others, i] = z * sensors.rod_noise_mm
        ac_noise[:, i] = g[1].standard_normal((len(sig), T)) * sig[:, None]

    faults = fault_arrays(col["fault"], col["onset_s"], col["magnitude"], col["freq_hz"],
                          np.zeros((n, T)), act_m, ts, plants[m_idx].i_max)
    ramp_deg = np.degrees(np.arcsin(np.clip(faults.u_loop / act_m.r_mm, -1.0, 1.0)))
    return AircraftPrepared(
        ts=ts, n=n, T=T, monitored=m_idx, acts=acts, plant=_stack(plants), plant_m=plants[m_idx],
        lo_deg=lo, hi_deg=hi, trim_deg=trim,
        step_matrix=np.concatenate([phi, gam, ramp], axis=2),
        load_matrix=np.concatenate([model.C, model.D], axis=2),
        gains=gains, law_params=law_params, nz_c=nz_c, p_c=p_c, beta_c=beta_c,
        gust_alpha=gust_alpha,
        gust_beta=gust_beta, com_bias=com_bias.ravel(), com_scale=com_scale.ravel(),
        com_noise=com_noise.reshape(n_s * n, T), mon_bias=mon[0], mon_scale=mon[1],
        mon_noise=mon_noise[0], surf_bias=mon[2], surf_noise=mon_noise[1],
        pres_noise=mon_noise[2], ac_noise=ac_noise, faults=faults, ramp_deg=ramp_deg,
        flight_true=flight_true, schedule=schedule,
    )


@dataclass(frozen=True)
class AircraftTrajectory:
    """Closed-loop result: the monitored surface as at the actuator level, (n, T) each, plus
    every surface and the aircraft."""

    x: np.ndarray             # monitored rod position [mm]
    delta: np.ndarray         # monitored surface deflection [rad]
    i_cmd: np.ndarray         # monitored current order [mA]
    i_app: np.ndarray         # monitored current flowing [mA]
    y_com: np.ndarray         # monitored COM acquisition [mm]
    u: np.ndarray             # monitored fault-free rod order [mm]
    rods: np.ndarray          # (7, n, T) COM acquisitions of every surface [mm]
    surfaces: np.ndarray      # (7, n, T) true deflections [rad]
    states: np.ndarray        # (7, n, T) aircraft perturbation state (lpv.STATES)
    # (9, n, T) aircraft sensors (AIRCRAFT_SIGNAL_UNITS order; SI: rad, rad/s, g)
    sensors: np.ndarray
    spoiler: np.ndarray       # (n, T) spoiler input held over [t_k, t_k+1) [rad]


def integrate_aircraft(p: AircraftPrepared, sensors: SensorParams = SENSORS,
                       engine: str | None = None) -> AircraftTrajectory:
    """The closed-loop time loop: the compiled block kernel of :mod:`.kernel` with *engine*
    ``"compiled"`` (default: :func:`scenarios.compiled.current_engine`) where it can run bit
    for bit (:func:`.kernel.available`), else :func:`integrate_reference`."""
    if kernels.resolve_engine(engine) == "compiled" and kernel.available():
        return _integrate_compiled(p, sensors)
    return integrate_reference(p, sensors)


def _integrate_compiled(p: AircraftPrepared, sensors: SensorParams) -> AircraftTrajectory:
    """:func:`integrate_reference` through :func:`.kernel.integrate_block` (same numbers)."""
    n, m = p.n, p.monitored
    pl, fa = p.plant, p.faults
    act_m = p.acts[m]
    run_margin = FAULT_DEFAULTS.runaway_margin_deg
    trim_rad = np.radians(p.trim_deg)
    x, delta = servo_start(p)
    empty = np.zeros((0, 0))

    def c(a, dtype=float):
        return np.ascontiguousarray(a, dtype=dtype)

    def opt(a):
        return empty if a is None else c(a)

    g, lp = p.gains, p.law_params
    gains = c(np.stack([np.broadcast_to(np.asarray(getattr(g, f.name), float), (n,))
                        for f in fields(laws.Gains)]))
    steps, step_spoiler = laws.order_steps(p.ts, lp)
    law = np.array([np.radians(lp.bank_max_deg), lp.bank_gain, lp.roll_bandwidth,
                    lp.yaw_damping, lp.sideslip_gain, lp.sideslip_integral, G0_MS2,
                    *laws.filter_coefficients(p.ts, lp), step_spoiler])
    scal = np.array([p.ts, sensors.rod_quant_mm, act_m.r_mm, act_m.stop_min_deg - run_margin,
                     act_m.stop_max_deg + run_margin, np.radians(act_m.stop_min_deg),
                     np.radians(act_m.stop_max_deg),
                     np.radians(AIRCRAFT_ACTUATORS["aileron"].delta_max_deg)])
    flags = np.array([fa.com_add is not None, fa.com_osc is not None, fa.cur_add is not None,
                      fa.cur_force is not None, bool((fa.k_jam < NEVER).any()),
                      bool((fa.k_disc < NEVER).any())])
    rods, surf, states, meas_rec, xs, icmd, iapp, u_rec, sp_rec = record_arrays(p)
    kernel.integrate_block(
        kernel.LOOPS, m, x, delta, c(trim_rad), c(p.trim_deg), c(p.lo_deg), c(p.hi_deg),
        kernels.plant_matrix(pl), c(_PITCH), c(_ROLL), c(_YAW), c(_ELEVATORS, np.bool_),
        c(steps), c(p.step_matrix), c(p.load_matrix), gains, law,
        c(np.radians(p.flight_true["alpha_deg"])), c(p.nz_c), c(p.p_c), c(p.beta_c),
        c(p.gust_alpha), c(p.gust_beta), c(p.ac_noise), c(p.com_scale), c(p.com_bias),
        c(p.com_noise), opt(fa.com_add), opt(fa.com_osc), c(fa.k_osc, np.int64),
        opt(fa.cur_add), opt(fa.cur_force), c(fa.k_jam, np.int64), c(fa.jam_offset),
        c(fa.k_disc, np.int64), flags, c(p.ramp_deg), scal,
        rods, surf, states, meas_rec, xs, icmd, iapp, u_rec, sp_rec)
    return AircraftTrajectory(x=xs, delta=surf[m], i_cmd=icmd, i_app=iapp, y_com=rods[m],
                              u=u_rec, rods=rods, surfaces=surf, states=states, sensors=meas_rec,
                              spoiler=sp_rec)


def record_arrays(p: AircraftPrepared) -> tuple[np.ndarray, ...]:
    """The series a block's time loop records, uninitialised: every rod and surface (7, n, T),
    the aircraft states and sensors, and the monitored servo's rod, commanded and applied
    current, order and the spoilers' (n, T)."""
    n, T, n_s = p.n, p.T, len(p.acts)
    return (np.empty((n_s, n, T)), np.empty((n_s, n, T)), np.empty((lpv.N_STATES, n, T)),
            np.empty((p.ac_noise.shape[0], n, T)), np.empty((n, T)), np.empty((n, T)),
            np.empty((n, T)), np.empty((n, T)), np.empty((n, T)))


def servo_start(p: AircraftPrepared) -> tuple[np.ndarray, np.ndarray]:
    """Every rod [mm] and surface [rad] at t_0: the surfaces at their trim, inside the rods'
    strokes (docs/physics.md §2)."""
    pl = p.plant
    x = np.clip(pl.r_mm * np.sin(np.radians(p.trim_deg).ravel()), pl.x_min, pl.x_max)
    return x, np.arcsin(x / pl.r_mm)


def monitored_servo(p: AircraftPrepared) -> types.SimpleNamespace:
    """The monitored servo's faults and COM errors, as the acquisition functions of
    :mod:`scenarios.acquisition` read them."""
    mon = slice(p.monitored * p.n, (p.monitored + 1) * p.n)
    return types.SimpleNamespace(faults=p.faults, com_scale=p.com_scale[mon],
                                 com_bias=p.com_bias[mon], com_noise=p.com_noise[mon])


def com_acquisition(x: np.ndarray, k: int, p: AircraftPrepared, pm, sensors: SensorParams,
                    y_hold: np.ndarray):
    """The COM rod acquisitions of every servo at t_k [mm] (docs/physics.md §4: scale, bias,
    noise, quantisation; the monitored one with its sensor faults), the hold of the
    monitored one, and the elevator deflection the laws read from them [rad, from trim]."""
    n_s, n, mon = len(p.acts), p.n, slice(p.monitored * p.n, (p.monitored + 1) * p.n)
    y = quantize(x * (1.0 + p.com_scale) + p.com_bias + p.com_noise[:, k], sensors.rod_quant_mm)
    y[mon], y_hold = acquire_com(x[mon], k, pm, sensors, y_hold)
    trim_rad = np.radians(p.trim_deg)
    de_meas = (np.arcsin(np.clip(y / p.plant.r_mm, -1.0, 1.0)).reshape(n_s, n)[_ELEVATORS]
               - trim_rad[_ELEVATORS]).mean(axis=0)
    return y, y_hold, de_meas


def jam_onset(x: np.ndarray, delta: np.ndarray, k: int, fa, pl: PlantArrays, mon: slice) -> None:
    """An "offset" solid jam: the monitored rod jumps at its onset (docs/physics.md §5);
    *x* [mm] and *delta* [rad] of step *k* updated in place."""
    x_m = x[mon]
    x_j = jam_onset_position(x_m, k, fa, pl.x_min[mon], pl.x_max[mon])
    if x_j is not x_m:
        delta[mon] = np.where(x_j != x_m, np.arcsin(x_j / pl.r_mm[mon]), delta[mon])
        x[mon] = x_j


def surface_orders(p: AircraftPrepared, state: laws.LawState, meas: dict, nz_c: np.ndarray,
                   k: int, pitch_clipped: np.ndarray, order_prev: np.ndarray,
                   step_deg: np.ndarray):
    """The flight computer's orders of period *k* (docs/aircraft.md §4): the laws' pitch, roll
    and yaw demands distributed over the surfaces, clipped to their authority and rate-limited,
    and the monitored surface's runaway ramp added (docs/physics.md §5). Returns the roll demand
    [rad], the orders (7, n) [deg], the rate limiter's memory, whether a pitch order was
    clipped and the monitored servo's fault-free order [mm]."""
    m, act_m = p.monitored, p.acts[p.monitored]
    run_margin = FAULT_DEFAULTS.runaway_margin_deg
    de, da, dr = laws.step(state, meas, nz_c, p.p_c[:, k], p.beta_c[:, k], p.gains, p.ts,
                           pitch_clipped, p.law_params)
    raw = p.trim_deg + np.degrees(_PITCH[:, None] * de + _ROLL[:, None] * da
                                  + _YAW[:, None] * dr)
    order = laws.rate_limit(order_prev, np.clip(raw, p.lo_deg, p.hi_deg), step_deg)
    order_prev = order.copy()
    pitch_clipped = (order[_ELEVATORS] != raw[_ELEVATORS]).any(axis=0)
    u_free_m = act_m.deg_to_mm(order[m])
    order[m] = np.clip(order[m] + p.ramp_deg[:, k], act_m.stop_min_deg - run_margin,
                       act_m.stop_max_deg + run_margin)
    return da, order, order_prev, pitch_clipped, u_free_m


def servo_currents(order: np.ndarray, y: np.ndarray, i_prev: np.ndarray, k: int,
                   p: AircraftPrepared, pm) -> tuple[np.ndarray, np.ndarray]:
    """The servo-valve currents of period *k* [mA] ([COMB] eq. 2): commanded from the orders
    [deg] and the COM rods *y* [mm], and applied (the monitored one with its current faults,
    :func:`scenarios.acquisition.applied_current`, from the previous period's command)."""
    pl, mon = p.plant, slice(p.monitored * p.n, (p.monitored + 1) * p.n)
    u_loop = pl.r_mm * np.sin(np.radians(order.ravel()))
    i_new = np.clip(pl.K * (u_loop - y), -pl.i_max, pl.i_max)
    i_app = i_prev.copy()
    i_app[mon] = applied_current(i_prev[mon], k, pm)
    return i_new, i_app


def advance_servos(x: np.ndarray, delta: np.ndarray, i_app: np.ndarray, loaded: np.ndarray,
                   k: int, p: AircraftPrepared, any_jam: bool, any_disc: bool):
    """Every servo-loop over [t_k, t_k+1) (docs/physics.md §2–§5): the rods by RK4, the
    monitored one held by a jam from its onset, its surface floating once disconnected.
    Returns the rods [mm] and surfaces [rad] at t_k+1; *loaded* updated in place."""
    pl, fa, ts = p.plant, p.faults, p.ts
    mon = slice(p.monitored * p.n, (p.monitored + 1) * p.n)
    act_m = p.acts[p.monitored]
    if any_disc:
        loaded[mon] = k < fa.k_disc
    x_next = rk4_step(x, i_app, pl, loaded, ts)
    if any_jam:
        x_next[mon] = np.where(k >= fa.k_jam, x[mon], x_next[mon])
    delta_next = np.arcsin(x_next / pl.r_mm)
    if any_disc:
        d_min, d_max = np.radians(act_m.stop_min_deg), np.radians(act_m.stop_max_deg)
        with np.errstate(invalid="ignore", divide="ignore"):
            floating = float_step(delta[mon], p.plant_m, ts, d_min, d_max)
        delta_next[mon] = np.where(loaded[mon], delta_next[mon], floating)
    return x_next, delta_next


def integrate_reference(p: AircraftPrepared, sensors: SensorParams = SENSORS) -> AircraftTrajectory:
    """The closed-loop time loop in NumPy, vectorised over runs and surfaces (the reference
    of the compiled kernel, :mod:`.kernel`)."""
    n, T, ts, m = p.n, p.T, p.ts, p.monitored
    n_s = len(p.acts)
    pl, fa = p.plant, p.faults
    mon = slice(m * n, (m + 1) * n)
    pm = monitored_servo(p)
    trim_rad = np.radians(p.trim_deg)

    rods, surf, states, meas_rec, xs, icmd, iapp, u_rec, sp_rec = record_arrays(p)

    x, delta = servo_start(p)
    i_prev = np.zeros(n * n_s)
    y_hold = np.zeros(n)
    nx_u = lpv.N_STATES + lpv.N_INPUTS
    xu = np.zeros((n, nx_u + n_s, 1))       # [x; u; Δδ] of the aircraft step
    xa = xu[:, :lpv.N_STATES, 0]            # views
    u_air = xu[:, lpv.N_STATES:nx_u, 0]
    d_surf = xu[:, nx_u:, 0]
    state = laws.LawState.zeros(n)
    pitch_clipped = np.zeros(n, dtype=bool)
    steps, step_spoiler = laws.order_steps(ts, p.law_params)
    step_deg = steps[:, None]
    order_prev = p.trim_deg.copy()          # (7, n) orders of the previous period [deg]
    da_prev = np.zeros(n)
    loaded = np.ones(n * n_s, dtype=bool)
    any_jam = bool((fa.k_jam < NEVER).any())
    any_disc = bool((fa.k_disc < NEVER).any())
    roll_lim = np.radians(AIRCRAFT_ACTUATORS["aileron"].delta_max_deg)
    nse = p.ac_noise
    theta0 = np.radians(p.flight_true["alpha_deg"])     # trimmed level flight: θ0 = α0
    for k in range(T):
        if any_jam:
            jam_onset(x, delta, k, fa, pl, mon)
        # aircraft sensors at t_k
        u_air[:, :n_s] = (delta.reshape(n_s, n) - trim_rad).T
        u_air[:, lpv.I_SPOILER] = da_prev
        u_air[:, lpv.I_GUST_ALPHA] = p.gust_alpha[:, k]
        u_air[:, lpv.I_GUST_BETA] = p.gust_beta[:, k]
        loads = (p.load_matrix @ xu[:, :nx_u])[:, :, 0].T
        meas = {"p": xa[:, lpv.IP] + nse[0, :, k], "q": xa[:, lpv.IQ] + nse[1, :, k],
                "r": xa[:, lpv.IR] + nse[2, :, k], "phi": xa[:, lpv.IPHI] + nse[3, :, k],
                "theta": theta0 + xa[:, lpv.ITH] + nse[4, :, k], "dnz": loads[0] + nse[5, :, k],
                "ny": loads[1] + nse[6, :, k],
                "beta": xa[:, lpv.IB] + p.gust_beta[:, k] + nse[7, :, k],
                # air-relative
                "alpha": theta0 + xa[:, lpv.IA] + p.gust_alpha[:, k] + nse[8, :, k]}
        # servo-loops: COM acquisitions at t_k
        y, y_hold, meas["de"] = com_acquisition(x, k, p, pm, sensors, y_hold)
        # laws and surface orders
        nz_c = p.nz_c[:, k] + laws.turn_load_factor(meas["phi"], p.law_params)
        da, order, order_prev, pitch_clipped, u_free_m = surface_orders(
            p, state, meas, nz_c, k, pitch_clipped, order_prev, step_deg)
        # servo-loops: currents
        i_new, i_app = servo_currents(order, y, i_prev, k, p, pm)
        # record t_k
        rods[:, :, k] = y.reshape(n_s, n)
        surf[:, :, k] = delta.reshape(n_s, n)
        states[:, :, k] = xa.T
        meas_rec[:, :, k] = (meas["p"], meas["q"], meas["r"], meas["phi"], meas["theta"],
                             1.0 + meas["dnz"], meas["ny"], meas["beta"], meas["alpha"])
        xs[:, k] = x[mon]
        icmd[:, k] = i_new[mon]
        iapp[:, k] = i_app[mon]
        u_rec[:, k] = u_free_m
        sp_rec[:, k] = da_prev
        # advance the surfaces over [t_k, t_k+1)
        x_next, delta_next = advance_servos(x, delta, i_app, loaded, k, p, any_jam, any_disc)
        # advance the aircraft over [t_k, t_k+1): inputs of t_k held, the surfaces' motion to
        # t_k+1 as a ramp (exact, lpv.discretise_ramp)
        d_surf[:] = (delta_next - delta).reshape(n_s, n).T
        xa[:] = (p.step_matrix @ xu)[:, :, 0]
        x, delta, i_prev = x_next, delta_next, i_new
        da_prev = laws.rate_limit(da_prev, np.clip(da, -roll_lim, roll_lim), step_spoiler)
    return AircraftTrajectory(x=xs, delta=surf[m], i_cmd=icmd, i_app=iapp, y_com=rods[m],
                              u=u_rec, rods=rods, surfaces=surf, states=states, sensors=meas_rec,
                              spoiler=sp_rec)


#: Conversion of the recorded aircraft sensors (SI) to the units of AIRCRAFT_SIGNAL_UNITS.
TO_UNITS = {"deg/s": np.degrees, "deg": np.degrees, "g": lambda v: v}


def simulate_aircraft(runs: pd.DataFrame, *, ts: float = TS_S, sensors: SensorParams = SENSORS,
                      pressure_sensor: bool = False,
                      turbulence: DrydenParams | None = MODERATE,
                      law_params: laws.LawParams = laws.LAWS,
                      aircraft_sensors: AircraftSensorParams = AIRCRAFT_SENSORS,
                      truth: bool = True) -> tuple[Signals, Truth | None]:
    """Simulate every run of *runs* with the aircraft in the loop (one monitored surface and
    one duration per call); returns (:class:`Signals`, :class:`Truth`) like
    :func:`scenarios.simulate.simulate` (*truth* False: ``(Signals, None)``, for callers
    that read the signals only, e.g. a learning set).

    The runs are simulated in blocks of at most :attr:`AircraftPlant.batch_runs` (a run's
    series never depend on its block), each written into the arrays of the whole batch as it
    ends: the memory is that of the results plus the working set of one block."""
    kw = dict(ts=ts, sensors=sensors, pressure_sensor=pressure_sensor, turbulence=turbulence,
              law_params=law_params, aircraft_sensors=aircraft_sensors)
    block = AircraftPlant.batch_runs
    if len(runs) <= block:
        return _simulate_block(runs, truth=truth, **kw)
    n = len(runs)
    sig_out = truth_out = None
    sig_rest, truth_rest, faults = [], [], []
    for start in range(0, n, block):
        sig, tru = _simulate_block(runs.iloc[start:start + block], truth=truth, **kw)
        rows = slice(start, start + sig.n_runs)
        sig_out = _write(sig_out, _series_of_signals(sig), n, rows)
        sig_rest.append(_per_run(sig, aircraft={}, rods={}, **dict.fromkeys(SIGNAL_UNITS)))
        if tru is not None:
            truth_out = _write(truth_out, _series_of_truth(tru), n, rows)
            faults.append((rows, tru.rod_fault_mm))
            truth_rest.append(_per_run(tru, rod_mm=None, surface_deg=None, current_mA=None,
                                       aircraft={}, surfaces_deg={}, rod_fault_mm=None))
        del sig, tru
    signals = _signals_from(sig_rest, sig_out)
    result = signals, (None if not truth else _truth_from(truth_rest, truth_out, faults, n))
    release_freed_memory()
    return result


def _per_run(block, **dropped):
    """*block* (Signals or Truth) without its (runs, steps) series: what stays of a block
    once they are written into the batch arrays."""
    return types.SimpleNamespace(**{**{f.name: getattr(block, f.name) for f in fields(block)},
                                    **dropped})


def _series_of_signals(sig: Signals) -> dict:
    out = {name: getattr(sig, name) for name in SIGNAL_UNITS}
    out.update({("aircraft", k): v for k, v in sig.aircraft.items()})
    out.update({("rods", k): v for k, v in sig.rods.items()})
    return out


def _series_of_truth(tru: Truth) -> dict:
    out = {name: getattr(tru, name) for name in ("rod_mm", "surface_deg", "current_mA")}
    out.update({("aircraft", k): v for k, v in tru.aircraft.items()})
    out.update({("surfaces_deg", k): v for k, v in tru.surfaces_deg.items()})
    return out


def _write(out: dict | None, series: dict, n: int, rows: slice) -> dict:
    """Copy a block's (runs, steps) *series* into the batch arrays *out* (allocated at the
    first block) at *rows*; the block's own arrays can then be freed."""
    if out is None:
        out = {k: np.empty((n,) + np.shape(v)[1:], dtype=np.asarray(v).dtype)
               for k, v in series.items()}
    for k, v in series.items():
        out[k][rows] = v
    return out


def _signals_from(parts: list, series: dict) -> Signals:
    """The batch's :class:`Signals`: the written *series*, the per-run data of the blocks."""
    first = parts[0]
    return Signals(
        ts=first.ts, **{name: series[name] for name in SIGNAL_UNITS},
        schedule={k: np.concatenate([p.schedule[k] for p in parts]) for k in first.schedule},
        actuator=first.actuator, run_ids=np.concatenate([p.run_ids for p in parts]),
        aircraft={k[1]: v for k, v in series.items() if k[0] == "aircraft"},
        rods={k[1]: v for k, v in series.items() if k[0] == "rods"},
        airframe=first.airframe,
    )


def _truth_from(parts: list, series: dict, faults: list, n: int) -> Truth:
    """The batch's :class:`Truth` (``rod_fault_mm`` NaN for the runs of a block without a
    jam, as :func:`rod_measurement_fault` gives them; None when no block has a jam)."""
    first = parts[0]
    rod_fault = None
    if any(f is not None for _, f in faults):
        rod_fault = np.full(series["rod_mm"].shape, np.nan)
        for rows, f in faults:
            if f is not None:
                rod_fault[rows] = f

    def cat(name):
        return np.concatenate([getattr(p, name) for p in parts])

    return Truth(
        rod_mm=series["rod_mm"], surface_deg=series["surface_deg"],
        current_mA=series["current_mA"], fault=cat("fault"), onset_s=cat("onset_s"),
        magnitude=cat("magnitude"),
        flight={k: np.concatenate([p.flight[k] for p in parts]) for k in first.flight},
        aircraft={k[1]: v for k, v in series.items() if k[0] == "aircraft"},
        surfaces_deg={k[1]: v for k, v in series.items() if k[0] == "surfaces_deg"},
        rod_fault_mm=rod_fault)


def _simulate_block(runs: pd.DataFrame, *, ts, sensors, pressure_sensor, turbulence,
                    law_params, aircraft_sensors, truth: bool) -> tuple[Signals, Truth | None]:
    """:func:`simulate_aircraft` of one block of runs."""
    p = prepare_aircraft(runs, ts=ts, sensors=sensors, turbulence=turbulence,
                         law_params=law_params, aircraft_sensors=aircraft_sensors)
    traj = integrate_aircraft(p, sensors)
    return trajectory_signals(traj, p, runs, ts=ts, sensors=sensors,
                              pressure_sensor=pressure_sensor, truth=truth)


def trajectory_signals(traj: AircraftTrajectory, p: AircraftPrepared, runs: pd.DataFrame, *,
                       ts: float, sensors: SensorParams, pressure_sensor: bool,
                       truth: bool) -> tuple[Signals, Truth | None]:
    """The :class:`Signals` a detector reads of a simulated block (the monitored servo's
    acquisitions, the aircraft sensors, every rod) and, with *truth*, its :class:`Truth`."""
    act = surface_actuator(AIRCRAFT_SURFACES[p.monitored])
    mon, surface_deg, surface, pressure = acquire(traj, p, act, sensors, pressure_sensor,
                                                  plant=p.plant_m)
    aircraft = {name: TO_UNITS[unit](series)           # the nine sensors, then the spoilers
                for (name, unit), series in zip(AIRCRAFT_SIGNAL_UNITS.items(), traj.sensors)}
    aircraft["spoiler"] = np.degrees(traj.spoiler)
    signals = Signals(
        ts=ts, command=traj.u, current=traj.i_cmd, rod_com=traj.y_com, rod_mon=mon,
        surface=surface, pressure=pressure, schedule=p.schedule, actuator=act,
        run_ids=runs["run_id"].astype(str).to_numpy(),
        aircraft=aircraft, rods={s: traj.rods[j] for j, s in enumerate(AIRCRAFT_SURFACES)},
        airframe=p.airframe,
    )
    if not truth:
        return signals, None
    truth_of_block = Truth(
        rod_mm=traj.x, surface_deg=surface_deg, current_mA=traj.i_app,
        fault=runs["fault"].astype(str).to_numpy(),
        onset_s=runs["onset_s"].to_numpy(float), magnitude=runs["magnitude"].to_numpy(float),
        flight=p.flight_true,
        aircraft={s: np.degrees(traj.states[j]) for j, s in enumerate(lpv.STATES)},
        surfaces_deg={s: np.degrees(traj.surfaces[j]) for j, s in enumerate(AIRCRAFT_SURFACES)},
        rod_fault_mm=rod_measurement_fault(runs["fault"].to_numpy(),
                                           runs["onset_s"].to_numpy(float), traj.y_com,
                                           traj.u, p.plant_m, ts),
    )
    return signals, truth_of_block


class AircraftSurfaces:
    """The surfaces, servo-loops and signals of an aircraft plant (ours or another flight model
    flown by our servo-loops): the part of the :class:`scenarios.plants.Plant` protocol that
    depends on the surfaces only."""

    @property
    def surfaces(self) -> tuple[str, ...]:
        return AIRCRAFT_SURFACES

    def run_surface(self, surface: str, monitored: str | None = None) -> str:
        """The monitored aircraft surface: *monitored*, or the left surface of *surface*
        (``elevator`` → ``left_elevator``, ``aileron`` → ``left_inboard_aileron``)."""
        return monitored or DEFAULT_MONITORED[surface]

    def actuator(self, surface: str) -> ActuatorParams:
        return surface_actuator(surface)

    def provides(self, surface: str, *, pressure_sensor: bool) -> frozenset[str]:
        return servo_provides(self.actuator(surface), pressure_sensor) | {"aircraft"}


@dataclass(frozen=True)
class AircraftPlant(AircraftSurfaces):
    """The aircraft in the loop (docs/physics.md §7): rigid body, control laws and every
    surface's servo-loop; the run rows name the *monitored* aircraft surface. A
    :class:`scenarios.plants.Plant`.

    aircraft_sensors : the noise of the aircraft sensors (default :data:`AIRCRAFT_SENSORS`,
        docs/physics.md §7).
    turbulence : the Dryden level the aircraft flies in, a name of
        :data:`scenarios.turbulence.LEVELS` (default ``"moderate"``; ``"none"``: calm air,
        the turbulence-free runs of [CHEN] footnote 1).
    """

    aircraft_sensors: AircraftSensorParams = AIRCRAFT_SENSORS
    turbulence: str = "moderate"
    kind = "aircraft"
    #: runs on threads (no per-process state)
    needs_processes = False
    #: runs simulated together at most (campaign.evaluate.evaluate cuts a larger chunk into
    #: blocks): a run holds ~60 (n_steps,) float64 series while it is simulated (every
    #: surface, the aircraft states and sensors, their noise), ~2.9 MB for 60 s at 100 Hz,
    #: so a block of 25 holds ~70 MB where a chunk of 100 held ~290 MB (est.)
    batch_runs = 25
    #: runs of the learning set simulated together (campaign.runner.simulate_chunks): two
    #: threads simulating blocks of 25 beside chen-mc's 300-run learning set (300 MB) raised
    #: the campaign's peak by ~180 MB; parts of 10 raise it by ~70 MB, for the same CPU time
    #: (the compiled loop runs run after run). A run's series never depend on its block.
    learning_part_runs = 10

    def check(self, faults=()) -> None:
        """Nothing to check before work: the aircraft plant simulates every fault."""

    def simulate(self, runs: pd.DataFrame, *, ts: float = TS_S, sensors: SensorParams = SENSORS,
                 pressure_sensor: bool = False) -> tuple[Signals, Truth]:
        return simulate_aircraft(runs, ts=ts, sensors=sensors, pressure_sensor=pressure_sensor,
                                 aircraft_sensors=self.aircraft_sensors,
                                 turbulence=turbulence_level(self.turbulence))

    def simulate_signals(self, runs: pd.DataFrame, *, ts: float = TS_S,
                         sensors: SensorParams = SENSORS,
                         pressure_sensor: bool = False) -> Signals:
        """The :class:`Signals` of :meth:`simulate` alone (no :class:`Truth` is built: a
        learning set holds about half the memory)."""
        return simulate_aircraft(runs, ts=ts, sensors=sensors, pressure_sensor=pressure_sensor,
                                 aircraft_sensors=self.aircraft_sensors,
                                 turbulence=turbulence_level(self.turbulence), truth=False)[0]


def _warm_kernel() -> None:
    """Load (or compile) the aircraft kernel on a one-second run (kernels.warm_up)."""
    if not kernel.available():
        return
    runs = single_run("aileron", "cruise", "disconnection", duration_s=1.0, onset_s=0.5)
    runs["surface"] = DEFAULT_MONITORED["aileron"]
    _integrate_compiled(prepare_aircraft(runs, turbulence=None), SENSORS)


kernels.register_warmup(_warm_kernel, kernels=(kernel.integrate_block,))
