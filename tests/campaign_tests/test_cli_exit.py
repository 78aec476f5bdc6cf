"""The executable leaves without the interpreter's teardown only when nothing is lost by it
(campaign/cli/commands.py, ``leave``; docs/execution.md, "Leaving the process"): the exit
code is kept, the exit handlers run, the standard streams are flushed, and a thread still
working is waited for as by a normal exit."""

from __future__ import annotations

import subprocess
import sys
import textwrap
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def leave_in_child(body: str, tmp_path: Path) -> subprocess.CompletedProcess:
    script = textwrap.dedent(f"""
        import atexit, sys, threading, time
        from pathlib import Path
        from campaign.cli.commands import leave
        out = Path({str(tmp_path)!r})
    """) + textwrap.dedent(body)
    return subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          cwd=ROOT, timeout=60)


def test_the_code_the_handlers_and_the_buffered_output_survive(tmp_path):
    done = leave_in_child("""
        atexit.register(lambda: (out / "handler").write_text("ran"))
        sys.stdout.write("x" * 100_000)          # more than a pipe's buffer, not flushed
        sys.stderr.write("last words")
        leave(3)
    """, tmp_path)
    assert done.returncode == 3
    assert (tmp_path / "handler").read_text() == "ran"
    assert done.stdout == "x" * 100_000
    assert done.stderr == "last words"


def test_a_thread_still_working_is_waited_for(tmp_path):
    # a non-daemon thread: the normal exit joins it; os._exit would have killed it
    done = leave_in_child("""
        def work():
            time.sleep(0.5)
            (out / "thread").write_text("finished")
        threading.Thread(target=work).start()
        leave(0)
    """, tmp_path)
    assert done.returncode == 0
    assert (tmp_path / "thread").read_text() == "finished"


def test_the_executable_is_the_one_that_leaves():
    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    assert scripts["fdd-campaign"] == "campaign.cli:console_main"


def test_a_reader_that_leaves_early_does_not_change_the_exit_code(tmp_path):
    """``fdd-campaign run smoke | head -1``, then ``gate … | head -1``: the reader closes the
    pipe after one line; the command still finishes (the directory complete, the gate's
    verdict taken) and exits with its own status, not 2 with an error about a path."""
    out = tmp_path / "smoke"
    for argv in (["run", "smoke", "--out", str(out)], ["gate", str(out), "--max-fa", "0"]):
        proc = subprocess.Popen([sys.executable, "-m", "campaign.cli", *argv],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        first = proc.stdout.readline()
        proc.stdout.close()                      # the reader leaves, as head -1 does
        err = proc.stderr.read().decode()
        proc.wait(timeout=300)
        assert first, argv
        assert "Broken pipe" not in err and "cannot access" not in err, err
        assert proc.returncode == 0, err         # smoke has no false alarm: both pass
    assert (out / "summary.parquet").exists()
