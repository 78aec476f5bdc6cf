"""``fdd-campaign study chen-flight-data`` (campaign/tools/studies/chen_flight_data.py): the
campaigns it runs are chen-mc with [CHEN] Table 2's flight-data errors at another half-width,
and what the mc design draws for them (docs/chen-estimator.md §5.2)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from campaign.config import ConfigError
from campaign.plan import build_plan
from campaign.tools.studies.chen_flight_data import (
    DELAY_LIMIT_S,
    DETECTORS,
    campaign_for,
    run_study,
)

FLIGHT_DATA = ("d_vcas", "d_alt", "d_mass", "d_cg")


def test_each_level_is_chen_mc_with_its_flight_data_errors():
    c = campaign_for(0.02, seed=5)
    u = c.uncertainty
    assert (u.vcas, u.alt, u.mass, u.cg, u.aero) == (0.02, 0.02, 0.02, 0.02, 0.05)
    assert c.campaign.seed == 5 and c.plant.turbulence == "none"
    assert {g.fault: g.count for g in c.groups} == {"none": 200, "disconnection": 334}
    assert [(d.name, d.label) for d in c.detectors] == [(n, lab) for n, lab, _ in DETECTORS]
    assert dict(c.detectors[1].params) == {}           # [CHEN]'s rule, the default
    assert dict(c.detectors[2].params) == {"threshold_method": "evt"}
    names = {campaign_for(w).campaign.name for w in (0.1, 0.05, 0.02, 0.0)}
    assert len(names) == 4                    # one directory per level
    small = campaign_for(0.1, fault_free=3, disconnections=4, learning_runs=5,
                         turbulence="moderate")
    assert {g.fault: g.count for g in small.groups} == {"none": 3, "disconnection": 4}
    assert small.learning.runs_per_manoeuvre == 5 and small.plant.turbulence == "moderate"


@pytest.mark.parametrize("level, field", [(0.6, "uncertainty.vcas"), (-0.01, "uncertainty.vcas")])
def test_a_level_out_of_range_is_named(level, field):
    with pytest.raises(ConfigError, match=field):
        campaign_for(level)


def test_the_flight_data_errors_are_drawn_uniformly_and_independently_per_run():
    """What the docs state of Table 2's errors in the mc design: each run draws each of the
    four flight-data errors over the whole band ±w, uniformly (a Sobol dimension of its own:
    the quarters of the band hold a quarter of the runs each, within 3 points of a percent
    on 1 534 runs), not tied to one another: pooled over the campaign's cells the sample
    correlations are below 0.15. (Within one cell of 200 runs the VCAS and altitude errors
    correlate by ±0.06–0.19, measured at seeds 0, 1, 2 and 52813: a property of the first
    200 points of a scrambled Sobol sequence; pooled, 0.02–0.08.)"""
    plan = build_plan(campaign_for(0.02))
    d = plan[list(FLIGHT_DATA)].to_numpy(float)
    assert np.abs(d).max() <= 0.02 and np.abs(d).max() > 0.0195
    for j in range(4):
        quarters = np.histogram(d[:, j], bins=4, range=(-0.02, 0.02))[0] / len(d)
        np.testing.assert_allclose(quarters, 0.25, atol=0.03)
    corr = np.corrcoef(d.T) - np.eye(4)
    assert np.abs(corr).max() < 0.15, corr


@pytest.mark.slow
def test_the_study_table_counts_what_the_stored_runs_say(tmp_path):
    """The printed table against a recount of the stored rows: a false alarm is a fault-free
    run whose margin reached 1 (the alarm decision), a miss a disconnection with no alarm,
    a delay the first alarm minus the plan's onset; the worst margin is the largest one."""
    from campaign.result import load

    counts = {"fault_free": 2, "disconnections": 4, "learning_runs": 5}
    table = run_study(tmp_path, seed=1234, levels=(0.02,), jobs=1, progress=False,
                      echo=lambda *a: None, **counts)
    camp = load(tmp_path / campaign_for(0.02, 1234, **counts).campaign.name)
    onset = pd.read_parquet(camp.root / "plan.parquet").set_index("run_id")["onset_s"]
    assert list(table["detector"]) == [label for _, label, _ in DETECTORS]
    for row in table.itertuples():
        r = camp.results[camp.results["detector"] == row.detector]
        free, disc = r[r["fault"] == "none"], r[r["fault"] == "disconnection"]
        assert (row.fault_free, row.faulty) == (12, 4)
        assert row.fa == int((free["margin"] >= 1.0).sum())
        assert row.worst_margin == free["margin"].max()
        alarm = disc["first_alarm_s"].to_numpy(float)
        assert row.pre_onset == int((alarm < onset[disc["run_id"]].to_numpy()).sum())
        assert row.md == int(np.isnan(alarm).sum())
        delays = np.sort(alarm - onset[disc["run_id"]].to_numpy())
        delays = delays[np.isfinite(delays)]
        if delays.size:
            assert row.delay_min_s == pytest.approx(delays[0], abs=1e-9)
            assert row.delay_max_s == pytest.approx(delays[-1], abs=1e-9)
            assert row.delay_median_s == pytest.approx(float(np.median(delays)), abs=1e-9)
            assert row.over_limit == int((delays > DELAY_LIMIT_S + 1e-9).sum())
    # the default chen-global-paper is [CHEN]'s rule: τ0 = 1.5 × the largest learning value
    assert camp.fitted["chen-global-paper"].threshold_method == "max"
