"""The global [CHEN] estimators against the size of the flight-data errors, run by
``fdd-campaign study chen-flight-data --seed S --out DIR [--jobs N] [--levels 0.1 0.05 0.02 0]``
(``--fault-free``, ``--disconnections``, ``--learning-runs``: smaller campaigns to try it)
(docs/chen-estimator.md §5.2).

[CHEN] Table 2 puts ±10 % on the measured VCAS and altitude and on the estimated mass and CG,
the scheduling data of the LPV estimators; it prints no distribution (the Monte Carlo
campaign samples "according to a suitable probability distribution", §5.2). Our ``mc``
design draws each of them per run, uniformly over ±w and independently of the others (one
dimension of a scrambled Sobol sequence each, :mod:`campaign.plan`); the ±5 % on the six
aerodynamic coefficients are drawn alike.

For each half-width w of *levels* the study runs the preset ``chen-mc`` with
``[uncertainty] vcas = alt = mass = cg = w`` (the aerodynamic ±5 % kept), its fault-free
group (1200 runs, 200 per manoeuvre) and its disconnection group (334 in cruise) — the jam
groups are left out, they do not change these detectors' rows — and the detectors

* ``chen-global`` (``gust_channel = false``, the presets' default: τ0 + b(t));
* ``chen-global-paper`` ([CHEN]'s constant threshold above the largest fault-free residual
  of the learning set, with our margin ``safety`` = 1.5, its default);
* ``chen-global-paper-evt`` (``threshold_method = "evt"``: the constant τ0 calibrated to
  10⁻⁴ per run per manoeuvre, ours),

each campaign into ``DIR/chen-mc-flight-data-<w in %>`` (rerunning resumes; ``fdd-campaign
report`` and ``show`` read each). The detectors are the same at every level: their polytope
and the activity bound's k_j stay those of Table 2's ±10 %; only the aircraft's errors change.
Two things change with w besides the errors: the realistic-case rule is evaluated at the
campaign's widths (docs/physics.md §6), so a few flight points near the buffet and speed
limits are admitted at small w, and the Sobol sequence of a cell skips the points it
rejects, so the runs of two levels are not paired.

The table: per level and detector, the learned τ0 [deg], the false alarms on the fault-free
runs and before onset, the worst fault-free margin and its manoeuvre, the disconnections
missed, and the delays after onset (min/median/mean/max [s]) with the count above
:data:`DELAY_LIMIT_S`, beside [CHEN]'s delays (Tables 3–4, inferred in seconds,
docs/chen-estimator.md §6).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["CHEN_DELAYS_S", "DELAY_LIMIT_S", "DETECTORS", "LEVELS", "campaign_for",
           "format_table", "level_table", "run_study"]

#: Half-widths of the flight-data errors compared (relative; [CHEN] Table 2: 0.10).
LEVELS: tuple[float, ...] = (0.10, 0.05, 0.02, 0.0)
#: The detectors compared: (registry name, label, parameters).
DETECTORS: tuple[tuple[str, str, dict], ...] = (
    ("chen-global", "chen-global", {"gust_channel": False}),
    ("chen-global-paper", "chen-global-paper", {}),
    ("chen-global-paper", "chen-global-paper-evt", {"threshold_method": "evt"}),
)
#: [CHEN]'s disconnection delays [s]: its printed min/max DTP × 120 s (the denominator
#: inferred from its printed DTPs, docs/chen-estimator.md §6; reports.render.paper).
CHEN_DELAYS_S = {"Table 3 (sweep)": (0.91, 7.01), "Table 4 (Monte Carlo)": (0.96, 4.52)}
#: The delay the table counts beyond [s]: twice [CHEN]'s largest Monte Carlo delay.
DELAY_LIMIT_S = 2.0 * CHEN_DELAYS_S["Table 4 (Monte Carlo)"][1]
#: Groups of ``chen-mc`` kept.
_FAULTS = ("none", "disconnection")


def _name(level: float) -> str:
    """Campaign name of a level: ``chen-mc-flight-data-<w in %>`` (e.g. 2, 0.5)."""
    pct = f"{100.0 * level:.10g}".replace(".", "p")
    return f"chen-mc-flight-data-{pct}"


def campaign_for(level: float, seed: int | None = None, turbulence: str | None = None, *,
                 fault_free: int | None = None, disconnections: int | None = None,
                 learning_runs: int | None = None):
    """The campaign of one level: the preset ``chen-mc`` with ``[uncertainty] vcas = alt =
    mass = cg = level``, its fault-free and disconnection groups, the detectors of
    :data:`DETECTORS`, *seed* (default: the preset's) and *turbulence* (default: the
    preset's calm air); *fault_free* runs per manoeuvre, *disconnections* and
    *learning_runs* per manoeuvre replace the preset's 200, 334 and 50 when given (smaller
    campaigns to try the study; the tables of docs/chen-estimator.md are of the preset's).
    Raises :class:`campaign.config.ConfigError` for a level out of the ``[uncertainty]``
    range (0–0.5) or a count below 1."""
    from ...config.load import load_config, with_overrides

    base = load_config("chen-mc")
    data = base.to_dict()
    groups = [dict(g) for g in data["group"] if g["fault"] in _FAULTS]
    for g in groups:
        count = fault_free if g["fault"] == "none" else disconnections
        if count is not None:
            g["count"] = int(count)
    values = {
        "campaign.name": _name(level),
        "campaign.description": (f"chen-mc with the flight-data errors of [CHEN] Table 2 at "
                                 f"±{100.0 * level:g} % (VCAS, altitude, mass, CG): fault-free "
                                 "and disconnection groups, the global estimators "
                                 "(fdd-campaign study chen-flight-data)"),
        **{f"uncertainty.{k}": float(level) for k in ("vcas", "alt", "mass", "cg")},
        "group": groups,
        "detector": [{"name": n, "label": lab, "params": dict(p)} for n, lab, p in DETECTORS],
    }
    if turbulence is not None:
        values["plant.turbulence"] = turbulence
    if learning_runs is not None:
        values["learning.runs_per_manoeuvre"] = int(learning_runs)
    return with_overrides(base, seed, values=values)


def _delays(rows: pd.DataFrame) -> dict:
    d = rows.loc[rows["detected"].astype(bool), "delay_s"].to_numpy(float)
    if d.size == 0:
        return {"delay_min_s": math.nan, "delay_median_s": math.nan, "delay_mean_s": math.nan,
                "delay_max_s": math.nan, "over_limit": 0}
    return {"delay_min_s": float(d.min()), "delay_median_s": float(np.median(d)),
            "delay_mean_s": float(d.mean()), "delay_max_s": float(d.max()),
            "over_limit": int((d > DELAY_LIMIT_S + 1e-9).sum())}


def level_table(result, level: float) -> pd.DataFrame:
    """One row per detector of :data:`DETECTORS` of the finished campaign *result*
    (:class:`campaign.result.Campaign`) of flight-data level *level*."""
    res = result.results
    fitted = result.fitted
    out = []
    for _, label, _ in DETECTORS:
        rows = res[(res["detector"] == label) & (res["status"] == "ok")]
        free = rows[rows["fault"] == "none"]
        disc = rows[rows["fault"] == "disconnection"]
        worst = free.loc[free["margin"].idxmax()] if len(free) else None
        out.append({
            "level": level, "detector": label,
            "tau0_deg": float(getattr(fitted[label], "threshold_", math.nan)),
            "fa": int(free["false_alarm"].astype(bool).sum()), "fault_free": len(free),
            "worst_margin": float(worst["margin"]) if worst is not None else math.nan,
            "worst_manoeuvre": str(worst["manoeuvre"]) if worst is not None else "",
            "pre_onset": int(disc["pre_onset_alarm"].astype(bool).sum()),
            "md": int((~disc["detected"].astype(bool)).sum()), "faulty": len(disc),
            **_delays(disc),
        })
    return pd.DataFrame(out)


def format_table(table: pd.DataFrame) -> str:
    """The study's table as text, [CHEN]'s delays under it."""
    head = ("| flight-data errors | detector | τ0 (deg) | FA fault-free | worst margin "
            "(manoeuvre) | FA before onset | MD | delay min/median/mean/max (s) | "
            f"> {DELAY_LIMIT_S:.2f} s |")
    lines = [head, "|" + "---|" * 9]
    for r in table.itertuples():
        delays = ("–" if math.isnan(r.delay_min_s) else
                  f"{r.delay_min_s:.2f}/{r.delay_median_s:.2f}/{r.delay_mean_s:.2f}/"
                  f"{r.delay_max_s:.2f}")
        lines.append(f"| ±{100.0 * r.level:g} % | `{r.detector}` | {r.tau0_deg:.2f} | "
                     f"{r.fa}/{r.fault_free} | {r.worst_margin:.2f} ({r.worst_manoeuvre}) | "
                     f"{r.pre_onset}/{r.faulty} | {r.md}/{r.faulty} | {delays} | "
                     f"{r.over_limit} |")
    paper = "; ".join(f"{k} {lo:.2f}–{hi:.2f} s" for k, (lo, hi) in CHEN_DELAYS_S.items())
    lines.append("")
    lines.append(f"[CHEN] (±10 %, no wind): FA 0, MD 0, delays {paper} (its DTP × 120 s, "
                 "inferred: docs/chen-estimator.md §6).")
    return "\n".join(lines)


def run_study(out, seed: int | None = None, levels=LEVELS, jobs: int = 2,
              turbulence: str | None = None, progress: bool = True, echo=print,
              **counts) -> pd.DataFrame | None:
    """Run (or resume) every level's campaign into ``out/<campaign name>``, print the table
    and return it (:func:`level_table` rows of every level); None when a campaign was
    interrupted (rerunning resumes it). *counts*: ``fault_free``, ``disconnections``,
    ``learning_runs`` of :func:`campaign_for`. Every level's campaign is built, hence
    checked, before the first one runs."""
    from ...runner import run

    configs = [(float(w), campaign_for(float(w), seed, turbulence, **counts)) for w in levels]
    parts = []
    for level, config in configs:
        echo(f"== flight-data errors ±{100.0 * level:g} %: {config.campaign.name} ==")
        result = run(config, Path(out) / config.campaign.name, jobs=jobs, progress=progress)
        if not result.complete:
            return None
        parts.append(level_table(result, level))
    table = pd.concat(parts, ignore_index=True)
    echo(format_table(table))
    return table
