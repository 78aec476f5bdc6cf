"""The report's trade-off figure: for one fault type, each detector's false-alarm bound
against its worst-case detection time at the threshold scales the campaign stores, the
campaign's own operating point (scale 1) marked (docs/thresholds.md, "Other thresholds from
one campaign: tradeoff"). Drawn from the table of :func:`campaign.tradeoff.tradeoff`
(``tradeoff.parquet``'s columns); nothing here reads a file."""

from __future__ import annotations

import numpy as np
import pandas as pd

from .report import SMALL_PT, TITLE_PT, pyplot
from ...scoring.metrics import FAULT_FREE

__all__ = ["tradeoff_figure", "tradeoff_points"]


def tradeoff_points(table: pd.DataFrame, fault: str) -> dict[str, pd.DataFrame]:
    """detector → its points for *fault*, one per scale (ascending): ``scale``, ``dtp_max``
    (worst DTP of the detected runs of that fault type), ``md_count``, ``fa_upper95`` (the
    Clopper–Pearson bound of its fault-free runs) and ``fa_certified`` (``certify``'s bound,
    NaN where it gives none); only detectors with a threshold scale and the scales where
    the detections are known, when there are two or more."""
    out = {}
    for name, g in table.groupby("detector", sort=False):
        if not bool(g["threshold_scale"].iloc[0]):
            continue
        free = g[g["fault"] == FAULT_FREE].set_index("scale")
        hit = g[(g["fault"] == fault) & g["md_rate"].notna()].set_index("scale")
        scales = sorted(set(free.index) & set(hit.index))
        if len(scales) < 2:             # no curve: detections known at one scale only
            continue
        out[str(name)] = pd.DataFrame({
            "scale": scales,
            "dtp_max": hit.loc[scales, "dtp_max"].to_numpy(float),
            "md_count": hit.loc[scales, "md_count"].to_numpy(int),
            "n_runs": hit.loc[scales, "n_runs"].to_numpy(int),
            "fa_upper95": free.loc[scales, "fa_upper95"].to_numpy(float),
            "fa_certified": free.loc[scales, "fa_prob_certified_upper95"].to_numpy(float)})
    return out


def tradeoff_figure(points: dict[str, pd.DataFrame], *, title: str,
                    max_dtp: float | None = None):
    """The figure of :func:`tradeoff_points`: x the worst-case DTP of the detected runs,
    y the per-run false-alarm bound (log), a line per detector through its scales (the
    smallest and the largest labelled), a dotted line through ``certify``'s bounds where it
    gives them, the scale-1 point ringed in black; a scale with missed runs is a hollow
    marker, its misses written beside it; the DTP requirement *max_dtp* as a dashed
    vertical line."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.6, 4.2))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for i, (name, p) in enumerate(points.items()):
        colour = colours[i % len(colours)]
        x, y = p["dtp_max"].to_numpy(float), p["fa_upper95"].to_numpy(float)
        shown = np.isfinite(x) & np.isfinite(y)
        ax.plot(x[shown], y[shown], "-", color=colour, lw=1.2, label=name)
        missed = p["md_count"].to_numpy() > 0
        ax.scatter(x[shown & ~missed], y[shown & ~missed], color=colour, s=22, zorder=3)
        ax.scatter(x[shown & missed], y[shown & missed], facecolors="white",
                   edgecolors=colour, s=26, zorder=3)
        cert = p["fa_certified"].to_numpy(float)
        if np.isfinite(cert[shown]).any():
            ax.plot(x[shown], cert[shown], ":", color=colour, lw=1.2)
        ends = {float(p["scale"].min()), float(p["scale"].max())}
        for xi, yi, s, md, n in zip(x, y, p["scale"], p["md_count"], p["n_runs"]):
            if not (np.isfinite(xi) and np.isfinite(yi)):
                continue
            # the scales at the ends of the line, and the misses of every hollow point
            text = (f"×{s:g}" if s in ends else "") + (f" {md}/{n} missed" if md else "")
            if text:
                ax.annotate(text.strip(), (xi, yi), textcoords="offset points",
                            xytext=(4, 3), fontsize=SMALL_PT - 1, color=colour)
            if s == 1.0:
                ax.scatter([xi], [yi], facecolors="none", edgecolors="black", s=110, lw=1.4,
                           zorder=4)
    if max_dtp is not None and np.isfinite(max_dtp):
        ax.axvline(max_dtp, color="tab:red", ls="--", lw=1, label=f"DTP limit {max_dtp:g}")
    ax.scatter([], [], facecolors="none", edgecolors="black", s=110, lw=1.4,
               label="the campaign's thresholds (×1)")
    ax.set_yscale("log")
    ax.set_xlabel("worst DTP of the detected runs [-]")
    ax.set_ylabel("false-alarm bound per run (95 %) [-]")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=SMALL_PT, loc="upper left", bbox_to_anchor=(1.01, 1.0))  # beside
    ax.set_title(title, fontsize=TITLE_PT)
    return fig
