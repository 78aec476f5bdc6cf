"""The mutation-testing set-up of tests/mutation/run.py stays consistent with the code
(docs/testing.md): every mutated module and mapped test file exists, and every mutant
listed as equivalent still points at the source line it was judged on."""

import importlib.util
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def _runner():
    spec = importlib.util.spec_from_file_location("mutation_run", REPO / "tests/mutation/run.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


run = _runner()


@pytest.mark.parametrize("module", sorted(run.TESTS))
def test_every_mutated_module_and_its_tests_exist(module):
    assert (REPO / module).is_file(), module
    assert run.TESTS[module], f"{module} has no test file mapped"
    for test_file in run.TESTS[module]:
        assert (REPO / test_file).is_file(), f"{module}: mapped test file {test_file} is missing"


def test_every_equivalent_mutant_points_at_its_source_line():
    entries = run.load_equivalent()
    for e in entries:
        lines = (REPO / e["module"]).read_text().splitlines()
        assert e["line"] <= len(lines), e
        assert lines[e["line"] - 1].strip() == e["code"], (
            f"{e['module']}:{e['line']} no longer reads {e['code']!r}; re-judge the mutant and "
            "update tests/mutation/equivalent.toml")
        assert e["operator"] in run.OPERATORS, e
        assert e["reason"].strip() and "\n" not in e["reason"], e
    keys = [(e["module"], e["operator"], e["line"], e["col"]) for e in entries]
    assert len(keys) == len(set(keys)), "an equivalent mutant is listed twice"


def test_the_operator_set_names_cosmic_ray_operators():
    operators = pytest.importorskip("cosmic_ray.plugins")
    known = {name.removeprefix("core/") for name in operators.operator_names()}
    assert set(run.OPERATORS) <= known, sorted(set(run.OPERATORS) - known)


def test_unknown_module_is_refused_with_exit_code_2(capsys):
    with pytest.raises(SystemExit) as exc:
        run.main(["--report", "reports/nope.py"])
    assert exc.value.code == 2
    assert "unknown module" in capsys.readouterr().err


def _session_db(path: Path, specs) -> None:
    """A cosmic-ray session (the columns run.py reads) with one pending mutant per spec
    (operator, line, col)."""
    import sqlite3

    with sqlite3.connect(path) as con:
        con.execute("create table mutation_specs (operator_name, start_pos_row, start_pos_col, "
                    "definition_name, job_id primary key)")
        con.execute("create table work_results (worker_outcome, output, test_outcome, diff, "
                    "job_id primary key)")
        for i, (op, row, col) in enumerate(specs):
            con.execute("insert into mutation_specs values (?, ?, ?, 'f', ?)",
                        (f"core/{op}", row, col, f"j{i}"))


def test_a_listed_equivalent_is_not_run_and_counts_as_equivalent(tmp_path, monkeypatch):
    """_skip_equivalents marks the pending mutants listed in equivalent.toml (same module,
    operator, line and column) as not to run; score counts each as an equivalent mutant,
    and a mutant of the same line with another operator or column still runs. One whose
    entry was dropped counts as pending and is run on the next pass."""
    import sqlite3

    e = run.load_equivalent()[0]
    monkeypatch.setattr(run, "SESSIONS", tmp_path)
    db = run._session(e["module"])
    _session_db(db, [(e["operator"], e["line"], e["col"]),
                     (e["operator"], e["line"], e["col"] + 1),
                     ("AddNot", e["line"], e["col"])])
    run._skip_equivalents(db, e["module"], [e])
    with sqlite3.connect(db) as con:
        done = con.execute("select job_id, worker_outcome, output from work_results").fetchall()
    assert done == [("j0", "SKIPPED", "equivalent")]
    s, survivors = run.score(e["module"], [e])
    assert (s.mutants, s.equivalent, s.survived, s.killed, s.pending) == (3, 1, 1, 0, 2)
    assert survivors == []
    # the entry dropped from the list (re-judged): the mutant is pending, and runs again
    s, _ = run.score(e["module"], [])
    assert (s.mutants, s.equivalent, s.pending) == (3, 0, 3)
    run._skip_equivalents(db, e["module"], [])
    with sqlite3.connect(db) as con:
        assert con.execute("select count(*) from work_results").fetchone() == (0,)
