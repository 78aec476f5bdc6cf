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
