"""Shipped presets and suites load without a note or warning; a user's file still gets the
one-line note that a liquid jam's [[group]] magnitude is read in % (once, not again when it is
re-validated with overrides such as --seed)."""

import warnings

import pytest

from campaign.config import load_config
from campaign.config.load import PRESET_DIR, preset_path, shipped_names, with_overrides
from campaign.config.rules import MagnitudeReadingNote


@pytest.mark.parametrize("name", shipped_names(PRESET_DIR))
def test_every_shipped_preset_loads_silently(name):
    with warnings.catch_warnings():
        warnings.simplefilter("error")          # any note or warning fails
        config = load_config(name)
        with_overrides(config, seed=9091)       # as `run PRESET --seed S` does


def test_a_users_file_gets_the_magnitude_note_once(tmp_path):
    path = tmp_path / "mine.toml"
    path.write_text(preset_path("vanek-scenarios").read_text())   # a liquid-jam magnitude
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        config = load_config(str(path))
        with_overrides(config, seed=5150)
    notes = [w for w in seen if issubclass(w.category, MagnitudeReadingNote)]
    assert len(notes) == 1 and "group[1].magnitude = 6.7" in str(notes[0].message)
    assert issubclass(MagnitudeReadingNote, FutureWarning)         # printed as "note:"
