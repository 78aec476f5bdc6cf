"""The evidence figures' specs by value (campaign/evidence/figures.py, docs/evidence.md):
which rows each figure takes, the manoeuvre whose tail is drawn, the tail fit of the
certificate's curve (ξ ≥ 0), the Kaplan–Meier curves per fault type with their misses
censored and the required detection times. No simulation: result rows as a campaign forms
them (``run_id``, ``detector``, ``fault``, ``manoeuvre``, ``status``, ``margin``,
``detected``, ``delay_s``), built by hand."""

from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from campaign.evidence.certify.levels import EXTRAPOLATION_DECADES
from campaign.evidence.figures import _curve_specs, _tail_specs, evidence_figure_specs
from detectors.tail import CURVE_SHAPES, MIN_TAIL_FIT_RUNS, fit_tail
from reports.scoring.quantiles import gpd_plotting_quantiles
from reports.scoring.survival import kaplan_meier


def _free_rows(detector, manoeuvre, margins, start=0):
    n = len(margins)
    return pd.DataFrame({"run_id": [f"r{start + i}" for i in range(n)],
                         "detector": detector, "fault": "none", "manoeuvre": manoeuvre,
                         "status": "ok", "margin": np.asarray(margins, float),
                         "detected": False, "delay_s": np.nan})


def _faulty_rows(detector, fault, delays, start=1000):
    """Faulty rows: a NaN delay is a missed fault (not detected)."""
    delays = np.asarray(delays, float)
    n = delays.size
    return pd.DataFrame({"run_id": [f"f{start + i}" for i in range(n)],
                         "detector": detector, "fault": fault, "manoeuvre": "m",
                         "status": "ok", "margin": np.nan, "detected": np.isfinite(delays),
                         "delay_s": delays})


def _campaign(results, levels=None, required=()):
    cert = None if levels is None else SimpleNamespace(levels=levels)
    config = SimpleNamespace(requirements=SimpleNamespace(detection_time_s=tuple(required)))
    return SimpleNamespace(results=results, certificate=cert, config=config)


def _curve(detector="d", levels=(1.0, 0.9), tail_class=None, confidence=0.95):
    n = len(levels)
    tail_class = ("a",) * n if tail_class is None else tail_class
    return pd.DataFrame({"detector": detector, "level": list(levels),
                         "p_estimate": np.linspace(1e-3, 2e-3, n),
                         "p_upper95": np.linspace(3e-3, 4e-3, n),
                         "confidence": confidence, "tail_class": list(tail_class)})


RNG = np.random.default_rng(2024)
#: two manoeuvres of 80 fault-free margins each: "a" holds the single largest margin,
#: "b" the heavier bulk; both fit (80 ≥ MIN_TAIL_FIT_RUNS)
A = 0.2 * RNG.exponential(size=80)
A[5] = 3.0
B = 0.4 * RNG.exponential(size=80)


# ---- the exceedance curve -------------------------------------------------------------------
def test_curve_spec_takes_this_detectors_levels_in_order():
    curve = pd.concat([_curve("d", levels=(1.0, 0.9, 0.95)),
                       _curve("e", levels=(0.5,))], ignore_index=True)
    g = _free_rows("d", "a", A)
    (spec,) = _curve_specs("d", g, curve)
    section, group, title, caption, kind, args, kwargs = spec
    assert (section, group, kind) == ("certificate", "d", "exceedance")
    assert title == "Exceedance curve — d" and kwargs == {"title": "d: exceedance curve"}
    level, est, upper, margins = args
    mine = curve[curve["detector"] == "d"].sort_values("level")
    assert list(level) == [0.9, 0.95, 1.0]
    assert list(est) == mine["p_estimate"].tolist()
    assert list(upper) == mine["p_upper95"].tolist()
    np.testing.assert_array_equal(margins, A)
    # the confidence as a percentage, and the decades the curve may go under counting
    assert "certificate's 95 % upper bound" in caption
    assert f"never more than {EXTRAPOLATION_DECADES} decades" in caption


def test_curve_spec_states_another_confidence_in_percent():
    (spec,) = _curve_specs("d", _free_rows("d", "a", A), _curve(confidence=0.99))
    assert "certificate's 99 % upper bound" in spec[3]


def test_no_curve_spec_without_a_curve_or_without_this_detector():
    g = _free_rows("d", "a", A)
    assert _curve_specs("d", g, None) == []
    assert _curve_specs("x", g, _curve("d")) == []


# ---- the tail figures -----------------------------------------------------------------------
def _expected_tail(values):
    return fit_tail(np.asarray(values, float), shapes=CURVE_SHAPES)


def test_tail_specs_fit_the_manoeuvre_of_the_largest_margin_without_a_curve():
    g = pd.concat([_free_rows("d", "a", A), _free_rows("d", "b", B, start=80)])
    me, qq = _tail_specs("d", g, None)
    fit = _expected_tail(A)
    assert me[:3] == ("certificate", "d", "Mean excess — d") and me[4] == "mean_excess"
    np.testing.assert_array_equal(me[5][0], A)
    assert me[5][1] == fit.u
    assert "of a (the manoeuvre of the largest margin)" in me[3]
    assert me[6] == {"title": "d (a): mean excess"}
    assert qq[:3] == ("certificate", "d", "Tail QQ plot — d") and qq[4] == "tail_qq"
    tail, shape, scale = qq[5]
    np.testing.assert_array_equal(tail, fit.tail_values())
    assert (shape, scale) == (fit.shape, fit.scale) and shape >= 0.0
    assert len(tail) == fit.k
    assert f"The {fit.k} largest margins of a" in qq[3] and f"u = {fit.u:.3g}" in qq[3]
    assert qq[6]["title"] == f"d (a): tail QQ (ξ = {fit.shape:.2f})"
    np.testing.assert_allclose(qq[6]["quantiles"],
                               gpd_plotting_quantiles(fit.k, fit.shape, fit.scale), rtol=0)


def test_tail_specs_fit_the_curves_dominant_manoeuvre_at_margin_one_only():
    g = pd.concat([_free_rows("d", "a", A), _free_rows("d", "b", B, start=80)])
    # at level 1 "b" dominates; at 0.9 "a" (not read); another detector's row says "a"
    curve = pd.concat([_curve("d", levels=(0.9, 1.0), tail_class=("a", "b")),
                       _curve("e", levels=(1.0,), tail_class=("a",))], ignore_index=True)
    me, qq = _tail_specs("d", g, curve)
    np.testing.assert_array_equal(me[5][0], B)
    assert me[5][1] == _expected_tail(B).u
    assert "of b (the manoeuvre whose tail dominates the bound at margin 1)" in me[3]
    # a dominant class the rows do not hold (a counted bound: "") falls back to the largest
    for other in ("", "zz"):
        me, _ = _tail_specs("d", g, _curve("d", levels=(1.0,), tail_class=(other,)))
        assert "of a (the manoeuvre of the largest margin)" in me[3]


def test_tail_specs_drop_non_finite_margins_before_choosing_and_fitting():
    a = A.copy()
    b = np.r_[B, np.inf, np.nan]           # an infinite margin must not choose "b"
    g = pd.concat([_free_rows("d", "a", a), _free_rows("d", "b", b, start=80)])
    me, _ = _tail_specs("d", g, None)
    assert "of a (" in me[3]
    g = pd.concat([_free_rows("d", "b", b, start=80)])
    me, _ = _tail_specs("d", g, None)
    np.testing.assert_array_equal(me[5][0], B)     # fitted on the finite ones only


def test_no_tail_specs_when_no_finite_margin_or_too_few_to_fit():
    assert _tail_specs("d", _free_rows("d", "a", [np.nan, np.inf]), None) == []
    few = A[:MIN_TAIL_FIT_RUNS - 1]
    assert _tail_specs("d", _free_rows("d", "a", few), None) == []
    assert len(_tail_specs("d", _free_rows("d", "a", A[:MIN_TAIL_FIT_RUNS]), None)) == 2


# ---- the whole set of a campaign ------------------------------------------------------------
def _results():
    free = pd.concat([_free_rows("d", "a", A), _free_rows("d", "b", B, start=80),
                      _free_rows("c", "a", B, start=200)], ignore_index=True)
    jam = _faulty_rows("d", "jam", [0.5, 1.0, np.nan, 2.0, 1.0])
    runaway = _faulty_rows("d", "runaway", [0.2, np.nan, np.nan], start=2000)
    other = _faulty_rows("c", "jam", [0.7, 0.8], start=3000)
    failed = _faulty_rows("d", "jam", [0.1], start=4000).assign(status="error")
    failed_free = _free_rows("d", "b", [99.0], start=5000).assign(status="error")
    # in the rows: detector d before c, and d's runaway runs before its jam runs
    return pd.concat([free, runaway, jam, other, failed, failed_free], ignore_index=True)


def test_survival_specs_per_detector_and_fault_with_misses_censored():
    res = _results()
    specs = evidence_figure_specs(_campaign(res, required=(("jam", 1.5),)))
    # no certificate: only the survival figures, one per detector, in the rows' order
    assert [(s[0], s[1]) for s in specs] == [("survival", "d"), ("survival", "c")]
    d = specs[0]
    assert d[2] == "Detection delay (Kaplan–Meier) — d" and d[4] == "survival"
    (curves,) = d[5]
    # faults in sorted order (runaway's rows come first); the failed run is not counted
    assert list(curves) == ["jam (1 of 5 missed)", "runaway (2 of 3 missed)"]
    for label, delays, missed in (("jam (1 of 5 missed)", [0.5, 1.0, 2.0, 1.0], 1),
                                  ("runaway (2 of 3 missed)", [0.2], 2)):
        for got, want in zip(curves[label], kaplan_meier(np.array(delays), missed)):
            np.testing.assert_array_equal(got, want)
    # jam: 4 detected of 5 at t = 0.5, 1.0, 1.0, 2.0 → F̂(2.0) = 4/5
    t, f = curves["jam (1 of 5 missed)"][:2]
    assert list(t) == [0.5, 1.0, 2.0] and f[-1] == pytest.approx(0.8, abs=1e-12)
    assert d[6] == {"title": "d: detection delay per fault type",
                    "required": {"jam (1 of 5 missed)": ("jam", 1.5)}}
    (e_curves,) = specs[1][5]
    assert list(e_curves) == ["jam (0 of 2 missed)"]
    assert specs[1][6]["required"] == {"jam (0 of 2 missed)": ("jam", 1.5)}


def test_certificate_specs_come_first_from_the_fault_free_ok_rows():
    res = _results()
    levels = pd.concat([_curve("d", levels=(0.9, 1.0), tail_class=("a", "b")),
                        _curve("c", levels=(1.0,), tail_class=("a",))], ignore_index=True)
    specs = evidence_figure_specs(_campaign(res, levels=levels))
    kinds = [(s[4], s[1]) for s in specs]
    # the detectors in the rows' order (d, then c), not sorted
    assert kinds == [("exceedance", "d"), ("mean_excess", "d"), ("tail_qq", "d"),
                     ("exceedance", "c"), ("mean_excess", "c"), ("tail_qq", "c"),
                     ("survival", "d"), ("survival", "c")]
    # the curve's runs: d's fault-free ok rows (the failed margin 99 left out)
    np.testing.assert_array_equal(specs[0][5][3], np.r_[A, B])
    np.testing.assert_array_equal(specs[1][5][0], B)          # b dominates d at margin 1
    np.testing.assert_array_equal(specs[3][5][3], B)          # c's own rows
    assert specs[-2][6]["required"] == {}


def test_no_figures_without_rows():
    empty = _results().iloc[:0]
    assert evidence_figure_specs(_campaign(empty, levels=_curve())) == []
    # the rows given override the campaign's
    specs = evidence_figure_specs(_campaign(empty), results=_results())
    assert [s[4] for s in specs] == ["survival", "survival"]
