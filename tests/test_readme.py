"""The README's quick start runs as written (on small inputs), so it cannot rot.

Every command of the README's ``## Quick start`` code block is parsed and run through the
command line's entry point (:func:`campaign.cli.commands.main`), in a temporary working directory,
in the block's order; each must exit 0 (``gate``: 0 or 1, its documented "exit 1 on any
false alarm") and write the files it names. ``source .venv/bin/activate`` is checked by
running one bare ``fdd-campaign`` from the PATH it gives.

Quick equivalents, so that the block runs in about a minute (the documented mapping):

* a study that runs campaigns → the same with fewer runs (:data:`QUICK_STUDIES`);
* a long campaign → ``smoke`` (:data:`QUICK_CAMPAIGNS`); the flags stay (``--plant``,
  ``--out``, …);
* ``--jobs N`` → ``--jobs 1`` (the campaign's results do not depend on it);
* ``--worst-case N`` → ``--worst-case 40`` (the gate's worst-case searches, on smoke);
* ``--scheduler tcp://…`` → left out (no cluster here; tests/campaign_tests/test_dask_cluster.py);
* ``bench`` → ``bench`` on 8 runs of 20 s without the campaign (:data:`QUICK_BENCH`);
* ``RUN_ID`` → the first run id of the campaign directory's plan;
* ``results-v1/``, ``results-v2/`` (compare) → ``results/`` and ``smoke/``, two campaigns the
  block has run before;
* ``fmu build`` and the FMU campaign run only where fmpy is installed (else skipped there).

``gate`` and ``falsify`` may exit 1: their documented "a false alarm" (counted, or found by
the search), not a failure of the command.

What the quick start's commands print as the next command to run (``next: …``, ``run it
with: …``, ``replay: …``) runs as printed, one hint of each shape, in the directories the
block made (a hint of a shape the block ran itself, in another of its directories, is not
run again); so does the example of every ``--help`` (its quick equivalent as above, with
``falsify --budget 40`` and ``certify --sampling 60``).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import re
import shlex
import shutil
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd
import pytest

from campaign.cli.commands import build_parser, main

README = Path(__file__).resolve().parents[1] / "README.md"

#: Long campaigns → their quick stand-in.
QUICK_CAMPAIGNS = {name: "smoke" for name in (
    "addsafe-mc", "addsafe-grid", "comb-table1", "chen-local", "chen-tables", "vanek-section5")}
#: The arguments of the quick ``bench``.
QUICK_BENCH = ["--runs", "8", "--duration", "20", "--reference-runs", "1", "--campaign", "none",
               "--no-cold", "--no-detectors"]
#: Quick equivalents of the studies that run campaigns: arguments appended to the example
#: (a repeated option's last value wins), each a smaller campaign of the same kind.
QUICK_STUDIES = {
    "chen-flight-data": ["--levels", "0.02", "--fault-free", "1", "--disconnections", "2",
                         "--learning-runs", "2"],
    "vanek-jam-limit": ["--learning-runs", "3"],
    "saturation": ["--runs", "5"],
}
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
        if i > 0 and argv[i - 1] == "--worst-case":
            arg = "40"
        out.append(QUICK_CAMPAIGNS.get(arg, COMPARE_DIRS.get(arg, arg)))
    if out[:1] == ["bench"]:
        out = ["bench", *QUICK_BENCH]
    if out[:1] == ["study"] and len(out) > 1:
        out += QUICK_STUDIES.get(out[1], [])
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


@dataclass
class Ran:
    """One command run: the line it came from, the argv run, its exit code and output."""

    line: str
    argv: list[str]
    code: int
    out: str
    err: str


@dataclass
class QuickStart:
    """The quick start run once in a fresh working directory (:func:`quick_start`)."""

    root: Path
    ran: list[Ran] = field(default_factory=list)
    has_fmpy: bool = True


def _call(argv: list[str], line: str) -> Ran:
    """Run ``fdd-campaign ARGV`` through the entry point, its output captured."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    return Ran(line, argv, code, out.getvalue(), err.getvalue())


def _skipped(argv: list[str], has_fmpy: bool) -> bool:
    """Whether *argv* needs fmpy, or the [jsbsim] extra, where it is not installed."""
    import importlib.util

    if "jsbsim" in argv and importlib.util.find_spec("jsbsim") is None:
        return True
    return not has_fmpy and ("fmu" in argv[:1] or any(a.endswith(".fmu") for a in argv))


def _with_run_id(argv: list[str]) -> list[str]:
    """*argv* with ``RUN_ID`` replaced by the first run id of the directory's plan."""
    if "RUN_ID" in argv:
        plan = pd.read_parquet(Path(argv[1]) / "plan.parquet")
        argv[argv.index("RUN_ID")] = str(plan["run_id"].iloc[0])
    return argv


def _check(ran: Ran) -> None:
    """The command exited as documented and wrote the files it names."""
    # gate and falsify: exit 1 is their documented "a false alarm" (found or counted)
    allowed = {0, 1} if ran.argv[0] in ("gate", "falsify") else {0}
    assert ran.code in allowed, (f"{ran.line!r} → fdd-campaign {' '.join(ran.argv)}: exit "
                                 f"{ran.code}\n{ran.err[-2000:]}")
    for path in _named_files(ran.argv):
        assert path.exists(), f"{ran.line!r} did not write {path}"


@pytest.fixture(scope="module")
def quick_start(tmp_path_factory) -> QuickStart:
    """Every command of the quick start, in order, in a fresh working directory."""
    root = tmp_path_factory.mktemp("readme")
    state = QuickStart(root)
    try:
        import fmpy  # noqa: F401
    except ImportError:
        state.has_fmpy = False
    with contextlib.chdir(root):
        for line in _block("## Quick start")[1:]:
            words = shlex.split(line, comments=True)
            if not words:                  # a comment continuing the line above
                continue
            assert words[0] == "fdd-campaign", line
            argv = _quick(words[1:])
            if not _skipped(argv, state.has_fmpy):
                state.ran.append(_call(_with_run_id(argv), line))
    return state


@pytest.mark.slow
def test_readme_quick_start_runs(quick_start, tmp_path):
    lines = _block("## Quick start")
    assert lines[0].startswith("source .venv/bin/activate")
    # what activating the venv gives: a bare fdd-campaign on PATH
    bindir = Path(sys.executable).parent
    env = {**os.environ, "PATH": f"{bindir}{os.pathsep}{os.environ.get('PATH', '')}"}
    exe = shutil.which("fdd-campaign", path=env["PATH"])
    assert exe is not None and Path(exe).parent == bindir
    assert subprocess.run(["fdd-campaign", "--version"], env=env, capture_output=True,
                          text=True, cwd=tmp_path).returncode == 0
    with contextlib.chdir(quick_start.root):
        for ran in quick_start.ran:
            _check(ran)
            # paths are printed normalised (the README's directories end in "/")
            doubled = re.search(r"(?<!:)//\S*", ran.out + ran.err)
            assert doubled is None, f"{ran.line!r} printed {doubled.group(0)!r}"
    assert len(quick_start.ran) >= 20


#: A command printed as a hint: ``fdd-campaign`` and the words after it (a word is a name, a
#: path or an option; a hint ends at a comma, a semicolon, a bracket or the end of the line).
HINT = re.compile(r"fdd-campaign(?: (?!or\b|then\b|and\b)[\w./:=@+-]+)+")


def _hints(text: str) -> list[str]:
    """The commands *text* suggests (``next: …``, ``run it with: …``, ``replay: …``)."""
    return [m.group(0).rstrip(".") for m in HINT.finditer(text)
            if len(m.group(0).split()) > 2]


def _shape(hint: str, root: Path) -> str:
    """*hint* with its directories (those under *root*, and an output directory ``--out
    NAME/`` yet to be made) and run ids replaced by placeholders: hints of one shape differ
    only in the campaign they name, and one of each is run."""
    words = hint.split()[1:]
    for i, word in enumerate(words):
        if re.fullmatch(r"[0-9a-f]{20}", word):
            words[i] = "RUN_ID"
        elif ((root / word).is_dir() or (words[i - 1:i] == ["--out"] and word.endswith("/"))) \
                and not (i == 1 and words[0] in ("run", "plan")):
            words[i] = "DIR"         # (run and plan take a campaign there, e.g. smoke)
    return " ".join(words)


@pytest.mark.slow
def test_every_hint_of_the_quick_start_runs_as_printed(quick_start):
    """Each command the quick start's commands print as a suggestion (one of each shape) runs
    as printed, in the directories they made."""
    shapes: dict[str, tuple[str, str]] = {}
    for ran in quick_start.ran:
        for hint in _hints(ran.out):
            shapes.setdefault(_shape(hint, quick_start.root), (hint, ran.line))
    # the hints of run, init, gate, falsify and fmu build
    expected = {"gate DIR --junit gate.xml", "report DIR", "gate DIR --all-requirements",
                "plan my-campaign.toml --out DIR", "run my-campaign.toml --out DIR",
                "run falsify/worst.toml --out DIR", "gate DIR"}
    if quick_start.has_fmpy:
        expected.add("run smoke --plant servo.fmu --out DIR")
    assert expected <= set(shapes), sorted(shapes)
    # a hint of a shape the quick start ran itself (another of its directories) is not
    # run again
    ran = {_shape(f"fdd-campaign {' '.join(r.argv)}", quick_start.root)
           for r in quick_start.ran if r.code == 0}
    with contextlib.chdir(quick_start.root):
        for hint, line in shapes.values():
            argv = shlex.split(hint)[1:]
            assert "results/" not in argv[2:] or argv[0] != "run", \
                f"{line!r} suggests running into results/, which the README's first command filled"
            if _skipped(argv, quick_start.has_fmpy) or _shape(hint, quick_start.root) in ran:
                continue
            _check(_call(argv, f"{hint} (printed by {line})"))


def _help_examples() -> list[str]:
    """The example of every sub-command's --help and of the top-level --help."""
    parser = build_parser()
    texts = [parser.epilog]

    def walk(p):
        for action in p._actions:
            if isinstance(action, argparse._SubParsersAction):
                for sub in action.choices.values():
                    texts.append(sub.epilog or "")
                    walk(sub)
    walk(parser)
    lines = []
    for text in texts:
        for line in text.replace("\\\n", " ").splitlines():
            line = line.strip()
            if line.startswith("fdd-campaign "):
                lines.append(" ".join(line.split()))
    return lines


#: Quick equivalents of the help examples' long options (beside :func:`_quick`).
QUICK_OPTIONS = {"--budget": "40", "--sampling": "60"}


@pytest.mark.slow
def test_every_help_example_runs_as_printed(quick_start):
    """The example of every ``--help`` runs (its quick equivalent: :func:`_quick`, a smaller
    falsify budget and certify sample) in the directories the quick start made."""
    examples = _help_examples()
    assert len(examples) >= 16
    readme = {" ".join(shlex.split(x, comments=True)) for x in _block("## Quick start")}
    ran = set()
    with contextlib.chdir(quick_start.root):
        for example in examples:
            if example in readme:          # run by the quick start already
                continue
            argv = _quick(shlex.split(example)[1:])
            argv = [QUICK_OPTIONS.get(argv[i - 1], a) if i else a for i, a in enumerate(argv)]
            if _skipped(argv, quick_start.has_fmpy):
                continue
            _check(_call(_with_run_id(argv), example))
            ran.add(argv[0])
    # the examples the quick start does not show as they are
    assert {"plan", "show", "verify", "gate", "init", "bench", "falsify", "certify"} <= ran


def _python_block(after: str) -> str:
    """The first ```python block of the README after the text *after*."""
    text = README.read_text()
    return re.search(r"```python\n(.*?)```", text[text.index(after):], re.S).group(1)


@pytest.mark.slow
def test_the_readme_python_example_runs_as_written(tmp_path, capsys):
    """The README's Python lines run as written (smoke is small already): ``campaign.run``
    returns the campaign, ``campaign.load`` reads the same one back, and what they print is
    the object's repr and the summary table."""
    namespace: dict = {}
    with contextlib.chdir(tmp_path):
        exec(compile(_python_block("From Python:"), str(README), "exec"), namespace)
    result, again, rows = namespace["result"], namespace["again"], namespace["rows"]
    assert again == result and again.root == Path("smoke-out")
    assert (tmp_path / "smoke-out" / "summary.parquet").exists()
    printed = capsys.readouterr().out
    assert printed.startswith(repr(result) + "\n" + result.table())
    # smoke: 20 runs, each scored by its one detector
    assert rows["run_id"].nunique() == len(result.plan) == 20 and len(rows) == 20
