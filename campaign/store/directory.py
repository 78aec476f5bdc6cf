"""The campaign directory: Parquet and JSON files written atomically, a manifest of their
SHA-256 digests, a lock, resume by replaying shards.

Layout (docs/design.md §6, Outputs)::

    DIR/campaign.json         the frozen configuration this directory belongs to
    DIR/manifest.json         SHA-256 and size of every file below, the engine version and
                              the campaign's identity (:meth:`CampaignDir.verify`)
    DIR/plan.parquet          the run table
    DIR/learning.parquet      the learning-set run table
    DIR/fitted/LABEL.json     each fitted detector as data: registry name, parameters and
    DIR/fitted/LABEL.npz      learned values (:mod:`detectors.state`), arrays in the .npz
    DIR/fitted-origin.json    only when the detectors were fitted in another campaign
                              directory (``run --fitted-from``): where from, and the SHA-256
                              of the fitted files (:meth:`CampaignDir.fitted_sha256`)
    DIR/runs/part-NNNNNN.parquet  result rows, one shard per finished chunk
    DIR/summary.parquet       rates, bounds, DTP statistics
    DIR/detection-times.parquet  first alarm per group × detector variant (fixed-onset
                              campaigns only, :mod:`reports.scoring.detection_times`)
    DIR/tradeoff.parquet      the results at other threshold scales (``fdd-campaign tradeoff``,
                              :mod:`campaign.tradeoff`)
    DIR/report.html           the HTML report (``fdd-campaign report``; not in the manifest)
    DIR/worst-case/NAME-nN-seedS/  one worst-case search of ``gate --worst-case N``
                              (:meth:`CampaignDir.worst_case_search_dir`): ``search.parquet``,
                              ``worst.toml`` (the corpus later gates replay first) and
                              ``learned/``; ``DIR/worst-case/replay/`` the corpus replay's
                              work directory. Not in the manifest (as ``sampling/`` and
                              ``validation/``): evidence re-evaluated by every gate
    DIR/.fdd-campaign.lock    held by the run writing into the directory
                              (:class:`campaign.store.lock.DirLock`)

:class:`CampaignDir` alone names these files and reads and writes them; the rest of the
engine asks it. Every file is written under a temporary name and moved into place with
``os.replace``, so a crash or a kill leaves either the old file or the new one, never a torn
one; leftover temporary files are removed when the directory is opened again. Files and
directories get the modes the user's umask gives (``0644``/``0755`` under umask 022). Every
Parquet file carries the campaign configuration, the engine version and its row count in its
schema metadata.

Nothing read from a campaign directory is ever unpickled: a fitted detector is rebuilt from
its registry name, parameters and learned values (:meth:`CampaignDir.read_fitted`), and a
directory written by an older version (fitted detectors stored as ``.pkl``) is refused with
the way forward (docs/security.md).

The manifest is updated atomically after each file lands and before a file is replaced or
removed, so it never claims a file that is not there, or the old content of a replaced one;
a file written just before a crash may be missing from it, and resuming removes such a file
(a shard's runs are run again). The runner records its shards at most every
:data:`MANIFEST_DEFER_S` seconds (``write_shard(..., defer_manifest=True)``, then
:meth:`CampaignDir.flush_manifest`): the manifest is rewritten whole, so one rewrite per
shard made a campaign's manifest writes grow with the square of its shards (7 ms a shard at
4 000 shards); a kill then re-runs at most those seconds of shards. It makes a directory
tamper-evident, not tamper-proof: anyone who can write the files can write a matching
manifest too.
"""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from reports.scoring.alarm_steps import ALARM_SCALES, ALARM_STEPS_COLUMN
from scenarios.errors import ArgumentError, InputError

from .lock import LOCK_NAME, CampaignLockedError, DirLock, holder_text
from .files import (atomic_write_bytes, engine_version, read_metadata, sha256_of,
                    write_parquet, write_parquet_blocks, write_text)

__all__ = ["CampaignDir", "CampaignDirError", "CampaignLockedError", "DirLock", "ManifestError",
           "OutDirError", "SearchDir",
           "campaign_identity", "engine_version", "read_metadata", "sha256_of", "write_parquet",
           "write_text"]

SHARD_GLOB = "part-*.parquet"
#: Files of one worst-case search directory (``fdd-campaign falsify --out DIR`` and each
#: search of ``gate --worst-case``): every evaluated run, and the campaign file of explicit
#: ``[[run]]`` entries replaying the worst of them (written last: a search is finished when
#: it is there).
SEARCH_FILE = "search.parquet"
WORST_FILE = "worst.toml"
#: Sub-directory of a campaign directory holding the searches of ``gate --worst-case``.
WORST_CASE_DIR = "worst-case"
#: Sub-directory of the subset simulations of ``certify --sampling``: the runner's work
#: directory, one directory of evaluated batches per detector, and the levels file.
SAMPLING_DIR = "sampling"
#: File under :data:`SAMPLING_DIR` with the levels of every sampled detector.
SAMPLING_LEVELS_FILE = "levels.parquet"
#: Sub-directory of ``certify --validate``: a campaign directory per validation and its
#: coverage table beside it.
VALIDATION_DIR = "validation"
MANIFEST_NAME = "manifest.json"
#: ``format`` of manifest.json and of fitted/LABEL.json: a reader refuses any other.
MANIFEST_FORMAT = "fdd-campaign manifest 1"
#: Longest time [s] a shard written with ``defer_manifest=True`` waits for the manifest to
#: be rewritten with it (:meth:`CampaignDir.write_shard`).
MANIFEST_DEFER_S = 2.0
FITTED_FORMAT = "fdd-campaign fitted detector 1"


#: Result columns a shard may lack: written by a later version than the directory's first
#: shards, or left out of a shard where every value is null (:func:`_stored_alarm_steps`).
OPTIONAL_RESULT_COLUMNS: tuple[str, ...] = (ALARM_STEPS_COLUMN,)
#: Key of a shard's metadata listing the threshold scales its ``alarm_steps`` hold.
ALARM_SCALES_KEY = "alarm_scales"


def _stored_alarm_steps(results: pd.DataFrame) -> tuple[pd.DataFrame, dict]:
    """(*results* as a shard stores them, the shard's extra metadata): the ``alarm_steps``
    column (:mod:`reports.scoring.alarm_steps`) left out when every value is null (a chunk of
    fault-free runs: about 500 bytes of schema a shard), else kept, packed
    (:func:`campaign.store.files.write_parquet`), with the scales it holds in the metadata."""
    if ALARM_STEPS_COLUMN not in results.columns:
        return results, {}
    if results[ALARM_STEPS_COLUMN].isna().all():
        return results.drop(columns=ALARM_STEPS_COLUMN), {}
    return results, {"packed": (ALARM_STEPS_COLUMN,), ALARM_SCALES_KEY: list(ALARM_SCALES)}


def _read_optional(path: Path) -> pd.DataFrame | None:
    """The table at *path*, or None when the command that writes it has not run."""
    return pd.read_parquet(path) if path.exists() else None


class CampaignDirError(InputError, ValueError):
    """The output directory cannot be used for this campaign (message says why and how)."""


class OutDirError(CampaignDirError, ArgumentError):
    """A campaign directory that cannot take this campaign, whose message names the
    argument *out* that gives it (``campaign.run(config, out)``); ``fdd-campaign`` names
    its option (:class:`scenarios.errors.ArgumentError`)."""


class ManifestError(CampaignDirError):
    """The files of a campaign directory do not match its manifest; ``problems`` lists each
    file that differs, is missing or is not in the manifest."""

    def __init__(self, message: str, problems: list[str] = ()):
        super().__init__(message)
        self.problems = list(problems)

    def __reduce__(self):
        return (type(self), (str(self), self.problems))


#: ``[runner]`` keys that do not change any result (rows are bit-identical across chunk
#: sizes; a time limit only decides which runs are retried), so a directory resumed with
#: other values still holds the same campaign. ``engine`` is not among them: the two
#: engines may differ in the last bit.
RESULT_NEUTRAL_RUNNER_KEYS: tuple[str, ...] = ("chunk_size", "run_timeout_s")


def _current_form(config: dict) -> dict:
    """A stored campaign's JSON form as this version writes it: a directory written before a
    key moved (docs/campaign-file.md, "Keys that moved") or before a key with a default was
    added still resumes. A form this version cannot read is returned as it is (and then
    differs from any campaign it is compared with)."""
    import warnings

    from ..config import CampaignConfig, ConfigError

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FutureWarning)
            return json.loads(CampaignConfig.from_dict(config).to_json())
    except ConfigError:
        return config


def campaign_identity(config: dict) -> dict:
    """The part of a campaign's JSON form that decides its results."""
    out = dict(config)
    runner = {k: v for k, v in (out.get("runner") or {}).items()
              if k not in RESULT_NEUTRAL_RUNNER_KEYS}
    out["runner"] = runner
    return out


#: Differences named at most by :func:`identity_changes` (the rest are counted).
MAX_CHANGES_NAMED = 8
#: A key one of two campaigns does not have.
_ABSENT = object()


def _value_text(value) -> str:
    """*value* of a campaign's JSON form as a short text (TOML-like, cut at 40 characters)."""
    if value is _ABSENT:
        return "(absent)"
    text = json.dumps(value, ensure_ascii=False, separators=(", ", " = "))
    return text if len(text) <= 40 else text[:37] + "..."


def _table_title(section: str, index: int, table: Mapping) -> str:
    """``[[group]] 2 ("liquid_jam@cruise")``: the *index*-th (0-based) table of an array of
    tables, counted from 1 as in the file, with its name or label."""
    name = table.get("name") if section != "detector" else table.get("label")
    return f"[[{section}]] {index + 1}" + (f" ({json.dumps(name)})" if name else "")


def _dict_changes(where: str, old: Mapping, new: Mapping, out: list[str],
                  prefix: str = "") -> None:
    """Each key of *old* and *new* (dicts) whose values differ, as ``WHERE key: old → new``;
    dicts are entered (``params.safety``)."""
    for key in list(old) + [k for k in new if k not in old]:
        a, b = old.get(key, _ABSENT), new.get(key, _ABSENT)
        if a == b:
            continue
        if isinstance(a, dict) and isinstance(b, dict):
            _dict_changes(where, a, b, out, prefix=f"{prefix}{key}.")
        else:
            out.append(f"{where} {prefix}{key}: {_value_text(a)} → {_value_text(b)}")


def identity_changes(stored: Mapping, new: Mapping) -> list[str]:
    """What differs between two campaigns' identities (:func:`campaign_identity` of their
    JSON forms), in the campaign file's words, one text per changed value:
    ``[campaign] seed: 0 → 5``, ``[[group]] 2 ("liquid_jam@cruise") count: 333 → 100``,
    ``[faults.runaway] rate_deg_s: [1.0, 10.0] → [1.0, 5.0]``, ``[[detector]] 3 ("x")
    added``. Empty when they are the same campaign."""
    out: list[str] = []
    for section in list(stored) + [k for k in new if k not in stored]:
        a, b = stored.get(section, _ABSENT), new.get(section, _ABSENT)
        if a == b:
            continue
        if isinstance(a, list) and isinstance(b, list):      # an array of tables
            for i in range(max(len(a), len(b))):
                if i >= len(a):
                    out.append(f"{_table_title(section, i, b[i])} added")
                elif i >= len(b):
                    out.append(f"{_table_title(section, i, a[i])} removed")
                elif a[i] != b[i]:
                    if isinstance(a[i], dict) and isinstance(b[i], dict):
                        _dict_changes(_table_title(section, i, a[i]), a[i], b[i], out)
                    else:
                        out.append(f"[[{section}]] {i + 1}: {_value_text(a[i])} → "
                                   f"{_value_text(b[i])}")
        elif isinstance(a, dict) and isinstance(b, dict):
            for key in list(a) + [k for k in b if k not in a]:
                x, y = a.get(key, _ABSENT), b.get(key, _ABSENT)
                if x == y:
                    continue
                if isinstance(x, dict) and isinstance(y, dict):   # [faults.runaway]
                    _dict_changes(f"[{section}.{key}]", x, y, out)
                else:
                    out.append(f"[{section}] {key}: {_value_text(x)} → {_value_text(y)}")
        else:
            out.append(f"[{section}]: {_value_text(a)} → {_value_text(b)}")
    return out


def changes_text(changes: list[str]) -> str:
    """*changes* (:func:`identity_changes`) joined with "; ", the first
    :data:`MAX_CHANGES_NAMED` of them and the count of the rest."""
    named = "; ".join(changes[:MAX_CHANGES_NAMED])
    rest = len(changes) - MAX_CHANGES_NAMED
    return named + (f"; and {rest} more" if rest > 0 else "")


#: Top-level files of a campaign directory that the manifest covers (with every file under
#: ``runs/`` and ``fitted/``).
MANIFEST_TOP_FILES: tuple[str, ...] = ("campaign.json", "plan.parquet", "learning.parquet",
                                       "summary.parquet", "detection-times.parquet",
                                       "fitted-origin.json", "certificate.parquet",
                                       "certificate-hazard.parquet",
                                       "certificate-levels.parquet", "tradeoff.parquet")


def identity_sha256(config_json: str) -> str:
    """SHA-256 of the canonical JSON of :func:`campaign_identity` of a campaign's JSON form."""
    ident = json.dumps(campaign_identity(json.loads(config_json)), sort_keys=True,
                       separators=(",", ":"), ensure_ascii=False)
    return hashlib.sha256(ident.encode()).hexdigest()


def _is_temporary(path: Path) -> bool:
    return path.name.startswith(".") and path.name.endswith(".tmp")


#: Rows of a row group of ``plan.parquet``: reading the plan a chunk at a time
#: (:meth:`CampaignDir.plan_batches`) decodes one row group at a time, about 0.7 MB; a plan
#: written in one group (before this layout, or by pyarrow's default) is decoded whole,
#: about 1 KB per run.
PLAN_ROW_GROUP_ROWS = 2048
#: Rows of the plan decoded at once by a reader that scans some of its columns
#: (:meth:`CampaignDir.plan_batches`): a few MB, whatever the size of the plan.
PLAN_SCAN_ROWS = 65536

#: Runs whose rows one batch of :meth:`CampaignDir.result_batches` holds [runs]: 5000 runs
#: of six detector variants are about 30 000 rows, some 10 MB as a DataFrame.
RESULT_BATCH_RUNS = 5000


class _RunIndex:
    """Positions of run ids in a plan's order, by binary search in the sorted ids (bytes):
    about 28 bytes per run of the plan, where a dict of str would take over 100."""

    def __init__(self, run_ids):
        ids = _as_bytes(run_ids)
        self.order = np.argsort(ids, kind="stable")
        self.sorted = ids[self.order]

    def __len__(self) -> int:
        return len(self.sorted)

    def positions(self, run_ids) -> np.ndarray:
        """Each run id's position in the plan; ``len(self)`` for one that is not in it."""
        ids = _as_bytes(run_ids)
        n = len(self.sorted)
        if n == 0:
            return np.full(len(ids), 0, dtype=np.int64)
        at = np.minimum(np.searchsorted(self.sorted, ids), n - 1)
        return np.where(self.sorted[at] == ids, self.order[at], n).astype(np.int64)


def _as_bytes(run_ids) -> np.ndarray:
    """Run ids as a NumPy bytes array (UTF-8)."""
    if hasattr(run_ids, "to_pylist"):          # a pyarrow array
        fixed = _fixed_width_bytes(run_ids)
        if fixed is not None:
            return fixed
        run_ids = run_ids.to_pylist()
    values = np.asarray(run_ids, dtype=object)
    if values.size == 0:
        return np.empty(0, dtype="S1")
    try:
        return values.astype("S")
    except UnicodeEncodeError:
        return np.char.encode(values.astype(str), "utf-8")


def _fixed_width_bytes(column) -> np.ndarray | None:
    """The values of a pyarrow string column whose values all have one length in bytes (as
    run ids do), as a NumPy bytes array read from its data buffer: no Python string per
    value (about 75 bytes each, 75 MB for the run ids of 10⁶ runs). None for any other
    column (nulls, values of several lengths, another type)."""
    array = column.combine_chunks() if hasattr(column, "combine_chunks") else column
    if array.type not in (pa.string(), pa.large_string()) or array.null_count or not len(array):
        return None
    _, offsets, data = array.buffers()
    kind = np.int32 if array.type == pa.string() else np.int64
    offsets = np.frombuffer(offsets, dtype=kind)[array.offset:array.offset + len(array) + 1]
    width = int(offsets[1] - offsets[0])
    if width < 1 or not (np.diff(offsets) == width).all():
        return None
    values = np.frombuffer(data, dtype=np.uint8)[offsets[0]:offsets[-1]]
    ids = values.view(f"S{width}")
    if (np.char.str_len(ids) != width).any():   # a NUL at the end: bytes arrays drop it
        return None
    return ids


def _plan_ordered(rows: pd.DataFrame, stored_order: bool = False,
                  positions: bool = False) -> pd.DataFrame:
    """Rows (with their plan position ``_pos``) deduplicated as :meth:`CampaignDir.read_results`
    does (the last row of a run and detector) and sorted by plan position, then detector
    (with *stored_order*: a run's rows in the order they were stored, the rows of a run
    being those of one shard); *positions* keeps ``_pos`` as the column ``plan_pos``."""
    # by run id, not position: the runs outside the plan all have the position n
    rows = rows.drop_duplicates(["run_id", "detector"], keep="last")
    rows = rows.sort_values(["_pos"] if stored_order else ["_pos", "detector"], kind="stable")
    rows = rows.rename(columns={"_pos": "plan_pos"}) if positions else rows.drop(columns="_pos")
    return rows.reset_index(drop=True)


class SearchDir:
    """One worst-case search directory (``fdd-campaign falsify --out DIR``, and each search
    of ``gate --worst-case`` under a campaign directory's ``worst-case/``,
    :meth:`CampaignDir.worst_case_search_dir`): the only code that names and writes its
    files — every evaluated run (``search.parquet``), the plain Monte Carlo it is compared
    with (``monte-carlo.parquet``), the fitted detectors' runner directory (``learned/``)
    and, written last, the campaign file replaying the worst runs (``worst.toml``)."""

    def __init__(self, root):
        self.root = Path(root)
        self.search_path = self.root / SEARCH_FILE
        self.worst_path = self.root / WORST_FILE
        self.monte_carlo_path = self.root / "monte-carlo.parquet"
        self.learned = self.root / "learned"

    def write_search(self, search: pd.DataFrame, config_json: str, **extra) -> None:
        """Write ``search.parquet`` (*extra* into its metadata)."""
        write_parquet(search, self.search_path, config_json, kind="falsify-search", **extra)

    def write_monte_carlo(self, runs: pd.DataFrame, config_json: str, **extra) -> None:
        """Write ``monte-carlo.parquet`` (*extra* into its metadata)."""
        write_parquet(runs, self.monte_carlo_path, config_json, kind="falsify-mc", **extra)

    def write_worst(self, text: str) -> None:
        """Write ``worst.toml``, atomically: a directory holding it holds a finished
        search."""
        write_text(self.worst_path, text)


class CampaignDir:
    """One campaign's output directory: the only code that names, reads and writes its files.

    Every Parquet file is written with the campaign's JSON form (*config_json*, as
    ``CampaignConfig.to_json()``) in its metadata (:func:`write_parquet`). Every file it
    writes into a directory that has a manifest is recorded there (:meth:`verify`).
    """

    def __init__(self, root):
        self.root = Path(root)
        self.config_path = self.root / "campaign.json"
        self.manifest_path = self.root / MANIFEST_NAME
        self.lock_path = self.root / LOCK_NAME
        self.plan_path = self.root / "plan.parquet"
        self.learning_path = self.root / "learning.parquet"
        self.summary_path = self.root / "summary.parquet"
        self.detection_times_path = self.root / "detection-times.parquet"
        self.certificate_path = self.root / "certificate.parquet"
        self.hazard_path = self.root / "certificate-hazard.parquet"
        self.certificate_levels_path = self.root / "certificate-levels.parquet"
        self.tradeoff_path = self.root / "tradeoff.parquet"
        self.report_path = self.root / "report.html"
        self.runs = self.root / "runs"
        self.fitted = self.root / "fitted"
        self.fitted_origin_path = self.root / "fitted-origin.json"
        self._manifest: dict | None = None
        self._manifest_written = -float("inf")  # time.monotonic() of the last rewrite
        self._manifest_pending = False          # entries recorded but not yet written
        self._next_shard: int | None = None    # number of the next shard (next_shard_path)

    def is_campaign(self) -> bool:
        """Whether the directory belongs to a campaign (holds ``campaign.json``)."""
        return self.config_path.exists()

    def missing_outputs(self) -> list[str]:
        """Names of the files a finished run leaves (``campaign.json``, ``plan.parquet``,
        ``summary.parquet``) that the directory does not hold."""
        return [p.name for p in (self.config_path, self.plan_path, self.summary_path)
                if not p.exists()]

    # ---- the lock ---------------------------------------------------------------------
    @contextmanager
    def locked(self, log=None):
        """Hold the directory's lock (:class:`DirLock`) for the duration of the block."""
        lock = DirLock(self.lock_path).acquire(log)
        try:
            yield lock
        finally:
            lock.release()

    # ---- identity ---------------------------------------------------------------------
    def open(self, config_json: str, log=None) -> bool:
        """Create the directory, or check that it holds this same campaign and that its
        files match its manifest; call it holding the lock (:meth:`locked`).

        Returns True when earlier results exist (a resume). Raises
        :class:`CampaignDirError` when the directory holds a different campaign or pickled
        detectors, and :class:`ManifestError` when a recorded file was changed or removed.
        A file missing from the manifest (written just before the previous run stopped)
        is removed, with a note on *log*; a directory of an older version, without a
        manifest, has one made of the files it holds.
        """
        log = log or (lambda msg: None)
        stored = self.config_path
        if self.root.exists() and not self.root.is_dir():
            raise CampaignDirError(f"{self.root} exists and is not a directory")
        if stored.exists():
            changes = identity_changes(campaign_identity(_current_form(self.read_config())),
                                       campaign_identity(json.loads(config_json)))
            if changes:
                raise OutDirError.said(
                    "{root} holds the results of a different campaign: its campaign.json "
                    "differs from this configuration in {changes}. A directory holds one "
                    "campaign: a rerun resumes it only with the same configuration ([runner] "
                    "chunk_size and run_timeout_s may differ; other [requirements] limits need "
                    "no rerun: fdd-campaign gate {root} --requirements FILE); fix: run the "
                    "edited campaign into a new {out} directory (this one stays as it is; "
                    "'fdd-campaign compare {root} NEW' then shows what the edit changed), or "
                    "delete this one to start again", root=self.root,
                    changes=changes_text(changes))
        elif self.root.exists() and any(p.name != LOCK_NAME for p in self.root.iterdir()):
            raise OutDirError.said("{root} is not empty and holds no campaign.json; choose an "
                                   "empty or new {out} directory", root=self.root)
        self.runs.mkdir(parents=True, exist_ok=True)
        self.fitted.mkdir(parents=True, exist_ok=True)
        for leftover in list(self.root.rglob(".*.tmp")):
            leftover.unlink()
        self.refuse_pickles()
        if not stored.exists():
            write_text(stored, config_json)
            self._new_manifest()
        elif not self.manifest_path.exists():
            log(f"note: {self.root} has no {MANIFEST_NAME} (written by an older fdd-campaign): "
                "recording the files it holds now (their content before now is not proven)")
            self._new_manifest()
        else:
            self._recover(log)
        return any(self.runs.glob(SHARD_GLOB))

    def read_config(self) -> dict:
        """The stored ``campaign.json`` as a dict; :class:`CampaignDirError` when it is not
        valid JSON."""
        try:
            return json.loads(self.config_path.read_text())
        except json.JSONDecodeError as exc:
            raise CampaignDirError(f"{self.config_path} is not valid JSON ({exc}); the "
                                   "directory is damaged: rerun the campaign") from None

    # ---- the manifest -----------------------------------------------------------------
    def _rel(self, path: Path) -> str:
        return Path(path).relative_to(self.root).as_posix()

    def _owned_files(self) -> list[str]:
        """Every file the manifest covers that the directory holds (relative paths)."""
        out = [name for name in MANIFEST_TOP_FILES if (self.root / name).is_file()]
        for sub in (self.fitted, self.runs):
            if sub.is_dir():
                out += [self._rel(p) for p in sorted(sub.rglob("*"))
                        if not p.is_dir() and not _is_temporary(p)]
        return out

    def _new_manifest(self) -> None:
        """Start the manifest with every covered file the directory holds."""
        self._manifest = {
            "format": MANIFEST_FORMAT,
            "engine_versions": [engine_version()],
            "campaign": {"name": (self.read_config().get("campaign") or {}).get("name"),
                         "identity_sha256": identity_sha256(self.config_path.read_text())},
            "files": {},
        }
        self._record(*(self.root / rel for rel in self._owned_files()))

    def read_manifest(self) -> dict:
        """The stored manifest; :class:`ManifestError` when there is none or it is not one."""
        path = self.manifest_path
        if not path.exists():
            raise ManifestError(
                f"{self.root} has no {MANIFEST_NAME}, so its files cannot be checked: it was "
                "written by an older fdd-campaign, or not by 'fdd-campaign run'. Rerun the "
                "'fdd-campaign run' command that wrote it (delete its fitted/ directory first "
                "if it holds .pkl files): the runs done are kept and a manifest is recorded",
                [f"{MANIFEST_NAME} is missing"])
        try:
            manifest = json.loads(path.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise ManifestError(f"{path} is not valid JSON ({exc}); the directory's files "
                                "cannot be checked", [f"{MANIFEST_NAME} is not valid JSON"]) \
                from None
        if (not isinstance(manifest, dict) or manifest.get("format") != MANIFEST_FORMAT
                or not isinstance(manifest.get("files"), dict)):
            raise ManifestError(f"{path} is not an fdd-campaign manifest (format "
                                f"{MANIFEST_FORMAT!r} expected)",
                                [f"{MANIFEST_NAME} is not a manifest"])
        return manifest

    def _loaded_manifest(self) -> dict | None:
        """The manifest being maintained: the one this object read or started, else the
        directory's own, else None (a directory without one: nothing is recorded)."""
        if self._manifest is None and self.manifest_path.exists():
            self._manifest = self.read_manifest()
        return self._manifest

    def _write_manifest(self) -> None:
        m = self._manifest
        if engine_version() not in m["engine_versions"]:
            m["engine_versions"].append(engine_version())
        m["files"] = dict(sorted(m["files"].items()))
        write_text(self.manifest_path, json.dumps(m, indent=1, ensure_ascii=False) + "\n")
        self._manifest_written = time.monotonic()
        self._manifest_pending = False

    def _record(self, *paths: Path, defer: bool = False) -> None:
        """Add *paths* (written and in place) to the manifest, with their SHA-256 and size.
        With *defer*, the manifest is rewritten only when its last rewrite is
        :data:`MANIFEST_DEFER_S` old (or at the next rewrite, or :meth:`flush_manifest`)."""
        if self._loaded_manifest() is None:
            return
        for path in paths:
            self._manifest["files"][self._rel(path)] = {"sha256": sha256_of(path),
                                                        "bytes": Path(path).stat().st_size}
        if defer and time.monotonic() - self._manifest_written < MANIFEST_DEFER_S:
            self._manifest_pending = True
            return
        self._write_manifest()

    def flush_manifest(self) -> None:
        """Rewrite the manifest now if a deferred shard is not in the stored one yet."""
        if self._manifest_pending:
            self._write_manifest()

    def _forget(self, *paths: Path) -> None:
        """Take *paths* out of the manifest before they are replaced or removed."""
        if self._loaded_manifest() is None:
            return
        rels = [self._rel(p) for p in paths if self._rel(p) in self._manifest["files"]]
        if rels:
            for rel in rels:
                del self._manifest["files"][rel]
            self._write_manifest()

    def _write_recorded(self, path: Path, write, defer: bool = False) -> None:
        """``write()`` the file *path*, keeping the manifest true at every moment (*defer*:
        recorded as :meth:`_record` says)."""
        self._forget(path)
        write()
        self._record(path, defer=defer)

    def remove(self, path) -> None:
        """Remove the file *path* of this directory (and its manifest entry first)."""
        path = Path(path)
        self._forget(path)
        path.unlink(missing_ok=True)

    def verify(self) -> list[str]:
        """What does not match the manifest: one message per file that differs from its
        recorded SHA-256, is recorded but missing, or is held but not recorded (files under
        ``runs/`` and ``fitted/`` and the top-level files of :data:`MANIFEST_TOP_FILES`);
        empty when everything matches. :class:`ManifestError` when there is no manifest."""
        manifest = self.read_manifest()
        recorded = manifest["files"]
        problems = []
        held = set(self._owned_files())
        for rel, entry in recorded.items():
            path = self.root / rel
            if rel not in held:
                problems.append(f"{rel} is in the manifest but missing")
            elif not isinstance(entry, dict) or sha256_of(path) != entry.get("sha256"):
                problems.append(f"{rel} does not match the manifest (its SHA-256 differs from "
                                "the one recorded when it was written)")
        problems += [f"{rel} is not in the manifest" for rel in sorted(held - set(recorded))]
        if self.config_path.exists() and not problems:
            ident = (manifest.get("campaign") or {}).get("identity_sha256")
            if ident != identity_sha256(self.config_path.read_text()):
                problems.append("campaign.json does not match the campaign identity recorded "
                                "in the manifest")
        return problems

    def check_manifest(self) -> None:
        """Raise :class:`ManifestError` naming the files that do not match the manifest
        (:meth:`verify`); ``fdd-campaign gate``, ``report``, ``show`` and ``compare`` call
        it before reading anything else."""
        problems = self.verify()
        if not problems:
            return
        shown = "; ".join(problems[:5]) + (f"; and {len(problems) - 5} more"
                                           if len(problems) > 5 else "")
        busy = DirLock.holder(self.lock_path)
        hint = (f" (a run is writing into it now: {holder_text(busy)}; wait for it to "
                "finish)" if busy else
                "; its results may have been changed after the run wrote them: restore the "
                "directory from where it came from, or rerun the campaign into a new "
                f"directory ('fdd-campaign verify {self.root}' lists every difference)")
        raise ManifestError(f"{self.root} does not match its manifest: {shown}{hint}",
                            problems)

    def _recover(self, log) -> None:
        """On resume: refuse recorded files that changed or went missing, remove files
        written but not recorded before the previous run stopped."""
        problems = self.verify()
        stray = [p.split(" is not in the manifest")[0] for p in problems
                 if p.endswith(" is not in the manifest")]
        changed = [p for p in problems if not p.endswith(" is not in the manifest")]
        if "campaign.json" in stray:
            changed.append("campaign.json is not in the manifest")
        if changed:
            raise ManifestError(
                f"{self.root} does not match its manifest: {'; '.join(changed[:5])}; its "
                "results may have been changed after they were written, so they are not "
                "resumed: restore the directory, or run the campaign into a new directory",
                changed)
        for rel in stray:
            log(f"note: {rel} was written but not recorded in {MANIFEST_NAME} before the "
                "previous run stopped: removed (whatever it held is computed again)")
            (self.root / rel).unlink()

    # ---- run tables -------------------------------------------------------------------
    def has_plan(self) -> bool:
        return self.plan_path.exists()

    def write_plan(self, plan, config_json: str, model_version: str) -> int:
        """Write the run table ``plan.parquet`` with the version of the simulated models it
        is planned with (:data:`campaign.plan.MODEL_VERSION`; :meth:`check_model_version`);
        returns its number of rows. *plan*: a DataFrame, or the blocks of one as they are
        made (:class:`campaign.plan.PlanBlocks`: iterable, with ``rows`` and ``check()``),
        written as they come, so the memory holds one block whatever the size of the plan;
        the same file. Their ``check()`` may refuse the plan once every block is read, before
        the file takes its name."""
        self.check_model_version(model_version)
        extra = {"kind": "plan", "model_version": model_version}
        if isinstance(plan, pd.DataFrame):
            self._write_recorded(self.plan_path, lambda: write_parquet(
                plan, self.plan_path, config_json, row_group_rows=PLAN_ROW_GROUP_ROWS,
                **extra))
            return len(plan)
        self._write_recorded(self.plan_path, lambda: write_parquet_blocks(
            plan, self.plan_path, config_json, rows=plan.rows,
            row_group_rows=PLAN_ROW_GROUP_ROWS, before_commit=plan.check, **extra))
        return plan.rows

    def planned_runs(self) -> int:
        """The number of rows of ``plan.parquet`` (from its footer)."""
        return pq.read_metadata(self.plan_path).num_rows

    def plan_run_ids(self):
        """The ``run_id`` column of ``plan.parquet`` as a pyarrow array (the ids in one
        buffer, 28 bytes a run, where a list or an object array of str takes about 80),
        for :meth:`result_batches` and :meth:`done_mask`."""
        return pq.read_table(self.plan_path, columns=["run_id"]).column(0)

    def plan_rows(self, positions) -> pd.DataFrame:
        """The rows of the run table at *positions* (distinct, ascending row numbers),
        indexed by them as the same rows of :meth:`read_plan` are, read a row group at a
        time (:meth:`plan_batches`): a few runs of a large plan without the rest."""
        positions = np.asarray(positions, dtype=np.int64)
        parts, none = [], None
        for batch in self.plan_batches(PLAN_ROW_GROUP_ROWS):
            inside = positions[(positions >= batch.index.start)
                               & (positions < batch.index.stop)]
            if inside.size:
                parts.append(batch.loc[inside])
            elif none is None:
                none = batch.iloc[:0]       # no row asked for: the columns and dtypes
        if parts:
            return pd.concat(parts)
        return self.read_plan() if none is None else none     # (a plan of no rows)

    def run_index(self) -> _RunIndex:
        """The plan's run ids indexed: ``.positions(run_ids)`` gives each id's row in the
        plan (the plan's length for an id it does not hold), 28 bytes a run."""
        return _RunIndex(self.plan_run_ids())

    def read_plan(self, columns=None) -> pd.DataFrame:
        """The run table (only *columns* when given)."""
        return pd.read_parquet(self.plan_path, columns=columns)

    def plan_batches(self, batch_rows: int = PLAN_SCAN_ROWS,
                     columns=None) -> Iterator[pd.DataFrame]:
        """The run table (only *columns* when given) as consecutive DataFrames of
        *batch_rows* rows, read from ``plan.parquet`` one at a time (one row group decoded at
        a time, :data:`PLAN_ROW_GROUP_ROWS`); each indexed by its rows' positions in the
        plan, as the same rows of :meth:`read_plan` are."""
        start = 0
        plan = pq.ParquetFile(self.plan_path, pre_buffer=False)
        for batch in plan.iter_batches(batch_size=batch_rows, columns=columns):
            frame = batch.to_pandas()
            frame.index = pd.RangeIndex(start, start + len(frame))
            start += len(frame)
            yield frame

    def check_model_version(self, model_version: str) -> None:
        """:class:`CampaignDirError` when ``plan.parquet`` was planned with another model than
        *model_version* (a plan without a recorded version: ``servo-1``): its run ids, draws
        and results belong to that model, so resuming would mix two models."""
        if not self.has_plan():
            return
        planned = str(read_metadata(self.plan_path).get("model_version", "servo-1"))
        if planned != model_version:
            raise OutDirError.said(
                "{root} was planned with model {planned}; this fdd-campaign simulates model "
                "{model} (docs/physics.md): re-plan into a new {out} directory (or delete this "
                "one to start again)", root=self.root, planned=planned, model=model_version)

    def write_learning(self, learning: pd.DataFrame, config_json: str) -> None:
        """Write the learning-set run table ``learning.parquet``."""
        self._write_recorded(self.learning_path, lambda: write_parquet(
            learning, self.learning_path, config_json, kind="learning"))

    # ---- fitted detectors -------------------------------------------------------------
    def _fitted_paths(self, label: str) -> tuple[Path, Path]:
        return self.fitted / f"{label}.json", self.fitted / f"{label}.npz"

    def refuse_pickles(self) -> None:
        """:class:`CampaignDirError` when ``fitted/`` holds pickles (older versions stored
        fitted detectors so): loading a pickle can run any code, so none is ever read."""
        pickles = sorted(self.fitted.glob("*.pkl")) if self.fitted.is_dir() else []
        if pickles:
            raise CampaignDirError(
                f"{pickles[0]} is a pickled detector, written by an older fdd-campaign; "
                "loading a pickle can run any code, so fdd-campaign never reads one. To use "
                f"this directory, delete {self.fitted} and rerun the 'fdd-campaign run' "
                "command that wrote it: the detectors are fitted again on the learning set "
                "and stored as data, and the runs already done are kept")

    def has_fitted(self, label: str) -> bool:
        """Whether the fitted detector *label* is stored."""
        return all(p.exists() for p in self._fitted_paths(label))

    def write_fitted(self, label: str, name: str, det) -> None:
        """Store the fitted detector *label* (registry name *name*) as data:
        ``fitted/LABEL.json`` (name, parameters, learned values, engine version) and
        ``fitted/LABEL.npz`` (the arrays among them), :mod:`detectors.state`. Raises
        :class:`detectors.state.StateTypeError` (nothing written) when a parameter or a
        learned attribute is not plain data."""
        from detectors.state import encode

        cls = type(det)
        params, arrays = encode(det.get_params(), "parameter ")
        learned, arrays = encode(det.fitted_state(), "learned attribute ", arrays)
        doc = {"format": FITTED_FORMAT, "detector": name,
               "class": f"{cls.__module__}:{cls.__qualname__}",
               "engine_version": engine_version(), "params": params, "learned": learned}
        text = json.dumps(doc, indent=1, ensure_ascii=False, allow_nan=False) + "\n"
        doc_path, npz_path = self._fitted_paths(label)
        self._forget(doc_path, npz_path)

        def save(tmp):
            with open(tmp, "wb") as fh:
                np.savez(fh, **arrays)

        atomic_write_bytes(npz_path, save)
        write_text(doc_path, text)
        self._record(npz_path, doc_path)

    def read_fitted(self, label: str, name: str | None = None):
        """The fitted detector *label* stored by :meth:`write_fitted`, rebuilt from its
        registry name and parameters (:func:`detectors.registry.make_detector`) with its
        learned attributes set; never unpickles anything (arrays are read with
        ``allow_pickle=False``). *name*: the registry name the campaign gives *label*, checked
        against the stored one. :class:`CampaignDirError` when it is missing or damaged."""
        from detectors.registry import load_detector_class, make_detector
        from detectors.state import StateFormatError, decode

        self.refuse_pickles()
        doc_path, npz_path = self._fitted_paths(label)
        if not doc_path.exists() or not npz_path.exists():
            missing = doc_path if not doc_path.exists() else npz_path
            raise CampaignDirError(
                f"{missing} is missing: the fitted detector {label!r} is needed to re-simulate "
                "runs; copy the whole campaign directory (fitted/ included) or rerun "
                "'fdd-campaign run' into it")

        def damaged(why: str) -> CampaignDirError:
            return CampaignDirError(f"{doc_path} cannot be read back ({why}); the directory "
                                    f"is damaged: delete {self.fitted} and rerun "
                                    "'fdd-campaign run' into it to fit the detectors again")

        try:
            doc = json.loads(doc_path.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise damaged(f"not valid JSON: {exc}") from None
        if not isinstance(doc, dict) or doc.get("format") != FITTED_FORMAT:
            raise damaged(f"not a fitted detector of format {FITTED_FORMAT!r}")
        stored = doc.get("detector")
        if name is not None and stored != name:
            raise damaged(f"it holds detector {stored!r}, the campaign names {name!r}")
        # the detector's module first: the dataclasses of its learned state (e.g. the
        # threshold calibrations) are registered when it is imported, and decoded by name
        load_detector_class(stored)
        try:
            with np.load(npz_path, allow_pickle=False) as npz:
                arrays = {key: npz[key] for key in npz.files}
            params = decode(doc.get("params"), arrays)
            learned = decode(doc.get("learned"), arrays)
        except StateFormatError as exc:
            raise damaged(str(exc)) from None
        except (ValueError, OSError, EOFError) as exc:   # bad zip, object arrays, truncation
            raise damaged(f"{npz_path.name}: {type(exc).__name__}: {exc}") from None
        bad = [k for k in learned if not (k.isidentifier() and k.endswith("_")
                                          and not k.startswith("_"))]
        if bad:
            raise damaged(f"learned attribute names must end in '_': {bad}")
        det = make_detector(stored, params)
        vars(det).update(learned)          # as unpickling did: the stored values, as they are
        return det

    def fitted_sha256(self, labels) -> str | None:
        """SHA-256 identifying the fitted detectors *labels* as stored: of the lines
        ``LABEL.json SHA256`` and ``LABEL.npz SHA256`` (the digest of each file, labels
        sorted); ``None`` when one of them is not stored. Two campaigns with the same value
        evaluate the very same fitted detectors (thresholds and every learned value)."""
        lines = []
        for label in sorted(labels):
            for path in self._fitted_paths(label):
                if not path.exists():
                    return None
                lines.append(f"{path.name} {sha256_of(path)}\n")
        return hashlib.sha256("".join(lines).encode()).hexdigest()

    def adopt_fitted(self, source: "CampaignDir", labels) -> dict:
        """Copy the fitted detectors *labels* and the learning-set table of campaign
        directory *source* (checked against its manifest by the caller) into this one, byte
        for byte, and record where they came from in ``fitted-origin.json``; returns that
        record (``fitted_from``, ``fitted_sha256``, ``campaign``)."""
        import shutil

        files = [p for label in labels for p in source._fitted_paths(label)]
        if source.learning_path.exists():
            files.append(source.learning_path)
        for src in files:
            dst = self.root / src.relative_to(source.root)
            self._forget(dst)
            atomic_write_bytes(dst, lambda tmp, src=src: shutil.copyfile(src, tmp))
            self._record(dst)
        origin = {"fitted_from": str(source.root.resolve()),
                  "fitted_sha256": source.fitted_sha256(labels),
                  "campaign": (source.read_config().get("campaign") or {}).get("name")}
        self._write_recorded(self.fitted_origin_path, lambda: write_text(
            self.fitted_origin_path, json.dumps(origin, indent=1, ensure_ascii=False) + "\n"))
        return origin

    def read_fitted_origin(self) -> dict | None:
        """The record of :meth:`adopt_fitted`, or ``None`` when the detectors were fitted
        here."""
        if not self.fitted_origin_path.exists():
            return None
        try:
            origin = json.loads(self.fitted_origin_path.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise CampaignDirError(f"{self.fitted_origin_path} is not valid JSON ({exc}); the "
                                   "directory is damaged: rerun the campaign") from None
        return origin if isinstance(origin, dict) else None

    # ---- summary and detection times --------------------------------------------------
    def has_summary(self) -> bool:
        return self.summary_path.exists()

    def write_summary(self, summary: pd.DataFrame, config_json: str, **extra) -> None:
        """Write ``summary.parquet``; *extra* (``complete``, ``runs_done``, ``runs_planned``)
        goes into its metadata."""
        self._write_recorded(self.summary_path, lambda: write_parquet(
            summary, self.summary_path, config_json, kind="summary", **extra))

    def read_summary(self) -> tuple[pd.DataFrame, dict]:
        """(summary, metadata of ``summary.parquet``)."""
        return (pq.read_table(self.summary_path).to_pandas(),
                read_metadata(self.summary_path))

    def write_detection_times(self, times: pd.DataFrame, config_json: str) -> None:
        """Write ``detection-times.parquet``
        (:func:`reports.scoring.detection_times.detection_time_table`)."""
        self._write_recorded(self.detection_times_path, lambda: write_parquet(
            times, self.detection_times_path, config_json, kind="detection_times"))

    def read_detection_times(self) -> pd.DataFrame | None:
        """The stored detection times, or None when the campaign has none."""
        return _read_optional(self.detection_times_path)

    def write_certificate(self, cert: pd.DataFrame, config_json: str, **extra) -> None:
        """Write ``certificate.parquet`` (:func:`campaign.evidence.certify.certify`); *extra* goes
        into its metadata."""
        self._write_recorded(self.certificate_path, lambda: write_parquet(
            cert, self.certificate_path, config_json, kind="certificate", **extra))

    def read_certificate(self) -> pd.DataFrame | None:
        """The stored false-alarm certificate, or None when ``certify`` has not run."""
        return _read_optional(self.certificate_path)

    def write_hazard(self, hazard: pd.DataFrame, config_json: str) -> None:
        """Write ``certificate-hazard.parquet``, the hazard per flight hour
        (:func:`campaign.evidence.hazard.hazard_table`, written by ``certify``)."""
        self._write_recorded(self.hazard_path, lambda: write_parquet(
            hazard, self.hazard_path, config_json, kind="certificate-hazard"))

    def read_hazard(self) -> pd.DataFrame | None:
        """The stored hazard table, or None when ``certify`` has not made one."""
        return _read_optional(self.hazard_path)

    def write_certificate_levels(self, levels: pd.DataFrame, config_json: str, **extra) -> None:
        """Write ``certificate-levels.parquet``
        (:func:`campaign.evidence.certify.levels.level_table`); *extra* goes into its metadata."""
        self._write_recorded(self.certificate_levels_path, lambda: write_parquet(
            levels, self.certificate_levels_path, config_json, kind="certificate-levels",
            **extra))

    def read_certificate_levels(self) -> pd.DataFrame | None:
        """The stored exceedance curve of the certificate, or None when ``certify`` has not
        written one."""
        return _read_optional(self.certificate_levels_path)

    def write_tradeoff(self, table: pd.DataFrame, config_json: str, **extra) -> None:
        """Write ``tradeoff.parquet`` (:func:`campaign.tradeoff.tradeoff`); *extra* goes
        into its metadata."""
        self._write_recorded(self.tradeoff_path, lambda: write_parquet(
            table, self.tradeoff_path, config_json, kind="tradeoff", **extra))

    def read_tradeoff(self) -> pd.DataFrame | None:
        """The stored trade-off table, or None when ``tradeoff`` has not run."""
        return _read_optional(self.tradeoff_path)

    def alarm_scales_stored(self) -> tuple[int, list]:
        """(shards that hold the ``alarm_steps`` column, the distinct scale lists their
        metadata records, in first-seen order): what :mod:`campaign.tradeoff` checks before
        it reads the column."""
        held, seen = 0, []
        for path in self.shard_paths():
            try:
                names = pq.read_schema(path).names
            except (pa.ArrowInvalid, OSError) as exc:
                raise CampaignDirError(f"{path}: not a readable result shard ({exc}); the "
                                       f"directory is damaged: 'fdd-campaign verify "
                                       f"{self.root}' names what differs") from None
            if ALARM_STEPS_COLUMN not in names:
                continue
            held += 1
            scales = read_metadata(path).get(ALARM_SCALES_KEY)
            if scales not in seen:
                seen.append(scales)
        return held, seen

    # ---- evidence: certify's subset simulations and validations -----------------------
    # (not covered by the manifest: work that ``certify`` reads back or makes again)
    @property
    def sampling_root(self) -> Path:
        """``DIR/sampling``: the subset simulations of ``certify --sampling``."""
        return self.root / SAMPLING_DIR

    def sampling_runner_dir(self) -> Path:
        """The runner's work directory of the subset simulations (its setup and the fitted
        detectors taken from here)."""
        return self.sampling_root / "runner"

    def _sampling_batch_path(self, work: str, batch: int) -> Path:
        return self.sampling_root / work / f"batch-{int(batch):05d}.parquet"

    def read_sampling_batch(self, work: str, batch: int) -> pd.DataFrame | None:
        """Batch *batch* of the subset simulation *work* (its run ids and margins), or None
        when it is not stored."""
        return _read_optional(self._sampling_batch_path(work, batch))

    def write_sampling_batch(self, work: str, batch: int, run_ids, margin,
                             config_json: str) -> None:
        """Write batch *batch* of the subset simulation *work*
        (``sampling/WORK/batch-NNNNN.parquet``: ``run_id``, ``margin``), atomically."""
        write_parquet(pd.DataFrame({"run_id": run_ids, "margin": margin}),
                      self._sampling_batch_path(work, batch), config_json,
                      kind="certify-sampling-batch", batch=int(batch))

    def write_sampling_levels(self, levels: pd.DataFrame, config_json: str) -> None:
        """Write ``sampling/levels.parquet``, the levels of every sampled detector
        (:func:`campaign.evidence.certify.write_sampling_levels`)."""
        write_parquet(levels, self.sampling_root / SAMPLING_LEVELS_FILE, config_json,
                      kind="certify-sampling-levels")

    def validation_dir(self, seed: int, n: int) -> Path:
        """The campaign directory of the validation of *n* runs at campaign seed *seed*:
        ``validation/seed-S-nN``."""
        return self.root / VALIDATION_DIR / f"seed-{int(seed)}-n{int(n)}"

    def write_validation(self, table: pd.DataFrame, seed: int, n: int,
                         config_json: str) -> Path:
        """Write the coverage table of that validation, ``validation/seed-S-nN.parquet``
        (:func:`campaign.evidence.certify.validate.validate_levels`); returns its path."""
        path = self.validation_dir(seed, n).with_suffix(".parquet")
        write_parquet(table, path, config_json, kind="certify-validation",
                      validation_seed=int(seed))
        return path

    # ---- worst-case searches (gate --worst-case) ----------------------------------------
    @property
    def worst_case_root(self) -> Path:
        """``DIR/worst-case``: the searches of ``gate --worst-case`` and their corpus."""
        return self.root / WORST_CASE_DIR

    def worst_case_search_dir(self, name: str, budget: int, seed: int) -> Path:
        """The directory of the search of detector *name* (result-row name) with *budget*
        runs and *seed*: ``worst-case/NAME-nBUDGET-seedSEED`` (the name made file-safe)."""
        safe = "".join(ch if ch.isalnum() or ch in "-_.=" else "_" for ch in name)
        return self.worst_case_root / f"{safe}-n{int(budget)}-seed{int(seed)}"

    def worst_case_replay_dir(self) -> Path:
        """The work directory of the corpus replay (the fitted detectors taken from here)."""
        return self.worst_case_root / "replay"

    @staticmethod
    def _search_meta(search_dir: Path) -> dict | None:
        """The metadata of a finished search in *search_dir* (its ``worst.toml`` written,
        hence its ``search.parquet``), or None."""
        search_dir = Path(search_dir)
        if not (search_dir / WORST_FILE).is_file() or not (search_dir / SEARCH_FILE).is_file():
            return None
        try:
            return read_metadata(search_dir / SEARCH_FILE)
        except (pa.ArrowInvalid, OSError):       # torn by a kill: computed again
            return None

    def finished_search(self, name: str, budget: int, seed: int, config_json: str) -> bool:
        """Whether the search of (*name*, *budget*, *seed*) is stored, finished, and was
        made for this campaign (*config_json*, the JSON form in its metadata)."""
        meta = self._search_meta(self.worst_case_search_dir(name, budget, seed))
        return (meta is not None and meta.get("detector") == name
                and int(meta.get("budget", -1)) == int(budget)
                and int(meta.get("seed", -1)) == int(seed)
                and campaign_identity(meta.get("config") or {})
                == campaign_identity(json.loads(config_json)))

    def worst_case_corpus(self, name: str) -> list[Path]:
        """The ``worst.toml`` of every finished search of detector *name* stored here (any
        budget and seed), sorted by path: the corpus a worst-case gate replays first."""
        root = self.worst_case_root
        if not root.is_dir():
            return []
        return [d / WORST_FILE for d in sorted(root.iterdir())
                if d.is_dir() and (self._search_meta(d) or {}).get("detector") == name]

    def write_report(self, page: str, path=None) -> Path:
        """Write the HTML report *page* to *path* (default ``report.html`` here)."""
        path = Path(path) if path else self.report_path
        write_text(path, page)
        return path

    # ---- shards -----------------------------------------------------------------------
    def shard_paths(self) -> list[Path]:
        return sorted(self.runs.glob(SHARD_GLOB))

    def next_shard_path(self) -> Path:
        """The name of the next shard: one more than the last one's number. The directory
        is listed once; later calls count on (only the run holding the lock writes shards),
        so writing n shards does not list the directory n times."""
        if self._next_shard is None:
            paths = self.shard_paths()
            self._next_shard = int(paths[-1].stem.split("-")[1]) + 1 if paths else 0
        path = self.runs / f"part-{self._next_shard:06d}.parquet"
        while path.exists():        # written by another object of this directory meanwhile
            self._next_shard += 1
            path = self.runs / f"part-{self._next_shard:06d}.parquet"
        return path

    def write_shard(self, results: pd.DataFrame, config_json: str,
                    defer_manifest: bool = False) -> Path:
        """Store the result rows of one finished chunk as the next shard (then record it in
        the manifest); returns its path. With *defer_manifest* the stored manifest may lag
        by up to :data:`MANIFEST_DEFER_S` seconds of shards: the writer calls
        :meth:`flush_manifest` when it stops (a shard a crash leaves out of the manifest is
        removed on resume, and its runs are run again)."""
        path = self.next_shard_path()
        results, extra = _stored_alarm_steps(results)
        self._write_recorded(path, lambda: write_parquet(results, path, config_json,
                                                         kind="results", **extra),
                             defer=defer_manifest)
        self._next_shard += 1
        return path

    def _read_shard(self, path: Path, columns=None):
        """The table of one result shard; one that cannot be read (truncated, overwritten)
        is the directory's damage (:class:`CampaignDirError`, exit 2), not the engine's. An
        optional column (:data:`OPTIONAL_RESULT_COLUMNS`) asked for and not in the shard
        comes back null."""
        try:
            if columns is None or not set(columns) & set(OPTIONAL_RESULT_COLUMNS):
                return pq.read_table(path, columns=columns)
            shard = pq.ParquetFile(path)
            held = set(shard.schema_arrow.names)
            table = shard.read(columns=[c for c in columns if c in held])
            for c in columns:
                if c not in held:
                    table = table.append_column(c, pa.nulls(len(table), pa.binary()))
            return table.select(list(columns))
        except (pa.ArrowInvalid, OSError) as exc:     # truncated, overwritten, unreadable
            raise CampaignDirError(
                f"{path}: not a readable result shard ({exc}); the directory is damaged: "
                f"'fdd-campaign verify {self.root}' names what differs from its manifest; "
                "rerun the campaign into a new directory") from None

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
            df = self._read_shard(path).to_pandas()
            df["_seq"] = seq
            frames.append(df)
        df = pd.concat(frames, ignore_index=True)
        latest = df.groupby("run_id", sort=False)["_seq"].transform("max")
        df = df[df["_seq"] == latest]
        df = df.sort_values("_seq", kind="stable").drop_duplicates(["run_id", "detector"],
                                                                   keep="last")
        return df.drop(columns="_seq").reset_index(drop=True)

    def result_batches(self, run_ids=None, columns=None,
                       batch_runs: int = RESULT_BATCH_RUNS, *, stored_order: bool = False,
                       positions: bool = False) -> Iterator[pd.DataFrame]:
        """The rows of :meth:`read_results` in plan order, as consecutive DataFrames of the
        rows of at most *batch_runs* runs each, so that no reader holds every row at once.

        Rows are ordered by the run's position in *run_ids* (default: the ``run_id`` column
        of ``plan.parquet``), then by ``detector`` (a stable sort): concatenated, the batches
        are ``read_results()`` sorted so, the order every table of the campaign is computed
        in. Rows of a run id that is not in *run_ids* come last, by detector. *columns*:
        the columns read (``run_id`` and ``detector`` are always read and returned).
        With *stored_order*, a run's rows keep the order they were stored in (the detectors
        in the order they were evaluated), the order of :attr:`campaign.result.Campaign.results`;
        with *positions*, each row also has ``plan_pos`` (int64), its run's position in
        *run_ids* (their count for a run id not among them).

        Memory: the shards' ``run_id`` columns are read once to find, for each run, its
        latest shard (one int32 per run of the plan, 4 MB for 10⁶ runs, and the plan's run
        ids as bytes, 20 bytes each); then each batch reads the shards that hold its runs.
        A shard is read once per batch it has rows in: the shards of a campaign's chunks are
        runs in plan order, so about once; a retry shard, whose runs are spread over the
        plan, once per batch."""
        paths = self.shard_paths()
        if not paths:
            return
        if run_ids is None:
            run_ids = self.plan_run_ids()
        index = _RunIndex(run_ids)
        del run_ids                  # the index holds them, as bytes
        n = len(index)
        if columns is not None:
            columns = list(dict.fromkeys(["run_id", "detector", *columns]))
        latest = np.full(n + 1, -1, dtype=np.int32)    # slot n: run ids not in run_ids
        held = []
        for seq, path in enumerate(paths):
            pos = np.unique(index.positions(self._read_shard(path, ["run_id"]).column(0)))
            latest[pos] = seq                          # shards in order: the last one wins
            held.append(pos)
        spans = []
        for seq, pos in enumerate(held):
            kept = pos[(pos < n) & (latest[pos] == seq)]
            spans.append((int(kept[0]), int(kept[-1])) if kept.size else None)
        del held
        for start in range(0, n, batch_runs):
            stop = min(start + batch_runs, n)
            frames = []
            for seq, span in enumerate(spans):
                if span is None or span[1] < start or span[0] >= stop:
                    continue
                df = self._read_shard(paths[seq], columns).to_pandas()
                pos = index.positions(df["run_id"])
                keep = (pos >= start) & (pos < stop) & (latest[np.minimum(pos, n)] == seq)
                if keep.any():
                    frames.append(df[keep].assign(_pos=pos[keep]))
            if frames:
                yield _plan_ordered(pd.concat(frames, ignore_index=True), stored_order,
                                    positions)
        if latest[n] >= 0:              # run ids outside the plan: the rule of read_results
            frames = []
            for seq, path in enumerate(paths):
                df = self._read_shard(path, columns).to_pandas()
                df = df[index.positions(df["run_id"]) == n]
                if len(df):
                    frames.append(df.assign(_pos=n, _seq=seq))
            df = pd.concat(frames, ignore_index=True)
            df = df[df["_seq"] == df.groupby("run_id", sort=False)["_seq"].transform("max")]
            yield _plan_ordered(df.drop(columns="_seq"), stored_order, positions)

    def done_mask(self, run_ids) -> np.ndarray:
        """For each of *run_ids*: whether every result row of that run has status ``ok``
        (errors are retried on resume); read a batch of rows at a time
        (:meth:`result_batches`)."""
        index = _RunIndex(run_ids)
        done = np.zeros(len(index), dtype=bool)
        for batch in self.result_batches(run_ids, columns=["status"]):
            pos = index.positions(batch["run_id"])
            known = pos < len(index)
            ok = (batch["status"] == "ok").to_numpy()
            done[pos[known & ok]] = True
            done[pos[known & ~ok]] = False
        return done

    def runs_done(self) -> int:
        """How many runs of the plan have every result row ``ok`` (:meth:`done_mask`; errors
        are retried on resume)."""
        if not self.shard_paths():
            return 0
        if not self.has_plan():      # results without a plan: read them whole
            df = self.read_results()
            return len(set(df["run_id"]) - set(df.loc[df["status"] != "ok", "run_id"]))
        return int(self.done_mask(self.plan_run_ids()).sum())
