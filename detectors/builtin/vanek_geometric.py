"""The geometric (fundamental problem of residual generation) aileron fault filter of
[VANEK] §2 and §5 on the aircraft plant level: ``vanek-geometric``.

Design model: the rigid-body linear model of :mod:`scenarios.aircraft.lpv` (states α, q, θ,
β, p, r, φ in rad) at a flight point, on the simulated aircraft's surface layout (each
elevator's lift acting 4.1 m off the plane of symmetry, docs/physics.md §7.3; parameter
``design_model``, :data:`DESIGN_MODELS`, keeps [VANEK] §4.2's elevators in unison as an
ablation), outputs y = (α, q, θ, β, p, r, φ), every state, as [VANEK] §4.1's aircraft
measures the aerodynamic angles (α, β) with the rates and attitudes — the load factors are
left out as in [VANEK] §5 (their direct feed-through complicates the synthesis). That is the
design with ``aoa_sensor`` true, the default; ``aoa_sensor`` false leaves α out (outputs q,
θ, β, p, r, φ: the aircraft layout without the angle-of-attack vane; the vertical gust then
reaches r̂ and the thresholds are 2–5 times higher, docs/vanek-geometric.md). Fault
directions ([VANEK] §5: "successive input directions from the B matrix"):

* L1 — the left inboard aileron's column of B (the fault to detect);
* L2 — the left elevator's and the rudder's columns (the faults to isolate from), and, with
  ``decouple_gusts``, the gust sideslip's direction e_β and, with ``aoa_sensor``, the gust
  angle of attack's e_α (the β and α outputs are the air-relative angles of the vanes:
  :func:`gust_sideslip_direction`, :func:`gust_aoa_direction`). With α (C = I), S* is the
  span of L2 itself: dimension 4, S* ∩ L1 = 0 over the envelope
  (tests/detectors_tests/test_geometric.py). Without α, e_α is decoupled only by the unison model,
  whose S* holds the short-period directions;
  on the aircraft's layout S* (dimension 3) does not hold it, and it cannot be added: S*
  holding the elevator, the rudder, e_β and e_α then has dimension 5 and contains L1
  (docs/vanek-geometric.md).

Known inputs u: the other surfaces' COM rod positions converted to deflections
(δ = asin(x/r)), the spoilers' roll order and the left inboard aileron's *expected*
deflection, so that f1 is that aileron's departure from what the flight control computer
expects of it. Expected deflection: when the left inboard aileron is the monitored surface,
the nominal servo-loop model driven by its order (as :class:`PositionMonitor` ``loop``);
otherwise its COM rod. Spoilers: their equivalent aileron angle as applied,
``Signals.aircraft["spoiler"]`` (no servo-loop in this simulator; it stands for their rod
measurements, as in ``chen-global``). The runs start trimmed in straight, wings-level
flight, so the filter starts at w = 0 with every signal taken as a perturbation from trim:
the rates, the sideslip, the bank angle (:data:`ZERO_TRIM`) and the spoiler angle (zero at
trim) as measured, the pitch attitude and the surfaces relative to their first sample, the
angle of attack relative to the pitch attitude's first sample (α0 = θ0 in level flight; its
own first sample would carry the vane's noise and the gust's α of that instant).
(docs/vanek-geometric.md measures why the inputs are not referenced to their own first
samples and why the spoiler angle is not rebuilt from the orders.)

Filter: :func:`detectors.synthesis.geometric.design` (W*, S*, P, H, M, Ĝ, LMI of eq. 3–4) then the
bilinear transform at Ts ([VANEK] §5). Its residual r (one component per row of H) is
reduced to one signal, the least-squares reconstruction of the aileron fault at steady
state, r̂ = g⁺ r with g = M N⁻¹ P L1 the DC gain from f1 to r, so r̂ → f1 [deg] for a
constant fault. r̂ is then low-passed (first order, time constant ``smoothing_s``, bilinear
at Ts): the residual's direct feed-through −H y carries the sensors' white noise unfiltered,
and [VANEK] §5 tracks the fault only in a limited band (T_id). This low-pass is a plain
stand-in for that band limit, not the H∞ post-filter of [VANEK] §3.

Sensitivity (measured, docs/vanek-geometric.md): nominal fault-free floor 0.13–0.25° of
aileron-equivalent (LPV), up to 1° (LTI off its design point); the β vane's noise sets it.

Variants (those chosen, all computed by one ``detect``; default ``lti`` and ``lpv``):

``lti``
    designed once at the nominal flight point :data:`NOMINAL` ([VANEK] §4.2–5);
``lpv``
    the same algebraic construction (subspaces, friend and the LMI of eq. 3–4) repeated at
    each run's *measured* flight point (``Signals.schedule``: VCAS, altitude, mass, CG), the
    flight point of a run being constant here; designs are cached by flight point. This
    frozen-point form gives the filter of the measured point exactly;
``lpv-affine``
    the LPV filter of [VANEK] §5: the aircraft model affine in VCAS and altitude
    (:func:`affine_model`, least squares over the realistic envelope at [VANEK]'s 200 t and
    30 % CG; largest fit error 9 % of the largest entry). With the unison model S* is the
    same at every point (checked), so S*, P, H, M are fixed, the friend Ĝ(VCAS, h) is linear
    in A and the filter affine in (VCAS, h); one output injection for the whole box
    :data:`AFFINE_BOX`, from the LMI of eq. 3–4 at its four corners with a common X
    (quadratic stability in the box). On the aircraft's layout no parameter-independent S*
    exists (:func:`design_affine`): S* and the injection are designed at each run's point of
    the affine model. The filter of a run is this family at its measured VCAS and altitude
    (clipped to the box).

Thresholds: per variant, calibrated to a per-run false-alarm target (``"evt"``,
docs/thresholds.md) or ``safety`` × the largest fault-free learning |r̂| (``"max"``; [VANEK]
§5 applies its 1.5 to the elevator runaway's peak, 0.175 LTI, 0.105 LPV); alarm once |r̂|/τ
has stayed ≥ 1 for ``confirm_s``, then latched. With ``adaptive`` (the default) and α read,
the lti and lpv variants' threshold is τ = τ0 + b(t): b the bound the [CHEN] Table-2 errors
(the aircraft's aerodynamic coefficients and the measured VCAS, altitude, mass and CG) put on
the residual, computed online from the measured state and surfaces through the filter's
own error dynamics (:mod:`detectors.synthesis.vanek_model_error`), and τ0 learned, as above, on each
learning run's largest |r̂| − b (what the bound does not cover: sensor noise, turbulence,
the rods' errors). The other variants keep a constant τ. Isolation:
:attr:`VanekGeometric.capabilities` declares the left inboard aileron, so that the gate
scores an alarm on another surface's faults as an isolation failure
(:mod:`campaign.isolation`).
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass

import numpy as np
import scipy.signal

from scenarios.params import param
from scenarios.signals import Signals

from ..synthesis import geometric as geo
from ..base import Capabilities, Detection, Detector, decide, windowed_min
from ..calibrate import THRESHOLD_PARAMS, learned_threshold
from ..params import Param

VARIANTS = ("lti", "lpv")
#: Optional variant: [VANEK] §5's LPV filter affine in VCAS and altitude (module docstring).
AFFINE_VARIANTS = ("lpv-affine",)
#: Optional variants (:mod:`detectors.synthesis.vanek_hinf`; need the optional extra ``hinf``): the
#: LTI filter followed by the H∞ post-filter of [VANEK] §3, and the one-step H∞ FDI filter
#: of [VANEK] §3 designed at the same point, for comparison.
HINF_VARIANTS = ("lti-hinf", "one-step")
#: Most designed filters a detector keeps (oldest dropped first): the lpv and lpv-affine
#: variants design one per run (5.5 KB cached, measured with tracemalloc), so a cache
#: without a bound grew with the campaign; one detect needs its chunk's designs twice
#: (r̂, then b(t)).
DESIGN_CACHE_SIZE = 4096
#: Measured outputs of the design model (names of Signals.aircraft), [VANEK] §4.1 and §5
#: (body rates, attitudes and the aerodynamic angles α, β; every state of the design model).
OUTPUTS = ("alpha", "q", "theta", "beta", "p", "r", "phi")


def design_outputs(aoa_sensor: bool = False) -> tuple[str, ...]:
    """:data:`OUTPUTS`, or without α (*aoa_sensor* False: q, θ, β, p, r, φ)."""
    return OUTPUTS if aoa_sensor else tuple(o for o in OUTPUTS if o != "alpha")
FAULT_SURFACE = "left_inboard_aileron"
#: Outputs whose trim value is zero in the runs' trimmed, wings-level, straight flight
#: (taken as measured, not relative to their first, noisy, sample).
ZERO_TRIM = ("q", "beta", "p", "r", "phi")
ISOLATED_SURFACES = ("left_elevator", "rudder")


@dataclass(frozen=True)
class NominalPoint:
    """Design point of the LTI variant ([VANEK] §4.1–4.2 cruise, §5 mass and CG)."""

    vcas_kt: float = param("kt", "[VANEK] §4.1 (cruise speed 240 kt)", "calibrated airspeed")
    alt_ft: float = param("ft", "[VANEK] §4.2 (9144 m)", "altitude")
    mass_t: float = param("t", "[VANEK] §5 (200 000 kg)", "mass")
    cg_pct: float = param("% MAC", "[VANEK] §5 (x_cg = 0.3)", "centre of gravity")


NOMINAL = NominalPoint(vcas_kt=240.0, alt_ft=30000.0, mass_t=200.0, cg_pct=30.0)


@dataclass(frozen=True)
class _Filter:
    """One discretised filter: w' = Ad w + Bd v, r̂ = c (Cd w + Dd v), v = [u; y]; and, for
    the geometric designs, the path of a model error d (an unknown input of the state
    equation, :mod:`detectors.synthesis.vanek_model_error`): e' = Ad e + Bdist d, r̂_d = c (Cd e +
    Ddist d) (None for the H∞ variants)."""

    Ad: np.ndarray
    Bd: np.ndarray
    Cd: np.ndarray
    Dd: np.ndarray
    c: np.ndarray
    Bdist: np.ndarray | None = None
    Ddist: np.ndarray | None = None


def _discrete(gen: geo.ResidualGenerator, ts: float) -> _Filter:
    """The generator discretised at *ts* [s] (bilinear, [VANEK] §5) with the least-squares
    reconstruction r̂ = g⁺ r, g the steady-state gain from f1, and its model-error path
    ė = N e − P d, r = M e (same N and M, hence the same Ad and Cd)."""
    Ad, Bd, Cd, Dd = geo.bilinear(gen, ts)
    _, Bdist, _, Ddist = geo.bilinear_ss(gen.N, -gen.P, gen.M,
                                         np.zeros((gen.M.shape[0], gen.P.shape[1])), ts)
    g = geo.dc_gain(gen)[:, 0]
    return _Filter(Ad=Ad, Bd=Bd, Cd=Cd, Dd=Dd, c=g / float(g @ g), Bdist=Bdist, Ddist=Ddist)


#: Design models of :func:`_model` (parameter ``design_model``): ``"aircraft"`` the plant's own
#: surface layout, each elevator's lift acting ``elevator_arm_m`` off the plane of symmetry
#: (docs/physics.md §7.3); ``"unison"`` the two elevators moving in unison as in [VANEK]
#: §4.2 (elevator arm 0), kept as an ablation: its left elevator has pitch and lift only, and
#: the roll of an asymmetric elevator pair leaks into the residual (docs/vanek-geometric.md).
DESIGN_MODELS = ("aircraft", "unison")


def _model(point: dict, design_model: str = "aircraft", aero=None):
    """(A, B) of the design model at a flight point (arrays of one run) on the surface
    layout *design_model* (:data:`DESIGN_MODELS`), with the aerodynamic draws *aero* (a
    mapping coefficient → relative error, :func:`scenarios.aircraft.lpv.run_models`; None:
    the nominal coefficients)."""
    import dataclasses

    from scenarios.aircraft import lpv
    from scenarios.aircraft.data import LAYOUT

    if design_model not in DESIGN_MODELS:
        raise ValueError(f"design_model {design_model!r}: one of {list(DESIGN_MODELS)}")
    layout = LAYOUT if design_model == "aircraft" else dataclasses.replace(LAYOUT,
                                                                          elevator_arm_m=0.0)
    draws = np.zeros(1) if not aero else {c: np.atleast_1d(float(d)) for c, d in aero.items()}
    m = lpv.run_models(point, draws, layout=layout)
    return m.A[0], m.B[0]


def _model_at(point: dict, aero: dict, design_model: str = "aircraft"):
    """(A, B) of the surface layout *design_model* at the flight point of keywords
    ``vcas_kt``, ``alt_ft``, ``mass_t``, ``cg_pct`` with the aerodynamic draws *aero*: the
    *model* of :func:`detectors.synthesis.vanek_model_error.error_matrices`. The layout is the
    filter's own, so that the allowance covers the flight point's and [CHEN] Table 2's
    errors, not the choice of the unison ablation (whose leak stays measurable)."""
    return _model(_point(point["vcas_kt"], point["alt_ft"], point["mass_t"], point["cg_pct"]),
                  design_model, aero)


def _columns():
    from scenarios.aircraft import lpv
    from scenarios.aircraft.data import LAYOUT

    names = LAYOUT.names
    i1 = names.index(FAULT_SURFACE)
    i2 = [names.index(s) for s in ISOLATED_SURFACES]
    known = [j for j in range(len(names)) if j not in i2] + [lpv.I_SPOILER]
    return i1, i2, known


def _gust_direction(A, B, state: int, gust: int, name: str, symbol: str) -> np.ndarray:
    """e_state, once checked that the gust input *gust* acts as B_g = A e_state."""
    from scenarios.aircraft import lpv

    b_g, a_s = B[:, gust], A[:, state]
    if not np.allclose(b_g, a_s, rtol=1e-12, atol=1e-12 * np.abs(a_s).max()):
        raise ValueError(f"the gust {name}'s column of B is not the {symbol} column of A: the "
                         f"model's aerodynamics do not act on the air-relative {name}")
    return np.eye(lpv.N_STATES)[:, state]


def gust_sideslip_direction(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """The direction along which the gust sideslip β_g acts on the design model, whose β
    output is the *air-relative* sideslip β_a = β + β_g (:mod:`scenarios.aircraft.loop`).

    The aerodynamics see β_a, so the gust's column of B is the β column of A (B_g = A e_β;
    checked here). In the state x̃ with β_a in place of β, x̃ = x + e_β β_g:
    dx̃/dt = A x̃ + B u + (B_g − A e_β) β_g + e_β dβ_g/dt = A x̃ + B u + e_β dβ_g/dt, and
    y = C x̃ with the same C. The gust is one unknown input along e_β (its rate), so the
    design model keeps (A, B, C) and decouples e_β."""
    from scenarios.aircraft import lpv

    return _gust_direction(A, B, lpv.IB, lpv.I_GUST_BETA, "sideslip", "β")


def gust_aoa_direction(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """e_α, the direction of the gust angle of attack α_g for the α vane's air-relative
    α + α_g: as :func:`gust_sideslip_direction` with α for β (the α̇ terms of
    :mod:`scenarios.aircraft.lpv` act on the inertial α, so B_g = A e_α; checked)."""
    from scenarios.aircraft import lpv

    return _gust_direction(A, B, lpv.IA, lpv.I_GUST_ALPHA, "angle of attack", "α")


def design_filter(point: dict, ts: float, *, decouple_gusts: bool = True, decay: float = 0.5,
                  radius: float = 20.0, design_model: str = "aircraft", aoa_sensor: bool = False
                  ) -> tuple[geo.ResidualGenerator, _Filter]:
    """The geometric filter at *point* (``mass_t``, ``cg_pct``, ``mach``, ``qbar_pa``,
    ``tas_ms`` arrays of one element) on the design model *design_model*
    (:data:`DESIGN_MODELS`), continuous and discretised at *ts* [s]. Input order of the
    discrete filter: the known surfaces of :func:`_columns` [rad], then the outputs
    :func:`design_outputs` (*aoa_sensor*)
    [rad, rad/s]."""
    A, B = _model(point, design_model)
    return _design_at(A, B, ts, decouple_gusts, decay, radius, aoa_sensor)


def _design_at(A, B, ts: float, decouple_gusts: bool, decay: float, radius: float,
               aoa_sensor: bool) -> tuple[geo.ResidualGenerator, _Filter]:
    """The geometric filter of the design model (A, B) (:func:`detectors.synthesis.geometric.design`
    on :func:`_fault_columns`), continuous and discretised at *ts* [s]."""
    _, _, known = _columns()
    L1, L2 = _fault_columns(A, B, decouple_gusts, aoa_sensor)
    gen = geo.design(A, B[:, known], _output_matrix(aoa_sensor), L1, L2, decay=decay,
                     radius=radius, names1=[FAULT_SURFACE])
    return gen, _discrete(gen, ts)


@dataclass(frozen=True)
class AffineBox:
    """Scheduling box of the ``lpv-affine`` variant (the realistic envelope's extent)."""

    vcas_kt: tuple = param("kt", "scenarios.envelope: realistic VCAS 160–300 kt",
                           "calibrated airspeed range")
    alt_ft: tuple = param("ft", "scenarios.envelope: realistic altitudes 8 000–38 000 ft",
                          "altitude range")


AFFINE_BOX = AffineBox(vcas_kt=(160.0, 300.0), alt_ft=(8000.0, 38000.0))
#: Scheduling variables of ``lpv-affine``, in order (names of ``Signals.schedule``).
AFFINE_SCHEDULE = ("vcas_kt", "alt_ft")


def affine_model(mass_t: float = NOMINAL.mass_t, cg_pct: float = NOMINAL.cg_pct,
                 design_model: str = "aircraft"):
    """The aircraft model affine in VCAS [kt] and altitude [ft] ([VANEK] §5):
    [A, B](v, h) = K0 + v·Kv + h·Kh, fitted by least squares on the exact models of the
    realistic (VCAS, altitude) points of the envelope (``scenarios.envelope``) at *mass_t*
    and *cg_pct*. Returns the function (v, h) → (A, B) and the largest fit error over those
    points relative to the largest entry of each matrix. (Scheduling on mass and CG too, by
    the same least squares over the 53 realistic points, fits to 14 % only: the dependence
    on the mass is 1/m, far from affine over 120–233 t; in the three presets of the suite
    vanek-section5, 17 of the 32 faulty runs then alarm before their onset.)"""
    from scenarios import envelope

    pts = envelope.realistic_points()
    pts = pts[pts["realistic"]][list(AFFINE_SCHEDULE)].drop_duplicates().to_numpy(float)
    models = [_model(_point(v, h, mass_t, cg_pct), design_model) for v, h in pts]
    AB = np.array([np.hstack(m) for m in models])                    # (k, n, n + m)
    X = np.column_stack([np.ones(len(pts)), pts])                    # [1, v, h]
    coef = np.linalg.lstsq(X, AB.reshape(len(pts), -1), rcond=None)[0]
    coef = coef.reshape(X.shape[1], *AB.shape[1:])
    n = models[0][0].shape[0]
    fit = np.einsum("kc,cij->kij", X, coef)
    err = max(float(np.abs(fit[:, :, sl] - AB[:, :, sl]).max() / np.abs(AB[:, :, sl]).max())
              for sl in (slice(0, n), slice(n, None)))

    def at(*theta):
        m = coef[0] + np.tensordot(np.asarray(theta, float), coef[1:], axes=1)
        return m[:, :n], m[:, n:]

    return at, err


def _output_matrix(aoa_sensor: bool = False) -> np.ndarray:
    """C of the design model: the states measured as :func:`design_outputs`."""
    from scenarios.aircraft import lpv

    return np.eye(lpv.N_STATES)[[lpv.STATES.index(s) for s in design_outputs(aoa_sensor)]]


def _fault_columns(A, B, decouple_gusts: bool, aoa_sensor: bool = False):
    """(L1, L2) of the design model (A, B) (module docstring): with *decouple_gusts* the
    gust directions e_β and, when α is measured (*aoa_sensor*), e_α."""
    i1, i2, _ = _columns()
    L2 = B[:, i2]
    if decouple_gusts:
        gusts = [gust_sideslip_direction(A, B)] + ([gust_aoa_direction(A, B)] if aoa_sensor
                                                   else [])
        L2 = np.column_stack([L2, *gusts])
    return B[:, [i1]], L2


def design_affine(ts: float, *, decouple_gusts: bool = True, decay: float = 0.5,
                  radius: float = 20.0, design_model: str = "aircraft", aoa_sensor: bool = False):
    """The ``lpv-affine`` filter family ([VANEK] §5) on the aircraft model affine in VCAS and
    altitude (:func:`affine_model`, at [VANEK]'s 200 t and 30 % CG, surface layout
    *design_model* of :data:`DESIGN_MODELS`). Returns a function θ → (the continuous residual
    generator, the :class:`_Filter` discretised at *ts*), θ the values of
    :data:`AFFINE_SCHEDULE` (clipped to :data:`AFFINE_BOX`).

    ``"unison"``: [VANEK] §5's construction, :func:`detectors.synthesis.geometric.design_lpv` at the
    four corners of the box (S* the same at every point, checked; S*, P, H, M fixed, one
    output injection for the box).

    ``"aircraft"``: that construction has no solution. The left elevator's column of B turns
    with the flight point (its α : q : p proportions), so the smallest unobservability
    subspace containing the elevator's direction at *every* point of the box — what a
    parameter-independent S* must contain — has dimension 5 and contains the aileron's
    direction (at the four corners, with or without α and the gusts). S* (dimension 4
    with α, 3 without) is computed at each θ from the affine model, with its own injection
    (the LMI of eq. 3–4 at that θ): the filter is exact for the affine model at every θ, but
    no longer affine in θ (a run's flight point is constant here, so it is designed once per
    run, like ``lpv``)."""
    model, _ = affine_model(design_model=design_model)
    C = _output_matrix(aoa_sensor)
    _, _, known = _columns()
    ranges = [getattr(AFFINE_BOX, k) for k in AFFINE_SCHEDULE]

    def clipped(theta):
        return model(*[float(np.clip(t, *r)) for t, r in zip(theta, ranges)])

    if design_model == "aircraft":
        def at(*theta) -> tuple[geo.ResidualGenerator, _Filter]:
            return _design_at(*clipped(theta), ts, decouple_gusts, decay, radius, aoa_sensor)

        return at
    corners = np.array(np.meshgrid(*ranges, indexing="ij")).reshape(len(ranges), -1).T
    As, L1s, L2s = [], [], []
    for theta in corners:
        A, B = model(*theta)
        L1, L2 = _fault_columns(A, B, decouple_gusts, aoa_sensor)
        As.append(A)
        L1s.append(L1)
        L2s.append(L2)
    fam = geo.design_lpv(As, C, L1s, L2s, decay=decay, radius=radius, names1=[FAULT_SURFACE])

    def at_common(*theta) -> tuple[geo.ResidualGenerator, _Filter]:
        A, B = clipped(theta)
        L1, L2 = _fault_columns(A, B, decouple_gusts, aoa_sensor)
        gen = fam.at(A, B[:, known], L1, L2)
        return gen, _discrete(gen, ts)

    return at_common


def one_step_design(point: dict, ts: float, design_model: str = "unison",
                    aoa_sensor: bool = False):
    """The one-step H∞ FDI filter of [VANEK] §3
    (:func:`detectors.synthesis.vanek_hinf.one_step_filter`) at *point*, and its discretisation as a
    :class:`_Filter` on the inputs of
    :meth:`VanekGeometric.filter_inputs`. The design model leaves out the pitch attitude
    (a pure integrator with the speed held, which the filtering problem cannot have); the
    filter ignores the measured θ. The gust sideslip reaches the β output directly (the
    sensor reads the air-relative sideslip). Noise: the aircraft sensors' σ and the rods'
    (0.03 mm over the lever arm) for the known surfaces; the spoiler angle is known exactly
    (a small σ keeps the problem regular); with *aoa_sensor* the α vane reads α + α_g the
    same way. *design_model*: :data:`DESIGN_MODELS`."""
    from scenarios.aircraft import lpv
    from scenarios.aircraft.data import LAYOUT
    from scenarios.aircraft.loop import AIRCRAFT_ACTUATORS
    from scenarios.params import SENSORS

    from ..synthesis.vanek_hinf import ONE_STEP, one_step_filter, sensor_sigmas

    A, B = _model(point, design_model)
    i1, i2, known = _columns()
    keep = [j for j, name in enumerate(lpv.STATES) if name != "theta"]
    outputs = design_outputs(aoa_sensor)
    outs = [o for o in outputs if o != "theta"]
    A = A[np.ix_(keep, keep)]
    B = B[keep]
    names = [lpv.STATES[j] for j in keep]
    C = np.eye(len(keep))[[names.index(o) for o in outs]]
    sig_y = sensor_sigmas(outs)
    sig_u = np.array([SENSORS.rod_noise_mm / AIRCRAFT_ACTUATORS[LAYOUT.actuator[j]].r_mm
                      if j < len(LAYOUT.names) else ONE_STEP.exact_sigma_rad for j in known])
    gusts = [lpv.I_GUST_BETA, lpv.I_GUST_ALPHA]
    d_g = np.zeros((len(outs), len(gusts)))
    d_g[outs.index("beta"), 0] = 1.0        # the sideslip sensor reads β + β_g
    if aoa_sensor:
        d_g[outs.index("alpha"), 1] = 1.0   # the α vane reads α + α_g
    f = one_step_filter(A, B, C, outs, i1, i2, known, gusts, sig_y, sig_u, ts,
                        gust_feedthrough=d_g)
    Ad, Bd, Cd, Dd = geo.bilinear_ss(f.A, f.B, f.C, f.D, ts)
    # inputs [u_known; outputs without θ] → [u_known; outputs] (θ column zero)
    cols = list(range(len(known))) + [len(known) + outputs.index(o) for o in outs]
    n_in = len(known) + len(outputs)
    Bfull = np.zeros((Bd.shape[0], n_in))
    Bfull[:, cols] = Bd
    Dfull = np.zeros((Dd.shape[0], n_in))
    Dfull[:, cols] = Dd
    return f, _Filter(Ad=Ad, Bd=Bfull, Cd=Cd, Dd=Dfull, c=np.ones(1))


def _point(vcas_kt, alt_ft, mass_t, cg_pct, mach=None, qbar_pa=None) -> dict:
    from scenarios import envelope
    from scenarios.atmosphere import tas_ms

    one = lambda v: np.atleast_1d(np.asarray(v, float))  # noqa: E731
    if mach is None:
        fc = envelope.flight_condition(one(alt_ft), one(vcas_kt), one(mass_t), one(cg_pct))
        mach, qbar_pa = fc["mach"], fc["qbar_pa"]
    return {"mass_t": one(mass_t), "cg_pct": one(cg_pct), "mach": one(mach),
            "qbar_pa": one(qbar_pa), "tas_ms": tas_ms(one(mach), one(alt_ft))}


class VanekGeometric(Detector):
    """Geometric aileron fault filter of [VANEK], LTI and LPV (module docstring).

    Parameters
    ----------
    safety : float
        With ``threshold_method = "max"``: threshold = safety × largest fault-free |r̂| of
        the learning set (> 1; 1.5 is [VANEK] §5's factor, which it applies to the elevator
        runaway's residual peak instead).
    confirm_s : float
        Confirmation time [s] (≥ 0).
    decay : float
        Decay rate imposed on the filter poles by the LMI of [VANEK] eq. 3–4 [1/s] (> 0).
    radius : float
        Largest filter pole modulus [rad/s] (> decay; well below π/Ts for the bilinear map).
    decouple_gusts : bool
        Also decouple the gusts: the lateral direction e_β and, with ``aoa_sensor``, the
        vertical one e_α (module docstring).
    aoa_sensor : bool
        Read the angle-of-attack vane (``Signals.aircraft["alpha"]``) as an output of the
        design model (default True: every state measured, both gusts decoupled). False: the
        outputs q, θ, β, p, r, φ; the vertical gust then reaches r̂, and the model-error
        allowance cannot be formed (``adaptive`` has no effect). A fitted detector keeps the
        outputs it was fitted with (``aoa_sensor_``).
    adaptive : bool
        With α read, the threshold of the lti and lpv variants is τ0 + b(t), b the model-error
        allowance of :mod:`detectors.synthesis.vanek_model_error` (default True); False: constant
        τ0. A fitted detector keeps what it was fitted with (``adaptive_``; absent: constant).
    design_model : str
        Surface layout of the design model (:data:`DESIGN_MODELS`): ``"aircraft"`` (default,
        the simulated aircraft's, elevator arm included) or ``"unison"`` (the elevators in
        unison as in [VANEK] §4.2; an ablation that does not isolate the left elevator's roll).
    smoothing_s : float
        Time constant of the low-pass on r̂ [s] (≥ 0; 0: none).
    variants : sequence of str
        Any of ``"lti"``, ``"lpv"``, ``"lpv-affine"`` (module docstring) and, with the
        optional extra ``hinf``, ``"lti-hinf"``
        (the LTI filter followed by the H∞ post-filter of [VANEK] §3, no low-pass) and
        ``"one-step"`` (the one-step H∞ FDI filter of [VANEK] §3 at the LTI design point, no
        low-pass; for comparison: no exact decoupling).
    threshold_method, target_fa_per_run, threshold_confidence, threshold_tail
        How thresholds are learned: calibrated to a per-run false-alarm target per
        manoeuvre (``"evt"``, the default) or ``safety`` × the largest learning value
        (``"max"``); :data:`detectors.calibrate.THRESHOLD_PARAMS`, docs/thresholds.md.
    """

    #: an aileron filter, blind to the left elevator and the rudder: an alarm on their faults
    #: is an isolation failure (docs/vanek-geometric.md, "Isolation in the gate")
    capabilities = Capabilities(needs_fit=True, causal=True, needs_aircraft=True,
                                fault_surfaces=(FAULT_SURFACE,), threshold_scale=True)

    parameters = (
        Param("safety", "float", gt=1.0, doc="threshold_method = max: threshold = safety × "
              "the largest fault-free |r̂| over the learning set",
              source="[VANEK] §5's factor 1.5, applied there to the elevator runaway's "
              "residual peak"),
        Param("confirm_s", "float", ge=0.0, unit="s", doc="confirmation time"),
        Param("decay", "float", gt=0.0, unit="1/s", doc="decay rate imposed on the filter "
              "poles by the LMI", source="[VANEK] eq. 3–4; value est."),
        Param("radius", "float", gt="decay", unit="rad/s", doc="largest filter pole modulus "
              "(well below π/Ts for the bilinear map)", source="[VANEK] eq. 3–4; value est."),
        Param("decouple_gusts", "bool", doc="also decouple the gusts: the sideslip direction "
              "e_β and, with aoa_sensor, the angle-of-attack direction e_α"),
        Param("smoothing_s", "float", ge=0.0, unit="s", doc="time constant of the low-pass on "
              "r̂ (0: none); stands for the band limit of [VANEK] §5"),
        Param("variants", "choices", choices=VARIANTS + AFFINE_VARIANTS + HINF_VARIANTS,
              doc="filters run by one detect; lti-hinf and one-step need the extra hinf",
              source="[VANEK] §3–5"),
        *THRESHOLD_PARAMS,
        Param("design_model", "choice", choices=DESIGN_MODELS,
              doc="surface layout of the design model: aircraft = the simulated aircraft's "
              "(elevator arm included, docs/physics.md §7.3); unison = the elevators in unison "
              "(ablation: the left elevator's roll leaks into the residual)",
              source="[VANEK] §4.2 (unison); docs/physics.md §7.3 (aircraft)"),
        Param("aoa_sensor", "bool", doc="read the angle-of-attack vane (Signals.aircraft "
              "alpha) as an output of the design model, decoupling both gusts (default); "
              "false: the outputs q, θ, β, p, r, φ, the vertical gust not decoupled on the "
              "aircraft's layout and no model-error allowance",
              source="[VANEK] §4.1 (aerodynamic angles α, β measured)"),
        Param("adaptive", "bool", doc="threshold τ0 + b(t) of the lti and lpv variants, b the "
              "bound the Table-2 errors put on the residual given the measured state and "
              "surfaces (with aoa_sensor only: it needs every state; false: constant τ0)",
              source="[CHEN] Table 2; detectors/synthesis/vanek_model_error.py"),
    )

    def __init__(self, safety=1.5, confirm_s=0.05, decay=0.5, radius=20.0, decouple_gusts=True,
                 smoothing_s=2.0, variants=VARIANTS, threshold_method="evt",
                 target_fa_per_run=1e-4, threshold_confidence=0.95,
                 threshold_tail="exponential", design_model="aircraft", aoa_sensor=True,
                 adaptive=True):
        self.safety = safety
        self.confirm_s = confirm_s
        self.decay = decay
        self.radius = radius
        self.decouple_gusts = decouple_gusts
        self.smoothing_s = smoothing_s
        self.variants = variants
        self.threshold_method = threshold_method
        self.target_fa_per_run = target_fa_per_run
        self.threshold_confidence = threshold_confidence
        self.threshold_tail = threshold_tail
        self.design_model = design_model
        self.aoa_sensor = aoa_sensor
        self.adaptive = adaptive

    def validate_params(self) -> None:
        """The declared checks (:attr:`parameters`), then that the optional variants of
        :data:`HINF_VARIANTS` have their libraries."""
        super().validate_params()
        if any(x in HINF_VARIANTS for x in self._variant_list()):
            try:
                import control  # noqa: F401
                import slycot  # noqa: F401
            except ImportError as exc:
                raise ValueError(f"variants {list(HINF_VARIANTS)} need python-control and "
                                 f"slycot ({exc}): pip install 'fdd-campaign[hinf]'") from exc

    def _variant_list(self) -> list[str]:
        return [self.variants] if isinstance(self.variants, str) else list(self.variants)

    def check_signals(self, signals: Signals) -> None:
        from scenarios import design_models

        super().check_signals(signals)              # needs_aircraft: Signals.aircraft, .rods
        airframe = design_models.check_airframe(signals.airframe)
        if airframe != design_models.OWN:
            # its filters and their Table-2 allowance are designed on lpv.run_models; on
            # another aircraft that would be a design model that is not the aircraft's
            raise ValueError(
                f"{type(self).__name__} is designed on the project's aircraft model only "
                f"(scenarios.aircraft.lpv); these signals come from {airframe}, whose own "
                "linearisations it cannot design on yet (its model-error allowance needs about "
                "20 trimmed models per run, docs/aircraft.md §9.6). Use [plant] kind = "
                "\"aircraft\", or chen-global, which is designed on the JSBSim aircraft")
        missing = [s for s in design_outputs(self._reads_alpha()) + ("spoiler",)
                   if s not in signals.aircraft]
        if missing:
            hint = (" (the angle of attack is measured from model servo-4 on; or set "
                    "aoa_sensor = false)" if "alpha" in missing else "")
            raise ValueError(f"{type(self).__name__}: Signals.aircraft lacks {missing}{hint}")

    # ---- design ------------------------------------------------------------------------
    def _layout(self) -> str:
        """The design model (:data:`DESIGN_MODELS`) of the filters: as fitted
        (``design_model_``), else the parameter; a detector fitted before the parameter
        existed was fitted on the unison model and keeps the filters of its thresholds."""
        learned = vars(self)
        if "design_model_" in learned:
            return learned["design_model_"]
        return "unison" if "thresholds_deg_" in learned else self.design_model

    def _reads_alpha(self) -> bool:
        """Whether the filters read α: as fitted (``aoa_sensor_``) once fitted, else the
        parameter; a detector fitted before the parameter existed did not."""
        learned = vars(self)
        if "aoa_sensor_" in learned:
            return learned["aoa_sensor_"]
        return False if "thresholds_deg_" in learned else bool(self.aoa_sensor)

    def _bounded(self) -> bool:
        """Whether the thresholds of the lti and lpv variants carry the model-error allowance
        b(t): as fitted (``adaptive_``) once fitted, else the parameter with α read; a
        detector fitted before the allowance existed has constant thresholds."""
        learned = vars(self)
        if "adaptive_" in learned:
            return learned["adaptive_"]
        if "thresholds_deg_" in learned:
            return False
        return bool(self.adaptive) and self._reads_alpha()

    def _design(self, point: dict, ts: float, kind: str = "geometric") -> _Filter:
        """The discretised filter of *kind* at *point* (cached): ``"geometric"`` (the
        variants lti and lpv), ``"lti-hinf"`` or ``"one-step"``."""
        layout, aoa = self._layout(), self._reads_alpha()
        # the point's exact values: a rounded key made two nearby runs share the design of
        # whichever came first in their worker
        key = (kind, layout, aoa, round(float(ts), 9)) + tuple(float(point[k][0])
                                                          for k in sorted(point))
        return self._memo(key, lambda: self._design_anew(point, ts, kind, layout, aoa))

    def _memo(self, key: tuple, make) -> _Filter:
        """The filter cached under *key*, else ``make()`` cached (at most
        :data:`DESIGN_CACHE_SIZE`, the oldest dropped first)."""
        cache = self.__dict__.setdefault("_cache", OrderedDict())
        try:
            return cache[key]
        except KeyError:
            pass
        f = cache[key] = make()
        while len(cache) > DESIGN_CACHE_SIZE:
            try:
                cache.popitem(last=False)
            except KeyError:                    # emptied by another thread meanwhile
                break
        return f

    def _design_anew(self, point: dict, ts: float, kind: str, layout: str, aoa: bool
                     ) -> _Filter:
        """:meth:`_design` without the cache."""
        if kind == "one-step":
            # on the unison model whatever design_model says: on the aircraft's layout the
            # synthesis returns a filter whose closed loop exceeds its γ (measured peak 0.49
            # against γ = 0.186 at the LTI design point), so it is not a valid H∞ design
            f = one_step_design(point, ts, "unison", aoa)[1]
        else:
            gen, f = design_filter(point, ts, decouple_gusts=self.decouple_gusts,
                                   decay=float(self.decay), radius=float(self.radius),
                                   design_model=layout, aoa_sensor=aoa)
            if kind == "lti-hinf":
                from ..synthesis.vanek_hinf import cascade, post_filter, sensor_sigmas

                q = post_filter(gen, sensor_sigmas(design_outputs(aoa)) * np.sqrt(ts))
                Ad, Bd, Cd, Dd = geo.bilinear_ss(*cascade(gen, q), ts)
                f = _Filter(Ad=Ad, Bd=Bd, Cd=Cd, Dd=Dd, c=np.ones(1))
        return f

    def _affine(self, theta: tuple, ts: float) -> _Filter:
        """The ``lpv-affine`` filter at θ (:data:`AFFINE_SCHEDULE`; family and filters
        cached)."""
        families = self.__dict__.setdefault("_families", {})
        layout, aoa = self._layout(), self._reads_alpha()
        fam_key = (layout, aoa, round(float(ts), 9))
        if fam_key not in families:
            families[fam_key] = design_affine(ts, decouple_gusts=self.decouple_gusts,
                                              decay=float(self.decay),
                                              radius=float(self.radius),
                                              design_model=layout, aoa_sensor=aoa)
        key = ("affine", layout, aoa, round(float(ts), 9)) + tuple(float(t) for t in theta)
        return self._memo(key, lambda: families[fam_key](*theta)[1])

    def _filters(self, variant: str, signals: Signals) -> list[_Filter]:
        kind = variant if variant in HINF_VARIANTS else "geometric"
        if variant == "lpv-affine":
            s = signals.schedule
            return [self._affine(tuple(s[k][i] for k in AFFINE_SCHEDULE), signals.ts)
                    for i in range(signals.n_runs)]
        if variant != "lpv":          # designed once, at the LTI design point
            f = self._design(_point(NOMINAL.vcas_kt, NOMINAL.alt_ft, NOMINAL.mass_t,
                                    NOMINAL.cg_pct), signals.ts, kind)
            return [f] * signals.n_runs
        s = signals.schedule
        return [self._design(_point(s["vcas_kt"][i], s["alt_ft"][i], s["mass_t"][i],
                                    s["cg_pct"][i], s["mach"][i], s["qbar_pa"][i]), signals.ts)
                for i in range(signals.n_runs)]

    # ---- signals -----------------------------------------------------------------------
    @staticmethod
    def filter_inputs(signals: Signals, aoa_sensor: bool = False) -> np.ndarray:
        """v = [u; y] of every run and step, shape (n_runs, n_steps, n_inputs), in rad and
        rad/s, relative to the first sample (module docstring); y the outputs
        :func:`design_outputs` (*aoa_sensor*)."""
        from scenarios.aircraft.data import LAYOUT
        from scenarios.aircraft.loop import AIRCRAFT_ACTUATORS

        from .position_monitor import PositionMonitor

        names = LAYOUT.names
        _, _, known = _columns()
        act = signals.actuator
        monitored = getattr(act, "surface", None)

        def deflection(name, x_mm):
            r = AIRCRAFT_ACTUATORS[LAYOUT.actuator[names.index(name)]].r_mm
            return np.arcsin(np.clip(x_mm / r, -1.0, 1.0))

        delta = {}
        for j in known[:-1]:
            name = names[j]
            if name == FAULT_SURFACE and monitored == FAULT_SURFACE:
                x = PositionMonitor.model_output(signals)   # expected rod from the order
            else:
                x = signals.rods[name]
            delta[name] = deflection(name, x)
        # the roll spoilers' equivalent angle as applied (no servo-loop here; it stands for
        # their rod measurements, :data:`scenarios.signals.AIRCRAFT_SIGNAL_UNITS`)
        spoiler = np.radians(signals.aircraft["spoiler"])
        cols = [delta[names[j]] for j in known[:-1]] + [spoiler]
        outputs = design_outputs(aoa_sensor)
        cols += [np.radians(signals.aircraft[s]) for s in outputs]
        v = np.stack(cols, axis=2)
        ref = v[:, :1, :].copy()
        n_u = v.shape[2] - len(outputs)
        ref[:, :, [n_u - 1] + [n_u + outputs.index(o) for o in ZERO_TRIM]] = 0.0
        if aoa_sensor:
            # trimmed level flight: α0 = θ0, so α is referenced to θ's first sample (σ 0.02°)
            # rather than its own (σ 0.1° of vane noise plus the gust's α at that instant)
            ref[:, :, n_u + outputs.index("alpha")] = ref[:, :, n_u + outputs.index("theta")]
        return v - ref

    def estimates(self, signals: Signals, v: np.ndarray | None = None
                  ) -> dict[str, np.ndarray]:
        """r̂ [deg] of each variant, shape (n_runs, n_steps): the reconstructed departure of
        the left inboard aileron from its expected deflection (module docstring); *v*: the
        filter's inputs when already computed (:meth:`filter_inputs`)."""
        if v is None:
            v = self.filter_inputs(signals, self._reads_alpha())
        n, T, _ = v.shape
        out = {}
        for variant in self._variant_list():
            fl = self._filters(variant, signals)
            Ad = np.stack([f.Ad for f in fl])
            Bd = np.stack([f.Bd for f in fl])
            cC = np.stack([f.c @ f.Cd for f in fl])
            cD = np.stack([f.c @ f.Dd for f in fl])
            bv = np.einsum("nij,ntj->nti", Bd, v)             # (n, T, nw)
            w = np.zeros((n, Ad.shape[1]))
            ws = np.empty((n, T, Ad.shape[1]))
            for k in range(T):                                # vectorised over runs
                ws[:, k] = w
                w = np.einsum("nij,nj->ni", Ad, w) + bv[:, k]
            r = np.einsum("ni,nti->nt", cC, ws) + np.einsum("ni,nti->nt", cD, v)
            lowpass = self._lowpass(signals.ts)
            if lowpass is not None and variant not in HINF_VARIANTS:
                r = scipy.signal.lfilter(*lowpass, r, axis=1)
            out[variant] = np.degrees(r)
        return out

    def _lowpass(self, ts: float) -> tuple | None:
        """(b, a) of the first-order low-pass on r̂ (``smoothing_s``, bilinear at *ts*), or
        None without one."""
        if self.smoothing_s <= 0.0:
            return None
        return scipy.signal.bilinear([1.0], [float(self.smoothing_s), 1.0], fs=1.0 / ts)

    # ---- model-error allowance (detectors/synthesis/vanek_model_error.py) ------------------------
    @staticmethod
    def model_error_signals(signals: Signals, v: np.ndarray | None = None) -> np.ndarray:
        """s = [x̃; u] of every run and step, shape (n_runs, n_steps, 15) [rad, rad/s]: the
        measured states in the order of :data:`scenarios.aircraft.lpv.STATES` (as
        :meth:`filter_inputs` reads them, α included), then the seven surfaces' deflections
        from their COM rods (every surface, the monitored one as it moves) relative to their
        first sample, then the spoilers' equivalent angle. *v*: :meth:`filter_inputs` with
        α, when already computed."""
        from scenarios.aircraft.data import LAYOUT
        from scenarios.aircraft.loop import AIRCRAFT_ACTUATORS

        if v is None:
            v = VanekGeometric.filter_inputs(signals, aoa_sensor=True)
        x = v[:, :, v.shape[2] - len(OUTPUTS):]
        cols = []
        for j, name in enumerate(LAYOUT.names):
            r = AIRCRAFT_ACTUATORS[LAYOUT.actuator[j]].r_mm
            d = np.arcsin(np.clip(signals.rods[name] / r, -1.0, 1.0))
            cols.append(d - d[:, :1])
        cols.append(np.radians(signals.aircraft["spoiler"]))
        return np.concatenate([x, np.stack(cols, axis=2)], axis=2)

    def _error_matrices(self, variant: str, point: dict, mach=None, qbar_pa=None) -> np.ndarray:
        """:func:`detectors.synthesis.vanek_model_error.error_matrices` of *variant*'s filter for a
        run measured at *point* (keywords ``vcas_kt``, ``alt_ft``, ``mass_t``, ``cg_pct``; the
        measured Mach and q̄ the ``lpv`` filter is designed at, when given): about the model
        the filter was designed on, the measured point's (``lpv``) or :data:`NOMINAL`'s
        (``lti``). Not cached: every run has its own measured point, so a cache would only
        grow with the runs."""
        from ..synthesis import vanek_model_error as me

        layout = self._layout()
        at = (_point(**point, mach=mach, qbar_pa=qbar_pa) if variant == "lpv" else
              _point(NOMINAL.vcas_kt, NOMINAL.alt_ft, NOMINAL.mass_t, NOMINAL.cg_pct))
        return me.error_matrices(lambda pt, aero: _model_at(pt, aero, layout), point,
                                 _model(at, layout))

    def allowances(self, signals: Signals, v: np.ndarray | None = None
                   ) -> dict[str, np.ndarray]:
        """b(t) [deg] of each bounded variant (``lti``, ``lpv``), shape (n_runs, n_steps):
        the bound the Table-2 errors put on the part of r̂ the model error produces
        (:mod:`detectors.synthesis.vanek_model_error`); empty when the thresholds are constant
        (:meth:`_bounded`); *v*: :meth:`filter_inputs` with α, when already computed."""
        from ..synthesis import vanek_model_error as me

        if not self._bounded():
            return {}
        s = self.model_error_signals(signals, v)
        sched = signals.schedule
        out = {}
        for variant in [v for v in self._variant_list() if v in VARIANTS]:
            fl = self._filters(variant, signals)
            K = np.stack([self._error_matrices(variant, {k: float(sched[k][i]) for k in
                                                         ("vcas_kt", "alt_ft", "mass_t",
                                                          "cg_pct")},
                                               sched["mach"][i], sched["qbar_pa"][i])
                          for i in range(signals.n_runs)])
            b = me.bound(K, np.stack([f.Ad for f in fl]), np.stack([f.Bdist for f in fl]),
                         np.stack([f.c @ f.Cd for f in fl]),
                         np.stack([f.c @ f.Ddist for f in fl]), s, self._lowpass(signals.ts))
            out[variant] = np.degrees(b)
        return out

    def _estimates_and_allowances(self, signals: Signals) -> tuple[dict, dict]:
        """:meth:`estimates` and :meth:`allowances` from one computation of the filter's
        inputs (the monitored rod's servo model among them): with the allowance, both read
        α (:meth:`_bounded`)."""
        if not self._bounded():
            return self.estimates(signals), {}
        v = self.filter_inputs(signals, aoa_sensor=True)
        return self.estimates(signals, v), self.allowances(signals, v)

    # ---- contract ----------------------------------------------------------------------
    def _fit(self, signals: Signals) -> None:
        self.design_model_ = str(self.design_model)     # the model the thresholds belong to
        self.aoa_sensor_ = bool(self.aoa_sensor)        # and the outputs
        self.adaptive_ = bool(self.adaptive) and self.aoa_sensor_   # and the allowance
        est, bounds = self._estimates_and_allowances(signals)
        # each variant is scored on its own, so each is calibrated at the full target; with
        # the allowance, on the per-run maximum of |r̂| − b(t) (τ0 of τ0 + b(t))
        self.thresholds_deg_, calibration = {}, {}
        for k, r in est.items():
            excess = np.abs(r) - bounds[k] if k in bounds else np.abs(r)
            tau, calibration[k] = learned_threshold(
                np.maximum(np.max(excess, axis=1), 0.0), self.threshold_method,
                float(self.safety), self.target_fa_per_run, self.threshold_confidence,
                tail=self.threshold_tail, classes=signals.classes)
            if not tau > 0.0:
                raise ValueError(f"{type(self).__name__}[{k}]: the learned threshold is "
                                 f"{tau}: the learning runs' residual never exceeds its "
                                 "model-error allowance; learn on runs with sensor noise")
            self.thresholds_deg_[k] = float(tau)
        if self.threshold_method != "max":
            self.calibration_ = calibration
        self.learning_runs_ = int(signals.n_runs)

    def _detect(self, signals: Signals) -> dict[str, Detection]:
        est, bounds = self._estimates_and_allowances(signals)
        n_confirm = int(round(self.confirm_s / signals.ts)) + 1
        out = {}
        for k, r in est.items():
            tau = self.thresholds_deg_[k] + bounds[k] if k in bounds else self.thresholds_deg_[k]
            norm = np.abs(r) / tau
            # the decision: the least |r̂|/(τ0 + b) of the confirmation window (the whole
            # threshold τ0 + b(t) times s gives norm/s)
            decision = windowed_min(norm, n_confirm)
            out[k] = Detection(alarm=decide(decision), residual=norm, decision=decision)
        return out

    def __getstate__(self):
        state = dict(self.__dict__)
        state.pop("_cache", None)             # designs are rebuilt on demand
        state.pop("_families", None)
        return state

    def allowance_terms(self, signals: Signals, variant: str = "lpv") -> dict[str, np.ndarray]:
        """The terms of b(t) of *variant* (``lti`` or ``lpv``) [deg], each (n_runs, n_steps):
        ``"design point"`` |r̂_0| (zero for ``lpv``), then for each error of
        :data:`detectors.synthesis.vanek_model_error.ERRORS` max(|r̂_j+|, |r̂_j−|), low-passed
        (:mod:`detectors.synthesis.vanek_model_error`). They sum to :meth:`allowances`' b(t)
        of the variant; what share of it each Table-2 error takes (docs/vanek-geometric.md,
        "Why the default-size jam is missed")."""
        from ..synthesis import vanek_model_error as me

        if variant not in VARIANTS:
            raise ValueError(f"variant {variant!r} has no model-error allowance; allowed: "
                             f"{', '.join(VARIANTS)}")
        s = self.model_error_signals(signals)
        sched = signals.schedule
        fl = self._filters(variant, signals)
        K = np.stack([self._error_matrices(variant, {k: float(sched[k][i]) for k in
                                                     ("vcas_kt", "alt_ft", "mass_t", "cg_pct")},
                                           sched["mach"][i], sched["qbar_pa"][i])
                      for i in range(signals.n_runs)])
        path = (np.stack([f.Ad for f in fl]), np.stack([f.Bdist for f in fl]),
                np.stack([f.c @ f.Cd for f in fl]), np.stack([f.c @ f.Ddist for f in fl]))
        lowpass = self._lowpass(signals.ts)
        out = {"design point": np.degrees(me.bound(K[:, :1], *path, s, lowpass))}
        zero = np.zeros_like(K[:, :1])
        for j, e in enumerate(me.ERRORS):
            Kj = np.concatenate([zero, K[:, 1 + 2 * j:3 + 2 * j]], axis=1)
            out[e] = np.degrees(me.bound(Kj, *path, s, lowpass))
        return out
