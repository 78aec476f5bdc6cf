"""The former names a user's code or installed script may still use: each still answers,
as its new name does, with a deprecation note where Python code calls it."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest

import campaign.cli
from campaign.cli import commands
from campaign.result import Campaign


def test_campaign_out_is_its_root_with_a_deprecation_warning():
    # the object campaign.run returned before Campaign had ``out``, not ``root``
    held = SimpleNamespace(root=Path("/some/campaign"))
    with pytest.warns(DeprecationWarning, match="Campaign.root"):
        assert Campaign.out.fget(held) == Path("/some/campaign")


def test_old_console_script_entry_runs_the_executable(monkeypatch):
    # an installation made before the entry point moved calls
    # campaign.cli.commands:console_main; it must run the one executable
    calls = []
    monkeypatch.setattr(campaign.cli, "console_main", lambda: calls.append("ran"))
    commands.console_main()
    assert calls == ["ran"]
