"""Campaign suites: several campaigns run one after the other, each into its own directory.

A campaign file holds one design (a grid or a Monte Carlo sample), so a study that needs
both — [CHEN] Table 3 (parametric sweep) and Table 4 (Monte Carlo) — is two campaigns. A
suite file names them and gives each a title::

    [suite]
    name = "chen-tables"
    description = "..."

    [[member]]
    campaign = "chen-sweep"        # a preset name, or a .toml path relative to this file
    title = "[CHEN] Table 3 — parametric sweep"

    [[member]]
    campaign = "chen-mc"
    title = "[CHEN] Table 4 — Monte Carlo campaign"
    reference = "chen-table-4"     # optional: print the published table beside ours

``fdd-campaign run SUITE --out DIR`` runs every member with the campaign runner into
``DIR/<member campaign name>`` and prints each member's table under its title; ``DIR``
then holds ``suite.json`` (the suite, its members, their titles, directories and whether
each is complete), written after each member. Rerunning resumes member by member; ``gate``,
``report`` and ``plan`` accept a suite (its file or its directory) and act on every member.
Shipped suites live in ``campaign/suites`` (``fdd-campaign presets`` lists them).

Every problem of a suite file is reported at once (:class:`campaign.config.ConfigError`),
including those of its members' campaign files, before any member runs.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from reports.render.paper import PAPER_TABLES
from scenarios.catalog import suggest

from .config import CampaignConfig, ConfigError, load_config, looks_like_path, read_toml
from .config.load import PRESET_DIR, SUITE_DIR, shipped_dir, shipped_names
from .store.directory import CampaignDirError

__all__ = ["SUITE_FILE", "Member", "Suite", "is_suite_dir", "list_suites", "load_spec",
           "load_suite", "reference_text", "suite_members", "suite_references",
           "write_suite_json"]

#: Name of the file that marks a suite's output directory.
SUITE_FILE = "suite.json"

_SUITE_KEYS = ("name", "description")
_MEMBER_KEYS = ("campaign", "title", "reference")


@dataclass(frozen=True)
class Member:
    """One campaign of a suite: its validated configuration and its title."""

    spec: str                 # as written in the suite file
    title: str
    config: CampaignConfig
    #: a published table to print beside the member's (reports.render.paper.PAPER_TABLES), or None
    reference: str | None = None

    @property
    def name(self) -> str:
        """The member's campaign name: its directory in the suite's output."""
        return self.config.campaign.name


@dataclass(frozen=True)
class Suite:
    """A validated suite file."""

    name: str
    description: str
    members: tuple[Member, ...]
    source: str


# ---- shipped suites -----------------------------------------------------------------------
def _suite_dir():
    return shipped_dir(SUITE_DIR)


def _suite_names() -> list[str]:
    return shipped_names(SUITE_DIR)


def list_suites() -> dict[str, str]:
    """Shipped suites: name → description (from their ``[suite] description``)."""
    import tomllib

    out = {}
    for name in _suite_names():
        with open(str(_suite_dir().joinpath(f"{name}.toml")), "rb") as fh:
            out[name] = str(tomllib.load(fh).get("suite", {}).get("description", ""))
    return out


def _suite_path(spec) -> Path | None:
    """The suite file *spec* names (a shipped suite's name or a path to a suite file), or
    None when *spec* is not a suite."""
    text = str(spec)
    if not isinstance(spec, Path) and not looks_like_path(text) and not Path(text).is_file():
        if text in _suite_names():
            return Path(str(_suite_dir().joinpath(f"{text}.toml")))
        return None
    path = Path(text)
    if not path.is_file():
        return None
    try:
        data = read_toml(path, str(path))
    except ConfigError:
        return None                    # load_config reports the file's syntax error
    return path if isinstance(data, dict) and "suite" in data else None


# ---- loading ------------------------------------------------------------------------------
def _unknown_keys(where: str, table: dict, allowed: tuple[str, ...]) -> list[str]:
    return [f"{where}.{k}: unknown key{suggest(k, allowed)}; allowed: {', '.join(allowed)}"
            for k in table if k not in allowed]


def load_suite(spec) -> Suite:
    """Load and validate a suite: a shipped suite's name or a path to a suite file.

    Raises :class:`ConfigError` listing every problem (the members' included)."""
    path = _suite_path(spec)
    if path is None:
        names = _suite_names()
        raise ConfigError([f"{spec}: not a suite (a file with a [suite] table) nor a shipped "
                           f"suite{suggest(str(spec), names)}; shipped suites: "
                           f"{', '.join(names)}"], str(spec))
    source = str(path)
    data = read_toml(path, source)
    errors: list[str] = []
    for k in data:
        if k not in ("suite", "member"):
            errors.append(f"{k}: unknown section{suggest(k, ['suite', 'member'])}; a suite "
                          "file has [suite] and [[member]] tables only")
    head = data.get("suite")
    if not isinstance(head, dict):
        errors.append("suite: expected a table [suite] with name and description")
        head = {}
    errors += _unknown_keys("suite", head, _SUITE_KEYS)
    name = head.get("name")
    if not (isinstance(name, str) and name.strip()):
        errors.append("suite.name: required, a non-empty string (names the suite in reports)")
    description = head.get("description", "")
    if not isinstance(description, str):
        errors.append("suite.description: expected a string")
    raw = data.get("member", [])
    if not isinstance(raw, list) or not raw:
        errors.append("member: no [[member]] table; fix: add one [[member]] per campaign, "
                      "each with campaign = \"<preset or file>\" and title = \"...\"")
        raw = []
    members: list[Member] = []
    seen: dict[str, int] = {}
    for j, m in enumerate(raw):
        where = f"member[{j}]"
        if not isinstance(m, dict):
            errors.append(f"{where}: expected a table with campaign and title")
            continue
        errors += _unknown_keys(where, m, _MEMBER_KEYS)
        title = m.get("title")
        if not (isinstance(title, str) and title.strip()):
            errors.append(f"{where}.title: required, a non-empty string (printed above the "
                          "member's table)")
        reference = m.get("reference")
        if reference is not None and reference not in PAPER_TABLES:
            errors.append(f"{where}.reference: unknown table {reference!r}"
                          f"{suggest(str(reference), list(PAPER_TABLES))}; allowed: "
                          f"{', '.join(PAPER_TABLES)} (or leave it out)")
            reference = None
        spec_m = m.get("campaign")
        if not (isinstance(spec_m, str) and spec_m.strip()):
            errors.append(f"{where}.campaign: required, a preset name or a .toml path "
                          "(relative to the suite file)")
            continue
        target = spec_m
        if looks_like_path(spec_m) and not Path(spec_m).is_absolute():
            target = str(path.parent / spec_m)
        if _suite_path(target) is not None:
            errors.append(f"{where}.campaign: {spec_m!r} is itself a suite; a member must be "
                          "a campaign (list that suite's members here instead)")
            continue
        try:
            config = load_config(target)
        except ConfigError as exc:
            errors += [f"{where} ({spec_m}): {e}" for e in exc.errors]
            continue
        cname = config.campaign.name
        if cname in seen:
            errors.append(f"{where}.campaign: {spec_m!r} has the campaign name {cname!r} of "
                          f"member[{seen[cname]}]; their output directories would collide "
                          "(DIR/<campaign name>): give each member its own campaign name")
            continue
        seen[cname] = j
        if isinstance(title, str):
            members.append(Member(spec=spec_m, title=title.strip(), config=config,
                                  reference=reference))
    if errors:
        raise ConfigError(errors, source)
    return Suite(name=name.strip(), description=description, members=tuple(members),
                 source=source)


def load_spec(spec) -> CampaignConfig | Suite:
    """A campaign (:func:`campaign.config.load_config`) or, when *spec* names a suite, the
    suite (:func:`load_suite`). A name that is neither a shipped preset nor a shipped suite
    (nor a file) is refused naming the closest of both and listing both."""
    if _suite_path(spec) is not None:
        return load_suite(spec)
    text = str(spec)
    presets = shipped_names(PRESET_DIR)
    if (not isinstance(spec, Path) and not looks_like_path(text) and not Path(text).is_file()
            and text not in presets):
        suites = _suite_names()
        raise ConfigError([f"{text}: unknown preset or suite{suggest(text, presets + suites)}; "
                           f"presets: {', '.join(presets)}; suites: {', '.join(suites)}; or a "
                           "path to a .toml file ('fdd-campaign presets' describes each)"], text)
    return load_config(spec)


# ---- output directories -------------------------------------------------------------------
def is_suite_dir(directory) -> bool:
    """Whether *directory* is a suite's output directory (holds ``suite.json``)."""
    return (Path(directory) / SUITE_FILE).is_file()


def write_suite_json(suite: Suite, out, complete: dict[str, bool]) -> Path:
    """Write ``out/suite.json`` atomically; *complete*: member name → finished."""
    from .store.directory import write_text

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    doc = {"suite": suite.name, "description": suite.description, "source": suite.source,
           "members": [{"campaign": m.name, "spec": m.spec, "title": m.title,
                        "directory": m.name, "complete": complete.get(m.name),
                        "reference": m.reference}
                       for m in suite.members]}
    path = out / SUITE_FILE
    write_text(path, json.dumps(doc, indent=2, ensure_ascii=False) + "\n")
    return path


def suite_members(directory) -> list[tuple[str, Path]]:
    """(title, member directory) of a suite's output directory, in the suite's order.

    Raises :class:`campaign.store.directory.CampaignDirError` naming the problem when ``suite.json``
    is damaged or a member directory is missing."""
    root = Path(directory)
    try:
        doc = json.loads((root / SUITE_FILE).read_text())
        members = [(str(m["title"]), root / str(m["directory"])) for m in doc["members"]]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise CampaignDirError(f"{root / SUITE_FILE} is damaged ({exc}); rerun 'fdd-campaign run' "
                         "on the suite into this directory") from None
    missing = [str(d) for _, d in members if not d.is_dir()]
    if missing:
        raise CampaignDirError(f"{root} is a suite directory whose member(s) {', '.join(missing)} "
                         "have not run yet; rerun 'fdd-campaign run' on the suite into it")
    return members


def suite_references(directory) -> dict[str, str]:
    """Member directory name → the published table its suite member names (``reference``);
    members without one, and suites written before the key existed, are left out."""
    try:
        doc = json.loads((Path(directory) / SUITE_FILE).read_text())
        return {str(m["directory"]): str(m["reference"]) for m in doc["members"]
                if m.get("reference") in PAPER_TABLES}
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return {}


def reference_text(directory, summary) -> str:
    """The published table a suite member names (``reference``) beside *summary*
    (:func:`reports.render.table.format_paper_table`), after a blank line, when *directory* is
    that member's directory inside a suite directory; '' otherwise (a campaign run alone,
    a member without ``reference``, no results yet)."""
    from reports.render.table import format_paper_table

    path = Path(directory)
    reference = suite_references(path.parent).get(path.name) if is_suite_dir(path.parent) \
        else None
    if not reference or summary is None or len(summary) == 0:
        return ""
    return "\n\n" + format_paper_table(summary, reference, _required_times(path))


def _required_times(directory: Path) -> dict | None:
    """The member's required detection times (fault → s) from its stored ``campaign.json``;
    None when they cannot be read (the table then names them without values)."""
    try:
        times = json.loads((directory / "campaign.json").read_text())["requirements"][
            "detection_time_s"]
        return {str(f): float(t) for f, t in dict(times).items()}
    except (OSError, ValueError, KeyError, TypeError):
        return None
