"""Plot of one aircraft-level run (``fdd-campaign simulate --plant aircraft --plot``)."""

from __future__ import annotations

import numpy as np


def plot_aircraft_run(frame, *, onset_s: float, title: str, path, monitored: str) -> None:
    """Write :func:`aircraft_run_figure` of *frame* to *path* (PNG)."""
    import matplotlib.pyplot as plt

    fig = aircraft_run_figure(frame, onset_s=onset_s, title=title, monitored=monitored)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def aircraft_run_figure(frame, *, onset_s: float, title: str, monitored: str):
    """The monitored surface's rod signals, every surface's true deflection, and the
    aircraft response (measured p, q, r; φ, θ, β; n_z, n_y) with the fault onset; each
    panel's legend beside it, never over a curve.

    *frame*: :meth:`scenarios.Signals.to_pandas` output of an aircraft-level run plus
    ``true_<surface> [deg]`` columns.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = frame.index.to_numpy()
    fig, axes = plt.subplots(5, 1, figsize=(10, 13), sharex=True, constrained_layout=True)
    ax = axes[0]
    ax.plot(t, frame["command [mm]"], label=f"{monitored}: command u", lw=1.2)
    ax.plot(t, frame["rod_com [mm]"], label="rod COM", lw=0.8)
    if "true_rod [mm]" in frame:
        ax.plot(t, frame["true_rod [mm]"], "k--", label="true rod", lw=0.8)
    ax.set_ylabel("rod [mm]")
    ax = axes[1]
    for col in frame.columns:
        if col.startswith("true_") and col.endswith("[deg]") and col != "true_surface [deg]":
            name = col[len("true_"):-len(" [deg]")]
            ax.plot(t, frame[col], label=name, lw=1.6 if name == monitored else 0.8,
                    ls="-" if name == monitored else "--")
    ax.set_ylabel("surfaces [deg]")
    for ax, names, unit in ((axes[2], ("p", "q", "r"), "deg/s"),
                            (axes[3], ("phi", "theta", "beta"), "deg"),
                            (axes[4], ("nz", "ny"), "g")):
        for name in names:
            ax.plot(t, frame[f"{name} [{unit}]"], label=f"{name} (measured)", lw=0.8)
        ax.set_ylabel(unit)
    axes[-1].set_xlabel("time [s]")
    for ax in axes:
        ax.grid(alpha=0.3)
        # beside the panel, never over it: inside, some position always covers a curve
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=9, frameon=False)
        if np.isfinite(onset_s):
            ax.axvline(onset_s, color="r", ls=":", lw=1.2)
    axes[0].set_title(title + (f" (onset {onset_s:.2f} s, red)" if np.isfinite(onset_s) else ""))
    return fig
