"""Figures drawn from stored data (matplotlib, no display needed)."""

from __future__ import annotations

import numpy as np


def plot_run(frame, *, onset_s: float, title: str, path) -> None:
    """One run's command, rod (COM/MON), surface and current with the fault onset.

    *frame* is :meth:`scenarios.Signals.to_pandas` output (columns carry their units),
    optionally with ``true_*`` columns.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = frame.index.to_numpy()
    fig, axes = plt.subplots(3, 1, figsize=(10, 8), sharex=True, constrained_layout=True)
    ax = axes[0]
    ax.plot(t, frame["command [mm]"], label="command u", lw=1.2)
    ax.plot(t, frame["rod_com [mm]"], label="rod COM", lw=0.8)
    ax.plot(t, frame["rod_mon [mm]"], label="rod MON", lw=0.8, alpha=0.8)
    if "true_rod [mm]" in frame:
        ax.plot(t, frame["true_rod [mm]"], "k--", label="true rod", lw=0.8)
    ax.set_ylabel("rod [mm]")
    ax.legend(loc="best", fontsize=8)
    ax = axes[1]
    if np.isfinite(frame["surface [deg]"]).any():
        ax.plot(t, frame["surface [deg]"], label="surface sensor", lw=0.8)
    if "true_surface [deg]" in frame:
        ax.plot(t, frame["true_surface [deg]"], "k--", label="true surface", lw=0.8)
    ax.set_ylabel("surface [deg]")
    ax.legend(loc="best", fontsize=8)
    ax = axes[2]
    ax.plot(t, frame["current [mA]"], label="current order (FCC)", lw=0.8)
    if "true_current [mA]" in frame:
        ax.plot(t, frame["true_current [mA]"], "k--", label="current flowing", lw=0.8)
    ax.set_ylabel("current [mA]")
    ax.set_xlabel("time [s]")
    ax.legend(loc="best", fontsize=8)
    for ax in axes:
        ax.grid(alpha=0.3)
        if np.isfinite(onset_s):
            ax.axvline(onset_s, color="r", ls=":", lw=1.2)
    axes[0].set_title(title + (f" (onset {onset_s:.2f} s, red)" if np.isfinite(onset_s) else ""))
    fig.savefig(path, dpi=110)
    plt.close(fig)
