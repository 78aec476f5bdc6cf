"""scenarios.aircraft.laws by value (docs/aircraft.md §4): the pitch gains place the poles
they are documented to place, the roll and yaw gains are the nominal model's derivatives,
and one FCC period, the filters, the rate limiter and the loop matrices are recomputed here
from the equations of the module docstring on hand-chosen numbers."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from scenarios import envelope
from scenarios.aircraft import laws, lpv
from scenarios.aircraft.data import LAWS, LAYOUT
from scenarios.aircraft.loop import tas_from_mach


def _flight():
    """Six flight points spread over the realistic envelope (160-300 kt, 8 000-38 000 ft,
    120-233 t, CG 17-41 %), as the laws' flight dictionary."""
    alt = np.array([8000.0, 15000.0, 28000.0, 38000.0, 20000.0, 33000.0])
    vcas = np.array([160.0, 250.0, 300.0, 220.0, 280.0, 180.0])
    mass = np.array([120.0, 233.0, 180.0, 150.0, 210.0, 130.0])
    cg = np.array([17.0, 41.0, 30.0, 25.0, 35.0, 20.0])
    fc = envelope.flight_condition(alt, vcas, mass, cg)
    return {"mass_t": mass, "cg_pct": cg, "mach": fc["mach"], "qbar_pa": fc["qbar_pa"],
            "tas_ms": tas_from_mach(fc["mach"], alt)}


@pytest.fixture(scope="module")
def nominal():
    return lpv.run_models(_flight(), 0.0)


@pytest.mark.parametrize("changes", [{}, {"pitch_zeta": 0.6, "pitch_integral": 1.5,
                                          "pitch_cap": 0.4, "pitch_omega_max": 2.5}])
def test_the_pitch_gains_place_the_documented_poles(nominal, changes):
    """On α̇ = a11·α + a12·q, q̇ = a21·α + a22·q + b·δe, ż = n_α·α and
    δe = −k_n·n_α·α − k_q·q − k_i·z, the characteristic polynomial is
    (s² + 2ζω_sp·s + ω_sp²)(s + a) with ω_sp = sqrt(CAP·n_α) clipped to [ω_min, ω_max]:
    LAWS (ζ = 0.7, a = 1 rad/s, CAP = 0.3, 1-2 rad/s) and other values (a ≠ 1, so a product
    and a quotient by a differ); 1e-9 relative on each coefficient."""
    laws_p = replace(LAWS, **changes)
    g = laws.gains(nominal, laws_p)
    A, B, C = nominal.A, nominal.B, nominal.C
    b = B[:, lpv.IQ, 0] + B[:, lpv.IQ, 1]                    # both elevators
    n_alpha = C[:, 0, lpv.IA]
    w = np.clip(np.sqrt(laws_p.pitch_cap * n_alpha), laws_p.pitch_omega_min,
                laws_p.pitch_omega_max)
    np.testing.assert_allclose(g.omega_sp, w, rtol=1e-15)
    z, a = laws_p.pitch_zeta, laws_p.pitch_integral
    for i in range(len(b)):
        M = np.array([[A[i, lpv.IA, lpv.IA], A[i, lpv.IA, lpv.IQ], 0.0],
                      [A[i, lpv.IQ, lpv.IA] - b[i] * g.k_n[i] * n_alpha[i],
                       A[i, lpv.IQ, lpv.IQ] - b[i] * g.k_q[i], -b[i] * g.k_i[i]],
                      [n_alpha[i], 0.0, 0.0]])
        want = np.polymul([1.0, 2 * z * w[i], w[i] ** 2], [1.0, a])
        np.testing.assert_allclose(np.poly(M), want, rtol=1e-9, err_msg=str(i))


def test_the_short_period_frequency_is_scheduled_on_cap_and_clipped():
    """ω_sp = sqrt(CAP·n_α), CAP = 0.3, within [1, 2] rad/s: n_α = 2, 5, 10, 20 g/rad give
    1 (clipped), sqrt(1.5), sqrt(3) and 2 (clipped)."""
    np.testing.assert_array_equal(laws.short_period_omega(np.array([2.0, 5.0, 10.0, 20.0])),
                                  [1.0, math.sqrt(1.5), math.sqrt(3.0), 2.0])
    assert laws.short_period_omega(1.0 / 0.3 * 4.0) == 2.0          # exactly at ω_max
    assert laws.short_period_omega(1.0 / 0.3) == pytest.approx(1.0)  # exactly at ω_min


def test_the_roll_and_yaw_gains_are_the_nominal_derivatives(nominal):
    """L_p = ∂ṗ/∂p; L_δa = the roll order's effect: right ailerons +, left −, spoilers +;
    N_δr the rudder's; n̂_δ the two elevators' direct lift; TAS the model's."""
    g = laws.gains(nominal)
    B, D = nominal.B, nominal.D
    names = LAYOUT.names
    col = {n: i for i, n in enumerate(names)}
    roll = sum((1.0 if n.startswith("right") else -1.0) * B[:, lpv.IP, col[n]]
               for n in names if "aileron" in n) + B[:, lpv.IP, len(names)]
    np.testing.assert_allclose(g.L_da, roll, rtol=1e-14)
    np.testing.assert_array_equal(g.L_p, nominal.A[:, lpv.IP, lpv.IP])
    np.testing.assert_array_equal(g.N_dr, B[:, lpv.IR, col["rudder"]])
    np.testing.assert_allclose(g.nz_de, D[:, 0, col["left_elevator"]]
                               + D[:, 0, col["right_elevator"]], rtol=1e-14)
    np.testing.assert_array_equal(g.tas_ms, nominal.tas_ms)


def test_distributed_sums_the_weighted_columns_in_order():
    cols = np.array([[1.0, 2.0, 4.0], [3.0, -1.0, 0.5]])
    np.testing.assert_array_equal(laws.distributed(cols, np.array([2.0, 0.0, -1.0])),
                                  [2.0 - 4.0, 6.0 - 0.5])


def test_filters_rate_limits_and_turn_load_factor():
    """c = 1 − exp(−Ts/τ) (eq. 4.8) for the pitch (0.1 s), roll (0.05 s) and yaw (0.2 s)
    filters; the rate limiter of eq. 4.9; the order steps at Ts = 0.01 s (24, 28, 26 °/s);
    1/cos φ − 1 with φ clipped at 33°."""
    assert laws.filter_coefficient(0.1, 0.01) == 1.0 - math.exp(-0.01 / 0.1)
    assert laws.filter_coefficients(0.01) == (1.0 - math.exp(-0.01 / 0.1),
                                              1.0 - math.exp(-0.01 / 0.05),
                                              1.0 - math.exp(-0.01 / 0.2))
    np.testing.assert_array_equal(laws.rate_limit(np.array([1.0, 1.0, 1.0]),
                                                  np.array([3.0, 1.2, -2.0]), 0.5),
                                  [1.5, 1.2, 0.5])
    steps, spoiler = laws.order_steps(0.01)
    np.testing.assert_allclose(steps, [0.24, 0.24, 0.28, 0.28, 0.28, 0.28, 0.26], rtol=1e-14)
    assert spoiler == pytest.approx(math.radians(28.0) * 0.01, rel=1e-15)
    phi = np.radians(np.array([-40.0, 20.0, 33.0, 50.0]))
    want = 1.0 / np.cos(np.radians([-33.0, 20.0, 33.0, 33.0])) - 1.0
    np.testing.assert_allclose(laws.turn_load_factor(phi), want, rtol=1e-15)


@pytest.mark.parametrize("changes", [{}, {"yaw_damping": 1.3, "sideslip_gain": 0.8,
                                          "sideslip_integral": 0.4, "bank_gain": 0.6,
                                          "roll_bandwidth": 2.5, "pitch_filter_s": 0.12,
                                          "roll_filter_s": 0.06, "yaw_filter_s": 0.25,
                                          "bank_max_deg": 30.0}])
def test_one_fcc_period_by_hand(changes):
    """docs/aircraft.md §4.1-4.3 on one period from a non-zero state, two runs (the second
    with its elevator order limited: no integration), with LAWS and with other values (no
    gain of 1, so a product and a quotient by a gain differ)."""
    L = replace(LAWS, **changes)
    g = laws.Gains(k_n=np.array([0.2, 0.3]), k_q=np.array([0.5, 0.4]),
                   k_i=np.array([0.1, 0.15]), L_p=np.array([-1.2, -0.8]),
                   L_da=np.array([2.0, 3.0]), N_dr=np.array([-1.5, -2.5]),
                   nz_de=np.array([0.05, 0.07]), tas_ms=np.array([200.0, 150.0]),
                   omega_sp=np.array([1.5, 1.2]))
    s0 = dict(z_pitch=np.array([0.3, -0.2]), phi_ref=np.array([0.1, 0.05]),
              z_beta=np.array([0.02, -0.01]), nz_f=np.array([0.4, 0.1]),
              q_f=np.array([0.01, -0.02]), p_f=np.array([0.03, 0.0]),
              r_f=np.array([0.005, 0.01]), beta_f=np.array([0.002, -0.003]))
    state = laws.LawState(**{k: v.copy() for k, v in s0.items()})
    meas = {"dnz": np.array([0.5, -0.3]), "de": np.array([0.02, -0.01]),
            "q": np.array([0.02, 0.01]), "p": np.array([0.05, -0.04]),
            "phi": np.array([0.2, 0.7]), "r": np.array([0.01, 0.02]),
            "beta": np.array([0.004, 0.001])}
    nz_c, p_c, beta_c = np.array([0.1, 0.0]), np.array([0.02, -0.1]), np.array([0.0, 0.001])
    ts = 0.01
    clipped = np.array([False, True])
    de, da, dr = laws.step(state, meas, nz_c, p_c, beta_c, g, ts, clipped, L)
    cp, cr, cy = ((1 - math.exp(-ts / L.pitch_filter_s)), (1 - math.exp(-ts / L.roll_filter_s)),
                  (1 - math.exp(-ts / L.yaw_filter_s)))
    nz_f = s0["nz_f"] + cp * (meas["dnz"] - g.nz_de * meas["de"] - s0["nz_f"])
    q_f = s0["q_f"] + cp * (meas["q"] - s0["q_f"])
    want_de = -g.k_n * nz_f - g.k_q * q_f - g.k_i * s0["z_pitch"]
    z = s0["z_pitch"] + np.array([ts * (0.5 - 0.1), 0.0])
    phi_ref = s0["phi_ref"] + ts * p_c
    p_dem = p_c + L.bank_gain * (phi_ref - meas["phi"])
    p_f = s0["p_f"] + cr * (meas["p"] - s0["p_f"])
    want_da = (L.roll_bandwidth * (p_dem - p_f) - g.L_p * p_f) / g.L_da
    bank = math.radians(L.bank_max_deg)
    phi_c = np.clip(meas["phi"], -bank, bank)                   # run 2: 0.7 rad, beyond it
    r_turn = 9.80665 * np.sin(phi_c) / g.tas_ms
    r_f = s0["r_f"] + cy * (meas["r"] - s0["r_f"])
    beta_f = s0["beta_f"] + cy * (meas["beta"] - s0["beta_f"])
    e_beta = beta_f - beta_c
    want_dr = (-L.yaw_damping * (r_f - r_turn) + L.sideslip_gain * e_beta
               + L.sideslip_integral * s0["z_beta"]) / g.N_dr
    for got, want in ((de, want_de), (da, want_da), (dr, want_dr), (state.nz_f, nz_f),
                      (state.q_f, q_f), (state.z_pitch, z), (state.phi_ref, phi_ref),
                      (state.p_f, p_f), (state.r_f, r_f), (state.beta_f, beta_f),
                      (state.z_beta, s0["z_beta"] + ts * e_beta)):
        np.testing.assert_allclose(got, want, rtol=1e-13, atol=1e-17)
    assert LAWS.bank_max_deg == 33.0 and laws.LawState.zeros(3).p_f.tolist() == [0.0] * 3


def test_the_loop_matrices_by_hand(nominal):
    """pitch_loop_matrix on [α, q, F(Δn_z − n̂_δ·δe), F(q), z, δe] and roll_loop_matrix on
    [p, F(p), δa] (docs/aircraft.md §4.5), entry by entry, for a model flown with
    aerodynamic draws (so n_δ ≠ n̂_δ) and gains placed on the nominal one."""
    flown = lpv.run_models(_flight(), 0.05)
    g = laws.gains(nominal)
    M = laws.pitch_loop_matrix(flown, g, servo_bandwidth_per_s=15.0)
    A, B, C, D = flown.A, flown.B, flown.C, flown.D
    tau, bw = 0.1, 15.0
    ba, bq = B[:, lpv.IA, 0] + B[:, lpv.IA, 1], B[:, lpv.IQ, 0] + B[:, lpv.IQ, 1]
    na, nd = C[:, 0, lpv.IA], D[:, 0, 0] + D[:, 0, 1]
    W = np.zeros_like(M)
    W[:, 0, [0, 1, 5]] = np.stack([A[:, lpv.IA, lpv.IA], A[:, lpv.IA, lpv.IQ], ba], 1)
    W[:, 1, [0, 1, 5]] = np.stack([A[:, lpv.IQ, lpv.IA], A[:, lpv.IQ, lpv.IQ], bq], 1)
    W[:, 2, [0, 2, 5]] = np.stack([na / tau, np.full_like(na, -1 / tau), (nd - g.nz_de) / tau], 1)
    W[:, 3, 1], W[:, 3, 3] = 1 / tau, -1 / tau
    W[:, 4, 0], W[:, 4, 5] = na, nd
    W[:, 5, [2, 3, 4, 5]] = np.stack([-bw * g.k_n, -bw * g.k_q, -bw * g.k_i,
                                      np.full_like(na, -bw)], 1)
    assert M.shape == (6, 6, 6)                      # six runs, six states
    np.testing.assert_allclose(M, W, rtol=1e-14, atol=0)
    assert np.abs(nd - g.nz_de).max() > 0
    R = laws.roll_loop_matrix(flown, g, servo_bandwidth_per_s=17.5)
    tau_r = 0.05
    roll = sum(w * B[:, lpv.IP, j] for j, w in enumerate(laws.ROLL_DISTRIBUTION) if w)
    V = np.zeros_like(R)
    V[:, 0, 0], V[:, 0, 2] = A[:, lpv.IP, lpv.IP], roll
    V[:, 1, 0], V[:, 1, 1] = 1 / tau_r, -1 / tau_r
    V[:, 2, 1], V[:, 2, 2] = -17.5 * (3.0 + g.L_p) / g.L_da, -17.5
    assert R.shape == (6, 3, 3)                      # six runs, three states
    np.testing.assert_allclose(R, V, rtol=1e-14, atol=0)


def test_the_dominant_pair_is_the_lowest_frequency_complex_pair():
    ev = np.array([[-1.0 + 2.0j, -1.0 - 2.0j, -0.3 + 0.4j, -0.3 - 0.4j, -5.0],
                   [-2.0, -3.0, -0.1, -4.0, -6.0]])
    w, z = laws.dominant_pair(ev)
    assert w[0] == pytest.approx(0.5) and z[0] == pytest.approx(0.6)
    assert np.isnan(w[1]) and np.isnan(z[1])


def test_the_order_distributions_by_value():
    """docs/aircraft.md §4: the pitch order drives both elevators, the roll order the
    ailerons antisymmetrically (right +1, left −1) and the spoilers (+1, one input of the
    model), the yaw order the rudder; the two gust inputs of the model are not orders. The
    columns are lpv's inputs: the seven surfaces of LAYOUT, the spoilers, α_g, β_g."""
    assert list(LAYOUT.names) == ["left_elevator", "right_elevator", "left_inboard_aileron",
                                  "right_inboard_aileron", "left_outboard_aileron",
                                  "right_outboard_aileron", "rudder"]
    assert (lpv.I_SPOILER, lpv.I_GUST_ALPHA, lpv.I_GUST_BETA) == (7, 8, 9)
    assert laws.PITCH_DISTRIBUTION.tolist() == [1, 1, 0, 0, 0, 0, 0, 0, 0, 0]
    assert laws.ROLL_DISTRIBUTION.tolist() == [0, 0, -1, 1, -1, 1, 0, 1, 0, 0]
    assert laws.YAW_DISTRIBUTION.tolist() == [0, 0, 0, 0, 0, 0, 1, 0, 0, 0]


def test_the_gains_are_frozen(nominal):
    """A run's gains are placed once, from the measured point: nothing changes them during
    the run."""
    g = laws.gains(nominal)
    with pytest.raises(AttributeError):
        g.k_n = g.k_n * 2.0


def test_a_pair_is_complex_beyond_a_nanoradian_per_second():
    """dominant_pair counts an eigenvalue as part of a complex pair when |Im| > 1e-9 rad/s,
    strictly: a pair at exactly 1e-9 (a real double root split by round-off) is a real
    mode, and the pair of the row is the next one."""
    ev = np.array([[-1.0 + 1e-9j, -1.0 - 1e-9j, -2.0 + 3.0j, -2.0 - 3.0j]])
    w, z = laws.dominant_pair(ev)
    assert w[0] == pytest.approx(math.sqrt(13.0), rel=1e-15)
    assert z[0] == pytest.approx(2.0 / math.sqrt(13.0), rel=1e-15)
