"""The learning set is simulated on the workers that run the campaign's chunks (worker
processes for any plant, worker threads for a plant that runs on threads), and its signals,
so the fitted detectors, are those of one process (campaign.runner._fitted)."""

from __future__ import annotations

import pytest

import campaign.runner as runner
from campaign.config import CampaignConfig
from campaign.runner import run

from small_campaigns import small_campaign


@pytest.fixture
def parts(monkeypatch):
    """The workers each call of simulate_chunks was given (None: simulated in this process)."""
    seen = []
    real = runner.simulate_chunks

    def recorded(plan, settings, chunk_size, submit=None, workers=1):
        seen.append(workers if submit is not None else None)
        return real(plan, settings, chunk_size, submit=submit, workers=workers)

    monkeypatch.setattr(runner, "simulate_chunks", recorded)
    return seen


def _fitted_bytes(directory) -> dict:
    return {p.name: p.read_bytes() for p in sorted((directory / "fitted").iterdir())}


@pytest.mark.parametrize("kind, backend", [("aircraft", "loky"), ("aircraft", "threading")])
def test_the_learning_set_runs_on_the_campaigns_workers(tmp_path, parts, kind, backend):
    cfg = small_campaign("learn-on-workers", 6029, [], learning_runs=3)
    cfg["plant"] = {"kind": kind}
    config = CampaignConfig.from_dict(cfg, "test")
    quiet = {"progress": False, "log": lambda m: None}
    run(config, tmp_path / "one", jobs=1, **quiet)
    run(config, tmp_path / "two", jobs=2, backend=backend, **quiet)
    # one process alone, then the two workers of the pool
    assert parts == [None, 2]
    # the 6 learning runs' signals are the same wherever they were simulated: the fitted
    # position monitor (its bands are functions of every learning sample) is byte for byte
    assert _fitted_bytes(tmp_path / "two") == _fitted_bytes(tmp_path / "one")
