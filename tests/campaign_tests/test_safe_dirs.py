"""Campaign directories are safe to share and tamper-evident: fitted detectors are stored as
data and never unpickled, a SHA-256 manifest is checked by every reader, one run at a time
writes into a directory, and files follow the user's umask (docs/security.md)."""

from __future__ import annotations

import hashlib
import json
import os
import pickle
import signal
import socket
import stat
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from campaign.plant_setup import resolve
from campaign.cli.commands import main
from campaign.config import CampaignConfig, load_config
from campaign.plan import build_plan
from campaign.evaluate import simulate_and_detect
from campaign.runner import fit_detectors, settings_of
from campaign.store.directory import (
    LOCK_NAME,
    MANIFEST_NAME,
    CampaignDir,
    CampaignLockedError,
    DirLock,
    write_parquet,
)
from detectors import registry
from detectors.base import Capabilities, Detection, Detector
from detectors.registry import BUILTIN
from detectors.state import (
    StateFormatError,
    StateTypeError,
    decode,
    encode,
    register_state_type,
)

TESTS = Path(__file__).resolve().parents[1]


# ---- the plain-data codec ----------------------------------------------------------------------
@register_state_type
@dataclass(frozen=True)
class _Design:
    """A frozen dataclass registered as plain data."""

    gain: np.ndarray
    poles: tuple
    name: str


@dataclass(frozen=True)
class _Unregistered:
    x: float


def _round_trip(values: dict) -> dict:
    doc, arrays = encode(values)
    text = json.dumps(doc, allow_nan=False)
    return decode(json.loads(text), {k: np.array(v) for k, v in arrays.items()})


def _same(a, b) -> bool:
    """Equal to the bit and of the same types, recursively."""
    if type(a) is not type(b):
        return False
    if isinstance(a, np.ndarray):
        return (a.dtype == b.dtype and a.shape == b.shape
                and a.tobytes() == b.tobytes())
    if isinstance(a, np.generic):
        return a.dtype == b.dtype and a.tobytes() == b.tobytes()
    if isinstance(a, float):
        return np.float64(a).tobytes() == np.float64(b).tobytes()
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, dict):
        return list(a) == list(b) and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, _Design):
        return all(_same(getattr(a, f), getattr(b, f)) for f in ("gain", "poles", "name"))
    return a == b


def test_every_supported_type_round_trips_to_the_bit():
    values = {
        "none_": None, "flag_": True, "count_": 3, "big_": 2 ** 70, "x_": 0.1 + 0.2,
        "negzero_": -0.0, "nan_": float("nan"), "inf_": float("-inf"), "z_": 1.5 - 2.0j,
        "name_": "loop", "tuple_": (1.0, "a", (2, 3)), "list_": [1, [2.5, None]],
        "f8_": np.linspace(0.0, 1.0, 7), "be_": np.arange(4, dtype=">i4").reshape(2, 2),
        "bool_": np.array([True, False]), "f32_": np.float32(1.1), "i64_": np.int64(-5),
        "u_": np.array(["a", "bc"]), "fortran_": np.asfortranarray(np.ones((2, 3))),
        "empty_": np.zeros((0, 3)), "scalar0d_": np.array(2.5),
        "dict_": {"a=0.6": np.ones(3), "b": {"c": 1.0}},
        "keys_": {("geometric", 0.01): 1.0, 3: "x", None: 2, "$odd": 4},
        "design_": _Design(gain=np.eye(2), poles=(0.5, 0.9), name="lti"),
    }
    back = _round_trip(values)
    assert list(back) == list(values)
    for k in values:
        assert _same(values[k], back[k]), k
    assert back["fortran_"].flags.f_contiguous


@pytest.mark.parametrize("value, where, what", [
    ({1, 2}, "thresholds_", "builtins:set"),
    ({"a": [1, {2}]}, "thresholds_['a'][1]", "builtins:set"),
    (np.array([object()], dtype=object), "thresholds_", "dtype object"),
    (_Unregistered(1.0), "thresholds_", "is not registered as plain data"),
    (lambda x: x, "thresholds_", "function"),
    ({frozenset(): 1}, "thresholds_", "dict key of type frozenset"),
])
def test_anything_else_is_refused_naming_where_it_is(value, where, what):
    with pytest.raises(StateTypeError, match="(not|as) plain data") as info:
        encode({"thresholds_": value})
    assert info.value.path == where and what in str(info.value)


def test_decoding_never_builds_a_class_the_file_names():
    doc, arrays = encode({"d_": _Design(gain=np.eye(1), poles=(), name="x")})
    doc["d_"]["$dataclass"] = "os:_wrap_close"
    with pytest.raises(StateFormatError, match="'os:_wrap_close' is not registered"):
        decode(doc, arrays)
    with pytest.raises(StateFormatError, match="unknown tag"):
        decode({"x_": {"$pickle": "gASV"}}, {})
    with pytest.raises(StateFormatError, match="not in the stored arrays"):
        decode({"x_": {"$ndarray": "a9", "dtype": "<f8", "shape": [1]}}, {})


# ---- every built-in detector read back from its directory detects bit-identically ---------------
def _small(preset: str) -> CampaignConfig:
    """*preset* shrunk to two runs of 20 s and one learning run per manoeuvre (three)."""
    d = load_config(preset).to_dict()
    d["campaign"]["duration_s"] = 20.0
    groups = []
    for g in d["group"][:2]:
        g = {k: v for k, v in g.items() if k != "manoeuvre_start_s"}
        g["count"] = 1
        if g.get("onset_s") is not None:
            g["onset_s"] = 8.0
        groups.append(g)
    d["group"] = groups
    d["learning"] = {"runs_per_manoeuvre": 1, "manoeuvres": d["learning"]["manoeuvres"][:3]}
    return CampaignConfig.from_dict(d)


#: Presets whose detectors, together, are every built-in one.
PRESETS = ("comb-table1", "chen-mc", "vanek-isolation")


def test_the_presets_below_cover_every_builtin_detector():
    names = {d.name for p in PRESETS for d in load_config(p).detectors}
    assert names == set(BUILTIN)


@pytest.mark.slow
@pytest.mark.parametrize("preset", PRESETS)
def test_fitted_detectors_read_back_from_the_directory_detect_bit_identically(preset,
                                                                              tmp_path):
    config = _small(preset)
    campaign = resolve(config)
    settings = settings_of(campaign)
    cdir = CampaignDir(tmp_path / "c")
    cdir.open(config.to_json())
    fitted = fit_detectors(campaign, cdir, settings, 50, log=lambda m: None)
    assert not list(cdir.fitted.glob("*.pkl"))
    rebuilt = {d.label: cdir.read_fitted(d.label, d.name) for d in config.detectors}
    for label, det in rebuilt.items():
        assert type(det) is type(fitted[label])
        assert det.get_params() == fitted[label].get_params()
        assert det.fitted_state().keys() == fitted[label].fitted_state().keys()
    plan = build_plan(config)
    _, _, direct = simulate_and_detect(plan, fitted, settings)
    _, _, again = simulate_and_detect(plan, rebuilt, settings)
    assert set(direct) == set(again) and direct
    for name in direct:
        for field in ("alarm", "residual"):
            a, b = getattr(direct[name], field), getattr(again[name], field)
            assert a.dtype == b.dtype and a.tobytes() == b.tobytes(), (name, field)


class OpaqueState(Detector):
    """Learns a value that is not plain data (a set)."""

    capabilities = Capabilities(needs_fit=True)

    def __init__(self, safety=1.0):
        self.safety = safety

    def _fit(self, signals):
        self.seen_manoeuvres_ = {"cruise"}

    def _detect(self, signals):
        shape = (signals.n_runs, signals.n_steps)
        return Detection(alarm=np.zeros(shape, dtype=bool), residual=np.zeros(shape))


def test_learned_state_that_is_not_plain_data_stops_the_campaign_at_fit_time(
        tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(registry.BUILTIN, "opaque", f"{__name__}:OpaqueState")
    cfg = tmp_path / "c.toml"
    cfg.write_text('[campaign]\nname = "opaque"\nseed = 1\nduration_s = 20.0\n'
                   '[[group]]\nfault = "none"\nmanoeuvres = ["cruise"]\ncount = 1\n'
                   '[[detector]]\nname = "opaque"\n'
                   '[learning]\nruns_per_manoeuvre = 1\nmanoeuvres = ["cruise"]\n')
    assert main(["run", str(cfg), "--out", str(tmp_path / "o"), "--quiet", "--jobs", "1"]) == 2
    err = capsys.readouterr().err
    assert ("detector 'opaque' (opaque): its learned attribute seen_manoeuvres_ cannot be "
            "stored") in err
    assert "builtins:set" in err and "Traceback" not in err
    assert not list((tmp_path / "o" / "runs").glob("*.parquet"))


# ---- a finished campaign, its copies and what readers make of them -------------------------------
@pytest.fixture(scope="module")
def smoke_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("safe") / "smoke"
    assert main(["run", "smoke", "--out", str(out), "--quiet", "--jobs", "1"]) == 0
    return out


def test_a_fitted_detector_reads_back_in_a_process_that_never_imported_it(smoke_dir):
    """The position monitor's learned calibrations are registered dataclasses, known once
    its module is imported: reading the directory from a fresh process (a script, a
    notebook) imports it first, instead of calling the directory damaged."""
    code = ("import sys; from campaign.store.directory import CampaignDir\n"
            "assert 'detectors.builtin.position_monitor' not in sys.modules\n"
            "det = CampaignDir(sys.argv[1]).read_fitted('position-monitor', 'position-monitor')\n"
            "print(type(det.calibration_['loop']).__name__, det.thresholds_mm_['loop'])")
    done = subprocess.run([sys.executable, "-c", code, str(smoke_dir)], capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    threshold = CampaignDir(smoke_dir).read_fitted("position-monitor").thresholds_mm_["loop"]
    assert done.stdout.split() == ["Calibration", repr(threshold)]


def _copy(src: Path, dst: Path) -> Path:
    import shutil

    shutil.copytree(src, dst)
    return dst


def _flip_one_false_alarm(shard: Path) -> None:
    """Rewrite *shard* with one ``false_alarm`` value flipped, metadata kept (a hand edit)."""
    table = pq.read_table(shard)
    df = table.to_pandas()
    df.loc[0, "false_alarm"] = not bool(df.loc[0, "false_alarm"])
    pq.write_table(pa.Table.from_pandas(df, preserve_index=False)
                   .replace_schema_metadata(table.schema.metadata), shard)


def _resign(directory: Path) -> None:
    """Rewrite the manifest so that it matches the files (what a forger would do)."""
    cdir = CampaignDir(directory)
    manifest = cdir.read_manifest()
    manifest["files"] = {}
    for rel in cdir._owned_files():
        data = (directory / rel).read_bytes()
        manifest["files"][rel] = {"sha256": hashlib.sha256(data).hexdigest(),
                                  "bytes": len(data)}
    (directory / MANIFEST_NAME).write_text(json.dumps(manifest))


def test_a_finished_campaign_verifies(smoke_dir, capsys):
    assert main(["verify", str(smoke_dir)]) == 0
    out = capsys.readouterr().out
    assert "files match the manifest (campaign 'smoke'" in out
    manifest = json.loads((smoke_dir / MANIFEST_NAME).read_text())
    assert "runs/part-000000.parquet" in manifest["files"]
    assert "fitted/position-monitor.json" in manifest["files"]
    assert manifest["campaign"]["name"] == "smoke" and manifest["engine_versions"]
    assert not (smoke_dir / LOCK_NAME).exists()


@pytest.mark.parametrize("command", ["gate", "verify", "report", "compare"])
def test_a_flipped_false_alarm_in_a_shard_is_refused_naming_the_shard(smoke_dir, tmp_path,
                                                                      capsys, command):
    copy = _copy(smoke_dir, tmp_path / "edited")
    _flip_one_false_alarm(copy / "runs" / "part-000000.parquet")
    args = {"gate": ["gate", str(copy)], "verify": ["verify", str(copy)],
            "report": ["report", str(copy), "--no-html"],
            "compare": ["compare", str(smoke_dir), str(copy)]}[command]
    assert main(args) == 2
    cap = capsys.readouterr()
    assert ("runs/part-000000.parquet does not match the manifest" in cap.out + cap.err)
    assert "Traceback" not in cap.err


@pytest.mark.parametrize("command", ["gate", "verify"])
def test_a_deleted_shard_is_refused_naming_it(smoke_dir, tmp_path, capsys, command):
    copy = _copy(smoke_dir, tmp_path / "deleted")
    (copy / "runs" / "part-000000.parquet").unlink()
    assert main([command, str(copy)]) == 2
    cap = capsys.readouterr()
    assert "runs/part-000000.parquet is in the manifest but missing" in cap.out + cap.err


def test_an_extra_shard_is_refused_naming_it(smoke_dir, tmp_path, capsys):
    copy = _copy(smoke_dir, tmp_path / "extra")
    (copy / "runs" / "part-000001.parquet").write_bytes(
        (copy / "runs" / "part-000000.parquet").read_bytes())
    assert main(["gate", str(copy)]) == 2
    assert "runs/part-000001.parquet is not in the manifest" in capsys.readouterr().err
    assert main(["run", "smoke", "--out", str(copy), "--quiet", "--jobs", "1"]) == 0
    # resuming: a file the manifest does not hold is a leftover of a crash, removed
    assert not (copy / "runs" / "part-000001.parquet").exists()
    assert main(["verify", str(copy)]) == 0


def test_resume_refuses_a_directory_whose_results_were_changed(smoke_dir, tmp_path, capsys):
    copy = _copy(smoke_dir, tmp_path / "edited")
    _flip_one_false_alarm(copy / "runs" / "part-000000.parquet")
    assert main(["run", "smoke", "--out", str(copy), "--quiet", "--jobs", "1"]) == 2
    assert ("runs/part-000000.parquet does not match the manifest"
            in capsys.readouterr().err)


def test_resume_refuses_a_truncated_shard_as_a_damaged_directory(smoke_dir, tmp_path, capsys):
    # the run counts the runs already done before it opens the directory: an unreadable
    # shard is the directory's damage (exit 2, naming the shard and the check), not a fault
    # of the engine (exit 3)
    copy = _copy(smoke_dir, tmp_path / "truncated")
    shard = copy / "runs" / "part-000000.parquet"
    shard.write_bytes(shard.read_bytes()[:100])
    assert main(["run", "smoke", "--out", str(copy), "--quiet", "--jobs", "1"]) == 2
    err = capsys.readouterr().err
    assert f"{shard}: not a readable result shard" in err
    assert f"'fdd-campaign verify {copy}'" in err and "internal error" not in err


def test_a_directory_without_manifest_is_refused_by_readers(smoke_dir, tmp_path, capsys):
    copy = _copy(smoke_dir, tmp_path / "old")
    (copy / MANIFEST_NAME).unlink()
    assert main(["gate", str(copy)]) == 2
    assert "has no manifest.json, so its files cannot be checked" in capsys.readouterr().err


PAYLOAD = "touch {marker}"


class _Evil:
    """A pickle that runs a shell command when loaded."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (os.system, (PAYLOAD.format(marker=self.marker),))


@pytest.mark.parametrize("resigned", [False, True])
def test_a_planted_pickle_is_never_loaded(smoke_dir, tmp_path, capsys, resigned):
    copy = _copy(smoke_dir, tmp_path / "planted")
    marker = tmp_path / "PWNED"
    (copy / "fitted" / "position-monitor.pkl").write_bytes(pickle.dumps(_Evil(marker)))
    if resigned:                       # even with a manifest forged to include it
        _resign(copy)
    run_id = pd.read_parquet(copy / "plan.parquet")["run_id"].iloc[0]
    for args in (["report", str(copy), "--jobs", "1"], ["show", str(copy), run_id],
                 ["gate", str(copy)], ["compare", str(copy), str(smoke_dir)],
                 ["run", "smoke", "--out", str(copy), "--quiet", "--jobs", "1"]):
        assert main(args) == 2, args
        err = capsys.readouterr().err
        assert ("position-monitor.pkl" in err), (args, err)
    assert not marker.exists()


def test_an_older_directory_with_pickles_says_how_to_go_on(smoke_dir, tmp_path, capsys):
    copy = _copy(smoke_dir, tmp_path / "old")
    (copy / MANIFEST_NAME).unlink()
    for p in (copy / "fitted").iterdir():
        p.unlink()
    (copy / "fitted" / "position-monitor.pkl").write_bytes(pickle.dumps({"threshold": 1.0}))
    assert main(["run", "smoke", "--out", str(copy), "--quiet", "--jobs", "1"]) == 2
    err = capsys.readouterr().err
    assert "is a pickled detector, written by an older fdd-campaign" in err
    assert f"delete {copy / 'fitted'} and rerun" in err
    for p in (copy / "fitted").iterdir():      # as the message says
        p.unlink()
    assert main(["run", "smoke", "--out", str(copy), "--quiet", "--jobs", "1"]) == 0
    assert "has no manifest.json (written by an older fdd-campaign)" in capsys.readouterr().err
    assert main(["verify", str(copy)]) == 0
    rows = pd.read_parquet(copy / "summary.parquet")
    pd.testing.assert_frame_equal(rows, pd.read_parquet(smoke_dir / "summary.parquet"))


# ---- the manifest during a run -------------------------------------------------------------------
def test_the_manifest_never_claims_a_file_that_is_not_there(tmp_path, monkeypatch):
    """At every manifest update during a run, each file it names is there with the recorded
    digest, and no file is written while the manifest names it."""
    import campaign.store.directory as storage

    checks = {"manifests": 0, "writes": 0}
    original_write = CampaignDir._write_manifest

    def write_and_check(self):
        original_write(self)
        on_disk = json.loads(self.manifest_path.read_text())
        for rel, entry in on_disk["files"].items():
            data = (self.root / rel).read_bytes()
            assert hashlib.sha256(data).hexdigest() == entry["sha256"], rel
        checks["manifests"] += 1

    original_parquet = storage.write_parquet

    def parquet_and_check(df, path, config_json, **extra):
        manifest = Path(path).parent / MANIFEST_NAME
        if Path(path).parent.name == "runs":
            manifest = Path(path).parent.parent / MANIFEST_NAME
        if manifest.exists():
            rel = Path(path).relative_to(manifest.parent).as_posix()
            assert rel not in json.loads(manifest.read_text())["files"], rel
            checks["writes"] += 1
        original_parquet(df, path, config_json, **extra)

    monkeypatch.setattr(CampaignDir, "_write_manifest", write_and_check)
    monkeypatch.setattr(storage, "write_parquet", parquet_and_check)
    out = tmp_path / "o"
    for _ in range(2):                      # a run and a resume (summary rewritten)
        assert main(["run", "smoke", "--out", str(out), "--quiet", "--jobs", "1",
                     "--chunk-size", "7"]) == 0
    assert checks["manifests"] > 6 and checks["writes"] > 6
    assert main(["verify", str(out)]) == 0


def test_a_shard_written_but_not_recorded_before_a_crash_is_run_again(smoke_dir, tmp_path,
                                                                     capsys):
    copy = _copy(smoke_dir, tmp_path / "crashed")
    cdir = CampaignDir(copy)
    config, plan = load_config("smoke"), cdir.read_plan()
    results = cdir.read_results()
    for path in cdir.shard_paths():
        cdir.remove(path)
    first = plan["run_id"].iloc[:5]
    cdir.write_shard(results[results["run_id"].isin(first)], config.to_json())
    # the next shard lands, then the process dies before the manifest update
    write_parquet(results[~results["run_id"].isin(first)], cdir.next_shard_path(),
                  config.to_json(), kind="results")
    assert main(["gate", str(copy)]) == 2
    assert "runs/part-000001.parquet is not in the manifest" in capsys.readouterr().err
    assert main(["run", "smoke", "--out", str(copy), "--quiet", "--jobs", "1"]) == 0
    err = capsys.readouterr().err
    assert "runs/part-000001.parquet was written but not recorded" in err
    assert "resuming" in err and "5 of 20 runs already done" in err
    assert main(["verify", str(copy)]) == 0
    again = CampaignDir(copy).read_results().sort_values(["run_id", "detector"])
    pd.testing.assert_frame_equal(
        again.reset_index(drop=True),
        results.sort_values(["run_id", "detector"]).reset_index(drop=True), check_exact=True)


# ---- modes follow the umask ----------------------------------------------------------------------
@pytest.mark.parametrize("umask, file_mode, dir_mode", [(0o022, 0o644, 0o755),
                                                        (0o027, 0o640, 0o750)])
def test_files_and_directories_follow_the_umask(tmp_path, umask, file_mode, dir_mode):
    old = os.umask(umask)
    try:
        out = tmp_path / "o"
        assert main(["run", "smoke", "--out", str(out), "--quiet", "--jobs", "1"]) == 0
        assert main(["gate", str(out), "--junit", str(tmp_path / "gate.xml")]) == 0
    finally:
        os.umask(old)
    paths = [out, *out.rglob("*"), tmp_path / "gate.xml"]
    assert len(paths) > 8
    for p in paths:
        want = dir_mode if p.is_dir() else file_mode
        assert stat.S_IMODE(p.stat().st_mode) == want, (p, oct(p.stat().st_mode))


# ---- one run at a time ---------------------------------------------------------------------------
SLOW_CAMPAIGN = """\
[campaign]
name = "slow"
seed = 3
duration_s = 20.0

[[group]]
fault = "none"
manoeuvres = ["cruise", "nose_up"]
count = 3

[[detector]]
name = "position-monitor"

[[detector]]
name = "misbehaving"
params = {{ marker = "{marker}", mode = "sleep", sleep_s = {sleep_s} }}

[learning]
runs_per_manoeuvre = 1
manoeuvres = ["cruise"]

[runner]
chunk_size = 2
"""

RUNNER = """\
import sys
sys.path.insert(0, {tests!r})
from detectors import registry
registry.BUILTIN["misbehaving"] = "machinery_detectors:Misbehaving"
from campaign.cli.commands import main
sys.exit(main(sys.argv[1:]))
"""


def _slow_campaign(tmp_path, sleep_s: float) -> tuple[Path, Path]:
    """A campaign file whose first run sleeps *sleep_s* [s], and a script running
    ``fdd-campaign`` with the sleeping detector registered."""
    cfg = tmp_path / "slow.toml"
    marker = tmp_path / "marked.json"
    config_text = SLOW_CAMPAIGN.format(marker=marker, sleep_s=sleep_s)
    cfg.write_text(config_text)
    import tomllib

    registry.BUILTIN.setdefault("misbehaving", "machinery_detectors:Misbehaving")
    try:
        config = CampaignConfig.from_dict(tomllib.loads(config_text))
    finally:
        registry.BUILTIN.pop("misbehaving", None)
    marker.write_text(json.dumps([build_plan(config)["run_id"].iloc[0]]))
    script = tmp_path / "run.py"
    script.write_text(RUNNER.format(tests=str(TESTS)))
    return cfg, script


def _raw_rows(out: Path) -> pd.DataFrame:
    """Every row of every shard, as stored (no deduplication)."""
    return pd.concat([pd.read_parquet(p) for p in sorted((out / "runs").glob("part-*"))],
                     ignore_index=True)


def test_two_runs_into_one_directory_at_once_one_is_refused(tmp_path):
    cfg, script = _slow_campaign(tmp_path, sleep_s=6.0)
    out = tmp_path / "o"
    cmd = [sys.executable, str(script), "run", str(cfg), "--out", str(out), "--quiet",
           "--jobs", "1"]
    procs = [subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True) for _ in range(2)]
    outs = [p.communicate(timeout=300) for p in procs]
    codes = [p.returncode for p in procs]
    assert sorted(codes) == [0, 2], (codes, outs)
    winner, loser = (0, 1) if codes[0] == 0 else (1, 0)
    err = outs[loser][1]
    assert f"is being written by another run (pid {procs[winner].pid} on host " \
           f"{socket.gethostname()}, started " in err
    rows = _raw_rows(out)
    assert not rows.duplicated(["run_id", "detector"]).any()
    assert len(rows) == 6 * 2
    assert main(["verify", str(out)]) == 0


def test_the_lock_of_a_killed_run_is_taken_over_with_a_note(tmp_path, capsys, monkeypatch):
    cfg, script = _slow_campaign(tmp_path, sleep_s=60.0)
    out = tmp_path / "o"
    proc = subprocess.Popen([sys.executable, str(script), "run", str(cfg), "--out", str(out),
                             "--quiet", "--jobs", "1"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        lock = out / LOCK_NAME
        t_end = time.monotonic() + 120
        while time.monotonic() < t_end and not (lock.exists() and lock.read_text()):
            time.sleep(0.1)
        assert json.loads(lock.read_text())["pid"] == proc.pid
        with pytest.raises(CampaignLockedError, match=f"pid {proc.pid}"):
            DirLock(lock).acquire()
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
    assert lock.exists()                      # left behind by the killed run
    (tmp_path / "marked.json").unlink()       # the rerun does not sleep
    monkeypatch.setitem(registry.BUILTIN, "misbehaving", "machinery_detectors:Misbehaving")
    monkeypatch.syspath_prepend(str(TESTS))
    assert main(["run", str(cfg), "--out", str(out), "--quiet", "--jobs", "1"]) == 0
    err = capsys.readouterr().err
    notes = [line for line in err.splitlines() if "taking over the lock" in line]
    assert len(notes) == 1 and f"pid {proc.pid}" in notes[0]
    assert not lock.exists()
    assert not _raw_rows(out).duplicated(["run_id", "detector"]).any()
    assert main(["verify", str(out)]) == 0


def test_a_run_refused_in_the_instant_the_holder_names_itself_still_names_the_holder(tmp_path):
    """The holder takes the flock first and writes its name a moment later: a run refused in
    between waits for the name instead of reporting ``pid ?`` (seen once in CI)."""
    import fcntl
    import threading

    lock = tmp_path / "o" / LOCK_NAME
    lock.parent.mkdir()
    fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o666)
    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)     # held, file still empty
    holder = {"pid": 424242, "host": "elsewhere", "started": "2026-01-01T00:00:00+00:00"}
    timer = threading.Timer(0.3, lambda: os.pwrite(fd, json.dumps(holder).encode(), 0))
    timer.start()
    try:
        with pytest.raises(CampaignLockedError,
                           match="pid 424242 on host elsewhere, started 2026-01-01"):
            DirLock(lock).acquire()
    finally:
        timer.join()
        os.close(fd)


def test_a_lock_file_being_rewritten_names_its_new_holder():
    """A holder writes its name over the previous one, then cuts the file: read in between,
    the first JSON object is the new holder's."""
    old = json.dumps({"pid": 1, "host": "h", "started": "a long time ago, before the new one"})
    new = json.dumps({"pid": 2, "host": "h", "started": "now"})
    assert DirLock._parse((new + old[len(new):]).encode())["pid"] == 2


def test_a_failed_setup_releases_the_lock(tmp_path):
    out = tmp_path / "o"
    out.mkdir()
    (out / "stray.txt").write_text("not a campaign")
    with pytest.raises(Exception, match="not empty and holds no campaign.json"):
        from campaign import run

        run(load_config("smoke"), out, jobs=1, progress=False, log=lambda m: None)
    assert not (out / LOCK_NAME).exists()


# ---- dask: plain TCP beyond loopback is warned about, TLS options are checked --------------------
def test_plain_tcp_to_another_host_is_warned_about_in_one_line():
    from campaign.execute import ClusterError, connect

    notes = []
    with pytest.raises(ClusterError, match="cannot reach"):
        connect("tcp://192.0.2.1:8786", timeout_s=0.2, log=notes.append)   # TEST-NET-1
    assert len(notes) == 1 and notes[0].startswith("warning: tcp://192.0.2.1:8786 is plain TCP")
    assert "\n" not in notes[0]
    notes.clear()
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(ClusterError):
        connect(f"tcp://127.0.0.1:{port}", timeout_s=0.2, log=notes.append)
    assert notes == []


@pytest.mark.parametrize("args, needle", [
    (["--tls-cert", "c.pem"], "--tls-cert apply to a dask cluster: give --scheduler "
                              "tls://HOST:PORT too"),
    (["--scheduler", "tcp://127.0.0.1:1", "--tls-ca-file", "ca.pem"],
     "--tls-ca-file apply to a tls:// scheduler"),
    (["--scheduler", "tls://127.0.0.1:1", "--tls-ca-file", "missing-ca.pem"],
     "--tls-ca-file missing-ca.pem: no such file"),
])
def test_tls_options_are_checked_before_any_work(tmp_path, capsys, monkeypatch, args, needle):
    monkeypatch.chdir(tmp_path)
    assert main(["run", "smoke", "--out", "o", "--quiet", *args]) == 2
    assert needle in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_a_tls_scheduler_without_certificates_says_which_are_missing(tmp_path, capsys):
    import dask

    with dask.config.set({"distributed.comm.tls.ca-file": None,
                          "distributed.comm.tls.client.cert": None}):
        assert main(["run", "smoke", "--out", str(tmp_path / "o"), "--quiet",
                     "--scheduler", "tls://127.0.0.1:1"]) == 2
    err = capsys.readouterr().err
    assert "--tls-ca-file (or dask's distributed.comm.tls.ca-file)" in err
    assert "--tls-cert (or dask's distributed.comm.tls.client.cert)" in err



def test_a_directory_written_before_the_plant_keys_moved_still_resumes(tmp_path, capsys):
    """campaign.json of an older version spells the plant in [campaign] and has no
    manifest: the same campaign resumes (nothing recomputed), it is not refused as a
    different one."""
    import json

    from campaign.cli.commands import main

    out = tmp_path / "old"
    assert main(["run", "smoke", "--out", str(out), "--quiet", "--jobs", "1"]) == 0
    config = json.loads((out / "campaign.json").read_text())
    config["campaign"]["plant"] = config["plant"].pop("kind")      # the old spelling
    (out / "campaign.json").write_text(json.dumps(config, sort_keys=True, separators=(",", ":")))
    (out / "manifest.json").unlink()                                 # older versions had none
    shards = sorted(p.name for p in (out / "runs").glob("part-*.parquet"))
    capsys.readouterr()
    assert main(["run", "smoke", "--out", str(out), "--quiet", "--jobs", "1"]) == 0
    err = capsys.readouterr().err
    assert "20 of 20 runs already done" in err
    assert sorted(p.name for p in (out / "runs").glob("part-*.parquet")) == shards


@pytest.mark.parametrize("size", [0, 1, (1 << 20) - 1, 1 << 20, (1 << 20) + 1, 3 << 20])
def test_file_digests_are_the_sha256_of_the_bytes(tmp_path, size):
    # the manifest's digests (hashlib.file_digest) equal the digest of the whole content
    # read at once, at and around the 1 MiB blocks files used to be read in: a directory
    # written before stays verifiable
    from campaign.store.files import sha256_of

    data = np.random.default_rng(size).bytes(size)
    path = tmp_path / "file.bin"
    path.write_bytes(data)
    assert sha256_of(path) == hashlib.sha256(data).hexdigest()
