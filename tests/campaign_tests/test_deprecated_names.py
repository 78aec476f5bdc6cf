"""The former names a user's code or installed script may still use: each still answers,
as its new name does, with a deprecation note where Python code calls it."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest

from campaign.cli import commands
from campaign.result import Campaign


def test_campaign_out_is_its_root_with_a_deprecation_warning():
    # the object campaign.run returned before Campaign had ``out``, not ``root``
    held = SimpleNamespace(root=Path("/some/campaign"))
    with pytest.warns(DeprecationWarning, match="Campaign.root"):
        assert Campaign.out.fget(held) == Path("/some/campaign")


def test_old_console_script_entry_runs_the_command_line(monkeypatch):
    # an installation made before the entry point moved calls
    # campaign.cli.commands:console_main: it runs the command line and leaves with its code
    left = []
    monkeypatch.setattr("campaign.startup.defer_collection", lambda: None)   # keep the gc on
    monkeypatch.setattr(commands, "main", lambda: 2)
    monkeypatch.setattr(commands, "leave", left.append)
    commands.console_main()
    assert left == [2]
