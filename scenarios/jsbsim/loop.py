"""The closed loop on JSBSim: our servo-loops, sensors, faults and laws fly a JSBSim aircraft.

Everything but the aircraft is that of the aircraft plant (:mod:`scenarios.aircraft.loop`,
docs/physics.md §7): the seven surfaces' nonlinear servo-loops with the A330 actuator and
hinge-moment tables at the run's sampled point, the fault injection on the monitored
surface, the COM/MON acquisitions, the aircraft sensor noise, the pilot's manoeuvre orders
and the laws of :mod:`scenarios.aircraft.laws` — their gains placed on JSBSim's
linearisation (:func:`scenarios.jsbsim.fdm.design_model`), never on our derivative model,
of the nominal aircraft trimmed at the run's *measured* point: the flight computer knows
neither the true point nor the coefficient errors (as on the aircraft plant). In place of
our linear rigid body, one JSBSim FDM per run (:class:`scenarios.jsbsim.fdm.Fdm`), trimmed
at the run's true flight point mapped onto the JSBSim aircraft
(:func:`scenarios.jsbsim.fdm.flight_point`) with the run's [CHEN] Table 2 coefficient
errors on its aerodynamic axes (:data:`scenarios.jsbsim.fdm.AERO_AXES`), advanced one step of Ts per
FCC period with each surface at the mean of its positions at t_k and t_k+1 (the
midpoint of the servo's motion over the period) and the gust of t_k.

Gusts: the Dryden velocities of :func:`scenarios.turbulence.dryden_gusts` at the JSBSim
point's TAS and altitude from the run's manoeuvre stream after its pilot draws (the same
stream order as the aircraft plant); the v and w components enter JSBSim as a wind in NED
axes (``atmosphere/gust-*-fps``), u is not applied (as our plant, which holds the speed).

Sensors at t_k, from JSBSim's state: p, q, r (``velocities/*-rad_sec``), φ, θ, the load
factors (``accelerations/Nz``, ``Ny``: n_z is JSBSim's Nz minus its trimmed value plus 1),
and the air-relative sideslip and angle of attack (``aero/beta-rad``, ``aero/alpha-rad``),
each plus its noise. Truth ``aircraft`` holds α − α0, q, θ − θ0, β, p, r, φ (lpv.STATES).

Not applied here: the spoilers (no roll spoilers in the 737's aerodynamics: ``spoiler`` is
recorded as 0).

A run that cannot trim, diverges (|φ| > 80°, |α| > 30°, below 500 ft) or returns NaN raises
:class:`scenarios.jsbsim.fdm.JsbsimRunError` naming the run, the time and the cause; the
engine records it as the run's ``error`` (campaign.evaluate, run by run).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from .. import envelope
from ..aircraft import laws, pilot
from ..aircraft.data import (
    AIRCRAFT_SENSORS,
    AIRCRAFT_SURFACES,
    LAYOUT,
    AircraftSensorParams,
)
from ..aircraft.loop import (
    AircraftPrepared,
    AircraftSurfaces,
    AircraftTrajectory,
    advance_servos,
    com_acquisition,
    jam_onset,
    monitored_servo,
    prepare_aircraft,
    record_arrays,
    servo_currents,
    servo_start,
    trajectory_signals,
    surface_orders,
)
from ..atmosphere import G0_MS2
from ..faults import NEVER
from ..params import SENSORS, TS_S, SensorParams
from ..runs import aero_draws, manoeuvre_sets, run_streams
from ..signals import Signals, Truth
from ..turbulence import DrydenParams, dryden_gusts
from ..turbulence import level as turbulence_level
from . import fdm as F


@dataclass(frozen=True)
class JsbsimLoopParams:
    """What the JSBSim plant adds to the laws of :mod:`scenarios.aircraft.laws`: our aircraft
    holds its speed (lpv.py), JSBSim's does not. Without these a 0.3 g pull held 10 s at
    160 kt / 233 t on our grid (205 kt / 53 t on the 737) leaves it in a 15° climb that its
    thrust cannot hold, and it stalls 20 s later (measured: nose_up and aoa_protection at
    18 000 ft, α 30° at 33 s)."""

    #: autothrottle: throttle = throttle_trim + kp·(VCAS_trim − VCAS) + ki·∫(VCAS_trim − VCAS)
    #: (est.: the 737's two CFM56 give about 2 m/s² per unit throttle at 50 t and FL180,
    #: so kp closes the speed loop in about 5 s; ki = kp/10 s)
    at_kp_per_kt: float = 0.05
    at_ki_per_kt_s: float = 0.005
    #: the pilot brings the flight path back to level after a manoeuvre: the load-factor
    #: order gets −V/(g·τ)·γ with γ ≈ θ − α·cos φ from the measured angles (est. τ = 15 s,
    #: slow against the manoeuvres' 2–10 s holds)
    path_tau_s: float = 15.0


LOOP = JsbsimLoopParams()


#: Divergence limits (est.: far outside any of the six manoeuvres, docs/physics.md §7).
PHI_MAX_RAD = np.radians(80.0)
ALPHA_MAX_RAD = np.radians(30.0)
H_MIN_FT = 500.0


@dataclass(frozen=True)
class JsbsimPrepared:
    base: AircraftPrepared        # servo-loops, sensors, faults, pilot orders, laws
    fdms: list                    # one trimmed Fdm per run
    gusts: np.ndarray             # (n, 3, T) body gust velocities [m/s]
    nz0: np.ndarray               # (n,) JSBSim's trimmed Nz
    run_ids: np.ndarray


def prepare_jsbsim(runs: pd.DataFrame, *, aircraft: str = "737", ts: float = TS_S,
                   sensors: SensorParams = SENSORS,
                   aircraft_sensors: AircraftSensorParams = AIRCRAFT_SENSORS,
                   turbulence: DrydenParams | None = None,
                   law_params: laws.LawParams = laws.LAWS) -> JsbsimPrepared:
    """Trim one FDM per run and design its laws on JSBSim's linearisation (module docstring)."""
    model = F.aircraft_model(aircraft)
    base = prepare_aircraft(runs, ts=ts, sensors=sensors, turbulence=None,
                            law_params=law_params, aircraft_sensors=aircraft_sensors)
    n, T = base.n, base.T
    ft = base.flight_true
    point = F.flight_point(ft["alt_ft"], ft["vcas_kt"], ft["mass_t"], ft["cg_pct"], model)
    ids = runs["run_id"].astype(str).to_numpy()
    d = {c: runs[c].to_numpy(float) for c in ("d_alt", "d_vcas", "d_mass", "d_cg")}
    schedule = envelope.measured_schedule(point["alt_ft"], point["vcas_kt"], point["mass_t"],
                                          point["cg_pct"], d["d_alt"], d["d_vcas"],
                                          d["d_mass"], d["d_cg"])
    aero = aero_draws({c: runs[c].to_numpy(float) for c in AERO_COLUMNS})
    fdms = [_trimmed(model, ts, ids[i], point, i, {c: v[i] for c, v in aero.items()})
            for i in range(n)]
    # the laws know what the flight computer knows: the nominal aircraft (no coefficient
    # error) at the measured point, as on the aircraft plant (docs/aircraft.md §9.1), held
    # within the aircraft's ranges as a gain schedule's lookup is
    at = F.scheduled_point(schedule, model)
    design = F.design_model([_trimmed(model, ts, ids[i], at, i, None) for i in range(n)])
    gains = laws.gains(design, law_params)

    trim = np.zeros_like(base.trim_deg)
    jsb = np.degrees(np.array([f.trim_surfaces for f in fdms]))          # (n, 3)
    for j, (name, kind) in enumerate(zip(AIRCRAFT_SURFACES, LAYOUT.actuator)):
        trim[j] = (jsb[:, 0] if kind == "elevator" else jsb[:, 2] if kind == "rudder"
                   else jsb[:, 1] * (1.0 if name.startswith("left") else -1.0))
    trim = np.clip(trim, base.lo_deg, base.hi_deg)

    tas = np.array([f.tas_ms for f in fdms])
    gusts = np.zeros((n, 3, T))
    if turbulence is not None:
        col = {c: runs[c].to_numpy() for c in ("seed", "stream", "manoeuvre")}
        t = np.arange(T) * ts
        sets = manoeuvre_sets(runs)
        for i in range(n):
            g = run_streams(col["seed"][i], col["stream"][i])[0]
            pilot.inputs_for_runs([str(col["manoeuvre"][i])], t, [g],
                                  [pilot.set_params(sets[i])])      # the same draws first
            gusts[i] = dryden_gusts(T, ts, tas[i], float(point["alt_ft"][i]), g, turbulence)
    gusts[:, 0] = 0.0
    flight = {**{k: np.asarray(v, float) for k, v in point.items()},
              "mach": np.array([f.mach for f in fdms]),
              "qbar_pa": np.array([f.qbar_pa for f in fdms]), "tas_ms": tas,
              "alpha_deg": np.degrees([f.alpha0 for f in fdms])}
    base = replace(base, trim_deg=trim, gains=gains,
                   gust_alpha=-gusts[:, 2] / tas[:, None], gust_beta=-gusts[:, 1] / tas[:, None],
                   flight_true=flight, schedule={k: np.asarray(v, float)
                                                 for k, v in schedule.items()},
                   airframe=F.airframe_name(model))
    nz0 = np.array([f.read()[F.READ_NZ] for f in fdms])
    return JsbsimPrepared(base=base, fdms=fdms, gusts=gusts, nz0=nz0, run_ids=ids)


#: The run columns of [CHEN] Table 2's coefficient draws (:func:`scenarios.runs.aero_draws`).
AERO_COLUMNS = tuple(f"d_{c}" for c in envelope.AERO_COEFFICIENTS)


def _trimmed(model: F.AircraftModel, ts: float, run_id: str, point: dict, i: int,
             aero: dict | None) -> F.Fdm:
    """A new FDM of *model* trimmed at entry *i* of *point* (``alt_ft``, ``vcas_kt``,
    ``mass_t``, ``cg_pct`` arrays on the JSBSim aircraft) with the coefficient errors *aero*;
    a trim failure names the run."""
    f = F.Fdm(model, ts)
    try:
        f.trim(*(float(point[c][i]) for c in envelope.FLIGHT_COLUMNS), aero=aero)
    except F.JsbsimRunError as exc:
        raise F.JsbsimRunError(f"run {run_id}: {exc}") from None
    return f


def integrate_jsbsim(jp: JsbsimPrepared, sensors: SensorParams = SENSORS) -> AircraftTrajectory:
    """The closed-loop time loop of :func:`scenarios.aircraft.loop.integrate_reference` with
    JSBSim in place of the linear aircraft step."""
    p = jp.base
    n, T, ts, m = p.n, p.T, p.ts, p.monitored
    n_s = len(p.acts)
    pl, fa = p.plant, p.faults
    mon = slice(m * n, (m + 1) * n)
    pm = monitored_servo(p)
    fdms = jp.fdms
    W = F.SURFACE_MAP

    rods, surf, states, meas_rec, xs, icmd, iapp, u_rec, _ = record_arrays(p)

    x, delta = servo_start(p)
    i_prev = np.zeros(n * n_s)
    y_hold = np.zeros(n)
    state = laws.LawState.zeros(n)
    pitch_clipped = np.zeros(n, dtype=bool)
    steps, _ = laws.order_steps(ts, p.law_params)
    step_deg = steps[:, None]
    order_prev = p.trim_deg.copy()
    loaded = np.ones(n * n_s, dtype=bool)
    any_jam = bool((fa.k_jam < NEVER).any())
    any_disc = bool((fa.k_disc < NEVER).any())
    nse = p.ac_noise
    alpha0 = np.radians(p.flight_true["alpha_deg"])
    theta0 = np.array([f.theta0 for f in fdms])
    vals = np.array([f.read() for f in fdms]).T          # (len(READ), n) at t_0
    gusty = bool(jp.gusts.any())
    vc0 = np.array([f.vc0_kt for f in fdms])
    thr0 = np.array([f.throttle0 for f in fdms])
    speed_int = np.zeros(n)
    path_gain = np.array([f.tas_ms for f in fdms]) / (G0_MS2 * LOOP.path_tau_s)
    for k in range(T):
        _check(vals, jp.run_ids, k * ts)
        if any_jam:
            jam_onset(x, delta, k, fa, pl, mon)
        meas = {"p": vals[F.READ_P] + nse[0, :, k], "q": vals[F.READ_Q] + nse[1, :, k],
                "r": vals[F.READ_R] + nse[2, :, k], "phi": vals[F.READ_PHI] + nse[3, :, k],
                "theta": vals[F.READ_THETA] + nse[4, :, k],
                "dnz": vals[F.READ_NZ] - jp.nz0 + nse[5, :, k],
                "ny": vals[F.READ_NY] + nse[6, :, k],
                "beta": vals[F.READ_BETA] + nse[7, :, k],
                "alpha": vals[F.READ_ALPHA] + nse[8, :, k]}
        y, y_hold, meas["de"] = com_acquisition(x, k, p, pm, sensors, y_hold)
        gamma = meas["theta"] - meas["alpha"] * np.cos(meas["phi"])
        nz_c = (p.nz_c[:, k] + laws.turn_load_factor(meas["phi"], p.law_params)
                - path_gain * gamma)
        speed_err = vc0 - vals[F.READ_VC]
        speed_int = speed_int + speed_err * ts
        throttle = np.clip(thr0 + LOOP.at_kp_per_kt * speed_err
                           + LOOP.at_ki_per_kt_s * speed_int, 0.0, 1.0)
        _, order, order_prev, pitch_clipped, u_free_m = surface_orders(
            p, state, meas, nz_c, k, pitch_clipped, order_prev, step_deg)
        i_new, i_app = servo_currents(order, y, i_prev, k, p, pm)
        rods[:, :, k] = y.reshape(n_s, n)
        surf[:, :, k] = delta.reshape(n_s, n)
        states[:, :, k] = (vals[F.READ_ALPHA] - alpha0, vals[F.READ_Q],
                           vals[F.READ_THETA] - theta0, vals[F.READ_BETA], vals[F.READ_P],
                           vals[F.READ_R], vals[F.READ_PHI])
        meas_rec[:, :, k] = (meas["p"], meas["q"], meas["r"], meas["phi"], meas["theta"],
                             1.0 + meas["dnz"], meas["ny"], meas["beta"], meas["alpha"])
        xs[:, k] = x[mon]
        icmd[:, k] = i_new[mon]
        iapp[:, k] = i_app[mon]
        u_rec[:, k] = u_free_m
        x_next, delta_next = advance_servos(x, delta, i_app, loaded, k, p, any_jam, any_disc)
        # JSBSim over [t_k, t_k+1): each surface at the midpoint of its motion
        jsb = _to_jsbsim(W, (0.5 * (delta + delta_next)).reshape(n_s, n))   # (3, n)
        if gusty:
            ned = F.body_to_ned(vals[F.READ_PHI], vals[F.READ_THETA], vals[F.READ_PSI],
                                jp.gusts[:, :, k].T) / F.FT_M
        for i, f in enumerate(fdms):
            f.set_surfaces(jsb[0, i], jsb[1, i], jsb[2, i])
            f.set_throttle(throttle[i])
            if gusty:
                f.set_gust_ned(ned[0, i], ned[1, i], ned[2, i])
            try:
                f.step()
            except F.JsbsimRunError as exc:
                raise F.JsbsimRunError(f"run {jp.run_ids[i]} at {k * ts:.2f} s: {exc}") from None
            vals[:, i] = f.read()
        x, delta, i_prev = x_next, delta_next, i_new
    return AircraftTrajectory(x=xs, delta=surf[m], i_cmd=icmd, i_app=iapp, y_com=rods[m],
                              u=u_rec, rods=rods, surfaces=surf, states=states, sensors=meas_rec,
                              spoiler=np.zeros((n, T)))


def _to_jsbsim(weights: np.ndarray, surfaces: np.ndarray) -> np.ndarray:
    """JSBSim's three positions (3, n) from our seven surfaces (7, n), summed surface by
    surface in a fixed order: a matrix product's BLAS blocking depends on n, and a run's
    series must not depend on the runs of its block (docs/design.md §9, Determinism)."""
    out = np.zeros((weights.shape[0], surfaces.shape[1]))
    for row in range(weights.shape[0]):
        for j in np.flatnonzero(weights[row]):
            out[row] = out[row] + weights[row, j] * surfaces[j]
    return out


def _check(vals: np.ndarray, ids, t: float) -> None:
    """:class:`JsbsimRunError` for the first run that diverged or returned NaN."""
    bad = (~np.isfinite(vals).all(axis=0) | (np.abs(vals[F.READ_PHI]) > PHI_MAX_RAD)
           | (np.abs(vals[F.READ_ALPHA]) > ALPHA_MAX_RAD) | (vals[F.READ_H] < H_MIN_FT))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        v = vals[:, i]
        raise F.JsbsimRunError(
            f"run {ids[i]} diverged at {t:.2f} s on JSBSim: φ {np.degrees(v[F.READ_PHI]):.1f}°, "
            f"α {np.degrees(v[F.READ_ALPHA]):.1f}°, {v[F.READ_H]:.0f} ft (limits |φ| ≤ 80°, "
            f"|α| ≤ 30°, ≥ 500 ft; NaN: JSBSim returned no number)")


def simulate_jsbsim(runs: pd.DataFrame, *, aircraft: str = "737", ts: float = TS_S,
                    sensors: SensorParams = SENSORS, pressure_sensor: bool = False,
                    turbulence: DrydenParams | None = None,
                    aircraft_sensors: AircraftSensorParams = AIRCRAFT_SENSORS,
                    truth: bool = True) -> tuple[Signals, Truth | None]:
    """Simulate *runs* (one monitored surface and duration) on JSBSim; (Signals, Truth) as
    :func:`scenarios.aircraft.loop.simulate_aircraft`."""
    jp = prepare_jsbsim(runs, aircraft=aircraft, ts=ts, sensors=sensors,
                        aircraft_sensors=aircraft_sensors, turbulence=turbulence)
    traj = integrate_jsbsim(jp, sensors)
    return trajectory_signals(traj, jp.base, runs, ts=ts, sensors=sensors,
                              pressure_sensor=pressure_sensor, truth=truth)


@dataclass(frozen=True)
class JsbsimPlant(AircraftSurfaces):
    """A JSBSim aircraft in the loop (docs/aircraft.md §9): our servo-loops, sensors and
    laws flying JSBSim's nonlinear 6-DOF model; the run rows name the monitored surface, as
    for :class:`scenarios.aircraft.loop.AircraftPlant`. A :class:`scenarios.plants.Plant`.

    aircraft : a name of :data:`scenarios.jsbsim.fdm.AIRCRAFT` (default ``"737"``).
    turbulence : a level of :data:`scenarios.turbulence.LEVELS` (default ``"moderate"``).
    """

    aircraft: str = "737"
    turbulence: str = "moderate"
    aircraft_sensors: AircraftSensorParams = AIRCRAFT_SENSORS
    kind = "jsbsim"
    #: an FGFDMExec per run, held by the process that simulates it
    needs_processes = True
    #: runs simulated together (their servo-loops and laws vectorised, their FDMs stepped
    #: one after the other); a run's series never depend on its block
    batch_runs = 10
    learning_part_runs = 10

    def __post_init__(self):
        model = F.aircraft_model(self.aircraft)
        if model.beta:
            warnings.warn(f"the JSBSim {self.aircraft} model is marked beta by its authors",
                          stacklevel=2)

    def check(self, faults=()) -> None:
        """JSBSim must be installed (exit 2 naming the extra)."""
        F.jsbsim_module()

    def simulate(self, runs: pd.DataFrame, *, ts: float = TS_S, sensors: SensorParams = SENSORS,
                 pressure_sensor: bool = False) -> tuple[Signals, Truth]:
        return simulate_jsbsim(runs, aircraft=self.aircraft, ts=ts, sensors=sensors,
                               pressure_sensor=pressure_sensor,
                               turbulence=turbulence_level(self.turbulence),
                               aircraft_sensors=self.aircraft_sensors)

    def simulate_signals(self, runs: pd.DataFrame, *, ts: float = TS_S,
                         sensors: SensorParams = SENSORS, pressure_sensor: bool = False) -> Signals:
        return simulate_jsbsim(runs, aircraft=self.aircraft, ts=ts, sensors=sensors,
                               pressure_sensor=pressure_sensor,
                               turbulence=turbulence_level(self.turbulence),
                               aircraft_sensors=self.aircraft_sensors, truth=False)[0]
