"""chen-global pinned by value (docs/chen-estimator.md §5, [CHEN] eq. 8–9, 16–17, 20–21, 25
and Table 2), independent of the implementation: the scheduling vector, the Table-2 corners
of the envelope, the bounds k_j, the affine model, the fault and output directions, the
polytope, the stability checks, the static gain and τ0 of the fit against their documented
formulas; the estimator's recursion and its uncertainty filters (first-order hold on the
rods and sensors, the spoilers held) against a plain-Python loop whose discretisation is
written in closed form (A⁻¹(Φ − I) and the first moment of e^{Aσ}, not the augmented matrix
exponential), in both engines; the decision τ0 + b(t), its comparison's side and the
latching confirmation on hand-built statistics; and the errors raised on bad input.

The learning and test runs are hand-built Signals (no aircraft simulation): smooth rod
deflections, spoiler angle and lateral outputs, each channel a different wave, at three
measured flight points, one of them outside the scheduling box (clipped).
"""

from __future__ import annotations

import copy
import dataclasses
import itertools
import math
from dataclasses import replace

import numpy as np
import pytest
import scipy.linalg

import detectors.builtin.chen_global as cg
from detectors.builtin.chen_global import ChenGlobalEstimator
from detectors.synthesis.chen_global_uncertainty import SIGNALS, signal_matrices, uncertainty_matrix
from scenarios import envelope
from scenarios import compiled as kernels
from scenarios.signals import Signals

MONITORED = "left_inboard_aileron"
SURFACES = ("left_inboard_aileron", "right_inboard_aileron", "left_outboard_aileron",
            "right_outboard_aileron", "rudder")
#: C_b: y = [φ, p, r] of x = [β, p, r, φ] (docs/chen-estimator.md §5).
C_B = np.array([[0.0, 0.0, 0.0, 1.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]])
#: M_g column (side force, rolling, yawing moment) of each driving signal of SIGNALS.
CHANNEL_OF_SIGNAL = [("cy", "cl", "cn").index(c) for c, _ in SIGNALS]
TS = 0.01


# ---- plain transcriptions of the documented formulas -----------------------------------
def plain_rho(schedule: dict) -> np.ndarray:
    """ρ = (q̄·PG/m, q̄·PG/(m·V), q̄·PG/(m·V²), g/V) (docs/chen-estimator.md §5), (n, 4);
    m in kg (1000 kg per t), V the TAS of the measured Mach and altitude, PG relative to
    the derivative set's reference Mach."""
    from scenarios.aircraft.data import A330_SCALING, B747_CONDITION
    from scenarios.atmosphere import G0_MS2, tas_ms
    from scenarios.servo import compressibility_factor

    mach = np.asarray(schedule["mach"], float)
    v = tas_ms(mach, np.asarray(schedule["alt_ft"], float))
    cap = A330_SCALING.mach_cap
    pg = compressibility_factor(mach, cap) / compressibility_factor(B747_CONDITION.mach, cap)
    out = []
    for q, p, m_t, vi in zip(np.asarray(schedule["qbar_pa"], float), pg,
                             np.asarray(schedule["mass_t"], float), v):
        a = q * p / (m_t * 1000.0)
        out.append([a, a / vi, a / vi ** 2, G0_MS2 / vi])
    return np.array(out)


def plain_lateral(schedule: dict) -> tuple[np.ndarray, np.ndarray]:
    """(A_b, B_b) straight from scenarios.aircraft.lpv (states β, p, r, φ; inputs the four
    ailerons, the rudder, the spoilers)."""
    from scenarios.aircraft import lpv
    from scenarios.aircraft.data import LAYOUT
    from scenarios.atmosphere import tas_ms

    n = len(schedule["mach"])
    flight = {k: schedule[k] for k in ("mass_t", "cg_pct", "mach", "qbar_pa")}
    flight["tas_ms"] = tas_ms(np.asarray(schedule["mach"], float),
                              np.asarray(schedule["alt_ft"], float))
    model = lpv.run_models(flight, np.zeros(n))
    idx = [lpv.IB, lpv.IP, lpv.IR, lpv.IPHI]
    cols = [LAYOUT.names.index(s) for s in SURFACES] + [lpv.I_SPOILER]
    return model.A[:, idx][:, :, idx], model.B[:, idx][:, :, cols]


def plain_affine(model: dict, rho: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A = coef_A[0] + Σ_k ρ_keep[k]·coef_A[1 + k], the same for B, at one ρ (4,)."""
    A, B = model["coef_A"][0].copy(), model["coef_B"][0].copy()
    for k, comp in enumerate(model["keep"]):
        A = A + rho[comp] * model["coef_A"][1 + k]
        B = B + rho[comp] * model["coef_B"][1 + k]
    return A, B


def plain_fault_matrix(A, B, col, gust):
    """F = [B_b W, A_b[:, β]] with the gust channel, [B_b W] without."""
    return np.column_stack([B[:, col], A[:, 0]]) if gust else B[:, [col]]


def plain_envelope(margin: float) -> list[tuple[tuple, dict]]:
    """[(corner (dv, dh, dm, dc), measured schedule)] of every realistic Table-1 point seen
    through the corner of the Table-2 errors widened by 1 + margin."""
    pts = envelope.realistic_points()
    pts = pts[pts["realistic"]]
    w = envelope.UNCERTAINTY
    s = 1.0 + margin
    out = []
    for corner in itertools.product((-1.0, 0.0, 1.0), repeat=4):
        dv, dh, dm, dc = corner
        out.append((corner, envelope.measured_schedule(
            pts["alt_ft"].to_numpy(float), pts["vcas_kt"].to_numpy(float),
            pts["mass_t"].to_numpy(float), pts["cg_pct"].to_numpy(float),
            dh * w.alt * s, dv * w.vcas * s, dm * w.mass * s, dc * w.cg * s)))
    return out


def plain_box(margin: float) -> tuple[np.ndarray, np.ndarray]:
    """The ρ box over the widened envelope, widened by 2 % of its width on each side."""
    rho = np.vstack([plain_rho(s) for _, s in plain_envelope(margin)])
    lo, hi = rho.min(axis=0), rho.max(axis=0)
    return lo - 0.02 * (hi - lo), hi + 0.02 * (hi - lo)


def plain_discretisation(Ae: np.ndarray, ts: float):
    """(Φ, Ψ0, Ψ1'): Φ = e^{Ae·ts}, Ψ0 = ∫0^ts e^{Ae σ} dσ = Ae⁻¹(Φ − I) (zero-order hold)
    and Ψ1' = ∫0^ts e^{Ae σ}(ts − σ)/ts dσ = Ψ0 − Ae⁻¹(ts·Φ − Ψ0)/ts (the weight of the
    increment of an input that ramps over the period, first-order hold)."""
    Phi = scipy.linalg.expm(Ae * ts)
    inv = np.linalg.inv(Ae)
    psi0 = inv @ (Phi - np.eye(len(Ae)))
    return Phi, psi0, psi0 - inv @ (ts * Phi - psi0) / ts


def plain_inputs(sig: Signals, r: int) -> np.ndarray:
    """u_b of run r [deg] (6, T): δ = asin(x/r) of the COM rods (clipped to ±1), spoilers."""
    from scenarios.aircraft.data import surface_actuator

    rows = []
    for s in SURFACES:
        radius = surface_actuator(s).r_mm
        rows.append([math.degrees(math.asin(min(max(x / radius, -1.0), 1.0)))
                     for x in sig.rods[s][r]])
    rows.append(list(sig.aircraft["spoiler"][r]))
    return np.array(rows)


def plain_recursion(det, sig: Signals, bounds: bool):
    """(f̂ (n, T), w (5, n, T)) of eq. 16 and the five uncertainty filters, run by run:

    x̂_0 = C^T y_0; f_all = L2 (y_k − C x̂_k), f̂ = f_all[0]; w_j,k = L2[0] C e_j,k;
    z = Zx [β̂, p, r, φ] + Zu u_k + Zu[:, W] f̂ + Zx[:, β] f_all[1] (gust channel);
    e_j ← Φ e_j + Ψ0 M_g[:, c(j)] z_j (δ_g held); x̂ ← Φ x̂ + Ψ0 G [u; y]_k + Ψ1' G Δ[u; y]_k,
    G = [B, −L1], L1 = −F H† + Z1 H⊥ (eq. 20), Δ the next step's increment (0 at the last
    step and for the spoilers, which are held).
    """
    d = det.design_
    lo, hi = det.schedule_box_
    col = d["column"]
    n, T = sig.command.shape
    f_hat, w = np.zeros((n, T)), np.zeros((5, n, T))
    rho_all = np.clip(plain_rho(sig.schedule), lo, hi)
    M = uncertainty_matrix()
    for r in range(n):
        A, B = plain_affine(det.model_, rho_all[r])
        F = plain_fault_matrix(A, B, col, det.gust_channel)
        L1 = -F @ d["H_dagger"] + d["Z1"] @ d["H_perp"]
        Ae = A + L1 @ C_B
        G = np.hstack([B, -L1])
        Phi, psi0, psi1 = plain_discretisation(Ae, sig.ts)
        Zx, Zu = (z[0] for z in signal_matrices(A[None], B[None]))
        u = plain_inputs(sig, r)
        y = np.stack([sig.aircraft[k][r] for k in ("phi", "p", "r")])
        v = np.vstack([u, y])
        xh = C_B.T @ y[:, 0]
        e = np.zeros((5, 4))
        for k in range(T):
            fa = d["L2"] @ (y[:, k] - C_B @ xh)
            f_hat[r, k] = fa[0]
            if bounds:
                w[:, r, k] = e @ (C_B.T @ d["L2"][0])
                xt = np.array([xh[0], y[1, k], y[2, k], y[0, k]])
                z = Zx @ xt + Zu @ u[:, k] + Zu[:, col] * fa[0]
                if len(fa) > 1:
                    z = z + Zx[:, 0] * fa[1]
                e = np.array([Phi @ e[j] + psi0 @ M[:, CHANNEL_OF_SIGNAL[j]] * z[j]
                              for j in range(5)])
            dv = v[:, k + 1] - v[:, k] if k + 1 < T else np.zeros(9)
            dv[5] = 0.0
            xh = Phi @ xh + psi0 @ G @ v[:, k] + psi1 @ G @ dv
    return f_hat, w


def plain_lowpass(x: np.ndarray, tau: float, ts: float) -> np.ndarray:
    """y_k = a·y_{k−1} + (1 − a)·x_k, y_{−1} = 0, a = exp(−ts/τ); none for τ = 0."""
    if tau == 0.0:
        return np.array(x, float)
    a = math.exp(-ts / tau)
    out = np.zeros_like(x, dtype=float)
    prev = np.zeros(x.shape[:-1])
    for k in range(x.shape[-1]):
        prev = a * prev + (1.0 - a) * x[..., k]
        out[..., k] = prev
    return out


def plain_components(det, sig):
    """(|f̂| low-passed, b = Σ_j k_j |w_j| low-passed) of docs/chen-estimator.md §5."""
    f_hat, w = plain_recursion(det, sig, bounds=True)
    f_abs = np.abs(plain_lowpass(f_hat, det.filter_s, sig.ts))
    b = sum(k * np.abs(plain_lowpass(w[j], det.filter_s, sig.ts))
            for j, k in enumerate(det.error_bounds_))
    return f_abs, b


def plain_confirm(raw: np.ndarray, n_c: int) -> np.ndarray:
    """Alarm from the step where raw has held n_c consecutive steps, latched."""
    out = np.zeros_like(raw, dtype=bool)
    for r in range(raw.shape[0]):
        count, on = 0, False
        for k in range(raw.shape[1]):
            count = count + 1 if raw[r, k] else 0
            on = on or count >= n_c
            out[r, k] = on
    return out


# ---- hand-built signals ----------------------------------------------------------------
def _schedule(points) -> dict:
    alt, vcas, mass, cg_ = (np.array([p[i] for p in points], float) for i in range(4))
    return envelope.measured_schedule(alt, vcas, mass, cg_, 0.0, 0.0, 0.0, 0.0)


def make_signals(points, T: int, phase: float = 0.0) -> Signals:
    """Runs at the true (= measured) *points* (alt ft, VCAS kt, mass t, CG %), T steps of
    10 ms: every rod, the spoilers and φ, p, r a different smooth wave (rods in mm; the
    second run's right outboard rod beyond its lever arm half of the time: δ clipped to
    90°)."""
    from scenarios.aircraft.data import surface_actuator
    from scenarios.aircraft.loop import surface_actuator as loop_actuator

    n = len(points)
    t = np.arange(T) * TS
    rods = {}
    for j, s in enumerate(SURFACES):
        radius = surface_actuator(s).r_mm
        rods[s] = np.stack([radius * (0.05 + 0.02 * j) * np.sin(2.1 * t * (1 + 0.3 * j)
                                                                 + phase + r)
                            for r in range(n)])
    if n > 1:
        rods["right_outboard_aileron"][1] *= 30.0
    wave = lambda f, amp: np.stack([amp * np.sin(f * t + 0.7 * r + phase) + 0.1 * amp * r  # noqa: E731
                                    for r in range(n)])
    aircraft = {"phi": wave(0.9, 6.0), "p": wave(1.7, 3.0), "r": wave(2.3, 1.0),
                "spoiler": wave(3.1, 4.0)}
    zeros = np.zeros((n, T))
    aircraft.update({k: zeros for k in ("q", "theta", "nz", "ny", "beta")})
    rods.update({s: zeros for s in ("left_elevator", "right_elevator")})
    return Signals(ts=TS, command=zeros, current=zeros, rod_com=zeros, rod_mon=zeros,
                   surface=np.full((n, T), np.nan), pressure=np.full((n, T), np.nan),
                   schedule=_schedule(points), actuator=loop_actuator(MONITORED),
                   run_ids=np.array([f"r{i}" for i in range(n)]), aircraft=aircraft,
                   rods=rods)


LEARNING_POINTS = [(28000.0, 300.0, 180.0, 30.0), (8000.0, 160.0, 120.0, 17.0),
                   (38000.0, 220.0, 233.0, 41.0)]
#: The third point flies faster and lower than any realistic point: ρ beyond the box.
TEST_POINTS = [(18000.0, 220.0, 180.0, 30.0), (12000.0, 250.0, 150.0, 25.0),
               (2000.0, 420.0, 100.0, 30.0)]


@pytest.fixture(scope="module")
def learning():
    return make_signals(LEARNING_POINTS, 300)


@pytest.fixture(scope="module")
def fitted(learning):
    """chen-global fitted with τ0 = safety × the largest learning value (the "max" rule)."""
    return ChenGlobalEstimator(threshold_method="max", safety=1.7).fit(learning)


@pytest.fixture(scope="module")
def eval_signals():
    return make_signals(TEST_POINTS, 200, phase=0.4)


# ---- no fit needed ---------------------------------------------------------------------
def test_scheduling_vector_is_the_documented_formula():
    sched = _schedule([(28000.0, 300.0, 180.0, 30.0), (2000.0, 150.0, 233.0, 41.0)])
    np.testing.assert_allclose(cg.scheduling_vector(sched), plain_rho(sched), rtol=1e-13)
    # the components along the last axis, whatever the shape of the schedule's entries
    grid = {k: np.stack([v, v[::-1], v]) for k, v in sched.items()}           # (3, 2)
    np.testing.assert_allclose(cg.scheduling_vector(grid),
                               plain_rho({k: v.ravel() for k, v in grid.items()})
                               .reshape(3, 2, 4), rtol=1e-13)
    del sched["cg_pct"]
    with pytest.raises(ValueError, match=r"scheduling data \['cg_pct'\] in Signals.schedule"):
        cg.scheduling_vector(sched)


def test_output_matrix_and_monitored_column():
    np.testing.assert_array_equal(cg.output_matrix(), C_B)
    for j, s in enumerate(SURFACES[:4]):
        assert cg.monitored_column(s) == j
    with pytest.raises(ValueError, match="set \\[plant\\] monitored_surface to one of "
                                         "left_inboard_aileron, right_inboard_aileron, "
                                         "left_outboard_aileron, right_outboard_aileron$"):
        cg.monitored_column("rudder")


def test_envelope_schedules_are_the_table2_corners_widened_by_the_margin():
    pts = envelope.realistic_points()
    pts = pts[pts["realistic"]]
    n = len(pts)
    w = envelope.UNCERTAINTY
    for margin in (0.25, 0.0):
        got = cg.envelope_schedules(margin)
        assert len(got["mach"]) == 81 * n
        for i, (dv, dh, dm, dc) in enumerate(itertools.product((-1.0, 0.0, 1.0), repeat=4)):
            part = slice(i * n, (i + 1) * n)
            for key, true, d, width in (("vcas_kt", "vcas_kt", dv, w.vcas),
                                        ("alt_ft", "alt_ft", dh, w.alt),
                                        ("mass_t", "mass_t", dm, w.mass),
                                        ("cg_pct", "cg_pct", dc, w.cg)):
                np.testing.assert_allclose(got[key][part], pts[true].to_numpy(float)
                                           * (1.0 + d * width * (1.0 + margin)), rtol=1e-14)
    # without the corners: the points themselves, measured without error (whatever margin)
    got = cg.envelope_schedules(0.25, corners=False)
    assert len(got["mach"]) == n
    for key in ("vcas_kt", "alt_ft", "mass_t", "cg_pct"):
        np.testing.assert_allclose(got[key], pts[key].to_numpy(float), rtol=1e-14)


def test_table2_error_bounds_are_the_largest_relative_errors():
    """k_j = max((1 + d)·max ρ/ρ̂ − 1, 1 − (1 − d)·min ρ/ρ̂) over the components scaling
    signal j (static: q̄·PG/m; rate: q̄·PG/(m·V); side force: the last three) and every
    point × corner, d = 5 %; docs/chen-estimator.md §5 gives 0.43 and 0.59."""
    corners = plain_envelope(0.0)
    true = plain_rho(dict(corners)[(0.0, 0.0, 0.0, 0.0)])
    ratio = np.stack([true / plain_rho(s) for _, s in corners])
    comps = {"all": [1, 2, 3], "static": [0], "rate": [1]}
    d = envelope.UNCERTAINTY.aero
    assert d == 0.05
    expected = [max((1 + d) * ratio[..., comps[part]].max() - 1.0,
                    1.0 - (1 - d) * ratio[..., comps[part]].min()) for _, part in SIGNALS]
    got = cg.table2_error_bounds()
    np.testing.assert_allclose(got, expected, rtol=1e-12)
    np.testing.assert_allclose(got, [0.43, 0.59, 0.43, 0.59, 0.43], atol=0.005)


def test_lateral_models_and_the_affine_fit_reproduce_the_aircraft_model():
    sched = _schedule(LEARNING_POINTS + TEST_POINTS[:2])
    A, B = cg.lateral_models(sched)
    A0, B0 = plain_lateral(sched)
    np.testing.assert_array_equal(A, A0)
    np.testing.assert_array_equal(B, B0)
    # the fit over a few envelope points, checked at other points (exact to round-off:
    # 1e-9 of the largest entry, the documented tolerance)
    corners = plain_envelope(0.25)
    fit_on = {k: np.concatenate([s[k][::7] for _, s in corners[::10]]) for k in sched}
    model = cg.fit_affine(fit_on)
    np.testing.assert_array_equal(model.keep, [0, 1, 3])      # Cyp = Cyr = 0: no ρ3 term
    assert model.residual < 1e-9 and model.coef_A.shape == (4, 4, 4)
    other = _schedule([(33000.0, 250.0, 200.0, 35.0), (5000.0, 180.0, 130.0, 20.0)])
    A1, B1 = plain_lateral(other)
    got = [plain_affine({"coef_A": model.coef_A, "coef_B": model.coef_B, "keep": model.keep},
                        r) for r in plain_rho(other)]
    A2, B2 = model.matrices(plain_rho(other))
    for i in range(2):
        for X, ref in ((got[i][0], A1[i]), (got[i][1], B1[i]), (A2[i], A1[i]), (B2[i], B1[i])):
            assert np.abs(X - ref).max() <= 1e-9 * np.abs(ref).max()


def test_the_affine_model_is_the_documented_sum_over_the_kept_components():
    rng = np.random.default_rng(7)
    model = cg.AffineLateralModel(coef_A=rng.normal(size=(3, 4, 4)),
                                  coef_B=rng.normal(size=(3, 4, 6)), keep=np.array([0, 2]),
                                  residual=0.0)
    rho = rng.normal(size=(2, 4))
    A, B = model.matrices(rho)
    for i in range(2):
        ref = plain_affine({"coef_A": model.coef_A, "coef_B": model.coef_B,
                            "keep": model.keep}, rho[i])
        np.testing.assert_allclose(A[i], ref[0], rtol=1e-14, atol=1e-14)
        np.testing.assert_allclose(B[i], ref[1], rtol=1e-14, atol=1e-14)


def test_a_model_that_is_not_affine_in_rho_is_refused(monkeypatch):
    real = cg.lateral_models

    def quadratic(schedule, airframe=None):
        A, B = real(schedule, airframe)
        A = A.copy()
        A[:, 0, 0] *= 1.0 + np.asarray(schedule["qbar_pa"], float) / 1e4   # ∝ ρ0², not affine
        return A, B

    monkeypatch.setattr(cg, "lateral_models", quadratic)
    with pytest.raises(ValueError, match="not affine in the scheduling vector"):
        cg.fit_affine(_schedule(LEARNING_POINTS + TEST_POINTS))


def test_a_component_below_the_negligible_share_is_dropped(monkeypatch):
    """A ρ component whose coefficients stay below 1e-9 of the largest model entry is
    dropped (NUMERICS.negligible), and the fit without it is still accepted: here a term
    1e-9·ρ2/max ρ2 [deg/s per deg] added to L_p, 1/11.5 of the 1e-9 share of the largest
    entry (|Y| ≤ 11.5), leaves a relative residual below 1e-9/11.5."""
    real = cg.lateral_models

    def tiny_rho2(schedule, airframe=None):
        A, B = real(schedule, airframe)
        rho2 = plain_rho(schedule)[:, 2]
        A = A.copy()
        A[:, 1, 1] += 1e-9 * rho2 / rho2.max()
        return A, B

    sched = {k: np.concatenate([s[k][::5] for _, s in plain_envelope(0.25)[::4]])
             for k in ("alt_ft", "vcas_kt", "mass_t", "cg_pct", "mach", "qbar_pa")}
    Y = np.concatenate([m.reshape(len(m), -1) for m in real(sched)], axis=1)
    assert 11.0 < np.abs(Y).max() < 12.0
    monkeypatch.setattr(cg, "lateral_models", tiny_rho2)
    model = cg.fit_affine(sched)
    np.testing.assert_array_equal(model.keep, [0, 1, 3])
    assert 1e-13 < model.residual < 1e-9 / 11.0


def test_a_component_exactly_at_the_negligible_level_is_dropped(monkeypatch):
    """Decision boundary of the exact fit's components: one is kept when its largest
    coefficient is more than negligible × the largest model entry; exactly at that level it
    is dropped, as below it (the least squares are replaced by prescribed coefficients, so
    the level is met to the last bit)."""
    sched = _schedule(LEARNING_POINTS)
    A, B = cg.lateral_models(sched)
    Y = np.concatenate([A.reshape(len(A), -1), B.reshape(len(B), -1)], axis=1)
    level = cg.NUMERICS.negligible * np.abs(Y).max()
    coef = np.zeros((5, Y.shape[1]))
    coef[0] = Y[0]
    coef[1, 0] = level                                   # ρ0: exactly at the level
    coef[2, 3] = -2.0 * level                            # ρ1: above it
    coef[3, 7] = 0.5 * level                             # ρ2: below it
    coef[4, 20] = np.nextafter(level, np.inf)            # ρ3: one ulp above it

    def prescribed(x, Y_, keep):
        return coef[np.r_[0, np.asarray(keep) + 1]], Y_

    monkeypatch.setattr(cg, "_least_squares", prescribed)
    np.testing.assert_array_equal(cg.fit_affine(sched).keep, [1, 3])


@pytest.mark.parametrize("gust", [True, False])
def test_fault_matrix_and_h_direction(gust):
    rng = np.random.default_rng(1)
    A, B = rng.normal(size=(2, 4, 4)), rng.normal(size=(2, 4, 6))
    det = ChenGlobalEstimator(gust_channel=gust)
    for col in range(4):
        F = det._fault_matrix(A, B, col)
        for i in range(2):
            np.testing.assert_array_equal(F[i], plain_fault_matrix(A[i], B[i], col, gust))
    # E of Remark 4.1: the unit vector of h_output; the gust's along r, or φ when h_output
    # is r (rows φ, p, r)
    for h, second in (("phi", 2), ("p", 2), ("r", 0)):
        E = ChenGlobalEstimator(h_output=h, gust_channel=gust)._h_direction()
        ref = np.zeros((3, 2 if gust else 1))
        ref[("phi", "p", "r").index(h), 0] = 1.0
        if gust:
            ref[second, 1] = 1.0
        np.testing.assert_array_equal(E, ref)


def test_the_documented_defaults_and_parameter_limits():
    det = ChenGlobalEstimator()
    # docs/chen-estimator.md §5: ε = 0.03 along φ, confirm 0.1 s, low-pass 0.5 s, τ0 ≥ 0.2°,
    # calibrated at 1e-4 per run
    assert (det.h_perturbation, det.h_output, det.confirm_s, det.filter_s, det.floor_deg) == \
        (0.03, "phi", 0.1, 0.5, 0.2)
    assert (det.safety, det.schedule_margin, det.gust_channel, det.adaptive) == \
        (1.5, 0.25, True, True)
    assert (det.threshold_method, det.target_fa_per_run, det.threshold_confidence,
            det.threshold_tail) == ("evt", 1e-4, 0.95, "exponential")
    det.validate_params()
    ChenGlobalEstimator(confirm_s=0.0, filter_s=0.0, schedule_margin=0.0, safety=1.01,
                        floor_deg=1e-3, h_perturbation=1e-3).validate_params()
    for bad in ({"h_perturbation": 0.0}, {"safety": 1.0}, {"confirm_s": -0.01},
                {"filter_s": -0.01}, {"schedule_margin": -0.01}, {"floor_deg": 0.0}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            ChenGlobalEstimator(**bad).validate_params()
    caps = ChenGlobalEstimator.capabilities
    assert (caps.needs_fit, caps.needs_surface_sensor, caps.causal, caps.needs_aircraft) == \
        (True, False, True, True)
    # its alarm is a decision |f̂| > τ, so a trade-off curve may scale τ (threshold_scale)
    assert caps.threshold_scale is True
    assert cg.NUMERICS == cg.GlobalNumerics(affine_tolerance=1e-9, negligible=1e-9,
                                            grid_per_axis=9, polytope_margin=0.02)
    with pytest.raises(dataclasses.FrozenInstanceError):    # constants, not settings
        cg.NUMERICS.grid_per_axis = 5


def test_bad_signals_are_named(learning):
    from scenarios.aircraft.loop import surface_actuator

    det = ChenGlobalEstimator()
    det.check_signals(learning)
    for bad, needle in (
            (replace(learning, aircraft=None), 'kind = "aircraft"'),
            (replace(learning, rods=None), 'kind = "aircraft"'),
            (replace(learning, aircraft={k: v for k, v in learning.aircraft.items()
                                         if k != "spoiler"}), r"needs the signals \['spoiler'\]"),
            (replace(learning, aircraft={k: v for k, v in learning.aircraft.items()
                                         if k != "p"}), r"needs the signals \['p'\]"),
            (replace(learning, rods={k: v for k, v in learning.rods.items()
                                     if k != "rudder"}), r"needs the signals \['rudder'\]"),
            (replace(learning, actuator=None), "actuator table"),
            (replace(learning, actuator=surface_actuator("rudder")), "monitored_surface"),
            (replace(learning, schedule={k: v for k, v in learning.schedule.items()
                                         if k != "mass_t"}), r"\['mass_t'\]")):
        with pytest.raises(ValueError, match=needle):
            det.check_signals(bad)


def _decision_detector(f_abs, b, tau0=2.0, confirm_s=0.03):
    det = ChenGlobalEstimator(confirm_s=confirm_s)
    det.threshold_ = tau0
    det._components = lambda signals: (f_abs.copy(), b.copy())
    return det


def _blank(n, T, ts=TS):
    zeros = np.zeros((n, T))
    return Signals(ts=ts, command=zeros, current=zeros, rod_com=zeros, rod_mon=zeros,
                   surface=zeros, pressure=zeros)


def test_decision_is_f_over_tau0_plus_b_at_least_one_for_n_steps_latched():
    """r = |f̂|/(τ0 + b); alarm once r ≥ 1 held confirm_s/ts = 3 steps, kept to the end;
    r = 1 exactly is an exceedance (the decision statistic, the least r of the window,
    reaches 1 there: margin ≥ s ⟺ alarm at threshold × s); 2 steps are not enough; an
    alarm at the last step."""
    T = 12
    b = np.tile(np.linspace(0.0, 1.1, T), (5, 1))
    f_abs = np.zeros((5, T))
    f_abs[0, 3:6] = 2.0 + b[0, 3:6] + 1e-9         # 3 steps above: alarm at step 5, latched
    f_abs[1, 3:5] = 2.0 + b[1, 3:5] + 1e-9         # 2 steps above: none
    f_abs[1, 7:9] = 2.0 + b[1, 7:9] + 1e-9
    f_abs[2, 2:8] = 2.0 + b[2, 2:8]                # exactly on τ0 + b: alarm at step 4
    f_abs[3, 9:] = 2.0 + b[3, 9:] + 0.5            # the last three steps: alarm at the end
    f_abs[4, 4:7] = 1.9                            # above τ0 − 0.1 but b > 0.3 there: none
    det = _decision_detector(f_abs, b)
    out = det._detect(_blank(5, T))
    np.testing.assert_allclose(out.residual, f_abs / (2.0 + b), rtol=1e-15)
    expected = np.zeros((5, T), bool)
    expected[0, 5:] = True
    expected[2, 4:] = True
    expected[3, 11] = True
    np.testing.assert_array_equal(out.alarm, expected)
    # n_c = round(confirm_s/ts): 0.05 s at 10 ms → 5 steps; 0 s → one step
    raw = f_abs / (2.0 + b) >= 1.0
    for confirm_s, n_c in ((0.05, 5), (0.0, 1), (0.02, 2)):
        out = _decision_detector(f_abs, b, confirm_s=confirm_s)._detect(_blank(5, T))
        np.testing.assert_array_equal(out.alarm, plain_confirm(raw, n_c))
    # ts = 20 ms: 0.03 s is 1.5 steps, rounded to 2
    out = _decision_detector(f_abs, b)._detect(_blank(5, T, ts=0.02))
    np.testing.assert_array_equal(out.alarm, plain_confirm(raw, 2))


def test_lowpass_and_bound_are_the_documented_filters():
    rng = np.random.default_rng(4)
    x = rng.normal(size=(2, 50))
    for tau in (0.5, 0.05, 0.0):
        det = ChenGlobalEstimator(filter_s=tau)
        for xi in (x, x[0], rng.normal(size=(3, 2, 50))):         # along the last axis
            np.testing.assert_allclose(det._lowpass(xi, TS), plain_lowpass(xi, tau, TS),
                                       rtol=1e-12, atol=1e-14)
        w = rng.normal(size=(5, 2, 50))
        det.error_bounds_ = np.array([0.4, 0.6, 0.45, 0.55, 0.3])
        expected = sum(k * np.abs(plain_lowpass(w[j], tau, TS))
                       for j, k in enumerate(det.error_bounds_))
        np.testing.assert_allclose(det._bound(w.copy(), TS), expected, rtol=1e-12,
                                   atol=1e-14)


# ---- the fit ---------------------------------------------------------------------------
def test_fit_polytope_model_and_bounds(fitted):
    lo, hi = plain_box(0.25)
    np.testing.assert_allclose(fitted.schedule_box_[0], lo, rtol=1e-12)
    np.testing.assert_allclose(fitted.schedule_box_[1], hi, rtol=1e-12)
    keep = fitted.model_["keep"]
    np.testing.assert_array_equal(keep, [0, 1, 3])
    corners = []
    for c in itertools.product((0, 1), repeat=3):
        rho = lo.copy()
        for k, ci in zip(keep, c):
            rho[k] = (lo[k], hi[k])[ci]
        corners.append(rho)
    np.testing.assert_allclose(fitted.vertex_rho_, corners, rtol=1e-12)
    assert fitted.model_["affine_residual"] < 1e-9
    # the coefficients reproduce the aircraft model at the learning points (1e-9 relative)
    sched = _schedule(LEARNING_POINTS)
    A0, B0 = plain_lateral(sched)
    for i, rho in enumerate(plain_rho(sched)):
        A, B = plain_affine(fitted.model_, rho)
        assert np.abs(A - A0[i]).max() <= 1e-9 * np.abs(A0[i]).max()
        assert np.abs(B - B0[i]).max() <= 1e-9 * np.abs(B0[i]).max()
    np.testing.assert_allclose(fitted.error_bounds_, cg.table2_error_bounds(), rtol=0)
    assert fitted.design_["column"] == 0 and fitted.learning_runs_ == 3
    H = fitted.design_["H"]
    np.testing.assert_allclose(H, 0.03 * np.array([[1.0, 0.0], [0.0, 0.0], [0.0, 1.0]]))
    np.testing.assert_allclose(fitted.design_["L2"] @ H, np.eye(2), atol=1e-9)
    assert fitted.gamma_ > 0.0 and not hasattr(fitted, "calibration_")


def _error_matrix(fitted, rho):
    d = fitted.design_
    A, B = plain_affine(fitted.model_, rho)
    F = plain_fault_matrix(A, B, 0, True)
    return A + (-F @ d["H_dagger"] + d["Z1"] @ d["H_perp"]) @ C_B, A, F


def test_fit_stability_checks_and_static_gain(fitted):
    """The stored checks: the largest real pole at the vertices and on the 9³ grid of the
    box, the largest modulus of e^{Ā ts} on the grid, and the static gain f → f̂ of the
    unperturbed model, L2 C (−Ā)⁻¹ F[:, 0], at the vertices (min, max)."""
    lo, hi = fitted.schedule_box_
    keep = fitted.model_["keep"]
    vert = [_error_matrix(fitted, rho) for rho in fitted.vertex_rho_]
    assert fitted.stability_["vertex_max_real_pole"] == pytest.approx(
        max(np.linalg.eigvals(a).real.max() for a, _, _ in vert), rel=1e-9)
    grid = []
    for g in itertools.product(*[np.linspace(lo[k], hi[k], 9) for k in keep]):
        rho = lo.copy()
        rho[keep] = g
        grid.append(_error_matrix(fitted, rho)[0])
    grid = np.array(grid)
    assert fitted.stability_["grid_points"] == 729
    assert fitted.stability_["grid_max_real_pole"] == pytest.approx(
        np.linalg.eigvals(grid).real.max(), rel=1e-9)
    assert fitted.stability_["grid_max_discrete_modulus"] == pytest.approx(
        np.abs(np.linalg.eigvals(scipy.linalg.expm(grid * TS))).max(), rel=1e-12)
    L2 = fitted.design_["L2"]
    gains = [(L2 @ C_B @ np.linalg.solve(-a, F))[0, 0] for a, _, F in vert]
    assert fitted.static_gain_ == pytest.approx((min(gains), max(gains)), rel=1e-9)
    assert 0.9 < fitted.static_gain_[0] < fitted.static_gain_[1] < 1.0


@pytest.mark.parametrize("engine", ["numpy", "compiled"])
def test_recursion_and_bound_follow_the_documented_loop(fitted, eval_signals, engine,
                                                        monkeypatch):
    """f̂ and w against the plain loop, over windows of 64 steps that do not divide the
    200-step runs (the ramps' increments cross the windows' edges) and at once; one run's
    ρ beyond the box (clipped), one rod beyond its lever arm (δ clipped)."""
    lo, hi = fitted.schedule_box_
    rho = plain_rho(eval_signals.schedule)
    assert (rho[2] > hi).any() and ((rho[:2] > lo) & (rho[:2] < hi)).all()
    ref_f, ref_w = plain_recursion(fitted, eval_signals, bounds=True)
    scale_f, scale_w = np.abs(ref_f).max(), np.abs(ref_w).max(axis=(1, 2))
    assert scale_f > 1.0 and (scale_w > 0.01).all()      # every channel drives them
    for window in (64, 500):
        monkeypatch.setattr(cg, "TIME_WINDOW", window)
        with kernels.use_engine(engine):
            f_hat, w = fitted._recursion(eval_signals, bounds=True)
            f_only, none = fitted._recursion(eval_signals, bounds=False)
        # closed-form discretisation vs the augmented matrix exponential, and the observer's
        # 1/ε output gain: agreement to 1e-9 of each series' size (6e-11 measured for f̂)
        np.testing.assert_allclose(f_hat, ref_f, rtol=0, atol=1e-9 * scale_f)
        for j in range(5):
            np.testing.assert_allclose(w[j], ref_w[j], rtol=0, atol=1e-9 * scale_w[j])
        assert f_only.tobytes() == f_hat.tobytes() and none is None
    np.testing.assert_array_equal(fitted.estimate(eval_signals), f_hat)
    np.testing.assert_array_equal(fitted.uncertainty_response(eval_signals), w)


@pytest.mark.parametrize("engine", ["numpy", "compiled"])
def test_one_unknown_input_recursion(fitted, eval_signals, engine):
    """Without the gust channel (q = 1: F = B_b W, L2 one row), on the fitted arrays cut to
    the fault's column (a hand-built estimator: the recursion's equations do not depend on
    where its gains come from)."""
    det = ChenGlobalEstimator(gust_channel=False)
    for name in ("schedule_box_", "model_", "error_bounds_"):
        setattr(det, name, getattr(fitted, name))
    d = dict(fitted.design_)
    d["H_dagger"], d["L2"] = d["H_dagger"][:1], d["L2"][:1]
    det.design_ = d
    ref_f, ref_w = plain_recursion(det, eval_signals, bounds=True)
    with kernels.use_engine(engine):
        f_hat, w = det._recursion(eval_signals, bounds=True)
    np.testing.assert_allclose(f_hat, ref_f, rtol=0, atol=1e-9 * np.abs(ref_f).max())
    np.testing.assert_allclose(w, ref_w, rtol=0, atol=1e-9 * np.abs(ref_w).max())


def test_components_decision_and_learned_threshold(fitted, learning, eval_signals):
    """|f̂| and b low-passed, r = |f̂|/(τ0 + b) confirmed over 0.1 s; τ0 = max(safety ×
    the largest per-run max of (|f̂| − b)⁺, floor) on the learning runs ("max")."""
    f_abs, b = plain_components(fitted, learning)
    expected = max(1.7 * max(max((f_abs - b)[r].max(), 0.0) for r in range(3)), 0.2)
    assert fitted.threshold_ == pytest.approx(expected, rel=1e-9)
    np.testing.assert_allclose(fitted._excess(learning), f_abs - b, rtol=0,
                               atol=1e-9 * f_abs.max())
    f_abs, b = plain_components(fitted, eval_signals)
    got_f, got_b = fitted._components(eval_signals)
    np.testing.assert_allclose(got_f, f_abs, rtol=0, atol=1e-9 * f_abs.max())
    np.testing.assert_allclose(got_b, b, rtol=0, atol=1e-9 * b.max())
    np.testing.assert_allclose(fitted.activity_bound(eval_signals), got_b, rtol=0)
    # the decision at a lower τ0 (a copy of the fitted detector), so that some runs alarm:
    # τ0 = 332° on these hand-built runs, whose outputs no aircraft would fly
    low = copy.copy(fitted)
    low.threshold_ = 40.0
    r = f_abs / (low.threshold_ + b)
    assert np.abs(r - 1.0).min() > 1e-6            # no step on the boundary
    out = low.detect(eval_signals)
    np.testing.assert_allclose(out.residual, r, rtol=0, atol=1e-9 * r.max())
    np.testing.assert_array_equal(out.alarm, plain_confirm(r > 1.0, 10))
    assert out.alarm.any() and not out.alarm.all()
    # without the bound: |f̂| low-passed against τ0 alone, b = 0
    flat = ChenGlobalEstimator(adaptive=False)
    for name in ("schedule_box_", "model_", "design_", "error_bounds_", "threshold_"):
        setattr(flat, name, getattr(fitted, name))
    f_abs0, b0 = flat._components(eval_signals)
    assert not b0.any() and b0.shape == f_abs0.shape
    np.testing.assert_allclose(f_abs0, f_abs, rtol=0, atol=1e-9 * f_abs.max())


def test_quiet_learning_runs_leave_the_floor_and_a_calibration(learning):
    """Runs without any lateral activity: f̂ ≡ 0 and b ≡ 0, so every per-run maximum of
    (|f̂| − b)⁺ is 0, the calibrated threshold (the default "evt" rule, one manoeuvre) is 0
    and τ0 is the floor; the calibration is kept with the fitted state."""
    quiet = replace(learning, aircraft={k: np.zeros_like(v) for k, v in learning.aircraft.items()},
                    rods={k: np.zeros_like(v) for k, v in learning.rods.items()},
                    classes=np.array(["cruise"] * 3))
    det = ChenGlobalEstimator(floor_deg=0.3).fit(quiet)
    assert det.threshold_ == 0.3
    assert det.calibration_.largest == 0.0 and det.calibration_.threshold == 0.0
    assert not det._excess(quiet).any()


def test_an_estimator_unstable_on_the_polytope_is_refused(learning, monkeypatch):
    """The stability checks of the fit (continuous and discretised, every vertex and the
    grid of the box) refuse gains that do not stabilise the error dynamics (eq. 17)."""
    from detectors.synthesis import lpv_synthesis

    real = lpv_synthesis.synthesise

    def unstable(*args, **kwargs):
        design = real(*args, **kwargs)
        design.Z1 = design.Z1 + 1e3       # L1 = −F H† + Z1 H⊥: a pole far in the right half
        return design

    monkeypatch.setattr(lpv_synthesis, "synthesise", unstable)
    with pytest.raises(ValueError, match="not stable over the scheduling polytope"):
        ChenGlobalEstimator(threshold_method="max").fit(learning)


def _affine_rows(x, A0, A_k, B0):
    """Y (n, 16 + 24) of models A = A0 + Σ x_k A_k (B = B0) at the rows of x (n, 4)."""
    A = A0[None] + np.einsum("nk,kij->nij", x, A_k)
    B = np.broadcast_to(B0, (len(x), 4, 6))
    return np.concatenate([A.reshape(len(x), -1), B.reshape(len(x), -1)], axis=1)


def test_the_stable_components_rule_keeps_every_component_of_a_stable_fit():
    """A model affine in all four components and stable over the whole box: the full fit
    has the smallest residual of all subsets (nested least squares) and is stable at every
    vertex, so it is the one kept."""
    rng = np.random.default_rng(11)
    x = rng.uniform(0.0, 1.0, (60, 4))
    A0 = -2.0 * np.eye(4)
    A_k = 0.2 * rng.standard_normal((4, 4, 4))            # ‖Σ x_k A_k‖ < 2 on the box
    Y = _affine_rows(x, A0, A_k, np.ones((4, 6)))
    keep = cg._stable_components(x, Y, np.zeros(4), np.ones(4))
    np.testing.assert_array_equal(keep, [0, 1, 2, 3])


def test_the_stable_components_rule_drops_a_component_whose_vertices_are_no_aircraft():
    """The data fit x1 exactly, but x1 only spans [0, 0.3] while the box reaches 1, where
    the model A0 + x1·A1 has a pole at +2 1/s: every subset with x1 is refused at a vertex,
    and the rule keeps one without it (x0, whose effect is real, among them). No stable
    subset at all is a ValueError naming the box."""
    rng = np.random.default_rng(12)
    x = rng.uniform(0.0, 1.0, (60, 4))
    x[:, 1] *= 0.3
    A0 = -np.eye(4)
    A_k = np.zeros((4, 4, 4))
    A_k[0] = -0.5 * np.eye(4)
    A_k[1][0, 0] = 3.0                                    # a00 = −1 + 3·x1: +2 at x1 = 1
    Y = _affine_rows(x, A0, A_k, np.ones((4, 6)))
    keep = cg._stable_components(x, Y, np.zeros(4), np.ones(4))
    assert 1 not in keep and 0 in keep
    # within the data's own range of x1 the exact fit is stable and kept whole
    lo, hi = np.zeros(4), np.array([1.0, 0.3, 1.0, 1.0])
    np.testing.assert_array_equal(cg._stable_components(x, Y, lo, hi)[:2], [0, 1])
    with pytest.raises(ValueError, match="no affine LPV fit.*stable at every vertex"):
        cg._stable_components(x, _affine_rows(x, np.eye(4), A_k, np.ones((4, 6))),
                              np.zeros(4), np.ones(4))


def test_the_stable_components_rule_keeps_a_single_component_when_only_it_is_an_aircraft():
    """Each of x1, x2, x3 spans only [0, 0.2] in the data, where its term 5·x_k on a00 is
    real, but the box reaches 1, where A0 + x_k·A_k has a pole at +2 1/s: every subset with
    one of them is refused at a vertex, and the single component x0 (whose fit, a00 about
    −1.5 − 0.5·x0 with the three terms left out, is stable at its vertices) is kept."""
    rng = np.random.default_rng(13)
    x = rng.uniform(0.0, 1.0, (60, 4))
    x[:, 1:] *= 0.2
    A_k = np.zeros((4, 4, 4))
    A_k[0] = -0.5 * np.eye(4)
    A_k[1:, 0, 0] = 5.0                                   # a00 = −3 + 5·x_k: +2 at x_k = 1
    Y = _affine_rows(x, -3.0 * np.eye(4), A_k, np.ones((4, 6)))
    np.testing.assert_array_equal(cg._stable_components(x, Y, np.zeros(4), np.ones(4)), [0])


def test_the_stable_components_rule_searches_past_a_refused_subset():
    """The first component's box vertices are no aircraft (a00 = −3 + 5·x0 reaches +2 at
    x0 = 1, while the data span x0 in [0, 0.2]): every subset with x0 is refused, first
    among its size, and the search goes on to the subsets after it, keeping the best of
    those without x0 (here x1, x2, x3, all stable)."""
    rng = np.random.default_rng(16)
    x = rng.uniform(0.0, 1.0, (60, 4))
    x[:, 0] *= 0.2
    A_k = np.zeros((4, 4, 4))
    A_k[0, 0, 0] = 5.0
    for k in (1, 2, 3):
        A_k[k] = -0.2 * k * np.eye(4)
    Y = _affine_rows(x, -3.0 * np.eye(4), A_k, np.ones((4, 6)))
    np.testing.assert_array_equal(cg._stable_components(x, Y, np.zeros(4), np.ones(4)),
                                  [1, 2, 3])


def test_of_equal_fits_the_stable_components_rule_keeps_the_one_found_first():
    """Two components equal over the data (x1 = x0) fit exactly alike, to the last bit: of
    equal residuals the rule keeps the subset met first, fewer components and then lower
    indices, here x0. Their joint fit splits the slope between them (least squares' least
    norm), and its vertex (0, 1) is the midpoint of A1 and A2, both stable, whose coupling
    of 5 both ways gives a pole at +4 1/s: it is refused, so the tie is between x0 and x1."""
    rng = np.random.default_rng(15)
    t = rng.uniform(0.0, 1.0, 40)
    x = np.stack([t, t], axis=1)
    A1, A2 = -np.eye(4), -np.eye(4)
    A1[0, 1] = A2[1, 0] = 10.0
    A_k = np.zeros((2, 4, 4))
    A_k[0] = A2 - A1                                       # A = A1 + x0·(A2 − A1)
    Y = _affine_rows(x, A1, A_k, np.ones((4, 6)))
    assert np.linalg.eigvals(0.5 * (A1 + A2)).real.max() == pytest.approx(4.0)
    np.testing.assert_array_equal(cg._stable_components(x, Y, np.zeros(2), np.ones(2)), [0])


def test_a_pole_at_zero_is_not_stable():
    """Stable is every eigenvalue in the open left half-plane: a fit whose vertices all
    have a pole at exactly 0 (a neutral mode: the data's a33 is 0 everywhere, so is every
    fitted coefficient of it, and A is diagonal) is refused; at −1e-3 it is kept whole."""
    rng = np.random.default_rng(14)
    x = rng.uniform(0.0, 1.0, (60, 4))
    A_k = np.zeros((4, 4, 4))
    for k in range(4):
        A_k[k][:3, :3] = -0.1 * (k + 1) * np.eye(3)
    neutral = np.diag([-1.0, -1.0, -1.0, 0.0])
    with pytest.raises(ValueError, match="no affine LPV fit.*stable at every vertex"):
        cg._stable_components(x, _affine_rows(x, neutral, A_k, np.ones((4, 6))),
                              np.zeros(4), np.ones(4))
    slow = np.diag([-1.0, -1.0, -1.0, -1e-3])
    np.testing.assert_array_equal(
        cg._stable_components(x, _affine_rows(x, slow, A_k, np.ones((4, 6))),
                              np.zeros(4), np.ones(4)), [0, 1, 2, 3])


def test_a_nonlinear_aircrafts_fit_is_its_stable_components_with_its_residual(monkeypatch):
    """On an aircraft whose models are not affine in ρ (here ours with L_β's entry scaled by
    1 + q̄/1e4, ∝ ρ0² — as a JSBSim aircraft's linearisations are only approximately
    affine), the fit is not refused: its components are the best-fitting subset whose
    vertices of the box are stable (a plain search here), its coefficients the least squares
    on them, and its residual the largest relative misfit (far above affine_tolerance). The
    box is needed: without it, a ValueError."""
    from scenarios import design_models

    real = cg.lateral_models

    def quadratic(schedule, airframe=None):
        A, B = real(schedule)
        A = A.copy()
        A[:, 0, 0] *= 1.0 + np.asarray(schedule["qbar_pa"], float) / 1e4
        return A, B

    monkeypatch.setattr(cg, "lateral_models", quadratic)
    monkeypatch.setattr(design_models, "exactly_affine", lambda airframe: airframe is None)
    seen = {}
    real_rule = cg._stable_components

    def spy(x, Y, lo, hi):
        seen.update(x=x, lo=lo, hi=hi)
        return real_rule(x, Y, lo, hi)

    monkeypatch.setattr(cg, "_stable_components", spy)
    sched = {k: np.concatenate([s[k][::5] for _, s in plain_envelope(0.25)[::4]])
             for k in ("alt_ft", "vcas_kt", "mass_t", "cg_pct", "mach", "qbar_pa")}
    lo, hi = plain_box(0.25)
    model = cg.fit_affine(sched, airframe="nonlinear", box=(lo, hi))
    rho = plain_rho(sched)
    # the rule sees the box in the units it sees the data in (each ρ over its largest value)
    scale = rho.max(axis=0)
    np.testing.assert_allclose(seen["x"] * scale, rho, rtol=1e-12)
    np.testing.assert_allclose(seen["lo"] * scale, lo, rtol=1e-12)
    np.testing.assert_allclose(seen["hi"] * scale, hi, rtol=1e-12)
    A, B = quadratic(sched)
    Y = np.concatenate([A.reshape(len(A), -1), B.reshape(len(B), -1)], axis=1)
    best = (np.inf, None, None)
    for r in range(1, 5):
        for keep in itertools.combinations(range(4), r):
            X = np.column_stack([np.ones(len(rho)), rho[:, keep]])
            coef = np.linalg.lstsq(X, Y, rcond=None)[0]
            verts = np.column_stack([np.ones(2 ** r),
                                     list(itertools.product(*zip(lo[list(keep)],
                                                                 hi[list(keep)])))])
            if np.linalg.eigvals((verts @ coef)[:, :16].reshape(-1, 4, 4)).real.max() < 0.0:
                misfit = np.abs(X @ coef - Y).max()
                if misfit < best[0]:
                    best = (misfit, keep, coef)
    misfit, keep, coef = best
    np.testing.assert_array_equal(model.keep, keep)
    assert model.residual == pytest.approx(misfit / np.abs(Y).max(), rel=1e-9)
    assert model.residual > 1e3 * cg.NUMERICS.affine_tolerance
    np.testing.assert_allclose(model.coef_A, coef[:, :16].reshape(-1, 4, 4), rtol=1e-8,
                               atol=1e-10 * np.abs(coef).max())
    with pytest.raises(ValueError, match="needs the scheduling box"):
        cg.fit_affine(sched, airframe="nonlinear")
