"""Validation of a certificate's exceedance curve by brute force (``fdd-campaign certify DIR
--validate N``; docs/evidence.md, "Validation by brute force").

N fault-free runs of the campaign's own distribution — its fault-free groups as a Monte
Carlo design of about N runs (:func:`campaign.evidence.falsify.monte_carlo_config`), with another
seed, so other flight points, draws and simulation streams — are run with the detectors
fitted in the campaign directory (``--fitted-from``: not learned again) into
``DIR/validation/seed-S-nN/``, a campaign directory of its own: on local workers or a dask
cluster, and resumable (the same command goes on from the runs it holds).

At every detector and level of ``certificate-levels.parquet`` the N runs give the
frequency f = c/N of margins ≥ level and its exact one-sided lower Clopper–Pearson bound
f_lo at the certificate's confidence. A point is **tested** when c ≥
:data:`MIN_VALIDATION_EXCEEDANCES` (fewer say too little about the probability), **covered**
when f ≤ ``p_upper95``, and **consistent** when f_lo ≤ ``p_upper95`` (the brute force's
own sampling error allowed for: a miss of a 95 % bound is expected at about one point in
twenty). Written to ``DIR/validation/seed-S-nN.parquet`` (:data:`VALIDATION_COLUMNS`).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from reports.scoring.metrics import lower_bound

from ...store.directory import VALIDATION_DIR

__all__ = ["MIN_VALIDATION_EXCEEDANCES", "VALIDATION_COLUMNS", "VALIDATION_DIR",
           "check_validation", "coverage_table", "summarise", "validate", "validate_levels",
           "validation_config"]

#: Fewest brute-force exceedances at a level for it to be tested.
MIN_VALIDATION_EXCEEDANCES = 5

#: Columns of ``validation/seed-S-nN.parquet``.
VALIDATION_COLUMNS: tuple[str, ...] = (
    "detector", "level", "p_estimate", "p_upper95", "method", "n_runs", "validation_runs",
    "validation_count", "validation_freq", "validation_lower95", "tested", "covered",
    "consistent", "validation_seed",
)


def validation_config(config, n: int, seed: int):
    """*config*'s fault-free groups as a Monte Carlo design of about *n* runs with campaign
    seed *seed* (the campaign's own distribution, other draws)."""
    from ...config import CampaignConfig
    from ..falsify import monte_carlo_config

    data = monte_carlo_config(config, int(n)).to_dict()
    data["campaign"]["seed"] = int(seed)
    data["campaign"]["name"] = f"{config.campaign.name}-validation"
    return CampaignConfig.from_dict(data, source=f"{config.source} (validation, seed {seed})")


def coverage_table(levels: pd.DataFrame, results, seed: int) -> pd.DataFrame:
    """:data:`VALIDATION_COLUMNS` of an exceedance curve *levels* (rows of
    ``certificate-levels.parquet``) against the result rows of a brute-force campaign (a
    DataFrame, or the :class:`campaign.evidence.certify.rows.CertifyRows` gathered from them
    a batch at a time: one margin per fault-free run and detector is kept)."""
    from .rows import CertifyRows

    if isinstance(results, pd.DataFrame):
        results = CertifyRows.of_table(results)
    margins = {str(name): results.free(name).margin for name in results.free_names()}
    rows = []
    for r in levels.to_dict(orient="records"):
        m = margins.get(str(r["detector"]))
        m = np.empty(0) if m is None else m[np.isfinite(m)]
        n = int(m.size)
        c = int((m >= r["level"]).sum())
        f = c / n if n else math.nan
        lo = float(lower_bound(c, n, float(r["confidence"]))) if n else math.nan
        tested = c >= MIN_VALIDATION_EXCEEDANCES
        rows.append({
            "detector": r["detector"], "level": float(r["level"]),
            "p_estimate": float(r["p_estimate"]), "p_upper95": float(r["p_upper95"]),
            "method": r["method"], "n_runs": int(r["n_runs"]), "validation_runs": n,
            "validation_count": c, "validation_freq": f, "validation_lower95": lo,
            "tested": bool(tested), "covered": bool(f <= r["p_upper95"]) if n else False,
            "consistent": bool(lo <= r["p_upper95"]) if n else False,
            "validation_seed": int(seed)})
    out = pd.DataFrame(rows, columns=list(VALIDATION_COLUMNS))
    for col in ("n_runs", "validation_runs", "validation_count", "validation_seed"):
        out[col] = out[col].astype("int64")
    return out


def validate_levels(directory, config, levels: pd.DataFrame, n: int, *, seed: int,
                    jobs: int = 2, scheduler: str | None = None, tls=None,
                    log=None) -> pd.DataFrame:
    """Run the validation of the campaign in *directory* (its *config*, its exceedance curve
    *levels*) with *n* runs at campaign seed *seed* (module docstring) and return its
    :func:`coverage_table`, also written to ``DIR/validation/seed-S-nN.parquet``."""
    from .rows import CertifyRows
    from ...runner import run
    from ...store.directory import CampaignDir

    cdir = CampaignDir(directory)
    vconfig = validation_config(config, n, seed)
    done = run(vconfig, cdir.validation_dir(seed, n), jobs=int(jobs), scheduler=scheduler,
               tls=tls, fitted_from=directory, log=log)
    table = coverage_table(levels, CertifyRows.of_campaign(done), seed)
    cdir.write_validation(table, seed, n, vconfig.to_json())
    return table


def summarise(table: pd.DataFrame) -> str:
    """The coverage of a :func:`coverage_table` in words."""
    tested = table[table["tested"]]
    runs = int(table["validation_runs"].max()) if len(table) else 0
    if tested.empty:
        return (f"validation: no detector × level has ≥ {MIN_VALIDATION_EXCEEDANCES} "
                f"exceedances in the {runs} runs; nothing to test (more runs, or lower "
                "levels)")
    misses = tested[~tested["covered"]]
    text = (f"validation ({runs} runs, seed {int(table['validation_seed'].iloc[0])}): "
            f"p_upper95 covers the brute-force frequency at {len(tested) - len(misses)} of "
            f"{len(tested)} detector × level points with ≥ {MIN_VALIDATION_EXCEEDANCES} "
            f"exceedances; {int(tested['consistent'].sum())} of {len(tested)} consistent "
            "(the frequency's own lower bound under p_upper95)")
    for r in misses.to_dict(orient="records"):
        text += (f"\n  not covered: {r['detector']} at {r['level']:g}: {r['validation_count']}"
                 f"/{r['validation_runs']} = {r['validation_freq']:.3g} (lower bound "
                 f"{r['validation_lower95']:.3g}) > p_upper95 {r['p_upper95']:.3g}")
    return text


def check_validation(config, n: int, seed: int | None) -> int:
    """The validation seed for campaign *config* (default its seed + 1), or
    :class:`campaign.evidence.certify.CertifyError` (exit 2) for fewer than 100 runs, a grid
    campaign (no distribution to draw from) or the campaign's own seed — checked before any work."""
    from .estimate import CertifyOptionError

    if int(n) < 100:
        raise CertifyOptionError.of("n", n, "the brute-force runs must be ≥ 100 (a level is "
                                    f"tested only where they show ≥ "
                                    f"{MIN_VALIDATION_EXCEEDANCES} exceedances)", 60000)
    if config.campaign.design != "mc":
        raise CertifyOptionError.said(
            "{n}: the campaign's design is {design}; validation draws new runs of an 'mc' "
            "design's distribution (a grid has none): leave {n} out",
            design=repr(config.campaign.design))
    own = int(config.campaign.seed)
    seed = own + 1 if seed is None else int(seed)
    if seed == own:
        raise CertifyOptionError.of("seed", seed, "the campaign's own seed, whose runs are "
                                    "the ones certified; choose another", own + 1)
    return seed


def validate(directory, n: int, *, seed: int | None = None, jobs: int = 2,
             scheduler: str | None = None, tls=None, log=None) -> pd.DataFrame:
    """Validate the exceedance curve written by ``certify`` in campaign *directory* with
    *n* brute-force runs (:func:`validate_levels`) at campaign seed *seed*
    (:func:`check_validation`). :class:`campaign.evidence.certify.CertifyError` (exit 2) also for a
    directory without ``certificate-levels.parquet``."""
    from .estimate import CertifyOptionError
    from ...result import load

    loaded = load(directory)
    seed = check_validation(loaded.config, n, seed)
    cert = loaded.certificate
    levels = None if cert is None else cert.levels
    if levels is None:
        raise CertifyOptionError.said("{n}: {directory} has no certificate-levels.parquet; "
                                      "certify it first (fdd-campaign certify {directory})",
                                      directory=directory)
    return validate_levels(loaded.root, loaded.config, levels, n, seed=seed, jobs=jobs,
                           scheduler=scheduler, tls=tls, log=log)
