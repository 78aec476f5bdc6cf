"""Census of the control laws' surface activity on the aircraft plant, run by
``fdd-campaign study saturation [--seeds S …] [--runs N] [--surfaces …]`` (docs/aircraft.md §5).

Per monitored surface, manoeuvre and seed: fault-free runs of the six ADDSAFE manoeuvres
(of the ``normal`` manoeuvre set, or ``stress``) sampled as a campaign samples them (``mc`` design,
scrambled Sobol sequence over the realistic envelope and the uncertainty box,
:func:`campaign.plan.build_plan`), flown through the laws in the chosen turbulence, and counted:

* ``sat_any``: the fraction of runs whose monitored servo-valve current order reaches its
  saturation ±i_max at least once (the current is clipped there, so saturated samples equal
  ±i_max exactly);
* ``sat_over_5pct``: the fraction of runs saturated during more than 5 % of their samples;
* ``delta_min_deg``, ``delta_max_deg``: the extreme deflections of the monitored surface over
  the runs [deg];
* ``rms_rate_deg_s``: the root mean square of the surface's rate dδ/dt over every sample of
  the runs, ``max_rms_rate_deg_s`` the largest of the runs' own RMS rates [deg/s].

The runs are simulated a block of ``AircraftPlant.batch_runs`` at a time and reduced as
each block ends, so the memory is that of one block.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from scenarios.aircraft.data import AIRCRAFT_SURFACES
from scenarios.catalog import MANOEUVRES
from scenarios.turbulence import LEVELS

__all__ = ["DEFAULT_SEEDS", "DEFAULT_SURFACES", "census", "census_plan", "format_table",
           "run_study", "run_statistics"]

#: Seeds of the census (no test uses them; docs/aircraft.md §5).
DEFAULT_SEEDS = (52361, 70913)
#: Monitored surfaces of the census: those the aircraft presets monitor.
DEFAULT_SURFACES = ("left_elevator", "left_inboard_aileron", "rudder")
#: Runs per manoeuvre and seed, and their duration [s] (the isolation presets' 40 s).
DEFAULT_RUNS, DEFAULT_DURATION_S = 50, 40.0
#: Share of a run's samples above which a saturated run counts in ``sat_over_5pct``.
LONG_SATURATION = 0.05

COLUMNS = ("surface", "manoeuvre", "seed", "runs", "sat_any", "sat_over_5pct",
           "delta_min_deg", "delta_max_deg", "rms_rate_deg_s", "max_rms_rate_deg_s")


def census_plan(surface: str, seed: int, runs: int = DEFAULT_RUNS,
                duration_s: float = DEFAULT_DURATION_S, manoeuvres=MANOEUVRES,
                manoeuvre_set: str = "normal") -> pd.DataFrame:
    """The fault-free run table of the census for monitored *surface*: *runs* runs of each
    manoeuvre of *manoeuvre_set* (docs/physics.md §7), sampled as a campaign with seed *seed*
    samples them."""
    from ...config.schema import CampaignConfig
    from ...plan import build_plan

    if surface not in AIRCRAFT_SURFACES:
        raise ValueError(f"unknown aircraft surface {surface!r}; allowed: "
                         f"{', '.join(AIRCRAFT_SURFACES)}")
    if runs < 1:
        raise ValueError(f"runs must be at least 1 per manoeuvre, got {runs}")
    config = CampaignConfig.from_dict({
        "campaign": {"name": "saturation-census", "seed": int(seed), "duration_s": duration_s,
                     "surface": "aileron" if "aileron" in surface else "elevator",
                     "design": "mc", "sampler": "sobol", "realistic_only": True},
        "plant": {"kind": "aircraft", "monitored_surface": surface},
        "manoeuvres": {"set": manoeuvre_set},
        "group": [{"name": "fault-free", "fault": "none", "manoeuvres": list(manoeuvres),
                   "count": int(runs)}],
        "detector": [{"name": "position-monitor"}],
    }, source="saturation census")
    return build_plan(config)


def run_statistics(current_mA: np.ndarray, i_max_mA: float, surface_deg: np.ndarray,
                   ts: float) -> pd.DataFrame:
    """Per run (row of the (runs, steps) arrays): whether the current order reaches ±i_max,
    the share of its samples there, its extreme deflections [deg] and the sum of squares of
    the surface rate [(deg/s)²] with its number of samples."""
    saturated = np.abs(current_mA) >= i_max_mA
    rate = np.diff(surface_deg, axis=1) / ts
    return pd.DataFrame({
        "sat_any": saturated.any(axis=1), "sat_share": saturated.mean(axis=1),
        "delta_min_deg": surface_deg.min(axis=1), "delta_max_deg": surface_deg.max(axis=1),
        "rate_sq": (rate * rate).sum(axis=1), "rate_n": np.full(len(rate), rate.shape[1]),
    })


def _simulate_runs(plan: pd.DataFrame, plant) -> pd.DataFrame:
    """:func:`run_statistics` of every run of *plan* on *plant* (an
    :class:`scenarios.aircraft.loop.AircraftPlant`), a block of runs at a time."""
    out = []
    block = plant.batch_runs
    for start in range(0, len(plan), block):
        rows = plan.iloc[start:start + block]
        signals, truth = plant.simulate(rows)
        stats = run_statistics(signals.current, signals.actuator.i_max_mA, truth.surface_deg,
                               signals.ts)
        stats["manoeuvre"] = rows["manoeuvre"].to_numpy()
        out.append(stats)
    return pd.concat(out, ignore_index=True)


def census(seeds=DEFAULT_SEEDS, surfaces=DEFAULT_SURFACES, runs: int = DEFAULT_RUNS,
           duration_s: float = DEFAULT_DURATION_S, turbulence: str = "moderate",
           manoeuvres=MANOEUVRES, manoeuvre_set: str = "normal", echo=None) -> pd.DataFrame:
    """The census table (:data:`COLUMNS`), one row per monitored surface, manoeuvre and seed;
    *echo* (a callable) hears of each part as it ends."""
    from scenarios.aircraft.loop import AircraftPlant

    if turbulence not in LEVELS:
        raise ValueError(f"unknown turbulence level {turbulence!r}; allowed: "
                         f"{', '.join(LEVELS)}")
    plant = AircraftPlant(turbulence=turbulence)
    rows = []
    for surface in surfaces:
        for seed in seeds:
            plan = census_plan(surface, seed, runs, duration_s, manoeuvres, manoeuvre_set)
            stats = _simulate_runs(plan, plant)
            for manoeuvre in manoeuvres:
                s = stats[stats["manoeuvre"] == manoeuvre]
                rows.append({
                    "surface": surface, "manoeuvre": manoeuvre, "seed": int(seed),
                    "runs": len(s), "sat_any": float(s["sat_any"].mean()),
                    "sat_over_5pct": float((s["sat_share"] > LONG_SATURATION).mean()),
                    "delta_min_deg": float(s["delta_min_deg"].min()),
                    "delta_max_deg": float(s["delta_max_deg"].max()),
                    "rms_rate_deg_s": float(np.sqrt(s["rate_sq"].sum() / s["rate_n"].sum())),
                    "max_rms_rate_deg_s": float(np.sqrt(s["rate_sq"] / s["rate_n"]).max()),
                })
            if echo is not None:
                echo(f"{surface}, seed {seed}: {len(stats)} runs")
    return pd.DataFrame(rows, columns=list(COLUMNS))


def format_table(table: pd.DataFrame) -> str:
    """The table as printed by ``fdd-campaign study saturation``."""
    shown = table.copy()
    for col in ("sat_any", "sat_over_5pct"):
        shown[col] = [f"{x:.1%}" for x in table[col]]
    for col in ("delta_min_deg", "delta_max_deg", "rms_rate_deg_s", "max_rms_rate_deg_s"):
        shown[col] = [f"{x:.1f}" for x in table[col]]
    with pd.option_context("display.width", 160):
        return shown.to_string(index=False)


def run_study(seeds=DEFAULT_SEEDS, surfaces=DEFAULT_SURFACES, runs: int = DEFAULT_RUNS,
              duration_s: float = DEFAULT_DURATION_S, turbulence: str = "moderate",
              manoeuvre_set: str = "normal", echo=print, progress=None) -> pd.DataFrame:
    """Compute and print the census; returns its table (:func:`census`)."""
    table = census(seeds, surfaces, runs, duration_s, turbulence, manoeuvre_set=manoeuvre_set,
                   echo=progress)
    echo(format_table(table))
    return table
