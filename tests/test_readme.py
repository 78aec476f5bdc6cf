"""The README's quick start runs as written (on small inputs), so it cannot rot.

Every command of the README's ``## Quick start`` code block is parsed and run through the
command line's entry point (:func:`campaign.cli.main`), in a temporary working directory,
in the block's order; each must exit 0 (``gate``: 0 or 1, its documented "exit 1 on any
false alarm") and write the files it names. ``source .venv/bin/activate`` is checked by
running one bare ``fdd-campaign`` from the PATH it gives.

Quick equivalents, so that the block runs in about a minute (the documented mapping):

* a long campaign → ``smoke`` (:data:`QUICK_CAMPAIGNS`); the flags stay (``--plant``,
  ``--out``, …);
* ``--jobs N`` → ``--jobs 1`` (the campaign's results do not depend on it);
* ``--scheduler tcp://…`` → left out (no cluster here; tests/test_dask_cluster.py);
* ``bench`` → ``bench`` on 8 runs of 20 s without the campaign (:data:`QUICK_BENCH`);
* ``RUN_ID`` → the first run id of the campaign directory's plan;
* ``results-v1/``, ``results-v2/`` (compare) → ``results/`` and ``smoke/``, two campaigns the
  block has run before;
* ``fmu build`` and the FMU campaign run only where fmpy is installed (else skipped there).

``gate`` and ``falsify`` may exit 1: their documented "a false alarm" (counted, or found by
the search), not a failure of the command.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from campaign.cli import main

README = Path(__file__).resolve().parents[1] / "README.md"

#: Long campaigns → their quick stand-in.
QUICK_CAMPAIGNS = {name: "smoke" for name in (
    "addsafe-mc", "addsafe-grid", "comb-table1", "chen-local", "chen-tables", "vanek-section5")}
#: The arguments of the quick ``bench``.
QUICK_BENCH = ["--runs", "8", "--duration", "20", "--reference-runs", "1", "--campaign", "none",
               "--no-cold", "--no-detectors"]
#: Directories standing in for compare's results-v1/ and results-v2/.
COMPARE_DIRS = {"results-v1/": "results/", "results-v2/": "smoke/"}


def _block(title: str) -> list[str]:
    """The lines of the first ```bash block after the heading *title*, continuation lines
    (ending in a backslash) joined."""
    text = README.read_text()
    start = text.index(title)
    m = re.search(r"```bash\n(.*?)```", text[start:], re.S)
    lines, current = [], ""
    for raw in m.group(1).splitlines():
        line = raw.rstrip()
        if line.endswith("\\"):
            current += line[:-1] + " "
            continue
        current += line
        if current.strip():
            lines.append(current.strip())
        current = ""
    return lines


def _quick(argv: list[str]) -> list[str]:
    """*argv* (after ``fdd-campaign``) with the quick equivalents of the module docstring."""
    out, skip = [], False
    for i, arg in enumerate(argv):
        if skip:
            skip = False
            continue
        if arg == "--scheduler":
            skip = True
            continue
        if i > 0 and argv[i - 1] == "--jobs":
            arg = "1"
        out.append(QUICK_CAMPAIGNS.get(arg, COMPARE_DIRS.get(arg, arg)))
    if out[:1] == ["bench"]:
        out = ["bench", *QUICK_BENCH]
    return out


def _named_files(argv: list[str]) -> list[Path]:
    """The files a command says it writes."""
    cmd = argv[0]
    opts = {argv[i]: argv[i + 1] for i in range(len(argv) - 1) if argv[i].startswith("--")}
    files = []
    if cmd == "run":
        files.append(Path(opts["--out"]) / "summary.parquet")
    elif cmd == "report":
        files.append(Path(argv[1]) / "report.html")
    elif cmd == "init":
        files.append(Path(argv[1]))
    elif cmd == "falsify":
        files += [Path(opts["--out"]) / "search.parquet", Path(opts["--out"]) / "worst.toml"]
    for option in ("--junit", "--plot"):
        if option in opts:
            files.append(Path(opts[option]))
    if cmd in ("simulate", "show", "fmu") and "--out" in opts:
        files.append(Path(opts["--out"]))
    return files


def test_readme_first_commands_are_two():
    """The README opens with exactly two commands: run the flagship campaign, run the tests."""
    assert len(_block("# fdd-campaign")) == 2


@pytest.mark.slow
def test_readme_quick_start_runs(tmp_path, monkeypatch, capsys):
    lines = _block("## Quick start")
    assert lines[0].startswith("source .venv/bin/activate")
    # what activating the venv gives: a bare fdd-campaign on PATH
    bindir = Path(sys.executable).parent
    env = {**os.environ, "PATH": f"{bindir}{os.pathsep}{os.environ.get('PATH', '')}"}
    exe = shutil.which("fdd-campaign", path=env["PATH"])
    assert exe is not None and Path(exe).parent == bindir
    assert subprocess.run(["fdd-campaign", "--version"], env=env, capture_output=True,
                          text=True, cwd=tmp_path).returncode == 0

    monkeypatch.chdir(tmp_path)
    has_fmpy = True
    try:
        import fmpy  # noqa: F401
    except ImportError:
        has_fmpy = False
    ran = 0
    for line in lines[1:]:
        words = shlex.split(line, comments=True)
        if not words:                  # a comment continuing the line above
            continue
        assert words[0] == "fdd-campaign", line
        argv = _quick(words[1:])
        if not has_fmpy and ("fmu" in argv[:1] or any(a.endswith(".fmu") for a in argv)):
            continue
        if "RUN_ID" in argv:
            plan = pd.read_parquet(Path(argv[1]) / "plan.parquet")
            argv[argv.index("RUN_ID")] = str(plan["run_id"].iloc[0])
        code = main(argv)
        out = capsys.readouterr()
        # gate and falsify: exit 1 is their documented "a false alarm" (found or counted)
        allowed = {0, 1} if argv[0] in ("gate", "falsify") else {0}
        assert code in allowed, f"{line!r} → fdd-campaign {' '.join(argv)}: exit {code}\n" \
                                f"{out.err[-2000:]}"
        for path in _named_files(argv):
            assert path.exists(), f"{line!r} did not write {path}"
        ran += 1
    assert ran >= 20
