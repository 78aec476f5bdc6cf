"""Dryden turbulence: intensity table, exact discretisation, statistics, stationarity."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.signal import cont2discrete, lfilter

from scenarios.params import parameter_table
from scenarios.turbulence import (
    MODERATE,
    _lagged_initial_state,
    _stationary_state_factor,
    dryden_filters,
    dryden_gusts,
    lagged_gust,
)

TS = 0.01


def _autocorr(x: np.ndarray, max_lag: int) -> np.ndarray:
    """Normalised sample autocorrelation ρ(k), k = 0..max_lag (FFT, unbiased per lag)."""
    x = x - x.mean()
    n = x.size
    spec = np.fft.rfft(x, 2 * n)
    acov = np.fft.irfft(spec * np.conj(spec))[: max_lag + 1] / (n - np.arange(max_lag + 1))
    return acov / acov[0]


def _dryden_records(n_records=4, seconds=2000.0, tas=250.0, alt=28000.0, seed=7):
    rng = np.random.default_rng(seed)
    n = int(seconds / TS)
    return np.array([dryden_gusts(n, TS, tas, alt, rng) for _ in range(n_records)])


@pytest.fixture(scope="module")
def records():
    return _dryden_records()


# ---- the parameter table -------------------------------------------------------------
def test_sigma_table_interpolates_and_clamps():
    assert MODERATE.sigma_ms(8000) == pytest.approx(3.0)
    assert MODERATE.sigma_ms(28000) == pytest.approx(1.9)
    assert MODERATE.sigma_ms(13000) == pytest.approx(0.5 * (3.0 + 2.3))
    assert MODERATE.sigma_ms(33000) == pytest.approx(0.5 * (1.9 + 1.45))
    assert MODERATE.sigma_ms(0.0) == pytest.approx(3.0)       # clamped below the table
    assert MODERATE.sigma_ms(45000.0) == pytest.approx(1.45)  # clamped above
    assert MODERATE.scale_length_m == pytest.approx(1750 * 0.3048)


def test_every_parameter_has_unit_and_source():
    for row in parameter_table(MODERATE):
        assert row["unit"] and row["source"], row["name"]


@pytest.mark.parametrize("changes", [
    {"alt_table_ft": (8000.0, 8000.0), "sigma_table_ms": (1.0, 1.0)},
    {"sigma_table_ms": (3.0, 2.3, 1.9)},
    {"sigma_table_ms": (3.0, -1.0, 1.9, 1.45)},
    {"scale_length_ft": 0.0},
])
def test_invalid_dryden_params_are_rejected(changes):
    with pytest.raises(ValueError):
        dataclasses.replace(MODERATE, **changes)


# ---- discretisation ---------------------------------------------------------------------
@pytest.mark.parametrize("tas, ts", [(80.0, 0.01), (250.0, 0.01), (150.0, 0.002)])
def test_closed_form_zoh_equals_cont2discrete(tas, ts):
    f = dryden_filters(tas, ts)
    T = f.time_constant_s
    assert T == pytest.approx(MODERATE.scale_length_m / tas)
    cases = [(f.u, ([1.0], [T, 1.0])),
             (f.vw, ([math.sqrt(3.0) * T, 1.0], [T * T, 2.0 * T, 1.0]))]
    for filt, (num, den) in cases:
        bd, ad, _ = cont2discrete((num, den), ts, method="zoh")
        bd = bd.ravel()
        np.testing.assert_allclose(filt.a, ad, rtol=1e-12, atol=1e-15)
        assert filt.b[0] == 0.0 and abs(bd[0]) < 1e-15
        # same zeros: the coefficients differ only by the unit-variance gain
        ratio = filt.b[1:] / bd[1:]
        np.testing.assert_allclose(ratio, ratio[0], rtol=1e-8)


@pytest.mark.parametrize("tas", [60.0, 250.0])
def test_filters_have_unit_variance(tas):
    # Σ h_k² of the impulse response is the stationary variance for unit white noise;
    # 40 time constants of record leave a tail below 1e-30.
    f = dryden_filters(tas, TS)
    impulse = np.zeros(int(40 * f.time_constant_s / TS))
    impulse[0] = 1.0
    for filt in (f.u, f.vw):
        h = lfilter(filt.b, filt.a, impulse)
        assert math.fsum(h * h) == pytest.approx(1.0, rel=1e-9)


def _df2t(b, a):
    """lfilter's state-space (transposed direct form II), for independent checks."""
    n = a.size - 1
    A = np.zeros((n, n))
    A[:, 0] = -a[1:]
    A[:-1, 1:] += np.eye(n - 1)
    return A, b[1:] - a[1:] * b[0]


@pytest.mark.parametrize("tas", [80.0, 250.0])
def test_initial_state_covariances_solve_the_lyapunov_equation(tas):
    f = dryden_filters(tas, TS)
    for filt in (f.u, f.vw):
        S = _stationary_state_factor(filt)
        A, B = _df2t(filt.b, filt.a)
        P = S @ S.T
        # residual of P = A·P·Aᵀ + B·Bᵀ, relative to P's unit scale
        np.testing.assert_allclose(A @ P @ A.T + np.outer(B, B), P, atol=1e-12)
    # the lagged cascade: zi = M·xi is linear in the normals, so cov(zi) = M·Mᵀ exactly
    gamma = math.exp(-TS / 0.5)
    beta = 1.0 - gamma
    for filt in (f.u, f.vw):
        n = filt.a.size
        M = np.column_stack([_lagged_initial_state(filt, beta, gamma, e) for e in np.eye(n)])
        b = np.convolve(filt.b, [0.0, beta])
        a = np.convolve(filt.a, [1.0, -gamma])
        A, B = _df2t(b, a)
        P = M @ M.T
        scale = np.sqrt(np.outer(np.diag(P), np.diag(P)))
        np.testing.assert_allclose((A @ P @ A.T + np.outer(B, B)) / scale, P / scale, atol=1e-9)
        # y[n] = zc₀[n−1] (b[0] = 0): P₀₀ is the output variance Σ h_k² of the cascade
        impulse = np.zeros(int(40 * f.time_constant_s / TS))
        impulse[0] = 1.0
        h = lfilter(b, a, impulse)
        assert P[0, 0] == pytest.approx(math.fsum(h * h), rel=1e-6)


# ---- statistics -------------------------------------------------------------------------
def test_gust_std_matches_sigma(records):
    # 4 records × 2000 s at T = L/V ≈ 2.1 s: the relative standard error of each std is
    # ≈ sqrt(T/(2·2000 s)) ≈ 2.3 %, about 1.2 % for the pooled value: 10 % is > 4σ per
    # record, and a wrong gain (e.g. continuous σ·sqrt(2L/V) without 1/sqrt(ts)) fails.
    sigma = MODERATE.sigma_ms(28000)
    per_record = records.std(axis=2)
    np.testing.assert_allclose(per_record, sigma, rtol=0.10)
    np.testing.assert_allclose(records.std(axis=(0, 2)), sigma, rtol=0.05)
    assert np.abs(records.mean(axis=2)).max() < 0.2 * sigma


def test_u_correlation_time_is_L_over_V(records):
    # R_u(τ) = σ²·exp(−τ/T): the lag where ρ = 1/e estimates T. Standard error of ρ(T)
    # from 4 × 2000 s ≈ 0.013 → ≈ 3.5 % on T; 20 % is ≈ 6σ, while L or V off by 1.5× fails.
    T = MODERATE.scale_length_m / 250.0
    lag = int(round(T / TS))
    rho = np.mean([_autocorr(r[0], lag) for r in records], axis=0)
    T_hat = -T / math.log(rho[lag])
    assert T_hat == pytest.approx(T, rel=0.20)


@pytest.mark.parametrize("row", [1, 2])
def test_v_w_autocorrelation_is_dryden(records, row):
    # R_w(τ)/σ² = (1 − τ/(2T))·exp(−τ/T) (MIL-HDBK-1797). Standard error of each pooled
    # ρ ≈ 0.015; 0.05 is > 3σ, while the first-order shape exp(−τ/T) is off by 0.18 at τ = T.
    T = MODERATE.scale_length_m / 250.0
    lags = np.array([0.5, 1.0, 2.0, 3.0]) * T
    k = np.round(lags / TS).astype(int)
    rho = np.mean([_autocorr(r[row], k.max()) for r in records], axis=0)[k]
    tau = k * TS
    expected = (1.0 - tau / (2.0 * T)) * np.exp(-tau / T)
    np.testing.assert_allclose(rho, expected, atol=0.05)


def test_components_are_uncorrelated(records):
    # independent noises: |ρ| at lag 0 has a standard error ≈ 0.02 per 2000 s record
    for i, j in [(0, 1), (0, 2), (1, 2)]:
        r = np.mean([np.corrcoef(rec[i], rec[j])[0, 1] for rec in records])
        assert abs(r) < 0.08


def test_gusts_are_stationary_from_the_first_sample():
    # T = L/V ≈ 6.7 s at 80 m/s: a filter started at rest would have std ≈ 0 at t = 0
    # and reach ≈ 26 % of σ after 1 s. 3000 runs: the std over runs has a relative
    # standard error of 1.3 %, so 7 % is > 5σ.
    rng = np.random.default_rng(11)
    sigma = MODERATE.sigma_ms(8000)
    samples = np.array([dryden_gusts(101, TS, 80.0, 8000.0, rng)[:, [0, 1, 100]]
                        for _ in range(3000)])
    np.testing.assert_allclose(samples.std(axis=0), sigma, rtol=0.07)


def test_lagged_gust_variance_matches_the_continuous_spectrum():
    # Var = (1/π)∫₀^∞ Φ_w(ω)/(1 + τ²ω²) dω with Φ_w = σ²T(1 + 3T²ω²)/(1 + T²ω²)²:
    # an independent check of gain, filter and lag together. 4 × 1000 s at T ≈ 2.1 s
    # give ≈ 2 % standard error on the std; 8 % tolerance.
    tas, alt, lag = 250.0, 28000.0, 0.5
    sigma, T = MODERATE.sigma_ms(alt), MODERATE.scale_length_m / tas

    def phi(w):
        return sigma**2 * T * (1 + 3 * (T * w) ** 2) / (1 + (T * w) ** 2) ** 2

    var, _ = quad(lambda w: phi(w) / (1 + (lag * w) ** 2), 0, np.inf)
    rng = np.random.default_rng(3)
    x = np.concatenate([lagged_gust(100_000, TS, tas, alt, rng, component="w", lag_s=lag)
                        for _ in range(4)])
    assert x.std() == pytest.approx(math.sqrt(var / math.pi), rel=0.08)
    # no lag: the gust itself
    x = np.concatenate([lagged_gust(100_000, TS, tas, alt, rng, component="u") for _ in range(4)])
    assert x.std() == pytest.approx(sigma, rel=0.08)


@pytest.mark.parametrize("component", ["u", "w"])
def test_lagged_gust_is_stationary_from_the_first_sample(component):
    # same argument as for the gusts; the reference is the std at 3 s (> 6 lag constants)
    rng = np.random.default_rng(5)
    s = np.array([lagged_gust(301, TS, 80.0, 8000.0, rng, component=component, lag_s=0.5)[[0, 300]]
                  for _ in range(3000)])
    std0, std_late = s.std(axis=0)
    assert std0 == pytest.approx(std_late, rel=0.07)


# ---- determinism and errors ----------------------------------------------------------
def test_deterministic_for_a_generator_state():
    a = dryden_gusts(500, TS, 200.0, 18000.0, np.random.default_rng(42))
    b = dryden_gusts(500, TS, 200.0, 18000.0, np.random.default_rng(42))
    c = dryden_gusts(500, TS, 200.0, 18000.0, np.random.default_rng(43))
    assert a.shape == (3, 500)
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)
    # a fixed number of draws: 5 initial-state normals + 3·n_steps
    rng, ref = np.random.default_rng(1), np.random.default_rng(1)
    dryden_gusts(500, TS, 200.0, 18000.0, rng)
    ref.standard_normal(5 + 3 * 500)
    assert rng.random() == ref.random()


@pytest.mark.parametrize("kwargs, exc", [
    ({"tas_ms": 0.0}, ValueError),
    ({"tas_ms": float("nan")}, ValueError),
    ({"ts": -0.01}, ValueError),
    ({"n_steps": 0}, ValueError),
    ({"alt_ft": float("inf")}, ValueError),
    ({"rng": 42}, TypeError),
])
def test_bad_inputs_raise(kwargs, exc):
    args = {"n_steps": 10, "ts": TS, "tas_ms": 200.0, "alt_ft": 10000.0,
            "rng": np.random.default_rng(0)}
    args.update(kwargs)
    with pytest.raises(exc):
        dryden_gusts(**args)


def test_lagged_gust_bad_options_raise():
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="allowed: u, v, w"):
        lagged_gust(10, TS, 200.0, 1e4, rng, component="x")
    with pytest.raises(ValueError, match="lag_s"):
        lagged_gust(10, TS, 200.0, 1e4, rng, lag_s=-1.0)


def test_calm_air_on_the_aircraft_plant():
    """``[plant] turbulence = "none"`` (docs/physics.md §7.2, [CHEN] footnote 1): the plant of
    the campaign flies without gusts. In cruise with no pilot input, what moves the roll rate
    is then only the sensor noise (σ = 0.02 deg/s, docs/physics.md §7) and its echo through
    the laws, while moderate turbulence rolls the aircraft by tenths of a degree per second:
    a factor 5 between the two standard deviations is far inside that gap."""
    from campaign.config import CampaignConfig
    from campaign.plant_setup import plant_of
    from scenarios.simulate import single_run

    def plant(level):
        return plant_of(CampaignConfig.from_dict({
            "campaign": {"name": "calm", "surface": "aileron"},
            "plant": {"kind": "aircraft", "turbulence": level},
            "group": [{"fault": "none", "count": 1}],
            "detector": [{"name": "position-monitor"}]}))

    assert plant("none").turbulence == "none" and plant("moderate").turbulence == "moderate"
    runs = single_run("aileron", "cruise", duration_s=20.0)
    runs["surface"] = "left_inboard_aileron"
    p_std = {level: float(np.std(plant(level).simulate(runs)[0].aircraft["p"][0, 500:]))
             for level in ("none", "moderate")}
    assert p_std["moderate"] > 5.0 * p_std["none"], p_std


@pytest.mark.parametrize("component, lag_s", [("w", 0.5), ("v", 0.3), ("u", 0.7), ("w", 0.0),
                                                ("u", 0.0)])
def test_compiled_gust_is_lfilter_of_the_generators_normals_bit_for_bit(component, lag_s):
    """The compiled gust (:func:`scenarios.compiled.filtered_normals_1`: each normal drawn
    and filtered as it comes) equals ``lfilter`` of ``rng.standard_normal`` bit for bit,
    for the order-1 (u) and order-2 (v, w) forming filters with and without the lag, over
    80 airspeeds and seeds, and leaves each generator in the same state."""
    for seed in range(80):
        ref_rng, rng = np.random.default_rng(seed), np.random.default_rng(seed)
        tas = 60.0 + 3.0 * seed
        ref = lagged_gust(3000, TS, tas, 2000.0 + 150.0 * seed, ref_rng, component=component,
                          lag_s=lag_s, engine="numpy")
        got = lagged_gust(3000, TS, tas, 2000.0 + 150.0 * seed, rng, component=component,
                          lag_s=lag_s, engine="compiled")
        np.testing.assert_array_equal(got, ref, err_msg=f"seed {seed}")
        assert rng.bit_generator.state == ref_rng.bit_generator.state
