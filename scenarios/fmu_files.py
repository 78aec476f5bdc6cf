"""Reading an FMU file, and saying what is wrong with one that cannot serve as a plant and
how to fix it (used by :mod:`scenarios.fmu` before any work: :func:`scenarios.fmu.inspect_fmu`,
:func:`scenarios.fmu.probe`)."""

from __future__ import annotations

import re
from pathlib import Path

from .errors import InputError


def not_a_zip(path: Path) -> str:
    """What *path* is, when it is not a zip archive (an FMU is one)."""
    with open(path, "rb") as fh:
        head = fh.read(512)
    if not head:
        return "is an empty file (0 bytes), not an FMU (a zip archive)"
    if head.startswith(b"PK"):
        return ("is a truncated or damaged zip archive (it has no zip directory at its end, "
                "e.g. an interrupted download or copy)")
    try:
        text = head.decode("utf-8")
    except UnicodeDecodeError:
        text = None
    if text is not None and all(ch.isprintable() or ch in "\r\n\t" for ch in text):
        first = text.strip().splitlines()[0] if text.strip() else ""
        what = f"is a text file, not an FMU (a zip archive); it starts with {first[:60]!r}"
        if text.startswith("version https://git-lfs"):
            what += " (a Git LFS pointer: fetch the file itself with 'git lfs pull')"
        return what
    return "is not a zip archive, so not an FMU"


def load_failure(info, stage: str, exc: Exception) -> str:
    """The message of an FMU (:class:`scenarios.fmu.FmuInfo` *info*) that fails at *stage*
    ("extract", "load", "instantiate"): its archive does not extract, its binary does not
    load or export the FMI functions, or its binary refuses to instantiate."""
    import fmpy

    v2 = info.version == "2.0"
    plat = fmpy.platform if v2 else fmpy.platform_tuple
    binary = f"binaries/{plat}/{info.model_identifier}{fmpy.sharedLibraryExtension}"
    detail = f"{type(exc).__name__}: {exc}"
    rebuild = f"fix: re-export the FMU for {plat} from its modelling tool"
    if info.sources:
        rebuild += (f", or compile the sources it ships for this platform "
                    f"('python -m fmpy compile {info.path}')")
    if stage == "extract":
        return f"FMU {info.path}: fails to extract ({detail}); fix: re-export or re-copy it"
    if stage == "load":
        if isinstance(exc, AttributeError) or "undefined symbol" in str(exc):
            return (f"FMU {info.path}: its binary {binary} does not export the FMI "
                    f"{info.version} functions ({detail}); {rebuild}")
        return (f"FMU {info.path}: its binary {binary} fails to load ({detail}): it is not "
                f"a shared library for this platform, or it needs libraries this machine "
                f"lacks; {rebuild}")
    token, call = (("a guid", "fmi2Instantiate") if v2 else
                   ("an instantiationToken", "fmi3InstantiateCoSimulation"))
    return (f"FMU {info.path}: fails to instantiate: {call} returned no instance ({detail}). "
            f"The usual cause is {token} in modelDescription.xml ({info.guid}) that is not "
            f"the one its binary was built with (a description edited or taken from another "
            f"export); fix: re-export the FMU so that modelDescription.xml and {binary} come "
            "from the same build")


class FmuError(InputError, ValueError):
    """An FMU that cannot be used for a campaign (checked before any run)."""


def model_description(path: Path):
    """(model description, archive members) of the FMU *path*; :class:`FmuError` naming
    the file when it is no readable FMU."""
    import zipfile

    from fmpy import read_model_description

    fix = ("fix: give the .fmu file exported by the modelling tool (a zip archive holding "
           "modelDescription.xml and binaries/), or build the built-in servo-loop with "
           f"'fdd-campaign fmu build --out {path}'")
    if not zipfile.is_zipfile(path):
        raise FmuError(f"FMU {path}: {not_a_zip(path)}; {fix}")
    try:
        with zipfile.ZipFile(path) as zf:
            members = zf.namelist()
            xml = zf.read("modelDescription.xml") if "modelDescription.xml" in members else None
    except (zipfile.BadZipFile, OSError, ValueError, EOFError) as exc:
        raise FmuError(f"FMU {path}: a damaged zip archive ({type(exc).__name__}: {exc}); "
                       f"{fix}") from None
    if xml is None:
        shown = ", ".join(members[:5]) + (", …" if len(members) > 5 else "")
        raise FmuError(f"FMU {path}: a zip archive without modelDescription.xml (it holds: "
                       f"{shown or 'nothing'}), so not an FMU; {fix}")
    # the version first: fmpy reads FMI 1.0 descriptions with other rules
    version = re.search(rb"<fmiModelDescription\b[^>]*?\sfmiVersion\s*=\s*[\"']([^\"']*)", xml)
    if version and not re.fullmatch(rb"2\.0|3\.\d+(\.\d+)?(-.*)?", version.group(1)):
        raise FmuError(f"FMU {path}: FMI version {version.group(1).decode(errors='replace')} "
                       "is not supported; fix: export the model as an FMI 2.0 or 3.0 "
                       "co-simulation FMU")
    try:
        return read_model_description(str(path), validate=False), members
    except Exception as exc:  # noqa: BLE001 - any unreadable description gets one message
        raise FmuError(f"FMU {path}: its modelDescription.xml cannot be read "
                       f"({type(exc).__name__}: {exc}); fix: re-export the FMU from its "
                       "modelling tool (FMI 2.0 or 3.0 co-simulation)") from None


def container(path: Path):
    """The FMU file's model description, its name in messages, FMI version, model
    identifier and whether it ships sources; :class:`FmuError` for a file the engine cannot
    run (not there, not FMI 2/3, not co-simulation, no binary for this platform)."""
    import fmpy

    if not path.is_file():
        what = "is a directory" if path.is_dir() else "file not found"
        raise FmuError(f"FMU {path}: {what}; fix: check [plant] fmu / --plant, or build the "
                       f"built-in servo-loop FMU with 'fdd-campaign fmu build --out {path}'")
    md, members = model_description(path)
    name = f"FMU {path} (model {md.modelName!r})"
    if md.fmiVersion not in ("2.0", "3.0") and not str(md.fmiVersion).startswith("3."):
        raise FmuError(f"{name}: FMI version {md.fmiVersion} is not supported; fix: export "
                       "the model as an FMI 2.0 or 3.0 co-simulation FMU")
    if md.coSimulation is None:
        kinds = {kind: why for kind, iface, why in (
            ("model exchange", md.modelExchange, "it has no ODE solver for model exchange"),
            ("scheduled execution", getattr(md, "scheduledExecution", None),
             "it has no clocks to schedule model partitions"))
            if iface is not None}
        what = " and ".join(kinds) + " only" if kinds else "it declares no interface"
        why = "; ".join(kinds.values()) or "it needs the co-simulation interface"
        raise FmuError(f"{name}: not a co-simulation FMU ({what}); the engine advances the "
                       f"plant with doStep, {why}; fix: export the model as a co-simulation "
                       "FMU (FMI 2.0 or 3.0)")
    version = "2.0" if md.fmiVersion == "2.0" else "3.0"
    ident = md.coSimulation.modelIdentifier
    plat = fmpy.platform if version == "2.0" else fmpy.platform_tuple
    binary = f"binaries/{plat}/{ident}{fmpy.sharedLibraryExtension}"
    sources = any(m.startswith("sources/") and m.endswith((".c", ".cpp")) for m in members)
    if binary not in members:
        found = sorted({m.split("/")[1] for m in members
                        if m.startswith("binaries/") and m.count("/") >= 2})
        fix = f"export the FMU for {plat}"
        if sources:
            fix += (f", or compile the sources it ships for this platform: "
                    f"'python -m fmpy compile {path}'")
        raise FmuError(f"{name}: no binary for this platform ({binary} is missing; it has: "
                       f"{', '.join(found) or 'no binaries'}); fix: {fix}")

    return md, name, version, ident, sources
