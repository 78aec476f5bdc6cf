"""The model-error allowance b(t) of vanek-geometric (detectors/synthesis/vanek_model_error.py):
that it bounds the residual the Table-2 errors produce through the filter, and how a fitted detector
uses it (τ0 + b(t), and constant thresholds for a detector fitted before it existed)."""

from __future__ import annotations

import numpy as np
import pytest

from detectors.builtin import vanek_geometric as vg
from detectors.synthesis import vanek_model_error as me

TS = 0.01
POINT = {"vcas_kt": 170.0, "alt_ft": 23000.0, "mass_t": 200.0, "cg_pct": 30.0}


def _signals(rng, n_steps=3000):
    """s = [x̃; u] (1, n_steps, 15) [rad]: each channel a sinusoid (0.02–1 Hz, 0.02 rad) plus
    a slow random walk, so that every state and surface moves at once."""
    t = np.arange(n_steps) * TS
    s = np.empty((1, n_steps, 7 + me.N_INPUTS))
    for j in range(s.shape[2]):
        s[0, :, j] = (0.02 * np.sin(2 * np.pi * rng.uniform(0.02, 1.0) * t + rng.uniform(0, 6))
                      + 1e-4 * np.cumsum(rng.normal(size=n_steps)))
    return s


def _path(f):
    return (f.Ad[None], f.Bdist[None], (f.c @ f.Cd)[None], (f.c @ f.Ddist)[None])


@pytest.mark.parametrize("variant", ["lpv", "lti"])
def test_the_allowance_bounds_the_residual_of_the_table2_errors(variant):
    """The aircraft drawn with every Table-2 error at once (random signs, 50–100 % of each
    half-width, and the two all-same-sign corners), the filter designed at the measured point
    (lpv) or at 240 kt / 30 000 ft (lti): the exact part of r̂ the model error produces,
    r̂_d = filter(ΔA x̃ + ΔB u), stays within b(t) at every step. b sums each error's worse
    end, a first-order bound; the products of two errors are what could break it (measured
    worst |r̂_d|/b 0.91 for lpv), so the assertion allows no margin above b at all."""
    rng = np.random.default_rng(11)
    design_at = POINT if variant == "lpv" else {"vcas_kt": 240.0, "alt_ft": 30000.0,
                                                "mass_t": 200.0, "cg_pct": 30.0}
    A, B = vg._model(vg._point(**design_at))
    _, f = vg._design_at(A, B, TS, True, 0.5, 20.0, True)
    K = me.error_matrices(vg._model_at, POINT, (A, B))
    if variant == "lpv":
        assert np.abs(K[0]).max() == 0.0            # designed at the measured point
    s = _signals(rng)
    b = me.bound(K[None], *_path(f), s, None)[0]
    widths = me.table2_widths()
    draws = [{e: rng.choice([-1.0, 1.0]) * w * rng.uniform(0.5, 1.0) for e, w in widths.items()}
             for _ in range(12)]
    draws += [{e: sign * w for e, w in widths.items()} for sign in (-1.0, 1.0)]
    worst = 0.0
    for d in draws:
        true_pt = {k: POINT[k] / (1.0 + d[e]) for e, k in me.SCHEDULE_ERRORS.items()}
        At, Bt = vg._model_at(true_pt, {c: d[c] for c in me.ERRORS[:6]})
        Kt = np.hstack([At - A, (Bt - B)[:, :me.N_INPUTS]])[None, None]
        exact = np.abs(me.bound(Kt, *_path(f), s, None)[0])
        assert exact.max() > 0.05 * b.max()         # the drawn error does reach r̂
        worst = max(worst, float((exact / b)[1:].max()))
    assert worst <= 1.0, worst


def test_error_matrices_rows_are_each_error_at_each_end():
    """Row 1 + 2j (2 + 2j) is the model with error j alone at the lower (upper) end of its
    Table-2 range minus the model at the point: e.g. the rolling-moment error scales the
    roll row's aerodynamic terms by ∓5 % and nothing in the pitch row."""
    from scenarios.aircraft import lpv

    A, B = vg._model(vg._point(**POINT))
    K = me.error_matrices(vg._model_at, POINT, (A, B))
    assert K.shape == (1 + 2 * len(me.ERRORS), lpv.N_STATES, lpv.N_STATES + me.N_INPUTS)
    j = me.ERRORS.index("cl")
    lo, hi = K[1 + 2 * j], K[2 + 2 * j]
    np.testing.assert_allclose(lo, -hi, rtol=1e-9, atol=1e-15)   # linear in the coefficient
    assert np.abs(hi[lpv.IQ]).max() == 0.0 and np.abs(hi[lpv.IP]).max() > 0.0
    # a 10 % VCAS error: q̄ scales by 1/1.1² and 1/0.9², so the two ends are not symmetric
    v = me.ERRORS.index("vcas")
    ratio = np.abs(K[1 + 2 * v]).max() / np.abs(K[2 + 2 * v]).max()
    assert ratio > 1.2, ratio


def test_a_detector_fitted_before_the_allowance_keeps_constant_thresholds():
    """A fitted state without ``adaptive_`` (fitted before the allowance existed) keeps the
    constant thresholds it was fitted with; a fresh detector with the α vane uses τ0 + b(t),
    one without α cannot (the bound needs every state)."""
    old = vg.VanekGeometric()
    old.thresholds_deg_ = {"lti": 1.0, "lpv": 1.0}
    assert not old._bounded()
    assert vg.VanekGeometric()._bounded()
    assert not vg.VanekGeometric(aoa_sensor=False)._bounded()
    assert not vg.VanekGeometric(adaptive=False)._bounded()


@pytest.mark.parametrize("variant", ["lpv", "lti"])
def test_the_allowance_is_computed_on_the_filters_own_layout(variant):
    """The allowance covers the flight point's and Table 2's errors, not the design-model
    choice: for the unison ablation its matrices are the unison model's, in which the left
    and right elevators' columns are the same (no roll from the elevator's arm), so the
    ablation's measured leak is not absorbed by b; on the aircraft's layout the two
    columns differ (the roll of each elevator's lift, docs/physics.md §7.3)."""
    from scenarios.aircraft import lpv
    from scenarios.aircraft.data import LAYOUT

    left, right = (LAYOUT.names.index(s) for s in ("left_elevator", "right_elevator"))
    cols = lpv.N_STATES + np.array([left, right])
    unison = vg.VanekGeometric(design_model="unison")._error_matrices(variant, POINT)
    aircraft = vg.VanekGeometric()._error_matrices(variant, POINT)
    if variant == "lpv":
        assert np.abs(unison[0]).max() == 0.0 and np.abs(aircraft[0]).max() == 0.0
    np.testing.assert_allclose(unison[..., cols[0]], unison[..., cols[1]], rtol=1e-12,
                               atol=1e-15)
    gap = np.abs(aircraft[..., cols[0]] - aircraft[..., cols[1]]).max()
    assert gap > 1e-3 * np.abs(aircraft[..., cols[0]]).max(), gap


def test_the_allowance_terms_sum_to_it_and_vcas_leads_at_the_low_speed_point():
    """``allowance_terms`` splits b(t) into |r̂_0| and one term per Table-2 error; they sum
    to ``allowances`` (the same filters, so to round-off). At [VANEK] §5's low-speed jam
    point (170 kt / 23 000 ft) in moderate turbulence the measured VCAS error's term is the
    largest of the LPV filter's (docs/vanek-geometric.md: 45–58 % of b over the steady part
    of four runs of vanek-scenarios; here 49–53 % at seeds 7–9, the mass term next at
    22–24 %): a 10 % VCAS error is 21 % of q̄, which scales every aerodynamic term of the
    model."""
    from scenarios.plants import simulate
    from scenarios.simulate import single_run

    run = single_run("left_inboard_aileron", "cruise", "none", seed=7, duration_s=30.0,
                     d_vcas=0.05, d_alt=-0.03, **POINT).assign(run_id="low-speed")
    sig, _ = simulate(run, plant="aircraft")
    det = vg.VanekGeometric()
    for variant in ("lpv", "lti"):
        b = det.allowances(sig)[variant]
        terms = det.allowance_terms(sig, variant)
        assert list(terms) == ["design point", *me.ERRORS]
        np.testing.assert_allclose(sum(terms.values()), b, rtol=1e-10, atol=1e-12)
        if variant == "lpv":
            assert np.abs(terms["design point"]).max() == 0.0
    lpv = det.allowance_terms(sig, "lpv")
    steady = {e: float(v[0, 1000:].mean()) for e, v in lpv.items()}
    assert max(steady, key=steady.get) == "vcas", steady
    with pytest.raises(ValueError, match="lpv-affine.*allowed: lti, lpv"):
        det.allowance_terms(sig, "lpv-affine")
