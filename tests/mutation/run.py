"""Mutation testing of the core modules with cosmic-ray (docs/testing.md).

Usage, from the repository root, with the ``mutation`` extra installed
(``pip install -e ".[test,mutation]"``)::

    python tests/mutation/run.py                      # every core module, cheapest first
    python tests/mutation/run.py reports/scoring/metrics.py   # one or more modules
    python tests/mutation/run.py --report             # scores of the stored sessions, no run

Each module is mutated in a scratch copy of the repository, never in the checkout, so the
checkout stays usable while a run goes on. A mutant's ``@njit`` kernels are compiled from
its mutated source, never served from a stale compile cache: every test run gets a fresh
numba cache directory (``NUMBA_CACHE_DIR``), seeded from the cache the unmutated code built
without the mutated module's entries (:func:`seed_cache`; for ``scenarios/compiled.py``, whose
functions and constants every other kernel compiles in, without any entry). A cache entry is
keyed on its source file's time stamp, which a same-second rewrite of the mutated file may not
change; dropping the entries removes that risk, and the other modules' entries stay valid
because their files are never rewritten. Interpreting the kernels instead
(``NUMBA_DISABLE_JIT=1``) is 10-40 times slower on the detector tests. Only
the test files mapped to the module (:data:`TESTS`) run, with ``-x``, one mutant at a time.
Each run is forked from a server process that imported the third-party libraries once
(:data:`PRELOAD`, never a project module, so every mutant's project code is imported afresh
from its mutated source); this saves the 2-4 s an interpreter needs to import NumPy, SciPy,
pandas, numba and pytest, which is about half of a killed mutant's time.

The operator set is the usual one-alternative-per-site set (:data:`OPERATORS`): each
arithmetic operator swapped for its inverse, each comparison moved across its boundary,
each condition negated, each number literal increased by one, each boolean flipped, each
``and``/``or`` swapped, each loop made to run zero times, each ``break``/``continue``
swapped, each unary minus dropped, each ``except`` made to catch nothing. cosmic-ray's other
operators (an operator swapped for every other operator, a literal also decreased by one,
a decorator removed) multiply the count by five without finding a different kind of gap;
removing ``@njit`` only changes speed (the interpreted kernel computes the same values).

Score of a module = killed / (mutants - equivalent), where a mutant is killed when a mapped
test fails, errors or times out on it (timeout = 4 x the unmutated run + 30 s), and the
equivalent mutants are those listed, each with its one-line reason, in
``tests/mutation/equivalent.toml``. Sessions (cosmic-ray's SQLite files) are kept in
``tests/mutation/sessions/`` (not tracked); a module whose source changed is started
afresh, an unchanged one resumes where it stopped. ``--rerun-survivors`` runs the
surviving mutants again (after new tests were written). A mutant listed equivalent is not
run (a survivor costs every mapped test, often until its time-out) and counts as
equivalent; ``--run-equivalents`` runs the listed ones too, to check the list.
"""

from __future__ import annotations

import argparse
import ast
import hashlib
import importlib
import os
import select
import shutil
import signal
import socket
import sqlite3
import subprocess
import sys
import tempfile
import time
import tomllib
from dataclasses import dataclass
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
SESSIONS = HERE / "sessions"
EQUIVALENT_FILE = HERE / "equivalent.toml"

#: Module (path from the repository root) -> the test files that cover it, cheapest module
#: first. A mutant of the module is run against these files only.
TESTS: dict[str, tuple[str, ...]] = {
    "reports/scoring/metrics.py": ("tests/reports_tests/test_metrics.py",
                                   "tests/reports_tests/test_decision_boundaries.py"),
    "reports/scoring/gate.py": ("tests/reports_tests/test_summary_gate.py",
                                "tests/reports_tests/test_decision_boundaries.py"),
    "reports/scoring/summary.py": ("tests/reports_tests/test_summary_gate.py",
                                   "tests/reports_tests/test_decision_boundaries.py"),
    "scenarios/faults.py": ("tests/scenarios_tests/test_fault_injection_values.py",
                            "tests/campaign_tests/test_run_table_properties.py"),
    "scenarios/runs.py": ("tests/scenarios_tests/test_run_validation.py",
                          "tests/campaign_tests/test_run_table_properties.py",
                          "tests/scenarios_tests/test_manoeuvre_sets.py"),
    "campaign/plan.py": ("tests/campaign_tests/test_design_values.py",
                         "tests/campaign_tests/test_run_table_properties.py",
                           "tests/campaign_tests/test_config.py"),
    "detectors/calibrate.py": ("tests/detectors_tests/test_calibrate_values.py",
                               "tests/detectors_tests/test_tail_values.py",
                               "tests/detectors_tests/test_calibrate.py"),
    "detectors/builtin/chen_global_paper.py": (
        "tests/detectors_tests/test_chen_global_paper.py",),
    "detectors/tail.py": ("tests/detectors_tests/test_tail_values.py",
                          "tests/detectors_tests/test_calibrate_values.py"),
    "scenarios/aircraft/laws.py": ("tests/scenarios_tests/test_aircraft_laws_values.py",
                                   "tests/scenarios_tests/test_aircraft_truth_blind.py"),
    "scenarios/aircraft/pilot.py": ("tests/scenarios_tests/test_aircraft_pilot_values.py",
                                    "tests/scenarios_tests/test_aircraft_model.py",
                                    "tests/scenarios_tests/test_manoeuvre_sets.py"),
    "scenarios/aircraft/lpv.py": ("tests/scenarios_tests/test_aircraft_lpv_values.py",
                                  "tests/scenarios_tests/test_aircraft_data_values.py",
                                  "tests/scenarios_tests/test_aircraft_model.py"),
    "scenarios/aircraft/data.py": ("tests/scenarios_tests/test_aircraft_data_values.py",
                                   "tests/scenarios_tests/test_aircraft_lpv_values.py",
                                   "tests/scenarios_tests/test_aircraft_pilot_values.py",
                                   "tests/scenarios_tests/test_aircraft_model.py"),
    "scenarios/aircraft/loop.py": ("tests/scenarios_tests/test_aircraft_loop_values.py",
                                   "tests/scenarios_tests/test_aircraft_truth_blind.py",
                                   "tests/scenarios_tests/test_aircraft_kernel.py"),
    "scenarios/aircraft/kernel.py": ("tests/scenarios_tests/test_aircraft_loop_values.py",
                                     "tests/scenarios_tests/test_aircraft_kernel.py"),
    "campaign/evidence/certify/levels.py": (
        "tests/campaign_tests/test_certify_level_rows_values.py",
        "tests/campaign_tests/test_certify_mixture_values.py",
        "tests/campaign_tests/test_certify_levels.py"),
    "campaign/evidence/certify/rows.py": (
        "tests/campaign_tests/test_certify_rows_values.py",
        "tests/campaign_tests/test_streamed_commands.py"),
    "campaign/evidence/certify/validate.py": (
        "tests/campaign_tests/test_certify_validate_values.py",
        "tests/campaign_tests/test_certify_levels.py"),
    "campaign/evidence/certify/estimate.py": (
        "tests/campaign_tests/test_certify_estimate_values.py",
        "tests/campaign_tests/test_certify_mixture_values.py"),
    "campaign/evidence/hazard.py": ("tests/campaign_tests/test_hazard_values.py",
                                    "tests/campaign_tests/test_hazard.py"),
    "campaign/evidence/rare.py": ("tests/campaign_tests/test_rare_values.py",
                                  "tests/campaign_tests/test_rare.py"),
    "campaign/evidence/figures.py": ("tests/campaign_tests/test_figures_values.py",),
    "campaign/evidence/falsify_search.py": (
        "tests/campaign_tests/test_falsify_search_values.py",),
    "campaign/evidence/worst_case.py": ("tests/campaign_tests/test_worst_case_values.py",),
    "campaign/evidence/falsify.py": ("tests/campaign_tests/test_falsify_values.py",
                                     "tests/campaign_tests/test_falsify_against_values.py"),
    "detectors/builtin/position_monitor.py": (
        "tests/detectors_tests/test_position_monitor_values.py",
        "tests/detectors_tests/test_position_monitor_band.py",
        "tests/reports_tests/test_decision_boundaries.py",
        "tests/scenarios_tests/test_kernels.py"),
    "scenarios/servo.py": ("tests/scenarios_tests/test_servo_values.py",
                           "tests/scenarios_tests/test_kernel_values.py",
                           "tests/scenarios_tests/test_servo_physics.py",
                           "tests/scenarios_tests/test_reference_physics.py"),
    "scenarios/compiled.py": ("tests/scenarios_tests/test_kernel_values.py",
                              "tests/scenarios_tests/test_kernels.py",
                              "tests/scenarios_tests/test_kernel_cache.py"),
    "detectors/base.py": ("tests/detectors_tests/test_detector_base_values.py",
                          "tests/detectors_tests/test_fit_blocks.py",
                          "tests/reports_tests/test_decision_boundaries.py"),
    "detectors/builtin/comb_interval.py": ("tests/detectors_tests/test_comb_interval_values.py",
                                   "tests/detectors_tests/test_interval_detector.py"),
    "detectors/builtin/chen_local.py": ("tests/detectors_tests/test_chen_local_fit_values.py",
                                "tests/detectors_tests/test_chen_local_values.py",
                                "tests/detectors_tests/test_chen_estimator.py"),
    "detectors/synthesis/chen_local_model.py": (
        "tests/detectors_tests/test_chen_local_model_values.py",
        "tests/detectors_tests/test_chen_local_fit_values.py",
        "tests/detectors_tests/test_chen_local_values.py",
        "tests/detectors_tests/test_chen_estimator.py"),
    "detectors/builtin/vanek_geometric.py": ("tests/detectors_tests/test_vanek_values.py",
                                     "tests/detectors_tests/test_vanek_geometric.py"),
    "detectors/synthesis/vanek_hinf.py": ("tests/detectors_tests/test_vanek_hinf_values.py",
                                          "tests/detectors_tests/test_vanek_values.py",
                                          "tests/detectors_tests/test_vanek_geometric.py"),
    "detectors/synthesis/vanek_model_error.py": ("tests/detectors_tests/test_vanek_model_error.py",
                                       "tests/detectors_tests/test_vanek_values.py"),
    "detectors/builtin/chen_global.py": ("tests/detectors_tests/test_chen_global_values.py",
                                 "tests/detectors_tests/test_chen_global.py"),
    "detectors/builtin/chen_global_kernel.py": (
        "tests/detectors_tests/test_chen_global_kernel_values.py",
        "tests/detectors_tests/test_chen_global_values.py",
        "tests/detectors_tests/test_chen_global.py"),
}
#: cosmic-ray operators run (see the module docstring); every other operator is skipped.
OPERATORS: tuple[str, ...] = (
    "ReplaceBinaryOperator_Add_Sub", "ReplaceBinaryOperator_Sub_Add",
    "ReplaceBinaryOperator_Mul_Div", "ReplaceBinaryOperator_Div_Mul",
    "ReplaceBinaryOperator_FloorDiv_Div", "ReplaceBinaryOperator_Mod_FloorDiv",
    "ReplaceBinaryOperator_Pow_Mul",
    "ReplaceBinaryOperator_BitOr_BitAnd", "ReplaceBinaryOperator_BitAnd_BitOr",
    "ReplaceComparisonOperator_Eq_NotEq", "ReplaceComparisonOperator_NotEq_Eq",
    "ReplaceComparisonOperator_Lt_LtE", "ReplaceComparisonOperator_LtE_Lt",
    "ReplaceComparisonOperator_Gt_GtE", "ReplaceComparisonOperator_GtE_Gt",
    "ReplaceComparisonOperator_Is_IsNot", "ReplaceComparisonOperator_IsNot_Is",
    "ReplaceUnaryOperator_Delete_USub", "ReplaceUnaryOperator_Delete_Not",
    "AddNot", "ReplaceTrueWithFalse", "ReplaceFalseWithTrue",
    "ReplaceAndWithOr", "ReplaceOrWithAnd",
    "ReplaceBreakWithContinue", "ReplaceContinueWithBreak",
    "ExceptionReplacer", "NumberReplacer", "ZeroIterationForLoop",
)

COPY_IGNORE = shutil.ignore_patterns(".venv", ".git", "__pycache__", "*.egg-info", "sessions",
                                     ".hypothesis", ".pytest_cache", "results*", "build", "dist")


#: Third-party modules the fork server imports once (docs/testing.md); project modules never.
PRELOAD: tuple[str, ...] = (
    "numpy", "scipy.stats", "scipy.signal", "scipy.linalg", "scipy.optimize", "scipy.special",
    "pandas", "pyarrow", "pyarrow.parquet", "numba", "joblib", "pytest", "hypothesis",
    "hypothesis.extra.numpy",
)
PROJECT = ("campaign", "scenarios", "detectors", "reports")
#: The unmutated code's numba cache, inside the scratch copy.
NUMBA_BASE = ".numba-base"


@dataclass
class Score:
    """Outcome counts of one module's session."""

    module: str
    mutants: int = 0
    killed: int = 0
    timeout: int = 0
    survived: int = 0
    pending: int = 0
    equivalent: int = 0

    @property
    def counted(self) -> int:
        """Non-equivalent mutants with an outcome."""
        return self.killed + self.timeout + self.survived - self.equivalent

    @property
    def score(self) -> float:
        """Killed share of the non-equivalent mutants, in percent (nan before any outcome)."""
        return 100.0 * (self.killed + self.timeout) / self.counted if self.counted else float("nan")


def _fail(message: str) -> None:
    print(f"mutation: {message}", file=sys.stderr)
    raise SystemExit(2)


def load_equivalent(path: Path = EQUIVALENT_FILE) -> list[dict]:
    """The equivalent-mutant list: entries with module, operator, line, col, code, reason."""
    entries = tomllib.loads(path.read_text()).get("equivalent", []) if path.exists() else []
    keys = {"module", "operator", "line", "col", "code", "reason"}
    for i, entry in enumerate(entries):
        if set(entry) != keys:
            _fail(f"{path.name} entry {i + 1} has keys {sorted(entry)}; it needs exactly "
                  f"{sorted(keys)}")
        if entry["module"] not in TESTS:
            _fail(f"{path.name} entry {i + 1}: module {entry['module']!r} is not a mutated "
                  f"module; use one of {sorted(TESTS)}")
    return entries


def _session(module: str) -> Path:
    return SESSIONS / (module.replace("/", "__").removesuffix(".py") + ".sqlite")


def _source_hash(module: str) -> str:
    return hashlib.sha256((REPO / module).read_bytes()).hexdigest()


#: Modules whose ``@njit`` functions or constants other modules' kernels compile in: a
#: mutant of one of them invalidates every cache entry, not only its own.
SHARED_KERNEL_MODULES = ("scenarios/compiled.py",)


def seed_cache(base: Path, target: Path, module: str) -> None:
    """Fill the empty numba cache directory ``target`` from ``base`` (the unmutated code's
    cache), leaving out every entry ``module``'s mutant can invalidate."""
    if module in SHARED_KERNEL_MODULES or not base.exists():
        return
    stem = Path(module).stem + "."
    shutil.copytree(base, target, dirs_exist_ok=True,
                    ignore=lambda _, names: [n for n in names if n.startswith(stem)])


def _child_cache(base: Path, module: str) -> Path:
    """A fresh numba cache directory for one test run of ``module``'s mutant, made active in
    this (forked) process."""
    import numba.core.config

    target = Path(tempfile.mkdtemp(prefix="numba-", dir=base.parent))
    seed_cache(base, target, module)
    os.environ["NUMBA_CACHE_DIR"] = str(target)
    numba.core.config.reload_config()
    return target


def _pytest_args(module: str) -> list[str]:
    return ["-x", "-q", "-p", "no:cacheprovider", *TESTS[module]]


def _test_command(module: str, sock: Path) -> str:
    return f"{sys.executable} {Path(__file__).resolve()} --client {sock} {module} " + " ".join(
        _pytest_args(module))


def serve(sock: Path, scratch: Path) -> None:
    """Fork server: import :data:`PRELOAD`, then for each client request fork a child that
    runs pytest in ``scratch`` and send back its exit code. A client that goes away (the
    mutant's timeout) takes its child with it."""
    os.chdir(scratch)
    for name in PRELOAD:
        try:
            importlib.import_module(name)
        except ImportError:
            pass
    leaked = sorted(m for m in sys.modules if m.split(".")[0] in PROJECT)
    if leaked:
        raise RuntimeError(f"the fork server imported project modules {leaked}")
    child = {"pid": 0}

    def stop(*_):
        # the test run in flight goes with the server (its own session: kill its group)
        if child["pid"]:
            os.killpg(child["pid"], signal.SIGKILL)
        os._exit(0)

    signal.signal(signal.SIGTERM, stop)
    server = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    server.bind(str(sock))
    server.listen(1)
    while True:
        conn, _ = server.accept()
        with conn:
            module, *args = conn.makefile().readline().split()
            pid = os.fork()
            if pid == 0:
                signal.signal(signal.SIGTERM, signal.SIG_DFL)
                server.close()
                os.setsid()
                null = os.open(os.devnull, os.O_WRONLY)
                os.dup2(null, 1)
                os.dup2(null, 2)
                cache = _child_cache(scratch / NUMBA_BASE, module)
                import pytest
                code = pytest.main(args)
                shutil.rmtree(cache, ignore_errors=True)
                os._exit(int(code))
            child["pid"] = pid
            rc = None
            while rc is None:
                done, status = os.waitpid(pid, os.WNOHANG)
                if done:
                    rc = os.waitstatus_to_exitcode(status)
                    break
                readable, _, _ = select.select([conn], [], [], 0.2)
                if readable and not conn.recv(1, socket.MSG_PEEK):
                    os.killpg(pid, signal.SIGKILL)
                    os.waitpid(pid, 0)
                    rc = -9
            child["pid"] = 0
            try:
                conn.sendall(f"{rc}\n".encode())
            except OSError:
                pass


def client(sock: Path, args: list[str]) -> int:
    """Ask the fork server to run pytest on a mutant of ``args[0]`` (a module) with the
    pytest arguments ``args[1:]``; its exit code (1 when none)."""
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as conn:
        conn.connect(str(sock))
        conn.sendall((" ".join(args) + "\n").encode())
        reply = conn.makefile().readline().strip()
    return int(reply) if reply.lstrip("-").isdigit() else 1


def _environment(scratch: Path) -> dict[str, str]:
    env = dict(os.environ)
    env.pop("NUMBA_DISABLE_JIT", None)
    env.update(PYTHONDONTWRITEBYTECODE="1", PYTHONPATH=str(scratch), PYTHONHASHSEED="0",
               NUMBA_CACHE_DIR=str(scratch / NUMBA_BASE))
    return env


def _write_config(path: Path, module: str, sock: Path, timeout: float) -> None:
    kept = "|".join(OPERATORS)
    path.write_text(
        "[cosmic-ray]\n"
        f'module-path = "{module}"\n'
        f"timeout = {timeout:.0f}\n"
        "excluded-modules = []\n"
        f'test-command = "{_test_command(module, sock)}"\n\n'
        "[cosmic-ray.distributor]\n"
        'name = "local"\n\n'
        "[cosmic-ray.filters.operators-filter]\n"
        f"exclude-operators = ['core/(?!(?:{kept})$)']\n")


def _skip_second_number_offsets(db: Path) -> None:
    """Keep one NumberReplacer mutant (+1) per literal: cosmic-ray makes two (+1, -1)."""
    with sqlite3.connect(db) as con:
        rows = con.execute(
            "select job_id, start_pos_row, start_pos_col, occurrence from mutation_specs "
            "where operator_name = 'core/NumberReplacer' order by occurrence").fetchall()
        seen = set()
        for job_id, row, col, _ in rows:
            if (row, col) in seen:
                con.execute("insert or replace into work_results (worker_outcome, output, "
                            "test_outcome, diff, job_id) values ('SKIPPED', 'second offset', "
                            "NULL, '', ?)", (job_id,))
            seen.add((row, col))


def annotation_spans(source: str) -> list[tuple[tuple[int, int], tuple[int, int]]]:
    """(start, end) positions (line 1-based, column 0-based in characters, as cosmic-ray
    reports them) of every annotation of a module that has ``from __future__ import
    annotations``; none otherwise. Under that import (PEP 563) an annotation is a string
    never evaluated at run time, so a mutant inside one cannot change behaviour."""
    tree = ast.parse(source)
    future = any(isinstance(node, ast.ImportFrom) and node.module == "__future__"
                 and any(a.name == "annotations" for a in node.names) for node in tree.body)
    if not future:
        return []
    lines = source.splitlines()

    def char_col(line: int, byte_col: int) -> int:
        return len(lines[line - 1].encode()[:byte_col].decode())

    spans = []
    for node in ast.walk(tree):
        notes = []
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            args = node.args
            notes = [a.annotation for a in (*args.posonlyargs, *args.args, *args.kwonlyargs,
                                            args.vararg, args.kwarg) if a is not None]
            notes.append(node.returns)
        elif isinstance(node, ast.AnnAssign):
            notes = [node.annotation]
        spans += [((n.lineno, char_col(n.lineno, n.col_offset)),
                   (n.end_lineno, char_col(n.end_lineno, n.end_col_offset)))
                  for n in notes if n is not None]
    return spans


def _skip_annotations(db: Path, module: str) -> None:
    """Mark the not yet run mutants inside annotations (:func:`annotation_spans`) skipped."""
    spans = annotation_spans((REPO / module).read_text())
    with sqlite3.connect(db) as con:
        rows = con.execute(
            "select s.job_id, s.start_pos_row, s.start_pos_col from mutation_specs s left join "
            "work_results r on s.job_id = r.job_id where r.job_id is null").fetchall()
        for job_id, row, col in rows:
            if any(start <= (row, col) < end for start, end in spans):
                con.execute("insert into work_results (worker_outcome, output, test_outcome, "
                            "diff, job_id) values ('SKIPPED', 'annotation', NULL, '', ?)",
                            (job_id,))


def _listed(equivalent: list[dict], module: str) -> set[tuple[str, int, int]]:
    """(operator, line, col) of the mutants of *module* listed in *equivalent*."""
    return {(e["operator"], e["line"], e["col"]) for e in equivalent if e["module"] == module}


def _skip_equivalents(db: Path, module: str, equivalent: list[dict]) -> None:
    """Mark the not yet run mutants listed equivalent (:data:`EQUIVALENT_FILE`, matched on
    operator, line and column of the unchanged source) skipped: each entry's reason says why
    no test can tell it from the original, so running it only costs a full pass of the
    mapped tests (a survivor runs every test, and often until its time-out). :func:`score`
    counts them as equivalent; ``--run-equivalents`` runs them instead, to check the list."""
    listed = _listed(equivalent, module)
    with sqlite3.connect(db) as con:
        # skipped as equivalent before, no longer listed: to run again
        for job_id, op, row, col in con.execute(
                "select s.job_id, s.operator_name, s.start_pos_row, s.start_pos_col from "
                "mutation_specs s join work_results r on s.job_id = r.job_id where "
                "upper(r.worker_outcome) = 'SKIPPED' and r.output = 'equivalent'").fetchall():
            if (op.removeprefix("core/"), row, col) not in listed:
                con.execute("delete from work_results where job_id = ?", (job_id,))
        rows = con.execute(
            "select s.job_id, s.operator_name, s.start_pos_row, s.start_pos_col from "
            "mutation_specs s left join work_results r on s.job_id = r.job_id "
            "where r.job_id is null").fetchall()
        for job_id, op, row, col in rows:
            if (op.removeprefix("core/"), row, col) in listed:
                con.execute("insert into work_results (worker_outcome, output, test_outcome, "
                            "diff, job_id) values ('SKIPPED', 'equivalent', NULL, '', ?)",
                            (job_id,))


def run_module(module: str, scratch: Path, sock: Path, rerun_survivors: bool,
               run_equivalents: bool = False) -> None:
    """Run (or resume) the cosmic-ray session of ``module`` in ``scratch``."""
    env = _environment(scratch)
    db, stamp = _session(module), _session(module).with_suffix(".sha256")
    config = scratch / "cosmic-ray.toml"
    # the unmutated run fills the base cache; the timed one runs as a mutant's will
    baseline = subprocess.run([sys.executable, "-m", "pytest", *_pytest_args(module)],
                              cwd=scratch, env=env, capture_output=True, text=True)
    if baseline.returncode != 0:
        _fail(f"the tests of {module} fail on the unmutated code, fix them first:\n"
              + baseline.stdout[-3000:])
    started = time.monotonic()
    client(sock, [module, *_pytest_args(module)])
    took = time.monotonic() - started
    _write_config(config, module, sock, timeout=4 * took + 30)
    fresh = not db.exists() or not stamp.exists() or stamp.read_text() != _source_hash(module)
    if fresh:
        db.unlink(missing_ok=True)
        subprocess.run(["cosmic-ray", "init", str(config), str(db)], cwd=scratch, env=env,
                       check=True)
        subprocess.run(["cr-filter-operators", str(db), str(config)], cwd=scratch, env=env,
                       check=True)
        _skip_second_number_offsets(db)
        stamp.write_text(_source_hash(module))
    elif rerun_survivors:
        with sqlite3.connect(db) as con:
            con.execute("delete from work_results where upper(test_outcome) = 'SURVIVED' "
                        "and upper(worker_outcome) != 'SKIPPED'")
    _skip_annotations(db, module)
    if run_equivalents:
        with sqlite3.connect(db) as con:
            con.execute("delete from work_results where upper(worker_outcome) = 'SKIPPED' "
                        "and output = 'equivalent'")
    else:
        _skip_equivalents(db, module, load_equivalent())
    print(f"mutation: {module}: tests {' '.join(TESTS[module])} "
          f"({took:.0f} s unmutated)", flush=True)
    subprocess.run(["cosmic-ray", "exec", str(config), str(db)], cwd=scratch, env=env, check=True)


def score(module: str, equivalent: list[dict]) -> tuple[Score, list[tuple]]:
    """Counts of ``module``'s session and its surviving, non-equivalent mutants."""
    result, survivors = Score(module), []
    db = _session(module)
    if not db.exists():
        return result, survivors
    source = (REPO / module).read_text()
    lines = source.splitlines()
    spans = annotation_spans(source)
    eq = _listed(equivalent, module)
    with sqlite3.connect(db) as con:
        rows = con.execute(
            "select s.operator_name, s.start_pos_row, s.start_pos_col, s.definition_name, "
            "r.worker_outcome, r.test_outcome, r.output, r.diff from mutation_specs s left join "
            "work_results r on s.job_id = r.job_id").fetchall()
    for op, row, col, name, worker, test, output, diff in rows:
        worker, test = (worker or "").lower() or None, (test or "").lower()
        listed = (op.removeprefix("core/"), row, col) in eq
        if worker == "skipped" and output == "equivalent":
            result.mutants += 1         # listed equivalent, not run (_skip_equivalents)
            if listed:
                result.survived += 1
                result.equivalent += 1
            else:                       # no longer listed: run on the next pass
                result.pending += 1
            continue
        if worker == "skipped" or any(a <= (row, col) < b for a, b in spans):
            continue
        result.mutants += 1
        if worker is None:
            result.pending += 1
        elif test == "killed" and output == "timeout":
            result.timeout += 1
        elif test in ("killed", "incompetent"):
            result.killed += 1
        else:
            result.survived += 1
            if listed:
                result.equivalent += 1
            else:
                survivors.append((module, row, col, op.removeprefix("core/"), name,
                                  lines[row - 1].strip() if row <= len(lines) else "", diff))
    return result, survivors


def report(modules: list[str], show_survivors: bool) -> list[Score]:
    """Print the per-module and overall scores; return them."""
    equivalent = load_equivalent()
    scores, total = [], Score("overall")
    print(f"{'module':34s} {'mutants':>7s} {'killed':>6s} {'timeout':>7s} {'survived':>8s} "
          f"{'equiv.':>6s} {'pending':>7s} {'score':>7s}")
    for module in modules:
        s, survivors = score(module, equivalent)
        scores.append(s)
        for field in ("mutants", "killed", "timeout", "survived", "pending", "equivalent"):
            setattr(total, field, getattr(total, field) + getattr(s, field))
        print(f"{module:34s} {s.mutants:7d} {s.killed:6d} {s.timeout:7d} {s.survived:8d} "
              f"{s.equivalent:6d} {s.pending:7d} {s.score:6.1f}%")
        if show_survivors:
            for _, row, col, op, name, code, diff in survivors:
                print(f"    survived {module}:{row}:{col} {op} in {name}: {code}")
    print(f"{'overall':34s} {total.mutants:7d} {total.killed:6d} {total.timeout:7d} "
          f"{total.survived:8d} {total.equivalent:6d} {total.pending:7d} {total.score:6.1f}%")
    for e in equivalent:
        lines = (REPO / e["module"]).read_text().splitlines()
        if e["line"] > len(lines) or lines[e["line"] - 1].strip() != e["code"]:
            print(f"mutation: stale equivalent entry {e['module']}:{e['line']} ({e['code']!r}); "
                  f"the source moved, update tests/mutation/equivalent.toml", file=sys.stderr)
    return scores


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--serve"]:
        serve(Path(argv[1]), Path(argv[2]))
        return 0
    if argv[:1] == ["--client"]:
        return client(Path(argv[1]), argv[2:])
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("modules", nargs="*", metavar="MODULE",
                        help=f"modules to mutate (default: all, in this order: {', '.join(TESTS)})")
    parser.add_argument("--report", action="store_true",
                        help="print the stored scores, run nothing")
    parser.add_argument("--survivors", action="store_true", help="list the surviving mutants")
    parser.add_argument("--rerun-survivors", action="store_true",
                        help="run the surviving mutants of an unchanged module again")
    parser.add_argument("--run-equivalents", action="store_true",
                        help="run the mutants listed in equivalent.toml too (by default they "
                             "are skipped and counted as equivalent)")
    parser.add_argument("--fail-under", type=float, default=None, metavar="PERCENT",
                        help="exit 1 when a module scores below PERCENT")
    args = parser.parse_args(argv)
    modules = args.modules or list(TESTS)
    unknown = [m for m in modules if m not in TESTS]
    if unknown:
        _fail(f"unknown module(s) {unknown}; mutated modules are {list(TESTS)}")
    load_equivalent()
    if not args.report:
        if shutil.which("cosmic-ray") is None:
            _fail('cosmic-ray is not installed; install the extra: pip install -e ".[mutation]"')
        SESSIONS.mkdir(exist_ok=True)
        # a terminated run still removes its scratch copy and stops its fork server
        signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
        with tempfile.TemporaryDirectory(prefix="fdd-mutation-") as tmp:
            scratch = Path(tmp) / "repo"
            shutil.copytree(REPO, scratch, ignore=COPY_IGNORE)
            sock = Path(tmp) / "fork-server.sock"
            server = subprocess.Popen([sys.executable, __file__, "--serve", str(sock),
                                       str(scratch)],
                                      cwd=scratch, env=_environment(scratch))
            try:
                while not sock.exists():
                    if server.poll() is not None:
                        _fail("the fork server stopped before it listened")
                    time.sleep(0.1)
                for module in modules:
                    run_module(module, scratch, sock, args.rerun_survivors,
                               args.run_equivalents)
            finally:
                server.terminate()
                server.wait()
    scores = report(modules, args.survivors)
    if args.fail_under is not None and any(s.score < args.fail_under for s in scores):
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
