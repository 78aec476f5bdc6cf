"""``fdd-campaign certify``: the per-run false-alarm probability of each detector beyond
counting (docs/evidence.md, "False-alarm probability certificates (certify)";
docs/design.md §8, Evidence beyond counting).

From a finished campaign's fault-free runs (``fault = "none"``, ``status = "ok"``), per
detector (result-row name, variants apart):

* ``fa_count``/``n_runs`` and ``fa_upper95_cp``, the exact one-sided Clopper–Pearson upper
  bound of the per-run false-alarm probability (:func:`reports.scoring.metrics.upper_bound`,
  Beta⁻¹(level; k + 1, n − k), the summary's ``fa_upper95`` at 95 %); assumes independent
  runs of one probability;
* ``fa_prob_evt`` and ``fa_prob_evt_upper95``: P(margin ≥ 1) and its one-sided bound, the
  level-1 row of the exceedance curve (:mod:`campaign.evidence.certify.levels`): each manoeuvre's
  margins counted where they reach 1, else its own generalised Pareto tail
  (:func:`detectors.tail.exceedance_curve`), combined by the manoeuvres' shares of the runs,
  the pooled count's bound when smaller, and never more than two decades below the counting
  bound (a point estimate below that limit is NaN, ``evt_note`` says why and what would
  carry it); ``evt_k`` … ``evt_gof_pvalue``: the tail fit of the manoeuvre whose term
  dominates the bound; ``evt_method``: which bound ``fa_prob_evt_upper95`` is — "mixture"
  (a tail fit: the manoeuvres' tails, some of them perhaps counted), "counted per manoeuvre"
  (the mixture with every manoeuvre counted: too few runs for any tail fit), "counted"
  (the pooled counting bound of the margins ≥ 1, smaller than the mixture's), "limit of
  the runs" (the tail fits claim less; the bound is the counting bound two decades down)
  or "none";
* ``exposure_h`` = Σ fault-free run durations [h] and ``fa_per_hour_upper95`` (and
  ``fa_per_hour_evt_upper95``): exposure model — false alarms arrive as a homogeneous
  Poisson process of rate λ [1/h] over flight time, independently between runs, so a run
  of duration d [h] is d hours of exposure and alarms with probability 1 − e^(−λd); the
  per-run bound p_up then gives λ ≤ −ln(1 − p_up)/d (d the runs' mean duration; the runs
  of a campaign share one duration);
* with ``sampling``: ``sampling_prob`` and its bounds, P(margin ≥ 1) by subset simulation
  (:mod:`campaign.evidence.rare`) over the campaign's run variables, simulated through the runner's
  pipeline on the local workers or a dask cluster, resumable (:func:`sample_fa_probability`).

Written to ``DIR/certificate.parquet`` (:data:`CERTIFICATE_COLUMNS`), the curve at every
level to ``DIR/certificate-levels.parquet``, beside ``DIR/certificate-hazard.parquet``, the
hazard per flight hour of both sides (false alarms, undetected faults;
:mod:`campaign.evidence.hazard`), and, with ``sampling``, the levels of every subset simulation in
``DIR/sampling/levels.parquet``.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from detectors.tail import CURVE_SHAPES, TailFitError, fit_tail
from reports.scoring.metrics import FAULT_FREE, upper_bound
from scenarios import envelope
from scenarios.envelope import FLIGHT_COLUMNS
from scenarios.errors import ArgumentError, InputError

from .levels import DEFAULT_LEVELS, detector_rows, level_table, parse_levels
from .rows import CertifyRows
from ...plan import run_id, variable_ranges
from ...execute import one_blas_thread
from ...store.directory import SAMPLING_DIR, CampaignDir
from ..hazard import per_hour
from ..rare import P0

__all__ = ["CERTIFICATE_COLUMNS", "CertifyError", "CertifyOptionError", "SAMPLING_DIR",
           "SAMPLING_STREAM_BASE", "certificate", "certify", "evt_estimate", "run_variables",
           "sample_fa_probability"]

#: Columns of ``certificate.parquet``, one row per detector.
CERTIFICATE_COLUMNS: tuple[str, ...] = (
    "detector", "level", "n_runs", "exposure_h", "run_duration_s", "fa_count", "fa_rate",
    "fa_upper95_cp", "fa_prob_evt", "fa_prob_evt_upper95", "fa_per_hour_upper95",
    "fa_per_hour_evt_upper95", "worst_margin", "evt_k", "evt_u", "evt_shape", "evt_scale",
    "evt_gof_pvalue", "evt_note", "evt_method", "sampling_runs", "sampling_prob",
    "sampling_lower95", "sampling_upper95", "sampling_cov", "sampling_levels", "sampling_note",
    "sampling_reached_level", "sampling_reached_prob",
)

#: First simulation stream of the sampled runs (disjoint from evaluation streams, < 2³²,
#: and learning streams, 2³² + j).
SAMPLING_STREAM_BASE = 2 ** 40


class CertifyError(InputError, ValueError):
    """A campaign directory or an option certify cannot work from (exit 2)."""


class CertifyOptionError(CertifyError, ArgumentError):
    """Arguments of :func:`certify` or :func:`campaign.evidence.certify.validate.validate`
    they cannot take, named as Python names them; ``fdd-campaign certify`` names its
    options (:class:`scenarios.errors.ArgumentError`)."""


# ---- counting and the tail fit -------------------------------------------------------------
def evt_estimate(margins, manoeuvres=None, level: float = 0.95, at_one: dict | None = None,
                 ) -> dict:
    """P(margin ≥ 1) with its bound (``fa_prob_evt``, ``fa_prob_evt_upper95``) and the
    ``evt_*`` diagnostics of one detector's fault-free *margins* (one *manoeuvres* label
    each; None: one class): the level-1 row of the exceedance curve
    (:func:`campaign.evidence.certify.levels.detector_rows`, or *at_one* when already computed)
    with the method that gave its bound (``evt_method``), and the tail fit of the manoeuvre
    whose term dominates its bound (k, u, ξ, σ, KS p-value; NaN when that term is
    counted)."""
    m = np.asarray(margins, float)
    cls = (np.full(m.size, "all") if manoeuvres is None
           else np.asarray(manoeuvres).astype(str))
    keep = np.isfinite(m)
    m, cls = m[keep], cls[keep]
    row = at_one or detector_rows("", m, cls, (1.0,), level)[0]
    out = {"fa_prob_evt": row["p_estimate"], "fa_prob_evt_upper95": row["p_upper95"],
           "evt_k": 0, "evt_u": math.nan, "evt_shape": math.nan, "evt_scale": math.nan,
           "evt_gof_pvalue": math.nan,
           "evt_note": f"{row['method']}: {row['note']}" if row["note"] else row["method"],
           "evt_method": row["method"]}
    dominant = row.get("tail_class", "")
    if row["method"] == "mixture" and not dominant:     # no manoeuvre's tail was fitted
        out["evt_method"] = "counted per manoeuvre"
    if dominant:
        try:
            fit = fit_tail(m[cls == dominant], shapes=CURVE_SHAPES)
        except TailFitError:
            return out
        out.update(evt_k=fit.k, evt_u=fit.u, evt_shape=fit.shape, evt_scale=fit.scale,
                   evt_gof_pvalue=fit.gof_pvalue)
        out["evt_note"] += (f"; dominant manoeuvre {dominant}: top {fit.k} of {fit.n} margins "
                            f"above u = {fit.u:.4g}, ξ = {fit.shape:.3g}, σ = {fit.scale:.3g}, "
                            f"KS p = {fit.gof_pvalue:.2g}")
    return out


def certificate(results, plan: pd.DataFrame | None = None, level: float = 0.95,
                levels: pd.DataFrame | None = None) -> pd.DataFrame:
    """The counting and tail-fit columns of :data:`CERTIFICATE_COLUMNS` (sampling columns
    NaN) from the result rows and the run table *plan* of a campaign, or from the
    :class:`campaign.evidence.certify.rows.CertifyRows` gathered from them a batch at a
    time (*plan* then unused: the durations are in it); *levels*: its exceedance curve
    (:func:`campaign.evidence.certify.levels.level_table`) when already computed (its
    level-1 rows are used), else the level 1 is computed here."""
    if isinstance(results, pd.DataFrame):
        results = CertifyRows.of_table(results, plan)
    if levels is None or not (levels["level"] == 1.0).any():
        levels = level_table(results, (1.0,), level)
    at_one = levels[levels["level"] == 1.0].set_index("detector")
    rows = []
    for detector in results.free_names():
        free = results.free(detector)
        margin = free.margin
        n = len(margin)
        k = free.false_alarms
        d_s = free.duration_s
        mean_h = float(np.nanmean(d_s)) / 3600.0
        cp = float(upper_bound(k, n, level))
        evt = evt_estimate(margin, free.manoeuvre, level,
                           at_one.loc[detector].to_dict() if detector in at_one.index
                           else None)
        if k and evt["fa_prob_evt_upper95"] < k / n:
            evt["evt_note"] += (f"; the bound is below the observed rate {k}/{n}: the tail "
                                "model does not describe these runs (see the QQ plot)")
        rows.append({
            "detector": detector, "level": float(level), "n_runs": n,
            "exposure_h": float(np.nansum(d_s)) / 3600.0, "run_duration_s": mean_h * 3600.0,
            "fa_count": k, "fa_rate": k / n, "fa_upper95_cp": cp,
            "fa_per_hour_upper95": per_hour(cp, mean_h),
            "fa_per_hour_evt_upper95": per_hour(evt["fa_prob_evt_upper95"], mean_h),
            "worst_margin": float(np.nanmax(margin)) if (~np.isnan(margin)).any()
            else math.nan, **evt,
            "sampling_runs": 0, "sampling_prob": math.nan, "sampling_lower95": math.nan,
            "sampling_upper95": math.nan, "sampling_cov": math.nan, "sampling_levels": 0,
            "sampling_note": "", "sampling_reached_level": math.nan,
            "sampling_reached_prob": math.nan,
        })
    out = pd.DataFrame(rows, columns=list(CERTIFICATE_COLUMNS))
    for c in ("n_runs", "fa_count", "evt_k", "sampling_runs", "sampling_levels"):
        out[c] = out[c].astype("int64")
    return out


# ---- the sampled estimate --------------------------------------------------------------------
def run_variables(config, plan: pd.DataFrame) -> dict[str, tuple[float, float]]:
    """The run variables of the campaign's fault-free population and their ranges
    (uniform priors, as the ``mc`` design draws them; :func:`campaign.plan.variable_ranges`):
    each flight-point column that varies among the fault-free runs, and each draw column
    with a non-zero half-width."""
    ff = plan[plan["fault"] == FAULT_FREE]
    return {col: (lo, hi) for col, (lo, hi) in variable_ranges(config).items()
            if col in ff and (ff[col].nunique() > 1 if col in FLIGHT_COLUMNS else hi > 0.0)}


class _BatchStore:
    """The evaluated batches of one subset simulation *work* of the campaign directory
    *cdir* (``DIR/sampling/WORK/``, written and read by
    :class:`campaign.store.directory.CampaignDir`): batch b's run ids and margins, written
    atomically as each batch finishes. The simulation is deterministic for its seed, so a
    rerun asks for the same batches in the same order: a stored batch whose run ids are the
    ones asked for is read back instead of simulated (resume after a kill), any other is
    simulated again."""

    def __init__(self, cdir, work: str, config_json: str):
        self.cdir, self.work, self.config_json, self.reused = cdir, work, config_json, 0

    def get(self, b: int, run_ids: list[str]):
        stored = self.cdir.read_sampling_batch(self.work, b)
        if stored is None or stored["run_id"].tolist() != run_ids:
            return None
        self.reused += len(run_ids)
        return stored["margin"].to_numpy(float)

    def put(self, b: int, run_ids: list[str], margin: np.ndarray) -> None:
        self.cdir.write_sampling_batch(self.work, b, run_ids, margin, self.config_json)


def _work_name(name: str, n: int, seed: int, level: float) -> str:
    """Directory of one detector's subset simulation under ``DIR/sampling/``: the detector
    name made file-safe and what decides its runs — the options and the sampler's version
    (a change starts afresh). The level cap is not among them: its levels are those of a
    lower cap, so raising it goes on from the stored batches."""
    import hashlib

    from ..rare import SAMPLER_VERSION

    safe = "".join(ch if ch.isalnum() or ch in "-_.=" else "_" for ch in name)
    key = hashlib.sha256(f"{name}|{n}|{seed}|{level!r}|{SAMPLER_VERSION}".encode()).hexdigest()
    return f"{safe}-{key[:12]}"




def sample_fa_probability(directory, config, plan: pd.DataFrame, names, *, n: int = 500,
                          p0: float = P0, max_levels: int = 12, level: float = 0.95,
                          seed: int = 0, jobs: int = 2, scheduler: str | None = None,
                          tls=None, log=None, progress=None) -> dict:
    """P(margin ≥ 1) of each result-row detector name in *names* by subset simulation
    (:func:`campaign.evidence.rare.subset_simulation`) over the fault-free population of the
    campaign in *directory* (its *config* and run table *plan*).

    The population: the manoeuvre (drawn with the weights of the fault-free runs of the
    plan), the continuous variables of :func:`run_variables` (uniform, mapped from
    standard normal coordinates by u = Φ(z); points outside the realistic envelope are
    outside the prior when the campaign has ``realistic_only``) and the simulation's noise
    stream (a fresh stream from :data:`SAMPLING_STREAM_BASE` on); every other column is that
    of a fault-free run of the same manoeuvre.

    Each batch of points is a run table evaluated through the runner's pipeline
    (:func:`campaign.runner.prepare` with the campaign's own fitted detectors, then
    :func:`campaign.runner.evaluate_rows`: the local workers, or the dask cluster at
    *scheduler*), by the detector owning the name only, and stored under
    ``directory/sampling/`` (:class:`_BatchStore`): killed and started again with the same
    options it reads the stored batches back and simulates only the rest, to the same
    result. *progress* (default: stderr) gets one line per batch with the runs done, the
    most the simulation can take and the time left if it needs them all. Returns
    {name: :class:`campaign.evidence.rare.SubsetResult`}."""
    import sys

    from scipy.stats import norm

    from ..rare import subset_simulation
    from ...progress import Progress
    from ...runner import evaluate_rows, prepare

    if config.campaign.design != "mc":
        raise CertifyOptionError.said(
            "{sampling}: the campaign's design is {design}; sampling re-draws the run "
            "variables of an 'mc' design (a grid has no probability distribution over its "
            "points): leave {sampling} out", design=repr(config.campaign.design))
    ff = plan[plan["fault"] == FAULT_FREE]
    if ff.empty:
        raise CertifyOptionError.said("{sampling}: the campaign has no fault-free run to "
                                      "sample around")
    log = log or (lambda msg: None)
    progress = progress or (lambda msg: print(msg, file=sys.stderr, flush=True))
    variables = run_variables(config, plan)
    cols = list(variables)
    lo = np.array([variables[c][0] for c in cols])
    hi = np.array([variables[c][1] for c in cols])
    manoeuvres = ff["manoeuvre"].value_counts(sort=False)
    names_m, weights = manoeuvres.index.to_numpy(), manoeuvres.to_numpy(float)
    templates = {m: ff[ff["manoeuvre"] == m].iloc[0] for m in names_m}
    realistic = bool(config.campaign.realistic_only)
    counter = iter(range(SAMPLING_STREAM_BASE, 2 ** 62))
    flight = [c for c in cols if c in FLIGHT_COLUMNS]

    def values(z):
        return lo + (hi - lo) * norm.cdf(z)

    def admissible(v):
        if not (realistic and flight):
            return np.ones(len(v), bool)
        pts = pd.DataFrame({c: v[:, cols.index(c)] for c in flight})
        for c in FLIGHT_COLUMNS:
            if c not in pts:
                pts[c] = float(ff[c].iloc[0])
        return envelope.realistic_rule(pts[list(FLIGHT_COLUMNS)],
                                       config.uncertainty)["realistic"].to_numpy(bool)

    def sample_prior(rng, m):
        z = rng.standard_normal((m, len(cols)))
        man = rng.choice(len(names_m), size=m, p=weights / weights.sum())
        nu = np.empty(m, dtype=object)
        nu[:] = [(int(j), next(counter)) for j in man]
        return z, nu, admissible(values(z))

    def new_stream(rng, nu):
        """The chains' nuisance move: a fresh noise stream, the manoeuvre kept (streams are
        i.i.d. under the prior, so this independence proposal is reversible)."""
        out = np.empty(len(nu), dtype=object)
        out[:] = [(j, next(counter)) for j, _ in nu]
        return out

    cdir = CampaignDir(directory)
    setup, detectors = prepare(config, cdir.sampling_runner_dir(), jobs=jobs,
                               scheduler=scheduler, tls=tls, fitted_from=directory,
                               log=progress)
    out = {}
    try:
        for name in names:
            label = next((lb for lb in detectors if name == lb or name.startswith(f"{lb}[")),
                         None)
            if label is None:
                continue
            owned = {label: detectors[label]}
            store = _BatchStore(cdir, _work_name(name, n, seed, level), config.to_json())
            most = n * (max_levels + 1)
            state = {"batch": 0}
            bar = Progress(most, log=progress, label=f"sampling {name}: ")

            def g(z, nu, name=name, owned=owned, store=store, state=state, bar=bar):
                v = values(z)
                ok = admissible(v)
                margin = np.full(len(z), -np.inf)
                b = state["batch"]
                state["batch"] += 1
                if not ok.any():
                    return margin
                records = []
                for i in np.flatnonzero(ok):
                    j, stream = nu[i]
                    row = templates[names_m[j]].to_dict()
                    row.update({c: float(v[i, k]) for k, c in enumerate(cols)})
                    row["stream"] = int(stream)
                    row["group"] = "certify-sampling"
                    row["run_id"] = ""
                    row["run_id"] = run_id(row)
                    records.append(row)
                rows = pd.DataFrame(records, columns=plan.columns)
                ids = rows["run_id"].tolist()
                got = store.get(b, ids)
                computed = got is None
                if computed:
                    res = evaluate_rows(setup, rows, owned, log=progress)
                    res = res[res["detector"] == name].drop_duplicates("run_id")
                    got = (res.set_index("run_id")["margin"].reindex(ids).to_numpy(float))
                    store.put(b, ids, got)
                bar.update(len(ids), computed=computed,
                           note=f" (batch {b + 1}, {store.reused} read back; at most this many "
                                "runs: the ETA is an upper bound)")
                margin[np.flatnonzero(ok)] = np.where(np.isfinite(got), got, -np.inf)
                return margin

            log(f"sampling {name}: subset simulation, {n} runs per level")
            out[name] = subset_simulation(g, sample_prior, len(cols), n=n, p0=p0,
                                          max_levels=max_levels, confidence=level,
                                          seed=seed, redraw=new_stream, log=log)
    finally:
        setup.close()
    return out


def fill_sampling_columns(cert: pd.DataFrame, found: dict, *, seed: int, n: int) -> None:
    """Write the ``sampling_*`` columns of *cert* from :func:`sample_fa_probability`'s
    results *found*: when margin 1 was reached, P̂(margin ≥ 1) and its bounds; otherwise
    no estimate of it (NaN), the level reached and its probability
    (``sampling_reached_level``, ``sampling_reached_prob``) with its bounds, whose upper
    one bounds P(margin ≥ 1) too; the note says which, with the chains' diagnostics."""
    for name, r in found.items():
        i = cert.index[cert["detector"] == name][0]
        cert.loc[i, ["sampling_prob", "sampling_lower95", "sampling_upper95", "sampling_cov",
                     "sampling_reached_level", "sampling_reached_prob"]] = [
            r.probability, r.lower if r.reached else math.nan, r.upper, r.cov,
            r.reached_level, r.reached_probability]
        cert.loc[i, ["sampling_runs", "sampling_levels"]] = [r.evaluations, len(r.levels)]
        cert.loc[i, "sampling_note"] = sampling_note(r, seed=seed, n=n)


def sampling_note(r, *, seed: int, n: int) -> str:
    """The certificate's words on one subset simulation *r*: what it estimated, and its
    chains' diagnostics (acceptance per level, the effective sample sizes, δ)."""
    acc = ", ".join(f"{d.acceptance:.2f}" for d in r.diagnostics if d.acceptance == d.acceptance)
    ess = min((d.ess for d in r.diagnostics), default=math.nan)
    streams = [d.distinct_nuisance for d in r.diagnostics if d.distinct_nuisance]
    head = (f"subset simulation, seed {seed}, {n} runs per level, p0 = {P0:g}, "
            f"{len(r.levels)} levels, {r.evaluations} runs; acceptance per level {acc}; "
            f"smallest effective sample size {ess:.0f}; δ = {r.cov:.2f}"
            + (f"; distinct (manoeuvre, noise stream) pairs at the last level "
               f"{streams[-1]} of {n}" if streams else ""))
    if r.reached:
        return head
    if not math.isfinite(r.reached_level):
        return head + "; no sampled run could be evaluated: no estimate"
    return (head + f"; margin 1 not reached: the highest level reached is {r.reached_level:.4g}"
            f" with P(margin ≥ {r.reached_level:.4g}) ≈ {r.reached_probability:.3g}, "
            f"≤ {r.upper:.3g}, which bounds P(margin ≥ 1) from above"
            + (" (the chains stopped climbing: no run above the last level)"
               if r.stalled else "; more levels (--max-levels) would go further"))


def write_sampling_levels(directory, found: dict, config_json: str) -> None:
    """``DIR/sampling/levels.parquet``: one row per sampled detector × level with its
    threshold, conditional probability, probability, γ, δ, effective sample size,
    acceptance rates, proposal scale and seeds
    (:meth:`campaign.evidence.rare.SubsetResult.to_pandas`)."""
    frames = [r.to_pandas().assign(detector=name) for name, r in found.items()]
    if not frames:
        return
    out = pd.concat(frames, ignore_index=True)
    out = out[["detector", *[c for c in out.columns if c != "detector"]]]
    CampaignDir(directory).write_sampling_levels(out, config_json)


# ---- the command -----------------------------------------------------------------------------
@one_blas_thread()
def certify(directory, *, level: float = 0.95, sampling: int | None = None, jobs: int = 2,
            seed: int = 0, detectors=None, scheduler: str | None = None, tls=None,
            log=print, progress=None, max_levels: int = 12,
            levels=DEFAULT_LEVELS):
    """Certificate of a finished campaign directory (module docstring); writes
    ``DIR/certificate.parquet``, its exceedance curve at *levels* (1.0 always among them)
    to ``DIR/certificate-levels.parquet`` (:func:`campaign.evidence.certify.levels.level_table`) and
    the hazard table to ``DIR/certificate-hazard.parquet``, and returns them as a
    :class:`campaign.result.Certificate` (with the assumptions the bounds rest on), the
    ``certificate`` of ``campaign.load(DIR)`` from then on.

    *detectors*: the result-row names sampled (default all; the others keep NaN sampling
    columns). The exceedance curve's tail fits run on *jobs* threads, one manoeuvre each at
    a time (the same curve with any *jobs*). With *sampling*, the runs are simulated on *jobs*
    local workers or on the dask
    scheduler *scheduler* (*tls*: its :class:`campaign.execute.TlsFiles`), their batches
    kept under ``DIR/sampling/`` (resumable), *progress* (default stderr) told each batch
    (:func:`sample_fa_probability`). Raises :class:`CertifyError` (exit 2) for an unfinished
    campaign, a level outside (0.5, 1), ``sampling`` below 20 or not a multiple of 1/P0 (10),
    ``jobs`` below 1 or an unknown detector name."""
    from ..hazard import hazard_table
    from ...result import Certificate, load

    problems = []
    if not (isinstance(level, float | int) and 0.5 < float(level) < 1.0):
        problems.append(("level", level, "must be a confidence in (0.5, 1)", 0.95))
    if sampling is not None and (int(sampling) < 20 or int(sampling) % round(1 / P0)):
        problems.append(("sampling", sampling, "runs per level of the subset simulation must "
                         f"be a multiple of {round(1 / P0)} and ≥ 20 (p0 = {P0:g})", 500))
    if int(jobs) < 1:
        problems.append(("jobs", jobs, "must be ≥ 1", 2))
    if not 1 <= int(max_levels) <= 30:
        problems.append(("max_levels", max_levels, "levels of the subset simulation after "
                         f"the first, in [1, 30] (p0 = {P0:g}: 12 reach {P0 ** 12:g})", 12))
    try:
        levels = tuple(sorted(set(parse_levels(levels)) | {1.0}))
    except ArgumentError as exc:
        problems += exc.problems
    if problems:
        raise CertifyOptionError(problems)
    loaded = load(directory)
    done, planned = loaded.runs_done, loaded.runs_planned
    if not loaded.complete or (planned is not None and done < planned):
        raise CertifyError(
            f"{directory}: the campaign is unfinished ({done} of {planned} runs done); a "
            "certificate is made from every fault-free run of the plan: finish it by running "
            "the same 'fdd-campaign run' command again")
    rows = CertifyRows.of_campaign(loaded)        # never every result row at once
    curve = level_table(rows, levels, float(level), jobs=int(jobs))
    cert = certificate(rows, None, float(level), curve)
    if cert.empty:
        raise CertifyError(f"{directory}: no fault-free run finished with status ok; a "
                           "false-alarm certificate needs fault-free runs (fault = \"none\")")
    names = list(cert["detector"])
    unknown = [d for d in (detectors or ()) if d not in names]
    if unknown:
        raise CertifyOptionError.of("detectors", unknown[0], f"no such detector in "
                                    f"{directory}; choose among {', '.join(names)}")
    if sampling:
        found = sample_fa_probability(loaded.root, loaded.config, loaded.plan,
                                      list(detectors or names), n=int(sampling),
                                      level=float(level), seed=seed, jobs=int(jobs),
                                      scheduler=scheduler, tls=tls, log=log,
                                      progress=progress, max_levels=int(max_levels))
        fill_sampling_columns(cert, found, seed=int(seed), n=int(sampling))
        write_sampling_levels(loaded.root, found, loaded.config.to_json())
    hazard = hazard_table(rows, None, dict(loaded.config.requirements.fault_rate_per_fh),
                          float(level))
    cdir = CampaignDir(loaded.root)
    with cdir.locked():
        cdir.write_certificate(cert, loaded.config.to_json(), sampling_seed=int(seed))
        cdir.write_hazard(hazard, loaded.config.to_json())
        cdir.write_certificate_levels(curve, loaded.config.to_json())
    return Certificate(table=cert, levels=curve, hazard=hazard, level=float(level),
                       sampling_seed=int(seed))
