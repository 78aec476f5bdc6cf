"""Quantiles of a fitted tail at the plotting positions of a QQ plot (the model axis of
:func:`reports.render.figures.report.tail_qq_figure`, computed where the fit is, so a process that
draws the figure needs no SciPy)."""

from __future__ import annotations

import numpy as np


def gpd_plotting_quantiles(k: int, shape: float, scale: float) -> np.ndarray:
    """The quantiles of the generalised Pareto distribution (*shape* ξ, *scale* σ) at the
    plotting positions i/(k + 1), i = 1…k: the model axis of
    :func:`reports.render.figures.report.tail_qq_figure`."""
    from scipy.stats import genpareto

    return genpareto.ppf(np.arange(1, k + 1) / (k + 1.0), shape, scale=scale)
