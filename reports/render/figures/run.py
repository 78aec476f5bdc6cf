"""Figures drawn from stored data (matplotlib, no display needed)."""

from __future__ import annotations


def plot_run(frame, *, onset_s: float, title: str, path) -> None:
    """One run's command, rod (COM/MON), surface and current with the fault onset, written
    to *path* (:func:`reports.render.figures.report.run_figure` without residual panel).

    *frame* is :meth:`scenarios.Signals.to_pandas` output (columns carry their units),
    optionally with ``true_*`` columns.
    """
    from .report import pyplot, run_figure

    fig = run_figure(frame, {}, onset_s=onset_s, title=title)
    fig.savefig(path, dpi=110, bbox_inches="tight")   # a wrapped title is kept whole
    pyplot().close(fig)
