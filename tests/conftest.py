"""Shared test helpers, and how a run of many test files is spread over the CPUs."""

import math

import numpy as np
import pytest

from scenarios import servo


# ---------------------------------------------------------------------------------------
# Parallel runs (docs/testing.md, "How long the suite takes")
# ---------------------------------------------------------------------------------------
def _names_a_folder(config) -> bool:
    """Whether the run collects from a folder: no paths given (the ``testpaths``, the whole
    suite) or a folder among them. Test files and node ids name no folder."""
    here = config.invocation_params.dir
    args = [a for a in config.args if not a.startswith("-")] or [str(config.rootpath)]
    return any((here / a.split("::")[0]).is_dir() for a in args)


@pytest.hookimpl(tryfirst=True)
def pytest_cmdline_main(config):
    """With pytest-xdist installed (the ``test`` extra), a run of a folder — ``python -m
    pytest`` itself — runs on one worker process per CPU (``-n auto``), each test file on
    one worker (``--dist loadfile``, so a module's shared campaign is run once). A run of
    test files or tests stays in this process: starting workers would cost more than it
    saves. ``-n``/``--numprocesses`` on the command line (``-n 0``: one process) decides
    the count instead (still a file per worker unless ``--dist`` says otherwise);
    ``--pdb`` and ``--collect-only`` run in one process."""
    if not config.pluginmanager.hasplugin("xdist") or hasattr(config, "workerinput"):
        return
    if config.option.numprocesses is None:
        if config.getoption("usepdb", False) or config.getoption("collectonly", False) \
                or not _names_a_folder(config):
            return
        config.option.numprocesses = "auto"
    if config.option.dist == "no":
        config.option.dist = "loadfile"
        # files in the order pytest_collection_modifyitems gives (slow files first), not
        # by their number of tests, pytest-xdist's default order since 3.6
        if hasattr(config.option, "loadscopereorder"):
            config.option.loadscopereorder = False


#: Compile the kernels one module registers (scenarios.compiled.register_warmup), in a
#: child process: python -c WARM_KERNELS MODULE ...
WARM_KERNELS = """
import importlib, sys
from scenarios import compiled
for name in sys.argv[1:]:
    importlib.import_module(name)
    for warm in list(compiled._WARMUPS):
        if warm.__module__ == name:
            warm()
"""


def kernel_modules(root):
    """The modules under *root* that register a kernel warm-up, by dotted name."""
    return [".".join(path.relative_to(root).with_suffix("").parts)
            for package in ("scenarios", "detectors")
            for path in sorted((root / package).rglob("*.py"))
            if "register_warmup(" in path.read_text(encoding="utf-8")
            and path.name != "__init__.py"]


@pytest.hookimpl(tryfirst=True)
def pytest_sessionstart(session):
    """Before the workers of a parallel run start: compile every registered kernel once
    (or load it from numba's cache), in two child processes. After a fresh clone (CI) the
    cache is empty, and each worker, and each process a test starts (a campaign's workers,
    a dask worker, a command run as a child), would compile the kernels it needs at the
    same moment as the others: two minutes of CPU time spent on the same work, against
    half a minute once. A run in one process compiles as it goes, as before."""
    config = session.config
    if hasattr(config, "workerinput") or not getattr(config.option, "numprocesses", None) \
            or config.getoption("collectonly", False):
        return
    import os
    import subprocess
    import sys

    root = config.rootpath
    modules = kernel_modules(root)
    # the servo-loop's kernels take about as long to compile as all the others together
    servo = [name for name in modules if name == "scenarios.compiled"]
    halves = [servo, [name for name in modules if name not in servo]]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(root), *filter(None, [os.environ.get("PYTHONPATH")])])}
    children = [subprocess.Popen([sys.executable, "-c", WARM_KERNELS, *half], cwd=root,
                                 env=env) for half in halves if half]
    for child in children:
        child.wait()                  # a failure shows in the tests that call the kernel


def pytest_collection_modifyitems(config, items):
    """On the workers of a parallel run, the files with a ``slow`` test first (each file
    otherwise in its collected order, its tests in theirs): a file runs on one worker, so
    a long file collected last (the README's, about 1.5 minutes) would run alone at the end
    while the other worker idles. Starting the longest work first (the classic
    longest-processing-time-first rule) leaves the short files to fill the end."""
    if not hasattr(config, "workerinput"):
        return
    slow_files = {item.nodeid.split("::")[0] for item in items
                  if item.get_closest_marker("slow") is not None}
    items.sort(key=lambda item: item.nodeid.split("::")[0] not in slow_files)


class LibmNumpy:
    """NumPy with ``arcsin`` and ``cos`` from the C library, as the compiled kernels use.

    NumPy evaluates arcsin/cos with its own SIMD routines on CPUs that have them (x86
    AVX-512), which differ from the C library in the last bit for some arguments; with the
    same library functions both implementations do the same arithmetic, operation for
    operation, so their results must be bit-identical."""

    def __getattr__(self, name):
        return getattr(np, name)

    arcsin = staticmethod(np.vectorize(math.asin, otypes=[float]))
    cos = staticmethod(np.vectorize(math.cos, otypes=[float]))


@pytest.fixture
def libm_numpy(monkeypatch):
    """The NumPy plant functions of :mod:`scenarios.servo` on the C library's arcsin/cos."""
    monkeypatch.setattr(servo, "np", LibmNumpy())


# ---------------------------------------------------------------------------------------
# FMUs (tests/scenarios_tests/test_fmu.py, tests/scenarios_tests/test_fmu_bad.py)
# ---------------------------------------------------------------------------------------
@pytest.fixture(scope="session")
def servo_fmu(tmp_path_factory):
    """The built-in servo-loop FMU (FMI 2.0), built once per test session from the shipped
    sources."""
    from scenarios.fmu_build import build_servo_fmu

    return build_servo_fmu(tmp_path_factory.mktemp("fmu") / "servo.fmu")


@pytest.fixture(scope="session")
def servo_fmu3(tmp_path_factory):
    """The same servo-loop as an FMI 3.0 co-simulation FMU."""
    from scenarios.fmu_build import build_servo_fmu

    return build_servo_fmu(tmp_path_factory.mktemp("fmu3") / "servo3.fmu", fmi="3")


def edit_fmu(src, dst, replace=None, drop=(), rename=None):
    """Copy the FMU *src* to *dst*, editing its members: *replace* maps a member name to
    new bytes or to a function of the old bytes, *drop* lists members (or folder prefixes
    ending in "/") to leave out, *rename* maps a member name to a new name."""
    import zipfile

    replace, rename = replace or {}, rename or {}
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for item in zin.infolist():
            name = item.filename
            if any(name == d or (d.endswith("/") and name.startswith(d)) for d in drop):
                continue
            data = zin.read(name)
            if name in replace:
                new = replace[name]
                data = new(data) if callable(new) else new
            item.filename = rename.get(name, name)
            zout.writestr(item, data)
    return dst


def warm_up_writability(monkeypatch, module, kernel: str) -> list[bool]:
    """Whether each call of *module*'s ``_warm_kernels`` hands the kernel *kernel* a
    writable first argument (the kernel replaced by a recorder): a detector's warm-up runs
    its kernel on the writable arrays of a fit and on the read-only views detect reads
    (scenarios.compiled.read_only_view), so that numba compiles both signatures at once."""
    writable = []
    monkeypatch.setattr(module, kernel, lambda first, *rest: writable.append(
        first.flags.writeable))
    module._warm_kernels()
    return writable
