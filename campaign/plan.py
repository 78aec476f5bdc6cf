"""Expand a campaign configuration into its run table (docs/design.md §3, data flow step 2).

Two designs, one signature (``build_plan(config) -> DataFrame``; a campaign makes and writes
the same table block by block, :class:`PlanBlocks`):

* ``mc`` — Monte Carlo over the envelope box and the uncertainty box with a scrambled Sobol
  sequence (``scipy.stats.qmc``; plain random with ``sampler = "random"``), one sequence per
  (group, manoeuvre) cell; points failing the realistic-envelope rule are skipped when
  ``realistic_only`` (the sequence simply continues).
* ``grid`` — the parametric sweep: every envelope grid point × the three uncertainty levels
  {min, nominal, max} ([CHEN] §5.1: 108 × 3 = 324 cases), realistic cases only by default.

Explicit ``[[run]]`` entries follow the groups' runs in either design, each with every value
and its stream as written (:func:`explicit_rows`).

Every sampled value is a column, so the table fully describes the campaign before it runs.
Run i's simulation streams are ``SeedSequence(seed, spawn_key=(i,))`` (``stream`` = i); the
learning set uses its own streams (:data:`LEARNING_STREAM_BASE` + j), never evaluation ones.
The run id is a hash of the row's canonical JSON and :data:`MODEL_VERSION`.
"""

from __future__ import annotations

import hashlib
import json
import math
import warnings
from collections.abc import Callable, Iterator

import numpy as np
import pandas as pd
from scipy.stats import qmc

from scenarios import envelope
from scenarios.catalog import MANOEUVRES, latest_onset_s
from scenarios.faults import liquid_jam_bias_mm, solid_jam_offset_mm
from scenarios.memory import release_freed_memory
from scenarios.runs import DEFAULT_MANOEUVRE_SET

from .config import ConfigError
from .plant_setup import as_resolved

#: Version of the simulated models: part of every run id, so a model change never reuses
#: results computed with the previous model (a directory planned with another version is
#: refused). What each version changed: CHANGELOG.md, "Model versions".
MODEL_VERSION = "servo-6"

#: First stream index of the learning set (disjoint from any evaluation index).
LEARNING_STREAM_BASE = 2 ** 32

#: spawn_key namespaces of the design's own sampling streams.
_DESIGN_KEY, _LEARNING_KEY = 2 ** 33, 2 ** 33 + 1

#: The continuous variables of a run (run-table columns): its flight point in the
#: ``[envelope]`` box and its relative deviations within ± their half-widths. The ``mc``
#: design draws them uniformly (:func:`variable_ranges`), ``fdd-campaign falsify`` searches
#: them and ``fdd-campaign certify --sampling`` re-samples them.
RUN_VARIABLES: tuple[str, ...] = envelope.FLIGHT_COLUMNS + envelope.DRAW_COLUMNS

#: Unit-cube dimensions of one run's sampled values (mc design): the run variables, then
#: the fault's onset, magnitude, sign and frequency.
_DIMS = RUN_VARIABLES + ("onset", "magnitude", "sign", "freq")

PLAN_COLUMNS = (
    "run_id", "group", "surface", "manoeuvre", "fault", "onset_s", "magnitude", "freq_hz",
    *envelope.FLIGHT_COLUMNS, "level", "realistic", "point",
    *envelope.DRAW_COLUMNS, "seed", "stream", "duration_s", "manoeuvre_start_s",
    "manoeuvre_set",
)

#: Columns left out of the run id while they hold their default (NaN is stored as None),
#: so adding them did not change the identity of runs that do not use them. Any other value
#: enters the id: a run of the ``stress`` manoeuvre set never shares an id (nor a stored
#: result, on resume) with its ``normal`` twin.
_OPTIONAL_ID_COLUMNS: dict[str, object] = {"manoeuvre_start_s": None,
                                           "manoeuvre_set": DEFAULT_MANOEUVRE_SET}


def run_id(row: dict) -> str:
    """Hash of the canonical JSON of a run row (without its id) and the model version."""
    return _hash_payload({k: _id_value(v) for k, v in row.items() if k != "run_id"})


def _id_value(v):
    """A row's value as its run id hashes it: NaN as None (JSON null)."""
    return None if isinstance(v, float) and math.isnan(v) else v


def _hash_payload(payload: dict) -> str:
    """:func:`run_id` of the row *payload* (without its id, NaN already None)."""
    for k, default in _OPTIONAL_ID_COLUMNS.items():
        if k in payload and payload[k] == default:
            del payload[k]
    text = json.dumps(payload, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256((MODEL_VERSION + "|" + text).encode()).hexdigest()[:20]


def _manoeuvres(names) -> list[str]:
    return list(MANOEUVRES) if list(names) == ["all"] else list(names)


def _unit_samples(n: int, config, cell_key: int) -> np.ndarray:
    """The first *n* points of the unit hypercube of one design cell (Sobol or plain
    random, :func:`_unit_sample_stream`)."""
    return _unit_sample_stream(config, cell_key)(n)


def _unit_sample_stream(config, cell_key: int) -> Callable[[int], np.ndarray]:
    """The sequence of unit-hypercube points of one design cell, drawn on: each call
    ``draw(size)`` returns its next *size* points, so that successive draws are its first
    points, the same numbers (a Sobol engine continues its sequence; a generator its stream
    of doubles, row after row)."""
    ss = np.random.SeedSequence(config.campaign.seed, spawn_key=(_DESIGN_KEY, cell_key))
    if config.campaign.sampler == "sobol":
        sampler = qmc.Sobol(d=len(_DIMS), scramble=True, seed=np.random.default_rng(ss))

        def draw(size: int) -> np.ndarray:
            with warnings.catch_warnings():   # a prefix of the sequence is what the design
                warnings.filterwarnings(      # takes (_unit_samples slices one too)
                    "ignore", message="The balance properties of Sobol", category=UserWarning)
                return sampler.random(size)
        return draw
    rng = np.random.default_rng(ss)
    return lambda size: rng.random((size, len(_DIMS)))


def _fault_values(fault: str, u_mag, u_sign, u_freq, config, act, variant=None):
    """Signed magnitude and frequency of a fault from unit samples (*variant*: the group's
    ``variant`` key; a solid jam has a magnitude, its rod offset [mm], only as "offset")."""
    f = config.faults
    sign = np.where(u_sign < 0.5, -1.0, 1.0)
    nan = np.full_like(u_mag, np.nan)
    if fault == "runaway":
        lo, hi = f.runaway.rate_deg_s
        return sign * (lo + (hi - lo) * u_mag), nan
    if fault == "hardover":
        return sign, nan
    if fault == "liquid_jam":
        lo, hi = f.liquid_jam.bias_pct_range
        pct = lo + (hi - lo) * u_mag
        return sign * np.array([liquid_jam_bias_mm(act, p) for p in pct]), nan
    if fault == "solid_jam" and variant == "offset":
        lo, hi = f.solid_jam.offset_pct_range
        pct = lo + (hi - lo) * u_mag
        return sign * np.array([solid_jam_offset_mm(act, p) for p in pct]), nan
    if fault in ("ofc_liquid", "ofc_solid"):
        sub = f.ofc_liquid if fault == "ofc_liquid" else f.ofc_solid
        amp = sub.amplitude_mA if fault == "ofc_liquid" else sub.amplitude_mm
        fr = sub.freq_hz
        return (amp[0] + (amp[1] - amp[0]) * u_mag,
                fr[0] + (fr[1] - fr[0]) * u_freq)
    return nan, nan


def fixed_magnitude(fault: str, size: float, drawn: np.ndarray, act) -> np.ndarray:
    """Run-table magnitudes of a group that fixes ``magnitude = size`` (in the unit of the
    fault's ``[faults.*]`` range, docs/campaign-file.md "Fault magnitudes"): a jam's % of the
    deflection range becomes its rod bias/offset [mm] (:func:`liquid_jam_bias_mm`,
    :func:`solid_jam_offset_mm`), and the direction stays the one drawn per run (the sign
    of *drawn*: both directions, unless the group's ``sign`` fixes it afterwards); the OFC
    amplitudes have no direction."""
    if fault == "liquid_jam":
        size = liquid_jam_bias_mm(act, size)
    elif fault == "solid_jam":
        size = solid_jam_offset_mm(act, size)
    if fault in ("ofc_liquid", "ofc_solid"):
        return np.full(len(drawn), size)
    return np.where(drawn < 0, -size, size)


def variable_ranges(config) -> dict[str, tuple[float, float]]:
    """Each of the :data:`RUN_VARIABLES` → its range (low, high) in run-table units: a
    flight-point column → the smallest and largest value of its ``[envelope]`` list, a
    draw column → (−w, w), w its half-width of ``[uncertainty]``/``[mismatch]``
    (:func:`scenarios.envelope.half_widths`; 0 holds it at 0)."""
    out = {}
    for col in envelope.FLIGHT_COLUMNS:
        values = getattr(config.envelope, col)
        out[col] = (float(min(values)), float(max(values)))
    widths = envelope.half_widths(config.uncertainty, config.mismatch)
    for col in envelope.DRAW_COLUMNS:
        out[col] = (-float(widths[col]), float(widths[col]))
    return out


def _fill_runs(campaign, group, manoeuvre, frame: pd.DataFrame, u_rest: np.ndarray,
               duration: float, manoeuvre_set: str) -> pd.DataFrame:
    """Add fault, onset and fixed-point columns to the flight-point rows of one cell
    (*campaign*: the :class:`campaign.plant_setup.ResolvedCampaign`)."""
    config, act = campaign.config, campaign.actuator
    ts = config.campaign.ts_s
    n = len(frame)
    fl = config.faults
    lo, hi = fl.onset_min_s, latest_onset_s(group.fault, duration, fl.onset_before_end_s)
    if group.fault == "none":
        onset = np.full(n, np.nan)
    elif group.onset_s is not None:
        onset = np.full(n, float(group.onset_s))
    else:
        onset = lo + (hi - lo) * u_rest[:, 0]
    onset = np.where(np.isfinite(onset), np.round(onset / ts) * ts, np.nan)
    variant = getattr(group, "variant", None)
    mag, freq = _fault_values(group.fault, u_rest[:, 1], u_rest[:, 2], u_rest[:, 3], config, act,
                              variant)
    if group.magnitude is not None and group.fault != "none":
        mag = fixed_magnitude(group.fault, float(group.magnitude), mag, act)
    if getattr(group, "freq_hz", None) is not None:
        freq = np.full(n, float(group.freq_hz))
    direction = getattr(group, "sign", None)
    if direction is not None and group.fault != "none":
        mag = np.abs(mag) * (-1.0 if direction == "negative" else 1.0)
    start = getattr(group, "manoeuvre_start_s", None)
    out = frame.copy()
    out.insert(0, "group", group.name)
    out["surface"] = campaign.surface
    out["manoeuvre"] = manoeuvre
    out["fault"] = group.fault
    out["onset_s"] = onset
    out["magnitude"] = mag
    out["freq_hz"] = freq
    out["duration_s"] = duration
    out["manoeuvre_start_s"] = np.nan if start is None else float(start)
    out["manoeuvre_set"] = manoeuvre_set
    for key in envelope.FLIGHT_COLUMNS:
        fixed = getattr(group, key, None)
        if fixed is not None:
            out[key] = float(fixed)
    return out


#: The points of its sequence an ``mc`` cell of n runs may draw to find n realistic ones:
#: max(4·n, 16) · 2^6 (four per run, doubled six times); fewer is a configuration error.
MC_SEARCH_DOUBLINGS = 6


def _mc_cell(campaign, group, manoeuvre, n: int, cell_key: int, duration: float,
             manoeuvre_set: str, block_rows: int | None = None) -> Iterator[pd.DataFrame]:
    """The runs (without ids, seeds or streams) of one ``mc`` cell, consecutive frames of at
    most *block_rows* rows: the first *n* points of the cell's sequence that the
    realistic-envelope rule keeps (any point without ``realistic_only``), drawn
    *block_rows* points at a time (None: as many as the search needs at once), so a cell
    of any size holds one block of draws at once.
    The frames do not depend on *block_rows*: each point's values, verdict and run are its
    own (elementwise arithmetic)."""
    config = campaign.config
    ranges = variable_ranges(config)
    n_flight = len(envelope.FLIGHT_COLUMNS)
    cap = max(4 * n, 16) << MC_SEARCH_DOUBLINGS
    draw = _unit_sample_stream(config, cell_key)
    found = drawn = 0
    while found < n:
        if drawn >= cap:
            raise ConfigError(
                f"group {group.name!r}: fewer than {n} realistic flight points in the envelope "
                "box; widen [envelope] or set realistic_only = false")
        size = min(max(4 * (n - found), 16), cap - drawn, block_rows or cap)
        u = draw(size)
        drawn += size
        pts = pd.DataFrame({col: ranges[col][0] + (ranges[col][1] - ranges[col][0]) * u[:, j]
                            for j, col in enumerate(envelope.FLIGHT_COLUMNS)})
        for j, col in enumerate(envelope.DRAW_COLUMNS):
            pts[col] = (2.0 * u[:, n_flight + j] - 1.0) * ranges[col][1]
        pts["realistic"] = envelope.realistic_rule(pts[list(envelope.FLIGHT_COLUMNS)],
                                                   config.uncertainty)["realistic"].to_numpy()
        keep = (pts["realistic"].to_numpy() if config.campaign.realistic_only
                else np.ones(len(pts), bool))
        idx = np.flatnonzero(keep)[:n - found]
        if idx.size == 0:
            continue
        pts = pts.iloc[idx].reset_index(drop=True)
        pts["level"] = "mc"
        pts["point"] = -1
        found += idx.size
        yield _fill_runs(campaign, group, manoeuvre, pts, u[idx][:, -4:], duration,
                         manoeuvre_set)


def _grid_cell(campaign, group, manoeuvre, cell_key: int, duration: float,
               manoeuvre_set: str) -> pd.DataFrame:
    config = campaign.config
    env = config.envelope
    table = envelope.GridTable(**{c: tuple(getattr(env, c)) for c in envelope.FLIGHT_COLUMNS})
    pts = envelope.realistic_rule(envelope.grid_points(table), config.uncertainty)
    if config.campaign.realistic_only:
        pts = pts[pts["realistic"]]
    rows = []
    for level in ("min", "nominal", "max"):
        draws = envelope.level_draws(level, config.uncertainty, config.mismatch)
        block = pts[["point", *envelope.FLIGHT_COLUMNS, "realistic"]].copy()
        for col in envelope.DRAW_COLUMNS:
            block[col] = draws[col]
        block["level"] = level
        rows.append(block)
    frame = pd.concat(rows, ignore_index=True)
    u = _unit_samples(len(frame), config, cell_key)
    return _fill_runs(campaign, group, manoeuvre, frame, u[:, -4:], duration, manoeuvre_set)


def explicit_rows(campaign, runs) -> pd.DataFrame:
    """Run-table rows (no ``run_id``, ``seed`` or ``stream`` yet, but the run's own stream
    under ``explicit_stream``) of explicit runs: the ``[[run]]`` entries of a campaign
    file, or any objects or dicts with their keys (``fdd-campaign falsify`` builds its
    candidate runs here, so a run it writes into ``worst.toml`` replays the same row and
    run id).

    Every value is taken as given; draw columns left out are 0, ``level`` is ``"run"``,
    ``point`` −1, ``realistic`` the verdict of the realistic-envelope rule
    (:func:`scenarios.envelope.realistic_rule`) and ``duration_s`` the campaign's.
    *campaign*: the :class:`campaign.plant_setup.ResolvedCampaign`."""
    config = campaign.config

    def get(run, name):
        return run.get(name) if isinstance(run, dict) else getattr(run, name)

    def number(value):
        return np.nan if value is None else float(value)

    rows = []
    for run in runs:
        draws = dict(get(run, "draws") or ())
        row = {"group": get(run, "group"), "surface": campaign.surface,
               "manoeuvre": get(run, "manoeuvre"), "fault": get(run, "fault"),
               "onset_s": number(get(run, "onset_s")),
               "magnitude": number(get(run, "magnitude")),
               "freq_hz": number(get(run, "freq_hz"))}
        row.update({k: float(get(run, k)) for k in envelope.FLIGHT_COLUMNS})
        row.update({"level": "run", "point": -1})
        row.update({col: float(draws.get(col, 0.0)) for col in envelope.DRAW_COLUMNS})
        row.update({"duration_s": float(config.campaign.duration_s),
                    "manoeuvre_start_s": number(get(run, "manoeuvre_start_s")),
                    "manoeuvre_set": config.manoeuvres.set,
                    "explicit_stream": int(get(run, "stream"))})
        rows.append(row)
    frame = pd.DataFrame(rows)
    frame["realistic"] = envelope.realistic_rule(
        frame[list(envelope.FLIGHT_COLUMNS)], config.uncertainty)["realistic"]
    return frame


def explicit_plan(campaign, runs) -> pd.DataFrame:
    """The run table (columns :data:`PLAN_COLUMNS`, run ids filled) of the explicit runs
    *runs* alone (:func:`explicit_rows`; *campaign* resolved or a configuration); two equal
    runs keep the same run id."""
    campaign = as_resolved(campaign)
    return _finish_block(explicit_rows(campaign, runs), campaign.seed, 0)


#: Rows whose run ids are computed from one list of row dicts [rows]: the dicts (about 3 KB
#: each) are made a block at a time, so a plan of 10⁶ runs does not hold 10⁶ of them at once.
RUN_ID_BLOCK = 4096


def _run_ids(plan: pd.DataFrame) -> list[str]:
    """:func:`run_id` of every row of *plan*, in order: the rows' values taken a column at a
    time (``Series.tolist``, the Python values ``to_dict(orient="records")`` gives, NaN made
    None there), about half the time of a dict per row from pandas."""
    keys = [c for c in plan.columns if c != "run_id"]
    ids: list[str] = []
    for start in range(0, len(plan), RUN_ID_BLOCK):
        block = plan.iloc[start:start + RUN_ID_BLOCK]
        columns = [[_id_value(v) for v in block[c].tolist()] for c in keys]
        ids.extend(_hash_payload(dict(zip(keys, values))) for values in zip(*columns))
    return ids


def _finish_block(frame: pd.DataFrame, seed: int, first_stream: int) -> pd.DataFrame:
    """Rows of a plan, complete: the columns :data:`PLAN_COLUMNS` in order, the campaign's
    *seed*, consecutive streams from *first_stream* (an explicit run keeps its own) and the
    run ids."""
    plan = frame.reset_index(drop=True)
    plan["seed"] = int(seed)
    plan["stream"] = np.arange(len(plan), dtype=np.int64) + first_stream
    if "explicit_stream" in plan.columns:      # explicit runs keep their own streams
        given = plan["explicit_stream"].to_numpy(float)
        keep = np.isfinite(given)
        plan.loc[keep, "stream"] = given[keep].astype(np.int64)
    plan["run_id"] = ""
    plan = plan[list(PLAN_COLUMNS)]
    plan["point"] = plan["point"].astype(np.int64)
    plan["realistic"] = plan["realistic"].astype(bool)
    plan["run_id"] = _run_ids(plan)
    return plan


class DuplicateRuns:
    """The run ids of a plan seen block by block (20 bytes a run, in one array of the plan's
    *rows*), to refuse two rows that describe the same run: :meth:`check` raises
    :class:`ConfigError` naming the group of the first row (in plan order) whose run an
    earlier row already describes."""

    def __init__(self, rows: int) -> None:
        self._ids = np.empty(rows, dtype=f"S{RUN_ID_CHARS}")
        self._seen = 0
        self._groups: list[tuple[int, object]] = []   # (rows, the group or each row's)

    def add(self, block: pd.DataFrame) -> None:
        end = self._seen + len(block)
        self._ids[self._seen:end] = block["run_id"].to_numpy().astype(f"S{RUN_ID_CHARS}")
        self._seen = end
        groups = block["group"].unique()
        self._groups.append((len(block), groups[0] if len(groups) == 1
                             else block["group"].to_numpy(object)))

    def check(self) -> None:
        ids = self._ids[:self._seen]
        ordered = np.sort(ids)
        if not (ordered[1:] == ordered[:-1]).any():
            return
        del ordered
        order = np.argsort(ids, kind="stable")    # equal ids: in plan order
        later = order[1:][ids[order[1:]] == ids[order[:-1]]]
        row = int(later.min())
        for rows, groups in self._groups:
            if row < rows:
                dup = groups if isinstance(groups, str) else groups[row]
                raise ConfigError(f"duplicate runs in group {dup!r}: two rows describe the "
                                  "same run")
            row -= rows


#: Characters of a run id (:func:`run_id`).
RUN_ID_CHARS = 20

#: Rows of a plan made at once when it is made block by block (:class:`PlanBlocks`) [rows]:
#: about 25 MB of draws and rows at a time, whatever the size of the plan.
PLAN_BLOCK_ROWS = 32768


class PlanBlocks:
    """The evaluation run table of *config* (:func:`build_plan`) made block by block: iterating
    gives its rows in order as consecutive DataFrames of at most *block_rows* rows, each
    complete (run ids, seed, streams) and indexed by its rows' positions in the plan, so that
    a plan of any size is written (:meth:`campaign.store.directory.CampaignDir.write_plan`)
    with one block in memory. ``rows``, the number of rows, is known before the first block.
    The rows do not depend on *block_rows* (:func:`_mc_cell`). Once every block is read,
    :meth:`check` refuses two rows that describe the same run (:class:`DuplicateRuns`).
    *campaign*: the :class:`campaign.plant_setup.ResolvedCampaign`."""

    def __init__(self, campaign, block_rows: int = PLAN_BLOCK_ROWS):
        self.campaign = campaign
        self.config = config = campaign.config
        self.block_rows = int(block_rows)
        self._cells: list[tuple[int, Callable[[], Iterator[pd.DataFrame]]]] = []
        duration, mset = config.campaign.duration_s, config.manoeuvres.set
        cell = 0
        for group in config.groups:
            for manoeuvre in _manoeuvres(group.manoeuvres):
                if config.campaign.design == "grid":       # a few hundred rows: made now
                    frame = _grid_cell(campaign, group, manoeuvre, cell, duration, mset)
                    self._cells.append((len(frame), lambda frame=frame: iter([frame])))
                else:
                    self._cells.append((group.count, lambda a=(group, manoeuvre, group.count,
                                                             cell, duration, mset):
                                        _mc_cell(campaign, *a, block_rows=self.block_rows)))
                cell += 1
        if config.runs:         # explicit runs after the groups' (whose streams stay 0…n−1)
            frame = explicit_rows(campaign, config.runs)
            self._cells.append((len(frame), lambda frame=frame: iter([frame])))
        self.rows = sum(rows for rows, _ in self._cells)
        self._duplicates: DuplicateRuns | None = None    # the ids of the last iteration

    def check(self) -> None:
        """:class:`ConfigError` when two rows of the blocks read so far describe the same
        run (call it once they are all read)."""
        if self._duplicates is not None:
            self._duplicates.check()

    def __iter__(self) -> Iterator[pd.DataFrame]:
        start, empty = 0, None
        self._duplicates = DuplicateRuns(self.rows)
        for _, frames in self._cells:
            for frame in frames():
                for lo in range(0, len(frame), self.block_rows):
                    block = _finish_block(frame.iloc[lo:lo + self.block_rows],
                                          self.config.campaign.seed, start)
                    block.index = pd.RangeIndex(start, start + len(block))
                    self._duplicates.add(block)
                    start += len(block)
                    yield block
                    del block
                    if self.rows > self.block_rows:     # what the block's rows and run ids
                        release_freed_memory()          # took (fragmented), given back
                if len(frame) == 0 and empty is None:
                    empty = frame
        if start == 0 and empty is not None:       # no row at all: the columns, typed
            yield _finish_block(empty, self.config.campaign.seed, 0)


def build_plan(campaign) -> pd.DataFrame:
    """The evaluation run table of *campaign* (columns :data:`PLAN_COLUMNS`; a
    :class:`campaign.plant_setup.ResolvedCampaign` or a configuration), in memory; a campaign
    writes it block by block (:class:`PlanBlocks`)."""
    plan = PlanBlocks(as_resolved(campaign))
    blocks = list(plan)
    plan.check()
    return pd.concat(blocks, ignore_index=True)


def build_learning_plan(campaign) -> pd.DataFrame:
    """The fault-free learning set (its own design streams and simulation streams) of
    *campaign*, the :class:`campaign.plant_setup.ResolvedCampaign`."""
    from types import SimpleNamespace

    config = campaign.config
    learn = config.learning
    duration = learn.duration_s or config.campaign.duration_s
    group = SimpleNamespace(name="learning", fault="none", onset_s=None, magnitude=None,
                            freq_hz=None, alt_ft=None, vcas_kt=None, mass_t=None, cg_pct=None)
    mset = config.manoeuvres.learning_set or config.manoeuvres.set
    frames = []
    for j, manoeuvre in enumerate(_manoeuvres(learn.manoeuvres)):
        frames.extend(_mc_cell(campaign, group, manoeuvre, learn.runs_per_manoeuvre,
                               _LEARNING_KEY + j, duration, mset))
    plan = _finish_block(pd.concat(frames, ignore_index=True), config.campaign.seed,
                         LEARNING_STREAM_BASE)
    duplicates = DuplicateRuns(len(plan))
    duplicates.add(plan)
    duplicates.check()
    return plan


def plan_counts(plan) -> pd.DataFrame:
    """Runs per group × manoeuvre × fault (what ``fdd-campaign plan`` prints), in the order
    of their first rows. *plan*: the run table, or consecutive parts of it (an iterable of
    DataFrames, e.g. :meth:`campaign.store.directory.CampaignDir.plan_batches`)."""
    keys = ["group", "fault", "manoeuvre"]
    parts = [plan] if isinstance(plan, pd.DataFrame) else plan
    counts: dict[tuple, int] = {}
    for part in parts:
        for key, n in part.groupby(keys, sort=False).size().items():
            counts[key] = counts.get(key, 0) + int(n)
    return pd.DataFrame([(*key, n) for key, n in counts.items()], columns=[*keys, "runs"])
