"""The campaign file: presets, starting file, validation messages, canonical form."""

from __future__ import annotations

import ast
import copy
import dataclasses
import importlib
import json
import pickle
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from campaign import config as cfg
from campaign.config import (
    CampaignConfig,
    ConfigError,
    init_text,
    list_presets,
    load_config,
    preset_path,
    schema_markdown,
    with_overrides,
)
from campaign.config.keys import leaf_fields
from campaign.config.rules import check_rules, derive_group_names, normalise
from campaign.config.schema import check_tables, iter_tables
from detectors import registry
from detectors.tail import MIN_TAIL_FIT_RUNS
from scenarios.catalog import FAULTS, MANOEUVRES, REQUIRED_DETECTION_TIME_S

REPO = Path(__file__).resolve().parents[2]

STUB_MODULE = "fdd_config_test_detectors"
STUB_SOURCE = '''
from detectors.base import Capabilities, Detector


class StubDetector(Detector):
    capabilities = Capabilities(needs_fit=False)

    def __init__(self, threshold=1.0, mode="abs", checks=("loop",)):
        self.threshold = threshold
        self.mode = mode
        self.checks = checks

    def validate_params(self):
        if not (isinstance(self.threshold, (int, float)) and self.threshold > 0):
            raise ValueError(f"threshold must be a number > 0, got {self.threshold!r}")
        if self.mode not in ("abs", "rel"):
            raise ValueError(f"mode must be 'abs' or 'rel', got {self.mode!r}")


class PressureDetector(StubDetector):
    capabilities = Capabilities(needs_fit=False, needs_pressure_sensor=True)


class SurfaceDetector(StubDetector):
    capabilities = Capabilities(needs_fit=False, needs_surface_sensor=True)


class PositionMonitorStub(Detector):
    def __init__(self, residual="model", safety=1.5, confirm_s=0.05,
                 checks=("loop", "com_mon", "surface")):
        self.residual = residual
        self.safety = safety
        self.confirm_s = confirm_s
        self.checks = checks
'''


def _position_monitor_importable() -> bool:
    try:
        registry.load_detector_class("position-monitor")
    except registry.DetectorSpecError:
        return False
    return True


@pytest.fixture(autouse=True)
def stub_detectors(monkeypatch, tmp_path_factory):
    """Register small test detectors (and stand in for position-monitor if it cannot be
    imported) without touching the source tree."""
    folder = tmp_path_factory.getbasetemp() / "stub_detectors"
    folder.mkdir(exist_ok=True)
    (folder / f"{STUB_MODULE}.py").write_text(STUB_SOURCE)
    monkeypatch.syspath_prepend(str(folder))
    importlib.invalidate_caches()
    monkeypatch.setitem(registry.BUILTIN, "stub-detector", f"{STUB_MODULE}:StubDetector")
    monkeypatch.setitem(registry.BUILTIN, "pressure-detector",
                        f"{STUB_MODULE}:PressureDetector")
    monkeypatch.setitem(registry.BUILTIN, "surface-detector", f"{STUB_MODULE}:SurfaceDetector")
    if not _position_monitor_importable():
        monkeypatch.setitem(registry.BUILTIN, "position-monitor",
                            f"{STUB_MODULE}:PositionMonitorStub")


BASE = """\
[campaign]
name = "t"

[[group]]
fault = "none"
count = 2

[[detector]]
name = "stub-detector"
"""


def write(tmp_path: Path, text: str, name: str = "c.toml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def errors_of(tmp_path: Path, text: str) -> list[str]:
    with pytest.raises(ConfigError) as info:
        load_config(write(tmp_path, text))
    return info.value.errors


def runs_per_group(config: CampaignConfig) -> dict[str, int]:
    return {g.name: (g.count or 0) * len(g.manoeuvres) for g in config.groups}


# ---------------------------------------------------------------------------------------
# presets and the starting file
# ---------------------------------------------------------------------------------------
def test_presets_are_shipped_with_descriptions():
    presets = list_presets()
    assert set(presets) >= {"smoke", "addsafe-mc", "addsafe-grid"}
    for name, description in presets.items():
        assert len(description) > 20, name
        assert preset_path(name).is_file()


@pytest.mark.parametrize("name", sorted(list_presets()))
def test_every_preset_loads_and_round_trips(name):
    config = load_config(name)
    assert config.campaign.name == name
    assert CampaignConfig.from_dict(config.to_dict()) == config
    assert any(d.name == "position-monitor" for d in config.detectors)


def test_smoke_preset_counts():
    c = load_config("smoke")
    assert c.campaign.duration_s == 30.0 and c.campaign.surface == "elevator"
    runs = runs_per_group(c)
    fault_free = sum(n for g, n in runs.items() if c.groups[list(runs).index(g)].fault == "none")
    assert fault_free == 12
    per_fault = {g.fault: (g.count or 0) * len(g.manoeuvres) for g in c.groups}
    for fault in ("runaway", "liquid_jam", "solid_jam", "disconnection"):
        assert per_fault[fault] == 2
    assert {m for g in c.groups if g.fault != "none" for m in g.manoeuvres} == {"cruise",
                                                                                "nose_up"}
    assert c.learning.runs_per_manoeuvre == 3


def test_addsafe_mc_preset_counts():
    c = load_config("addsafe-mc")
    assert (c.campaign.design, c.campaign.sampler, c.campaign.duration_s) == ("mc", "sobol", 60.0)
    per_fault = {g.fault: (g.count or 0) * len(g.manoeuvres) for g in c.groups}
    assert per_fault == {"none": 1200, "liquid_jam": 333, "solid_jam": 333,
                         "disconnection": 334, "runaway": 200}
    assert all(g.manoeuvres == ("cruise",) for g in c.groups if g.fault != "none")
    # 50 per manoeuvre: the fewest for a per-manoeuvre tail fit (docs/thresholds.md)
    assert c.learning.runs_per_manoeuvre == 50 >= MIN_TAIL_FIT_RUNS


def test_addsafe_grid_preset():
    c = load_config("addsafe-grid")
    assert c.campaign.design == "grid" and c.campaign.realistic_only
    assert c.campaign.sampler is None
    assert all(g.count is None for g in c.groups)
    assert {g.fault for g in c.groups} == {"none", "runaway", "liquid_jam", "solid_jam",
                                           "disconnection"}
    fault_free = [g for g in c.groups if g.fault == "none"]
    assert fault_free[0].manoeuvres == MANOEUVRES


def test_init_text_loads_and_documents_every_key(tmp_path):
    text = init_text()
    config = load_config(write(tmp_path, text, "init.toml"))
    assert config.campaign.name == "my-campaign"
    for section, cls, _, _ in iter_tables():
        for f in leaf_fields(cls):
            assert f"{f.name} = " in text, (section, f.name)


# ---------------------------------------------------------------------------------------
# bad files: each error names its path and how to fix it
# ---------------------------------------------------------------------------------------
BAD_FILES = {
    "fmu on the aircraft plant": (
        BASE + '\n[plant]\nkind = "aircraft"\nfmu = "servo.fmu"\n',
        "plant.fmu: an FMU replaces the single actuator servo-loop",
        'fix: set [plant] kind = "actuator" or remove [plant] fmu'),
    "unknown section": (
        BASE + "\n[envelop]\nalt_ft = [10000]\n",
        "envelop: unknown section", "did you mean 'envelope'?"),
    "unknown key": (
        BASE.replace('name = "t"', 'name = "t"\nsede = 3'),
        "campaign.sede: unknown key", "did you mean 'seed'?"),
    "wrong type": (
        BASE.replace('name = "t"', 'name = "t"\nseed = "3"'),
        "campaign.seed: expected an integer", "fix: e.g. seed = 0"),
    "float where int": (
        BASE.replace("count = 2", "count = 2.5"),
        "group[0].count: expected an integer", "fix: e.g. count = 10"),
    "out of range": (
        BASE.replace('name = "t"', 'name = "t"\nduration_s = 5'),
        "campaign.duration_s: 5 is out of range", "allowed: 20 ≤ duration_s ≤ 600 s"),
    "envelope value out of range": (
        BASE + "\n[envelope]\nalt_ft = [8000, 50000]\n",
        "envelope.alt_ft[1]: 50000 is out of range", "allowed: 0 ≤ value ≤ 45000 ft"),
    "unknown surface": (
        BASE.replace('name = "t"', 'name = "t"\nsurface = "elevatr"'),
        "campaign.surface: unknown surface 'elevatr'",
        "(did you mean 'elevator'?); allowed: elevator, aileron"),
    "unknown manoeuvre": (
        BASE.replace("count = 2", 'count = 2\nmanoeuvres = ["cruse"]'),
        "group[0].manoeuvres[0]: unknown manoeuvre 'cruse'", "did you mean 'cruise'?"),
    "all mixed with names": (
        BASE.replace("count = 2", 'count = 2\nmanoeuvres = ["all", "cruise"]'),
        "group[0].manoeuvres: \"all\" cannot be combined", "fix:"),
    "unknown fault": (
        BASE.replace('fault = "none"', 'fault = "solid-jam"'),
        "group[0].fault: unknown fault 'solid-jam' (did you mean 'solid_jam'?)",
        "allowed: " + ", ".join(FAULTS)),
    "unknown detector": (
        BASE.replace('name = "stub-detector"', 'name = "stub-detectr"'),
        "detector[0].name: unknown detector 'stub-detectr'", "did you mean 'stub-detector'?"),
    "bad detector param value": (
        BASE + "params = { threshold = -1.0 }\n",
        "detector[0].params:", "threshold must be a number > 0"),
    "unknown detector param": (
        BASE + "params = { treshold = 1.0 }\n",
        "detector[0].params:", "did you mean 'threshold'?"),
    "low above high": (
        BASE + "\n[faults.runaway]\nrate_deg_s = [10.0, 1.0]\n",
        "faults.runaway.rate_deg_s: low 10 > high 1", "fix: write [low, high] with low ≤ high"),
    "pair is not a pair": (
        BASE + "\n[faults.ofc_solid]\nfreq_hz = 2.0\n",
        "faults.ofc_solid.freq_hz: expected [low, high]", "fix: e.g. freq_hz = [0.5, 5.0]"),
    "no time left to detect a disconnection": (
        BASE.replace('name = "t"', 'name = "t"\nduration_s = 20.0')
        + '\n[[group]]\nfault = "disconnection"\ncount = 2\n\n[faults]\nonset_min_s = 8.0\n',
        "group[1].fault: a disconnection needs its detection budget of 15 s after the onset",
        "fix: lengthen campaign.duration_s to at least 23 s"),
    "turbulence on the actuator plant": (
        BASE + '\n[plant]\nturbulence = "none"\n',
        "plant.turbulence: only used with kind = \"aircraft\"",
        'fix: remove it or set [plant] kind = "aircraft"'),
    "empty onset window": (
        BASE.replace('name = "t"', 'name = "t"\nduration_s = 20.0')
        + "\n[faults]\nonset_min_s = 15.0\n",
        "faults.onset_min_s: empty onset window [15, 10] s", "fix: lower onset_min_s"),
    "duplicate labels": (
        BASE + '\n[[detector]]\nname = "stub-detector"\n',
        "detector[1].label: duplicate label 'stub-detector' (also detector[0])",
        "fix: give each [[detector]] a unique label"),
    "duplicate group names": (
        BASE.replace("count = 2", 'count = 2\nname = "a"')
        + '\n[[group]]\nname = "a"\nfault = "runaway"\ncount = 1\n',
        "group[1].name: duplicate group name 'a'", "fix: give each group a unique name"),
    "TOML syntax error": (
        BASE.replace('name = "t"', 'name = "t"\nseed = = 3'),
        "line 3, column", "TOML syntax error"),
    "missing name": (
        BASE.replace('name = "t"\n', 'description = "no name"\n'),
        "campaign.name: missing required key", 'fix: add name = "my-campaign" to [campaign]'),
    "no groups": (
        '[campaign]\nname = "t"\n\n[[detector]]\nname = "stub-detector"\n',
        "group: no [[group]] table", "fix: add at least one"),
    "no detectors": (
        '[campaign]\nname = "t"\n\n[[group]]\nfault = "none"\ncount = 1\n',
        "detector: no [[detector]] table", 'name = "position-monitor"'),
    "single-bracket array": (
        BASE.replace("[[group]]", "[group]"),
        "group: expected an array of tables", "fix: write [[group]] (double brackets)"),
    "count with grid": (
        BASE.replace('name = "t"', 'name = "t"\ndesign = "grid"'),
        "group[0].count: only used with design = \"mc\"", "fix: remove it"),
    "sampler with grid": (
        BASE.replace('name = "t"', 'name = "t"\ndesign = "grid"\nsampler = "random"')
        .replace("count = 2\n", ""),
        "campaign.sampler: only used with design = \"mc\"", "fix: remove it"),
    "count missing with mc": (
        BASE.replace("count = 2\n", ""),
        "group[0].count: missing; required with design = \"mc\"", "fix: add count = 10"),
    "magnitude of a fault without one": (
        BASE + '\n[[group]]\nfault = "solid_jam"\ncount = 1\nmagnitude = 2.0\n',
        "group[1].magnitude: fault 'solid_jam' has no magnitude", "fix: remove it"),
    "magnitude out of its fault range": (
        BASE + '\n[[group]]\nfault = "runaway"\ncount = 1\nmagnitude = 500.0\n',
        "group[1].magnitude: 500 is out of range for runaway", "0 < magnitude ≤ 100 deg/s"),
    "onset after the end": (
        BASE + '\n[[group]]\nfault = "runaway"\ncount = 1\nonset_s = 75.0\n',
        "group[1].onset_s: 75 s is not before the end of the run", "onset_s < duration_s"),
    "onset on a fault-free group": (
        BASE.replace("count = 2", "count = 2\nonset_s = 10.0"),
        "group[0].onset_s: a fault-free group", "fix: remove it"),
    "unknown fault in requirements": (
        BASE + "\n[requirements]\ndetection_time_s = { runaway = 0.5, solidjam = 1.0 }\n",
        "requirements.detection_time_s.solidjam: unknown fault", "did you mean 'solid_jam'?"),
    "detector needs the pressure sensor": (
        BASE.replace('name = "stub-detector"', 'name = "pressure-detector"'),
        "detector[0].name: detector 'pressure-detector' needs the chamber pressure sensor",
        "fix: set pressure_sensor = true"),
    "detector needs a surface sensor the aileron lacks": (
        BASE.replace('name = "t"', 'name = "t"\nsurface = "aileron"')
        .replace('name = "stub-detector"', 'name = "surface-detector"'),
        "detector[0].name: detector 'surface-detector' needs a surface position sensor",
        "fix: choose another surface"),
    "repeated envelope value": (
        BASE + "\n[envelope]\nmass_t = [120, 180, 120]\n",
        "envelope.mass_t: value 120 is repeated", "fix: list each value once"),
    "section given as a value": (
        BASE.replace("[campaign]\n", 'runner = 3\n[campaign]\n'),
        "runner: expected a table [runner]", "fix: write [runner]"),
}


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_bad_file_names_the_path_and_the_fix(tmp_path, case):
    text, where, fix = BAD_FILES[case]
    errors = errors_of(tmp_path, text)
    matching = [e for e in errors if where in e]
    assert matching, f"{case}: no error contains {where!r}; got {errors}"
    assert any(fix in e for e in matching), f"{case}: no fix {fix!r} in {matching}"


def test_bad_file_cases_are_distinct_kinds():
    # the brief asks for at least ten different kinds of bad files
    assert len({where.split(":")[0] + where.split(":")[-1] for _, where, _ in
                BAD_FILES.values()}) >= 10


def test_the_good_base_file_loads(tmp_path):
    # every bad file above is BASE plus one mistake: BASE itself must be valid
    config = load_config(write(tmp_path, BASE))
    assert config.groups[0].name == "none@all"
    assert config.detectors[0].label == "stub-detector"


def test_several_errors_are_reported_at_once(tmp_path):
    text = """\
[campaign]
sede = 1
surface = "rudder"
duration_s = 1000

[envelope]
alt_ft = []

[faults.liquid_jam]
bias_pct_range = [2.0, 1.0]

[[group]]
fault = "solid-jam"
count = 0

[[detector]]
name = "stub-detectr"

[[detector]]
name = "stub-detector"
params = { threshold = 0 }
"""
    with pytest.raises(ConfigError) as info:
        load_config(write(tmp_path, text))
    err = info.value
    expected = ["campaign.sede:", "campaign.surface:", "campaign.duration_s:",
                "campaign.name:", "envelope.alt_ft:", "faults.liquid_jam.bias_pct_range:",
                "group[0].fault:", "group[0].count:", "detector[0].name:",
                "detector[1].params:"]
    for path in expected:
        assert any(e.startswith(path) for e in err.errors), (path, err.errors)
    assert len(err.errors) == len(expected)
    text_all = str(err)
    assert f"{len(expected)} problems" in text_all
    assert all(e in text_all for e in err.errors)
    assert str(tmp_path / "c.toml") in text_all


def test_unknown_preset_and_missing_file_list_the_presets(tmp_path):
    with pytest.raises(ConfigError) as info:
        load_config("smoek")
    assert "did you mean 'smoke'?" in str(info.value)
    assert "addsafe-mc" in str(info.value)
    with pytest.raises(ConfigError) as info:
        load_config(tmp_path / "nope.toml")
    assert "file not found" in str(info.value) and "smoke" in str(info.value)


def test_config_error_survives_pickling():
    err = ConfigError(["a.b: problem; fix: this", "c: other"], "file.toml")
    back = pickle.loads(pickle.dumps(err))
    assert isinstance(back, ConfigError) and isinstance(back, ValueError)
    assert back.errors == err.errors and back.source == "file.toml"
    assert str(back) == str(err)


# ---------------------------------------------------------------------------------------
# canonical form, freezing, overrides
# ---------------------------------------------------------------------------------------
def test_to_json_is_canonical_and_stable(tmp_path):
    a = BASE + """
[envelope]
mass_t = [233, 120, 180]

[learning]
manoeuvres = ["all"]
"""
    # same campaign, written differently: key order, ints for floats, explicit defaults
    b = """\
[learning]
manoeuvres = ["turn_coordination", "cruise", "nose_up", "aoa_protection",
              "pitch_protection", "yaw_angle_mode"]

[[detector]]
label = "stub-detector"
name = "stub-detector"

[envelope]
mass_t = [120.0, 180.0, 233.0]

[[group]]
count = 2
manoeuvres = ["all"]
fault = "none"

[campaign]
seed = 0
name = "t"
duration_s = 60
"""
    ca = load_config(write(tmp_path, a, "a.toml"))
    cb = load_config(write(tmp_path, b, "b.toml"))
    assert ca == cb and hash(ca) == hash(cb)
    assert ca.to_json() == cb.to_json()
    js = ca.to_json()
    assert js == json.dumps(json.loads(js), sort_keys=True, separators=(",", ":"),
                            ensure_ascii=False)
    assert '"duration_s":60.0' in js and '"mass_t":[120.0,180.0,233.0]' in js
    # stable: loading again, and rebuilding from the JSON, give the same string
    assert load_config(write(tmp_path, a, "a2.toml")).to_json() == js
    assert CampaignConfig.from_dict(json.loads(js)).to_json() == js
    # sensitive: any change of a value changes it
    assert with_overrides(ca, seed=1).to_json() != js
    # to_dict is in schema order
    assert list(ca.to_dict()) == ["campaign", "envelope", "uncertainty", "mismatch",
                                  "faults", "group", "detector", "requirements",
                                  "learning", "manoeuvres", "runner", "plant"]


def _walk(value):
    yield value
    if dataclasses.is_dataclass(value):
        for f in dataclasses.fields(value):
            yield from _walk(getattr(value, f.name))
    elif isinstance(value, tuple):
        for v in value:
            yield from _walk(v)


@pytest.mark.parametrize("name", sorted(list_presets()))
def test_config_is_frozen_and_holds_no_mutable_containers(name):
    config = load_config(name)
    with pytest.raises(dataclasses.FrozenInstanceError):
        config.campaign.seed = 3
    assert not any(isinstance(v, (list, dict, set)) for v in _walk(config))
    hash(config)


def test_detector_params_are_frozen_and_thawed(tmp_path):
    text = BASE + 'params = { threshold = 2, checks = ["loop", "surface"], mode = "rel" }\n'
    det = load_config(write(tmp_path, text)).detectors[0]
    assert det.params == (("checks", ("loop", "surface")), ("mode", "rel"), ("threshold", 2))
    assert det.params_dict() == {"checks": ["loop", "surface"], "mode": "rel", "threshold": 2}
    assert registry.make_detector(det.name, det.params_dict()).threshold == 2


def test_defaults_are_filled_in(tmp_path):
    c = load_config(write(tmp_path, BASE))
    assert c.envelope.alt_ft == (8000.0, 18000.0, 28000.0, 38000.0)
    assert (c.uncertainty.aero, c.uncertainty.vcas, c.mismatch.hinge) == (0.05, 0.10, 0.20)
    assert c.faults.liquid_jam.bias_pct_range == (1.3, 1.3)
    assert dict(c.requirements.detection_time_s) == REQUIRED_DETECTION_TIME_S
    assert c.requirements.detection_window_s is None and c.learning.duration_s is None
    assert c.runner.chunk_size == 100 and c.campaign.sampler == "sobol"


def test_partial_detection_times_replace_only_the_given_faults(tmp_path):
    c = load_config(write(tmp_path, BASE + "\n[requirements]\ndetection_time_s = "
                                           "{ runaway = 0.8 }\n"))
    assert c.requirements.required_time("runaway") == 0.8
    assert c.requirements.required_time("solid_jam") == REQUIRED_DETECTION_TIME_S["solid_jam"]


def test_derived_group_names_are_unique(tmp_path):
    text = BASE + ('\n[[group]]\nfault = "runaway"\nmanoeuvres = ["cruise"]\ncount = 1\n' * 2)
    names = [g.name for g in load_config(write(tmp_path, text)).groups]
    assert names == ["none@all", "runaway@cruise", "runaway@cruise#2"]


def test_with_overrides_validates_and_leaves_the_original(tmp_path):
    c = load_config(write(tmp_path, BASE))
    d = with_overrides(c, seed=42, chunk_size=7, values={"group[0].count": 5})
    assert (d.campaign.seed, d.runner.chunk_size, d.groups[0].count) == (42, 7, 5)
    assert (c.campaign.seed, c.runner.chunk_size, c.groups[0].count) == (0, 100, 2)
    with pytest.raises(ConfigError) as info:
        with_overrides(c, seed=-1)
    assert info.value.errors[0].startswith("campaign.seed: -1 is out of range")


# ---------------------------------------------------------------------------------------
# generated reference
# ---------------------------------------------------------------------------------------
def test_docs_reference_is_up_to_date():
    doc = (REPO / "docs" / "campaign-file.md").read_text(encoding="utf-8")
    assert doc == schema_markdown(), (
        "docs/campaign-file.md is out of date; regenerate it with "
        "`python -m campaign.config --markdown > docs/campaign-file.md`")


def test_reference_documents_every_section_and_key():
    md = schema_markdown()
    for section, cls, _, array in iter_tables():
        assert (f"[[{section}]]" if array else f"[{section}]") in md
        for f in leaf_fields(cls):
            assert f"| `{f.name}` |" in md


def test_module_entry_prints_the_reference(capsys):
    assert cfg.main(["--markdown"]) == 0
    assert capsys.readouterr().out == schema_markdown()
    assert cfg.main(["--init"]) == 0
    assert tomllib.loads(capsys.readouterr().out)["campaign"]["name"] == "my-campaign"
    assert cfg.main(["--check", "nonexistent-preset"]) == 2


# ---------------------------------------------------------------------------------------
# rules: the values they derive are explicit steps, the rules only report
# ---------------------------------------------------------------------------------------
GRID_WITH_MC_KEYS = """\
[campaign]
name = "t"
design = "grid"
sampler = "random"

[[group]]
fault = "runaway"
manoeuvres = ["cruise"]
count = 3

[[group]]
fault = "none"
name = "runaway@cruise"

[[group]]
fault = "runaway"
manoeuvres = ["cruise"]

[[detector]]
name = "stub-detector"
"""


def test_rules_report_without_changing_the_values():
    errors: list[str] = []
    values = check_tables(tomllib.loads(GRID_WITH_MC_KEYS), errors)
    assert errors == []
    checked = copy.deepcopy(values)

    normalised = normalise(values)
    assert values == checked                                 # a new dict, input untouched
    assert values["campaign"]["sampler"] == "random" and values["groups"][0]["count"] == 3
    assert normalised["campaign"]["sampler"] is None         # mc-only keys on a grid design
    assert [g["count"] for g in normalised["groups"]] == [None, None, None]
    assert normalised["detectors"][0]["label"] == "stub-detector"   # label = name

    before_rules = copy.deepcopy(normalised)
    check_rules(normalised, errors)
    assert normalised == before_rules
    assert errors == [
        'campaign.sampler: only used with design = "mc"; fix: remove it (grid runs one run '
        'per case)',
        'group[0].count: only used with design = "mc"; fix: remove it (grid runs one run '
        'per case)',
    ]

    named = derive_group_names(normalised)
    assert normalised == before_rules
    assert [g["name"] for g in normalised["groups"]] == [None, "runaway@cruise", None]
    # derived names never take a name given in the file, nor each other's
    assert [g["name"] for g in named["groups"]] == ["runaway@cruise#2", "runaway@cruise",
                                                    "runaway@cruise#3"]


def test_config_layers_import_only_the_layers_below():
    """Each module of campaign.config imports only modules listed before it in the
    package docstring (no import cycle inside the package)."""
    order = ["keys", "text", "convert", "sections", "rules", "schema", "load", "docs"]
    folder = REPO / "campaign" / "config"
    assert sorted(p.stem for p in folder.glob("*.py")) == sorted(
        order + ["__init__", "__main__"])
    for i, name in enumerate(order):
        tree = ast.parse((folder / f"{name}.py").read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.level == 1:
                assert node.module in order[:i], (name, node.module)
            elif isinstance(node, ast.ImportFrom) and node.module:
                assert not node.module.startswith("campaign"), (name, node.module)
            elif isinstance(node, ast.Import):
                assert not any(a.name.startswith("campaign") for a in node.names), name


def test_loading_a_suite_name_as_a_campaign_does_not_import_the_suites():
    """campaign.suite builds on campaign.config, never the reverse."""
    code = ("import sys\n"
            "from campaign.config import ConfigError, load_config\n"
            "try:\n"
            "    load_config('chen-tables')\n"
            "except ConfigError as exc:\n"
            "    assert 'a suite of campaigns' in str(exc), exc\n"
            "else:\n"
            "    raise SystemExit('no error')\n"
            "print('campaign.suite' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=REPO, check=True)
    assert out.stdout.strip() == "False"


def test_init_text_lists_every_builtin_detector_parameter_from_its_declaration():
    """``fdd-campaign init`` shows each built-in detector's parameters and defaults from the
    one declaration the validator uses (detectors.params)."""
    from detectors.params import parameter_table
    from detectors.registry import BUILTIN, load_detector_class

    text = init_text()
    block = text[text.index("# Parameters of the built-in detectors"):]
    block = block[:block.index("\n\n")]
    for name in BUILTIN:
        assert f"#   {name}:" in block
        for row in parameter_table(load_detector_class(name)):
            assert f"#     {row['name']}" in block, (name, row["name"])
    assert "(built-in: position-monitor, comb-interval, chen-local, chen-global, " \
           "chen-global-paper, " \
           "vanek-geometric;" in " ".join(line.lstrip("# ") for line in text.splitlines())


# ---------------------------------------------------------------------------------------
# solid_jam variants (docs/physics.md §5)
# ---------------------------------------------------------------------------------------
SOLID = BASE + """
[[group]]
fault = "solid_jam"
manoeuvres = ["cruise"]
count = 4
"""


def test_solid_jam_variant_offset_samples_signed_offsets_and_names_the_group(tmp_path):
    from campaign.plan import build_plan
    from scenarios.faults import solid_jam_offset_mm
    from scenarios.params import AILERON

    aileron = SOLID.replace('name = "t"', 'name = "t"\nsurface = "aileron"')
    seized = load_config(write(tmp_path, aileron, "a.toml"))
    offset = load_config(write(tmp_path, aileron.replace(
        'fault = "solid_jam"', 'fault = "solid_jam"\nvariant = "offset"'), "b.toml"))
    assert seized.groups[1].name == "solid_jam@cruise" and seized.groups[1].variant is None
    assert offset.groups[1].name == "solid_jam[offset]@cruise"
    p_seized, p_offset = build_plan(seized), build_plan(offset)
    jam_s = p_seized[p_seized["fault"] == "solid_jam"]
    jam_o = p_offset[p_offset["fault"] == "solid_jam"]
    assert jam_s["magnitude"].isna().all()                   # seized: no magnitude
    mm = solid_jam_offset_mm(AILERON, 1.8)                   # [CHEN] §6.2 default
    np.testing.assert_allclose(np.abs(jam_o["magnitude"]), mm, rtol=1e-12)
    assert set(np.sign(jam_o["magnitude"])) == {-1.0, 1.0}   # sign drawn per run
    # the variants never share run ids (resume cannot mix them)
    assert not set(jam_s["run_id"]) & set(jam_o["run_id"])
    # the fault-free group is untouched by the variant of another group
    free = ["run_id", "alt_ft", "vcas_kt", "seed", "stream"]
    assert p_seized[p_seized["fault"] == "none"][free].equals(
        p_offset[p_offset["fault"] == "none"][free])


def test_solid_jam_offset_fixed_magnitude_in_percent_and_sign(tmp_path):
    from campaign.plan import build_plan
    from scenarios.faults import solid_jam_offset_mm
    from scenarios.params import AILERON

    text = SOLID.replace('name = "t"', 'name = "t"\nsurface = "aileron"').replace(
        'fault = "solid_jam"',
        'fault = "solid_jam"\nvariant = "offset"\nmagnitude = 3.0\nsign = "negative"')
    plan = build_plan(load_config(write(tmp_path, text)))
    jam = plan[plan["fault"] == "solid_jam"]
    np.testing.assert_allclose(jam["magnitude"], -solid_jam_offset_mm(AILERON, 3.0), rtol=1e-12)


@pytest.mark.parametrize("extra, fault, message", [
    ('magnitude = 1.8', "solid_jam",
     'group[1].magnitude: fault \'solid_jam\' has no magnitude with variant = "seized" (the '
     'default); fix: remove it, or set variant = "offset"'),
    ('variant = "seized"\nsign = "negative"', "solid_jam",
     'group[1].sign: fault \'solid_jam\' has no direction with variant = "seized"; fix: '
     'remove it'),
    ('variant = "offset"', "liquid_jam",
     "group[1].variant: fault 'liquid_jam' has no variants; allowed only with: solid_jam"),
    ('variant = "stuck"', "solid_jam", "group[1].variant: unknown"),
    ('variant = "offset"\nmagnitude = 80.0', "solid_jam", "group[1].magnitude: 80 is out of range"),
])
def test_solid_jam_variant_errors(tmp_path, extra, fault, message):
    text = SOLID.replace('fault = "solid_jam"', f'fault = "{fault}"\n{extra}')
    errors = errors_of(tmp_path, text)
    assert any(message in e for e in errors), errors


def test_variant_on_a_fault_free_group_is_refused(tmp_path):
    errors = errors_of(tmp_path, BASE.replace('fault = "none"',
                                              'fault = "none"\nvariant = "offset"'))
    assert any("group[0].variant: a fault-free group" in e for e in errors), errors


def test_chen_table_presets_use_the_offset_variant():
    for name in ("chen-mc", "chen-sweep", "chen-local"):
        groups = {g.fault: g for g in load_config(name).groups}
        assert groups["solid_jam"].variant == "offset"
    for name in ("addsafe-mc", "addsafe-grid", "smoke"):
        assert all(g.variant is None for g in load_config(name).groups)


@pytest.mark.parametrize("preset", [p for p in cfg.list_presets() if p.startswith("chen-")])
def test_chen_presets_fly_chens_solid_jam_and_allow_no_false_alarm(preset):
    """The presets that reproduce [CHEN] fly its solid jam (eq. 4: the measurement stuck
    1.8 % of the range away, variant "offset", docs/physics.md §5), and their gate holds
    every detector to zero false alarms: chen-local[solid] needs no allowance since it
    decides on f̂'s step from its reference mean (docs/chen-estimator.md §3–4)."""
    config = cfg.load_config(preset)
    solid = [g for g in config.groups if g.fault == "solid_jam"]
    assert solid and all(g.variant == "offset" for g in solid)
    assert dict(config.requirements.detector_max_fa_rate) == {}
    assert config.requirements.max_fa_rate == 0.0
