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
