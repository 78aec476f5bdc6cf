"""Messages naming what is wrong with an FMU file that cannot serve as a plant, and the fix
(used by :mod:`scenarios.fmu` before any work: :func:`scenarios.fmu.inspect_fmu`,
:func:`scenarios.fmu.probe`)."""

from __future__ import annotations

from pathlib import Path


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
