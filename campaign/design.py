"""Expand a campaign configuration into its run table (docs/design.md §3, data flow step 2).

Two designs, one signature (``build_plan(config) -> DataFrame``):

* ``mc`` — Monte Carlo over the envelope box and the uncertainty box with a scrambled Sobol
  sequence (``scipy.stats.qmc``; plain random with ``sampler = "random"``), one sequence per
  (group, manoeuvre) cell; points failing the realistic-envelope rule are skipped when
  ``realistic_only`` (the sequence simply continues).
* ``grid`` — the parametric sweep: every envelope grid point × the three uncertainty levels
  {min, nominal, max} ([CHEN] §5.1: 108 × 3 = 324 cases), realistic cases only by default.

Every sampled value is a column, so the table fully describes the campaign before it runs.
Run i's simulation streams are ``SeedSequence(seed, spawn_key=(i,))`` (``stream`` = i); the
learning set uses its own streams (:data:`LEARNING_STREAM_BASE` + j), never evaluation ones.
The run id is a hash of the row's canonical JSON and :data:`MODEL_VERSION`.
"""

from __future__ import annotations

import hashlib
import json
import math

import numpy as np
import pandas as pd
from scipy.stats import qmc

from scenarios import envelope
from scenarios.catalog import MANOEUVRES
from scenarios.faults import liquid_jam_bias_mm

from .plant import run_actuator, run_surface

#: Version of the simulated models: part of every run id, so a model change never reuses
#: results computed with the previous model. servo-2: one draw per aerodynamic coefficient
#: and per hinge-moment coefficient, longitudinal–lateral coupling of the surfaces,
#: aft-loaded aileron hinge moment (docs/physics.md §3, §6, §7).
MODEL_VERSION = "servo-2"

#: First stream index of the learning set (disjoint from any evaluation index).
LEARNING_STREAM_BASE = 2 ** 32

#: spawn_key namespaces of the design's own sampling streams.
_DESIGN_KEY, _LEARNING_KEY = 2 ** 33, 2 ** 33 + 1

#: Unit-cube dimensions of one run's sampled values (mc design).
_DIMS = ("alt_ft", "vcas_kt", "mass_t", "cg_pct") + envelope.DRAW_COLUMNS + (
    "onset", "magnitude", "sign", "freq")

PLAN_COLUMNS = (
    "run_id", "group", "surface", "manoeuvre", "fault", "onset_s", "magnitude", "freq_hz",
    "alt_ft", "vcas_kt", "mass_t", "cg_pct", "level", "realistic", "point",
    *envelope.DRAW_COLUMNS, "seed", "stream", "duration_s", "manoeuvre_start_s",
)

#: Columns left out of the run id while they hold NaN (their default), so adding them
#: did not change the identity of runs that do not use them.
_OPTIONAL_ID_COLUMNS = ("manoeuvre_start_s",)


def run_id(row: dict) -> str:
    """Hash of the canonical JSON of a run row (without its id) and the model version."""
    payload = {k: (None if isinstance(v, float) and math.isnan(v) else v)
               for k, v in row.items() if k != "run_id"}
    for k in _OPTIONAL_ID_COLUMNS:
        if payload.get(k, 0) is None:
            del payload[k]
    text = json.dumps(payload, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256((MODEL_VERSION + "|" + text).encode()).hexdigest()[:20]


def _manoeuvres(names) -> list[str]:
    return list(MANOEUVRES) if list(names) == ["all"] else list(names)


def _unit_samples(n: int, config, cell_key: int) -> np.ndarray:
    """*n* points of the unit hypercube for one design cell (Sobol or plain random)."""
    ss = np.random.SeedSequence(config.campaign.seed, spawn_key=(_DESIGN_KEY, cell_key))
    if config.campaign.sampler == "sobol":
        sampler = qmc.Sobol(d=len(_DIMS), scramble=True, seed=np.random.default_rng(ss))
        return sampler.random_base2(max(int(math.ceil(math.log2(max(n, 2)))), 1))[:n]
    return np.random.default_rng(ss).random((n, len(_DIMS)))


def _fault_values(fault: str, u_mag, u_sign, u_freq, config, act):
    """Signed magnitude and frequency of a fault from unit samples."""
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
    if fault in ("ofc_liquid", "ofc_solid"):
        sub = f.ofc_liquid if fault == "ofc_liquid" else f.ofc_solid
        amp = sub.amplitude_mA if fault == "ofc_liquid" else sub.amplitude_mm
        fr = sub.freq_hz
        return (amp[0] + (amp[1] - amp[0]) * u_mag,
                fr[0] + (fr[1] - fr[0]) * u_freq)
    return nan, nan


def _scale(u, values) -> np.ndarray:
    lo, hi = float(min(values)), float(max(values))
    return lo + (hi - lo) * u


def _fill_runs(config, group, manoeuvre, frame: pd.DataFrame, u_rest: np.ndarray,
               duration: float) -> pd.DataFrame:
    """Add fault, onset and fixed-point columns to the flight-point rows of one cell."""
    act = run_actuator(config)
    ts = config.campaign.ts_s
    n = len(frame)
    fl = config.faults
    lo, hi = fl.onset_min_s, duration - fl.onset_before_end_s
    if group.fault == "none":
        onset = np.full(n, np.nan)
    elif group.onset_s is not None:
        onset = np.full(n, float(group.onset_s))
    else:
        onset = lo + (hi - lo) * u_rest[:, 0]
    onset = np.where(np.isfinite(onset), np.round(onset / ts) * ts, np.nan)
    mag, freq = _fault_values(group.fault, u_rest[:, 1], u_rest[:, 2], u_rest[:, 3], config, act)
    if group.magnitude is not None and group.fault != "none":
        mag = np.full(n, float(group.magnitude))
    if getattr(group, "freq_hz", None) is not None:
        freq = np.full(n, float(group.freq_hz))
    direction = getattr(group, "sign", None)
    if direction is not None and group.fault != "none":
        mag = np.abs(mag) * (-1.0 if direction == "negative" else 1.0)
    start = getattr(group, "manoeuvre_start_s", None)
    out = frame.copy()
    out.insert(0, "group", group.name)
    out["surface"] = run_surface(config)
    out["manoeuvre"] = manoeuvre
    out["fault"] = group.fault
    out["onset_s"] = onset
    out["magnitude"] = mag
    out["freq_hz"] = freq
    out["duration_s"] = duration
    out["manoeuvre_start_s"] = np.nan if start is None else float(start)
    for key in ("alt_ft", "vcas_kt", "mass_t", "cg_pct"):
        fixed = getattr(group, key, None)
        if fixed is not None:
            out[key] = float(fixed)
    return out


def _mc_cell(config, group, manoeuvre, n: int, cell_key: int, duration: float) -> pd.DataFrame:
    env, widths = config.envelope, envelope.half_widths(config.uncertainty, config.mismatch)
    need, extra = n, 0
    while True:
        u = _unit_samples(max(4 * need, 16) << extra, config, cell_key)
        pts = pd.DataFrame({
            "alt_ft": _scale(u[:, 0], env.alt_ft), "vcas_kt": _scale(u[:, 1], env.vcas_kt),
            "mass_t": _scale(u[:, 2], env.mass_t), "cg_pct": _scale(u[:, 3], env.cg_pct),
        })
        for j, col in enumerate(envelope.DRAW_COLUMNS):
            pts[col] = (2.0 * u[:, 4 + j] - 1.0) * widths[col]
        pts["realistic"] = envelope.realistic_rule(pts[["alt_ft", "vcas_kt", "mass_t", "cg_pct"]],
                                                   config.uncertainty)["realistic"].to_numpy()
        keep = pts["realistic"].to_numpy() if config.campaign.realistic_only else np.ones(len(pts), bool)
        if keep.sum() >= n:
            idx = np.flatnonzero(keep)[:n]
            break
        extra += 1
        if extra > 6:
            raise ValueError(
                f"group {group.name!r}: fewer than {n} realistic flight points in the envelope "
                "box; widen [envelope] or set realistic_only = false")
    pts = pts.iloc[idx].reset_index(drop=True)
    pts["level"] = "mc"
    pts["point"] = -1
    return _fill_runs(config, group, manoeuvre, pts, u[idx][:, -4:], duration)


def _grid_cell(config, group, manoeuvre, cell_key: int, duration: float) -> pd.DataFrame:
    env = config.envelope
    table = envelope.GridTable(alt_ft=tuple(env.alt_ft), vcas_kt=tuple(env.vcas_kt),
                               mass_t=tuple(env.mass_t), cg_pct=tuple(env.cg_pct))
    pts = envelope.realistic_rule(envelope.grid_points(table), config.uncertainty)
    if config.campaign.realistic_only:
        pts = pts[pts["realistic"]]
    rows = []
    for level in ("min", "nominal", "max"):
        draws = envelope.level_draws(level, config.uncertainty, config.mismatch)
        block = pts[["point", "alt_ft", "vcas_kt", "mass_t", "cg_pct", "realistic"]].copy()
        for col in envelope.DRAW_COLUMNS:
            block[col] = draws[col]
        block["level"] = level
        rows.append(block)
    frame = pd.concat(rows, ignore_index=True)
    u = _unit_samples(len(frame), config, cell_key)
    return _fill_runs(config, group, manoeuvre, frame, u[:, -4:], duration)


def _finish(frames: list[pd.DataFrame], seed: int, stream_base: int) -> pd.DataFrame:
    plan = pd.concat(frames, ignore_index=True)
    plan["seed"] = int(seed)
    plan["stream"] = np.arange(len(plan), dtype=np.int64) + stream_base
    plan["run_id"] = ""
    plan = plan[list(PLAN_COLUMNS)]
    plan["point"] = plan["point"].astype(np.int64)
    plan["realistic"] = plan["realistic"].astype(bool)
    records = plan.to_dict(orient="records")
    plan["run_id"] = [run_id(r) for r in records]
    if plan["run_id"].duplicated().any():
        dup = plan.loc[plan["run_id"].duplicated(), "group"].iloc[0]
        raise ValueError(f"duplicate runs in group {dup!r}: two rows describe the same run")
    return plan


def build_plan(config) -> pd.DataFrame:
    """The evaluation run table of *config* (columns :data:`PLAN_COLUMNS`)."""
    frames, cell = [], 0
    for group in config.groups:
        for manoeuvre in _manoeuvres(group.manoeuvres):
            if config.campaign.design == "grid":
                frames.append(_grid_cell(config, group, manoeuvre, cell,
                                         config.campaign.duration_s))
            else:
                frames.append(_mc_cell(config, group, manoeuvre, group.count, cell,
                                       config.campaign.duration_s))
            cell += 1
    return _finish(frames, config.campaign.seed, 0)


def build_learning_plan(config) -> pd.DataFrame:
    """The fault-free learning set (its own design streams and simulation streams)."""
    from types import SimpleNamespace

    learn = config.learning
    duration = learn.duration_s or config.campaign.duration_s
    group = SimpleNamespace(name="learning", fault="none", onset_s=None, magnitude=None,
                            freq_hz=None, alt_ft=None, vcas_kt=None, mass_t=None, cg_pct=None)
    frames = []
    for j, manoeuvre in enumerate(_manoeuvres(learn.manoeuvres)):
        frames.append(_mc_cell(config, group, manoeuvre, learn.runs_per_manoeuvre,
                               _LEARNING_KEY + j, duration))
    return _finish(frames, config.campaign.seed, LEARNING_STREAM_BASE)


def plan_counts(plan: pd.DataFrame) -> pd.DataFrame:
    """Runs per group × manoeuvre × fault (what ``fdd-campaign plan`` prints)."""
    return (plan.groupby(["group", "fault", "manoeuvre"], sort=False).size()
            .rename("runs").reset_index())
