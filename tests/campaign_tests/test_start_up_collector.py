"""The garbage collector at the start of ``fdd-campaign run`` (campaign/startup.py,
``defer_collection`` and ``start_up_done``; docs/execution.md, "The collector at start-up"):
nothing is collected while the command imports its libraries and loads its kernels, those
objects are then frozen out of the collector's reach, and the collector is on again for the
campaign; every other command has it on before it starts, and a program calling
``campaign.run`` keeps its collector untouched. Each case runs in a child process: the
collector's state is the process's."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

from small_campaigns import campaign_toml, small_campaign

ROOT = Path(__file__).resolve().parents[2]

# a child's record of its collector: every collection (with the number of frozen objects at
# the time), and the state at its exit (the exit handlers run before `leave` ends it)
RECORDER = """
    import atexit, gc, json, sys
    passes = []
    gc.callbacks.append(lambda phase, info: phase == "start" and passes.append(
        gc.get_freeze_count()))
    report_path = sys.argv[1]
    def record():
        report = {"enabled": gc.isenabled(), "frozen": gc.get_freeze_count(),
                  "passes": passes}
        open(report_path, "w").write(json.dumps(report))
    atexit.register(record)
"""


def in_child(body: str, tmp_path: Path, *args: str) -> dict:
    report = tmp_path / "collector.json"
    script = textwrap.dedent(RECORDER) + textwrap.dedent(body)
    done = subprocess.run([sys.executable, "-c", script, str(report), *args],
                          capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(report.read_text())


def small_file(tmp_path: Path) -> Path:
    path = tmp_path / "small.toml"
    path.write_text(campaign_toml(small_campaign("collector", 4093, [])))
    return path


CONSOLE = """
    from campaign.cli import console_main
    sys.argv = ["fdd-campaign", *sys.argv[2:]]
    passes.clear()                    # what importing the entry point collected
    console_main()
"""


def test_run_collects_nothing_until_its_kernels_are_loaded(tmp_path):
    state = in_child(CONSOLE, tmp_path, "run", str(small_file(tmp_path)), "--jobs", "2",
                     "--out", str(tmp_path / "out"), "--quiet")
    # the modules and kernels (well over 10⁵ objects) were frozen, and no pass of the
    # collector ran before that (nothing frozen yet); it is on again and ran during the
    # campaign
    assert state["frozen"] > 100_000
    assert state["passes"] and min(state["passes"]) > 100_000
    assert state["enabled"]


def test_every_other_command_has_its_collector_before_it_starts(tmp_path):
    state = in_child(CONSOLE, tmp_path, "presets")
    assert state["enabled"]
    assert state["frozen"] > 0      # what the parser's imports made, frozen


def test_a_program_that_runs_a_campaign_keeps_its_collector(tmp_path):
    state = in_child("""
        from campaign.config import load_config
        from campaign.runner import run
        run(load_config(sys.argv[2]), sys.argv[3], jobs=2, progress=False,
            log=lambda message: None)
    """, tmp_path, str(small_file(tmp_path)), str(tmp_path / "out"))
    assert state == {"enabled": True, "frozen": 0, "passes": state["passes"]}
    assert state["passes"]           # collected as usual, nothing frozen


def test_a_collector_turned_off_by_the_caller_stays_off(tmp_path):
    state = in_child("""
        from campaign.startup import defer_collection, start_up_done
        gc.disable()
        passes.clear()
        defer_collection()
        start_up_done()
    """, tmp_path)
    assert state == {"enabled": False, "frozen": 0, "passes": []}
