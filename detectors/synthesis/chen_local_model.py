"""The local quasi-LPV actuator model of [CHEN] eq. 12–14 and its identification.

Model ([CHEN] eq. 12–14, after Hecker & Pfifer 2014), with the servo-valve current limit
and the damping neighbour of eq. 11::

    ẋ = K(ρ, x, sign ẋ)·σ(u − x)·D·(u − x),   K = C0(ρ) + C1(ρ)·sign(ẋ)·(x + C2(ρ))

x the rod position [mm], u the rod order [mm], K [1/s]. With K > 0, sign(ẋ) = sign(u − x)
(eq. 14), which the model and the estimator use. C0 [1/s], C1 [1/(s·mm)] and C2 [mm] are
affine in the scheduling vector ρ built from the *measured* flight data of
``Signals.schedule`` (:data:`SCHEDULE`): C_m(ρ) = c_m0 + Σ_j c_mj·ρ_j.

Two known factors complete eq. 12–13 where the orders move fast:

* σ(e) = min(1, e_sat/|e|), the servo-valve current saturation, which eq. 11 leaves out:
  the loop's current K_s·(u − y) is clipped at ±i_max, so beyond e_sat = i_max/K_s [mm]
  (:func:`saturation_mm`, from the actuator table) the rod moves at the saturated rate.
  Without it, in a fast order reversal the model runs ahead of the rod by up to 30 mm
  (identification runs, elevator: RMS on the saturated steps 8.9 mm without σ, 0.38 mm
  with it).
* D = 1/√(1 + κ·(C0·σ·e)²), the damping-mode neighbour's load F_damping of eq. 11 at the
  no-load rod speed C0·σ·e, κ = Ka/(S·ΔP_ref) (:func:`damping_coefficient`): 5 % of the
  saturated speed of the aileron. (RMS on the saturated steps 1.6 mm without D.)

σ and D are quasi-LPV scheduling functions of the state, like x and sign ẋ in ρ̃ of eq. 24:
K·σ·D stays in the interval [K_min·σ_min·D_min, K_max] the design of eq. 23 certifies.
(The square root of eq. 11 kept whole instead of eq. 13's first-order expansion fits the
identification runs equally well and follows the aircraft plant's loaded roll-ins worse:
largest fault-free liquid residual in the turns 1.26 mm against 0.43 mm; eq. 13 is kept.)

Why this structure fits the servo-loop (docs/physics.md §3): linearising the square-root load
factor of [CHEN] eq. 11 around a small load gives K ≈ Kci·K_s·(1 − sign(ẋ)·F_aero/(2·S·ΔP))
with F_aero affine in δ ≈ x/r, i.e. C0 = Kci·K_s, C1 ∝ q̄·Chδ·PG(M) and C2 ∝ Chα·α/Chδ:
q̄, Mach and α are the natural scheduling variables. :func:`physical_coefficients` gives
these values, used as the starting point of the fit.

Discretisation at Ts (the FCC period): K·σ·D frozen over a period, bilinear (Tustin)
transform, the order entering one period late (the FCC transport delay, docs/physics.md §2)::

    x_{k+1} = v_k + (x_k − v_k)·φ(K_k·σ_k·D_k),   φ(K) = (1 − K·Ts/2)/(1 + K·Ts/2),   v_k = u_{k−d}

(d = ``input_delay_steps``). φ is stable (|φ| < 1) for every K > 0 and costs a few
multiply-adds and one division, which are correctly rounded: the result of a run does not
depend on the other runs of a batch (a vectorised exponential can differ in the last bit
between array lengths).

Identification (Hecker & Pfifer's output-error least squares): the nonlinear servo-loop of
:mod:`scenarios.simulate` is run fault-free, with the nominal actuator, at every realistic
point of the [CHEN] Table-1 grid (:func:`scenarios.envelope.realistic_points`) under a
deterministic excitation order (:func:`excitation_orders`: slow moves and moves fast enough
to saturate the current, across each point's authority); the coefficients minimise the
difference between the model's simulated rod position (driven by the order alone) and the
servo-loop's true rod position, with ``scipy.optimize.least_squares`` and the exact
Jacobian of the recursion (forward sensitivities).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from scenarios.params import ActuatorParams, param

#: Scheduling variables (keys of ``Signals.schedule``) and their normalisation scale
#: (ρ_j = value / scale; numerical only, keeps the fit well conditioned).
SCHEDULE: dict[str, float] = {"qbar_pa": 10_000.0, "mach": 1.0, "alpha_deg": 10.0}


@dataclass(frozen=True)
class IdentificationSettings:
    """Settings of the output-error identification (numerical, est.)."""

    levels: tuple = param("-", "est.", "successive order levels, as fractions of the "
                          "point's authority interval (0 = lower, 1 = upper limit)")
    rates_deg_s: tuple = param("deg/s", "est. (≤ the manoeuvres' 25 °/s, scenarios.manoeuvres)",
                               "peak rates of the raised-cosine moves between levels (cycled)")
    holds_s: tuple = param("s", "est.", "holds after each move (cycled)")
    sine_amp_frac: float = param("-", "est.", "small sine added to the order, fraction of "
                                 "the authority interval (excites small-signal dynamics)")
    sine_hz: float = param("Hz", "est.", "frequency of that sine")
    input_delay_steps: int = param("steps", "docs/physics.md §2 (one Ts of transport delay)",
                                   "delay d of the order in the discrete model")
    max_nfev: int = param("-", "numerical", "iteration budget of least_squares")

    def schedule_moves(self, span_deg: float) -> tuple[list[tuple[float, float, float, float]],
                                                       float]:
        """Moves (start [s], from, to [fractions], duration [s]) for an authority interval
        of *span_deg* [deg], and the run duration [s] that holds them."""
        moves, t = [], self.holds_s[0]
        for j in range(len(self.levels) - 1):
            a, b = self.levels[j], self.levels[j + 1]
            rate = self.rates_deg_s[j % len(self.rates_deg_s)]
            dur = max(np.pi * abs(b - a) * span_deg / (2.0 * rate), 0.05)
            moves.append((t, a, b, dur))
            t += dur + self.holds_s[(j + 1) % len(self.holds_s)]
        return moves, t


SETTINGS = IdentificationSettings(
    # slow moves (≤ 25 °/s, the manoeuvres' rates), then fast ones (80–300 °/s: the current
    # saturates, as in an aileron reversal flown through the laws), both ways, near the limits
    levels=(0.5, 0.7, 0.35, 0.9, 0.1, 0.6, 0.02, 0.45, 0.98, 0.5,
            0.95, 0.05, 0.7, 0.02, 0.98, 0.3, 0.5),
    rates_deg_s=(20.0, 5.0, 25.0, 10.0, 15.0, 3.0, 22.0, 8.0, 18.0,
                 150.0, 80.0, 300.0, 120.0, 200.0, 100.0, 250.0),
    holds_s=(0.5, 0.8, 0.4, 1.0),
    sine_amp_frac=0.01,
    sine_hz=1.5,
    input_delay_steps=1,
    max_nfev=60,
)


def scheduling_vector(schedule: dict) -> np.ndarray:
    """ρ (n_runs, n_ρ) from measured scheduling data (:data:`SCHEDULE`)."""
    missing = [k for k in SCHEDULE if k not in schedule]
    if missing:
        raise ValueError(f"the quasi-LPV actuator model needs the scheduling data {missing} "
                         f"in Signals.schedule (has {sorted(schedule)})")
    return np.stack([np.asarray(schedule[k], float) / s for k, s in SCHEDULE.items()], axis=-1)


def basis(rho: np.ndarray) -> np.ndarray:
    """φ(ρ) = [1, ρ_1, …, ρ_nρ] (…, 1 + n_ρ): C_m(ρ) = c_m·φ(ρ)."""
    rho = np.asarray(rho, float)
    return np.concatenate([np.ones(rho.shape[:-1] + (1,)), rho], axis=-1)


def coefficients(theta: np.ndarray, rho: np.ndarray) -> tuple[np.ndarray, ...]:
    """(C0, C1, C2)(ρ) for the coefficient matrix *theta* (3, 1 + n_ρ)."""
    rho = np.asarray(rho, float)
    th = np.asarray(theta, float).reshape(3, -1)
    out = []
    for m in range(3):
        # elementwise (not a BLAS product): a run's value never depends on the batch
        c = np.full(rho.shape[:-1], th[m, 0])
        for j in range(rho.shape[-1]):
            c = c + th[m, j + 1] * rho[..., j]
        out.append(c)
    return tuple(out)


def gain(c0, c1, c2, x, s):
    """K = C0 + C1·s·(x + C2) [1/s] ([CHEN] eq. 13), s = sign(ẋ) ∈ {−1, 0, 1}."""
    return c0 + c1 * s * (x + c2)


def saturation_mm(act: ActuatorParams) -> float:
    """e_sat = i_max/K_s [mm]: the order–rod error beyond which the servo-valve current
    saturates (docs/physics.md §3)."""
    return float(act.i_max_mA / act.K_mA_per_mm)


def damping_coefficient(act: ActuatorParams) -> float:
    """κ = Ka/(S·ΔP_ref) [(s/mm)²]: the damping-mode neighbour's load F_damping = Ka·ẋ² of
    [CHEN] eq. 11 relative to the reference force (docs/physics.md §3, [COMB] eq. 2)."""
    return float(act.Ka_N_per_mm_s2 / (act.S_m2 * act.dP_ref_Pa))


def damping_factor(v0, kappa: float):
    """D = 1/√(1 + κ·v0²) [-]: the rod speed's reduction by the damping-mode neighbour at the
    no-load speed *v0* = C0·σ·(u − x) [mm/s] (the servo-loop's law, docs/physics.md §3)."""
    return 1.0 / np.sqrt(1.0 + kappa * v0 * v0)


def saturation_factor(e, e_sat: float):
    """σ(e) = min(1, e_sat/|e|) [-] (module docstring)."""
    a = np.abs(e)
    return np.where(a > e_sat, e_sat / np.where(a > e_sat, a, 1.0), 1.0)


def physical_coefficients(act: ActuatorParams, schedule: dict) -> np.ndarray:
    """(C0, C1, C2) per run (n, 3) from the linearised servo-loop law (module docstring)."""
    from scenarios.servo import compressibility_factor

    q = np.asarray(schedule["qbar_pa"], float)
    pg = compressibility_factor(schedule["mach"], act.mach_compress_cap)
    alpha_s = np.radians(np.asarray(schedule["alpha_deg"], float)) * (1.0 - act.downwash)
    bw = act.bandwidth_per_s
    r_m = act.r_mm / 1000.0
    c1 = bw * q * act.Sc_m2 * act.cc_m * pg * act.Ch_delta / (2.0 * r_m * act.r_mm
                                                              * act.stall_force_N)
    c2 = act.r_mm * act.Ch_alpha * alpha_s / act.Ch_delta
    return np.stack([np.full_like(q, bw), c1, c2], axis=-1)


def tustin_pole(a_neg, ts: float):
    """φ = (1 − a·Ts/2)/(1 + a·Ts/2): the bilinear discretisation of ẋ = −a·x at period Ts."""
    return (1.0 - 0.5 * ts * a_neg) / (1.0 + 0.5 * ts * a_neg)


def simulate_model(theta, rho, u, ts: float, x0, delay: int, sensitivities: bool = False,
                   e_sat: float = np.inf, kappa: float = 0.0):
    """Run the discrete model with current saturation *e_sat* [mm] and damping
    neighbour *kappa* [(s/mm)²] over orders *u* (n, T) from *x0* (n,); returns x (n, T)
    and, with *sensitivities*, dx/dθ (n, T, n_θ) (exact derivative of the recursion, the
    sign held piecewise constant)."""
    u = np.asarray(u, float)
    n, T = u.shape
    c0, c1, c2 = coefficients(theta, rho)
    phi = basis(rho)                                        # (n, 1 + nρ)
    nb = phi.shape[1]
    x = np.asarray(x0, float).copy()
    xs = np.empty((n, T))
    dxs = np.empty((n, T, 3 * nb)) if sensitivities else None
    dx = np.zeros((n, 3 * nb))
    for k in range(T):
        xs[:, k] = x
        v = u[:, max(k - delay, 0)]
        err = v - x
        s = np.sign(err)
        K = gain(c0, c1, c2, x, s)
        sig = saturation_factor(err, e_sat)
        w = sig * err                                   # error the current sees [mm]
        D = damping_factor(c0 * w, kappa)
        Ke = K * sig * D
        den = 1.0 + 0.5 * ts * Ke
        e = tustin_pole(Ke, ts)
        if sensitivities:
            dxs[:, k] = dx
            # ∂K/∂(c0, c1, c2) and ∂K/∂x (eq. 13)
            g0, g1, g2 = np.ones(n), s * (x + c2), c1 * s
            gx = c1 * s
            # σ = e_sat/|v − x| when saturated: ∂σ/∂x = σ/(v − x); w = σ·(v − x) is
            # then constant (∂w/∂x = 0), else ∂w/∂x = −1; D = (1 + κ(C0·w)²)^(−1/2)
            dsig = np.where(sig < 1.0, sig / np.where(err != 0.0, err, 1.0), 0.0)
            dD_dc0 = -D ** 3 * kappa * w * w * c0
            dD_dx = -D ** 3 * kappa * c0 * c0 * w * np.where(sig < 1.0, 0.0, -1.0)
            sd = sig * D
            dKe = (np.concatenate([(sd * g0 + K * sig * dD_dc0)[:, None] * phi,
                                   (sd * g1)[:, None] * phi, (sd * g2)[:, None] * phi], axis=1)
                   + (sd * gx + K * D * dsig + K * sig * dD_dx)[:, None] * dx)
            de = -ts / (den * den)                      # dφ/dK
            dx = e[:, None] * dx + ((x - v) * de)[:, None] * dKe
        x = v + (x - v) * e
    return (xs, dxs) if sensitivities else xs


def excitation_orders(lo_deg, hi_deg, ts: float,
                      settings: IdentificationSettings = SETTINGS) -> np.ndarray:
    """Surface orders [deg] (n, T): raised-cosine moves between the levels of *settings*
    inside each point's authority interval [lo, hi] (rate-limited as the manoeuvres are, so
    the current rarely saturates), plus a small sine. All runs share the widest timing."""
    lo = np.asarray(lo_deg, float)[:, None]
    hi = np.asarray(hi_deg, float)[:, None]
    moves, duration = settings.schedule_moves(float(np.max(hi - lo)))
    T = int(round(duration / ts))
    t = np.arange(T) * ts
    frac = np.full(T, settings.levels[0])
    for start, a, b, dur in moves:
        xi = np.clip((t - start) / dur, 0.0, 1.0)
        frac = np.where(t >= start, a + (b - a) * 0.5 * (1.0 - np.cos(np.pi * xi)), frac)
    frac = frac + settings.sine_amp_frac * np.sin(2 * np.pi * settings.sine_hz * t)
    return lo + (hi - lo) * np.clip(frac, 0.0, 1.0)[None, :]


@dataclass(frozen=True)
class LocalModelFit:
    """Identified quasi-LPV actuator model.

    theta : (3, 1 + n_ρ) coefficients of C0 [1/s], C1 [1/(s·mm)], C2 [mm] on [1, ρ].
    e_sat_mm : current-saturation error [mm]; kappa : damping-neighbour coefficient
    [(s/mm)²].
    rms_mm : output-error RMS [mm] over every identification run and step.
    max_abs_mm : largest output error [mm].
    rms_initial_mm : RMS of the physical (linearised) starting point [mm].
    rho_min, rho_max : (n_ρ,) bounds of ρ over the identification envelope.
    x_min_mm, x_max_mm : rod range of the identification runs [mm].
    n_points : flight points used; ts : period [s]; delay : input delay [steps].
    """

    theta: np.ndarray
    e_sat_mm: float
    kappa: float
    rms_mm: float
    max_abs_mm: float
    rms_initial_mm: float
    rho_min: np.ndarray
    rho_max: np.ndarray
    x_min_mm: float
    x_max_mm: float
    n_points: int
    ts: float
    delay: int

    def as_dict(self) -> dict:
        return {"theta": self.theta.tolist(), "e_sat_mm": self.e_sat_mm,
                "kappa": self.kappa,
                "rms_mm": self.rms_mm,
                "max_abs_mm": self.max_abs_mm, "rms_initial_mm": self.rms_initial_mm,
                "rho_names": list(SCHEDULE), "n_points": self.n_points}


def identification_runs(act: ActuatorParams, ts: float,
                        settings: IdentificationSettings = SETTINGS):
    """(schedule, order u [mm], true rod x [mm]) of the fault-free identification runs."""
    import pandas as pd

    from scenarios import envelope
    from scenarios.servo import authority_limits, plant_arrays
    from scenarios.simulate import single_run, simulate

    pts = envelope.realistic_points()
    pts = pts[pts["realistic"]].reset_index(drop=True)
    fc = envelope.flight_condition(pts["alt_ft"], pts["vcas_kt"], pts["mass_t"], pts["cg_pct"])
    plant = plant_arrays(act, qbar_pa=fc["qbar_pa"], alpha_deg=fc["alpha_deg"], mach=fc["mach"])
    lo, hi = authority_limits(plant, act)
    orders = excitation_orders(lo, hi, ts, settings)
    # an aircraft-plant surface (e.g. left_inboard_aileron) is identified on the actuator-level
    # servo-loop of its kind, with its own parameter table
    from scenarios.params import ACTUATORS

    kind = act.surface
    if kind not in ACTUATORS:
        from scenarios.aircraft.data import LAYOUT

        if kind not in LAYOUT.names:
            raise ValueError(f"no servo-loop to identify for surface {kind!r}")
        kind = LAYOUT.actuator[LAYOUT.names.index(kind)]
        act = act.replace(surface=kind)
    rows = pd.concat([single_run(act.surface, "cruise", "none", seed=0,
                                 duration_s=orders.shape[1] * ts,
                                 **{c: float(p[c]) for c in envelope.FLIGHT_COLUMNS})
                      .assign(stream=j, run_id=f"ident-{j}")
                      for j, p in pts.iterrows()], ignore_index=True)
    signals, truth = simulate(rows, ts=ts, actuators={act.surface: act}, orders_deg=orders)
    return signals.schedule, signals.command, truth.rod_mm


@functools.lru_cache(maxsize=8)
def fit_local_model(act: ActuatorParams, ts: float,
                    settings: IdentificationSettings = SETTINGS) -> LocalModelFit:
    """Identify the quasi-LPV model of *act* at period *ts* (cached per actuator)."""
    from scipy.optimize import least_squares

    schedule, u, x_true = identification_runs(act, ts, settings)
    rho = scheduling_vector(schedule)
    phi = basis(rho)
    # starting point: least-squares affine fit of the linearised physical coefficients
    phys = physical_coefficients(act, schedule)
    theta0 = np.linalg.lstsq(phi, phys, rcond=None)[0].T          # (3, nb)
    d = int(settings.input_delay_steps)
    x0 = x_true[:, 0]
    e_sat = saturation_mm(act)
    kappa = damping_coefficient(act)
    opts = dict(e_sat=e_sat, kappa=kappa)

    def resid(th):
        return (simulate_model(th, rho, u, ts, x0, d, **opts) - x_true).ravel()

    def jac(th):
        _, dx = simulate_model(th, rho, u, ts, x0, d, sensitivities=True, **opts)
        return dx.reshape(-1, dx.shape[-1])

    r0 = resid(theta0.ravel())
    sol = least_squares(resid, theta0.ravel(), jac=jac, method="lm",
                        max_nfev=settings.max_nfev, x_scale="jac")
    err = sol.fun
    return LocalModelFit(
        theta=sol.x.reshape(3, -1), e_sat_mm=e_sat, kappa=kappa,
        rms_mm=float(np.sqrt(np.mean(err ** 2))),
        max_abs_mm=float(np.max(np.abs(err))), rms_initial_mm=float(np.sqrt(np.mean(r0 ** 2))),
        rho_min=rho.min(axis=0), rho_max=rho.max(axis=0),
        x_min_mm=float(x_true.min()), x_max_mm=float(x_true.max()),
        n_points=int(rho.shape[0]), ts=float(ts), delay=d)
