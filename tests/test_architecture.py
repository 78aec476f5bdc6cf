"""The architecture as rules a change cannot break silently (docs/design.md §2): imports
flow one way with no cycle (also inside functions), no private name crosses a module, every
citation of the physics and design documents points to a section that exists in the
repository, the tree of docs/design.md §2 is the tree on disk, and campaign/ keeps its
modules in subpackages."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGES = ("campaign", "scenarios", "detectors", "reports")
#: Which package may import which (docs/design.md §2).
MAY_IMPORT = {
    "campaign": {"campaign", "scenarios", "detectors", "reports"},
    "detectors": {"detectors", "scenarios", "reports"},
    "scenarios": {"scenarios"},
    "reports": {"reports"},
}
#: The one module every package may import besides those: the base of the input errors
#: (:class:`scenarios.errors.InputError`), which imports nothing of the project.
SHARED = {"scenarios.errors"}


def _modules() -> dict[str, Path]:
    mods = {}
    for pkg in PACKAGES:
        for path in sorted((REPO / pkg).rglob("*.py")):
            name = ".".join(path.relative_to(REPO).with_suffix("").parts)
            mods[name.removesuffix(".__init__")] = path
    return mods


MODULES = _modules()


def _imports(name: str, path: Path) -> list[tuple[str, str | None, int]]:
    """(imported module, imported name or None, line) of every import in *path*, resolved to
    the project's modules (function-local imports included)."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            targets = [(alias.name, None) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            targets = [(f"{module}.{a.name}", None) if f"{module}.{a.name}" in MODULES
                       else (module, a.name) for a in node.names]
        else:
            continue
        for target, attr in targets:
            parts = target.split(".")
            while parts and ".".join(parts) not in MODULES:
                parts.pop()
            if parts and ".".join(parts) != name:
                out.append((".".join(parts), attr, node.lineno))
    return out


GRAPH = {name: _imports(name, path) for name, path in MODULES.items()}


def _cycles() -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in {t for t, _, _ in GRAPH[v]}:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in GRAPH:
        if v not in index:
            visit(v)
    return found


def test_the_checker_sees_function_local_and_relative_imports():
    # the runner imports the execution module inside a function; the simulator imports the
    # run-row module relatively: both must be seen, or the rules below prove nothing
    assert any(t == "scenarios.runs" for t, _, _ in GRAPH["scenarios.simulate"])
    assert len(MODULES) > 50


def test_no_import_cycle_between_the_project_modules():
    assert _cycles() == []


def test_no_private_name_is_imported_across_modules():
    crossing = [f"{name}:{line} imports {attr} from {target}"
                for name, edges in GRAPH.items() for target, attr, line in edges
                if attr and attr.startswith("_") and not attr.startswith("__")]
    assert crossing == []


def test_imports_flow_one_way_between_packages():
    upward = [f"{name}:{line} imports {target}"
              for name, edges in GRAPH.items() for target, _, line in edges
              if target.split(".")[0] not in MAY_IMPORT[name.split(".")[0]]
              and target not in SHARED]
    assert upward == []


def test_only_the_command_line_speaks_of_options():
    # the library raises errors named by Python argument (scenarios.errors.ArgumentError);
    # the command line's UsageError is for the command line alone, which names the options
    outside = [f"{name}:{line}" for name, edges in GRAPH.items()
               if not name.startswith("campaign.cli") for target, attr, line in edges
               if attr == "UsageError" or target.endswith(".UsageError")]
    assert outside == []


def test_the_scoring_layer_sits_below_the_rendering_layer():
    # reports/ is two layers (docs/design.md §2): scoring never imports rendering, and the
    # detectors and the evidence import only scoring
    below = [f"{name}:{line} imports {target}"
             for name, edges in GRAPH.items() for target, _, line in edges
             if (name.startswith(("reports.scoring", "detectors", "campaign.evidence"))
                 and target.startswith("reports.") and not target.startswith("reports.scoring"))]
    assert below == []
    assert any(t.startswith("reports.scoring") for t, _, _ in GRAPH["detectors.tail"])
    assert any(t.startswith("reports.scoring") for t, _, _ in GRAPH["reports.render.html"])


def test_the_shared_modules_import_nothing_of_the_project():
    # every package may import them, so they must sit below all of them
    assert {name: GRAPH[name] for name in SHARED} == {name: [] for name in SHARED}
    assert any(t in SHARED for t, _, _ in GRAPH["reports.scoring.gate"])   # the rule is exercised


def _sections(doc: str) -> set[str]:
    text = (REPO / "docs" / doc).read_text(encoding="utf-8")
    return set(re.findall(r"^#+ *§?(\d+)[.\s]", text, flags=re.M))


CITED = sorted({(m.group(1), m.group(2), str(path.relative_to(REPO)))
                for path in [*REPO.glob("*/**/*.py"), *REPO.glob("docs/*.md"),
                             REPO / "README.md"]
                if ".venv" not in path.parts
                for m in re.finditer(r"docs/(physics|design)\.md §(\d+)",
                                     path.read_text(encoding="utf-8"))})


@pytest.mark.parametrize("doc", ["physics", "design"])
def test_every_citation_of_the_documents_resolves_to_a_section(doc):
    sections = _sections(f"{doc}.md")
    cited = [c for c in CITED if c[0] == doc]
    assert cited, f"nothing cites docs/{doc}.md"
    missing = [f"{where}: docs/{doc}.md §{n}" for d, n, where in cited if n not in sections]
    assert missing == []


def test_no_citation_points_outside_the_repository():
    outside = [str(p.relative_to(REPO)) for p in [*REPO.glob("*/**/*.py"), *REPO.glob("docs/*.md")]
               if ".venv" not in p.parts and p != Path(__file__).resolve()
               and re.search(r"\b(PHYSICS|DESIGN)(\.md)?,? ?§|shared/",
                             p.read_text(encoding="utf-8"))]
    assert outside == []


#: Names that have one definition in the project (issue 34: one declaration mechanism, one
#: run-variable space, one Clopper–Pearson, one natural sort, one progress reporter, one
#: engine-version fallback), with the module that holds it.
ONE_DEFINITION = {
    "range_text": "scenarios.declare", "num": "scenarios.declare",
    "toml_value": "scenarios.declare", "FLIGHT_COLUMNS": "scenarios.envelope",
    "upper_bound": "reports.scoring.metrics", "natural_key": "reports.scoring.summary",
    "Progress": "campaign.progress", "engine_version": "campaign.store.files",
}


def _top_level(tree: ast.Module):
    """The statements of a module and of its classes (not those inside functions)."""
    for node in tree.body:
        yield node
        if isinstance(node, ast.ClassDef):
            yield from node.body


def test_each_shared_helper_is_defined_once():
    defined = {}
    for name, path in MODULES.items():
        for node in _top_level(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
                targets = [node.name]
            elif isinstance(node, ast.Assign) or (isinstance(node, ast.AnnAssign)
                                                  and node.value is not None):
                # an annotation without a value (a dataclass field) defines nothing
                nodes = node.targets if isinstance(node, ast.Assign) else [node.target]
                targets = [t.id for t in nodes if isinstance(t, ast.Name)]
            else:
                continue
            for t in targets:
                if t in ONE_DEFINITION:
                    defined.setdefault(t, set()).add(name)
    assert defined == {t: {m} for t, m in ONE_DEFINITION.items()}
    # nor written out again: the four flight-point columns as a literal
    flight = ["alt_ft", "vcas_kt", "mass_t", "cg_pct"]
    literal = [name for name, path in MODULES.items()
               for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
               if isinstance(node, (ast.Tuple, ast.List))
               and [getattr(e, "value", None) for e in node.elts] == flight]
    assert literal == ["scenarios.envelope"]


def test_the_changelog_tells_every_model_version_and_the_current_engine():
    # history lives in CHANGELOG.md, not in comments: it must list every model version the
    # run ids have hashed, newest (the current MODEL_VERSION) first, and the package's version
    import tomllib

    from campaign.plan import MODEL_VERSION

    text = (REPO / "CHANGELOG.md").read_text(encoding="utf-8")
    models = re.findall(r"^- \*\*(servo-\d+)\*\*", text, flags=re.M)
    newest = int(MODEL_VERSION.removeprefix("servo-"))
    assert models == [f"servo-{n}" for n in range(newest, 0, -1)]
    version = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["version"]
    assert re.search(rf"^- \*\*{re.escape(version)}\*\* \(current", text, flags=re.M)


#: At most this many modules directly in campaign/; the rest belong to its subpackages by role
#: (docs/design.md §2): a flat package of more is the layout the subpackages replaced.
MAX_CAMPAIGN_MODULES = 15


def _design_tree() -> dict[str, int]:
    """Paths of docs/design.md §2's tree (``campaign/store/lock.py``, ``campaign/store/``) ->
    line number in the document. An entry is a line whose first word ends in ``.py`` or
    ``/``, indented two spaces per level; other lines continue the description above."""
    lines = (REPO / "docs" / "design.md").read_text(encoding="utf-8").splitlines()
    start = lines.index("## 2. Layout and import direction")
    first = lines.index("```", start) + 1
    last = lines.index("```", first)
    entries, stack = {}, []
    for no in range(first, last):
        line = lines[no]
        word = line.split(maxsplit=1)[0] if line.strip() else ""
        if not word.endswith((".py", "/")):
            continue
        indent = len(line) - len(line.lstrip(" "))
        assert indent % 2 == 0, f"docs/design.md:{no + 1}: indent by two spaces per level"
        depth = indent // 2
        stack[depth:] = [word.rstrip("/")]
        path = "/".join(stack) + ("/" if word.endswith("/") else "")
        assert path not in entries, f"docs/design.md:{no + 1}: {path} is listed twice"
        entries[path] = no + 1
    return entries


TREE = _design_tree()


def test_the_tree_reader_sees_modules_folders_and_depth():
    # a module three levels down, a folder, a data folder: or the checks below prove nothing
    assert "campaign/tools/studies/vanek.py" in TREE
    assert "detectors/builtin/" in TREE and "campaign/presets/" in TREE
    assert len([p for p in TREE if p.endswith(".py")]) > 80


def test_every_module_of_the_packages_is_in_the_design_tree():
    on_disk = {str(path.relative_to(REPO)) for path in MODULES.values()
               if path.name != "__init__.py"}
    packages = {str(path.parent.relative_to(REPO)) + "/" for path in MODULES.values()
                if path.name == "__init__.py"}
    missing = sorted((on_disk | packages) - set(TREE))
    assert missing == [], "add a line for each to docs/design.md §2"


def test_everything_in_the_design_tree_exists():
    gone = [f"docs/design.md:{no}: {path}" for path, no in TREE.items()
            if not (REPO / path).exists()
            or (path.endswith(".py") and not (REPO / path).is_file())]
    assert gone == []


def test_campaign_holds_few_modules_directly():
    direct = sorted(p.name for p in (REPO / "campaign").glob("*.py") if p.name != "__init__.py")
    assert len(direct) <= MAX_CAMPAIGN_MODULES, direct


def test_no_test_folder_is_named_like_a_package():
    # pytest puts tests/ on sys.path (for conftest.py), and so do the dask tests' workers: a
    # folder tests/campaign/ would then be imported as a namespace package `campaign` by any
    # process that finds the project through its editable install (plain `pytest`, a dask
    # worker), shadowing the real one
    folders = {p.name for p in (REPO / "tests").iterdir() if p.is_dir()}
    assert not folders & set(PACKAGES)
