"""One object for a campaign directory: what ``campaign.run(...)`` returns and what
``campaign.load(DIR)`` reads back (docs/design.md §6, Outputs; §7, From Python).

A :class:`Campaign` holds the directory's results, summary, fitted detectors, certificate
(when ``fdd-campaign certify`` has run) and provenance (:class:`Provenance`: engine and
model versions, seed, FMU and fitted-detector digests, the campaign's identity), the same
whether just computed or read back: ``campaign.load(DIR) == campaign.run(config, DIR)``.
The heavy parts — the result rows, the run table, the fitted detectors, the certificate —
are read from the directory on first access, not when it is loaded; the summary and the
metadata are read at once (a few kB). Everything is read through
:class:`campaign.store.directory.CampaignDir`, after its files were checked against its manifest.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np
import pandas as pd

from reports.scoring.metrics import FAULT_FREE
from reports.scoring.summary import ALL_FAULTS, ALL_MANOEUVRES
from reports.render.table import format_table

from .store.directory import RESULT_BATCH_RUNS, CampaignDir, CampaignDirError, read_metadata

__all__ = ["CERTIFICATE_ASSUMPTIONS", "Campaign", "CampaignLoadError", "Certificate",
           "Provenance", "load"]


class CampaignLoadError(CampaignDirError):
    """A directory that cannot be read back as a campaign (message says why and how)."""


#: What the false-alarm certificate's bounds rest on (docs/evidence.md, "What they do not
#: mean"); the hazard table's own are :data:`campaign.evidence.hazard.ASSUMPTIONS`.
CERTIFICATE_ASSUMPTIONS: tuple[str, ...] = (
    "the fault-free runs are independent draws of one per-run false-alarm probability (the "
    "exact Clopper–Pearson bound; with Sobol designs the bounds are approximate)",
    "a probability is per run of the campaign's duration over its mix of manoeuvres and "
    "envelope, weighted as the campaign weights its manoeuvres",
    "beyond what the runs count, each manoeuvre's margins follow a generalised Pareto tail "
    "(ξ ≥ 0) of their top fifth, mixed by the manoeuvres' shares, never more than two decades "
    "under the counting bound",
    "per flight hour: false alarms arrive as a homogeneous Poisson process over flight time, "
    "independently between runs; a run of duration d is d hours of exposure",
    "margin ≥ 1 is taken as a false alarm: for a detector with a confirmation time the "
    "probability is an upper bound",
)


def _same(a, b) -> bool:
    """Two tables (or None) with the same columns, dtypes and values, NaN equal to NaN."""
    if a is None or b is None:
        return a is None and b is None
    return list(a.columns) == list(b.columns) and a.equals(b)


@dataclass(frozen=True, eq=False)
class Certificate:
    """The false-alarm certificate of a campaign (``fdd-campaign certify``,
    :func:`campaign.evidence.certify.certify`; docs/evidence.md).

    table : ``certificate.parquet``, one row per detector
        (:data:`campaign.evidence.certify.CERTIFICATE_COLUMNS`): counting bound, tail estimate and
        bound, per-hour bounds, subset simulation when sampled
    levels : ``certificate-levels.parquet``, the exceedance curve P(margin ≥ x) at every
        level (:func:`campaign.evidence.certify.levels.level_table`), or None
    hazard : ``certificate-hazard.parquet``, the hazard per flight hour of both sides
        (:func:`campaign.evidence.hazard.hazard_table`), or None
    level : confidence of the one-sided bounds (e.g. 0.95)
    sampling_seed : seed of the subset simulation (``certify --seed``)
    assumptions : what the bounds rest on (:data:`CERTIFICATE_ASSUMPTIONS`)
    """

    table: pd.DataFrame
    levels: pd.DataFrame | None = None
    hazard: pd.DataFrame | None = None
    level: float = 0.95
    sampling_seed: int | None = None
    assumptions: tuple[str, ...] = field(default=CERTIFICATE_ASSUMPTIONS)

    @classmethod
    def read(cls, cdir: CampaignDir) -> Certificate | None:
        """The certificate stored in *cdir*, or None when ``certify`` has not run."""
        table = cdir.read_certificate()
        if table is None:
            return None
        meta = read_metadata(cdir.certificate_path)
        level = float(table["level"].iloc[0]) if len(table) else 0.95
        seed = meta.get("sampling_seed")
        return cls(table=table, levels=cdir.read_certificate_levels(),
                   hazard=cdir.read_hazard(), level=level,
                   sampling_seed=None if seed is None else int(seed))

    def __eq__(self, other) -> bool:
        if not isinstance(other, Certificate):
            return NotImplemented
        return (self.level == other.level and self.sampling_seed == other.sampling_seed
                and self.assumptions == other.assumptions and _same(self.table, other.table)
                and _same(self.levels, other.levels) and _same(self.hazard, other.hazard))

    __hash__ = None

    def __repr__(self) -> str:
        bounds = ", ".join(f"{r['detector']} ≤ {r['fa_upper95_cp']:.3g}"
                           for r in self.table.to_dict(orient="records"))
        return (f"<Certificate at {100 * self.level:g} %: per-run false-alarm probability "
                f"(counting bound) {bounds or 'none'}; {len(self.assumptions)} assumptions>")


@dataclass(frozen=True)
class Provenance:
    """Where a campaign's results come from: what wrote them and with which inputs.

    engine_version : the fdd-campaign version that wrote ``summary.parquet``
    engine_versions : every version that wrote into the directory (``manifest.json``)
    model_version : the simulated models' version the plan was made with
        (:data:`campaign.plan.MODEL_VERSION`; ``servo-1`` when a plan recorded none)
    seed : the campaign's seed (``[campaign] seed``)
    identity_sha256 : SHA-256 of the campaign's identity, the part of its configuration
        that decides its results (:func:`campaign.store.directory.identity_sha256`)
    fitted_sha256 : SHA-256 of the fitted detectors' files
        (:meth:`campaign.store.directory.CampaignDir.fitted_sha256`)
    fitted_from : the campaign directory the fitted detectors were taken from
        (``run --fitted-from``), or None
    fmu_sha256 : SHA-256 of an FMU plant's file, or None
    """

    engine_version: str | None
    engine_versions: tuple[str, ...]
    model_version: str
    seed: int | None
    identity_sha256: str | None
    fitted_sha256: str | None
    fitted_from: str | None
    fmu_sha256: str | None

    @classmethod
    def read(cls, cdir: CampaignDir, meta: dict) -> Provenance:
        """The provenance recorded in *cdir* (*meta*: the summary's metadata)."""
        manifest = cdir.read_manifest() if cdir.manifest_path.exists() else {}
        plan_meta = read_metadata(cdir.plan_path) if cdir.has_plan() else {}
        seed = ((meta.get("config") or {}).get("campaign") or {}).get("seed")
        return cls(engine_version=meta.get("engine_version"),
                   engine_versions=tuple(manifest.get("engine_versions") or ()),
                   model_version=str(plan_meta.get("model_version", "servo-1")),
                   seed=None if seed is None else int(seed),
                   identity_sha256=(manifest.get("campaign") or {}).get("identity_sha256"),
                   fitted_sha256=meta.get("fitted_sha256"),
                   fitted_from=meta.get("fitted_from"), fmu_sha256=meta.get("fmu_sha256"))


class Campaign:
    """A campaign directory: results, summary, fitted detectors, certificate, provenance.

    Returned by ``campaign.run(config, out, ...)`` and by ``campaign.load(DIR)``; two
    objects of one directory compare equal (``==``) when every part read from it is the
    same. Build one with :func:`load` (or :meth:`of_dir`), not directly.

    Attributes read at once: ``root`` (the directory), ``summary`` (``summary.parquet``:
    rates, bounds, DTP statistics per detector × fault × manoeuvre), ``meta`` (its
    metadata: ``complete``, ``runs_done``, ``runs_planned``, the configuration's JSON form
    ``config``, digests), ``provenance`` (:class:`Provenance`) and ``wall_s`` (seconds the
    run took; None when read back). Read on first access: ``config``
    (:class:`campaign.config.CampaignConfig`), ``plan`` (the run table), ``results`` (one
    row per run × detector, in plan order), ``gate_results`` (only the rows the gate reads,
    streamed), ``detection_times`` (fixed-onset campaigns,
    else None), ``fitted`` (label → fitted Detector, rebuilt as data) and ``certificate``
    (:class:`Certificate`, or None before ``fdd-campaign certify``).
    """

    def __init__(self, cdir: CampaignDir, summary: pd.DataFrame, meta: dict, *,
                 wall_s: float | None = None, **known):
        self._cdir = cdir
        self.root = cdir.root
        self.summary = summary
        self.meta = meta
        self.wall_s = wall_s
        self.provenance = Provenance.read(cdir, meta)
        # parts the caller already holds (a run that just finished): not read again
        for name, value in known.items():
            if name not in self._LAZY:
                raise TypeError(f"Campaign: unknown part {name!r}")
            self.__dict__[name] = value

    _LAZY = ("config", "plan", "results", "gate_results", "detection_times", "roles")

    @classmethod
    def of_dir(cls, cdir: CampaignDir, **known) -> Campaign:
        """The campaign of directory *cdir* as it is now (its summary read; checks are the
        caller's, :func:`load`); *known*: parts already in memory."""
        summary, meta = cdir.read_summary()
        return cls(cdir, summary, meta, **known)

    # ---- read on first access ------------------------------------------------------------
    @cached_property
    def config(self):
        """The configuration the campaign ran with (``campaign.json``)."""
        from .config import CampaignConfig

        cdir = self._cdir
        return CampaignConfig.from_dict(cdir.read_config(), source=str(cdir.config_path))

    @cached_property
    def plan(self) -> pd.DataFrame:
        """The run table (``plan.parquet``)."""
        return self._cdir.read_plan()

    @cached_property
    def results(self) -> pd.DataFrame:
        """Every result row, one per run × detector, in plan order, a run's detectors in the
        order they were evaluated (runs not done are absent; an interrupted campaign has
        fewer)."""
        return plan_order(self._cdir.read_results(), self.plan)

    def result_batches(self, columns=None, batch_runs: int = RESULT_BATCH_RUNS,
                       positions: bool = False):
        """The rows of :attr:`results`, in its order, as consecutive DataFrames of the rows
        of at most *batch_runs* runs, only *columns* (and ``run_id``, ``detector``) when
        given, with *positions* also ``plan_pos``, the run's row in the plan
        (:meth:`campaign.store.directory.CampaignDir.result_batches`): what a reader of
        every row uses so as not to hold them all at once."""
        return self._cdir.result_batches(columns=columns, batch_runs=batch_runs,
                                         stored_order=True, positions=positions)

    def plan_column(self, name: str) -> np.ndarray:
        """One column of the plan, in plan order, as a NumPy array (8 bytes a run for a
        number), without reading the rest of the run table."""
        return self.plan_columns([name])[name].to_numpy()

    def plan_columns(self, names) -> pd.DataFrame:
        """Some columns of the plan (indexed by plan position, as :attr:`plan`), without
        reading the rest of the run table."""
        if "plan" in self.__dict__:
            return self.plan[list(names)]
        return self._cdir.read_plan(columns=list(names))

    def plan_rows(self, positions) -> pd.DataFrame:
        """The rows of the plan at *positions* (distinct, ascending), indexed by them, as
        the same rows of :attr:`plan` (:meth:`campaign.store.directory.CampaignDir.plan_rows`:
        a row group read at a time)."""
        if "plan" in self.__dict__:
            return self.plan.loc[np.asarray(positions, dtype=np.int64)]
        return self._cdir.plan_rows(positions)

    @cached_property
    def gate_results(self) -> pd.DataFrame:
        """The result rows the gate reads (:func:`reports.scoring.gate.gate_rows`: false alarms,
        misses and failed runs), in plan order, read a batch of runs at a time: what ``gate``
        and the report's error lines need, in memory that does not grow with the runs of a
        fault-free campaign."""
        from reports.scoring.gate import gate_rows

        parts = [gate_rows(batch) for batch in self._cdir.result_batches()]
        return pd.concat(parts, ignore_index=True) if parts else pd.DataFrame()

    @cached_property
    def roles(self):
        """What each detector is held to besides false alarms (:class:`campaign.isolation.Roles`:
        isolation, coverage, systems), from the configuration stored with the results
        (:func:`campaign.isolation.roles_of`); a run that just finished hands over those of
        the campaign it resolved."""
        from .isolation import roles_of

        return roles_of(self.meta.get("config"))

    def gate(self, requirements=None, *, all_requirements: bool = False,
             allow_errors: bool = False, allow_incomplete: bool = False):
        """The gate of this campaign (:func:`reports.scoring.gate.requirements_gate`), the one way
        to gate: ``fdd-campaign gate``, ``run``'s verdict and the report all ask it.

        *requirements*: the ``[requirements]`` to gate against in their JSON form (default:
        the campaign's own); *all_requirements*: also the MD and DTP limits (``gate
        --all-requirements``); *allow_errors*, *allow_incomplete*: as ``gate
        --allow-errors``, ``--allow-incomplete``. Reads :attr:`summary`,
        :attr:`gate_results`, :attr:`roles` and :attr:`coverage` of *self* (also of an
        object that stands for a campaign with other rows, e.g. at other threshold
        scales)."""
        from reports.scoring.gate import requirements_gate

        if requirements is None:
            requirements = self.config.to_dict()["requirements"]
        return requirements_gate(self.summary, self.gate_results, requirements,
                                 roles=self.roles, coverage=self.coverage,
                                 all_requirements=all_requirements, allow_errors=allow_errors,
                                 allow_incomplete=allow_incomplete)

    @cached_property
    def detection_times(self) -> pd.DataFrame | None:
        """First alarm per group × detector variant (``detection-times.parquet``,
        :mod:`reports.scoring.detection_times`) of a fixed-onset campaign; None for others."""
        return self._cdir.read_detection_times()

    @cached_property
    def fitted(self) -> dict:
        """The fitted detectors: label → Detector, rebuilt from ``fitted/`` as data
        (:meth:`campaign.store.directory.CampaignDir.read_fitted`), never unpickled, each at
        the ``threshold_scale`` of its ``[[detector]]`` entry."""
        from detectors.base import set_threshold_scales

        return set_threshold_scales(
            {d.label: self._cdir.read_fitted(d.label, d.name) for d in self.config.detectors},
            {d.label: d.scale for d in self.config.detectors})

    @cached_property
    def evaluated(self) -> dict:
        """What the campaign's runs are scored with: the fitted detectors (:attr:`fitted`)
        followed by its detection systems (``[[system]]``,
        :class:`detectors.system.DetectionSystem`), name → Detector."""
        from detectors.system import with_systems

        return with_systems(self.fitted, self.config.systems)

    @cached_property
    def certificate(self) -> Certificate | None:
        """The false-alarm certificate, or None when ``fdd-campaign certify`` has not run."""
        return Certificate.read(self._cdir)

    # ---- read at once ----------------------------------------------------------------------
    @property
    def out(self) -> Path:
        """Deprecated former name of :attr:`root` (of the object ``campaign.run`` returned)."""
        warnings.warn("Campaign.out is deprecated: use Campaign.root", DeprecationWarning,
                      stacklevel=2)
        return self.root

    @property
    def name(self) -> str | None:
        return ((self.meta.get("config") or {}).get("campaign") or {}).get("name")

    @property
    def complete(self) -> bool:
        """Whether every run of the plan was attempted (False after an interruption)."""
        return bool(self.meta.get("complete", True))

    @property
    def runs_done(self) -> int:
        return int(self.meta.get("runs_done") or 0)

    @property
    def runs_planned(self) -> int | None:
        planned = self.meta.get("runs_planned")
        return None if planned is None else int(planned)

    @property
    def coverage(self) -> tuple[int, int] | None:
        """(runs done, runs planned) as the gate checks them; None when the directory does
        not record its planned runs."""
        planned = self.runs_planned
        return None if planned is None else (self.runs_done, planned)

    @property
    def detector_names(self) -> list[str]:
        """The result-row names of the detectors (variants apart), in the summary's order."""
        return list(dict.fromkeys(self.summary["detector"].astype(str))) \
            if "detector" in self.summary else []

    def table(self) -> str:
        """The summary table, then the published table a suite member names beside it
        (:func:`campaign.suite.reference_text`)."""
        from .suite import reference_text

        return format_table(self.summary) + reference_text(self.root, self.summary)

    def counts(self) -> list[str]:
        """Per detector, one line of what the summary counts: false alarms of the
        fault-free runs, missed detections of the faulty ones."""
        s = self.summary
        if s.empty:
            return []
        every = s[s["manoeuvre"] == ALL_MANOEUVRES]
        out = []
        for name in self.detector_names:
            mine = every[every["detector"].astype(str) == name]
            free = mine[mine["fault"] == FAULT_FREE]
            faulty = mine[mine["fault"] == ALL_FAULTS]
            parts = []
            if len(free):
                fa, n = int(free["fa_count"].sum()), int(free["n_runs"].sum())
                parts.append(f"{fa} false alarm{'' if fa == 1 else 's'} in {n} fault-free runs")
            if len(faulty):
                md, n = int(faulty["md_count"].sum()), int(faulty["n_runs"].sum())
                parts.append(f"{md} missed of {n} faulty")
            out.append(f"{name}: {', '.join(parts) or 'no run scored'}")
        return out

    def __repr__(self) -> str:
        planned = "?" if self.runs_planned is None else self.runs_planned
        state = "complete" if self.complete else "interrupted"
        prov = self.provenance
        lines = [f"<Campaign {self.name!r} in {self.root}: {self.runs_done} of {planned} runs "
                 f"({state}), model {prov.model_version}, seed {prov.seed}"]
        lines += [f"  {line}" for line in self.counts()]
        cert = "certificate.parquet" if self._cdir.certificate_path.exists() else None
        lines.append(f"  certificate: {'yes' if cert else 'none (fdd-campaign certify DIR)'}>")
        return "\n".join(lines)

    def __eq__(self, other) -> bool:
        if not isinstance(other, Campaign):
            return NotImplemented
        return (self.root.resolve() == other.root.resolve() and self.meta == other.meta
                and self.provenance == other.provenance
                and self.config.to_json() == other.config.to_json()
                and _same(self.summary, other.summary) and _same(self.plan, other.plan)
                and _same(self.results, other.results)
                and _same(self.detection_times, other.detection_times)
                and self.certificate == other.certificate
                and _same_fitted(self._cdir, other._cdir, self.config))

    __hash__ = None


def _same_fitted(a: CampaignDir, b: CampaignDir, config) -> bool:
    """Whether two directories hold the same fitted detectors (the same files)."""
    labels = [d.label for d in config.detectors]
    return a.fitted_sha256(labels) == b.fitted_sha256(labels)


def plan_order(results: pd.DataFrame, plan: pd.DataFrame) -> pd.DataFrame:
    """*results* sorted by their runs' order in *plan*, index reset. Within a run the rows
    keep their stored order (the detectors in the order they were evaluated)."""
    if results.empty:
        return results
    order = pd.Series(np.arange(len(plan)), index=plan["run_id"].to_numpy())
    position = results["run_id"].map(order).to_numpy(dtype=float)
    if np.all(position[1:] >= position[:-1]):      # in order already (one copy saved)
        return results.reset_index(drop=True)
    return results.take(np.argsort(position, kind="stable")).reset_index(drop=True)


def load(directory) -> Campaign:
    """The campaign in *directory* (``fdd-campaign run --out``) after checking its files
    against its manifest (:meth:`campaign.store.directory.CampaignDir.check_manifest`,
    :class:`campaign.store.directory.ManifestError`); :class:`CampaignLoadError` (exit 2) names
    what is missing and what to do: no such directory, a suite's directory (give one of its
    campaigns), no summary yet (an interrupted run: run it again), or a directory of
    another kind."""
    from .suite import is_suite_dir

    root = Path(directory)
    cdir = CampaignDir(root)
    if not root.exists():
        raise CampaignLoadError(f"{root} does not exist; run a campaign into it first: "
                                f"fdd-campaign run CAMPAIGN --out {root}")
    if not root.is_dir():
        raise CampaignLoadError(f"{root} is not a directory; give the --out directory of "
                                "'fdd-campaign run'")
    if is_suite_dir(root) and not cdir.is_campaign():
        members = sorted(p.name for p in root.iterdir() if CampaignDir(p).is_campaign())
        raise CampaignLoadError(
            f"{root} is the directory of a suite of campaigns; give one of its campaign "
            f"directories: {', '.join(str(root / m) for m in members) or '(none run yet)'}")
    if not cdir.has_summary():
        raise CampaignLoadError(
            f"{root} holds no results summary: "
            + ("the campaign was stopped before it wrote one; finish it by running the same "
               "'fdd-campaign run' command again" if cdir.has_plan() else
               "it is not a campaign directory written by 'fdd-campaign run'"))
    cdir.refuse_pickles()      # a directory of an older version: say how to go on
    cdir.check_manifest()      # every file as the run wrote it (ManifestError, exit 2)
    missing = cdir.missing_outputs()
    if missing:
        raise CampaignLoadError(
            f"{root} is not a campaign directory: it holds no {missing[0]}; give the --out "
            "directory of a finished 'fdd-campaign run' (rerun it to finish an "
            "interrupted one)")
    return Campaign.of_dir(cdir)
