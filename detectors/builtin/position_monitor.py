"""The industrial position monitor: the state of practice every other detector must beat.

Airbus-style servo-loop monitoring (Goupil 2010/2011, [CHEN] §1) compares redundant and
modelled views of the same position and raises an alarm when a discrepancy stays above a
threshold for a confirmation time. Three consistency checks, each optional:

``loop``
    the COM rod acquisition against the output of a *nominal* servo-loop model driven by the
    order u — the model of docs/physics.md §3 with the nominal actuator parameters, loaded by the
    hinge moment at the *measured* flight point (the monitor never sees the true one). It
    catches runaways (the rod leaves the order) and solid jams (the rod stops following it).
    The plant differs from that model by a mismatch drawn per run (docs/physics.md §6): the
    servo-valve gain Kci and the supply pressure (the stall force S·ΔP) within ±5 %, and the
    hinge moment, the model's least known input (Ch0, Chα and Chδ each within ±20 %, [CHEN]
    Table 2 aerodynamic errors, q̄ from a measured airspeed). Near the stall force
    (docs/physics.md §8) a rod's position is very sensitive to the hinge moment, and while
    the current is saturated the rod moves open loop at a speed set by Kci and S·ΔP
    (docs/physics.md §3), so a valve-gain or supply error accumulates into a position error
    until the loop closes again. So the model is run at the corners of that mismatch, a band
    of models (:meth:`PositionMonitor.band_corners`): the nominal one, and a slow valve corner
    (Kci × the low ``kci_scale``, S·ΔP × the low ``supply_scale``; S·ΔP_ref stays nominal,
    as in the plant, docs/physics.md §3) and a fast one (both high), each with the hinge
    offset HM(0) = q̄·S_c·c_c·(Ch0 + Chα·α_s) and slope ∂HM/∂δ = q̄·S_c·c_c·Chδ at the ends
    of ``hinge_scale`` — independently (``band = "corners"``, the default: 1 + 2 × 2 × 2 = 9
    models) or both at the same end (``band = "paired"``, 5 models, cheaper, measured to
    leave false alarms: docs/thresholds.md, "The band of corner models"). The rod speed
    grows with Kci and with S·ΔP, so the two valve corners bound the speeds the plant can
    draw. The loop residual is how far the rod lies *outside* the hull of the models'
    outputs (0 inside it) — a set-membership check in the manner of [COMB]'s interval
    bounds. With every range at (1, 1) it is the plain difference to the nominal model;
    ``kci_scale = supply_scale = (1, 1)`` with ``band = "paired"`` is the band of three
    hinge-moment models of the versions before. The models are discretised
    at the FCC period Ts with one explicit Euler step (``model_step = "euler"``, the
    default: one rate-law evaluation per model and step, :func:`euler_step`, the model as
    a flight-control computer runs it at its period). On fault-free runs it stays within
    0.04 mm of the plant's own RK4 integrator (0.03 mm at most, in the pitch protection;
    tests/detectors_tests/test_position_monitor_band.py), a tenth of the smallest loop
    threshold the monitor learns, which it moves by a few per cent; the false alarms and
    misses of ``addsafe-mc`` are those of RK4 on seeds no test uses (docs/execution.md,
    "The position monitor's model step"). ``model_step = "heun"`` (Heun's step, the
    explicit trapezoidal rule, two evaluations, :func:`heun_step`) stays within
    2·10⁻⁴ mm of RK4 and ``model_step = "rk4"`` (four evaluations) is the plant's own.
``com_mon``
    COM against MON rod acquisition. A liquid jam biases the acquisition the loop closes on:
    the loop hides it on COM but MON keeps the offset (docs/physics.md §5).
``surface``
    the surface sensor, converted to rod travel x = r·sin δ, against the MON rod position —
    a disconnection leaves the rod healthy while the surface floats away. Skipped when the
    surface has no sensor.

Thresholds are learned on fault-free learning runs. By default (``threshold_method = "evt"``)
each check's threshold is calibrated from the learning runs' per-run maxima of |r_c|, per
manoeuvre class (:mod:`detectors.calibrate`, docs/thresholds.md), so that a fault-free run
exceeds it with probability ≤ ``target_fa_per_run``/m, m the number of active checks (the
checks share the detector's target: by the union bound the run's false-alarm probability is
then ≤ ``target_fa_per_run``); ``safety`` is not applied on top, and serves only as the
factor on the largest value when the learning set cannot support the target. With
``threshold_method = "max"``, τ_c = ``safety`` × the largest |r_c| seen. Never below
``floor_mm``. The normalised residual is max_c |r_c|/τ_c; the alarm is raised
once it has been ≥ 1 for ``confirm_s`` and is then latched. The decision statistic is its
least value over that confirmation window (:func:`detectors.base.windowed_min`): the alarm
is raised where it first reaches 1, and a run's margin is its largest value before onset,
so with every threshold times s the run alarms exactly when its margin is ≥ s.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from scenarios import compiled as kernels
from scenarios.compiled import (BAND_WORK_ROWS, BLOCK, STEP_STAGES, band_plants, resolve_engine,
                               servo_band, servo_band_step, servo_model)
from scenarios.servo import PlantArrays, plant_arrays, rk4_step, rod_rate
from scenarios.catalog import FAULT_TYPES
from scenarios.signals import Signals

from ..base import (Capabilities, Coverage, Detection, Detector, decide, per_run_maxima,
                    windowed_min)
from ..calibrate import THRESHOLD_PARAMS, learned_threshold
from ..params import Param

CHECKS = ("loop", "com_mon", "surface")
#: Discretisations of the loop check's servo models (``model_step``): one explicit Euler
#: step per FCC period, Heun's step, or the plant's RK4 step; each one's rate-law
#: evaluations per step are :data:`scenarios.compiled.STEP_STAGES`.
MODEL_STEPS = tuple(STEP_STAGES)
#: Layouts of the loop check's band of models (``band``, :meth:`PositionMonitor.band_corners`):
#: every valve corner with the hinge offset and slope factors at their ends independently, or
#: with both at the same end.
BANDS = ("corners", "paired")


def euler_step(x_mm, i_mA, p: PlantArrays, loaded, h: float) -> np.ndarray:
    """One explicit Euler step of the rod over *h* [s] with the current *i_mA* [mA] held,
    inside the stops: x + h·ẋ(x, i) (docs/physics.md §3, :func:`scenarios.servo.rod_rate`),
    one rate-law evaluation — the monitor's model as the FCC runs it at its period (the
    NumPy reference of :func:`scenarios.compiled.servo_band_step` without ``rk4``)."""
    return np.clip(x_mm + h * rod_rate(x_mm, i_mA, p, loaded), p.x_min, p.x_max)


def heun_step(x_mm, i_mA, p: PlantArrays, loaded, h: float) -> np.ndarray:
    """Heun's step of the rod over *h* [s] with the current *i_mA* [mA] held, inside the
    stops: x + h/2·(k₁ + k₂), k₁ = ẋ(x), k₂ = ẋ(x + h·k₁) (docs/physics.md §3, the explicit
    trapezoidal rule, second order), two rate-law evaluations (the NumPy reference of
    :func:`scenarios.compiled.servo_band_step` with two stages)."""
    k1 = rod_rate(x_mm, i_mA, p, loaded)
    k2 = rod_rate(x_mm + h * k1, i_mA, p, loaded)
    return np.clip(x_mm + (0.5 * h) * (k1 + k2), p.x_min, p.x_max)


#: The NumPy step of each ``model_step``.
_STEPS = {"euler": euler_step, "heun": heun_step, "rk4": rk4_step}


@kernels.njit(nogil=True, cache=True, error_model="numpy")
def _decide_block(rod_com, u, plants, ts, stages, rod_mon, surface_mm, tau, active, n_confirm,
                  norm_out, alarm_out):
    """Normalised residual and confirmed alarm of a block of runs, the loop check's model band
    integrated in the same pass, compiled (the NumPy reference is :meth:`PositionMonitor._detect`
    with :meth:`PositionMonitor.model_band` and :func:`detectors.base.confirm`).

    The band: the models of *plants* (m, rows, n; :func:`scenarios.compiled.plant_fields`, the
    nominal model first) driven by the order *u* (n, T) [mm] from y_COM at step 0, advanced
    by :func:`scenarios.compiled.servo_band_step` (docs/physics.md §2–3; *stages* 4: RK4,
    2: Heun, 1: Euler, per period); *ts* [s].
    norm = max over the active checks of |r_c|/τ_c (``tau`` and ``active`` in the order
    loop, com_mon, surface; NaN propagates as in ``np.maximum``),
    r_loop = distance of y_COM outside [band low, band high] (|y_COM − model| when the band
    is one model), r_com_mon = y_COM − y_MON, r_surface = x_surface − y_MON [mm];
    alarm once norm ≥ 1 for *n_confirm* consecutive steps, latched. Writes *norm_out*,
    *alarm_out* (n, T). Runs go in blocks of :data:`scenarios.compiled.BLOCK`, steps outer
    and the runs of the block inner (the SIMD-friendly form of the band's step); every
    run's arithmetic is independent of the others'.
    """
    n, T = rod_com.shape
    use_loop, use_cm, use_surf = active[0], active[1], active[2]
    m = plants.shape[0] if (use_loop and T > 0) else 0
    x = np.empty((m, n))
    for j in range(m):
        for r in range(n):
            x[j, r] = rod_com[r, 0]
    i_prev = np.zeros((m, n))
    lo = np.empty(BLOCK)
    hi = np.empty(BLOCK)
    work = np.empty((BAND_WORK_ROWS, BLOCK))
    count = np.zeros(n, dtype=np.int64)
    latched = np.zeros(n, dtype=np.bool_)
    for b0 in range(0, n, BLOCK):
        b1 = min(b0 + BLOCK, n)
        for k in range(T):
            if m > 0:
                servo_band_step(u, k, b0, b1, plants, x, i_prev, ts, lo, hi, work, stages)
            for r in range(b0, b1):
                v = 0.0
                if use_loop:
                    y = rod_com[r, k]
                    above = y - hi[r - b0]
                    below = lo[r - b0] - y
                    if math.isnan(above) or math.isnan(below):
                        c = math.nan                    # NaN propagates as in np.abs
                    else:
                        c = (above if above > 0.0 else max(0.0, below)) / tau[0]
                    v = c if (c > v or math.isnan(c)) else v
                if use_cm and not math.isnan(v):
                    c = abs(rod_com[r, k] - rod_mon[r, k]) / tau[1]
                    v = c if (c > v or math.isnan(c)) else v
                if use_surf and not math.isnan(v):
                    c = abs(surface_mm[r, k] - rod_mon[r, k]) / tau[2]
                    v = c if (c > v or math.isnan(c)) else v
                norm_out[r, k] = v
                count[r] = count[r] + 1 if v >= 1.0 else 0
                if count[r] >= n_confirm:
                    latched[r] = True
                alarm_out[r, k] = latched[r]


def _warm_kernels() -> None:
    """Compile (or load from the cache) the kernel of this module on tiny inputs."""
    z2 = np.zeros((1, 2))
    plants = np.ones((2, kernels.FIELD_ROWS, 1))
    for rod in (z2, kernels.read_only_view(z2)):  # signals as detect reads them: read-only
        _decide_block(rod, rod, plants, 0.01, 4, rod, np.zeros((0, 0)), np.ones(3),
                      np.array([True, True, False]), 1, np.zeros((1, 2)),
                      np.zeros((1, 2), dtype=np.bool_))


kernels.register_warmup(_warm_kernels, kernels=(_decide_block,))


class PositionMonitor(Detector):
    """Threshold-and-confirmation monitor on position discrepancies.

    Parameters
    ----------
    safety : float
        ``"max"`` (or an ``"evt"`` learning set too small for the target): threshold =
        safety × largest fault-free residual of the learning set (> 1).
    confirm_s : float
        Confirmation time [s]: the discrepancy must persist this long (≥ 0).
    checks : sequence of str
        Which consistency checks run: any of ``"loop"``, ``"com_mon"``, ``"surface"``.
    floor_mm : float
        Smallest threshold of a check [mm] (guards against a learning set without motion).
    threshold_method, target_fa_per_run, threshold_confidence, threshold_tail
        How thresholds are learned: calibrated to a per-run false-alarm target per
        manoeuvre (``"evt"``, the default) or ``safety`` × the largest learning value
        (``"max"``); :data:`detectors.calibrate.THRESHOLD_PARAMS`, docs/thresholds.md.
    hinge_scale : (float, float)
        (low, high) multiples of the nominal hinge moment's offset HM(0) and slope ∂HM/∂δ at
        which the band's models run (module docstring; each independently with ``band =
        "corners"``). Default (0.6, 1.6): the true hinge moment over the model's when the
        documented uncertainties add up — coefficient mismatch ±20 % (docs/physics.md §6,
        est.), aerodynamic error ±5 % and q̄ from an airspeed measured within ±10 % ([CHEN]
        Table 2; q̄ ∝ VCAS², so the true q̄ is 0.83–1.23 times the one the model uses):
        0.8 · 0.95 · 0.83 = 0.63 and 1.2 · 1.05 · 1.23 = 1.55, rounded outwards. (1, 1): the
        nominal hinge moment.
    kci_scale, supply_scale : (float, float)
        (low, high) multiples of the servo-valve gain Kci and of the stall force S·ΔP (S·ΔP_ref
        stays nominal) of the band's slow (both low) and fast (both high) valve corners.
        Default (0.95, 1.05): the half-widths of the plant's d_kci and d_supply draws
        (docs/physics.md §6, ±5 %, est.). (1, 1): the nominal valve and supply.
    band : str
        ``"corners"`` (the default): the nominal model and each valve corner with HM(0) and
        ∂HM/∂δ at the ends of ``hinge_scale`` independently, 9 models; ``"paired"``: both
        hinge factors at the same end, 5 models (docs/thresholds.md, "The band of corner
        models": it leaves false alarms the nine do not).
    model_step : str
        Discretisation of the loop check's models: ``"euler"`` (the default: one rate-law
        evaluation per model and FCC period, as a flight-control computer runs a model;
        within 0.04 mm of RK4 on fault-free runs, thresholds a few per cent apart, the same
        false alarms and misses; docs/execution.md), ``"heun"`` (Heun's step, two
        evaluations, within 2·10⁻⁴ mm of RK4) or ``"rk4"`` (the plant's integrator, four).
    """

    capabilities = Capabilities(needs_fit=True, needs_surface_sensor=False, causal=True,
                                fit_concurrently=True, threshold_scale=True)

    parameters = (
        Param("safety", "float", gt=1.0, doc="threshold of a check = safety × its largest "
              "fault-free residual over the learning set"),
        Param("confirm_s", "float", ge=0.0, unit="s", doc="time the discrepancy must persist "
              "before the alarm, which is then latched"),
        Param("checks", "choices", choices=CHECKS, doc="consistency checks that run: loop "
              "(COM rod vs nominal servo-loop model), com_mon (COM vs MON rod), surface "
              "(surface sensor vs MON rod)", source="Goupil 2010/2011, [CHEN] §1"),
        Param("floor_mm", "float", gt=0.0, unit="mm", doc="smallest threshold of a check "
              "(guards against a learning set without motion)"),
        *THRESHOLD_PARAMS,
        Param("hinge_scale", "floats", gt=0.0, length=2, doc="(low, high) multiples of the "
              "nominal hinge moment's offset HM(0) and slope ∂HM/∂δ: the band's models take "
              "each at these ends (independently with band = corners, together with band = "
              "paired); (1, 1): the nominal hinge moment",
              source="docs/physics.md §6 and [CHEN] Table 2 half-widths combined"),
        Param("model_step", "choice", choices=MODEL_STEPS, doc="discretisation of the loop "
              "check's servo models: euler (one rate-law evaluation per model and FCC period, as "
              "a flight-control computer runs it; within 0.04 mm of rk4 on fault-free runs), "
              "heun (two evaluations; within 2e-4 mm of rk4) or rk4 (the plant's integrator, "
              "four evaluations)",
              source="docs/physics.md §2–3, docs/execution.md"),
        Param("kci_scale", "floats", gt=0.0, length=2, doc="(low, high) multiples of the "
              "servo-valve gain Kci of the band's slow and fast valve corners (paired with "
              "supply_scale); (1, 1): the nominal gain",
              source="docs/physics.md §6, d_kci half-width 5 % (est.)"),
        Param("supply_scale", "floats", gt=0.0, length=2, doc="(low, high) multiples of the "
              "stall force S·ΔP (ΔP_ref stays nominal) of the band's slow and fast valve "
              "corners (paired with kci_scale); (1, 1): the nominal supply pressure",
              source="docs/physics.md §3 and §6, d_supply half-width 5 % (est.)"),
        Param("band", "choice", choices=BANDS, doc="models of the loop check's band: corners "
              "(the nominal model and each valve corner with the hinge offset and slope "
              "factors at their ends independently, 9 models) or paired (each valve corner "
              "with both hinge factors low or both high, 5 models)",
              source="docs/physics.md §6 (the mismatch the plant draws), docs/thresholds.md"),
    )

    def __init__(self, safety=1.5, confirm_s=0.05, checks=CHECKS, floor_mm=0.05,
                 threshold_method="evt", target_fa_per_run=1e-4, threshold_confidence=0.95,
                 threshold_tail="exponential", hinge_scale=(0.6, 1.6), model_step="euler",
                 kci_scale=(0.95, 1.05), supply_scale=(0.95, 1.05), band="corners"):
        self.safety = safety
        self.confirm_s = confirm_s
        self.checks = checks
        self.floor_mm = floor_mm
        self.threshold_method = threshold_method
        self.target_fa_per_run = target_fa_per_run
        self.threshold_confidence = threshold_confidence
        self.threshold_tail = threshold_tail
        self.hinge_scale = hinge_scale
        self.model_step = model_step
        self.kci_scale = kci_scale
        self.supply_scale = supply_scale
        self.band = band

    # ---- residuals ---------------------------------------------------------------------
    def coverage(self, variant: str | None = None) -> Coverage:
        """Every fault type with the surface check (Goupil 2010/2011: the monitor of a
        servo-loop's every failure case); without it every one but the disconnection, which
        leaves the rod signals healthy (docs/physics.md §5) and shows only on the surface
        sensor."""
        if "surface" in self._checks():
            return Coverage(None, "")
        return Coverage(tuple(f for f in FAULT_TYPES if f != "disconnection"),
                        "without the surface check a disconnection leaves the rod signals "
                        "the loop and com_mon checks read healthy (docs/physics.md §5)")

    def _checks(self) -> list[str]:
        """The ``checks`` parameter as a list (a single name is accepted)."""
        return [self.checks] if isinstance(self.checks, str) else list(self.checks)

    def _active_checks(self, signals: Signals) -> list[str]:
        checks = self._checks()
        if not signals.has_surface_sensor:
            checks = [c for c in checks if c != "surface"]
        return checks

    @staticmethod
    def model_plant(signals: Signals, hinge_scale: float = 1.0, corner=None):
        """Plant parameters (:class:`scenarios.servo.PlantArrays`) of a servo model of the
        band: the nominal actuator at the measured flight point (docs/physics.md §3, §6), its
        hinge moment (both HM(0) and ∂HM/∂δ) times *hinge_scale*; or, given *corner* =
        (Kci, S·ΔP, HM(0), ∂HM/∂δ) factors (:meth:`band_corners`), the servo-valve gain Kci,
        the stall force S·ΔP, HM(0) = q̄·S_c·c_c·(Ch0 + Chα·α_s) and ∂HM/∂δ = q̄·S_c·c_c·Chδ
        each times its factor (docs/physics.md §6, the mismatch the plant draws: d_kci,
        d_supply, d_ch0/d_cha, d_chd). The supply factor moves S·ΔP only, as the plant's
        d_supply does: S·ΔP_ref stays nominal (docs/physics.md §3, "Limits")."""
        sch = signals.schedule
        plant = plant_arrays(signals.actuator, qbar_pa=sch["qbar_pa"], alpha_deg=sch["alpha_deg"],
                             mach=sch["mach"])
        kci, supply, offset, slope = ((1.0, 1.0, hinge_scale, hinge_scale) if corner is None
                                      else (float(v) for v in corner))
        changes = {}
        if kci != 1.0:
            changes["Kci"] = plant.Kci * kci
        if supply != 1.0:
            changes["SdP"] = plant.SdP * supply
        if offset != 1.0:
            changes["hm_0"] = plant.hm_0 * offset
        if slope != 1.0:
            changes["hm_delta"] = plant.hm_delta * slope
        return replace(plant, **changes) if changes else plant

    @staticmethod
    def model_output(signals: Signals, engine: str | None = None,
                     hinge_scale: float = 1.0, model_step: str = "rk4",
                     corner=None) -> np.ndarray:
        """Nominal closed-loop servo model driven by the order (docs/physics.md §2–3) [mm].

        *engine*: ``"compiled"`` (:func:`scenarios.compiled.servo_model`) or ``"numpy"`` (the
        reference loop below); default :func:`scenarios.compiled.current_engine`.
        *hinge_scale*: the model's hinge moment (both HM(0) and ∂HM/∂δ) times this factor;
        *corner*: (Kci, S·ΔP, HM(0), ∂HM/∂δ) factors instead (:meth:`model_plant`).
        *model_step*: one of :data:`MODEL_STEPS` (:func:`euler_step`, or the plant's RK4 step:
        the default of this function, which other detectors call for the expected rod; the
        monitor passes its own ``model_step``).
        """
        if model_step not in MODEL_STEPS:
            raise ValueError(f"unknown model_step {model_step!r}; choose one of "
                             f"{', '.join(MODEL_STEPS)}")
        plant = PositionMonitor.model_plant(signals, hinge_scale, corner)
        if resolve_engine(engine) == "compiled":
            return servo_model(signals.command, signals.rod_com[:, 0], plant, signals.ts,
                               stages=STEP_STAGES[model_step])
        step = _STEPS[model_step]
        n, T = signals.command.shape
        out = np.empty((n, T))
        x = signals.rod_com[:, 0].astype(float).copy()
        i_prev = np.zeros(n)
        loaded = np.ones(n, dtype=bool)
        u = signals.command
        for k in range(T):
            out[:, k] = x
            i_new = np.clip(plant.K * (u[:, k] - x), -plant.i_max, plant.i_max)
            x = step(x, i_prev, plant, loaded, signals.ts)
            i_prev = i_new
        return out

    def band_corners(self) -> tuple[tuple[float, float, float, float], ...]:
        """The (Kci, S·ΔP, HM(0), ∂HM/∂δ) factors of the band's models (:meth:`model_plant`),
        the nominal model (1, 1, 1, 1) first, without repeats (just the nominal one when every
        range is (1, 1)). The valve corners: slow (the low ``kci_scale`` with the low
        ``supply_scale``; the rod speed of docs/physics.md §3 grows with both) and fast (both
        high). ``band = "corners"``: each valve corner with HM(0) and ∂HM/∂δ at the ends of
        ``hinge_scale`` independently (2 × 2 × 2, nine models with the nominal one);
        ``"paired"``: with both hinge factors low or both high (2 × 2, five models)."""
        kci = sorted(float(v) for v in self.kci_scale)
        supply = sorted(float(v) for v in self.supply_scale)
        h_lo, h_hi = sorted(float(v) for v in self.hinge_scale)
        if self.band == "paired":
            hinges = [(h_lo, h_lo), (h_hi, h_hi)]
        else:
            hinges = [(o, d) for o in (h_lo, h_hi) for d in (h_lo, h_hi)]
        corners = [(1.0, 1.0, 1.0, 1.0)]
        for valve in ((kci[0], supply[0]), (kci[1], supply[1])):
            for hinge in hinges:
                corner = (*valve, *hinge)
                if corner not in corners:
                    corners.append(corner)
        return tuple(corners)

    def rate_evaluations_per_step(self) -> int:
        """Evaluations of the rate law (docs/physics.md §3) per run and step of ``detect``:
        :data:`scenarios.compiled.STEP_STAGES` of its ``model_step`` per model of the band
        (Euler 1, Heun 2, RK4 4); none without the loop check (``fdd-campaign bench``'s
        arithmetic floor)."""
        if "loop" not in self._checks():
            return 0
        return len(self.band_corners()) * STEP_STAGES[self.model_step]

    def model_band(self, signals: Signals,
                   engine: str | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(low, high) [mm]: the hull of the model outputs at the nominal hinge moment and at
        ``hinge_scale`` times it (one array twice when ``hinge_scale = (1, 1)``).

        *engine*: ``"compiled"`` integrates the models in one pass
        (:func:`scenarios.compiled.servo_band`), ``"numpy"`` is the reference (each model by
        :meth:`model_output`, then ``np.minimum``/``np.maximum``); default
        :func:`scenarios.compiled.current_engine`. Both give the same values.
        """
        corners = self.band_corners()
        if len(corners) == 1:
            nominal = self.model_output(signals, engine=engine, model_step=self.model_step)
            return nominal, nominal
        if resolve_engine(engine) == "compiled":
            return servo_band(signals.command, signals.rod_com[:, 0],
                              [self.model_plant(signals, corner=c) for c in corners], signals.ts,
                              stages=STEP_STAGES[self.model_step])
        outs = [self.model_output(signals, engine="numpy", corner=c,
                                  model_step=self.model_step) for c in corners]
        return np.minimum.reduce(outs), np.maximum.reduce(outs)

    def residuals(self, signals: Signals) -> dict[str, np.ndarray]:
        """The raw residual [mm] of each active check, shape (n_runs, n_steps); the loop
        residual is the signed distance of the COM rod outside :meth:`model_band`."""
        out = {}
        checks = self._active_checks(signals)
        if "loop" in checks:
            lo, hi = self.model_band(signals)
            y = signals.rod_com
            # 0 inside the band (0·(y − hi) keeps a NaN acquisition NaN)
            out["loop"] = np.where(y > hi, y - hi, np.where(y < lo, y - lo, 0.0 * (y - hi)))
        if "com_mon" in checks:
            out["com_mon"] = signals.rod_com - signals.rod_mon
        if "surface" in checks:
            act = signals.actuator
            out["surface"] = act.deg_to_mm(signals.surface) - signals.rod_mon
        return out

    # ---- contract ----------------------------------------------------------------------
    def _fit(self, signals: Signals) -> None:
        maxima = per_run_maxima(
            signals, lambda block: {name: np.abs(r) for name, r in self.residuals(block).items()})
        # "evt": each check at target/m, so the run's probability is ≤ target (union bound)
        share = float(self.target_fa_per_run) / max(len(maxima), 1)
        self.thresholds_mm_, calibration = {}, {}
        for name, m in maxima.items():
            tau, calibration[name] = learned_threshold(
                m, self.threshold_method, self.safety, share,
                self.threshold_confidence, tail=self.threshold_tail, classes=signals.classes)
            self.thresholds_mm_[name] = float(max(tau, self.floor_mm))
        if self.threshold_method != "max":
            self.calibration_ = calibration
        self.learning_runs_ = int(signals.n_runs)

    def _detect(self, signals: Signals) -> Detection:
        checks = self._active_checks(signals)
        missing = sorted(set(checks) - set(self.thresholds_mm_))
        if missing:
            raise ValueError(f"no learned threshold for check(s) {missing}: the learning set "
                             "lacked the signals these checks need")
        if resolve_engine(None) == "compiled":
            return self._detect_compiled(signals, checks)
        res = self.residuals(signals)
        norm = np.zeros((signals.n_runs, signals.n_steps))
        for name, r in res.items():
            np.maximum(norm, np.abs(r) / self.thresholds_mm_[name], out=norm)
        decision = windowed_min(norm, self._n_confirm(signals.ts))
        return Detection(alarm=decide(decision), residual=norm, decision=decision)

    def _n_confirm(self, ts: float) -> int:
        """Steps the normalised residual must stay ≥ 1 for the alarm: ``confirm_s`` / Ts + 1
        (the step that crosses and ``confirm_s`` after it)."""
        return max(int(round(self.confirm_s / ts)) + 1, 1)

    def _detect_compiled(self, signals: Signals, checks: list[str]) -> Detection:
        """:meth:`_detect` through :func:`_decide_block` (same values; no (n, T) model band,
        residual, absolute value or confirmation counter arrays)."""
        empty = np.zeros((0, 0))

        def c(a):
            return np.ascontiguousarray(a, dtype=float)

        rod_com = c(signals.rod_com)
        if "loop" in checks:
            u = c(signals.command)
            plants = band_plants([self.model_plant(signals, corner=c)
                                  for c in self.band_corners()])
        else:
            u, plants = empty, np.zeros((0, kernels.FIELD_ROWS, signals.n_runs))
        rod_mon = c(signals.rod_mon) if ("com_mon" in checks or "surface" in checks) else empty
        surface = (c(signals.actuator.deg_to_mm(signals.surface))
                   if "surface" in checks else empty)
        tau = np.array([self.thresholds_mm_.get(name, 1.0) for name in CHECKS])
        norm = np.empty(rod_com.shape)
        alarm = np.empty(rod_com.shape, dtype=bool)
        n_confirm = self._n_confirm(signals.ts)
        active = np.array([name in checks for name in CHECKS])
        _decide_block(rod_com, u, plants, float(signals.ts), STEP_STAGES[self.model_step],
                      rod_mon, surface, tau, active, n_confirm, norm, alarm)
        return Detection(alarm=alarm, residual=norm, decision=windowed_min(norm, n_confirm))


kernels.invalidate_stale_cache(__name__)   # numba cache built from other kernel sources: flushed
