"""Small campaigns for the tests that run a third-party detector end to end: a 20 s campaign
of fault-free cruise / nose-up runs and elevator runaways, the named detectors and the
position monitor (label ``pm``), and its TOML text for the tests that go through a file."""

from __future__ import annotations

from campaign.config.text import toml_value


def small_campaign(name: str, seed: int, detectors, *, free: int = 3, pm_first: bool = True,
                   learning_runs: int = 2, learning_manoeuvres=("cruise", "nose_up"),
                   runner: dict | None = None) -> dict:
    """The campaign dict: *free* fault-free runs per manoeuvre (cruise, nose_up), two
    runaways in cruise (onsets between 5 s and 15 s), the *detectors* (``[[detector]]``
    tables) before or after the position monitor (*pm_first*)."""
    pm = {"name": "position-monitor", "label": "pm"}
    return {
        "campaign": {"name": name, "seed": seed, "duration_s": 20.0},
        "faults": {"onset_min_s": 5.0, "onset_before_end_s": 5.0},
        "group": [
            {"name": "ff", "fault": "none", "manoeuvres": ["cruise", "nose_up"], "count": free},
            {"name": "ra", "fault": "runaway", "manoeuvres": ["cruise"], "count": 2},
        ],
        "detector": [pm, *detectors] if pm_first else [*detectors, pm],
        "learning": {"runs_per_manoeuvre": learning_runs,
                     "manoeuvres": list(learning_manoeuvres)},
        "runner": dict(runner or {"chunk_size": 4}),
    }


def campaign_toml(cfg: dict) -> str:
    """A campaign dict as the text of a campaign file (values written by the project's own
    :func:`campaign.config.text.toml_value`)."""
    lines = []
    for section, body in cfg.items():
        for table in body if isinstance(body, list) else [body]:
            lines.append(f"[[{section}]]" if isinstance(body, list) else f"[{section}]")
            lines += [f"{k} = {toml_value(v)}" for k, v in table.items()]
    return "\n".join(lines) + "\n"
