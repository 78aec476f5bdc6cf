"""Why ``vanek-geometric``'s LPV filter misses most default-size aileron jams, measured on a
``vanek-scenarios`` campaign: ``fdd-campaign study vanek-jam-limit DIR [--seed S] [--jobs N]
[--group G] [--bias-deg 0.02]`` (docs/vanek-geometric.md, "Why the default-size jam is
missed"). DIR is the campaign's directory: a finished one is read (also the
``vanek-scenarios`` member of a ``vanek-section5`` suite directory); an empty or new one
first gets the preset ``vanek-scenarios`` run into it at seed S (``--learning-runs``: fewer
learning runs, to try the study).

The jam runs of group *G* (default ``liquid-jam-default``: 1.3 % of the travel at 170 kt /
23 000 ft, onset 20 s) are re-simulated from the plan, with the campaign's fitted detector,
beside their fault-free twins: the same rows (flight point, Table-2 draws, seed and stream,
so the same turbulence and sensor noise) without the fault. Over the steady part of each run
(from :data:`SETTLE_S` after onset to the end) the study gives

* the jam's steady LPV residual r̂ (its mean) against the learned τ0 and the allowance b(t)
  of the jam run and of its twin: whether b rises because of the jam or is the allowance the
  flight point's turbulence already gets;
* the share of the twin's b that each Table-2 error takes
  (:meth:`detectors.builtin.vanek_geometric.VanekGeometric.allowance_terms`), the largest
  named;
* the change of the twin's r̂ and b when the β vane reads a constant *bias_deg* more (a bias
  no model term covers: the filter's β input is not referenced to its first sample);
* whether the campaign detected the jam (its stored result row).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pandas as pd

from scenarios.errors import ArgumentError, InputError

__all__ = ["SETTLE_S", "campaign_dir", "jam_limit", "format_table", "run_study"]

#: Time after onset from which a run is taken to be steady [s] (est.: the filter's slowest
#: pole is at −0.5 1/s and its low-pass 2 s, so 10 s leaves e⁻⁵ of the transient).
SETTLE_S = 10.0
#: Registry name of the detector studied and its variant.
DETECTOR, VARIANT = "vanek-geometric", "lpv"


class JamLimitInputError(InputError, ValueError):
    """A campaign directory this study cannot read (no vanek-geometric detector, runs that
    cannot be re-simulated here): exit 2."""


def _load(directory):
    """The campaign of *directory* (:func:`campaign.result.load`), its configuration read
    back without the note on magnitudes already in the current reading (a preset's)."""
    import warnings

    from ...config.rules import MagnitudeReadingNote
    from ...result import load

    camp = load(directory)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MagnitudeReadingNote)
        camp.config                                   # noqa: B018 - read once, cached
    return camp


def _label(camp) -> str:
    labels = [d.label for d in camp.config.detectors if d.name == DETECTOR]
    if not labels:
        raise JamLimitInputError(f"{camp.root}: the campaign has no {DETECTOR} detector; give the "
                         "directory of a vanek-scenarios campaign (fdd-campaign run "
                         "vanek-scenarios --out DIR)")
    return labels[0]


def jam_limit(directory, group: str = "liquid-jam-default", bias_deg: float = 0.02
              ) -> pd.DataFrame:
    """One row per jam run of *group* of the finished campaign *directory* (module
    docstring); angles in degrees, means over the steady window."""
    from ...evaluate import simulate_signals
    from ...report_build import replay_settings

    camp = _load(directory)
    label = _label(camp)
    plan = camp.plan
    rows = plan[plan["group"] == group]
    if rows.empty or (rows["fault"] == "none").any():
        groups = sorted(plan.loc[plan["fault"] != "none", "group"].unique())
        raise ArgumentError.of("group", group, f"no faulty group of that name in {directory}; "
                               f"its faulty groups: {', '.join(groups)}")
    settings, why = replay_settings(camp)
    if settings is None:
        raise JamLimitInputError(f"{directory}: its runs cannot be re-simulated here ({why})")
    twins = rows.assign(fault="none", onset_s=np.nan, magnitude=np.nan,
                        run_id=rows["run_id"] + "-twin")
    det = camp.fitted[label]
    tau0 = float(det.thresholds_deg_[VARIANT])
    res = camp.results
    res = res[res["detector"] == f"{label}[{VARIANT}]"].set_index("run_id")
    sig = simulate_signals(rows, settings)
    twin = simulate_signals(twins, settings)
    biased = dataclasses.replace(twin, aircraft={**twin.aircraft,
                                                 "beta": twin.aircraft["beta"] + bias_deg})
    r_jam = det.estimates(sig)[VARIANT]
    b_jam = det.allowances(sig)[VARIANT]
    r_twin = det.estimates(twin)[VARIANT]
    b_twin = det.allowances(twin)[VARIANT]
    r_bias = det.estimates(biased)[VARIANT]
    b_bias = det.allowances(biased)[VARIANT]
    terms = det.allowance_terms(twin, VARIANT)
    out = []
    for i, (_, row) in enumerate(rows.iterrows()):
        k0 = int(round((float(row["onset_s"]) + SETTLE_S) / sig.ts))
        w = slice(k0, sig.n_steps)
        shares = {e: float(terms[e][i, w].mean() / b_twin[i, w].mean()) for e in terms}
        top = max(shares, key=shares.get)
        stored = res.loc[row["run_id"]] if row["run_id"] in res.index else None
        out.append({
            "run_id": row["run_id"], "vcas_kt": float(row["vcas_kt"]),
            "alt_ft": float(row["alt_ft"]), "d_vcas": float(row["d_vcas"]),
            "r_jam": float(abs(r_jam[i, w].mean())), "b_jam": float(b_jam[i, w].mean()),
            "b_jam_min": float(b_jam[i, w].min()), "b_jam_max": float(b_jam[i, w].max()),
            "b_twin": float(b_twin[i, w].mean()), "b_twin_min": float(b_twin[i, w].min()),
            "b_twin_max": float(b_twin[i, w].max()), "r_twin": float(abs(r_twin[i, w].mean())),
            "top_term": top, "top_share": shares[top], "vcas_share": shares["vcas"],
            "tau0": tau0, "bias_deg": float(bias_deg),
            "bias_dr": float((r_bias[i, w] - r_twin[i, w]).mean()),
            "bias_db": float((b_bias[i, w] - b_twin[i, w]).mean()),
            "detected": (bool(stored["detected"]) if stored is not None else None),
            "delay_s": (float(stored["delay_s"]) if stored is not None else math.nan),
        })
    return pd.DataFrame(out)


def format_table(t: pd.DataFrame) -> str:
    """The study's table as text, a summary line under it."""
    lines = ["| run | VCAS error | jam's steady \\|r̂\\| | τ0 | b with the jam: mean (min–max) | "
             "b of the fault-free twin: mean (min–max) | largest term of the twin's b "
             "(share; VCAS's) | β bias: Δr̂, Δb | detected |", "|" + "---|" * 9]
    for r in t.itertuples():
        det = ("–" if r.detected is None else
               (f"yes, {r.delay_s:.1f} s" if r.detected else "no"))
        lines.append(
            f"| {r.run_id} | {100 * r.d_vcas:+.1f} % | {r.r_jam:.2f}° | {r.tau0:.2f}° | "
            f"{r.b_jam:.2f}° ({r.b_jam_min:.2f}–{r.b_jam_max:.2f}) | {r.b_twin:.2f}° "
            f"({r.b_twin_min:.2f}–{r.b_twin_max:.2f}) | {r.top_term} ({100 * r.top_share:.0f} %;"
            f" {100 * r.vcas_share:.0f} %) | {r.bias_dr:+.2f}°, {r.bias_db:+.3f}° | {det} |")
    if len(t):
        lines += ["", f"steady window: {SETTLE_S:g} s after onset to the end; β bias "
                      f"{t['bias_deg'].iloc[0]:g}° on the twins; angles of the aileron "
                      "equivalent r̂ [deg]"]
    return "\n".join(lines)


def campaign_dir(directory, seed: int | None = None, jobs: int = 2,
                 learning_runs: int | None = None, progress: bool = True):
    """The ``vanek-scenarios`` campaign directory the study reads: *directory* when it holds
    a campaign (*seed*, when given, must be its seed), its ``vanek-scenarios`` member when it
    is a suite's directory; else the preset run into *directory* at *seed* (default the
    preset's) with *learning_runs* per manoeuvre (default the preset's). None when that run
    was interrupted (rerunning resumes it)."""
    from pathlib import Path

    from ...config.load import load_config, with_overrides
    from ...runner import run
    from ...store.directory import CampaignDir
    from ...suite import is_suite_dir

    directory = Path(directory)
    if is_suite_dir(directory) and CampaignDir(directory / "vanek-scenarios").is_campaign():
        directory = directory / "vanek-scenarios"
    if CampaignDir(directory).is_campaign():
        stored = _load(directory).config.campaign.seed
        if seed is not None and int(seed) != int(stored):
            raise ArgumentError.of("seed", seed, f"{directory} holds the campaign of seed "
                                   f"{stored}", None, "leave {seed} out to read it, or give "
                                   "another directory")
        return directory
    values = ({} if learning_runs is None else
              {"learning.runs_per_manoeuvre": int(learning_runs)})
    config = with_overrides(load_config("vanek-scenarios"), seed, values=values)
    result = run(config, directory, jobs=jobs, progress=progress)
    return directory if result.complete else None


def run_study(directory, group: str = "liquid-jam-default", bias_deg: float = 0.02,
              echo=print, **campaign) -> pd.DataFrame | None:
    """Compute and print the table; returns it (:func:`jam_limit`), or None when the
    campaign run into *directory* was interrupted. *campaign*: the keywords of
    :func:`campaign_dir`."""
    directory = campaign_dir(directory, **campaign)
    if directory is None:
        return None
    table = jam_limit(directory, group, bias_deg)
    echo(format_table(table))
    return table
