"""The campaign engine end to end: plan, determinism across jobs and chunk sizes, resume
after a kill, per-run errors, the gate and the command line."""

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from campaign import run
from campaign.plant_setup import resolve
from campaign.cli.commands import main
from campaign.config import CampaignConfig, load_config
from campaign.plan import LEARNING_STREAM_BASE, build_learning_plan, build_plan
from campaign.evaluate import ChunkSettings, evaluate
from campaign.store.directory import CampaignDirError

ROOT = Path(__file__).resolve().parents[2]


def tiny(**over) -> CampaignConfig:
    """A small, fast campaign (20 s runs) built from a dict."""
    data = {
        "campaign": {"name": "tiny", "seed": 7, "duration_s": 20.0},
        "faults": {"onset_min_s": 5.0, "onset_before_end_s": 5.0},
        "group": [
            {"name": "ff", "fault": "none", "manoeuvres": ["cruise", "nose_up"], "count": 3},
            {"name": "jam", "fault": "solid_jam", "manoeuvres": ["nose_up"], "count": 2},
            {"name": "ra", "fault": "runaway", "manoeuvres": ["cruise"], "count": 2},
            {"name": "lj", "fault": "liquid_jam", "manoeuvres": ["cruise"], "count": 2},
        ],
        "detector": [{"name": "position-monitor"}],
        "learning": {"runs_per_manoeuvre": 2},
        "runner": {"chunk_size": 4},
    }
    for key, value in over.items():
        data[key] = value
    return CampaignConfig.from_dict(data)


def test_addsafe_mc_plan_counts_match_chen():
    plan = build_plan(load_config("addsafe-mc"))
    counts = plan.groupby("fault").size()
    # [CHEN] §5.2: 1200 fault-free (200 × 6 manoeuvres), 333 + 333 + 334 faulty
    assert counts["none"] == 1200
    assert (plan[plan.fault == "none"].groupby("manoeuvre").size() == 200).all()
    assert counts["liquid_jam"] == 333 and counts["solid_jam"] == 333
    assert counts["disconnection"] == 334
    assert plan["run_id"].is_unique
    assert (plan["level"] == "mc").all() and plan["realistic"].all()
    onset = plan.loc[plan.fault != "none", "onset_s"]
    assert onset.min() >= 5.0 and onset.max() <= 50.0


def test_grid_plan_keeps_the_realistic_cases():
    plan = build_plan(load_config("addsafe-grid"))
    per_cell = plan.groupby(["group", "manoeuvre"]).size()
    # docs/physics.md §6: the realistic rule keeps 53 of 108 points, i.e. 159 of 324 cases
    assert (per_cell == 159).all()
    assert set(plan["level"]) == {"min", "nominal", "max"}


def test_plan_is_deterministic_and_learning_streams_are_disjoint():
    cfg = tiny()
    a, b = build_plan(cfg), build_plan(cfg)
    pd.testing.assert_frame_equal(a, b)
    learn = build_learning_plan(resolve(cfg))
    assert (learn["stream"] >= LEARNING_STREAM_BASE).all()
    assert (learn["fault"] == "none").all()
    assert not set(learn["run_id"]) & set(a["run_id"])


def _rows(result):
    return result.results.sort_values(["run_id", "detector"]).reset_index(drop=True)


def test_results_are_bit_identical_across_jobs_and_chunk_sizes(tmp_path):
    cfg = tiny()
    r1 = run(cfg, tmp_path / "j1", jobs=1, chunk_size=3, progress=False)
    r2 = run(cfg, tmp_path / "j2", jobs=2, chunk_size=5, progress=False)
    assert r1.complete and r2.complete
    assert len(r1.results) == len(r1.plan)
    pd.testing.assert_frame_equal(_rows(r1), _rows(r2), check_exact=True)


def test_faults_are_detected_and_fault_free_runs_are_quiet(tmp_path):
    res = run(tiny(), tmp_path / "out", jobs=1, progress=False)
    r = res.results
    assert (r["status"] == "ok").all()
    ff = r[r.fault == "none"]
    assert not ff["false_alarm"].any()
    faulty = r[r.fault != "none"]
    assert faulty["detected"].all()
    # runaways (≥ 1 °/s) and liquid jams (bias on COM, seen against MON) show within their
    # required detection time; a solid jam only shows once the order moves ([COMB] D_V3),
    # so it is only required to be detected
    quick = faulty[faulty.fault.isin(["runaway", "liquid_jam"])]
    assert len(quick) == 4 and (quick["dtp"] <= 1.0).all()
    assert (res.summary.columns[:3] == ["detector", "fault", "manoeuvre"]).all()
    for name in ("plan.parquet", "summary.parquet", "learning.parquet", "campaign.json"):
        assert (res.root / name).exists()


#: A small campaign whose faulty groups have fixed onsets: ``run`` stores its detection
#: times (reports.scoring.detection_times) beside the summary.
FIXED_ONSETS = """
[campaign]
name = "fixed-onsets"
seed = 5
duration_s = 20.0
[[group]]
name = "ff"
fault = "none"
manoeuvres = ["cruise"]
count = 2
[[group]]
name = "jam"
fault = "solid_jam"
manoeuvres = ["nose_up"]
count = 2
onset_s = 8.0
[[group]]
name = "ra"
fault = "runaway"
manoeuvres = ["cruise"]
count = 1
onset_s = 10.0
[[detector]]
name = "position-monitor"
[learning]
runs_per_manoeuvre = 1
"""


def test_python_api_and_command_line_leave_the_same_directory(tmp_path, capsys):
    cfg_file = tmp_path / "fixed.toml"
    cfg_file.write_text(FIXED_ONSETS)
    py, cli = tmp_path / "py", tmp_path / "cli"
    res = run(load_config(cfg_file), py, jobs=1, progress=False)
    assert main(["run", str(cfg_file), "--out", str(cli), "--jobs", "1", "--quiet"]) == 0
    assert "Detection times (s) of position-monitor" in capsys.readouterr().out

    def files(root):
        return sorted(str(p.relative_to(root)) for p in root.rglob("*") if p.is_file())

    assert files(py) == files(cli)
    assert "detection-times.parquet" in files(py)
    times = pd.read_parquet(py / "detection-times.parquet")
    pd.testing.assert_frame_equal(times, pd.read_parquet(cli / "detection-times.parquet"),
                                  check_exact=True)
    pd.testing.assert_frame_equal(times, res.detection_times, check_exact=True)
    # one row per group, the faulty groups alarmed after their onsets
    assert list(times["group"]) == ["ff", "jam", "ra"]
    faulty = times[times["fault"] != "none"]
    assert (faulty["n_alarmed"] == faulty["n_runs"]).all() and (faulty["delay_s"] > 0).all()


def test_load_reads_back_the_campaign_that_run_returned(tmp_path):
    """``campaign.load(DIR)`` gives the object ``campaign.run`` returned: the same result
    rows (in plan order, whatever order the chunks finished in), run table, summary,
    detection times, fitted detectors, provenance; the heavy parts are read on first
    access; the certificate, once made, is the one ``certify`` returned."""
    import dataclasses

    import campaign
    from campaign.evidence.certify import certify
    from campaign.plan import MODEL_VERSION
    from campaign.store.directory import CampaignDir

    cfg_file = tmp_path / "fixed.toml"
    cfg_file.write_text(FIXED_ONSETS)
    out = tmp_path / "out"
    # two workers and chunks of one run: the shards land in the order the chunks finish
    ran = campaign.run(load_config(cfg_file), out, jobs=2, chunk_size=1, progress=False)
    loaded = campaign.load(out)
    assert not {"results", "plan", "fitted", "certificate", "config"} & set(vars(loaded))
    assert loaded == ran and isinstance(loaded, campaign.Campaign)
    assert ran.wall_s > 0 and loaded.wall_s is None        # the seconds of a run, not stored
    for part in ("results", "plan", "summary", "detection_times"):
        pd.testing.assert_frame_equal(getattr(loaded, part), getattr(ran, part),
                                      check_exact=True)
    assert list(loaded.results["run_id"]) == list(ran.plan["run_id"])   # one detector
    prov = loaded.provenance
    assert (prov.model_version, prov.seed, prov.fitted_from) == (MODEL_VERSION, 5, None)
    assert prov.fitted_sha256 == CampaignDir(out).fitted_sha256(["position-monitor"])
    assert list(loaded.fitted) == ["position-monitor"]
    assert loaded.fitted["position-monitor"].fitted_state().keys() == \
        ran.fitted["position-monitor"].fitted_state().keys()
    # a few lines: directory, runs, each detector's counts (those of the result rows)
    r = loaded.results
    fa = int(r.loc[r["fault"] == "none", "false_alarm"].sum())
    md = int((~r.loc[r["fault"] != "none", "detected"].astype(bool)).sum())
    text = repr(loaded)
    assert text.splitlines()[0].startswith(f"<Campaign 'fixed-onsets' in {out}: 5 of 5 runs")
    assert (f"position-monitor: {fa} false alarm{'' if fa == 1 else 's'} in 2 fault-free "
            f"runs, {md} missed of 3 faulty") in text and len(text.splitlines()) == 3
    # another campaign (another seed) is not equal
    from campaign.config import with_overrides

    other = campaign.run(with_overrides(load_config(cfg_file), seed=6), tmp_path / "seed6",
                         jobs=1, progress=False)
    assert other != ran
    assert loaded.certificate is None
    cert = certify(out, jobs=1, log=lambda _: None)
    again = campaign.load(out).certificate
    assert isinstance(cert, campaign.Certificate) and again == cert
    assert again.assumptions and list(again.table["detector"]) == ["position-monitor"]
    assert again.levels is not None and again.hazard is not None
    assert dataclasses.replace(cert, level=0.9) != cert


def test_campaign_run_spells_out_the_runners_keywords():
    """``campaign.run`` shows its real keywords (not ``**kwargs``): the same names, kinds and
    defaults as :func:`campaign.runner.run`, so neither can drift from the other."""
    import inspect

    import campaign
    from campaign import runner

    def params(f):
        return {name: (p.kind, p.default) for name, p in inspect.signature(f).parameters.items()}

    assert params(campaign.run) == params(runner.run)
    assert not any(p.kind is inspect.Parameter.VAR_KEYWORD
                   for p in inspect.signature(campaign.run).parameters.values())


def test_a_campaign_of_random_onsets_stores_no_detection_times(tmp_path):
    res = run(tiny(), tmp_path / "out", jobs=1, progress=False)
    assert res.detection_times is None
    assert not (res.root / "detection-times.parquet").exists()


def test_a_bad_run_is_recorded_and_does_not_stop_the_chunk():
    cfg = tiny()
    plan = build_plan(cfg).iloc[:3].copy()
    plan.loc[plan.index[1], "alt_ft"] = 1e6          # impossible altitude
    from campaign.runner import fit_detectors  # noqa: F401  (contract: detectors come fitted)
    from detectors import make_detector
    from scenarios.simulate import simulate

    det = make_detector("position-monitor")
    det.fit(simulate(build_learning_plan(resolve(cfg)).iloc[:2])[0])
    settings = ChunkSettings(ts=0.01, pressure_sensor=False, required_time_s={}, window_s=None)
    out = evaluate(plan, {"pm": det}, settings)
    assert list(out["status"]) == ["ok", "error", "ok"]
    assert "alt_ft" in out["error"].iloc[1]


def test_resume_after_sigkill_loses_and_duplicates_nothing(tmp_path):
    cfg_file = tmp_path / "c.toml"
    cfg_file.write_text("""
[campaign]
name = "killme"
seed = 3
duration_s = 20.0
[faults]
onset_before_end_s = 5.0
[[group]]
fault = "none"
manoeuvres = ["all"]
count = 8
[[detector]]
name = "position-monitor"
[learning]
runs_per_manoeuvre = 1
[runner]
chunk_size = 4
""")
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "campaign.cli.commands", "run", str(cfg_file), "--out", str(out),
           "--jobs", "1", "--quiet"]
    proc = subprocess.Popen(cmd, cwd=tmp_path, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    deadline = time.time() + 120
    while time.time() < deadline and len(list((out / "runs").glob("part-*.parquet"))) < 2:
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    shards_at_kill = len(list((out / "runs").glob("part-*.parquet")))
    assert 2 <= shards_at_kill < 12, "the kill must land mid-campaign"
    assert main(["run", str(cfg_file), "--out", str(out), "--jobs", "2", "--quiet"]) == 0
    resumed = pd.read_parquet(out / "runs")
    assert len(resumed) == 48 and resumed["run_id"].is_unique
    fresh = run(load_config(cfg_file), tmp_path / "fresh", jobs=1, progress=False).results
    key = ["run_id", "detector"]
    a = resumed.sort_values(key).reset_index(drop=True)
    b = fresh.sort_values(key).reset_index(drop=True)
    pd.testing.assert_frame_equal(a[b.columns], b, check_exact=True)


def test_rerun_into_a_directory_of_another_campaign_is_refused(tmp_path, capsys):
    out = tmp_path / "out"
    run(tiny(), out, jobs=1, progress=False)
    other = tmp_path / "other.toml"
    other.write_text('[campaign]\nname = "other"\n[[group]]\nfault = "none"\ncount = 1\n'
                     '[[detector]]\nname = "position-monitor"\n')
    assert main(["run", str(other), "--out", str(out), "--quiet"]) == 2
    assert "different campaign" in capsys.readouterr().err


_EDITABLE = """[campaign]
name = "edited"
seed = {seed}
duration_s = 20.0
[[group]]
name = "ff"
fault = "none"
manoeuvres = ["cruise"]
count = 2
[[group]]
name = "jam"
fault = "solid_jam"
manoeuvres = ["cruise"]
count = {count}
[[detector]]
name = "position-monitor"
[learning]
runs_per_manoeuvre = 2
"""


def test_rerun_of_an_edited_campaign_file_names_what_changed(tmp_path, capsys):
    # the README's "edit it, run again": the refusal names each changed key with its stored
    # and new value, in the file's words, and the way on (a new --out)
    file, out = tmp_path / "c.toml", tmp_path / "c"
    file.write_text(_EDITABLE.format(seed=0, count=3))
    assert main(["plan", str(file), "--out", str(out)]) == 0
    capsys.readouterr()
    file.write_text(_EDITABLE.format(seed=5, count=1))
    assert main(["run", str(file), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert '[[group]] 2 ("jam") count: 3 → 1' in err
    assert "[campaign] seed: 0 → 5" in err
    assert "[[group]] 1" not in err                 # unchanged tables are not named
    assert "new --out directory" in err and "compare" in err
    assert not list((out / "runs").glob("part-*.parquet"))     # nothing ran


def test_identity_changes_name_added_tables_and_nested_keys():
    from campaign.store.directory import campaign_identity, changes_text, identity_changes

    a = json.loads(tiny().to_json())
    b = json.loads(tiny(detector=[{"name": "position-monitor", "params": {"safety": 2.0}},
                                  {"name": "comb-interval"}],
                        faults={"onset_min_s": 6.0, "onset_before_end_s": 5.0,
                                "runaway": {"rate_deg_s": [1.0, 5.0]}}).to_json())
    changes = identity_changes(campaign_identity(a), campaign_identity(b))
    assert "[faults] onset_min_s: 5.0 → 6.0" in changes
    assert "[faults.runaway] rate_deg_s: [1.0, 10.0] → [1.0, 5.0]" in changes
    assert '[[detector]] 1 ("position-monitor") params.safety: (absent) → 2.0' in changes
    assert '[[detector]] 2 ("comb-interval") added' in changes
    # chunk_size is not part of the identity: no change named for it
    c = json.loads(tiny(runner={"chunk_size": 9}).to_json())
    assert identity_changes(campaign_identity(a), campaign_identity(c)) == []
    many = [f"k{i}" for i in range(11)]
    assert changes_text(many).endswith("k7; and 3 more")


def test_resume_with_another_chunk_size_continues_the_same_campaign(tmp_path):
    # chunk_size and run_timeout_s do not change any result row, so they do not make another
    # campaign; the engine does (last-bit differences) and is still refused
    out = tmp_path / "out"
    first = run(tiny(), out, jobs=1, progress=False)
    again = run(tiny(runner={"chunk_size": 3, "run_timeout_s": 600.0}), out, jobs=1,
                progress=False)
    pd.testing.assert_frame_equal(_rows(again), _rows(first), check_exact=True)
    with pytest.raises(CampaignDirError, match="different campaign"):
        run(tiny(runner={"chunk_size": 4, "engine": "numpy"}), out, jobs=1, progress=False)


def test_gate_passes_on_defaults_and_fails_on_an_oversensitive_detector(tmp_path, capsys):
    ok = tmp_path / "ok"
    run(tiny(), ok, jobs=1, progress=False)
    junit = tmp_path / "gate.xml"
    assert main(["gate", str(ok), "--max-fa", "0", "--junit", str(junit)]) == 0
    assert junit.exists()
    # thresholds at 1.01 × the largest residual of 2 learning runs, no confirmation:
    # far too tight for 6 fault-free evaluation runs at other flight points
    sensitive = tiny(detector=[{"name": "position-monitor",
                                "params": {"safety": 1.01, "confirm_s": 0.0}}],
                     learning={"runs_per_manoeuvre": 1})
    bad = tmp_path / "bad"
    res = run(sensitive, bad, jobs=1, progress=False)
    assert res.results.loc[res.results.fault == "none", "false_alarm"].any()
    capsys.readouterr()
    assert main(["gate", str(bad), "--max-fa", "0"]) == 1
    assert "FAIL" in capsys.readouterr().out


def test_gate_checks_the_files_md_and_dtp_limits_only_with_all_requirements(tmp_path, capsys):
    # a DTP limit no detector can meet (delay ≥ one 10 ms step, required ≥ 0.5 s → DTP ≥ 0.02)
    out = tmp_path / "strict"
    run(tiny(requirements={"max_dtp": 0.001}), out, jobs=1, progress=False)
    assert main(["gate", str(out), "--max-fa", "0"]) == 0
    capsys.readouterr()
    assert main(["gate", str(out), "--max-fa", "0", "--all-requirements"]) == 1
    text = capsys.readouterr().out
    assert "FAIL" in text and "DTP" in text
    # an explicit flag still wins over the file
    assert main(["gate", str(out), "--all-requirements", "--max-dtp", "1000"]) == 0


@pytest.mark.parametrize("argv, needle", [
    (["run", "no-such-preset", "--out", "x"], "preset"),
    (["simulate", "--surface", "rudder"], "invalid choice"),
    (["gate", "/nonexistent/dir"], "/nonexistent/dir does not exist"),
])
def test_cli_bad_input_exits_2_with_a_message(argv, needle, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    try:
        code = main(argv)
    except SystemExit as exc:          # argparse refuses unknown choices itself
        code = exc.code
    assert code == 2
    captured = capsys.readouterr()
    assert needle in (captured.err + captured.out)


def test_simulate_command_writes_signals_truth_and_plot(tmp_path):
    out, png = tmp_path / "run.parquet", tmp_path / "run.png"
    assert main(["simulate", "--surface", "elevator", "--manoeuvre", "turn_coordination",
                 "--fault", "solid_jam", "--plot", str(png), "--out", str(out)]) == 0
    frame = pd.read_parquet(out)
    assert {"command [mm]", "rod_com [mm]", "rod_mon [mm]", "surface [deg]", "current [mA]",
            "true_rod [mm]", "true_surface [deg]"} <= set(frame.columns)
    after = frame[frame["time [s]"] >= 10.0]
    assert np.ptp(after["true_rod [mm]"]) == 0.0          # the solid jam froze the rod
    assert png.stat().st_size > 10_000


def test_every_parquet_file_says_how_it_was_made(tmp_path):
    import pyarrow.parquet as pq

    from campaign.store.directory import read_metadata

    res = run(tiny(), tmp_path / "out", jobs=1, progress=False)
    for path in [res.root / "plan.parquet", res.root / "summary.parquet",
                 *sorted((res.root / "runs").glob("*.parquet"))]:
        meta = read_metadata(path)
        assert meta["config"]["campaign"]["name"] == "tiny"
        assert meta["rows"] == pq.read_metadata(path).num_rows
        assert meta["engine_version"]


def _zero_estimate(with_estimate: bool = True):
    """A detector that never alarms and, *with_estimate*, estimates the rod fault as 0."""
    from detectors.base import Capabilities, Detection, Detector

    class ZeroEstimate(Detector):
        capabilities = Capabilities(needs_fit=False)

        def _detect(self, signals):
            shape = signals.command.shape
            return Detection(alarm=np.zeros(shape, bool), residual=np.zeros(shape),
                             estimate=np.zeros(shape) if with_estimate else None)

    return ZeroEstimate()


def _jam_runs() -> pd.DataFrame:
    """Three 20 s elevator runs in cruise: fault-free, liquid jam, solid jam (onset 5 s)."""
    from scenarios.simulate import single_run

    runs = pd.concat([single_run("elevator", "cruise", f, seed=i, onset_s=5.0,
                                 duration_s=20.0, **extra)
                      for i, (f, extra) in enumerate([("none", {}), ("liquid_jam", {}),
                                                      ("solid_jam", {"magnitude": -1.0})])],
                     ignore_index=True)
    runs["stream"] = [0, 1, 2]
    runs["run_id"] = ["ff", "liq", "sol"]
    return runs


def test_evaluate_stores_the_estimation_error_of_detectors_that_estimate_the_fault():
    # a detector whose estimate is always 0 errs by −f after onset: the stored mean is
    # minus the mean of the truth's rod-measurement fault over that window ([CHEN] §6.2),
    # the sample count the post-onset steps; fault-free runs and detectors without an
    # estimate store no sample
    from scenarios.faults import estimation_range_mm
    from scenarios.params import ELEVATOR
    from scenarios.simulate import simulate

    runs = _jam_runs()
    settings = ChunkSettings(ts=0.01, pressure_sensor=False,
                             required_time_s={"liquid_jam": 2.0, "solid_jam": 2.0},
                             window_s=None)
    out = evaluate(runs, {"z": _zero_estimate(), "n": _zero_estimate(False)}, settings)
    z = out[out["detector"] == "z"].set_index("run_id")
    _, truth = simulate(runs)
    f = truth.rod_fault_mm
    assert list(z["est_err_n"]) == [0, 1500, 1500]
    for j, rid in ((1, "liq"), (2, "sol")):
        assert z.loc[rid, "est_err_mean_mm"] == pytest.approx(-np.nanmean(f[j]), rel=1e-12)
        assert z.loc[rid, "est_err_var_mm2"] == pytest.approx(np.nanvar(f[j]), rel=1e-9)
        assert z.loc[rid, "est_range_mm"] == estimation_range_mm(ELEVATOR)
    assert np.isnan(z.loc["ff", "est_err_mean_mm"]) and np.isnan(z.loc["ff", "est_range_mm"])
    assert (out.loc[out["detector"] == "n", "est_err_n"] == 0).all()


def test_the_rod_fault_is_computed_only_when_an_estimate_is_scored(monkeypatch):
    """The truth's rod fault ([CHEN] eq. 4) takes a healthy servo model of every jam run:
    simulate defers it (Truth.rod_fault_mm), evaluating detectors without an estimate never
    computes it, and read later it is the array rod_measurement_fault gives, for the batch
    and for one run taken out of it."""
    import scenarios.simulate as sim

    runs = _jam_runs()
    models = []
    servo_model = sim.servo_model
    monkeypatch.setattr(sim, "servo_model",
                        lambda *a, **k: models.append(1) or servo_model(*a, **k))
    settings = ChunkSettings(ts=0.01, pressure_sensor=False, required_time_s={},
                             window_s=None)
    out = evaluate(runs, {"n": _zero_estimate(with_estimate=False)}, settings)
    assert len(out) == 3 and models == []           # scored without the healthy model

    signals, truth = sim.simulate(runs)
    assert models == []
    one = truth.take([2])
    eager = sim.rod_measurement_fault(runs["fault"].to_numpy(), runs["onset_s"].to_numpy(float),
                                      signals.rod_com, signals.command, sim.prepare(runs).plant,
                                      0.01)
    assert len(models) == 1                          # the reference's own healthy model
    np.testing.assert_array_equal(truth.rod_fault_mm, eager)
    assert len(models) == 2
    np.testing.assert_array_equal(truth.rod_fault_mm, eager)    # kept: not computed again
    np.testing.assert_array_equal(one.rod_fault_mm, eager[[2]])
    assert len(models) == 2
    assert np.isfinite(eager[1:, 600:]).all() and np.isnan(eager[0]).all()


def test_the_progress_reporter_rates_only_the_runs_computed_now():
    """One reporter for run, falsify and certify (campaign.progress.Progress): runs done
    before it started or read back count as done, never in the rate, so the ETA is not
    made short by a resume."""
    from campaign.progress import Progress

    lines: list[str] = []
    bar = Progress(100, done=40, log=lines.append, label="sampling x: ")
    bar.update(20, computed=False, note=" (read back)")
    # nothing computed yet: no rate, no ETA (not an infinite speed)
    assert lines[-1] == ("sampling x: 60/100 runs  60.0 %      0.0 runs/s  ETA   nan s"
                         " (read back)")
    bar.update(10)
    assert lines[-1].startswith("sampling x: 70/100 runs  70.0 %")
    assert float(lines[-1].split()[6]) > 0.0           # the 10 computed runs give a rate
    quiet = Progress(5, enabled=False, log=lines.append)
    quiet.update(5)
    assert len(lines) == 2 and quiet.done == 5
