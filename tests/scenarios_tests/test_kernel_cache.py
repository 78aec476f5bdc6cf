"""numba's on-disk cache of a kernel module is flushed when a module its kernels compile in
changes (scenarios.compiled.invalidate_stale_cache, on the last line of every kernel module,
so before any of its functions is loaded).

numba checks a cached function against its own source file only: a kernel calling a
compiled function of another module would otherwise be loaded with that function's old
arithmetic after the other module changed.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from scenarios import compiled as kernels

ROOT = Path(__file__).resolve().parents[2]

#: numba's on-disk cache exists only with numba installed (a core dependency; the guard is a
#: no-op without it). The subprocess test compiles with NUMBA_DISABLE_JIT removed from its
#: environment; the in-process tests need this process to compile as well.
needs_numba = pytest.mark.skipif(not kernels.HAVE_NUMBA,
                                 reason="numba is not installed: nothing is cached to flush")
needs_compiling = pytest.mark.skipif(
    not kernels.HAVE_NUMBA or __import__("numba").core.config.DISABLE_JIT,
    reason="numba missing or NUMBA_DISABLE_JIT set: this process compiles nothing, caches "
           "nothing (the subprocess test still runs the guard on compiled code)")

GUARD = ("from scenarios.compiled import invalidate_stale_cache\n"
         "FLUSHED = invalidate_stale_cache(__name__, depends=DEPENDS)\n")
CALLEE = ("from numba import njit\n\n@njit(cache=True)\ndef f(x):\n    return x + {add}\n"
          "DEPENDS = ()\n" + GUARD)
CALLER = ("from numba import njit\nfrom kmod_a import f\n\n@njit(cache=True)\n"
          "def g(x):\n    return f(x) * 2.0\nDEPENDS = ('kmod_a',)\n" + GUARD)
SCRIPT = """
import kmod_a, kmod_b
flushed = [m.__name__ for m in (kmod_a, kmod_b) if m.FLUSHED]
print(kmod_b.g(1.0), ",".join(flushed))
"""


def _run(tmp_path: Path) -> tuple[float, str]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), str(ROOT)])}
    env.pop("NUMBA_CACHE_DIR", None)
    env.pop("NUMBA_DISABLE_JIT", None)
    out = subprocess.run([sys.executable, "-c", SCRIPT],
                         env=env, cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    value, flushed = out.stdout.split()[0], (out.stdout.split() + [""])[1]
    return float(value), flushed


@needs_numba
def test_a_cached_caller_is_compiled_again_when_its_callee_module_changes(tmp_path):
    (tmp_path / "kmod_a.py").write_text(CALLEE.format(add="1.0"))
    (tmp_path / "kmod_b.py").write_text(CALLER)
    # first use: no stamp yet, both modules' caches flushed (empty anyway), g = (1 + 1)·2
    assert _run(tmp_path) == (4.0, "kmod_a,kmod_b")
    # same sources: nothing flushed, g loaded from the cache
    assert _run(tmp_path) == (4.0, "")
    assert list((tmp_path / "__pycache__").glob("kmod_b.g-*.nbi"))
    assert (tmp_path / "__pycache__" / "fdd-kernel-sources.json").is_file()
    # only the callee's module changes (numba recompiles f itself): the caller's cache entry,
    # built with the old f, is flushed, so g = (1 + 2)·2
    (tmp_path / "kmod_a.py").write_text(CALLEE.format(add="2.0"))
    assert _run(tmp_path) == (6.0, "kmod_b")
    assert _run(tmp_path) == (6.0, "")


def test_every_module_with_cached_kernels_calls_the_guard_last():
    """Every module of the package whose compiled functions numba caches ends with the
    guard, after its last compiled function; scenarios.compiled, whose functions and
    constants the others compile in, is among them (the default dependency). The aircraft
    kernel also names scenarios.aircraft.lpv, whose state indices it compiles in."""
    cached = {}
    for package in ("campaign", "detectors", "reports", "scenarios"):
        for path in (ROOT / package).rglob("*.py"):
            text = path.read_text()
            if re.search(r"\bcache=True\b", text):
                cached[".".join(path.relative_to(ROOT).with_suffix("").parts)] = text
    assert {"scenarios.compiled", "detectors.builtin.position_monitor",
            "detectors.builtin.comb_interval",
            "scenarios.aircraft.kernel"} <= set(cached)
    for name, text in cached.items():
        last = text.rstrip().splitlines()[-1].split("#")[0].strip()
        assert re.fullmatch(r"(kernels\.)?invalidate_stale_cache\(__name__(, depends=.*)?\)",
                            last), name
    aircraft = cached["scenarios.aircraft.kernel"].rstrip().splitlines()[-1]
    assert '"scenarios.aircraft.lpv"' in aircraft


@needs_compiling
def test_the_guard_is_best_effort_and_never_raises(tmp_path, monkeypatch):
    """A guard that cannot do its work leaves the cache as it is and returns False: an
    unknown module, a module without cached functions, a dependency that cannot be found or
    is not a sequence, a stamp that cannot be read or written."""
    (tmp_path / "kguard_mod.py").write_text(
        "from numba import njit\n\n@njit(cache=True)\ndef h(x):\n    return x\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    import kguard_mod  # noqa: F401 - the module the guard looks at

    stamp = tmp_path / "stamp.json"
    guard = kernels.invalidate_stale_cache
    assert guard("no_such_module_here", stamp=stamp) is False              # KeyError
    assert guard("json", stamp=stamp) is False                             # nothing cached
    assert guard("kguard_mod", depends=("no_such_module_here",), stamp=stamp) is False
    assert guard("kguard_mod", depends=None, stamp=stamp) is False         # TypeError
    assert not stamp.exists()
    stamp.write_text("{not json")                                          # ValueError
    assert guard("kguard_mod", depends=("kguard_mod",), stamp=stamp) is False
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    assert guard("kguard_mod", depends=("kguard_mod",),                   # OSError
                 stamp=blocker / "stamp.json") is False
    # and the same call with a usable stamp does its work: flushed once, then not again
    good = tmp_path / "cache" / "deeper" / "stamp.json"      # parents made
    assert guard("kguard_mod", depends=("kguard_mod",), stamp=good) is True
    assert guard("kguard_mod", depends=("kguard_mod",), stamp=good) is False


@needs_compiling
def test_the_guard_flushes_the_modules_own_functions_only(tmp_path, monkeypatch):
    """A compiled function another module imports into the guarded one (as the detectors
    import the shared kernels) keeps its cache: it is checked by its own module's guard."""
    (tmp_path / "kguard_dep.py").write_text(
        "from numba import njit\n\n@njit(cache=True)\ndef d(x):\n    return x + 1.0\n")
    (tmp_path / "kguard_own.py").write_text(
        "from numba import njit\nfrom kguard_dep import d\n\n@njit(cache=True)\n"
        "def e(x):\n    return d(x) * 3.0\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    import kguard_dep
    import kguard_own

    assert kguard_own.e(1.0) == 6.0                  # compiles both, saves both caches
    index = lambda f: f._cache._cache_file._load_index()   # noqa: E731 - numba's own index
    assert index(kguard_dep.d) and index(kguard_own.e)
    assert kernels.invalidate_stale_cache("kguard_own", depends=("kguard_dep",),
                                          stamp=tmp_path / "stamp.json") is True
    assert not index(kguard_own.e)                   # its own function: flushed
    assert index(kguard_dep.d)                       # the imported one: kept
