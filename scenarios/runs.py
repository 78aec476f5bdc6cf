"""The run row: the columns a batch of runs is described by, their physical ranges, their
validation, each run's random streams and its flight condition.

A campaign's run table (plan.parquet) carries exactly these columns; every plant
(:mod:`scenarios.plants`) simulates from them. Determinism (docs/design.md §9): run i draws
only from ``SeedSequence(seed, spawn_key=(stream,))`` (columns ``seed`` and ``stream``),
spawned into a manoeuvre/turbulence stream and a sensor stream.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from . import envelope
from .errors import InputError
from .catalog import FAULTS, MANOEUVRE_SETS, MANOEUVRES, SURFACES, suggest
from .declare import Declared
from .faults import required_magnitude

def _column(unit: str, doc: str, **bounds) -> Declared:
    return Declared(unit=unit, doc=doc, **bounds)


#: Relative deviations of a run row are accepted within ± this (−): wider than any campaign
#: file's half-width (docs/campaign-file.md), so a replayed run row is never refused for its
#: draws; the hinge-moment mismatches within ±:data:`HINGE_DRAW_LIMIT`.
DRAW_LIMIT, HINGE_DRAW_LIMIT = 0.5, 0.9


def _draw(doc: str, limit: float = DRAW_LIMIT) -> Declared:
    return _column("-", doc, ge=-limit, le=limit)


#: Columns of a run row: name → its declaration (unit, meaning and, for the numbers that
#: are checked, the physical range accepted, inclusive). The campaign's run table carries
#: them.
RUN_COLUMNS: dict[str, Declared] = {
    "run_id": _column("-", "identity of the run"),
    "surface": _column("-", "controlled surface: " + ", ".join(SURFACES)),
    "manoeuvre": _column("-", "fault-free manoeuvre: " + ", ".join(MANOEUVRES)),
    "fault": _column("-", "fault type: " + ", ".join(FAULTS)),
    "onset_s": _column("s", "fault onset (NaN for a fault-free run)"),
    "magnitude": _column("(per fault)", "fault magnitude, see scenarios.faults"),
    "freq_hz": _column("Hz", "oscillation frequency of an OFC (NaN otherwise)"),
    "alt_ft": _column("ft", "true pressure altitude", ge=0.0, le=45000.0),
    "vcas_kt": _column("kt", "true calibrated airspeed", ge=80.0, le=400.0),
    "mass_t": _column("t", "true mass", ge=50.0, le=300.0),
    "cg_pct": _column("% MAC", "true centre of gravity", ge=0.0, le=60.0),
    "d_cx": _draw("relative error of the drag coefficient Cx ([CHEN] Table 2)"),
    "d_cy": _draw("relative error of the side-force coefficient Cy ([CHEN] Table 2)"),
    "d_cz": _draw("relative error of the lift coefficient Cz ([CHEN] Table 2)"),
    "d_cl": _draw("relative error of the rolling-moment coefficient Cl ([CHEN] Table 2)"),
    "d_cm": _draw("relative error of the pitching-moment coefficient Cm ([CHEN] Table 2)"),
    "d_cn": _draw("relative error of the yawing-moment coefficient Cn ([CHEN] Table 2)"),
    "d_vcas": _draw("relative VCAS measurement error ([CHEN] Table 2)"),
    "d_alt": _draw("relative altitude measurement error ([CHEN] Table 2)"),
    "d_mass": _draw("relative mass estimation error ([CHEN] Table 2)"),
    "d_cg": _draw("relative CG estimation error ([CHEN] Table 2)"),
    "d_supply": _draw("relative supply-pressure mismatch (docs/physics.md §6, est.)"),
    "d_kci": _draw("relative servo-valve gain mismatch (docs/physics.md §6, est.)"),
    "d_ch0": _draw("relative mismatch of the hinge-moment coefficient Ch0 (docs/physics.md "
                   "§6, est.)", HINGE_DRAW_LIMIT),
    "d_cha": _draw("relative mismatch of the hinge-moment derivative Chα (docs/physics.md "
                   "§6, est.)", HINGE_DRAW_LIMIT),
    "d_chd": _draw("relative mismatch of the hinge-moment derivative Chδ (docs/physics.md "
                   "§6, est.)", HINGE_DRAW_LIMIT),
    "seed": _column("-", "campaign seed"),
    "stream": _column("-", "run stream index: SeedSequence(seed, spawn_key=(stream,))"),
    "duration_s": _column("s", "run duration", ge=1.0, le=3600.0),
}

#: Manoeuvre set of a run row without a ``manoeuvre_set`` column.
DEFAULT_MANOEUVRE_SET = MANOEUVRE_SETS[0]

#: Physical ranges accepted for run rows (inclusive), read from :data:`RUN_COLUMNS`:
#: column → (low, high).
RUN_RANGES: dict[str, tuple[float, float]] = {
    c: (d.ge, d.le) for c, d in RUN_COLUMNS.items() if d.bounded}


class RunSpecError(InputError, ValueError):
    """A run table that cannot be simulated; ``errors`` lists every problem found."""

    def __init__(self, errors):
        self.errors = list(errors)
        super().__init__("invalid run table:\n  - " + "\n  - ".join(self.errors))

    def __reduce__(self):
        return (type(self), (self.errors,))


def validate_runs(runs: pd.DataFrame, surfaces: tuple[str, ...] = SURFACES) -> None:
    """Raise :class:`RunSpecError` listing every problem of *runs* (names, ranges, onsets);
    *surfaces* are the allowed surface names (the aircraft plant has its own)."""
    errors = []
    missing = [c for c in RUN_COLUMNS if c not in runs.columns]
    if missing:
        raise RunSpecError([f"missing column(s) {missing}; a run row needs {list(RUN_COLUMNS)}"])
    if len(runs) == 0:
        raise RunSpecError(["the run table is empty"])
    for col, allowed in (("surface", surfaces), ("manoeuvre", MANOEUVRES), ("fault", FAULTS)):
        bad = sorted(set(runs[col].astype(str)) - set(allowed))
        for value in bad:
            errors.append(f"{col}: unknown value {value!r}{suggest(value, allowed)}; "
                          f"allowed: {', '.join(allowed)}")
    for col, (lo, hi) in RUN_RANGES.items():
        v = pd.to_numeric(runs[col], errors="coerce").to_numpy(float)
        bad = ~np.isfinite(v) | (v < lo) | (v > hi)
        if bad.any():
            errors.append(f"{col}: {int(bad.sum())} value(s) out of range; allowed: "
                          f"{RUN_COLUMNS[col].range_text(col)} (first: {float(v[bad][0])!r})")
    seed = pd.to_numeric(runs["seed"], errors="coerce").to_numpy(float)
    bad_seed = ~(np.isfinite(seed) & (seed >= 0) & (seed == np.floor(seed)))
    if bad_seed.any():
        errors.append(f"seed: {int(bad_seed.sum())} run(s) whose seed is not an integer ≥ 0 "
                      f"(first: {float(seed[bad_seed][0])!r}); fix: e.g. seed 0")
    if runs["surface"].nunique() > 1 or runs["duration_s"].nunique() > 1:
        errors.append("a batch must share one surface and one duration_s; split it first")
    fault = runs["fault"].astype(str).to_numpy()
    onset = runs["onset_s"].to_numpy(float)
    dur = runs["duration_s"].to_numpy(float)
    faulty = fault != "none"
    bad_onset = faulty & (~np.isfinite(onset) | (onset < 0) | (onset >= dur))
    if bad_onset.any():
        errors.append(f"onset_s: {int(bad_onset.sum())} faulty run(s) with an onset outside "
                      f"[0, duration_s) (first: {float(onset[bad_onset][0])!r} s)")
    needs = np.array([required_magnitude(f) for f in fault])
    bad_mag = needs & ~np.isfinite(runs["magnitude"].to_numpy(float))
    if bad_mag.any():
        errors.append(f"magnitude: {int(bad_mag.sum())} run(s) of fault types "
                      f"{sorted(set(fault[bad_mag]))} need a finite magnitude")
    ofc = np.char.startswith(fault.astype(str), "ofc")
    freq = runs["freq_hz"].to_numpy(float)
    bad_freq = ofc & ~(np.isfinite(freq) & (freq > 0))
    if bad_freq.any():
        errors.append(f"freq_hz: {int(bad_freq.sum())} OFC run(s) need a positive frequency")
    if "manoeuvre_start_s" in runs.columns:
        start = pd.to_numeric(runs["manoeuvre_start_s"], errors="coerce").to_numpy(float)
        bad_start = ~np.isnan(start) & ~((start >= 0) & (start < dur))
        if bad_start.any():
            errors.append(f"manoeuvre_start_s: {int(bad_start.sum())} run(s) with a start "
                          f"outside [0, duration_s) (first: {float(start[bad_start][0])!r} s)")
    if "manoeuvre_set" in runs.columns:
        bad = sorted(set(runs["manoeuvre_set"].astype(str)) - set(MANOEUVRE_SETS))
        for value in bad:
            errors.append(f"manoeuvre_set: unknown value {value!r}"
                          f"{suggest(value, MANOEUVRE_SETS)}; allowed: "
                          f"{', '.join(MANOEUVRE_SETS)}")
    if errors:
        raise RunSpecError(errors)


def manoeuvre_sets(runs: pd.DataFrame) -> list[str]:
    """The manoeuvre set of each run row (``normal`` where the column is absent)."""
    if "manoeuvre_set" not in runs.columns:
        return [DEFAULT_MANOEUVRE_SET] * len(runs)
    return [str(v) for v in runs["manoeuvre_set"]]



def run_streams(seed, stream) -> tuple[np.random.Generator, np.random.Generator]:
    """The run's manoeuvre/turbulence generator and its sensor generator: the two children
    of ``SeedSequence(seed, spawn_key=(stream,))``, made directly as the sequences
    ``spawn(2)`` would give (the same entropy, spawn keys (stream, 0) and (stream, 1), the
    same pool size), without the parent's pool: the same generators, 30 % cheaper."""
    seed, stream = int(seed), int(stream)
    man, sens = (np.random.Generator(np.random.PCG64(
        np.random.SeedSequence(seed, spawn_key=(stream, child)))) for child in (0, 1))
    return man, sens



def flight_of(f: dict) -> tuple[dict, dict]:
    """The true flight condition of each run (Mach, q̄, TAS, trimmed α …) and the scheduling
    data a detector sees (measured/estimated, [CHEN] Table 2), from the run columns *f*
    (float arrays: alt_ft, vcas_kt, mass_t, cg_pct and the d_* deviations)."""
    flight = envelope.flight_condition(f["alt_ft"], f["vcas_kt"], f["mass_t"], f["cg_pct"])
    flight_true = {"alt_ft": f["alt_ft"], "vcas_kt": f["vcas_kt"], "mass_t": f["mass_t"],
                   "cg_pct": f["cg_pct"], **{k: np.asarray(v, float) for k, v in flight.items()}}
    schedule = envelope.measured_schedule(
        f["alt_ft"], f["vcas_kt"], f["mass_t"], f["cg_pct"],
        f["d_alt"], f["d_vcas"], f["d_mass"], f["d_cg"])
    return flight_true, schedule


#: Run columns of the actuator-level draws, as the keyword arguments of
#: :func:`scenarios.servo.plant_arrays` (docs/physics.md §6).
PLANT_DRAWS: tuple[str, ...] = ("d_ch0", "d_cha", "d_chd", "d_supply", "d_kci")


def plant_draws(f: dict) -> dict:
    """The actuator-level draws of the run columns *f* (keywords of
    :func:`scenarios.servo.plant_arrays`)."""
    return {c: f[c] for c in PLANT_DRAWS}


def aero_draws(f: dict) -> dict:
    """The six aerodynamic-coefficient draws of the run columns *f*, keyed by coefficient
    (``cx`` … ``cn``, :data:`scenarios.envelope.AERO_COEFFICIENTS`; [CHEN] Table 2)."""
    return {c: f[f"d_{c}"] for c in envelope.AERO_COEFFICIENTS}
