"""A campaign is resolved once (campaign.plant_setup.resolve): its plant is built once per
run and handed down to the run table, the learning set, the workers and the gate; the seed
and the chunk size arrive with it."""

from __future__ import annotations

import pandas as pd
import pytest

import campaign.plant_setup as plant_setup
from campaign.config import CampaignConfig, with_overrides
from campaign.plan import build_plan
from campaign.plant_setup import resolve
from campaign.runner import run

from small_campaigns import small_campaign


@pytest.fixture
def built(monkeypatch):
    """Every plant the campaign modules build, counted (plant_of is the one constructor)."""
    made = []
    real = plant_setup.plant_of

    def counted(config):
        made.append(config.plant.kind)
        return real(config)

    monkeypatch.setattr(plant_setup, "plant_of", counted)
    return made


def test_a_run_builds_its_plant_once(tmp_path, built):
    # two groups × two manoeuvres of plan cells and a learning set of its own cells: each
    # cell took the surface and actuator of a plant built again before
    config = CampaignConfig.from_dict(small_campaign("once", 4711, []), "test")
    camp = run(config, tmp_path / "out", jobs=1, progress=False, log=lambda m: None)
    assert built == ["actuator"]
    # the gate reads the roles the run resolved: none rebuilt for it either
    assert camp.gate().checks
    assert built == ["actuator"]


def test_seed_and_chunk_size_arrive_with_the_resolved_campaign(tmp_path, built):
    config = CampaignConfig.from_dict(small_campaign("seeded", 4711, []), "test")
    resolved = resolve(config, seed=90210, chunk_size=3)
    assert (resolved.seed, resolved.chunk_size) == (90210, 3)
    assert resolved.surface == "elevator" and resolved.isolation == {}
    # the rows are those of the campaign file with that seed, whichever way it came
    by_file = build_plan(with_overrides(config, seed=90210))
    pd.testing.assert_frame_equal(build_plan(resolved), by_file)
    camp = run(config, tmp_path / "out", jobs=1, chunk_size=3, seed=90210, progress=False,
               log=lambda m: None)
    assert camp.config.campaign.seed == 90210
    assert sorted(camp.plan["run_id"]) == sorted(by_file["run_id"])
    # resolve (1), the file's plan (1), the run (1): one each
    assert len(built) == 3
