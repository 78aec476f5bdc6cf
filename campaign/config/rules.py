"""Rules of the campaign file that involve several keys, and the values they derive.

They run after every key was checked on its own (:func:`campaign.config.convert.build_table`)
on the checked values: one dict per table, keys → frozen value, default or
:data:`~campaign.config.convert.BAD` (whose error is already recorded), with the keys
written in the file under ``"__present__"``. Validation runs, in this order:

1. :func:`normalise` — keys that only apply to Monte Carlo designs are ``None`` with
   ``design = "grid"``; a ``[[detector]]`` without ``label`` is labelled with its name;
2. :func:`check_rules` — every rule appends its problems to the error list, in file order,
   and changes nothing;
3. :func:`derive_group_names` — a ``[[group]]`` without ``name`` is named
   ``fault@manoeuvres`` (unique, never one of the names given in the file).

:func:`normalise` and :func:`derive_group_names` return new values; their input is left
as it is.
"""

from __future__ import annotations

import inspect
import re
import warnings
from types import SimpleNamespace
from typing import Any, Mapping

from detectors.compat import incompatibilities, offline_problems
from scenarios.catalog import (AIRCRAFT_KINDS, DETECTION_BUDGET_S, MANOEUVRES, latest_onset_s,
                               suggest)

from .convert import is_ok
from .keys import key_spec, leaf_fields, thaw
from .sections import (
    FAULT_MAGNITUDE_KEY,
    FAULT_VARIANTS,
    MAGNITUDE_VARIANT,
    OFC_FAULTS,
    SIGNED_FAULTS,
    CampaignSection,
    FaultsSection,
    GroupSpec,
    PlantSection,
    PlantVariables,
)
from .text import num

__all__ = ["normalise", "check_rules", "check_detectors", "check_systems",
           "requirement_name_problems", "derive_group_names", "magnitude_spec",
           "single_fault_problems"]


# ----------------------------------------------------------------------------------------
# Old spellings (before anything is checked)
# ----------------------------------------------------------------------------------------
#: Keys that moved: (old section, old key) → (new section, new key). Campaign files that use
#: an old spelling keep working (docs/campaign-file.md, "Keys that moved").
MOVED_KEYS: dict[tuple[str, str], tuple[str, str]] = {
    ("campaign", "plant"): ("plant", "kind"),
    ("campaign", "monitored_surface"): ("plant", "monitored_surface"),
}


def migrate(data: Mapping[str, Any], errors: list[str]) -> Mapping[str, Any]:
    """*data* (a campaign file's content) with the keys of :data:`MOVED_KEYS` under their
    new names, each move announced by a one-line FutureWarning naming the new spelling. The
    old and the new spelling together with different values is an error (appended to
    *errors*). *data* itself is not changed."""
    moves = [(old, new) for old, new in MOVED_KEYS.items()
             if isinstance(data.get(old[0]), Mapping) and old[1] in data[old[0]]]
    if not moves:
        return data
    out = {k: dict(v) if isinstance(v, Mapping) else v for k, v in data.items()}
    for (sec, name), (new_sec, new_name) in moves:
        value = out[sec].pop(name)
        target = out.setdefault(new_sec, {})
        if not isinstance(target, dict):
            continue                     # reported by the section's own check
        if new_name in target and target[new_name] != value:
            errors.append(f"{sec}.{name}: old spelling of {new_sec}.{new_name}, which is also "
                          f"set, to another value; fix: remove {sec}.{name}")
            continue
        target.setdefault(new_name, value)
        warnings.warn(f"[{sec}] {name} is now [{new_sec}] {new_name}; the old spelling still "
                      "works", FutureWarning, stacklevel=5)
    return out


# ----------------------------------------------------------------------------------------
# Normalisation (before the rules) and derived names (after them)
# ----------------------------------------------------------------------------------------
def normalise(values: Mapping[str, Any]) -> dict[str, Any]:
    """The checked *values* as the rules and the dataclasses take them (a new dict).

    With ``design = "grid"`` every key that only applies to ``design = "mc"`` is ``None``
    (one written in the file is an error of :func:`check_rules`); a ``[[detector]]``
    without ``label`` whose ``name`` is valid takes its name as label.
    """
    design = values["campaign"]["design"]
    return {
        **values,
        "campaign": _without_mc_only_keys(values["campaign"], CampaignSection, design),
        "groups": [_without_mc_only_keys(g, GroupSpec, design) for g in values["groups"]],
        "detectors": [_with_label(d) for d in values["detectors"]],
    }


def _without_mc_only_keys(table: Mapping[str, Any], cls: type, design: Any) -> dict:
    if design != "grid":
        return dict(table)
    cleared = {f.name: None for f in leaf_fields(cls) if f.metadata["key"].only == "mc"}
    return {**table, **cleared}


def _with_label(det: Mapping[str, Any]) -> dict:
    """*det* with its label (its name when none is given) and without a ``threshold_scale``
    of 1, the default: a file that writes it has the canonical form of one that does not."""
    out = dict(det)
    if is_ok(det["name"]) and det["label"] is None:
        out["label"] = det["name"]
    if det.get("threshold_scale") == 1.0:
        out["threshold_scale"] = None
    return out


def derive_group_names(values: Mapping[str, Any]) -> dict[str, Any]:
    """*values* with a name for every ``[[group]]`` that has none (a new dict).

    The name is ``fault@manoeuvres`` (``all`` for every manoeuvre, else the manoeuvres
    joined by ``+``; ``fault[variant]@…`` when the group sets a ``variant``), with ``#2``, ``#3``, …
    appended when it is already taken by a name given in the file or derived before. Groups whose
    fault or manoeuvres are invalid keep no name (the file has errors).
    """
    groups = values["groups"]
    taken = {g["name"] for g in groups if g["name"] is not None and is_ok(g["name"])}
    named = []
    for g in groups:
        if g["name"] is None and is_ok(g["fault"], g["manoeuvres"]):
            man = g["manoeuvres"]
            variant = g.get("variant")
            kind = (f"{g['fault']}[{variant}]" if variant is not None and is_ok(variant)
                    else g["fault"])
            base = f"{kind}@{'all' if man == MANOEUVRES else '+'.join(man)}"
            name, n = base, 1
            while name in taken:
                n += 1
                name = f"{base}#{n}"
            taken.add(name)
            g = {**g, "name": name}
        named.append(g)
    return {**values, "groups": named}


# ----------------------------------------------------------------------------------------
# The rules
# ----------------------------------------------------------------------------------------
def check_rules(values: Mapping[str, Any], errors: list[str], *,
                requirement_names: bool = False) -> None:
    """Append to *errors* every problem that involves several keys of the (normalised)
    *values*, in the order of the file: [campaign], [faults], each [[group]], each
    [[detector]], with *requirement_names* the detectors [requirements] names, [plant]."""
    camp = values["campaign"]
    design, duration = camp["design"], camp["duration_s"]
    _check_mc_only_keys(camp, "campaign", CampaignSection, design, errors)
    _check_monitored_surface(values["plant"], errors)
    _check_turbulence(values["plant"], errors)
    _check_onset_window(values["faults"], duration, errors)
    _check_groups(values["groups"], design, duration, errors, values["faults"])
    _check_runs(values, errors)
    check_detectors(values["detectors"], camp, values["plant"], errors)
    check_systems(values["systems"], values["detectors"], errors)
    if requirement_names:
        _check_requirement_names(values["requirements"], values["detectors"], errors)
    _check_plant(values["plant"], camp, errors)


def _check_mc_only_keys(table: Mapping, path: str, cls: type, design: Any,
                        errors: list[str]) -> None:
    """Keys that only apply to Monte Carlo designs must not be written with grid."""
    if design != "grid":
        return
    for f in leaf_fields(cls):
        if f.metadata["key"].only == "mc" and f.name in table["__present__"]:
            errors.append(f"{path}.{f.name}: only used with design = \"mc\"; fix: "
                          f"remove it (grid runs one run per case)")


def _check_turbulence(plant: Mapping, errors: list[str]) -> None:
    """The turbulence level belongs to the aircraft plant (the actuator plant's orders carry
    the control law's reaction to moderate turbulence, docs/physics.md §7)."""
    if plant["kind"] not in AIRCRAFT_KINDS and plant.get("turbulence", "moderate") != "moderate":
        errors.append("plant.turbulence: only used with kind = \"aircraft\"; fix: remove it "
                      "or set [plant] kind = \"aircraft\" (or \"jsbsim\")")


def _check_monitored_surface(plant: Mapping, errors: list[str]) -> None:
    """The monitored surface belongs to the aircraft plant."""
    if plant["kind"] == "actuator" and plant.get("monitored_surface") is not None:
        errors.append("plant.monitored_surface: only used with kind = \"aircraft\"; fix: "
                      "remove it or set [plant] kind = \"aircraft\"")


def _check_onset_window(faults: Mapping, duration: Any, errors: list[str]) -> None:
    """The window the fault onset is sampled from must not be empty."""
    onset_min, before_end = faults["onset_min_s"], faults["onset_before_end_s"]
    if not is_ok(duration, onset_min, before_end):
        return
    latest = duration - before_end
    if onset_min > latest:
        errors.append(
            f"faults.onset_min_s: empty onset window [{num(onset_min)}, "
            f"{num(latest)}] s (duration_s {num(duration)} − onset_before_end_s "
            f"{num(before_end)}); fix: lower onset_min_s or "
            f"onset_before_end_s, or lengthen campaign.duration_s")


# ---- [[group]] ----------------------------------------------------------------------------
def _check_groups(groups: list, design: Any, duration: Any, errors: list[str],
                  faults: Mapping | None = None) -> None:
    """The rules of each [[group]], group by group; names given must be unique."""
    explicit: dict[str, str] = {}
    for i, g in enumerate(groups):
        p = f"group[{i}]"
        _check_mc_only_keys(g, p, GroupSpec, design, errors)
        _check_count(g, p, design, errors)
        fault = g["fault"]
        if is_ok(fault) and fault == "none":
            _check_fault_free(g, p, errors)
        elif is_ok(fault):
            _check_variant(g, p, fault, errors)
            _check_magnitude(g, p, fault, errors)
            _check_sign(g, p, fault, errors)
            _check_freq(g, p, fault, errors)
            _check_onset(g, p, duration, errors)
            _check_detection_budget(g, p, fault, duration, faults, errors)
        _check_manoeuvre_start(g, p, duration, errors)
        _check_unique_name(g, p, explicit, errors)


def _check_detection_budget(g: Mapping, p: str, fault: str, duration: Any,
                            faults: Mapping | None, errors: list[str]) -> None:
    """A group that draws its onsets must leave the fault's detection budget before the end
    of the run (:data:`scenarios.catalog.DETECTION_BUDGET_S`, docs/physics.md §5)."""
    if faults is None or _given(g, "onset_s") or fault not in DETECTION_BUDGET_S:
        return
    onset_min, before_end = faults["onset_min_s"], faults["onset_before_end_s"]
    if not is_ok(duration, onset_min, before_end):
        return
    latest = latest_onset_s(fault, duration, before_end)
    if onset_min > latest:
        errors.append(
            f"{p}.fault: a {fault} needs its detection budget of "
            f"{num(DETECTION_BUDGET_S[fault])} s after the onset (docs/physics.md §5), so its "
            f"onsets lie in [{num(onset_min)}, {num(latest)}] s: empty; fix: lengthen "
            f"campaign.duration_s to at least {num(onset_min + DETECTION_BUDGET_S[fault])} s, "
            f"lower faults.onset_min_s, or fix the group's onset_s")


def _given(g: Mapping, k: str) -> bool:
    """Whether key *k* of group (or run) *g* is set to a valid value."""
    return g.get(k) is not None and is_ok(g[k])


def _check_count(g: Mapping, p: str, design: Any, errors: list[str]) -> None:
    if design == "mc" and g["count"] is None:
        errors.append(f"{p}.count: missing; required with design = \"mc\" (runs per "
                      f"manoeuvre); fix: add count = 10")


def _check_fault_free(g: Mapping, p: str, errors: list[str]) -> None:
    for k in ("onset_s", "magnitude", "freq_hz", "sign", "variant"):
        if _given(g, k):
            errors.append(f"{p}.{k}: a fault-free group (fault = \"none\") has "
                          f"no {k}; fix: remove it")


def _variant(g: Mapping, fault: str) -> str | None:
    """The group's variant of *fault* (its default when not given; None: no variants)."""
    if fault not in FAULT_VARIANTS:
        return None
    return g["variant"] if _given(g, "variant") else FAULT_VARIANTS[fault][0]


def _check_variant(g: Mapping, p: str, fault: str, errors: list[str]) -> None:
    if fault not in FAULT_VARIANTS and _given(g, "variant"):
        errors.append(f"{p}.variant: fault {fault!r} has no variants; allowed only with: "
                      f"{', '.join(FAULT_VARIANTS)}; fix: remove it")


def _without_magnitude(g: Mapping, p: str, k: str, fault: str, errors: list[str]) -> bool:
    """True (and an error) when *fault* has variants and the group's has no magnitude."""
    if fault not in MAGNITUDE_VARIANT:
        return False
    variant, needed = _variant(g, fault), MAGNITUDE_VARIANT[fault]
    if variant == needed:
        return False
    what = "direction" if k == "sign" else k
    errors.append(f"{p}.{k}: fault {fault!r} has no {what} with variant = \"{variant}\""
                  f"{' (the default)' if not _given(g, 'variant') else ''}; fix: remove it, "
                  f"or set variant = \"{needed}\"")
    return True


def _check_magnitude(g: Mapping, p: str, fault: str, errors: list[str]) -> None:
    """A fixed magnitude needs a fault that has one, within that fault's [faults.*]
    range."""
    if not _given(g, "magnitude"):
        return
    if _without_magnitude(g, p, "magnitude", fault, errors):
        return
    spec = magnitude_spec(fault)
    if spec is None:
        errors.append(f"{p}.magnitude: fault {fault!r} has no magnitude; "
                      f"allowed only with: {', '.join(FAULT_MAGNITUDE_KEY)}; "
                      "fix: remove it")
        return
    if spec.out_of_range(g["magnitude"]):
        errors.append(f"{p}.magnitude: {num(g['magnitude'])} is out of range "
                      f"for {fault}; allowed: "
                      f"{spec.range_text('magnitude')}")
        return
    _announce_fixed_magnitude(g, p, fault)


def magnitude_spec(fault: str):
    """The key whose bounds and unit a fixed magnitude of *fault* has (its ``[faults.*]``
    range's, :data:`FAULT_MAGNITUDE_KEY`: runaway deg/s, a jam's %, the OFC amplitudes mA
    and mm), or None when the fault has no magnitude."""
    if fault not in FAULT_MAGNITUDE_KEY:
        return None
    sub, k = FAULT_MAGNITUDE_KEY[fault]
    return key_spec(FaultsSection, sub, k)


def single_fault_problems(fault: str, *, magnitude: float | None, variant: str | None,
                          sign: str | None, onset_s: float, duration_s: float,
                          names: Mapping[str, str]) -> list[str]:
    """The rules of a ``[[group]]``'s fault keys (``magnitude``, ``variant``, ``sign``,
    ``onset_s``) for one run given outside a campaign file (``fdd-campaign simulate``):
    the same ranges, units and combinations, each problem naming the key as *names* spells
    it (group key → e.g. ``"--magnitude"``; ``duration_s`` too) and its fix."""
    out: list[str] = []
    if fault == "none":
        return [f"{names[k]}: a fault-free run has no {k}; fix: leave it out, or give a fault"
                for k, v in (("magnitude", magnitude), ("variant", variant), ("sign", sign))
                if v is not None]
    if variant is not None and fault not in FAULT_VARIANTS:
        out.append(f"{names['variant']} {variant}: fault {fault!r} has no variants; allowed "
                   f"only with: {', '.join(FAULT_VARIANTS)}; fix: leave it out")
    chosen = (variant or FAULT_VARIANTS[fault][0]) if fault in FAULT_VARIANTS else None
    needed = MAGNITUDE_VARIANT.get(fault)
    for k, value in (("magnitude", magnitude), ("sign", sign)):
        if value is None:
            continue
        what = "direction" if k == "sign" else k
        if needed is not None and chosen != needed:
            out.append(f"{names[k]} {num(value) if k == 'magnitude' else value}: fault "
                       f"{fault!r} has no {what} with {names['variant']} {chosen}"
                       f"{' (the default)' if variant is None else ''}; fix: leave it out, "
                       f"or add {names['variant']} {needed}")
        elif k == "sign" and fault not in SIGNED_FAULTS:
            out.append(f"{names['sign']} {value}: fault {fault!r} has no direction; allowed "
                       f"only with: {', '.join(SIGNED_FAULTS)}; fix: leave it out")
        elif k == "magnitude":
            spec = magnitude_spec(fault)
            if spec is None:
                out.append(f"{names['magnitude']} {num(value)}: fault {fault!r} has no "
                           f"magnitude; allowed only with: {', '.join(FAULT_MAGNITUDE_KEY)}; "
                           "fix: leave it out")
            elif spec.out_of_range(value):
                sub, key_name = FAULT_MAGNITUDE_KEY[fault]
                fix = (f"{names['magnitude']} {num(-value)} {names['sign']} negative (the "
                       "direction is its own option)"
                       if fault in SIGNED_FAULTS and -value > 0 and not spec.out_of_range(-value)
                       else f"a {names['magnitude']} in that range")
                out.append(f"{names['magnitude']} {num(value)}: out of range for {fault}; "
                           f"allowed: {spec.range_text('magnitude')}, in the unit and within "
                           f"the bounds of [faults.{sub}] {key_name} (as a [[group]] "
                           f"magnitude); fix: {fix}")
    if not 0.0 <= onset_s < duration_s:
        out.append(f"{names['onset_s']} {num(onset_s)}: the fault's onset must fall within "
                   f"the run; allowed: 0 ≤ {names['onset_s']} < {names['duration_s']} = "
                   f"{num(duration_s)} s; fix: an earlier {names['onset_s']}, or a longer "
                   f"{names['duration_s']}")
    return out


class MagnitudeReadingNote(FutureWarning):
    """The note that a liquid jam's ``[[group]] magnitude`` is read in % of the deflection
    range (it was read as rod mm). No spelling of a file avoids it, so it is meant for files
    written before that change: the shipped presets (written in %) and a re-validation of
    values already read (:func:`campaign.config.load.with_overrides`) do not show it."""


def _announce_fixed_magnitude(g: Mapping, p: str, fault: str) -> None:
    """One-line notes where a fixed magnitude reads differently than it once did:
    a liquid jam's in % of the deflection range (it was taken as rod mm), and a signed
    fault's direction drawn per run unless ``sign`` is given (it was always positive)."""
    if fault == "liquid_jam":
        warnings.warn(f"{p}.magnitude = {num(g['magnitude'])} is read in % of the deflection "
                      "range, like [faults.liquid_jam] bias_pct_range (it was read as rod mm)",
                      MagnitudeReadingNote, stacklevel=6)
    if fault in SIGNED_FAULTS and not _given(g, "sign"):
        warnings.warn(f"{p}.magnitude: the direction is drawn per run (both signs; it was "
                      "always positive); fix it with sign = \"positive\" or \"negative\"",
                      FutureWarning, stacklevel=6)


def _check_sign(g: Mapping, p: str, fault: str, errors: list[str]) -> None:
    if _given(g, "sign") and _without_magnitude(g, p, "sign", fault, errors):
        return
    if fault not in SIGNED_FAULTS and _given(g, "sign"):
        errors.append(f"{p}.sign: fault {fault!r} has no direction; allowed only "
                      f"with: {', '.join(SIGNED_FAULTS)}; fix: remove it")


def _check_freq(g: Mapping, p: str, fault: str, errors: list[str]) -> None:
    if fault not in OFC_FAULTS and _given(g, "freq_hz"):
        errors.append(f"{p}.freq_hz: only for {', '.join(OFC_FAULTS)}; fix: "
                      "remove it")


def _check_onset(g: Mapping, p: str, duration: Any, errors: list[str]) -> None:
    onset = g["onset_s"]
    if is_ok(onset, duration) and onset is not None and onset >= duration:
        errors.append(f"{p}.onset_s: {num(onset)} s is not before the end "
                      f"of the run; allowed: 0 ≤ onset_s < duration_s = "
                      f"{num(duration)} s")


def _check_manoeuvre_start(g: Mapping, p: str, duration: Any, errors: list[str]) -> None:
    start = g["manoeuvre_start_s"]
    if is_ok(start, duration) and start is not None and start >= duration:
        errors.append(f"{p}.manoeuvre_start_s: {num(start)} s is not before the end of "
                      f"the run; allowed: 0 ≤ manoeuvre_start_s < duration_s = "
                      f"{num(duration)} s")


def _check_unique_name(g: Mapping, p: str, seen: dict[str, str], errors: list[str]) -> None:
    """A group name given in the file must not repeat one given before (*seen*: name →
    path of the group that gave it; updated)."""
    name = g["name"]
    if not _given(g, "name"):
        return
    if name in seen:
        errors.append(f"{p}.name: duplicate group name {name!r} (also "
                      f"{seen[name]}); fix: give each group a unique name")
    seen[name] = p


# ---- [[run]] ------------------------------------------------------------------------------
def _check_runs(values: Mapping[str, Any], errors: list[str]) -> None:
    """Each explicit [[run]]: the fault keys its fault type needs and no others, the onset
    and the manoeuvre start before the end of the run, draws naming draw columns of the run
    table within the campaign's half-widths, and, with realistic_only, a flight point that
    passes the realistic-envelope rule (docs/physics.md §6)."""
    from scenarios import envelope
    from scenarios.faults import required_magnitude

    runs = values["runs"]
    if not runs:
        return
    camp = values["campaign"]
    duration = camp["duration_s"]
    tables = [{k: v for k, v in values[sec].items() if k != "__present__"}
              for sec in ("uncertainty", "mismatch")]
    widths = (envelope.half_widths(SimpleNamespace(**tables[0]), SimpleNamespace(**tables[1]))
              if all(is_ok(*t.values()) for t in tables) else None)
    for i, r in enumerate(runs):
        p = f"run[{i}]"
        fault = r["fault"]
        if is_ok(fault) and fault == "none":
            _check_fault_free(r, p, errors)
        elif is_ok(fault):
            if not _given(r, "onset_s") and is_ok(r["onset_s"]):
                errors.append(f"{p}.onset_s: missing; a faulty run needs its onset; fix: "
                              "add onset_s = 30.0 (seconds, before the end of the run)")
            _check_onset(r, p, duration, errors)
            if required_magnitude(fault) and r["magnitude"] is None:
                errors.append(f"{p}.magnitude: missing; fault {fault!r} needs a signed "
                              "magnitude in the run-table unit (scenarios/faults.py); fix: "
                              "add magnitude = …")
            elif not required_magnitude(fault) and _given(r, "magnitude"):
                errors.append(f"{p}.magnitude: fault {fault!r} has no magnitude; fix: "
                              "remove it")
            if fault in OFC_FAULTS and r["freq_hz"] is None:
                errors.append(f"{p}.freq_hz: missing; an oscillatory failure needs its "
                              "frequency; fix: add freq_hz = 1.0")
            _check_freq(r, p, fault, errors)
        _check_manoeuvre_start(r, p, duration, errors)
        _check_draws(r, p, widths, errors)
        _check_realistic(r, p, camp, values["uncertainty"], errors)


def _check_draws(r: Mapping, p: str, widths: dict | None, errors: list[str]) -> None:
    """The draws of a [[run]] name draw columns (:data:`scenarios.envelope.DRAW_COLUMNS`),
    each within ± the campaign's half-width of that column (*widths*; None: the half-widths
    have errors of their own)."""
    from scenarios.envelope import DRAW_COLUMNS

    if not is_ok(r["draws"]):
        return
    for name, value in r["draws"]:
        if name not in DRAW_COLUMNS:
            errors.append(f"{p}.draws.{name}: unknown draw column{suggest(name, DRAW_COLUMNS)};"
                          f" allowed: {', '.join(DRAW_COLUMNS)}")
        elif widths is not None and abs(value) > widths[name]:
            errors.append(f"{p}.draws.{name}: {num(value)} is outside the campaign's "
                          f"half-width ±{num(widths[name])} ([uncertainty]/[mismatch]); fix: "
                          f"a value in [{num(-widths[name])}, {num(widths[name])}], or widen "
                          "the half-width")


def _check_realistic(r: Mapping, p: str, camp: Mapping, unc: Mapping,
                     errors: list[str]) -> None:
    """With realistic_only, the run's flight point must pass the realistic-envelope rule."""
    import pandas as pd

    from scenarios import envelope

    point = [r[k] for k in envelope.FLIGHT_COLUMNS]
    widths = {k: v for k, v in unc.items() if k != "__present__"}
    if not (camp["realistic_only"] is True and is_ok(*point, *widths.values())):
        return
    frame = pd.DataFrame([point], columns=list(envelope.FLIGHT_COLUMNS))
    flags = envelope.realistic_rule(frame, SimpleNamespace(**widths))
    if not bool(flags["realistic"].iloc[0]):
        errors.append(f"{p}: flight point {num(point[0])} ft, {num(point[1])} kt, "
                      f"{num(point[2])} t, {num(point[3])} % MAC fails the realistic-envelope "
                      f"rule ({flags['rejected_by'].iloc[0]}; docs/physics.md §6); fix: choose "
                      "a realistic point, or set [campaign] realistic_only = false")


# ---- [[detector]] -------------------------------------------------------------------------
def check_detectors(dets: list, camp: Mapping, plant: Mapping, errors: list[str]) -> None:
    """Each [[detector]]: unique label, registered name, parameters its class accepts,
    and the signals it needs provided by the campaign's plant
    (:func:`detectors.compat.incompatibilities`, the one compatibility rule)."""
    from detectors.registry import (
        DetectorSpecError,
        available_detectors,
        load_detector_class,
        parameter_errors,
    )

    registered = list(available_detectors())
    labels: dict[str, str] = {}
    for i, d in enumerate(dets):
        p = f"detector[{i}]"
        _check_unique_label(d, p, labels, errors)
        name = d["name"]
        if not is_ok(name):
            continue
        if name not in registered:
            errors.append(f"{p}.name: unknown detector {name!r}{suggest(name, registered)}; "
                          f"allowed: {', '.join(sorted(registered))} (third-party detectors "
                          "register through the entry-point group fdd_campaign.detectors)")
            continue
        if not is_ok(d["params"]):
            continue
        try:
            problems = parameter_errors(name, thaw(d["params"], "table"))
            cls = load_detector_class(name)
        except DetectorSpecError as exc:
            errors.append(f"{p}.name: {exc}")
            continue
        for msg in problems:
            hint = "" if "allowed:" in msg else f"; parameters and defaults: " \
                f"{signature_text(cls)}"
            errors.append(f"{p}.params: {msg}{hint}")
        caps = getattr(cls, "capabilities", None)
        if caps is not None:
            _check_compatibility(name, caps, p, camp, plant, errors)
            _check_threshold_scale(d, name, caps, p, errors)
            errors.extend(f"{p}.name: {msg}" for msg in offline_problems({name: caps}))


def _check_threshold_scale(d: Mapping, name: str, caps, p: str, errors: list[str]) -> None:
    """A ``threshold_scale`` other than 1 needs a detector whose decision has a threshold
    scale (:attr:`detectors.base.Capabilities.threshold_scale`)."""
    scale = d.get("threshold_scale")
    if is_ok(scale) and scale is not None and not getattr(caps, "threshold_scale", False):
        errors.append(f"{p}.threshold_scale: detector {name!r} has no threshold scale (its "
                      "Capabilities.threshold_scale is False: its alarm is not a decision "
                      "statistic compared with 1, so its thresholds cannot be multiplied); "
                      "fix: remove threshold_scale, or set the detector's own threshold "
                      "parameters in params")


def _check_unique_label(d: Mapping, p: str, seen: dict[str, str], errors: list[str]) -> None:
    """A detector label must not repeat one before (*seen*: label → path; updated)."""
    label = d["label"]
    if is_ok(label) and label is not None:
        if label in seen:
            errors.append(f"{p}.label: duplicate label {label!r} (also {seen[label]}); "
                          "fix: give each [[detector]] a unique label = \"…\"")
        seen[label] = p


def _check_compatibility(name: str, caps, p: str, camp: Mapping, plant: Mapping,
                         errors: list[str]) -> None:
    """Detector *name* (capabilities *caps*) must find what it reads on the campaign's plant
    (the plant kind's provides; an FMU plant provides what the actuator plant does)."""
    if not is_ok(camp["surface"], camp["pressure_sensor"], plant["kind"],
                 plant["monitored_surface"]):
        return
    from scenarios.plants import get_plant     # the plants' modules: only when a detector is named

    built = get_plant(plant["kind"])
    surface = built.run_surface(camp["surface"], plant["monitored_surface"])
    for msg in incompatibilities({name: caps}, built, surface,
                                 pressure_sensor=camp["pressure_sensor"]):
        errors.append(f"{p}.name: {msg}")


def signature_text(cls: type) -> str:
    """The keyword parameters of detector class *cls* with their defaults, for hints."""
    parts = []
    for prm in inspect.signature(cls.__init__).parameters.values():
        if prm.name == "self" or prm.kind in (prm.VAR_POSITIONAL, prm.VAR_KEYWORD):
            continue
        parts.append(prm.name if prm.default is prm.empty else f"{prm.name}={prm.default!r}")
    return ", ".join(parts) or "(none)"


# ---- [[system]] ---------------------------------------------------------------------------
def check_systems(systems: list, dets: list, errors: list[str]) -> None:
    """Each [[system]]: a name no detector label or other system has, and members that name
    the campaign's detectors (a label, or a label followed by a variant, LABEL[VARIANT];
    which variants a detector has is known from its results, where the engine checks
    them)."""
    labels = [d["label"] for d in dets]
    if not is_ok(*labels) or None in labels:
        labels = []
    seen: dict[str, str] = {label: "a [[detector]] label" for label in labels}
    for i, sysspec in enumerate(systems):
        p = f"system[{i}]"
        name = sysspec["name"]
        if is_ok(name):
            if name in seen:
                errors.append(f"{p}.name: {name!r} is already {seen[name]}; fix: give the "
                              "system a name of its own")
            seen.setdefault(name, f"the name of {p}")
        members = sysspec["members"]
        if not (labels and is_ok(members)):
            continue
        for j, member in enumerate(members):
            base = member.split("[", 1)[0]
            if base in labels and member == base:
                continue
            if base in labels and member.endswith("]"):
                _check_member_variant(member, dets[labels.index(base)], f"{p}.members[{j}]",
                                      errors)
                continue
            errors.append(f"{p}.members[{j}]: {member!r} names no detector of this "
                          f"campaign{suggest(base, labels)}; its detectors ([[detector]] "
                          f"labels): {', '.join(labels)} (or one of their variants: "
                          "LABEL[VARIANT])")


def _check_member_variant(member: str, det: Mapping, p: str, errors: list[str]) -> None:
    """A member ``LABEL[VARIANT]`` must be a variant its detector gives, when its parameters
    fix its variants (:meth:`detectors.base.Detector.variant_names`)."""
    from detectors.registry import make_detector

    if not is_ok(det["name"], det["params"]):
        return
    try:
        names = make_detector(det["name"], thaw(det["params"], "table")).variant_names()
    except Exception:  # noqa: BLE001 - the detector's own problems are reported by its table
        return
    variant = member.split("[", 1)[1][:-1]
    if names is not None and variant not in names:
        label = member.split("[", 1)[0]
        errors.append(f"{p}: {member!r} is no variant of detector {label!r}, whose results "
                      f"are {', '.join(f'{label}[{n}]' for n in names) or '(none)'}"
                      f"{suggest(variant, list(names))}; fix: name one of those, or the bare "
                      f"label {label!r} for all of them")


# ---- [requirements] -----------------------------------------------------------------------
def requirement_name_problems(names, labels) -> list[str]:
    """The problems of the detector names *names* of ``[requirements] detector_max_fa_rate``
    against the campaign's detector *labels*: each must be a label, or a label followed by
    a variant (``label[variant]``; which variants a detector has is known from its results,
    where :func:`reports.scoring.gate.evaluate_gate` checks them)."""
    known = ", ".join(labels) or "(none)"
    problems = []
    for name in names:
        base = name.split("[", 1)[0]
        if base in labels and (name == base or name.endswith("]")):
            continue
        problems.append(
            f"requirements.detector_max_fa_rate.{_quoted_key(name)}: names no detector of "
            f"this campaign{suggest(base, list(labels))}; its detectors ([[detector]] labels): "
            f"{known} (or one of their variants: LABEL[VARIANT]); fix: name one of "
            "them or remove the entry")
    return problems


def _quoted_key(name: str) -> str:
    """*name* as a key of a dotted TOML path (quoted unless bare)."""
    return name if re.fullmatch(r"[A-Za-z0-9_-]+", name) else f'"{name}"'


def _check_requirement_names(req: Mapping, dets: list, errors: list[str]) -> None:
    """Every detector named by ``detector_max_fa_rate`` is one of the campaign's
    [[detector]] labels (its variants included), found before anything runs."""
    limits = req["detector_max_fa_rate"]
    labels = [d["label"] for d in dets]
    if not limits or not is_ok(limits, *labels) or None in labels:
        return                  # nothing named, or the detectors have errors of their own
    errors.extend(requirement_name_problems([name for name, _ in limits], labels))


# ---- [plant] ------------------------------------------------------------------------------
def _check_plant(plant: Mapping, camp: Mapping, errors: list[str]) -> None:
    """The FMU keys mean nothing without an FMU (defaults written out are harmless); an FMU
    replaces the single actuator servo-loop, not the aircraft plant."""
    if plant["fmu"] is None:
        given = [k for k in ("push_parameters", "parameters") if k in plant["__present__"]
                 and plant[k] != PlantSection.__dataclass_fields__[k].default]
        given += [f"variables.{f.name}" for f in leaf_fields(PlantVariables)
                  if f.name in plant["variables"]["__present__"]
                  and plant["variables"][f.name] != f.default]
        for k in given:
            errors.append(f"plant.{k}: only used with an FMU plant; fix: set [plant] fmu = "
                          "\"servo.fmu\" or remove it")
    elif plant["kind"] in AIRCRAFT_KINDS:
        errors.append("plant.fmu: an FMU replaces the single actuator servo-loop, but "
                      f"[plant] kind = \"{plant['kind']}\"; fix: set [plant] kind = "
                      "\"actuator\" or remove [plant] fmu")
