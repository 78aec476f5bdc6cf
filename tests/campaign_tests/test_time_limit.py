"""``[runner] run_timeout_s`` is enforced or refused, never ignored: with a limit every run
is bounded on the local workers (loky processes, one for ``--jobs 1``; the fit and the
start-up check of a third-party detector too), and thread workers or a dask cluster, which
cannot stop a running chunk, are refused before any work with exit 2 and the fix,
``--quiet`` or not (docs/execution.md)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from campaign.plant_setup import resolve
from campaign.cli.commands import main
from campaign.config import CampaignConfig
from campaign.plan import build_learning_plan, build_plan
from campaign.store.directory import CampaignDir
from small_campaigns import campaign_toml, small_campaign

TESTS = Path(__file__).resolve().parents[1]
ROOT = TESTS.parent

#: A guard so that a regression (a limit ignored again) fails the test instead of hanging
#: the suite: the bounded run below takes well under a minute; the hanging detector would
#: sleep an hour.
HANG_GUARD_S = 600

#: Run through the command line in a child process (the guard above can stop it), with the
#: misbehaving test detector registered as a third-party detector.
DRIVER = """
import sys
from detectors import registry
registry.BUILTIN["misbehaving"] = "machinery_detectors:Misbehaving"
registry.BUILTIN["fit-sleeps"] = "plugin_detectors:FitSleeps"
from campaign.cli.commands import main
sys.exit(main(sys.argv[1:]))
"""


def _config(marker, *, timeout_s=2.0) -> dict:
    return small_campaign(
        "limit", 5150, [{"name": "misbehaving", "params": {"marker": str(marker),
                                                          "mode": "sleep", "sleep_s": 3600.0}}],
        free=2, pm_first=False, learning_runs=1, learning_manoeuvres=("cruise",),
        runner={"chunk_size": 2, "run_timeout_s": timeout_s})


def _write(tmp_path, cfg: dict) -> Path:
    path = tmp_path / "limit.toml"
    path.write_text(campaign_toml(cfg))
    return path


def _register_misbehaving(patch: pytest.MonkeyPatch) -> None:
    """The misbehaving test detector as a built-in one, in this process, while *patch* lasts."""
    from detectors import registry

    patch.setitem(registry.BUILTIN, "misbehaving", "machinery_detectors:Misbehaving")


@pytest.fixture
def misbehaving(monkeypatch):
    _register_misbehaving(monkeypatch)


class Child:
    """A command started in a child process (:data:`DRIVER`), its output read once."""

    def __init__(self, argv: list[str]):
        env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), str(TESTS)])}
        self.proc = subprocess.Popen([sys.executable, "-c", DRIVER, *argv], env=env,
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        self._done = None

    def result(self) -> tuple[int, str]:
        """(exit code, stderr), waiting at most :data:`HANG_GUARD_S`."""
        if self._done is None:
            try:
                _, err = self.proc.communicate(timeout=HANG_GUARD_S)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                raise
            self._done = (self.proc.returncode, err)
        return self._done


@pytest.fixture(scope="module")
def hanging(tmp_path_factory):
    """The three commands of the tests below, started at once: each spends most of its time
    waiting for a limit (the start-up check's 3 × 2 s, a run's 2 s, a fit's 2 s), so they
    wait side by side instead of one after the other. name → (Child, directory, plan,
    victim run id)."""
    started = {}
    with pytest.MonkeyPatch.context() as patch:
        _register_misbehaving(patch)
        for jobs in (1, 2):
            tmp = tmp_path_factory.mktemp(f"hanging-detector-{jobs}")
            marker = tmp / "marked.json"
            cfg = _config(marker)
            resolved = resolve(CampaignConfig.from_dict(cfg))
            plan, learning = build_plan(resolved), build_learning_plan(resolved)
            victim = plan["run_id"].iloc[3]
            marker.write_text(json.dumps([victim, learning["run_id"].iloc[0]]))
            path, out = _write(tmp, cfg), tmp / "out"
            started[jobs] = (Child(["run", str(path), "--jobs", str(jobs), "--quiet",
                                    "--out", str(out)]), out, plan, victim)
    tmp = tmp_path_factory.mktemp("hanging-fit")
    cfg = _config(tmp / "none.json")
    cfg["detector"] = [{"name": "fit-sleeps", "label": "slow"},
                       {"name": "position-monitor", "label": "pm"}]
    path, out = _write(tmp, cfg), tmp / "out"
    started["fit"] = (Child(["run", str(path), "--jobs", "1", "--quiet", "--out", str(out)]),
                      out, None, None)
    yield started
    for child, *_ in started.values():
        if child.proc.poll() is None:
            child.proc.kill()
            child.proc.wait()


@pytest.mark.slow
@pytest.mark.parametrize("jobs", [1, 2])
def test_a_hanging_detector_is_stopped_at_the_limit(hanging, jobs):
    """The detector sleeps an hour on one planned run and on the learning run of the
    start-up batch-invariance check; the limit is 2 s. The check is stopped (a note says
    so), the run is recorded as a timeout, every other run is scored, and the command ends
    (exit 0), on the default backend with --jobs 1 (in-process before: unbounded) and 2."""
    child, out, plan, victim = hanging[jobs]
    code, err = child.result()
    assert code == 0, err
    assert "did not finish its batch-invariance check" in err
    results = CampaignDir(out).read_results().set_index(["run_id", "detector"])
    assert len(results) == 2 * len(plan)
    late = results.loc[victim]
    assert (late["status"] == "timeout").all() and "run_timeout_s" in late["error"].iloc[0]
    assert (results.drop(index=victim, level="run_id")["status"] == "ok").all()


def test_a_hanging_fit_is_stopped_at_the_limit(hanging):
    """A third-party detector whose fit sleeps an hour, with a limit of 2 s and one learning
    run: the fit is stopped after 2 s and the start refused (exit 2) naming it."""
    child, out, _, _ = hanging["fit"]
    code, err = child.result()
    assert code == 2, err
    assert "detector 'slow' (FitSleeps) failed while fitting on the learning set" in err
    assert "fit did not finish within 2 s (run_timeout_s = 2 s for each of the 1 learning " \
           "runs)" in err
    assert not out.exists()


@pytest.mark.parametrize("options, named, fix", [
    (["--jobs", "2", "--backend", "threading"], "--backend threading", "--backend loky"),
    (["--jobs", "1", "--backend", "threading"], "--backend threading", "--backend loky"),
    (["--scheduler", "tcp://127.0.0.1:9"], "--scheduler tcp://127.0.0.1:9",
     "leave out --scheduler"),
])
def test_a_limit_that_cannot_hold_is_refused_before_any_work(tmp_path, misbehaving, capsys,
                                                             options, named, fix):
    """No marker: were the refusal gone, the campaign would just run (and this fail)."""
    path, out = _write(tmp_path, _config(tmp_path / "none.json")), tmp_path / "out"
    assert main(["run", str(path), "--quiet", "--out", str(out), *options]) == 2
    err = capsys.readouterr().err
    assert f"run_timeout_s = 2 s cannot be enforced with {named}" in err
    assert fix in err and "nothing was run" in err
    assert not out.exists()


def test_run_local_refuses_a_limit_on_threads():
    import pandas as pd

    from campaign.execute import run_local

    with pytest.raises(ValueError, match="cannot stop a running chunk"):
        run_local([pd.DataFrame({"run_id": ["a"]})], lambda rows: rows, None, print, jobs=1,
                  backend="threading", run_timeout_s=1.0)
