"""The campaign directory: Parquet files written atomically, resume by replaying shards.

Layout (docs/design.md §6, Outputs)::

    DIR/campaign.json         the frozen configuration this directory belongs to
    DIR/plan.parquet          the run table
    DIR/learning.parquet      the learning-set run table
    DIR/fitted/LABEL.pkl      each fitted detector (and LABEL.json: its learned values)
    DIR/runs/part-NNNNNN.parquet  result rows, one shard per finished chunk
    DIR/summary.parquet       rates, bounds, DTP statistics
    DIR/detection-times.parquet  first alarm per group × detector variant (fixed-onset
                              campaigns only, :mod:`reports.detection_times`)
    DIR/report.html           the HTML report (``fdd-campaign report``)

:class:`CampaignDir` alone names these files and reads and writes them; the rest of the
engine asks it. Every file is written under a temporary name and moved into place with
``os.replace``, so a crash or a kill leaves either the old file or the new one, never a torn
one; leftover temporary files are removed when the directory is opened again. Every Parquet
file carries the campaign configuration, the engine version and its row count in its schema
metadata.
"""

from __future__ import annotations

import json
import os
import pickle
import tempfile
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

METADATA_KEY = b"fdd_campaign"
SHARD_GLOB = "part-*.parquet"


def engine_version() -> str:
    try:
        return version("fdd-campaign")
    except PackageNotFoundError:  # running from a source tree that is not installed
        return "0+unknown"


class CampaignDirError(ValueError):
    """The output directory cannot be used for this campaign (message says why and how)."""


def _atomic_write_bytes(path: Path, write) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def write_parquet(df: pd.DataFrame, path: Path, config_json: str, **extra) -> None:
    """Write *df* to *path* atomically with the campaign metadata in the schema."""
    table = pa.Table.from_pandas(df, preserve_index=False)
    meta = dict(table.schema.metadata or {})
    meta[METADATA_KEY] = json.dumps({
        "engine_version": engine_version(), "rows": len(df),
        "config": json.loads(config_json), **extra,
    }).encode()
    table = table.replace_schema_metadata(meta)
    _atomic_write_bytes(Path(path), lambda tmp: pq.write_table(table, tmp))


def read_metadata(path: Path) -> dict:
    """The campaign metadata stored in a Parquet file by :func:`write_parquet`."""
    meta = pq.read_schema(path).metadata or {}
    return json.loads(meta.get(METADATA_KEY, b"{}"))


def write_text(path: Path, text: str) -> None:
    _atomic_write_bytes(Path(path), lambda tmp: Path(tmp).write_text(text))


def write_pickle(path: Path, obj) -> None:
    _atomic_write_bytes(Path(path), lambda tmp: Path(tmp).write_bytes(pickle.dumps(obj)))


def _plain(value):
    """*value* with NumPy arrays and scalars made JSON-serialisable (lists, floats, ints)."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    if isinstance(value, dict):
        return {str(k): _plain(x) for k, x in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(x) for x in value]
    return value


def fitted_json(det) -> str:
    """The human-readable form of a fitted detector (``fitted/LABEL.json``): its class,
    parameters and learned values (:meth:`detectors.base.Detector.fitted_state`)."""
    return json.dumps({"detector": type(det).__name__, "params": _plain(det.get_params()),
                       "fitted": _plain(det.fitted_state())}, indent=2, default=str)


#: ``[runner]`` keys that do not change any result (rows are bit-identical across chunk
#: sizes; a time limit only decides which runs are retried), so a directory resumed with
#: other values still holds the same campaign. ``engine`` is not among them: the two
#: engines may differ in the last bit.
RESULT_NEUTRAL_RUNNER_KEYS: tuple[str, ...] = ("chunk_size", "run_timeout_s")


def campaign_identity(config: dict) -> dict:
    """The part of a campaign's JSON form that decides its results."""
    out = dict(config)
    runner = {k: v for k, v in (out.get("runner") or {}).items()
              if k not in RESULT_NEUTRAL_RUNNER_KEYS}
    out["runner"] = runner
    return out


class CampaignDir:
    """One campaign's output directory: the only code that names, reads and writes its files.

    Every Parquet file is written with the campaign's JSON form (*config_json*, as
    ``CampaignConfig.to_json()``) in its metadata (:func:`write_parquet`).
    """

    def __init__(self, root):
        self.root = Path(root)
        self.config_path = self.root / "campaign.json"
        self.plan_path = self.root / "plan.parquet"
        self.learning_path = self.root / "learning.parquet"
        self.summary_path = self.root / "summary.parquet"
        self.detection_times_path = self.root / "detection-times.parquet"
        self.report_path = self.root / "report.html"
        self.runs = self.root / "runs"
        self.fitted = self.root / "fitted"

    def is_campaign(self) -> bool:
        """Whether the directory belongs to a campaign (holds ``campaign.json``)."""
        return self.config_path.exists()

    def missing_outputs(self) -> list[str]:
        """Names of the files a finished run leaves (``campaign.json``, ``plan.parquet``,
        ``summary.parquet``) that the directory does not hold."""
        return [p.name for p in (self.config_path, self.plan_path, self.summary_path)
                if not p.exists()]

    # ---- identity ---------------------------------------------------------------------
    def open(self, config_json: str) -> bool:
        """Create the directory, or check that it holds this same campaign.

        Returns True when earlier results exist (a resume). Raises
        :class:`CampaignDirError` when the directory holds a different campaign.
        """
        stored = self.config_path
        if self.root.exists() and not self.root.is_dir():
            raise CampaignDirError(f"{self.root} exists and is not a directory")
        if stored.exists():
            if (campaign_identity(json.loads(stored.read_text()))
                    != campaign_identity(json.loads(config_json))):
                raise CampaignDirError(
                    f"{self.root} holds the results of a different campaign (its campaign.json "
                    "differs from this configuration beyond [runner] chunk_size and "
                    "run_timeout_s); choose another --out directory, or delete this one to "
                    "start again"
                )
        elif self.root.exists() and any(self.root.iterdir()):
            raise CampaignDirError(
                f"{self.root} is not empty and holds no campaign.json; choose an empty or new "
                "--out directory"
            )
        self.runs.mkdir(parents=True, exist_ok=True)
        self.fitted.mkdir(parents=True, exist_ok=True)
        for leftover in list(self.root.rglob(".*.tmp")):
            leftover.unlink()
        if not stored.exists():
            write_text(stored, config_json)
        return any(self.runs.glob(SHARD_GLOB))

    def read_config(self) -> dict:
        """The stored ``campaign.json`` as a dict; :class:`CampaignDirError` when it is not
        valid JSON."""
        try:
            return json.loads(self.config_path.read_text())
        except json.JSONDecodeError as exc:
            raise CampaignDirError(f"{self.config_path} is not valid JSON ({exc}); the "
                                   "directory is damaged: rerun the campaign") from None

    # ---- run tables -------------------------------------------------------------------
    def has_plan(self) -> bool:
        return self.plan_path.exists()

    def write_plan(self, plan: pd.DataFrame, config_json: str) -> None:
        """Write the run table ``plan.parquet``."""
        write_parquet(plan, self.plan_path, config_json, kind="plan")

    def read_plan(self) -> pd.DataFrame:
        return pd.read_parquet(self.plan_path)

    def write_learning(self, learning: pd.DataFrame, config_json: str) -> None:
        """Write the learning-set run table ``learning.parquet``."""
        write_parquet(learning, self.learning_path, config_json, kind="learning")

    # ---- fitted detectors -------------------------------------------------------------
    def _fitted_pickle(self, label: str) -> Path:
        return self.fitted / f"{label}.pkl"

    def has_fitted(self, label: str) -> bool:
        """Whether the fitted detector *label* is stored."""
        return self._fitted_pickle(label).exists()

    def write_fitted(self, label: str, det) -> None:
        """Store the fitted detector *label*: ``fitted/LABEL.pkl`` (the object, read back by
        :meth:`read_fitted`) and ``fitted/LABEL.json`` (its learned values, for people)."""
        write_pickle(self._fitted_pickle(label), det)
        write_text(self.fitted / f"{label}.json", fitted_json(det))

    def read_fitted(self, label: str):
        """The fitted detector *label* stored by :meth:`write_fitted`;
        :class:`CampaignDirError` when it is missing."""
        path = self._fitted_pickle(label)
        if not path.exists():
            raise CampaignDirError(
                f"{path} is missing: the fitted detector {label!r} is needed to re-simulate "
                "runs; copy the whole campaign directory (fitted/ included) or rerun "
                "'fdd-campaign run' into it")
        return pickle.loads(path.read_bytes())

    # ---- summary and detection times --------------------------------------------------
    def has_summary(self) -> bool:
        return self.summary_path.exists()

    def write_summary(self, summary: pd.DataFrame, config_json: str, **extra) -> None:
        """Write ``summary.parquet``; *extra* (``complete``, ``runs_done``, ``runs_planned``)
        goes into its metadata."""
        write_parquet(summary, self.summary_path, config_json, kind="summary", **extra)

    def read_summary(self) -> tuple[pd.DataFrame, dict]:
        """(summary, metadata of ``summary.parquet``)."""
        return (pq.read_table(self.summary_path).to_pandas(),
                read_metadata(self.summary_path))

    def write_detection_times(self, times: pd.DataFrame, config_json: str) -> None:
        """Write ``detection-times.parquet``
        (:func:`reports.detection_times.detection_time_table`)."""
        write_parquet(times, self.detection_times_path, config_json, kind="detection_times")

    def read_detection_times(self) -> pd.DataFrame | None:
        """The stored detection times, or None when the campaign has none."""
        if not self.detection_times_path.exists():
            return None
        return pd.read_parquet(self.detection_times_path)

    def write_report(self, page: str, path=None) -> Path:
        """Write the HTML report *page* to *path* (default ``report.html`` here)."""
        path = Path(path) if path else self.report_path
        write_text(path, page)
        return path

    # ---- shards -----------------------------------------------------------------------
    def shard_paths(self) -> list[Path]:
        return sorted(self.runs.glob(SHARD_GLOB))

    def next_shard_path(self) -> Path:
        paths = self.shard_paths()
        last = int(paths[-1].stem.split("-")[1]) if paths else -1
        return self.runs / f"part-{last + 1:06d}.parquet"

    def write_shard(self, results: pd.DataFrame, config_json: str) -> None:
        """Store the result rows of one finished chunk as the next shard."""
        write_parquet(results, self.next_shard_path(), config_json, kind="results")

    def read_results(self) -> pd.DataFrame:
        """Every result row; of a run written more than once (a rerun retrying its error or
        timeout rows), only the rows of its latest shard are kept: a chunk writes all the
        rows of its runs at once, and failure rows name the detector label where the rows
        of a successful run may name its variants."""
        paths = self.shard_paths()
        if not paths:
            return pd.DataFrame()
        frames = []
        for seq, path in enumerate(paths):
            df = pq.read_table(path).to_pandas()
            df["_seq"] = seq
            frames.append(df)
        df = pd.concat(frames, ignore_index=True)
        latest = df.groupby("run_id", sort=False)["_seq"].transform("max")
        df = df[df["_seq"] == latest]
        df = df.sort_values("_seq", kind="stable").drop_duplicates(["run_id", "detector"],
                                                                   keep="last")
        return df.drop(columns="_seq").reset_index(drop=True)

    def done_run_ids(self) -> set[str]:
        """Runs whose every result row has status ``ok`` (errors are retried on resume)."""
        df = self.read_results()
        if df.empty:
            return set()
        bad = set(df.loc[df["status"] != "ok", "run_id"])
        return set(df["run_id"]) - bad
