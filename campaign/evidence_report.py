"""The report's figures of the evidence beyond counting (docs/evidence.md): per detector the
mean-excess and tail QQ plots of the fault-free margins' tail fit (when the directory holds
a certificate, ``fdd-campaign certify``), and the Kaplan–Meier detection-delay curves per
fault type. Figure specs in the form of :func:`campaign.report.build_report`:
(section, group, title, caption, kind, args, kwargs)."""

from __future__ import annotations

import numpy as np

from detectors.tail import TailFitError, fit_tail
from reports.metrics import FAULT_FREE
from reports.survival import kaplan_meier

from .storage import CampaignDir

__all__ = ["evidence_figure_specs"]


def evidence_figure_specs(camp) -> list[tuple]:
    """Figure specs of a loaded campaign (:class:`campaign.report.LoadedCampaign`)."""
    res = camp.results
    if res.empty:
        return []
    ok = res[res["status"].astype(str) == "ok"]
    specs = []
    if CampaignDir(camp.root).read_certificate() is not None:
        free = ok[ok["fault"].astype(str) == FAULT_FREE]
        for name, g in free.groupby("detector", sort=False):
            margins = g["margin"].to_numpy(float)
            margins = margins[np.isfinite(margins)]
            try:
                fit = fit_tail(margins)
            except TailFitError:
                continue
            specs.append((
                "certificate", name, f"Mean excess — {name}",
                "Mean excess of the fault-free margins over a threshold v; above the fit's "
                "threshold u (dashed) a generalised Pareto tail makes it straight.",
                "mean_excess", (margins, fit.u), {"title": f"{name}: mean excess"}))
            specs.append((
                "certificate", name, f"Tail QQ plot — {name}",
                f"The {fit.k} largest margins' excesses over u = {fit.u:.3g} against the "
                "fitted generalised Pareto quantiles: on the diagonal when the tail model "
                "fits.", "tail_qq", (fit.tail_values(), fit.shape, fit.scale),
                {"title": f"{name}: tail QQ (ξ = {fit.shape:.2f})"}))
    faulty = ok[ok["fault"].astype(str) != FAULT_FREE]
    for name, g in faulty.groupby("detector", sort=False):
        curves = {}
        for fault, h in g.groupby("fault", sort=True):
            hit = h["detected"].astype(bool).to_numpy()
            curves[f"{fault} ({int((~hit).sum())} of {len(h)} missed)"] = kaplan_meier(
                h["delay_s"].to_numpy(float)[hit], int((~hit).sum()))
        specs.append((
            "survival", name, f"Detection delay (Kaplan–Meier) — {name}",
            "Share of the faulty runs detected by each delay, misses right-censored at the "
            "end of the window (the curve stops below 1 by their share); band: pointwise "
            "95 % confidence (log-log).", "survival", (curves,),
            {"title": f"{name}: detection delay per fault type"}))
    return specs
