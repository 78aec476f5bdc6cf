"""The LPV H−/H∞ fault estimator of [CHEN] at the local actuator level: liquid and solid
jamming of a control-surface servo-loop (``chen-local``).

Model ([CHEN] eq. 24): the quasi-LPV actuator model of eq. 12–14 with the current limit
and the damping neighbour of eq. 11 (:mod:`detectors.synthesis.chen_local_model`, identified on the
nonlinear servo-loop over the envelope) with an additive rod-sensor fault::

    ẋ = −K̃(ρ̃)·x + K̃(ρ̃)·u + δ_l,    y = x + f_jam,    K̃ = K·σ·D,    ρ̃ = [ρ, x, sign ẋ, u − x]

In the form of eq. 15: A = −K̃, B = K̃, C = 1, D = 0, F = 0, H = 1 (+ ε of Remark 4.1),
M = 1 (δ_l enters the rod speed [mm/s]), N = 0. A is affine in the scalar K̃, so the
scheduling polytope of eq. 8 is the interval [K_min·σ_min·D_min, K_max] that bounds K̃ over
the envelope (r = 2 vertices; σ_min = e_sat over the order range, D_min at the saturated
no-load speed): K is evaluated on a dense grid — every realistic point of the
[CHEN] Table-1 grid seen through every corner of the Table-2 measurement errors (widened by
``schedule_margin``), × rod positions across that point's authority, × both directions of
motion — and the extremes are widened by :data:`NUMERICS`.polytope_margin (K is not
multi-affine in ρ: C1·C2 is quadratic, hence the grid). Online, ρ is clipped to the box of
that grid, K to [K_min, K_max] and K̃ to the polytope, so the estimator never leaves it.

Estimator ([CHEN] eq. 16, gains eq. 20–21, LMIs eq. 23 solved by
:func:`detectors.synthesis.lpv_synthesis.synthesise`): with one rod measurement and one fault, H⊥ is
empty, so L1(ρ) = −F·H† = 0 and L2 = H† = 1/(1 + ε): the design freedom Z1, Z2 vanishes
and the LMIs certify the estimator's stability at the vertices and give γ, the H∞ bound from
δ_l [mm/s] to the estimation error [mm] (γ = 1/K̃_min [s] for ε = 0). The estimator runs
the model on the order and schedules it on its own state x̂ (sign ẋ = sign(u − x̂), eq. 14,
and σ, D on u − x̂), discretised at Ts with K̃ frozen over a period by the bilinear transform of the
model (:func:`detectors.synthesis.chen_local_model.tustin_pole`; stable for every point
of the polytope)::

    x̂_{k+1} = x̂*_k + (x̂_k − x̂*_k)·φ(K̃_k − L1),   x̂*_k = (K̃_k·u_{k−d} − L1·y_k)/(K̃_k − L1),
    f̂_k = L2·(y_k − x̂_k),

with K̃_k held inside the polytope (scheduling data projected onto it).

Decision ([CHEN] §6.1–6.2), constant thresholds learned on the fault-free learning set:

* ``solid``: [CHEN]'s solid jam (eq. 4, §6.2; the ``"offset"`` jam of docs/physics.md §5)
  leaves the measurement stuck 1.8 % of the range away from the healthy rod, so f̂ steps by
  that offset at onset and stays there. The statistic asks whether f̂ has stepped away from
  where it just was and stayed away over a short confirmation window: with n_c =
  ``solid_confirm_s``/Ts and n_b = ``solid_reference_s``/Ts,

      r_k = (1/n_b)·Σ_{j=n_c}^{n_c+n_b−1} f̂_{k−j},   s_k = min_{0≤j<n_c} |f̂_{k−j} − r_k|,
      f̂_j = 0 for j < 0

  (the reference r is the mean of f̂ over the n_b steps before the window; the least
  distance from it over the window is the persistence). Slow model mismatch (correlation
  time about 0.2 s) is nearly the same in the reference and the window and cancels, as in
  the liquid statistic, so the turns' loaded roll-ins no longer set the threshold at the
  size of the jam; a liquid jam's step decays within the window. τ_sol is learned on
  max s per fault-free run. ``solid_reference_s = 0`` gives the level statistic, the
  least |f̂| over the window, for a rod seized where it stands (the ``"seized"`` jam:
  f̂ grows only as the order moves away, with no step): its threshold must then sit at the
  noise level, which 50 learning runs per manoeuvre do not calibrate
  (docs/chen-estimator.md §3);
* ``liquid``: a liquid jam adds a step f to the acquisition the loop closes on; the loop
  re-centres the biased acquisition on the order within a few loop time constants
  (τ = 1/(Kci·K) = 57 ms on the aileron, docs/physics.md §3, §5), so f̂ is a step of
  size f that decays over some 50 ms ([CHEN] Fig. 9c: it "occurs and then disappears").
  f̂ goes through the post-filter T(s) = (s + 1)/(s + 5) of §6.2, g = T f̂, and the
  statistic evaluates g over two adjacent windows, the last n_a = ``liquid_window_s``/Ts
  steps against the n_b = ``liquid_reference_s``/Ts steps before them::

      d_k = (1/n_a)·Σ_{j=0}^{n_a−1} g_{k−j} − (1/n_b)·Σ_{j=n_a}^{n_a+n_b−1} g_{k−j},
      g_j = 0 for j < 0

  (the difference of two adjacent window means: the filtered-derivative test for a step
  change in the mean, Basseville & Nikiforov 1993, *Detection of Abrupt Changes* §2.1).
  A jam's step f gives d ≈ f·(mean of its decay over the first n_a steps): 0.9·f with
  the default 20 ms (measured on ``chen-mc``). Fault-free model mismatch varies at the
  rate of the orders (correlation time about 0.2 s in cruise; the loaded roll-ins of the
  turns are its largest): it is nearly the same in both windows and cancels, while white
  sensor noise enters with σ·√(1/n_a + 1/n_b). Then an integrator of the time |d|
  spends at or beyond τ_liq (it never resets: it "maintains the effect of the fault bias till
  the end of the simulation"), and the liquid alarm is raised once it reaches
  ``liquid_confirm_s`` (its decision statistic: the n-th largest |d|/τ_liq so far, n the
  steps that time takes; the margin is its largest value before onset). τ_liq is learned
  on max |d| per fault-free run. ``liquid_reference_s = 0`` and ``liquid_window_s = 0``
  give the level |T f̂| itself (a statistic whose calibrated threshold was measured at
  the size of a 1.3 % jam on the aircraft plant: docs/chen-estimator.md §3). Integrating
  T f̂ itself would accumulate the per-run sensor bias and noise of the fault-free runs
  without bound, which no constant threshold can separate from a transient of ~f·τ.

The synthesis and the model identification run once in ``fit`` (cached per actuator and
period) and are stored in the fitted state; ``detect`` is a few multiply-adds and one
division per run and step, vectorised over runs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from scenarios import compiled as kernels
from scenarios.params import param
from scenarios.signals import Signals

from ..synthesis import chen_local_model as lm
from ..base import Capabilities, Coverage, Detection, Detector, decide, per_run_maxima
from ..calibrate import THRESHOLD_PARAMS, learned_threshold
from ..params import Param

#: Measurements the estimator can use as the rod sensor output y of [CHEN] eq. 24.
SENSORS = ("rod_com", "rod_mon")

#: Residual variants, in output order.
VARIANTS = ("liquid", "solid")


@dataclass(frozen=True)
class PostFilter:
    """The liquid-jam post-filter T(s) = (s + z)/(s + p) of [CHEN] §6.2."""

    zero_rad_s: float = param("rad/s", "[CHEN] §6.2", "zero z of T(s)")
    pole_rad_s: float = param("rad/s", "[CHEN] §6.2", "pole p of T(s)")


POST_FILTER = PostFilter(zero_rad_s=1.0, pole_rad_s=5.0)


@dataclass(frozen=True)
class LocalNumerics:
    """Numerical constants of the local design (not physical parameters)."""

    polytope_margin: float = param("-", "numerical", "relative widening of [K_min, K_max] "
                                   "beyond the dense-grid extremes (K is quadratic in ρ)")
    grid_rho: int = param("-", "numerical", "grid values per scheduling variable of the "
                          "polytope and stability checks")
    grid_x: int = param("-", "numerical", "rod positions of the polytope and stability grid")


NUMERICS = LocalNumerics(polytope_margin=0.05, grid_rho=7, grid_x=41)


def discrete_post_filter(ts: float, pf: PostFilter = POST_FILTER) -> tuple[np.ndarray, np.ndarray]:
    """(b, a) of T(s) discretised at *ts* by zero-order hold (scipy ``cont2discrete``)."""
    from scipy.signal import cont2discrete

    num, den, _ = cont2discrete(([1.0, pf.zero_rad_s], [1.0, pf.pole_rad_s]), ts, method="zoh")
    return np.ravel(num), np.ravel(den)


def liquid_window_taps(ts: float, window_s: float, reference_s: float) -> np.ndarray:
    """FIR taps h of the liquid statistic d = h * g (module docstring): n_a = max(round(
    *window_s*/*ts*), 1) taps of 1/n_a (the recent mean), then n_b = round(*reference_s*/*ts*)
    taps of −1/n_b (the reference mean just before it; none for n_b = 0). The taps sum to
    0 when n_b > 0: a constant g gives d = 0."""
    n_a = max(int(round(window_s / ts)), 1)
    n_b = int(round(reference_s / ts))
    h = np.full(n_a + n_b, 1.0 / n_a)
    if n_b:
        h[n_a:] = -1.0 / n_b
    return h


@kernels.njit(nogil=True, cache=True, error_model="numpy")
def _estimate_block(u, y, c0, c1, c2, L1, L2, delay, x_lo, x_hi, k_lo, k_hi, ke_lo, ke_hi,
                    e_sat, kappa, ts, f_out):
    """The estimator recursion of :meth:`ChenLocalEstimator.estimate`, compiled ([CHEN]
    eq. 13–14 and 16 with the current saturation, the damping factor and the bilinear step
    of :mod:`detectors.synthesis.chen_local_model`), in the NumPy reference's order of operations.
    *u*, *y* (n, T) [mm]; *c0*, *c1*, *c2* (n,) model coefficients; writes f̂ [mm] into
    *f_out* (n, T)."""
    n, T = u.shape
    half_ts = 0.5 * ts
    xh_run = np.empty(n)
    for r in range(n):
        xh_run[r] = y[r, 0]
    # steps outside, runs inside (as scenarios.compiled): the runs' recursions are
    # independent, so the processor overlaps them; each run's arithmetic is unchanged
    for k in range(T):
        for r in range(n):
            xh = xh_run[r]
            yk = y[r, k]
            f_out[r, k] = L2 * (yk - xh)
            v = u[r, max(k - delay, 0)]
            xs = min(max(xh, x_lo), x_hi)
            d = v - xh
            s = 1.0 if d > 0.0 else (-1.0 if d < 0.0 else d)         # np.sign
            K = c0[r] + c1[r] * s * (xs + c2[r])                     # [CHEN] eq. 13–14
            K = min(max(K, k_lo), k_hi)                              # inside the polytope
            ad = abs(d)
            sig = e_sat / ad if ad > e_sat else 1.0                  # current saturation
            w = sig * d
            v0 = c0[r] * w
            K = K * sig * (1.0 / np.sqrt(1.0 + kappa * v0 * v0))     # damping neighbour
            K = min(max(K, ke_lo), ke_hi)
            a = K - L1
            target = (K * v - L1 * yk) / a
            xh_run[r] = target + (xh - target) * ((1.0 - half_ts * a) / (1.0 + half_ts * a))


@kernels.njit(nogil=True, cache=True, error_model="numpy")
def _nth_largest_so_far(x, n, out):
    """out[r, k] = the *n*-th largest of x[r, 0 … k] (NaN samples left out; NaN until n
    values exist): the decision statistic of the liquid check, whose alarm is raised once
    *n* samples have reached the threshold (at threshold × s: once n samples are ≥ s, i.e.
    where this statistic first reaches s). Each run keeps its n largest values so far,
    sorted ascending. *x*, *out* (runs, T); n ≥ 1."""
    runs, T = x.shape
    top = np.empty(n)
    for r in range(runs):
        top[:] = -np.inf
        for k in range(T):
            v = x[r, k]
            if v > top[0]:                    # NaN compares False: left out
                j = 0
                while j + 1 < n and top[j + 1] < v:
                    top[j] = top[j + 1]
                    j += 1
                top[j] = v
            out[r, k] = top[0] if top[0] > -np.inf else np.nan


def _warm_kernels() -> None:
    """Compile (or load from the cache) the kernels of this module on tiny inputs."""
    for z in (np.zeros((1, 2)), kernels.read_only_view(np.zeros((1, 2)))):
        _nth_largest_so_far(z, 1, np.zeros((1, 2)))
    z2, z1 = np.zeros((1, 2)), np.ones(1)
    ro = kernels.read_only_view   # signals (and the schedule) as detect reads them: read-only
    for z, c in ((z2, z1), (ro(z2), z1), (ro(z2), ro(z1))):
        _estimate_block(z, z, c, c, c, 0.0, 1.0, 1, -1.0, 1.0, 1.0, 2.0, 0.5, 2.0, 1.0, 0.0,
                        0.01, np.zeros((1, 2)))


kernels.register_warmup(_warm_kernels, kernels=(_estimate_block, _nth_largest_so_far))


class ChenLocalEstimator(Detector):
    """[CHEN] H−/H∞ LPV fault estimator at the actuator level (see the module docstring).

    Parameters
    ----------
    sensor : str
        Rod measurement y: ``"rod_com"`` (the acquisition the loop closes on; default) or
        ``"rod_mon"``.
    safety : float
        Threshold = safety × the largest fault-free residual of the learning set (> 1).
    liquid_confirm_s : float
        Integrated time beyond τ_liq that raises the liquid alarm [s] (≥ 0; 0: first step).
    liquid_window_s : float
        Window n_a·Ts of the liquid statistic's recent mean [s] (≥ 0; 0: one step).
    liquid_reference_s : float
        Window n_b·Ts of the reference mean just before it, subtracted [s] (≥ 0; 0: no
        reference, the statistic is the level of the recent mean).
    solid_confirm_s : float
        Confirmation window n_c·Ts of the solid statistic: time f̂ must stay beyond τ_sol
        away from its reference mean [s] (≥ 0; 0: one step).
    solid_reference_s : float
        Window n_b·Ts of the reference mean of f̂ just before the confirmation window [s]
        (≥ 0; 0: no reference, the statistic is the least |f̂| over the window).
    schedule_margin : float
        Relative widening of the [CHEN] Table-2 measurement-error widths (±10 % VCAS, h,
        m, Xcg) over which the polytope of eq. 8 is computed (0.25: errors up to ±12.5 %);
        scheduling data outside its box are clipped to it.
    h_perturbation : float
        ε of [CHEN] Remark 4.1: H = 1 + ε (H already has full column rank here; ≥ 0).
    floor_mm : float
        Smallest threshold [mm] (> 0).
    post_filter_zero_rad_s, post_filter_pole_rad_s : float
        Zero z and pole p of the liquid-jam post-filter T(s) = (s + z)/(s + p) [rad/s]
        (0 < z < p); default [CHEN] §6.2's (s + 1)/(s + 5). T keeps the high-frequency gain
        1 (a jam's estimate is a step) and divides slow model mismatch by p/z.
    threshold_method, target_fa_per_run, threshold_confidence, threshold_tail
        How thresholds are learned: calibrated to a per-run false-alarm target per
        manoeuvre (``"evt"``, the default) or ``safety`` × the largest learning value
        (``"max"``); :data:`detectors.calibrate.THRESHOLD_PARAMS`, docs/thresholds.md.
    """

    capabilities = Capabilities(needs_fit=True, needs_surface_sensor=False, causal=True,
                                estimates_rod_fault=True, threshold_scale=True)

    #: variant → (fault types it is designed to detect, source) ([CHEN] §6.2: one
    #: statistic of f̂ per jam type)
    VARIANT_COVERAGE = {
        "liquid": (("liquid_jam",), "[CHEN] §6.2: the liquid-jam statistic (post-filtered "
                   "T f̂) is designed for liquid jams"),
        "solid": (("solid_jam",), "[CHEN] §6.2: the solid-jam statistic (f̂ held away from "
                  "its reference) is designed for solid jams"),
    }

    parameters = (
        Param("sensor", "choice", choices=SENSORS, doc="rod measurement y of eq. 24 (the "
              "acquisition the loop closes on, or the monitoring one)", source="[CHEN] eq. 24"),
        Param("safety", "float", gt=1.0, doc="thresholds = safety × the largest fault-free "
              "statistic over the learning set"),
        Param("liquid_confirm_s", "float", ge=0.0, unit="s", doc="integrated time beyond "
              "τ_liq that raises the liquid alarm (0: first step)",
              source="[CHEN] §6.2; value est."),
        Param("liquid_window_s", "float", ge=0.0, unit="s", doc="window of the recent mean "
              "of T f̂ in the liquid statistic (0: one step); about the first third of the "
              "loop's re-centring time constant", source="docs/chen-estimator.md §3; value est."),
        Param("liquid_reference_s", "float", ge=0.0, unit="s", doc="window of the reference "
              "mean of T f̂ just before the recent one, subtracted (0: no reference, the "
              "level |T f̂| of [CHEN] §6.2)", source="docs/chen-estimator.md §3; value est."),
        Param("solid_confirm_s", "float", ge=0.0, unit="s", doc="confirmation window over "
              "which f̂ must stay beyond τ_sol away from its reference mean (0: one step)",
              source="[CHEN] §6.2 (a fixed confirmation); value est."),
        Param("solid_reference_s", "float", ge=0.0, unit="s", doc="window of the reference "
              "mean of f̂ just before the confirmation window (0: no reference, the level "
              "|f̂|, for a jam seized where it stands)",
              source="docs/chen-estimator.md §3; value est."),
        Param("schedule_margin", "float", ge=0.0, doc="relative widening of the Table-2 "
              "measurement-error widths over which the polytope of eq. 8 is computed",
              source="[CHEN] Table 2, eq. 8; value est."),
        Param("h_perturbation", "float", ge=0.0, doc="ε of Remark 4.1: H = 1 + ε",
              source="[CHEN] Remark 4.1"),
        Param("floor_mm", "float", gt=0.0, unit="mm", doc="smallest threshold"),
        Param("post_filter_zero_rad_s", "float", gt=0.0, unit="rad/s", doc="zero z of the "
              "liquid-jam post-filter T(s) = (s + z)/(s + p)", source="[CHEN] §6.2"),
        Param("post_filter_pole_rad_s", "float", gt="post_filter_zero_rad_s", unit="rad/s",
              doc="pole p of T(s); p/z divides slow model mismatch", source="[CHEN] §6.2"),
        *THRESHOLD_PARAMS,
    )

    def __init__(self, sensor="rod_com", safety=1.5, liquid_confirm_s=0.02,
                 liquid_window_s=0.02, liquid_reference_s=0.04, solid_confirm_s=0.1,
                 solid_reference_s=0.2, schedule_margin=0.25, h_perturbation=0.0,
                 floor_mm=0.05, post_filter_zero_rad_s=POST_FILTER.zero_rad_s,
                 post_filter_pole_rad_s=POST_FILTER.pole_rad_s, threshold_method="evt",
                 target_fa_per_run=1e-4, threshold_confidence=0.95,
                 threshold_tail="exponential"):
        self.sensor = sensor
        self.safety = safety
        self.liquid_confirm_s = liquid_confirm_s
        self.liquid_window_s = liquid_window_s
        self.liquid_reference_s = liquid_reference_s
        self.solid_confirm_s = solid_confirm_s
        self.solid_reference_s = solid_reference_s
        self.schedule_margin = schedule_margin
        self.h_perturbation = h_perturbation
        self.floor_mm = floor_mm
        self.post_filter_zero_rad_s = post_filter_zero_rad_s
        self.post_filter_pole_rad_s = post_filter_pole_rad_s
        self.threshold_method = threshold_method
        self.target_fa_per_run = target_fa_per_run
        self.threshold_confidence = threshold_confidence
        self.threshold_tail = threshold_tail

    def coverage(self, variant: str | None = None) -> Coverage:
        """Each variant covers its own jam type (:data:`VARIANT_COVERAGE`); the detector
        as a whole, both."""
        if variant in self.VARIANT_COVERAGE:
            return Coverage(*self.VARIANT_COVERAGE[variant])
        both = [Coverage(*c) for c in self.VARIANT_COVERAGE.values()]
        return both[0].union(both[1])

    def variant_names(self) -> tuple[str, ...]:
        """The liquid-jam and the solid-jam statistics (:data:`VARIANTS`)."""
        return VARIANTS

    def check_signals(self, signals: Signals) -> None:
        super().check_signals(signals)
        if signals.actuator is None:
            raise ValueError("ChenLocalEstimator needs the nominal actuator parameters "
                             "(Signals.actuator is None)")
        lm.scheduling_vector(signals.schedule)        # names the missing scheduling data

    # ---- design (fit) ------------------------------------------------------------------
    def _polytope(self, model: lm.LocalModelFit, act) -> tuple[np.ndarray, np.ndarray,
                                                                np.ndarray]:
        """Scheduling box (lo, hi) and the values of K on the dense grid of the envelope.

        Grid: every realistic point of the [CHEN] Table-1 grid, seen through each
        combination of the Table-2 measurement errors (δVCAS, δh, δm, δXcg each at −w, 0,
        +w, widened by ``schedule_margin`` relative to w), × rod positions across that
        point's authority (orders never leave it, :func:`scenarios.servo.authority_limits`)
        × sign ẋ ∈ {−1, 0, 1}.
        """
        import itertools

        from scenarios import envelope
        from scenarios.servo import authority_limits, plant_arrays

        pts = envelope.realistic_points()
        pts = pts[pts["realistic"]]
        true = {c: pts[c].to_numpy(float) for c in envelope.FLIGHT_COLUMNS}
        fc = envelope.flight_condition(*true.values())
        plant = plant_arrays(act, qbar_pa=fc["qbar_pa"], alpha_deg=fc["alpha_deg"],
                             mach=fc["mach"])
        d_lo, d_hi = authority_limits(plant, act)
        frac = np.linspace(0.0, 1.0, NUMERICS.grid_x)
        x = act.deg_to_mm(d_lo[:, None] + (d_hi - d_lo)[:, None] * frac)
        w = envelope.UNCERTAINTY
        scale = 1.0 + float(self.schedule_margin)
        rhos = []
        for dv, dh, dm, dc in itertools.product(*[(-1.0, 0.0, 1.0)] * 4):
            meas = envelope.measured_schedule(true["alt_ft"], true["vcas_kt"], true["mass_t"],
                                              true["cg_pct"], dh * w.alt * scale,
                                              dv * w.vcas * scale, dm * w.mass * scale,
                                              dc * w.cg * scale)
            rhos.append(lm.scheduling_vector(meas))
        rho = np.stack(rhos, axis=1)                                   # (P, 81, nρ)
        c0, c1, c2 = lm.coefficients(model.theta, rho)                 # (P, 81)
        s = np.array([-1.0, 0.0, 1.0])
        K = lm.gain(c0[:, :, None, None], c1[:, :, None, None], c2[:, :, None, None],
                    x[:, None, :, None], s[None, None, None, :])
        flat = rho.reshape(-1, rho.shape[-1])
        return flat.min(axis=0), flat.max(axis=0), K

    def _fit(self, signals: Signals) -> None:
        from ..synthesis.lpv_synthesis import VertexSystem, synthesise

        act = signals.actuator
        ts = float(signals.ts)
        model = lm.fit_local_model(act, ts)
        lo, hi, K = self._polytope(model, act)
        k_min, k_max = float(K.min()), float(K.max())
        # K·σ·D (module docstring of chen_local_model): σ ≥ e_sat / (largest order–rod
        # error, the order range), D ≥ its value at the saturated no-load speed
        th0 = np.asarray(model.theta, float).reshape(3, -1)[0]      # C0 affine in ρ: its
        c0_max = float(th0[0] + np.maximum(th0[1:] * lo, th0[1:] * hi).sum())   # box max
        sig_min = min(1.0, model.e_sat_mm / (act.u_max_mm - act.u_min_mm))
        d_min = float(lm.damping_factor(c0_max * model.e_sat_mm, model.kappa))
        if not k_min > 0.0:
            raise ValueError(
                f"the identified actuator model has K = {k_min:.3g} 1/s ≤ 0 inside the "
                f"scheduling box (schedule_margin = {self.schedule_margin}): the quasi-LPV "
                "model of [CHEN] eq. 12 is not a stable first-order lag there; lower "
                "schedule_margin")
        m = NUMERICS.polytope_margin
        vertex_k = (k_min * sig_min * d_min * (1.0 - m), k_max * (1.0 + m))
        vertices = [VertexSystem.make(A=[[-k]], B=[[k]], C=[[1.0]], D=[[0.0]], F=[[0.0]],
                                      H=[[1.0]], M=[[1.0]], N=[[0.0]]) for k in vertex_k]
        design = synthesise(vertices, h_perturbation=float(self.h_perturbation))
        L1 = float(design.L1(np.zeros((1, 1)))[0, 0])
        L2 = float(design.L2[0, 0])
        # stability of the estimator: at the vertices and on the dense grid inside
        a_vertex = np.array([design.stability_margin(v) for v in design.vertices])
        a_grid = -np.concatenate([K.ravel(), K.ravel() * sig_min * d_min]) + L1
        phi_grid = np.abs(lm.tustin_pole(-a_grid, ts))
        if not (a_vertex.max() < 0.0 and a_grid.max() < 0.0 and phi_grid.max() < 1.0):
            raise ValueError(
                f"the estimator is not stable over the scheduling polytope (largest pole "
                f"{max(a_vertex.max(), a_grid.max()):.3g} 1/s); [CHEN] §4 notes the gains "
                "of eq. 20–21 need not stabilise it; narrow the polytope (schedule_margin)")
        for v in design.vertices:
            if not abs(lm.tustin_pole(-(v.A + L1 * v.C)[0, 0], ts)) < 1.0:
                raise ValueError("the discretised estimator is unstable at a vertex")

        self.model_ = model.as_dict()
        self.model_rms_mm_ = model.rms_mm
        self.gamma_ = design.gamma
        self.design_ = {"P": design.P, "S": design.S, "Z1": design.Z1, "Z2": design.Z2,
                        "H": design.H, "L1": L1, "L2": L2, "vertex_K": vertex_k,
                        "solver_status": design.solver_status}
        self.stability_ = {"vertex_max_real_pole": float(a_vertex.max()),
                           "grid_max_real_pole": float(a_grid.max()),
                           "grid_max_discrete_modulus": float(phi_grid.max()),
                           "grid_points": int(K.size)}
        self.schedule_box_ = (lo, hi)
        self.theta_ = model.theta
        self.delay_ = model.delay
        self.x_range_mm_ = (act.x_min_mm, act.x_max_mm)
        self.k_range_ = (k_min, k_max)
        self.saturation_ = {"e_sat_mm": model.e_sat_mm, "kappa": model.kappa,
                            "sigma_min": sig_min, "damping_min": d_min}
        self.post_filter_ = discrete_post_filter(ts, PostFilter(
            zero_rad_s=float(self.post_filter_zero_rad_s),
            pole_rad_s=float(self.post_filter_pole_rad_s)))

        def statistics(block: Signals) -> dict:
            f_hat, g = self._residuals(block)
            return {"liquid": np.abs(g),                # g: the liquid statistic d
                    "solid": self._solid_statistic(f_hat, ts)}

        self.solid_windows_ = self._solid_windows(ts, fitting=True)
        # each variant is scored on its own, so each is calibrated at the full target
        maxima = per_run_maxima(signals, statistics)
        self.thresholds_, calibration = {}, {}
        for name, m in maxima.items():
            tau, calibration[name] = learned_threshold(
                m, self.threshold_method, float(self.safety), self.target_fa_per_run,
                self.threshold_confidence, tail=self.threshold_tail, classes=signals.classes)
            self.thresholds_[name] = max(float(tau), float(self.floor_mm))
        if self.threshold_method != "max":
            self.calibration_ = calibration
        self.learning_runs_ = int(signals.n_runs)

    # ---- online part -------------------------------------------------------------------
    def estimate(self, signals: Signals) -> np.ndarray:
        """Fault estimate f̂ [mm] of [CHEN] eq. 16, shape (n_runs, n_steps). Compiled
        (:func:`_estimate_block`) or the NumPy loop below, as
        :func:`scenarios.compiled.current_engine` says."""
        lo, hi = self.schedule_box_
        rho = np.clip(lm.scheduling_vector(signals.schedule), lo, hi)
        c0, c1, c2 = lm.coefficients(self.theta_, rho)
        y = np.asarray(getattr(signals, self.sensor), float)
        u = np.asarray(signals.command, float)
        n, T = u.shape
        L1, L2 = self.design_["L1"], self.design_["L2"]
        d = int(self.delay_)
        x_lo, x_hi = self.x_range_mm_
        k_lo, k_hi = self.k_range_
        ke_lo, ke_hi = self.design_["vertex_K"]
        sat = self.saturation_
        e_sat, kappa = float(sat["e_sat_mm"]), float(sat["kappa"])
        ts = float(signals.ts)
        f_hat = np.empty((n, T))
        if kernels.current_engine() == "compiled":
            def flat(c):
                return np.ascontiguousarray(np.broadcast_to(c, (n,)), dtype=float)

            _estimate_block(np.ascontiguousarray(u), np.ascontiguousarray(y), flat(c0),
                            flat(c1), flat(c2), float(L1), float(L2), d, float(x_lo),
                            float(x_hi), float(k_lo), float(k_hi), float(ke_lo), float(ke_hi),
                            e_sat, kappa, ts, f_hat)
            return f_hat
        xh = y[:, 0].copy()
        for k in range(T):
            f_hat[:, k] = L2 * (y[:, k] - xh)
            v = u[:, max(k - d, 0)]
            xs = np.clip(xh, x_lo, x_hi)
            e = v - xh
            K = lm.gain(c0, c1, c2, xs, np.sign(e))        # [CHEN] eq. 13–14
            K = np.clip(K, k_lo, k_hi)                     # inside the polytope (eq. 8)
            sig = lm.saturation_factor(e, e_sat)
            K = K * sig * lm.damping_factor(c0 * (sig * e), kappa)
            K = np.clip(K, ke_lo, ke_hi)
            a = K - L1
            target = (K * v - L1 * y[:, k]) / a
            xh = target + (xh - target) * lm.tustin_pole(a, ts)
        return f_hat

    def _solid_windows(self, ts: float, fitting: bool = False) -> tuple[int, int]:
        """(n_c, n_b) of the solid statistic in steps of *ts*. A detector fitted before the
        reference existed (no ``solid_windows_``) keeps the statistic it learned on: the
        least |f̂| over its window, n_b = 0."""
        n_c = max(int(round(float(self.solid_confirm_s) / ts)), 1)
        if fitting or hasattr(self, "solid_windows_") or not hasattr(self, "thresholds_"):
            return n_c, int(round(float(self.solid_reference_s) / ts))
        return n_c, 0

    def _solid_statistic(self, f_hat: np.ndarray, ts: float) -> np.ndarray:
        """The solid statistic s [mm] at each step (module docstring; causal, f̂ taken as 0
        before the run): the least distance of f̂ from its reference mean over the last
        n_c steps, or for n_b = 0 the least |f̂| over them (0 until a full window exists)."""
        from scipy.ndimage import minimum_filter1d
        from scipy.signal import lfilter

        n_c, n_b = self._solid_windows(ts)
        if n_b == 0:
            # the window [k − n + 1, k]: origin (n − 1)//2 shifts the centred window left
            return minimum_filter1d(np.abs(f_hat), n_c, axis=1, mode="constant", cval=0.0,
                                    origin=(n_c - 1) // 2)
        taps = np.zeros(n_c + n_b)
        taps[n_c:] = 1.0 / n_b                       # r_k: mean of f̂_{k−n_c−n_b+1 … k−n_c}
        ref = lfilter(taps, [1.0], f_hat, axis=1)
        stat = np.abs(f_hat - ref)
        for j in range(1, n_c):                      # f̂_{k−j} − r_k, f̂ = 0 before the run
            lagged = np.zeros_like(f_hat)
            lagged[:, j:] = f_hat[:, :-j]
            np.minimum(stat, np.abs(lagged - ref), out=stat)
        return stat

    def _residuals(self, signals: Signals) -> tuple[np.ndarray, np.ndarray]:
        """f̂ [mm] and the liquid statistic d [mm] (module docstring), each (n_runs, n_steps)."""
        from scipy.signal import lfilter

        f_hat = self.estimate(signals)
        b, a = self.post_filter_
        g = lfilter(b, a, f_hat, axis=1)
        h = liquid_window_taps(float(signals.ts), float(self.liquid_window_s),
                               float(self.liquid_reference_s))
        if h.size == 1:       # the level |T f̂| itself (no window, no reference)
            return f_hat, g
        return f_hat, lfilter(h, [1.0], g, axis=1)

    def _detect(self, signals: Signals) -> dict[str, Detection]:
        f_hat, g = self._residuals(signals)
        ts = float(signals.ts)
        norm_liq = np.abs(g) / self.thresholds_["liquid"]
        norm_sol = self._solid_statistic(f_hat, ts) / self.thresholds_["solid"]
        # liquid: integrator of the time at or beyond the threshold (never reset, §6.2): the
        # alarm once liquid_samples(ts) samples have reached it, i.e. where their n-th
        # largest so far first reaches 1 (at threshold × s: first reaches s)
        decision_liq = np.empty(norm_liq.shape)
        _nth_largest_so_far(norm_liq, self.liquid_samples(ts), decision_liq)
        # solid: beyond τ_sol over the whole confirmation window (_solid_statistic is
        # already that window's least distance)
        # both variants carry the estimate f̂ [mm] (error statistics, docs/chen-estimator.md §8)
        return {"liquid": Detection(alarm=decide(decision_liq), residual=norm_liq,
                                    estimate=f_hat, decision=decision_liq),
                "solid": Detection(alarm=decide(norm_sol), residual=norm_sol, estimate=f_hat,
                                   decision=norm_sol)}

    def liquid_samples(self, ts: float) -> int:
        """Samples at or beyond τ_liq the liquid alarm waits for: the fewest n ≥ 1 whose
        integrated time n·Ts reaches ``liquid_confirm_s`` (at least one step) within half
        a step, n·Ts ≥ max(liquid_confirm_s, Ts) − Ts/2 as written here in floats."""
        ts = float(ts)
        need = max(float(self.liquid_confirm_s), ts) - 0.5 * ts
        n = max(int(np.ceil(need / ts)), 1)
        while n > 1 and (n - 1) * ts >= need:       # the float rounding of need / ts, both ways
            n -= 1
        while n * ts < need:
            n += 1
        return n


kernels.invalidate_stale_cache(__name__)   # numba cache built from other kernel sources: flushed
