"""scenarios.aircraft.lpv by value (docs/aircraft.md, module docstring of lpv.py): the
A330-class inertias, the scheduled and control derivatives, the continuous model and its
exact discretisations, each recomputed here from the formulas of the docstrings
(:class:`~scenarios.aircraft.data.ScalingParams`, :class:`~scenarios.aircraft.data.SurfaceLayout`,
the equations of motion) on three flight points of the realistic envelope.

Tolerances: relative 1e-12 on quantities that are a few floating-point operations on the same
inputs (the code and the formula round differently, by a few 1e-16); the model equations
are checked on A·x + B·u through a linear solve of a well-conditioned 7×7 system (relative
1e-10); the series of the matrix exponential is summed to 1e-16 of its first term. A wrong
sign, factor or column moves these by per cents."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import replace

import numpy as np
import pytest

from scenarios.aircraft import lpv
from scenarios.aircraft.data import (B747, B747_CONDITION, B747_DERIVATIVES,
                                     LAYOUT)
from scenarios.atmosphere import G0_MS2
from scenarios.envelope import A330, AERO_COEFFICIENTS

REL = 1e-12
#: Three flight points (Mach, CG [% MAC], mass [t], q̄ [Pa], TAS [m/s]): one below the
#: Prandtl–Glauert cap, one above it (M held at 0.75), a forward CG.
MACH = np.array([0.55, 0.82, 0.70])
CG = np.array([35.0, 28.0, 18.0])
MASS = np.array([190.0, 230.0, 140.0])
QBAR = np.array([9000.0, 14500.0, 12000.0])
TAS = np.array([170.0, 245.0, 215.0])
DRAWS = {"cz": 0.04, "cm": -0.03, "cy": 0.02, "cl": -0.05, "cn": 0.07}


def _pg(mach):
    """Prandtl–Glauert 1/sqrt(1 − M²) with M held at the scaling's 0.75 (ScalingParams)."""
    m = min(mach, 0.75)
    return 1.0 / math.sqrt(1.0 - m * m)


def _nominal(i):
    """Derivatives of point i before the draws: PG relative to M 0.8 (held at 0.75, so the
    reference factor is that of 0.75), Cmα and Cmδe moved by −Czx·(h − 0.25)."""
    k = _pg(MACH[i]) / _pg(0.75)
    d = {name: getattr(B747_DERIVATIVES, name) * k
         for name in B747_DERIVATIVES.__dataclass_fields__}
    dh = (CG[i] - 25.0) / 100.0
    d["Cm_alpha"] -= d["Cz_alpha"] * dh
    d["Cm_de"] -= d["Cz_de"] * dh
    return d, dh


def test_a330_inertias_scale_the_747_by_mass_and_length_squared():
    """I = I_747·(m/m_747)·(d/d_747)²: span for Ix and Izx, length for Iy, the diagonal
    sqrt(b² + l²) for Iz (ScalingParams); S and c̄ of the A330, b of the scaling."""
    f = lpv.a330_airframes(MASS)
    m747 = 2.83176e6 / 9.80665
    for i, mass in enumerate(MASS):
        k = mass * 1000.0 / m747
        assert f.mass_kg[i] == pytest.approx(mass * 1000.0, rel=REL)
        assert f.Ix[i] == pytest.approx(0.247e8 * k * (60.3 / 59.64) ** 2, rel=REL)
        assert f.Izx[i] == pytest.approx(-0.212e7 * k * (60.3 / 59.64) ** 2, rel=REL)
        assert f.Iy[i] == pytest.approx(0.449e8 * k * (63.7 / 70.6) ** 2, rel=REL)
        assert f.Iz[i] == pytest.approx(
            0.673e8 * k * (60.3 ** 2 + 63.7 ** 2) / (59.64 ** 2 + 70.6 ** 2), rel=REL)
    assert (f.S, f.c, f.b) == (361.6, 7.27, 60.3)
    r = lpv.reference_airframe()
    assert (r.mass_kg[0], r.Ix[0], r.Iy[0], r.Iz[0], r.Izx[0]) == (
        B747.mass_kg, 0.247e8, 0.449e8, 0.673e8, -0.212e7)
    assert (r.S, r.c, r.b) == (511.0, 8.324, 59.64)


def test_each_derivative_belongs_to_its_coefficient():
    assert [lpv.derivative_axis(n) for n in ("Cz_q", "Cm_de", "Cy_beta", "Cl_da", "Cn_r")] == [
        "cz", "cm", "cy", "cl", "cn"]
    assert set(lpv.AXIS_OF_PREFIX.values()) == set(AERO_COEFFICIENTS) - {"cx"}


def test_scheduled_derivatives_are_mach_and_cg_scaled_then_drawn_per_coefficient():
    got = lpv.scheduled_derivatives(MACH, CG, DRAWS)
    for i in range(3):
        nom, _ = _nominal(i)
        for name, value in nom.items():
            want = value * (1.0 + DRAWS[name[:2].lower()])
            assert got[name][i] == pytest.approx(want, rel=REL, abs=1e-300), (name, i)
    # a coefficient left out of the mapping is drawn 0; a number applies to every one
    part = lpv.scheduled_derivatives(MACH, CG, {"cm": 0.1})
    same = lpv.scheduled_derivatives(MACH, CG, 0.1)
    nominal = lpv.scheduled_derivatives(MACH, CG)
    np.testing.assert_allclose(part["Cm_q"], 1.1 * nominal["Cm_q"], rtol=REL)
    np.testing.assert_array_equal(part["Cz_alpha"], nominal["Cz_alpha"])
    np.testing.assert_allclose(same["Cl_p"], 1.1 * nominal["Cl_p"], rtol=REL)
    with pytest.raises(ValueError, match=r"unknown aerodynamic coefficient\(s\) \['cw'\]"):
        lpv.scheduled_derivatives(MACH, CG, {"cw": 0.1})


def test_one_flight_point_with_draws_per_run_gives_one_derivative_a_run():
    """A scalar Mach and CG with a mapping of per-run draws: arrays of the draws' shape,
    the derivatives and the control rows alike."""
    draws = {"cz": np.array([0.01, -0.02]), "cl": np.array([0.03, 0.0])}
    d = lpv.scheduled_derivatives(0.7, 30.0, draws)
    nominal = lpv.scheduled_derivatives(0.7, 30.0)
    np.testing.assert_allclose(d["Cz_q"], nominal["Cz_q"] * np.array([1.01, 0.98]), rtol=REL)
    np.testing.assert_allclose(d["Cm_q"], np.full(2, nominal["Cm_q"]), rtol=REL)
    c = lpv.control_derivatives(0.7, 30.0, draws)
    c0 = lpv.control_derivatives(0.7, 30.0)
    assert c["Cl"].shape == (2, lpv.N_INPUTS)
    np.testing.assert_allclose(c["Cl"], c0["Cl"] * np.array([[1.03], [1.0]]), rtol=REL)


def test_scheduled_derivatives_at_the_reference_point_are_the_table():
    """At the reference Mach and CG (25 % MAC) the scaling is the identity."""
    got = lpv.scheduled_derivatives(B747_CONDITION.mach, B747.cg_ref_pct)
    for name in B747_DERIVATIVES.__dataclass_fields__:
        assert float(got[name]) == pytest.approx(getattr(B747_DERIVATIVES, name), rel=REL)


def _rows(i, layout=LAYOUT):
    """Control derivative rows of point i from the SurfaceLayout docstring (before draws)."""
    nom, dh = _nominal(i)
    rows = {k: np.zeros(lpv.N_INPUTS) for k in ("Cz", "Cm", "Cy", "Cl", "Cn")}
    for j, name in enumerate(layout.names):
        side = 1.0 if name.startswith("right") else -1.0
        if "elevator" in name:
            cz = layout.elevator_share * nom["Cz_de"]
            rows["Cz"][j] = cz
            rows["Cm"][j] = layout.elevator_share * nom["Cm_de"]
            rows["Cl"][j] = side * (layout.elevator_arm_m / 60.3) * cz
            rows["Cn"][j] = layout.elevator_yaw * rows["Cl"][j]
        elif "aileron" in name:
            inboard = "inboard" in name
            share = layout.inboard_share if inboard else layout.outboard_share
            y_a = layout.inboard_arm_m if inboard else layout.outboard_arm_m
            x_a = layout.inboard_aft_m if inboard else layout.outboard_aft_m
            # δa = (δ_right − δ_left)/2 shared by the pair, times the A330 roll power
            cl = side / 2.0 * share * layout.aileron_factor * nom["Cl_da"]
            rows["Cl"][j] = cl
            rows["Cn"][j] = side / 2.0 * share * layout.aileron_factor * nom["Cn_da"]
            cl_lift = -side * cl * 60.3 / y_a
            rows["Cz"][j] = -cl_lift
            rows["Cm"][j] = -cl_lift * x_a / 7.27 + cl_lift * dh
        else:
            rows["Cy"][j], rows["Cl"][j], rows["Cn"][j] = nom["Cy_dr"], nom["Cl_dr"], nom["Cn_dr"]
    rows["Cl"][lpv.I_SPOILER] = layout.spoiler_factor * layout.aileron_factor * nom["Cl_da"]
    rows["Cn"][lpv.I_SPOILER] = layout.spoiler_yaw_ratio * rows["Cl"][lpv.I_SPOILER]
    return rows


@pytest.mark.parametrize("layout", [LAYOUT, replace(
    LAYOUT, elevator_share=0.45, inboard_share=0.6, outboard_share=0.4, aileron_factor=2.5,
    spoiler_factor=1.4, spoiler_yaw_ratio=0.15, elevator_yaw=0.03)], ids=["A330", "other"])
def test_control_derivatives_of_every_surface(layout):
    got = lpv.control_derivatives(MACH, CG, DRAWS, layout)
    for i in range(3):
        want = _rows(i, layout)
        for key, row in want.items():
            np.testing.assert_allclose(got[key][i], row * (1.0 + DRAWS[key.lower()]), rtol=REL,
                                       atol=1e-300, err_msg=f"{key} point {i}")
    # the gust columns carry no control derivative
    for key in got:
        assert not got[key][:, lpv.I_GUST_ALPHA:].any()


def test_the_documented_signs_of_the_surfaces():
    """Etkin & Reid signs (data.py): a left elevator trailing edge down lifts the left tail
    and rolls right wing down (Cl > 0); a right aileron down rolls left (Cl < 0) and lifts
    (Cz < 0); the spoilers roll with the aileron order, with proverse yaw of the same sign."""
    c = lpv.control_derivatives(MACH, CG)
    j = {n: k for k, n in enumerate(LAYOUT.names)}
    assert (c["Cl"][:, j["left_elevator"]] > 0).all()
    assert (c["Cl"][:, j["right_elevator"]] < 0).all()
    assert (c["Cl"][:, j["right_inboard_aileron"]] < 0).all()
    assert (c["Cz"][:, j["right_outboard_aileron"]] < 0).all()
    assert (c["Cz"][:, j["left_outboard_aileron"]] < 0).all()
    assert (c["Cl"][:, lpv.I_SPOILER] < 0).all() and (c["Cn"][:, lpv.I_SPOILER] < 0).all()


def _derivs_all_nonzero():
    """The scheduled set of the three points with Cyp and Cyr (0 in the 747 table) set
    non-zero, so that every term of the equations shows."""
    d = lpv.scheduled_derivatives(MACH, CG, DRAWS)
    d["Cy_p"] = np.array([0.05, -0.03, 0.02])
    d["Cy_r"] = np.array([0.2, 0.25, 0.15])
    return d


def _model():
    frames = lpv.a330_airframes(MASS)
    d = _derivs_all_nonzero()
    controls = lpv.control_derivatives(MACH, CG, DRAWS)
    return lpv.continuous_model(QBAR, TAS, d, frames, controls), d, frames, controls


def test_the_continuous_model_satisfies_the_equations_of_motion():
    """For random states and inputs, ẋ = A·x + B·u and (Δn_z, n_y) = C·x + D·u satisfy the
    module docstring's equations with Etkin & Reid's dimensional derivatives (Tables 4.4,
    4.5): forces ×q̄S, pitch ×q̄Sc̄, roll and yaw ×q̄Sb, rates ×c̄/(2V) or b/(2V)."""
    model, d, f, ctl = _model()
    rng = np.random.default_rng(7)
    S, c, b, g = f.S, f.c, f.b, G0_MS2
    for i in range(3):
        x = rng.normal(size=7) * 0.05
        u = rng.normal(size=lpv.N_INPUTS) * 0.05
        xd = model.A[i] @ x + model.B[i] @ u
        y = model.C[i] @ x + model.D[i] @ u
        a, q, th, be, p, r, ph = x
        ad, qd, thd, bd, pd, rd, phd = xd
        ag, bg = u[lpv.I_GUST_ALPHA], u[lpv.I_GUST_BETA]
        m, V, qS = f.mass_kg[i], TAS[i], QBAR[i] * S
        hc, hb = c / (2 * V), b / (2 * V)
        D = {k: v[i] for k, v in d.items()}
        sz, sm, sy, sl, sn = (ctl[k][i] @ u for k in ("Cz", "Cm", "Cy", "Cl", "Cn"))
        Za, Zq, Zad = qS * D["Cz_alpha"], qS * hc * D["Cz_q"], qS * hc * D["Cz_alphadot"]
        qSc = qS * c
        Ma, Mq, Mad = qSc * D["Cm_alpha"], qSc * hc * D["Cm_q"], qSc * hc * D["Cm_alphadot"]
        lhs_rhs = [
            ((m * V - Zad) * ad, Za * (a + ag) + (m * V + Zq) * q + qS * sz),
            (f.Iy[i] * qd - Mad * ad, Ma * (a + ag) + Mq * q + qS * c * sm),
            (thd, q),
            (m * V * bd, qS * D["Cy_beta"] * (be + bg) + qS * hb * D["Cy_p"] * p
             + (qS * hb * D["Cy_r"] - m * V) * r + m * g * ph + qS * sy),
            (f.Ix[i] * pd - f.Izx[i] * rd, qS * b * (D["Cl_beta"] * (be + bg) + hb * D["Cl_p"] * p
                                                    + hb * D["Cl_r"] * r + sl)),
            (f.Iz[i] * rd - f.Izx[i] * pd, qS * b * (D["Cn_beta"] * (be + bg) + hb * D["Cn_p"] * p
                                                    + hb * D["Cn_r"] * r + sn)),
            (phd, p),
        ]
        for k, (lhs, rhs) in enumerate(lhs_rhs):
            assert lhs == pytest.approx(rhs, rel=1e-10, abs=1e-10 * abs(rhs) + 1e-14), (i, k)
        assert y[0] == pytest.approx(V * (q - ad) / g, rel=1e-10)
        assert y[1] == pytest.approx(V * (bd + r) / g - ph, rel=1e-10)
    np.testing.assert_array_equal(model.tas_ms, TAS)


def test_run_models_builds_the_model_of_the_true_flight_point():
    """run_models = continuous_model(scheduled and control derivatives with the draws, the
    A330 inertias of the run's mass), and it takes the aircraft and the layout it is given."""
    flight = {"mass_t": MASS, "cg_pct": CG, "mach": MACH, "qbar_pa": QBAR, "tas_ms": TAS}
    got = lpv.run_models(flight, DRAWS)
    want = lpv.continuous_model(QBAR, TAS, lpv.scheduled_derivatives(MACH, CG, DRAWS),
                                lpv.a330_airframes(MASS),
                                lpv.control_derivatives(MACH, CG, DRAWS))
    for k in ("A", "B", "C", "D"):
        np.testing.assert_array_equal(getattr(got, k), getattr(want, k), err_msg=k)
    small = replace(A330, wing_area_m2=300.0, mac_m=6.5)
    other = lpv.run_models(flight, DRAWS, aircraft=small)
    np.testing.assert_allclose(other.A, lpv.continuous_model(
        QBAR, TAS, lpv.scheduled_derivatives(MACH, CG, DRAWS), lpv.a330_airframes(MASS, small),
        lpv.control_derivatives(MACH, CG, DRAWS, aircraft=small)).A, rtol=REL)
    assert not np.allclose(other.A, got.A, rtol=1e-3)
    lay = replace(LAYOUT, aileron_factor=2.0)
    moved = lpv.run_models(flight, DRAWS, layout=lay)
    np.testing.assert_allclose(moved.B, lpv.continuous_model(
        QBAR, TAS, lpv.scheduled_derivatives(MACH, CG, DRAWS), lpv.a330_airframes(MASS),
        lpv.control_derivatives(MACH, CG, DRAWS, lay)).B, rtol=REL)
    assert not np.allclose(moved.B, got.B, rtol=1e-3)


def test_the_reference_model_flies_the_747_at_its_condition():
    """q̄ = ρ·V²/2 at 40 000 ft, M 0.8 (ρ 0.3045 kg/m³, V 235.9 m/s), the 747 inertias."""
    ref = lpv.reference_model()
    qbar = 0.5 * 0.3045 * 235.9 ** 2
    want = lpv.continuous_model(np.array([qbar]), np.array([235.9]),
                                lpv.scheduled_derivatives(0.8, 25.0),
                                lpv.reference_airframe(), lpv.control_derivatives(0.8, 25.0))
    np.testing.assert_allclose(ref.A, want.A, rtol=REL, atol=1e-15)
    np.testing.assert_allclose(ref.B, want.B, rtol=REL, atol=1e-15)


def _series(A, B, ts, power):
    """Σ_k A^k·B·ts^(k+power)/(k+power)! to convergence (power 0 with B = I: Φ; 1: Γ;
    2: Γ₁·Ts, the ramp's term)."""
    term = B * ts ** power / math.factorial(power)
    total = term.copy()
    for k in range(1, 60):
        term = A @ term * ts / (k + power)
        total = total + term
    return total


@pytest.mark.parametrize("ts", [0.01, 0.4])
def test_the_exact_discretisations_are_the_matrix_exponential_series(ts):
    """ZOH: Φ = Σ (A·Ts)^k/k!, Γ = Σ A^k·B·Ts^(k+1)/(k+1)!; the surfaces' ramp over the
    period adds Γ₁ = (1/Ts)·Σ A^k·B·Ts^(k+2)/(k+2)! on their first seven columns."""
    model, *_ = _model()
    phi, gam = lpv.discretise(model, ts)
    phi_r, gam_r, gam1 = lpv.discretise_ramp(model, ts)
    assert gam1.shape == (3, 7, 7)
    for i in range(3):
        A, B = model.A[i], model.B[i]
        want_phi = _series(A, np.eye(7), ts, 0)
        want_gam = _series(A, B, ts, 1)
        want_g1 = _series(A, B[:, :lpv.N_SURFACES], ts, 2) / ts
        scale = np.abs(want_gam).max()
        np.testing.assert_allclose(phi[i], want_phi, rtol=0, atol=1e-12)
        np.testing.assert_allclose(phi_r[i], want_phi, rtol=0, atol=1e-12)
        np.testing.assert_allclose(gam[i], want_gam, rtol=0, atol=1e-10 * scale)
        np.testing.assert_allclose(gam_r[i], want_gam, rtol=0, atol=1e-10 * scale)
        np.testing.assert_allclose(gam1[i], want_g1, rtol=0, atol=1e-10 * scale)
    _, _, two = lpv.discretise_ramp(model, ts, n_ramp=2)
    np.testing.assert_allclose(two, gam1[:, :, :2], rtol=0, atol=1e-10 * np.abs(gam1).max())


def test_modes_pick_the_upper_roots_and_the_fastest_and_slowest_real_roots():
    """On a hand-made block-diagonal model: short period −1 ± 2j, an oscillation −3 ± 0.5j
    in the Dutch roll's place (faster than the roll and slower than 1 rad/s, so that
    counting a complex root as real would move the roll root), roll −2, spiral +0.01 (real
    roots told from complex ones by |Im| < 1e-9)."""
    A = np.zeros((1, 7, 7))
    A[0, :2, :2] = [[-1.0, 2.0], [-2.0, -1.0]]
    A[0, 3:5, 3:5] = [[-3.0, 0.5], [-0.5, -3.0]]
    A[0, 5, 5], A[0, 6, 6] = -2.0, 0.01
    m = lpv.ContinuousModel(A=A, B=np.zeros((1, 7, 10)), C=np.zeros((1, 2, 7)),
                            D=np.zeros((1, 2, 10)), tas_ms=np.ones(1))
    md = lpv.modes(m)
    assert md["short_period"][0] == pytest.approx(complex(-1.0, 2.0), abs=1e-12)
    assert md["dutch_roll"][0] == pytest.approx(complex(-3.0, 0.5), abs=1e-12)
    assert md["roll"][0] == pytest.approx(-2.0, abs=1e-12)
    assert md["spiral"][0] == pytest.approx(0.01, abs=1e-12)


def test_a_root_whose_imaginary_part_is_at_the_threshold_counts_as_complex():
    """Decision boundary of modes: |Im| = 1e-9 exactly (−3 ± 1e-9j, exact in the
    eigensolver for this block) is not a real root, so the roll root stays −2."""
    A = np.zeros((1, 7, 7))
    A[0, 3:5, 3:5] = [[-3.0, 1e-9], [-1e-9, -3.0]]
    A[0, 5, 5], A[0, 6, 6] = -2.0, 0.01
    m = lpv.ContinuousModel(A=A, B=np.zeros((1, 7, 10)), C=np.zeros((1, 2, 7)),
                            D=np.zeros((1, 2, 10)), tas_ms=np.ones(1))
    assert np.abs(np.linalg.eigvals(A[0, 3:, 3:]).imag).max() == 1e-9
    assert lpv.modes(m)["roll"][0] == -2.0


def test_models_are_frozen_and_the_options_of_run_models_are_keyword_only():
    """A model or an airframe set is never changed after it is built; run_models's aircraft
    and layout are named (passed by position they would be taken for one another)."""
    model, _, frames, _ = _model()
    with pytest.raises(dataclasses.FrozenInstanceError):
        model.A = model.A
    with pytest.raises(dataclasses.FrozenInstanceError):
        frames.S = 1.0
    flight = {"mass_t": MASS, "cg_pct": CG, "mach": MACH, "qbar_pa": QBAR, "tas_ms": TAS}
    with pytest.raises(TypeError, match="positional"):
        lpv.run_models(flight, 0.0, A330)
