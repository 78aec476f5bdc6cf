"""The LPV H−/H∞ fault estimator of [CHEN] at the global (aircraft) level: disconnection of
a monitored aileron, estimated from the lateral motion of the aircraft (``chen-global``).

Model ([CHEN] eq. 25), lateral rigid body of :mod:`scenarios.aircraft.lpv` (speed held,
stability axes), in degrees throughout (the model is linear, so one angle unit suffices)::

    ẋ_b = A_b(ρ) x_b + B_b(ρ) u_b + B_b(ρ) W f_dis + M_g δ_g,    y_b = C_b x_b + H f_dis

x_b = [β, p, r, φ] (β = v_y/V replaces v_y: the same state scaled by the held speed),
y_b = [φ, p, r] (the aircraft sensors of ``Signals.aircraft``), u_b = the deflections of the
four ailerons and the rudder computed from their COM rod acquisitions (``Signals.rods``,
δ = asin(x/r)), and the roll spoilers' equivalent angle. The spoilers have no servo-loop in
this simulator: they take the roll order of the previous period (fixed coupling,
:mod:`scenarios.aircraft.loop`), recorded in ``Signals.aircraft["spoiler"]``; it stands
for the spoiler rod measurements of [CHEN] eq. 25.

Fault model ([CHEN] eq. 5 and 25): a disconnected surface no longer follows its rod; the
aircraft sees u = u_0 + f_dis, with u_0 the deflection of the rod measurement and f_dis the
difference between the true (floating) deflection and it [deg]. W selects the monitored
aileron: F(ρ) = B_b(ρ)·W is its column of B_b. The fault has no feed-through (H = 0), so H
is perturbed to ε·E (Remark 4.1; ε = ``h_perturbation``, E the unit vector of the output
``h_output``, or of e_out + c·e_p with c = ``h_rate_weight``) and the design is exact for that
perturbed model (G_f̂f = I); on the unperturbed model the static gain from f_dis to f̂ is below one
and tends to one as ε → 0 (reported in the fitted state as ``static_gain_``).

Scheduling ([CHEN] eq. 8–9): with the derivative scaling of :mod:`scenarios.aircraft.lpv`
(Prandtl–Glauert factor PG(M), inertias proportional to the mass m), every entry of A_b and
B_b is affine in ρ = (q̄·PG/m, q̄·PG/(m·V), q̄·PG/(m·V²), g/V), computed from the *measured*
schedule (q̄, Mach, altitude, mass of ``Signals.schedule``). The affine coefficients are
obtained by least squares on models built by :func:`scenarios.aircraft.lpv.run_models` over
the envelope grid; the fit is checked exact (to round-off). Components whose coefficient
matrices vanish are dropped; the polytope is the box of the remaining components over every
realistic point of the [CHEN] Table-1 grid seen through the corners of the Table-2
measurement errors widened by ``schedule_margin`` (2^r vertices).

Uncertainty ([CHEN] eq. 25, Table 2): δ_g enters through M_g, realised in
:mod:`detectors.synthesis.chen_global_uncertainty` from the ±5 % coefficient errors (d_cy, d_cl,
d_cn scale whole rows of aerodynamic terms, docs/physics.md §6) and the ±10 % flight-data errors
(they reach the model through the measured ρ and scale the same terms): three constant
columns, the directions in which a side force, a rolling moment and a yawing moment
accelerate the aircraft ([CHEN] §6: "δ_g mainly affects the channels of the roll rate and
the yaw rate"; the side-force channel is kept), N_g = 0. The H∞ objective of eq. 23 bounds
δ_g → f̂ − f.

Gusts: a gust sideslip β_g enters the lateral equations exactly as A_b[:, β]·β_g and rolls
the aircraft like tens of degrees of one inboard aileron; with ``gust_channel`` it is a
second unknown input decoupled by the same eq. 20–21 (F = [B_b W, A_b[:, β]], E gets a
second column along r or φ), and f̂ is the first component of the estimate. [CHEN]'s model
has no such input (u_w = 0, its footnote 1); ``chen-mc`` and ``chen-sweep`` run without it
by default; :mod:`detectors.builtin.chen_global_paper` has what [CHEN] prints, and ours where
it prints nothing, each labelled (docs/chen-estimator.md §5.1).

Synthesis: :func:`detectors.synthesis.lpv_synthesis.synthesise` (vertex LMIs of eq. 23, Z1 = P⁻¹S,
gains of eq. 20–21, L1(ρ) = −F(ρ)H† + Z1H⊥ affine in ρ). It runs once in ``fit`` and its
results are kept in the fitted state. The estimator's stability is checked at every vertex
and on a dense grid of the box (continuous and discretised). Online, ρ is constant over a
run (the schedule is per run), so each run's estimator is discretised once, exactly, with
the rods and the aircraft sensors as ramps over the period (first-order hold; the spoiler
angle is held over the period in the plant, so it is held here): each step is then
x̂ ← Φ x̂ + Γ [u; y] + Γ₁ Δ[u; y] and f̂ = L2 (y − C x̂), about 80 multiply-adds per run,
vectorised over runs (the five filters of the activity bound below add about 150). (With y
held instead, the fast observer poles turn the half-period lag of p during a roll-in into
about 1° of f̂.)

Decision: |f̂| after a first-order low-pass of time constant ``filter_s`` (against sensor
noise) against the adaptive threshold τ0 + b(t), confirmed over ``confirm_s``. b(t) =
Σ_j k_j |w_j| (low-passed alike) is the bound the Table-2 errors put on |f̂ − f| given the
measured lateral activity: w_j is the response of f̂, through the estimator's own error
dynamics of eq. 17, to the aerodynamic accelerations the model computes on the measured
p, r, φ, the estimated β and gust and the rods with the estimated fault; k_j the largest
relative error of that term over the envelope and Table 2 (:func:`table2_error_bounds`;
no learned factor). τ0 covers what Table 2 does not (turbulence beyond the gust channel,
sensor noise, the plant's nonlinearities): it is learned from the fault-free learning set
as the per-run maximum of |f̂| − b(t), through :func:`detectors.calibrate.learned_threshold`
(calibrated to ``target_fa_per_run`` per run by default). With ``adaptive = False`` the
threshold is the constant τ0 learned on |f̂| alone (the decision before the bound existed).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from scenarios import compiled as kernels
from scenarios.params import param
from scenarios.signals import Signals

from ..base import Capabilities, Detection, Detector, decide, per_run_maxima, windowed_min
from ..calibrate import THRESHOLD_PARAMS, learned_threshold
from .chen_global_kernel import recursion_window
from ..params import Param

#: Steps whose inputs to the estimator's recursion are formed together (memory: a few
#: series per run of this length instead of the whole run).
TIME_WINDOW = 500

#: Lateral states of [CHEN] eq. 25 (β stands for v_y), outputs and inputs, in array order.
STATES = ("beta", "p", "r", "phi")
OUTPUTS = ("phi", "p", "r")
INPUT_SURFACES = ("left_inboard_aileron", "right_inboard_aileron", "left_outboard_aileron",
                  "right_outboard_aileron", "rudder")
#: Signals.aircraft entry of the spoiler input (the last column of u_b) [deg].
SPOILER = "spoiler"
#: Uncertainty distributions of the H∞ objective
#: (:func:`detectors.synthesis.chen_global_uncertainty.design_uncertainty_matrix`).
UNCERTAINTY_DESIGNS = ("table2", "fault-removed")


@dataclass(frozen=True)
class GlobalNumerics:
    """Numerical constants of the global design (not physical parameters)."""

    affine_tolerance: float = param("-", "numerical", "largest relative residual of the "
                                    "affine fit of A_b, B_b in ρ")
    negligible: float = param("-", "numerical", "a ρ component whose coefficients are below "
                              "this share of the largest entry is dropped")
    grid_per_axis: int = param("-", "numerical", "grid values per ρ component of the "
                               "stability check inside the box")
    polytope_margin: float = param("-", "numerical", "relative widening of the ρ box")


NUMERICS = GlobalNumerics(affine_tolerance=1e-9, negligible=1e-9, grid_per_axis=9,
                          polytope_margin=0.02)


def _tas(schedule: dict) -> np.ndarray:
    from scenarios.atmosphere import tas_ms

    return tas_ms(np.asarray(schedule["mach"], float), np.asarray(schedule["alt_ft"], float))


#: Measured scheduling data the global model needs.
SCHEDULE_KEYS = ("mach", "qbar_pa", "alt_ft", "mass_t", "cg_pct")


def scheduling_vector(schedule: dict) -> np.ndarray:
    """ρ = (q̄·PG/m, q̄·PG/(m·V), q̄·PG/(m·V²), g/V), shape (n, 4), from the measured schedule
    (q̄ [Pa], m [kg], V the TAS of the measured Mach and altitude [m/s]; PG the Prandtl–Glauert
    factor relative to the reference Mach of the derivative set, :mod:`scenarios.aircraft.lpv`)."""
    from scenarios.atmosphere import G0_MS2
    from scenarios.aircraft.data import A330_SCALING, B747_CONDITION
    from scenarios.envelope import KG_PER_T
    from scenarios.servo import compressibility_factor

    missing = [k for k in SCHEDULE_KEYS if k not in schedule]
    if missing:
        raise ValueError(f"the lateral LPV model needs the scheduling data {missing} in "
                         f"Signals.schedule (has {sorted(schedule)})")
    m = np.asarray(schedule["mass_t"], float) * KG_PER_T
    q = np.asarray(schedule["qbar_pa"], float)
    V = _tas(schedule)
    cap = A330_SCALING.mach_cap
    pg = (compressibility_factor(np.asarray(schedule["mach"], float), cap)
          / compressibility_factor(B747_CONDITION.mach, cap))
    a = q * pg / m
    return np.stack([a, a / V, a / (V * V), G0_MS2 / V], axis=-1)


def lateral_models(schedule: dict, airframe: str | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """(A_b (n, 4, 4), B_b (n, 4, 6)) of the nominal lateral model (every draw 0) at each
    measured flight point, from the design models of *airframe*
    (:func:`scenarios.design_models.nominal_models`: our
    :func:`scenarios.aircraft.lpv.run_models`, or a JSBSim aircraft's trimmed
    linearisations) (states :data:`STATES`, inputs :data:`INPUT_SURFACES` then the spoilers;
    any angle unit)."""
    from scenarios import design_models
    from scenarios.aircraft import lpv
    from scenarios.aircraft.data import LAYOUT

    model = design_models.nominal_models(airframe, schedule)
    idx = {"beta": lpv.IB, "p": lpv.IP, "r": lpv.IR, "phi": lpv.IPHI}
    rows = [idx[s] for s in STATES]
    cols = [LAYOUT.names.index(s) for s in INPUT_SURFACES] + [lpv.I_SPOILER]
    return model.A[:, rows][:, :, rows], model.B[:, rows][:, :, cols]


def envelope_schedules(schedule_margin: float, airframe: str | None = None,
                       corners: bool = True) -> dict:
    """Measured schedules of every realistic [CHEN] Table-1 point (as a flight point of
    *airframe*, :func:`scenarios.design_models.envelope_points`) seen through each corner
    (−w, 0, +w) of the Table-2 errors on VCAS, altitude, mass and CG, widened by
    *schedule_margin* relative to w (arrays of 53·81 points); without *corners*, the
    points themselves (53)."""
    from scenarios import design_models, envelope

    true = design_models.envelope_points(airframe)
    w = envelope.UNCERTAINTY
    if not corners:
        return envelope.measured_schedule(true["alt_ft"], true["vcas_kt"], true["mass_t"],
                                          true["cg_pct"], 0.0, 0.0, 0.0, 0.0)
    s = 1.0 + float(schedule_margin)
    parts = [envelope.measured_schedule(true["alt_ft"], true["vcas_kt"], true["mass_t"],
                                        true["cg_pct"], dh * w.alt * s, dv * w.vcas * s,
                                        dm * w.mass * s, dc * w.cg * s)
             for dv, dh, dm, dc in itertools.product(*[(-1.0, 0.0, 1.0)] * 4)]
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


def table2_error_bounds(airframe: str | None = None) -> np.ndarray:
    """k_j of each driving signal of :data:`detectors.synthesis.chen_global_uncertainty.SIGNALS`:
    the largest relative error of its term between the aircraft and the model scheduled on the
    measured flight data, over every realistic [CHEN] Table-1 point and every corner of the
    Table-2 measurement errors, with the ±5 % coefficient errors on top ([CHEN] Table 2,
    docs/physics.md §6; :func:`detectors.synthesis.chen_global_uncertainty.error_bounds`)."""
    from scenarios import envelope

    from ..synthesis.chen_global_uncertainty import CHANNELS, error_bounds

    corners = list(itertools.product(*[(-1.0, 0.0, 1.0)] * 4))
    rho = scheduling_vector(envelope_schedules(0.0, airframe)).reshape(len(corners), -1, 4)
    true = rho[corners.index((0.0, 0.0, 0.0, 0.0))]
    widths = {c: envelope.coefficient_width(envelope.UNCERTAINTY, c, "aero") for c in CHANNELS}
    return error_bounds(true[None], rho, widths)


@dataclass
class AffineLateralModel:
    """A_b(ρ), B_b(ρ) = coef[0] + Σ ρ_k coef[1 + k] over the kept ρ components ``keep``."""

    coef_A: np.ndarray        # (1 + r, 4, 4)
    coef_B: np.ndarray        # (1 + r, 4, 6)
    keep: np.ndarray          # indices of the kept components of scheduling_vector
    residual: float           # largest relative residual of the fit

    def matrices(self, rho: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(A (…, 4, 4), B (…, 4, 6)) at ρ (…, 4) (full scheduling vectors)."""
        phi = np.concatenate([np.ones(rho.shape[:-1] + (1,)), rho[..., self.keep]], axis=-1)
        # explicit sums (no BLAS): each run's matrices independent of the batch around it
        A = sum(phi[..., k, None, None] * self.coef_A[k] for k in range(phi.shape[-1]))
        B = sum(phi[..., k, None, None] * self.coef_B[k] for k in range(phi.shape[-1]))
        return A, B


def fit_affine(schedule: dict, numerics: GlobalNumerics = NUMERICS,
               airframe: str | None = None, box: tuple | None = None) -> AffineLateralModel:
    """Least-squares affine coefficients of A_b, B_b in ρ over the points of *schedule*, on
    the design models of *airframe* (:func:`lateral_models`).

    On the project's aircraft the model is affine in ρ by construction: every ρ component
    whose coefficients are not negligible is kept, and a residual above
    ``numerics.affine_tolerance`` raises ValueError (the scaling of lpv.py changed).

    A JSBSim aircraft's linearisations are not affine in ρ: the fit is a least-squares LPV
    approximation, as [CHEN] §5 fits its own to the aircraft's, and its largest relative
    residual is kept (``residual``). Its components are chosen (:func:`_stable_components`)
    so that the fitted model is a stable aircraft at every vertex of the scheduling box
    *box* = (lo, hi) the synthesis uses, as every linearisation of the envelope is."""
    from scenarios import design_models

    rho = scheduling_vector(schedule)
    A, B = lateral_models(schedule, airframe)
    Y = np.concatenate([A.reshape(len(A), -1), B.reshape(len(B), -1)], axis=1)
    scale = rho.max(axis=0)
    big = np.abs(Y).max()
    if design_models.exactly_affine(airframe):
        coef, _ = _least_squares(rho / scale, Y, np.arange(rho.shape[1]))
        keep = np.flatnonzero(np.abs(coef[1:]).max(axis=1) > numerics.negligible * big)
    else:
        if box is None:
            raise ValueError(f"the LPV fit on {airframe} needs the scheduling box (lo, hi)")
        keep = _stable_components(rho / scale, Y, box[0] / scale, box[1] / scale)
    coef, fitted = _least_squares(rho / scale, Y, keep)
    residual = float(np.abs(fitted - Y).max() / big)
    if residual > numerics.affine_tolerance and design_models.exactly_affine(airframe):
        raise ValueError(f"the lateral model is not affine in the scheduling vector of [CHEN] "
                         f"eq. 8 (relative residual {residual:.2g}); the derivative scaling of "
                         "scenarios.aircraft.lpv no longer matches chen_global.scheduling_vector")
    coef[1:] /= scale[keep][:, None]
    return AffineLateralModel(coef_A=coef[:, :16].reshape(-1, 4, 4),
                              coef_B=coef[:, 16:].reshape(-1, 4, 6), keep=keep,
                              residual=residual)


def _least_squares(x: np.ndarray, Y: np.ndarray, keep) -> tuple[np.ndarray, np.ndarray]:
    """(coef, fitted values) of Y on [1, x[:, keep]] by least squares."""
    X = np.concatenate([np.ones((len(x), 1)), x[:, keep]], axis=1)
    coef, *_ = np.linalg.lstsq(X, Y, rcond=None)
    return coef, X @ coef


def _stable_components(x: np.ndarray, Y: np.ndarray, lo: np.ndarray, hi: np.ndarray
                       ) -> np.ndarray:
    """The ρ components (indices) of the LPV fit of a nonlinear aircraft: of every non-empty
    subset, the one with the smallest largest residual among those whose fitted A_b is
    stable (every eigenvalue in the open left half-plane) at every vertex of the box
    [lo, hi] over the subset. The four components of [CHEN] eq. 8 are strongly correlated
    over the envelope (|r| up to 0.8 on the 737), so a fit on all four extrapolates to box
    vertices that are no aircraft: measured on JSBSim's 737, open-loop poles up to +5.9 1/s
    at the vertices of the four-component fit (residual 11 %), while every trimmed
    linearisation has its poles left of −0.007 1/s. ValueError when no subset is stable."""
    best, best_residual = None, np.inf
    for r in range(1, x.shape[1] + 1):
        for keep in itertools.combinations(range(x.shape[1]), r):
            keep = np.array(keep)
            coef, fitted = _least_squares(x, Y, keep)
            corners = np.array(list(itertools.product(*zip(lo[keep], hi[keep]))))
            X = np.concatenate([np.ones((len(corners), 1)), corners], axis=1)
            A = (X @ coef)[:, :16].reshape(-1, 4, 4)
            if np.linalg.eigvals(A).real.max() >= 0.0:
                continue
            residual = np.abs(fitted - Y).max()
            if residual < best_residual:
                best, best_residual = keep, residual
    if best is None:
        raise ValueError("no affine LPV fit of the aircraft's lateral linearisations in the "
                         "components of [CHEN] eq. 8 is stable at every vertex of the "
                         "scheduling box; narrow the box (schedule_margin)")
    return best


def output_matrix() -> np.ndarray:
    """C_b (3, 4): y_b = [φ, p, r] from x_b = [β, p, r, φ]."""
    return np.array([[1.0 if s == o else 0.0 for s in STATES] for o in OUTPUTS])


def monitored_column(surface: str) -> int:
    """Column of u_b of the monitored aileron (W of [CHEN] eq. 25 selects it)."""
    if surface not in INPUT_SURFACES[:4]:
        raise ValueError(f"chen-global estimates the disconnection of an aileron; the "
                         f"monitored surface is {surface!r}; set [plant] monitored_surface "
                         f"to one of {', '.join(INPUT_SURFACES[:4])}")
    return INPUT_SURFACES.index(surface)


class ChenGlobalEstimator(Detector):
    """[CHEN] H−/H∞ LPV disconnection estimator at the aircraft level (module docstring).

    Parameters
    ----------
    h_perturbation : float
        ε of [CHEN] Remark 4.1 (> 0): H = ε·E [deg of output per deg of fault].
    h_output : str
        Output E points to: ``"phi"``, ``"p"`` or ``"r"``.
    h_rate_weight : float
        c [s] of E ∝ e_out + c·e_p (≥ 0): Remark 4.1 leaves E free; along φ + c·p the fault
        reaches f̂ through the roll rate at once (docs/chen-estimator.md §5.1).
    uncertainty : str
        M of the H∞ objective: ``"table2"`` (M_g) or ``"fault-removed"`` (M_g without the
        fault column's direction, :func:`detectors.synthesis.chen_global_uncertainty.
        design_uncertainty_matrix`).
    safety : float
        ``"max"`` thresholds: τ0 = safety × the largest learning value (> 1).
    confirm_s : float
        Time |f̂| must stay beyond the threshold [s] (≥ 0).
    filter_s : float
        Time constant of the low-pass on f̂ [s] (≥ 0; 0: none).
    schedule_margin : float
        Relative widening of the Table-2 error widths over which the polytope is computed
        (≥ 0); scheduling data outside the box are clipped to it.
    floor_deg : float
        Smallest τ0 [deg] (> 0).
    gust_channel : bool
        Decouple the gust sideslip as a second unknown input.
    adaptive : bool
        Threshold τ0 + b(t) with the Table-2 activity bound b (module docstring); False: τ0.
    threshold_method, target_fa_per_run, threshold_confidence, threshold_tail
        How thresholds are learned: calibrated to a per-run false-alarm target per
        manoeuvre (``"evt"``, the default) or ``safety`` × the largest learning value
        (``"max"``); :data:`detectors.calibrate.THRESHOLD_PARAMS`, docs/thresholds.md.
    """

    capabilities = Capabilities(needs_fit=True, needs_surface_sensor=False, causal=True,
                                needs_aircraft=True, threshold_scale=True,
                                covers=("disconnection",),
                                coverage_reason="[CHEN] §6.1, eq. 25: the global estimator "
                                "of an aileron disconnection from the aircraft's lateral "
                                "motion")

    parameters = (
        Param("h_perturbation", "float", gt=0.0, unit="deg/deg", doc="ε of Remark 4.1: "
              "H = ε·E (H = 0 for a disconnection, so ε > 0)",
              source="[CHEN] Remark 4.1; value est."),
        Param("h_output", "choice", choices=OUTPUTS, doc="output E of Remark 4.1 points to",
              source="[CHEN] Remark 4.1; choice est."),
        Param("h_rate_weight", "float", ge=0.0, unit="s", doc="c of E ∝ e_out + c·e_p (Remark "
              "4.1's free perturbation direction; 0: E = e_out): gives the fault a path "
              "through the roll rate", source="[CHEN] Remark 4.1; value est."),
        Param("uncertainty", "choice", choices=UNCERTAINTY_DESIGNS, doc="M of the H∞ "
              "objective of eq. 23: \"table2\" the Table-2 realisation M_g (F lies in its "
              "span), \"fault-removed\" M_g with the fault column's direction projected out",
              source="[CHEN] eq. 25, Table 2; choice est."),
        Param("safety", "float", gt=1.0, doc="max thresholds (and the evt fallback): τ0 = "
              "safety × the largest per-run maximum of |f̂| − b(t) over the learning set"),
        Param("confirm_s", "float", ge=0.0, unit="s", doc="time |f̂| must stay beyond the "
              "threshold τ0 + b(t)"),
        Param("filter_s", "float", ge=0.0, unit="s", doc="time constant of the low-pass on "
              "f̂ (0: none)"),
        Param("schedule_margin", "float", ge=0.0, doc="relative widening of the Table-2 error "
              "widths over which the polytope is computed", source="[CHEN] Table 2; value est."),
        Param("floor_deg", "float", gt=0.0, unit="deg", doc="smallest τ0"),
        Param("gust_channel", "bool", doc="decouple the gust sideslip as a second unknown "
              "input (F = [B_b W, A_b[:, β]])"),
        Param("adaptive", "bool", doc="threshold τ0 + b(t), b the bound the Table-2 errors put "
              "on |f̂ − f| given the measured lateral activity (False: constant τ0)",
              source="[CHEN] eq. 17, 25 and Table 2; [COMB] (bounds scaling with the input)"),
        *THRESHOLD_PARAMS,
    )

    def __init__(self, h_perturbation=0.03, h_output="phi", h_rate_weight=0.0,
                 uncertainty="table2", safety=1.5, confirm_s=0.1,
                 filter_s=0.5, schedule_margin=0.25, floor_deg=0.2, gust_channel=True,
                 adaptive=True,
                 threshold_method="evt", target_fa_per_run=1e-4, threshold_confidence=0.95,
                 threshold_tail="exponential"):
        self.h_perturbation = h_perturbation
        self.h_output = h_output
        self.h_rate_weight = h_rate_weight
        self.uncertainty = uncertainty
        self.safety = safety
        self.confirm_s = confirm_s
        self.filter_s = filter_s
        self.schedule_margin = schedule_margin
        self.floor_deg = floor_deg
        self.gust_channel = gust_channel
        self.adaptive = adaptive
        self.threshold_method = threshold_method
        self.target_fa_per_run = target_fa_per_run
        self.threshold_confidence = threshold_confidence
        self.threshold_tail = threshold_tail

    def check_signals(self, signals: Signals) -> None:
        super().check_signals(signals)
        if signals.aircraft is None or signals.rods is None:
            raise ValueError(f"{type(self).__name__} needs the aircraft sensors and every "
                             "surface's rod (Signals.aircraft/rods are None): it needs "
                             "[plant] kind = \"aircraft\" or \"jsbsim\"")
        missing = [k for k in OUTPUTS + (SPOILER,) if k not in signals.aircraft]
        missing += [k for k in INPUT_SURFACES if k not in signals.rods]
        if missing:
            raise ValueError(f"{type(self).__name__} needs the signals {missing}")
        if signals.actuator is None:
            raise ValueError(f"{type(self).__name__} needs the monitored surface's actuator "
                             "table (Signals.actuator is None)")
        monitored_column(signals.actuator.surface)
        scheduling_vector(signals.schedule)

    # ---- design (fit) ------------------------------------------------------------------
    def _vertices(self, model: AffineLateralModel, lo, hi, col: int):
        from ..synthesis.chen_global_uncertainty import design_uncertainty_matrix
        from ..synthesis.lpv_synthesis import VertexSystem

        C = output_matrix()
        corners = []
        for corner in itertools.product(*[(0, 1)] * len(model.keep)):
            rho = lo.copy()
            for k, c in zip(model.keep, corner):
                rho[k] = (lo[k], hi[k])[c]
            corners.append(rho)
        _, B_all = model.matrices(np.array(corners))
        M = design_uncertainty_matrix(self.uncertainty, B_all[:, :, col])
        verts, rhos = [], []
        for rho in corners:
            A, B = model.matrices(rho)
            F = self._fault_matrix(A[None], B[None], col)[0]
            verts.append(VertexSystem.make(A=A, B=B, C=C, F=F,
                                           H=np.zeros((len(OUTPUTS), F.shape[1])), M=M))
            rhos.append(rho)
        return verts, np.array(rhos)

    def _fault_matrix(self, A: np.ndarray, B: np.ndarray, col: int) -> np.ndarray:
        """F(ρ) (…, 4, q): the monitored aileron's column of B_b (W of eq. 25), then, with
        ``gust_channel``, the β column of A_b (a gust sideslip β_g enters the lateral
        equations as A_b[:, β]·β_g, :mod:`scenarios.aircraft.lpv`)."""
        cols = [B[..., [col]]]
        if self.gust_channel:
            cols.append(A[..., [STATES.index("beta")]])
        return np.concatenate(cols, axis=-1)

    def _h_direction(self) -> np.ndarray:
        """E of Remark 4.1 (3, q): the fault's column along e_out + c·e_p (e_out the unit
        vector of ``h_output``, c = ``h_rate_weight``), normalised; then, for the gust
        channel, the unit vector of the other output of (φ, r)."""
        names = [self.h_output] + ([o for o in ("r", "phi") if o != self.h_output][:1]
                                   if self.gust_channel else [])
        E = np.array([[1.0 if o == n else 0.0 for n in names] for o in OUTPUTS])
        E[OUTPUTS.index("p"), 0] += float(self.h_rate_weight)
        E[:, 0] /= np.linalg.norm(E[:, 0])
        return E

    def _fit(self, signals: Signals) -> None:
        from scenarios import design_models

        from ..synthesis.lpv_synthesis import discretise, synthesise

        ts = float(signals.ts)
        col = monitored_column(signals.actuator.surface)
        airframe = design_models.check_airframe(signals.airframe)
        # on our aircraft, fitted over the whole polytope (exact either way); a JSBSim
        # aircraft is trimmed at the 53 realistic points only (0.15 CPU-s each)
        rho_env = scheduling_vector(envelope_schedules(self.schedule_margin, airframe))
        lo, hi = rho_env.min(axis=0), rho_env.max(axis=0)
        widen = NUMERICS.polytope_margin * (hi - lo)
        lo, hi = lo - widen, hi + widen
        fit_points = envelope_schedules(self.schedule_margin, airframe,
                                        corners=design_models.exactly_affine(airframe))
        model = fit_affine(fit_points, airframe=airframe, box=(lo, hi))
        verts, vertex_rho = self._vertices(model, lo, hi, col)
        E = self._h_direction()
        design = synthesise(verts, h_perturbation=float(self.h_perturbation), h_direction=E)
        C = output_matrix()
        # stability: every vertex and a dense grid of the box, continuous and discretised
        axes = [np.linspace(lo[k], hi[k], NUMERICS.grid_per_axis) for k in model.keep]
        grid = np.tile(lo, (NUMERICS.grid_per_axis ** len(model.keep), 1))
        for j, g in enumerate(itertools.product(*axes)):
            grid[j, model.keep] = g
        A_g, B_g = model.matrices(grid)
        F_g = self._fault_matrix(A_g, B_g, col)
        A_e = A_g - F_g @ design.H_dagger @ C + design.Z1 @ design.H_perp @ C
        cont = float(np.linalg.eigvals(A_e).real.max())
        vert = max(design.stability_margin(v) for v in design.vertices)
        disc = max(float(np.abs(np.linalg.eigvals(discretise(a, np.zeros((4, 1)), ts)[0])).max())
                   for a in A_e)
        if not (cont < 0.0 and vert < 0.0 and disc < 1.0):
            raise ValueError(
                f"the global estimator is not stable over the scheduling polytope (largest "
                f"real pole {max(cont, vert):.3g} 1/s, discrete modulus {disc:.6f}); [CHEN] §4 "
                "notes the gains of eq. 20–21 need not stabilise it: change h_perturbation "
                "or h_output, or narrow the polytope (schedule_margin)")
        # static gain f → f̂ of the unperturbed model (H = 0) at the vertices
        gains = [float((design.L2 @ C @ np.linalg.solve(-(v.A + design.L1(v.F) @ C), v.F))[0, 0])
                 for v in verts]

        self.model_ = {"coef_A": model.coef_A, "coef_B": model.coef_B, "keep": model.keep,
                       "affine_residual": model.residual}
        self.schedule_box_ = (lo, hi)
        self.vertex_rho_ = vertex_rho
        self.gamma_ = design.gamma
        self.design_ = {"P": design.P, "S": design.S, "Z1": design.Z1, "Z2": design.Z2,
                        "H": design.H, "H_dagger": design.H_dagger, "H_perp": design.H_perp,
                        "L2": design.L2, "column": col, "solver_status": design.solver_status}
        self.stability_ = {"vertex_max_real_pole": vert, "grid_max_real_pole": cont,
                           "grid_max_discrete_modulus": disc, "grid_points": int(len(grid))}
        self.static_gain_ = (min(gains), max(gains))
        self.error_bounds_ = table2_error_bounds(airframe)
        self.airframe_ = airframe
        excess = per_run_maxima(signals, lambda block: {"excess": self._excess(block)})
        tau, calibration = learned_threshold(
            np.maximum(excess["excess"], 0.0), self.threshold_method, float(self.safety),
            self.target_fa_per_run, self.threshold_confidence, tail=self.threshold_tail,
            classes=signals.classes)
        self.threshold_ = max(float(tau), float(self.floor_deg))
        if self.threshold_method != "max":
            self.calibration_ = calibration
        self.learning_runs_ = int(signals.n_runs)

    # ---- online part -------------------------------------------------------------------
    def _model(self) -> AffineLateralModel:
        m = self.model_
        return AffineLateralModel(coef_A=m["coef_A"], coef_B=m["coef_B"], keep=m["keep"],
                                  residual=m["affine_residual"])

    def inputs(self, signals: Signals, steps: slice = slice(None)) -> np.ndarray:
        """u_b [deg], shape (6, n_runs, len(steps)): rod deflections then the spoilers, over
        the steps *steps* (default all)."""
        from scenarios.aircraft.data import surface_actuator

        spoiler = np.asarray(signals.aircraft[SPOILER], float)[:, steps]
        out = np.empty((len(INPUT_SURFACES) + 1,) + spoiler.shape)
        for j, s in enumerate(INPUT_SURFACES):
            r = surface_actuator(s).r_mm
            out[j] = np.degrees(np.arcsin(np.clip(np.asarray(signals.rods[s], float)[:, steps]
                                                  / r, -1.0, 1.0)))
        out[-1] = spoiler
        return out

    def estimate(self, signals: Signals) -> np.ndarray:
        """Fault estimate f̂ [deg] of [CHEN] eq. 16 at the global level, (n_runs, n_steps)."""
        return self._recursion(signals, bounds=False)[0]

    def uncertainty_response(self, signals: Signals) -> np.ndarray:
        """w_j [deg], shape (5, n_runs, n_steps): the response of f̂ to each driving signal of
        the Table-2 uncertainty (:data:`detectors.synthesis.chen_global_uncertainty.SIGNALS`)
        through the estimator's error dynamics; |f̂ − f| ≤ Σ_j k_j |w_j|,
        k_j = ``error_bounds_``."""
        return self._recursion(signals, bounds=True)[1]

    def _recursion(self, signals: Signals, bounds: bool):
        """(f̂ (n, T), w (5, n, T) or None): the estimator of eq. 16 and, with *bounds*, the
        uncertainty filters of :mod:`detectors.synthesis.chen_global_uncertainty` run beside it."""
        import scipy.linalg

        from ..synthesis.chen_global_uncertainty import (signal_columns, signal_matrices,
                                                         uncertainty_matrix)

        lo, hi = self.schedule_box_
        rho = np.clip(scheduling_vector(signals.schedule), lo, hi)
        A, B = self._model().matrices(rho)                          # (n, 4, 4), (n, 4, 6)
        d = self.design_
        F = self._fault_matrix(A, B, d["column"])
        L1 = (-(F[:, :, :, None] * d["H_dagger"][None, None]).sum(axis=2)
              + d["Z1"] @ d["H_perp"])                              # (n, 4, 3), eq. 20
        A_e = A + L1[:, :, [OUTPUTS.index(s) if s in OUTPUTS else 0 for s in STATES]] * \
            np.array([s in OUTPUTS for s in STATES], float)         # L1 C_b (C_b selects)
        G_in = np.concatenate([B, -L1], axis=2)                     # on [u; y]
        ts = float(signals.ts)
        n, T = signals.command.shape
        n_x, n_in = len(STATES), G_in.shape[2]
        ramp = [j for j in range(n_in) if j != len(INPUT_SURFACES)]   # all but the spoilers
        n_r = len(ramp)
        M_g = uncertainty_matrix()
        n_m = M_g.shape[1] if bounds else 0
        size = n_x + n_in + n_m + n_r
        aug = np.zeros((n, size, size))
        aug[:, :n_x, :n_x] = A_e * ts
        aug[:, :n_x, n_x:n_x + n_in] = G_in * ts
        if bounds:                                  # δ_g held over the period (ZOH)
            aug[:, :n_x, n_x + n_in:n_x + n_in + n_m] = M_g * ts
        aug[:, n_x + np.array(ramp), n_x + n_in + n_m + np.arange(n_r)] = 1.0
        ex = scipy.linalg.expm(aug)                 # once per run (batched, per matrix)
        Phi = ex[:, :n_x, :n_x]
        Gam = ex[:, :n_x, n_x:n_x + n_in]
        Gam_M = ex[:, :n_x, n_x + n_in:n_x + n_in + n_m]
        Gam1 = ex[:, :n_x, n_x + n_in + n_m:]
        y = np.stack([np.asarray(signals.aircraft[k], float) for k in OUTPUTS])   # (3, n, T)
        n_u = len(INPUT_SURFACES) + 1

        def drive_of(u, a, b):
            """Γ u_k + Γ1 (u_{k+1} − u_k) for k in [a, b), (4, n, b − a), *u* the inputs over
            [a, b + 1): the rods and the aircraft sensors are ramps over the period. Formed a
            window of steps at a time (elementwise: the window changes no bit of it)."""
            uy = np.concatenate([u, y[:, :, a:b + 1]])
            out = np.zeros((n_x, n, b - a))
            for j in range(n_in):                       # elementwise: batch-invariant
                out += Gam[:, :, j].T[:, :, None] * uy[j][None, :, :b - a]
            du = np.zeros((n, b - a))
            for i, j in enumerate(ramp):
                du[:, :uy.shape[2] - 1] = np.diff(uy[j], axis=1)
                out += Gam1[:, :, i].T[:, :, None] * du[None]
            return out

        L2 = d["L2"]
        out = [STATES.index(o) for o in OUTPUTS]                    # C_b selects states
        xh = np.zeros((n_x, n))
        xh[out] = y[:, :, 0]
        f_hat = np.empty((n, T))
        PhiT = np.transpose(Phi, (1, 2, 0))                         # (4, 4, n)
        if bounds:
            Zx, Zu = signal_matrices(A, B)                          # (n, 5, 4), (n, 5, 6)
            n_s = Zx.shape[1]

            def z_u_of(u, a, b):                                    # rods' part of z
                out = np.zeros((n_s, n, b - a))
                for j in range(n_u):
                    out += Zu[:, :, j].T[:, :, None] * u[j][None, :, :b - a]
                return out
            z_f = Zu[:, :, d["column"]].T                           # (5, n): per deg of f̂
            z_g = Zx[:, :, 0].T                                     # (5, n): per deg of β_g
            ZxT = np.transpose(Zx, (1, 2, 0))                       # (5, 4, n)
            GmT = np.transpose(Gam_M[:, :, signal_columns()], (2, 1, 0))   # (5, 4, n)
            e = np.zeros((n_s, n_x, n))
            w = np.empty((n_s, n, T))
            C_L2 = np.zeros(n_x)
            C_L2[out] = L2[0]                                       # f̂ component of L2 C
        compiled = kernels.current_engine() == "compiled"
        if compiled:
            c = np.ascontiguousarray
            PhiT, L2c, Gam_c, Gam1_c = c(PhiT), c(L2, dtype=float), c(Gam), c(Gam1)
            ramp_c, rows = np.asarray(ramp, dtype=np.int64), np.asarray(out, dtype=np.int64)
            if bounds:
                ZxT, GmT, Zu_c, z_f, z_g = c(ZxT), c(GmT), c(Zu), c(z_f), c(z_g)
            else:                           # the kernel's unused arrays, empty
                e = ZxT = GmT = np.zeros((0, n_x, n))
                z_f = z_g = np.zeros((0, n))
                Zu_c, C_L2, w = np.zeros((n, 0, 0)), np.zeros(n_x), np.zeros((0, n, T))
        for a in range(0, T, TIME_WINDOW):
            b = min(a + TIME_WINDOW, T)
            u = self.inputs(signals, slice(a, b + 1))
            if compiled:
                recursion_window(y, u, a, b, xh, rows, L2c, PhiT, Gam_c, Gam1_c, ramp_c,
                                 f_hat, bounds, e, C_L2, ZxT, Zu_c, z_f, z_g, GmT, w)
                continue
            drive = drive_of(u, a, b)
            z_u = z_u_of(u, a, b) if bounds else None
            for k in range(a, b):                       # the NumPy reference
                kw = k - a
                innov = y[:, :, k] - xh[out]
                f_all = (L2[:, 0, None] * innov[0] + L2[:, 1, None] * innov[1]
                         + L2[:, 2, None] * innov[2])
                f_hat[:, k] = f_all[0]
                if bounds:
                    w[:, :, k] = (C_L2[None, :, None] * e).sum(axis=1)
                    xt = np.stack([xh[0], y[1, :, k], y[2, :, k], y[0, :, k]])  # [β̂, p, r, φ]
                    z = (ZxT * xt[None]).sum(axis=1) + z_u[:, :, kw] + z_f * f_all[0]
                    if f_all.shape[0] > 1:                           # gust channel: β_a
                        z = z + z_g * f_all[1]
                    e = (PhiT[None] * e[:, None, :, :]).sum(axis=2) + GmT * z[:, None, :]
                # x̂_{k+1} needs u_{k+1}, y_{k+1} (ramps over the period): known at step
                # k + 1, before f̂_{k+1} is formed, so the recursion stays causal
                xh = (PhiT * xh[None, :, :]).sum(axis=1) + drive[:, :, kw]
        return f_hat, (w if bounds else None)

    def _lowpass(self, x: np.ndarray, ts: float) -> np.ndarray:
        """First-order low-pass of time constant ``filter_s`` along the last axis."""
        from scipy.signal import lfilter

        if self.filter_s <= 0.0:
            return x
        a = math.exp(-float(ts) / float(self.filter_s))
        return lfilter([1.0 - a], [1.0, -a], x, axis=-1)

    def _filtered(self, signals: Signals) -> np.ndarray:
        return self._lowpass(self.estimate(signals), signals.ts)

    def activity_bound(self, signals: Signals) -> np.ndarray:
        """b(t) = Σ_j k_j |w_j| [deg], (n_runs, n_steps): the bound the Table-2 errors put on
        the low-passed |f̂ − f| given the measured lateral activity (module docstring of
        :mod:`detectors.synthesis.chen_global_uncertainty`); zeros without ``adaptive``."""
        return self._components(signals)[1]

    def _bound(self, w: np.ndarray, ts: float) -> np.ndarray:
        """Σ_j k_j |w_j| low-passed, accumulated one j at a time (the order of a sum over the
        first axis: the same bits as summing the stacked terms), each term formed in place
        (*w* may be overwritten: the caller's own work array)."""
        k = np.asarray(self.error_bounds_, float)
        out = None
        for j in range(len(k)):
            term = self._lowpass(w[j], ts)
            np.abs(term, out=term)
            term *= k[j]
            if out is None:
                out = term
            else:
                out += term
        return out

    def _components(self, signals: Signals) -> tuple[np.ndarray, np.ndarray]:
        """(|f̂| low-passed, b(t)) [deg], both (n_runs, n_steps)."""
        if not self.adaptive:
            return np.abs(self._filtered(signals)), np.zeros(signals.command.shape)
        f_hat, w = self._recursion(signals, bounds=True)
        f_abs = self._lowpass(f_hat, signals.ts)
        del f_hat
        np.abs(f_abs, out=f_abs)
        return f_abs, self._bound(w, signals.ts)

    def _excess(self, signals: Signals) -> np.ndarray:
        """|f̂| low-passed minus the activity bound b(t) [deg]: what τ0 must cover."""
        r, b = self._components(signals)
        r -= b
        return r

    def _detect(self, signals: Signals) -> Detection:
        f_abs, b = self._components(signals)
        r = f_abs / (self.threshold_ + b)
        n_c = max(int(round(float(self.confirm_s) / float(signals.ts))), 1)
        # the decision: the least r over the confirmation window (≥ 1 for the alarm; r = 1
        # exactly, where > and ≥ differ, has probability 0)
        decision = windowed_min(r, n_c)
        return Detection(alarm=decide(decision), residual=r, decision=decision)
