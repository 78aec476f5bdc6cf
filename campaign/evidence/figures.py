"""The report's figures of the evidence beyond counting (docs/evidence.md): per detector the
mean-excess and tail QQ plots of the tail fit of the manoeuvre holding the largest fault-free
margin, as the certificate's exceedance curve fits it (when the directory holds
a certificate, ``fdd-campaign certify``), and the Kaplan–Meier detection-delay curves per
fault type. Figure specs in the form of :func:`campaign.report_build.build_report`:
(section, group, title, caption, kind, args, kwargs)."""

from __future__ import annotations

import numpy as np

from detectors.tail import CURVE_SHAPES, TailFitError, fit_tail
from reports.scoring.metrics import FAULT_FREE
from reports.scoring.quantiles import gpd_plotting_quantiles
from reports.scoring.survival import kaplan_meier

from .certify.levels import EXTRAPOLATION_DECADES

__all__ = ["evidence_figure_specs"]


def _curve_specs(name: str, g, curve) -> list[tuple]:
    """The exceedance-curve figure spec of one detector from ``certificate-levels.parquet``
    (*curve*, None when certify wrote none) and its fault-free rows *g*."""
    if curve is None:
        return []
    mine = curve[curve["detector"] == name].sort_values("level")
    if mine.empty:
        return []
    return [("certificate", name, f"Exceedance curve — {name}",
             f"P(margin ≥ x) per fault-free run: the certificate's "
             f"{100 * float(mine['confidence'].iloc[0]):g} % upper bound at each level "
             "(certificate-levels.parquet: per manoeuvre counted or fitted, never more than "
             f"{EXTRAPOLATION_DECADES} decades under the counting bound) and its estimate "
             "where given, against the share of the campaign's runs at or above x.",
             "exceedance",
             (mine["level"].to_numpy(float), mine["p_estimate"].to_numpy(float),
              mine["p_upper95"].to_numpy(float), g["margin"].to_numpy(float)),
             {"title": f"{name}: exceedance curve"})]


def _tail_specs(name: str, g, curve) -> list[tuple]:
    """Mean-excess and QQ figure specs of one detector's fault-free rows *g*: the tail fit,
    as the certificate's curve fits it (:data:`detectors.tail.CURVE_SHAPES`), of the
    manoeuvre whose term dominates its bound at margin 1 (the ``tail_class`` of *curve*),
    or of the manoeuvre of the largest margin when no fitted tail dominates; none when it
    cannot be fitted."""
    margins = g["margin"].to_numpy(float)
    classes = g["manoeuvre"].to_numpy(str)
    keep = np.isfinite(margins)
    margins, classes = margins[keep], classes[keep]
    if margins.size == 0:
        return []
    dominant = ("" if curve is None else
                str(next(iter(curve.loc[(curve["detector"] == name) & (curve["level"] == 1.0),
                                        "tail_class"]), "")))
    worst = dominant if dominant in set(classes) else classes[int(np.argmax(margins))]
    why = ("the manoeuvre whose tail dominates the bound at margin 1" if worst == dominant
           else "the manoeuvre of the largest margin")
    mine = margins[classes == worst]
    try:
        fit = fit_tail(mine, shapes=CURVE_SHAPES)
    except TailFitError:
        return []
    return [
        ("certificate", name, f"Mean excess — {name}",
         f"Mean excess of the fault-free margins of {worst} ({why}) over a threshold v; "
         "above the fit's threshold u (dashed) a generalised Pareto tail makes it straight.",
         "mean_excess", (mine, fit.u), {"title": f"{name} ({worst}): mean excess"}),
        ("certificate", name, f"Tail QQ plot — {name}",
         f"The {fit.k} largest margins of {worst} as excesses over u = {fit.u:.3g} against "
         "the fitted generalised Pareto quantiles (ξ ≥ 0, as the certificate's curve): on "
         "the diagonal when the tail model fits.", "tail_qq",
         (fit.tail_values(), fit.shape, fit.scale),
         {"title": f"{name} ({worst}): tail QQ (ξ = {fit.shape:.2f})",
          "quantiles": gpd_plotting_quantiles(len(fit.tail_values()), fit.shape,
                                              fit.scale)}),
    ]


def evidence_figure_specs(camp, results=None) -> list[tuple]:
    """Figure specs of a campaign (:class:`campaign.result.Campaign`) from its result rows
    *results* (default :attr:`campaign.result.Campaign.results`; at least ``run_id``,
    ``detector``, ``fault``, ``manoeuvre``, ``status``, ``margin``, ``detected``,
    ``delay_s``)."""
    res = camp.results if results is None else results
    if res.empty:
        return []
    ok = res[res["status"].astype(str) == "ok"]
    specs = []
    if camp.certificate is not None:
        free = ok[ok["fault"].astype(str) == FAULT_FREE]
        curve = camp.certificate.levels
        for name, g in free.groupby("detector", sort=False):
            specs += _curve_specs(name, g, curve)
            specs += _tail_specs(name, g, curve)
    faulty = ok[ok["fault"].astype(str) != FAULT_FREE]
    required_s = dict(camp.config.requirements.detection_time_s)
    for name, g in faulty.groupby("detector", sort=False):
        curves, required = {}, {}
        for fault, h in g.groupby("fault", sort=True):
            hit = h["detected"].astype(bool).to_numpy()
            label = f"{fault} ({int((~hit).sum())} of {len(h)} missed)"
            curves[label] = kaplan_meier(h["delay_s"].to_numpy(float)[hit],
                                         int((~hit).sum()))
            if fault in required_s:
                required[label] = (fault, float(required_s[fault]))
        specs.append((
            "survival", name, f"Detection delay (Kaplan–Meier) — {name}",
            "Share of the faulty runs detected by each delay, misses right-censored at the "
            "end of the window (the curve stops below 1 by their share); band: pointwise "
            "95 % confidence (log-log); dotted: each fault type's required detection time "
            "(the DTP denominator of the campaign file's [requirements]): the curve's "
            "height there is the share detected in time.", "survival", (curves,),
            {"title": f"{name}: detection delay per fault type", "required": required}))
    return specs
