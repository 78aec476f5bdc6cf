"""Build the built-in servo-loop plant (docs/physics.md §3) as an FMI 2.0 (default) or FMI 3.0
co-simulation FMU.

The C sources and the model-description templates ship in ``scenarios/fmu_src``: the model
(``servo_model.c``) and one interface file per FMI version (``fmi2_servo.c``,
``fmi3_servo.c``). The build
fills the parameter start values from :mod:`scenarios.params` (the same table the built-in
plant uses), compiles the sources with the machine's C compiler against the FMI headers that
fmpy ships (``fmpy/c-code``), zips the standard FMU layout::

    modelDescription.xml
    binaries/<platform>/fdd_servo.so       (FMI 2.0: linux64; FMI 3.0: x86_64-linux)
    sources/*.c, *.h
    sources/buildDescription.xml           (FMI 3.0 only; FMI 2.0 lists its <SourceFiles>)

and checks the result with fmpy (``fmpy.validation.validate_fmu``, then one instantiation
and one step). It relies on no fmpy build helper (``fmpy.util.compile_platform_binary`` was
removed in fmpy 0.3.26): the compiler is called directly.

The parameters of the FMU carry the names of :class:`scenarios.servo.PlantArrays` (plus the
surface stops and the trimmed start position), so the engine pushes each run's true plant
parameters into the FMU at set-up (:mod:`scenarios.fmu`).
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
import uuid
import zipfile
from importlib import resources
from pathlib import Path

import numpy as np

from .errors import ArgumentError, InputError

from .params import TS_S

MODEL_IDENTIFIER = "fdd_servo"
#: FMI version → (C sources, model-description template).
VERSIONS = {
    "2": (("servo_model.c", "fmi2_servo.c"), "modelDescription.xml.in"),
    "3": (("servo_model.c", "fmi3_servo.c"), "modelDescription3.xml.in"),
}
HEADER_FILES = ("servo_model.h",)

#: FMU parameter → macro of the generated ``servo_start.h`` (start values).
START_MACROS = {
    "Kci": "START_KCI", "SdP": "START_SDP", "SdP_ref": "START_SDP_REF", "Ka": "START_KA",
    "r_mm": "START_R_MM", "x_min": "START_X_MIN", "x_max": "START_X_MAX",
    "hm_delta": "START_HM_DELTA", "hm_0": "START_HM_0", "stop_min_rad": "START_STOP_MIN",
    "stop_max_rad": "START_STOP_MAX", "h_max_s": "START_H_MAX",
}

#: Start value of the FMU's ``h_max_s`` [s], its longest internal integration sub-step: the
#: FCC period the model was designed for (:data:`scenarios.params.TS_S`, docs/physics.md §2).
#: ``doStep(h)`` takes ceil(h / h_max_s) equal RK4 sub-steps, so a step of Ts is the built-in
#: plant's single RK4 step and longer communication steps converge to the same trajectory.
H_MAX_S = TS_S

#: Compiler flags: position-independent shared object; no floating-point contraction (FMA)
#: and no fast-math, so the C arithmetic rounds like the numpy plant it is checked against.
CFLAGS = ("-shared", "-fPIC", "-O2", "-std=c99", "-ffp-contract=off", "-fno-fast-math")


class FmuBuildError(InputError, RuntimeError):
    """The FMU could not be built (no compiler, compiler error, validation failure)."""


class FmuOptionError(ArgumentError):
    """An argument of the build that cannot be used (*surface*, *out*, *fmi*), named as
    Python names it; ``fdd-campaign fmu build`` names its option
    (:class:`scenarios.errors.ArgumentError`)."""


def source_dir() -> Path:
    """Directory of the shipped C sources and model-description template."""
    return Path(str(resources.files("scenarios").joinpath("fmu_src")))


def fmi_header_dir(version: str = "2") -> Path:
    """Directory of the FMI headers shipped with fmpy (``fmpy/c-code``)."""
    import fmpy

    d = Path(fmpy.__file__).parent / "c-code"
    header = d / f"fmi{version}Functions.h"
    if not header.is_file():
        raise FmuBuildError(f"fmpy {fmpy.__version__} ships no {header.name} in {d}; fix: "
                            "install fmpy>=0.3.20 (pip install -U fmpy)")
    return d


def find_compiler() -> str:
    """The C compiler: ``$CC``, else ``cc``, else ``gcc``."""
    for cand in (os.environ.get("CC"), "cc", "gcc"):
        if cand and shutil.which(cand):
            return shutil.which(cand)
    raise FmuBuildError("no C compiler found (tried $CC, cc, gcc); fix: install one, e.g. "
                        "'apt-get install gcc', or set CC=/path/to/compiler")


def start_values(surface: str = "elevator") -> dict[str, float]:
    """Parameter start values of the FMU: the true plant of *surface* at the default flight
    point of ``fdd-campaign simulate`` (nominal, no uncertainty), from scenarios.params, and
    the internal sub-step ``h_max_s`` (:data:`H_MAX_S`)."""
    from . import envelope
    from .params import ACTUATORS
    from .servo import plant_arrays
    from .simulate import DEFAULT_POINT

    if surface not in ACTUATORS:
        raise FmuOptionError.of("surface", surface,
                                f"unknown surface; allowed: {', '.join(ACTUATORS)}")
    act = ACTUATORS[surface]
    pt = {k: np.array([v]) for k, v in DEFAULT_POINT.items()}
    fc = envelope.flight_condition(pt["alt_ft"], pt["vcas_kt"], pt["mass_t"], pt["cg_pct"])
    pl = plant_arrays(act, qbar_pa=fc["qbar_pa"], alpha_deg=fc["alpha_deg"], mach=fc["mach"])
    from .fmu import plant_parameters

    return {**plant_parameters(pl, act, 0), "h_max_s": H_MAX_S}


def _start_header(values: dict[str, float], guid: str) -> str:
    lines = ["/* Generated by fdd-campaign fmu build from scenarios/params.py; do not edit. */",
             "#ifndef FDD_SERVO_START_H", "#define FDD_SERVO_START_H",
             f'#define FDD_SERVO_GUID "{guid}"']
    for name, macro in START_MACROS.items():
        lines.append(f"#define {macro} {values[name]!r}")
    lines += ["#define START_X0 0.0", "#endif", ""]
    return "\n".join(lines)


def _build_description(source_files) -> str:
    """``sources/buildDescription.xml`` of the FMI 3.0 FMU: the C sources to compile (C99,
    as :data:`CFLAGS`), so that importers rebuild the binary (e.g. ``fmpy compile``); the
    FMI 2.0 FMU lists them in its model description (``<SourceFiles>``)."""
    files = "\n".join(f'      <SourceFile name="{name}"/>' for name in source_files)
    return ('<?xml version="1.0" encoding="UTF-8"?>\n'
            '<fmiBuildDescription fmiVersion="3.0">\n'
            f'  <BuildConfiguration modelIdentifier="{MODEL_IDENTIFIER}">\n'
            '    <SourceFileSet language="C99">\n'
            f"{files}\n"
            '    </SourceFileSet>\n'
            '  </BuildConfiguration>\n'
            '</fmiBuildDescription>\n')


def _version() -> str:
    try:
        from importlib.metadata import version

        return version("fdd-campaign")
    except Exception:  # noqa: BLE001 - running from a source tree
        return "dev"


def build_servo_fmu(out: str | os.PathLike = "servo.fmu", *, surface: str = "elevator",
                    fmi: str = "2", ts: float = 0.01, validate: bool = True, log=None) -> Path:
    """Compile and zip the servo-loop FMU (FMI version *fmi*: "2" or "3") into *out*;
    returns its path.

    Raises :class:`FmuBuildError` with the compiler output or the validation problems.
    """
    out = Path(out)
    if out.suffix != ".fmu":
        raise FmuOptionError.of("out", str(out), "an FMU file name must end in .fmu",
                                "servo.fmu")
    if str(fmi) not in VERSIONS:
        raise FmuOptionError.of("fmi", fmi, "FMI version not supported; allowed: 2, 3")
    SOURCE_FILES, TEMPLATE = VERSIONS[str(fmi)]
    src = source_dir()
    values = start_values(surface)
    digest = hashlib.sha256()
    for name in (*SOURCE_FILES, *HEADER_FILES, TEMPLATE):
        digest.update((src / name).read_bytes())
    digest.update(repr(sorted(values.items())).encode())
    guid = "{" + str(uuid.UUID(digest.hexdigest()[:32])) + "}"

    import fmpy

    with tempfile.TemporaryDirectory(prefix="fdd-fmu-build-") as tmp:
        root = Path(tmp)
        sources = root / "sources"
        sources.mkdir()
        for name in (*SOURCE_FILES, *HEADER_FILES):
            shutil.copy(src / name, sources / name)
        (sources / "servo_start.h").write_text(_start_header(values, guid))
        if str(fmi) == "3":   # FMI 3.0 source FMUs list their sources here
            (sources / "buildDescription.xml").write_text(_build_description(SOURCE_FILES),
                                                          encoding="utf-8")
        xml = (src / TEMPLATE).read_text(encoding="utf-8").format(
            guid=guid, version=_version(), surface=surface, ts=repr(ts),
            **{k: repr(v) for k, v in values.items()})
        (root / "modelDescription.xml").write_text(xml, encoding="utf-8")
        bindir = root / "binaries" / (fmpy.platform if str(fmi) == "2" else fmpy.platform_tuple)
        bindir.mkdir(parents=True)
        lib = bindir / (MODEL_IDENTIFIER + fmpy.sharedLibraryExtension)
        cmd = [find_compiler(), *CFLAGS, f"-I{fmi_header_dir(str(fmi))}", f"-I{sources}",
               "-o", str(lib), *[str(sources / f) for f in SOURCE_FILES], "-lm"]
        if log:
            log(" ".join(cmd))
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0:
            raise FmuBuildError(f"compiling the servo-loop FMU failed ({' '.join(cmd)}):\n"
                                f"{proc.stdout}{proc.stderr}")
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp_out = out.with_name(out.name + ".tmp")
        with zipfile.ZipFile(tmp_out, "w", zipfile.ZIP_DEFLATED) as zf:
            for path in sorted(root.rglob("*")):
                if path.is_file():
                    zf.write(path, path.relative_to(root).as_posix())
        os.replace(tmp_out, out)
    if validate:
        validate_fmu_file(out)
    return out


def validate_fmu_file(path: str | os.PathLike) -> None:
    """Check an FMU with fmpy (model description and, for this platform, one
    instantiation and step); raises :class:`FmuBuildError` listing the problems."""
    from fmpy.validation import validate_fmu

    try:
        problems = validate_fmu(str(path))
    except Exception as exc:  # noqa: BLE001 - fmpy raises on unreadable descriptions
        problems = [f"{type(exc).__name__}: {exc}"]
    if problems:
        raise FmuBuildError(f"FMU {path} does not validate:\n  - " + "\n  - ".join(problems))
    from .fmu import FmuPlant, probe

    probe(FmuPlant(path=str(path)))


def main(argv=None) -> int:  # pragma: no cover - thin wrapper, the CLI is the entry point
    out = build_servo_fmu(argv[0] if argv else "servo.fmu", log=print)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main(sys.argv[1:]))
