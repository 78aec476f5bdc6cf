"""Figures of the campaign report, drawn from plain arrays and DataFrames (matplotlib, Agg).

Every function returns a matplotlib Figure; :func:`figure_png` turns one into PNG bytes
(trimmed to what is drawn, so no title or legend is cut; palette-compressed). Text is at
least :data:`SMALL_PT` points, which at the report's :data:`REPORT_DPI` is 12 pixels: legible
on a screen where the page shows images at their own size. Nothing here knows how a campaign
is run or stored: the caller passes the numbers.

* :func:`envelope_figure` — one detector's |r|/τ of fault-free runs over time, a panel per
  manoeuvre: band of runs, worst run, threshold line at 1 (the presentation of [CHEN]
  Figs. 3–8);
* :func:`fault_figure` — one fault type across every detector: the DTP distribution of the
  detected runs and the runs in time / late / missed ([CHEN] §5 DTP; [CHEN] Table 4);
* :func:`run_figure` — one run: order, rod, surface, current, every detector's |r|/τ and
  alarm, fault onset (the presentation of [CHEN] Figs. 9–11, [COMB] Figs. 3–5);
* :func:`envelope_map_figure` — a per-run value (margin, DTP) over altitude × VCAS and
  mass × CG, misses marked.
"""

from __future__ import annotations

import io
import textwrap

import numpy as np
import pandas as pd

from ...scoring.quantiles import gpd_plotting_quantiles

__all__ = ["bin_max", "envelope_figure", "envelope_map_figure", "fault_figure",
           "figure_png", "render_png", "run_figure"]

#: Colour of the threshold line |r|/τ = 1 (green, as in [CHEN] Figs. 3–8).
THRESHOLD_COLOUR = "tab:green"
#: Colour of the worst run / the onset marker.
WORST_COLOUR = "tab:red"
#: Resolution of the report's figures [dots per inch]: 100 dpi makes a point 1.39 px.
REPORT_DPI = 100
#: Size of the smallest text (legends, tick labels, annotations) [pt]: 9 pt = 12.5 px at
#: REPORT_DPI, about the size of the page's own table text (13 px).
SMALL_PT = 9
#: Size of axis and figure titles [pt].
TITLE_PT = 11
#: Height of an axes title [axes fraction]: at the top, where matplotlib puts it unless tick
#: labels are above the axes (never in these figures). Given, it spares matplotlib that
#: check at every drawing (the extents of every axes' ticks of the row: a quarter of an
#: envelope figure's drawing).
TITLE_Y = 1.0
#: Colours kept by the palette compression of :func:`figure_png` (the most a PNG palette
#: holds): the figures use about a dozen line colours, their anti-aliased blends and the
#: colour maps of the envelope maps; fewer (64) were seen to merge tab:orange into tab:red
#: and to band the maps' colour scales. The palette PNG is
#: 36 % of the full-colour one (measured on addsafe-mc's report).
PALETTE_COLOURS = 256
#: zlib level of the palette PNGs: 6 (zlib's default) encodes 5–8× faster than 9 (or
#: PIL's ``optimize``) for files 4–9 % larger (measured on addsafe-mc's envelope, run and
#: map figures: 0.03 s instead of 0.11–0.21 s a figure).
PNG_COMPRESS_LEVEL = 6
#: Colour classes of the envelope maps' scale.
MAP_LEVELS = 10


def pyplot():
    """matplotlib.pyplot on the non-interactive Agg back end (imported on first use)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def new_figure(**kwargs):
    """A matplotlib Figure on its own Agg canvas, outside pyplot (no figure manager, nothing
    to close; ``pyplot().close`` of it does nothing), at :data:`REPORT_DPI` unless *kwargs*
    say otherwise; the keywords of :class:`matplotlib.figure.Figure`."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(**{"dpi": REPORT_DPI, **kwargs})
    FigureCanvasAgg(fig)
    return fig


#: Blank margin kept around a figure's drawn content when it is trimmed [in].
PAD_IN = 0.06


def figure_pixels(fig, dpi: int = REPORT_DPI):
    """RGB pixels (PIL image) of *fig* at *dpi*, trimmed to its drawn content plus
    :data:`PAD_IN` of white (as ``savefig(bbox_inches="tight")``: a title or legend that
    reaches past the canvas is kept whole, never cut).

    Drawn once on a white canvas; the content is the box of its pixels that are not white.
    ``savefig(bbox_inches="tight")`` lays the figure out once to find the box and draws it
    again, and encodes a PNG that would be decoded here; that path is taken only when the
    drawing touches the canvas's edge, i.e. may reach past it (the report's figures are
    laid out with room to spare, so that it does not).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from PIL import Image

    canvas = fig.canvas if isinstance(fig.canvas, FigureCanvasAgg) else FigureCanvasAgg(fig)
    fig.set_dpi(dpi)
    fig.set_facecolor("white")
    canvas.draw()
    rgba = np.asarray(canvas.buffer_rgba())                  # rows top to bottom
    rgb = rgba[:, :, :3]
    # not white: one 32-bit comparison a pixel (the canvas is opaque: alpha 255 everywhere)
    drawn = rgba.view(np.uint32)[:, :, 0] != np.frombuffer(b"\xff" * 4, np.uint32)[0]
    rows, cols = np.flatnonzero(drawn.any(axis=1)), np.flatnonzero(drawn.any(axis=0))
    height, width = drawn.shape
    if rows.size and rows[0] > 0 and cols[0] > 0 and rows[-1] < height - 1 \
            and cols[-1] < width - 1:
        pad = int(round(PAD_IN * dpi))
        r0, r1 = max(0, rows[0] - pad), min(height, rows[-1] + 1 + pad)
        c0, c1 = max(0, cols[0] - pad), min(width, cols[-1] + 1 + pad)
        out = np.full((rows[-1] + 1 - rows[0] + 2 * pad, cols[-1] + 1 - cols[0] + 2 * pad, 3),
                      255, np.uint8)              # white where the pad is past the canvas
        top, left = r0 - (rows[0] - pad), c0 - (cols[0] - pad)
        out[top:top + r1 - r0, left:left + c1 - c0] = rgb[r0:r1, c0:c1]
        return Image.fromarray(out)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight", pad_inches=PAD_IN,
                facecolor="white")
    buf.seek(0)
    return Image.open(buf).convert("RGB")


def figure_png(fig, dpi: int = REPORT_DPI) -> bytes:
    """PNG bytes of *fig*, trimmed to its drawn content (:func:`figure_pixels`) and reduced
    to an adaptive palette of :data:`PALETTE_COLOURS` colours; the figure is closed."""
    from PIL import Image

    image = figure_pixels(fig, dpi)
    if getattr(fig.canvas, "manager", None) is not None:      # a figure made with pyplot
        pyplot().close(fig)
    image = image.quantize(colors=PALETTE_COLOURS, method=Image.Quantize.MEDIANCUT,
                           dither=Image.Dither.NONE)
    out = io.BytesIO()
    image.save(out, format="PNG", compress_level=PNG_COMPRESS_LEVEL)
    return out.getvalue()


def bin_max(values: np.ndarray, n_bins: int) -> tuple[np.ndarray, np.ndarray]:
    """Largest value of each run in *n_bins* consecutive time bins, NaN ignored.

    Parameters
    ----------
    values : ndarray (n_runs, n_steps)
    n_bins : wanted number of bins (fewer when there are fewer steps)

    Returns
    -------
    (starts, binned): ``starts`` (n_b,) index of each bin's first step; ``binned``
    (n_runs, n_b) float32, NaN where a bin holds only NaN. Max-pooling keeps every peak, so
    no threshold crossing is hidden by the reduction.
    """
    values = np.asarray(values, dtype=float)
    n_steps = values.shape[1]
    step = max(1, int(np.ceil(n_steps / max(1, n_bins))))
    starts = np.arange(0, n_steps, step)
    filled = np.where(np.isnan(values), -np.inf, values)
    binned = np.maximum.reduceat(filled, starts, axis=1) if n_steps else filled
    binned = np.where(np.isneginf(binned), np.nan, binned)
    return starts, binned.astype(np.float32)


def envelope_figure(t_s: np.ndarray, panels: list, *, title: str):
    """Normalised residual of fault-free runs over time, one panel per manoeuvre.

    Parameters
    ----------
    t_s : ndarray (n_b,) [s] start time of each bin
    panels : list of (heading, binned, worst, worst_label): ``binned`` ndarray (n_runs, n_b)
        [-] per-run max of |r|/τ in each bin (:func:`bin_max`), ``worst`` the index of the
        run to highlight (the largest margin), ``worst_label`` its legend text
    """
    ncols = min(3, len(panels))
    nrows = -(-len(panels) // ncols)
    # the layout in inches (text at SMALL_PT/TITLE_PT): a two-line panel title above each
    # panel, tick labels and axis labels left and below, the suptitle on top and the legend
    # in a strip along the bottom, all inside the canvas (figure_pixels draws it once)
    left, right, top, bottom, legend = 0.62, 0.12, 0.72, 0.48, 0.34
    title_h, wgap = 0.42, 0.2
    # a panel above an empty slot of an incomplete last row shows its time axis
    hgap = title_h + (0.46 if len(panels) % ncols else 0.12)
    width, height = 4.0 * ncols, 2.5 * nrows + 0.5
    ax_h = (height - top - bottom - legend - (nrows - 1) * hgap) / nrows
    if ax_h < 1.2:                               # never squeeze a panel below 1.2 in
        height += (1.2 - ax_h) * nrows
        ax_h = 1.2
    ax_w = (width - left - right - (ncols - 1) * wgap) / ncols
    fig = new_figure(figsize=(width, height))
    axes = fig.subplots(nrows, ncols, sharex=True, sharey=True, squeeze=False,
                        gridspec_kw={"left": left / width, "right": 1 - right / width,
                                     "top": 1 - top / height,
                                     "bottom": (bottom + legend) / height,
                                     "wspace": wgap / ax_w, "hspace": hgap / ax_h})
    top_value = 1.15
    for ax, (heading, binned, worst, worst_label) in zip(axes.flat, panels):
        lo, hi, p05, p50, p95 = _band(binned)
        ax.fill_between(t_s, lo, hi, step="post", color="tab:blue", alpha=0.18, lw=0,
                        label="all runs (min–max)")
        ax.fill_between(t_s, p05, p95, step="post", color="tab:blue", alpha=0.35, lw=0,
                        label="5–95 % of runs")
        ax.step(t_s, p50, where="post", color="tab:blue", lw=0.8, label="median")
        ax.step(t_s, binned[worst], where="post", color=WORST_COLOUR, lw=1.0,
                label="worst run (largest margin)")
        ax.axhline(1.0, color=THRESHOLD_COLOUR, lw=1.5, ls="--", label="threshold |r|/τ = 1")
        if np.isfinite(binned).any():
            top_value = max(top_value, 1.08 * float(np.nanmax(binned)))
        ax.set_title(f"{heading}: {binned.shape[0]} runs\n{worst_label}", fontsize=SMALL_PT,
                     y=TITLE_Y)
        ax.grid(alpha=0.3)
        ax.tick_params(labelsize=SMALL_PT)
    for ax in axes.flat[len(panels):]:
        ax.remove()                     # no empty panel
    axes[0, 0].set_ylim(0.0, top_value)
    axes[0, 0].set_xlim(t_s[0], t_s[-1] + (t_s[1] - t_s[0] if len(t_s) > 1 else 1.0))
    for ax in axes[:, 0]:
        ax.set_ylabel("|r|/τ [-]", fontsize=SMALL_PT)
    for ax in axes.flat[max(0, len(panels) - ncols):len(panels)]:
        ax.set_xlabel("time [s]", fontsize=SMALL_PT)
        ax.xaxis.set_tick_params(labelbottom=True)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.suptitle(title, fontsize=TITLE_PT, y=1 - 0.08 / height, va="top")
    fig.legend(handles, labels, loc="lower center", bbox_to_anchor=(0.5, 0.02 / height),
               ncol=len(labels), fontsize=SMALL_PT, frameon=False)
    return fig


def _band(binned: np.ndarray):
    """(min, max, 5th, 50th, 95th percentile) over the runs (axis 0) of each time bin, NaN
    ignored (a bin where every run is NaN gives NaN). Without NaN: one vectorised
    ``np.percentile`` (``np.nanpercentile`` treats each bin on its own: 15× slower);
    the same values (linear interpolation in both)."""
    with np.errstate(all="ignore"), _quiet():
        lo, hi = np.nanmin(binned, axis=0), np.nanmax(binned, axis=0)
        if np.isnan(binned).any():
            p05, p50, p95 = np.nanpercentile(binned, [5, 50, 95], axis=0)
        else:
            p05, p50, p95 = np.percentile(binned, [5, 50, 95], axis=0)
    return lo, hi, p05, p50, p95


class _quiet:
    """Silence numpy's all-NaN-slice warnings inside a block."""

    def __enter__(self):
        import warnings

        self._w = warnings.catch_warnings()
        self._w.__enter__()
        warnings.simplefilter("ignore", RuntimeWarning)

    def __exit__(self, *exc):
        return self._w.__exit__(*exc)


def _horizontal() -> dict:
    """Keyword of a horizontal box plot: ``orientation`` from matplotlib 3.10, ``vert``
    before (deprecated since)."""
    import inspect

    from matplotlib.axes import Axes

    if "orientation" in inspect.signature(Axes.boxplot).parameters:
        return {"orientation": "horizontal"}
    return {"vert": False}


def fault_figure(rows: list, *, title: str, max_dtp: float | None = None):
    """One fault type across detectors: the DTP of the detected runs (box: quartiles and
    median, whiskers: min and max, diamond: mean) and the runs in time / late / missed as
    bars beside (misses are never dropped). A detector that detected no run has no box,
    only its bar; when no detector detected any run, the DTP panel is not drawn.

    Parameters
    ----------
    rows : list of (detector, dtp, n_missed), top to bottom: ``dtp`` ndarray
        (n_detected,) [-] of the detected runs, ``n_missed`` the scored runs without
        detection
    max_dtp : required DTP limit drawn as a line (1 = the required detection time); runs
        above it are "late" (None: late is DTP > 1)
    """
    horizontal = _horizontal()
    limit = 1.0 if max_dtp is None else float(max_dtp)
    names = [r[0] for r in rows]
    y = np.arange(len(rows))[::-1]              # first detector on top
    any_detected = any(len(r[1]) for r in rows)
    height = 0.42 * len(rows) + 1.5
    if any_detected:
        fig = new_figure(figsize=(11.0, height))
        ax, axc = fig.subplots(1, 2, sharey=True, gridspec_kw={"width_ratios": [3, 2]})
        data = [np.asarray(r[1], float) for r in rows]
        have = [i for i, d in enumerate(data) if len(d)]
        ax.boxplot([data[i] for i in have], positions=y[have], **horizontal, whis=(0, 100),
                   widths=0.5, showmeans=True, manage_ticks=False,
                   meanprops={"marker": "D", "markerfacecolor": "tab:purple",
                              "markeredgecolor": "tab:purple", "markersize": 4},
                   medianprops={"color": "tab:purple"})
        top = max(float(np.max(d)) for d in data if len(d))
        if top > 20 * limit:
            ax.set_xscale("symlog", linthresh=0.1 * limit, linscale=0.5)
        ax.axvline(limit, color=WORST_COLOUR, ls="--", lw=1.2, label=f"DTP limit {limit:g}")
        for i, d in enumerate(data):
            if not len(d):
                ax.text(0.01, y[i], "no run detected", transform=ax.get_yaxis_transform(),
                        va="center", fontsize=SMALL_PT, color="0.3")
        ax.set_xlabel("DTP = detection delay / required time [-] (detected runs)",
                      fontsize=SMALL_PT)
        ax.legend(fontsize=SMALL_PT, loc="lower left", bbox_to_anchor=(0.0, 1.0),
                  frameon=False)                 # above the panel: covers no box
        ax.grid(alpha=0.3, axis="x")
    else:
        fig = new_figure(figsize=(6.0, height))
        axc = fig.subplots()
        ax = axc
    ax.set_yticks(y, names, fontsize=SMALL_PT)
    ax.set_ylim(-0.6, len(rows) - 0.4)
    counts = np.array([[int(np.sum(np.asarray(r[1]) <= limit)),
                        int(np.sum(np.asarray(r[1]) > limit)), int(r[2])] for r in rows])
    left = np.zeros(len(rows))
    for k, (label, colour) in enumerate([("in time", "tab:green"), ("late", "tab:orange"),
                                         ("missed", WORST_COLOUR)]):
        axc.barh(y, counts[:, k], left=left, height=0.6, color=colour, label=label)
        for yi, c, x0 in zip(y, counts[:, k], left):
            if c >= 0.06 * counts.sum(axis=1).max():     # a count fits inside its bar
                axc.text(x0 + c / 2, yi, str(c), ha="center", va="center",
                         fontsize=SMALL_PT, color="white" if k != 1 else "black")
        left += counts[:, k]
    axc.set_xlim(0, max(1, float(left.max())))
    axc.set_xlabel("runs", fontsize=SMALL_PT)
    axc.legend(fontsize=SMALL_PT, ncol=3, loc="lower center", bbox_to_anchor=(0.5, 1.0),
               frameon=False)
    for a in {ax, axc}:
        a.tick_params(labelsize=SMALL_PT)
    fig.suptitle(title, fontsize=TITLE_PT)
    fig.tight_layout()
    return fig


def run_figure(frame: pd.DataFrame, residuals: dict, *, onset_s: float, title: str):
    """One run: signals, every detector's |r|/τ with the threshold, alarms, fault onset.

    Parameters
    ----------
    frame : :meth:`scenarios.Signals.to_pandas` output (time index [s], columns with units),
        optionally with ``true_*`` columns
    residuals : {detector: (residual (n_steps,) [-], alarm (n_steps,) bool)}
    onset_s : fault onset [s] (NaN for a fault-free run)
    """
    t = frame.index.to_numpy()
    ratios = [3, 2, 2, 3] if residuals else [3, 2, 2]
    # the panels' box [in]: 0.72 in from the left, 6.3 in wide; the canvas has room right
    # of it for the legends (up to 3.9 in: long detector names) and above for a title of
    # two lines, so that everything drawn is inside it (figure_pixels trims the rest)
    base = 1.85 * sum(ratios) / 2.5
    # canvas beyond that box: left for long tick labels, below for a legend taller than
    # its panel (six detectors: 13 entries), above for the title
    extra_left, extra_below = 0.4, 1.6
    width, height = 11.4, base + 0.45 + extra_below
    fig = new_figure(figsize=(width, height))
    axes = fig.subplots(len(ratios), 1, sharex=True, gridspec_kw={"height_ratios": ratios})
    fig.subplots_adjust(left=(extra_left + 0.72) / width, right=(extra_left + 6.3) / width,
                        top=(extra_below + 0.94 * base) / height,
                        bottom=(extra_below + (0.07 if residuals else 0.1) * base) / height,
                        hspace=0.12)
    ax = axes[0]
    ax.plot(t, frame["command [mm]"], label="order u", lw=1.1)
    ax.plot(t, frame["rod_com [mm]"], label="rod COM", lw=0.8)
    ax.plot(t, frame["rod_mon [mm]"], label="rod MON", lw=0.8, alpha=0.8)
    if "true_rod [mm]" in frame:
        ax.plot(t, frame["true_rod [mm]"], "k--", label="true rod", lw=0.7)
    ax.set_ylabel("rod [mm]")
    ax = axes[1]
    if np.isfinite(frame["surface [deg]"]).any():
        ax.plot(t, frame["surface [deg]"], label="surface sensor", lw=0.8)
    if "true_surface [deg]" in frame:
        ax.plot(t, frame["true_surface [deg]"], "k--", label="true surface", lw=0.7)
    ax.set_ylabel("surface [deg]")
    ax = axes[2]
    ax.plot(t, frame["current [mA]"], label="current order", lw=0.8)
    if "true_current [mA]" in frame:
        ax.plot(t, frame["true_current [mA]"], "k--", label="current flowing", lw=0.7)
    ax.set_ylabel("current [mA]")
    if residuals:
        _residual_panel(axes[3], t, residuals)
    axes[-1].set_xlabel("time [s]")
    for ax in axes:
        ax.grid(alpha=0.3)
        if np.isfinite(onset_s):
            ax.axvline(onset_s, color=WORST_COLOUR, ls=":", lw=1.2)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=SMALL_PT, frameon=False)
    text = title + (f"  (onset {onset_s:.2f} s, red dotted)" if np.isfinite(onset_s) else "")
    # above the top panel, wrapped to the figure's width (never cut at its right edge)
    fig.suptitle(textwrap.fill(text, 100, break_on_hyphens=False),
                 x=(extra_left + 0.09) / width, y=(extra_below + 0.955 * base) / height,
                 ha="left", va="bottom", fontsize=TITLE_PT)
    return fig


def _residual_panel(ax, t: np.ndarray, residuals: dict) -> None:
    """Every detector's |r|/τ against the threshold line; the alarm span of one detector
    shaded, of several a strip each along the top (overlapping shades would hide which
    detector alarmed when)."""
    top = 1.15
    strip = 0.04 if len(residuals) > 1 else 0.0    # height of an alarm strip [axes]
    for k, (name, (res, alarm)) in enumerate(residuals.items()):
        res = np.asarray(res, dtype=float)
        line, = ax.plot(t, res, lw=0.9, label=f"{name} |r|/τ")
        alarm = np.asarray(alarm, dtype=bool)
        if alarm.any():
            first = t[int(np.argmax(alarm))]
            lo, hi, alpha = ((1 - (k + 1) * strip, 1 - (k + 0.15) * strip, 0.9) if strip
                             else (0, 1, 0.15))
            ax.fill_between(t, lo, hi, where=alarm, step="post", color=line.get_color(),
                            alpha=alpha, lw=0, transform=ax.get_xaxis_transform(),
                            label=(f"{name} " if strip else "")
                            + f"alarm, first at {first:.2f} s")
        if np.isfinite(res).any():
            top = max(top, float(np.nanmax(res)) * 1.08)
    ax.axhline(1.0, color=THRESHOLD_COLOUR, ls="--", lw=1.3, label="threshold")
    # room above the curves for the strips
    ax.set_ylim(0, min(top, 50.0) / (1 - len(residuals) * strip))
    ax.set_ylabel("|r|/τ [-]")


def envelope_map_figure(points: pd.DataFrame, value: str, *, title: str, label: str,
                        highlight_above: float | None = None, missed: pd.DataFrame | None = None,
                        flagged: str | None = None, flagged_label: str = ""):
    """A per-run value over altitude × VCAS and mass × CG (two panels).

    Parameters
    ----------
    points : DataFrame with ``alt_ft, vcas_kt, mass_t, cg_pct`` and the column *value*
    value : column to colour by (e.g. ``margin`` [-], ``dtp`` [-])
    highlight_above : runs with value above this are ringed in red (e.g. 1: false alarm
        territory for a margin, the DTP limit for a DTP)
    missed : runs drawn as black crosses (missed detections: no DTP to colour)
    flagged : a bool column of *points* (e.g. ``false_alarm``): its runs are ringed in red,
        labelled *flagged_label* with their count, instead of those above
        *highlight_above* (so the count is the one of the summary table)
    """
    import matplotlib

    fig = new_figure(figsize=(9.6, 3.6))
    axes = fig.subplots(1, 2)
    fig.subplots_adjust(left=0.08, right=0.9, top=0.82, bottom=0.14, wspace=0.25)
    v = points[value].to_numpy(dtype=float)
    finite = np.isfinite(v)
    vmax = float(np.nanmax(v)) if finite.any() else 1.0
    vmin = float(np.nanmin(v)) if finite.any() else 0.0
    if highlight_above is not None:
        vmax = max(vmax, highlight_above)
    order = np.argsort(np.where(finite, v, -np.inf))  # largest drawn last, on top
    pts = points.iloc[order]
    vv = v[order]
    sc = None
    # MAP_LEVELS colour classes, drawn as such (the palette of figure_png would otherwise
    # merge nearby shades of a continuous scale unevenly)
    cmap = matplotlib.colormaps["YlOrRd"].resampled(MAP_LEVELS)
    for ax, (x, y, xl, yl) in zip(axes, [("vcas_kt", "alt_ft", "VCAS [kt]", "altitude [ft]"),
                                         ("cg_pct", "mass_t", "CG [% MAC]", "mass [t]")]):
        sc = ax.scatter(pts[x], pts[y], c=vv, cmap=cmap, vmin=vmin, vmax=vmax, s=16,
                        edgecolors="0.4", linewidths=0.3)
        if flagged is not None:
            over = pts[flagged].to_numpy(dtype=bool)
            ring_label = f"{flagged_label} ({int(over.sum())})"
        elif highlight_above is not None:
            over = vv > highlight_above
            ring_label = f"{label} > {highlight_above:g} ({int(over.sum())})"
        else:
            over = np.zeros(len(pts), dtype=bool)
        if over.any():
            ax.scatter(pts[x][over], pts[y][over], s=70, facecolors="none",
                       edgecolors=WORST_COLOUR, linewidths=1.2, label=ring_label)
        if missed is not None and len(missed):
            ax.scatter(missed[x], missed[y], marker="x", c="k", s=40, linewidths=1.2,
                       label=f"missed ({len(missed)})")
        if finite.any():
            i = order[-1]
            px = points[x].iloc[i]
            right = px > np.mean(ax.get_xlim())           # text towards the panel's inside
            ax.annotate(f"worst {v[i]:.3g}", (px, points[y].iloc[i]),
                        xytext=(-6 if right else 6, 6), textcoords="offset points",
                        ha="right" if right else "left", fontsize=SMALL_PT)
        ax.set_xlabel(xl)
        ax.set_ylabel(yl)
        ax.grid(alpha=0.3)
        if ax.get_legend_handles_labels()[0]:           # above the panel: covers no run
            ax.legend(fontsize=SMALL_PT, loc="lower left", bbox_to_anchor=(0.0, 1.0), ncol=2,
                      frameon=False)
    cax = fig.add_axes([0.92, 0.14, 0.015, 0.68])
    fig.colorbar(sc, cax=cax, label=label)
    fig.suptitle(title, fontsize=TITLE_PT)
    return fig


def mean_excess_figure(values: np.ndarray, u: float, *, title: str):
    """Mean-excess plot of per-run margins: e(v) = mean(X − v | X > v) against v, for v
    up to the 10th-largest value, with the tail threshold *u* of the fit marked. A
    generalised Pareto tail makes e(v) linear above u (slope ξ/(1 − ξ); Coles 2001 §4.3.1),
    so the plot shows whether u is high enough."""
    x = np.sort(np.asarray(values, float)[np.isfinite(values)])
    grid = x[: max(len(x) - 10, 1)]
    excess = [float(np.mean(x[x > v] - v)) for v in grid]
    fig, ax = _small_figure(legend_in=1.6)
    ax.plot(grid, excess, color="tab:blue", lw=1.2, label="mean excess")
    ax.axvline(u, color=WORST_COLOUR, ls="--", lw=1.0, label=f"u = {u:.3g}")
    ax.set_xlabel("margin threshold v [-]")
    ax.set_ylabel("mean excess over v [-]")
    _legend_beside(ax)
    ax.grid(alpha=0.3)
    ax.set_title(title, fontsize=TITLE_PT, y=TITLE_Y)
    return fig


def tail_qq_figure(excesses: np.ndarray, shape: float, scale: float, *, title: str,
                   quantiles: np.ndarray | None = None):
    """Tail QQ plot: the k sorted excesses over u against the quantiles of the fitted
    generalised Pareto distribution at plotting positions i/(k + 1); on the diagonal when
    the model fits. *quantiles*: those k quantiles when the caller has them
    (:func:`reports.scoring.quantiles.gpd_plotting_quantiles`; a worker process that draws the
    figure then needs no SciPy)."""
    y = np.sort(np.asarray(excesses, float))
    k = len(y)
    model = (gpd_plotting_quantiles(k, shape, scale) if quantiles is None
             else np.asarray(quantiles, float))
    fig, ax = _small_figure()
    ax.plot(model, y, ".", color="tab:purple", ms=3)
    top = float(max(np.max(model), np.max(y))) if k else 1.0
    ax.plot([0, top], [0, top], color="0.4", lw=0.8, ls=":")
    ax.set_xlabel("fitted GPD quantile of the excess [-]")
    ax.set_ylabel("observed excess over u [-]")
    ax.grid(alpha=0.3)
    ax.set_title(title, fontsize=TITLE_PT, y=TITLE_Y)
    return fig


def survival_figure(curves: dict, *, title: str, required: dict | None = None):
    """Kaplan–Meier distribution of the detection delay per fault type: *curves* maps a
    label to (t [s], F̂, F_lo, F_hi) (:func:`reports.scoring.survival.kaplan_meier`); the curve
    stops below 1 by the share of missed runs (right-censored at the window's end).

    *required* maps a curve's label to (fault type, its required detection time [s]: the
    DTP denominator): a dotted vertical line at that time, in the curve's colour, labelled
    in the legend (one grey line for fault types that share a time), so the share of runs
    detected in time is read where the curve crosses it."""
    fig, ax = _small_figure(width_in=5.6, height_in=3.2, legend_in=4.0)
    colours = {}
    for label, (t, f, f_lo, f_hi) in curves.items():
        if len(t) == 0:
            line, = ax.plot([], [], label=f"{label}: no detection")
            colours[label] = line.get_color()
            continue
        line, = ax.step(np.r_[0.0, t], np.r_[0.0, f], where="post", lw=1.2, label=label)
        colours[label] = line.get_color()
        ax.fill_between(np.r_[0.0, t], np.r_[0.0, f_lo], np.r_[0.0, f_hi], step="post",
                        color=line.get_color(), alpha=0.15, lw=0)
    at: dict = {}
    for label, (fault, seconds) in (required or {}).items():
        at.setdefault(float(seconds), []).append((label, fault))
    for seconds, shared in sorted(at.items()):
        colour = colours.get(shared[0][0], "0.3") if len(shared) == 1 else "0.3"
        names = ", ".join(fault for _, fault in shared)
        ax.axvline(seconds, color=colour, ls=(0, (1.5, 1.5)), lw=1.3,
                   label=f"required time of {names}: {seconds:g} s")
    ax.set_xlabel("detection delay [s]")
    ax.set_ylabel("share of runs detected")
    ax.set_ylim(0, 1.02)
    _legend_beside(ax)
    ax.grid(alpha=0.3)
    ax.set_title(title, fontsize=TITLE_PT, y=TITLE_Y)
    return fig


def _small_figure(width_in: float = 4.6, height_in: float = 3.0, legend_in: float = 0.0):
    """(figure, axes) of one panel *width_in* × *height_in* [in] as laid out before, with
    *legend_in* more inches of canvas to its right for a legend beside the axes, and 0.5 in
    right and 0.4 in left for tick labels past the axes' ends (what is not drawn on is
    trimmed by :func:`figure_pixels`)."""
    width = 0.4 + width_in + legend_in + 0.5
    fig = new_figure(figsize=(width, height_in))
    ax = fig.subplots()
    fig.subplots_adjust(left=1.1 / width, right=(0.4 + width_in - 0.15) / width,
                        top=1 - 0.42 / height_in, bottom=0.51 / height_in)
    return fig, ax


def _legend_beside(ax) -> None:
    """The legend right of the axes, top-aligned, without a frame: it covers no curve and
    no marker."""
    ax.legend(fontsize=SMALL_PT, loc="upper left", bbox_to_anchor=(1.01, 1.0),
              frameon=False)


def exceedance_figure(levels: np.ndarray, estimate: np.ndarray, upper: np.ndarray,
                      margins: np.ndarray, *, title: str):
    """The certificate's exceedance curve of one detector (``certificate-levels.parquet``):
    the bound P(margin ≥ x) ≤ p_upper95 and the estimate (where given) at each level x,
    against the runs' own exceedance frequencies (the share of the campaign's fault-free
    runs with margin ≥ x, down to one run), log scale."""
    m = np.sort(np.asarray(margins, float)[np.isfinite(margins)])[::-1]
    n = len(m)
    fig, ax = _small_figure(legend_in=2.3)
    if n:
        ax.step(m, np.arange(1, n + 1) / n, where="post", color="0.35", lw=1.0,
                label=f"runs' own share ({n} runs)")
    ax.plot(levels, upper, "v-", color=WORST_COLOUR, ms=5, lw=1.0, label="95 % upper bound")
    given = np.isfinite(estimate) & (np.asarray(estimate) > 0)
    if given.any():
        ax.plot(np.asarray(levels)[given], np.asarray(estimate)[given], "o", color="tab:blue",
                ms=4, label="estimate")
    ax.set_yscale("log")
    ax.set_xlabel("margin level x [-]")
    ax.set_ylabel("P(margin ≥ x) per run [-]")
    _legend_beside(ax)
    ax.grid(alpha=0.3, which="both")
    ax.set_title(title, fontsize=TITLE_PT, y=TITLE_Y)
    return fig


#: Figure kinds drawn by :func:`render_png`.
FIGURES = {"envelope": envelope_figure, "fault": fault_figure, "run": run_figure,
           "map": envelope_map_figure, "mean_excess": mean_excess_figure,
           "tail_qq": tail_qq_figure, "survival": survival_figure,
           "exceedance": exceedance_figure}


def render_png(kind: str, args: tuple, kwargs: dict, dpi: int = REPORT_DPI) -> bytes:
    """PNG bytes of the figure *kind* (a key of :data:`FIGURES`) drawn with *args* and
    *kwargs* — a picklable unit of work, so figures can be drawn in worker processes."""
    if kind not in FIGURES:
        raise ValueError(f"unknown figure kind {kind!r}; use one of {sorted(FIGURES)}")
    return figure_png(FIGURES[kind](*args, **kwargs), dpi=dpi)
