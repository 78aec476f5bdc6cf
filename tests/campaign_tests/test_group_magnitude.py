"""A ``[[group]]`` that fixes ``magnitude``: read in the unit of its fault's ``[faults.*]``
range and kept in both directions unless ``sign`` is given (docs/campaign-file.md, "Fault
magnitudes"; the run table holds the rod bias/offset in mm, docs/physics.md §5)."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from campaign.config import CampaignConfig
from campaign.plan import build_plan

#: The elevator actuator: r = 120 mm, electrical limits −30 … +15° = 45° (docs/physics.md §3)
R_MM, RANGE_DEG = 120.0, 45.0


def plan_of(group: dict, **faults) -> np.ndarray:
    data = {
        "campaign": {"name": "mag", "seed": 3, "duration_s": 30.0},
        "faults": {"onset_min_s": 5.0, "onset_before_end_s": 10.0, **faults},
        "group": [{"name": "g", "manoeuvres": ["cruise"], "count": 60, **group}],
        "detector": [{"name": "position-monitor"}],
    }
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        cfg = CampaignConfig.from_dict(data)
    return build_plan(cfg)["magnitude"].to_numpy()


def both_directions(mags: np.ndarray) -> bool:
    # 60 fair signs: 15 ≤ positives ≤ 45 fails with probability 1e-4 (binomial)
    return 15 <= int((mags > 0).sum()) <= 45


def test_a_liquid_jam_magnitude_is_a_share_of_the_deflection_range():
    mags = plan_of({"fault": "liquid_jam", "magnitude": 6.7})
    # 6.7 % of 45° = 3.015° of surface → r·sin(3.015°) of rod bias
    expected = R_MM * math.sin(math.radians(0.067 * RANGE_DEG))
    assert np.abs(mags) == pytest.approx(np.full(60, expected), rel=1e-12)
    assert both_directions(mags)


def test_an_offset_solid_jam_magnitude_is_a_share_of_the_deflection_range():
    mags = plan_of({"fault": "solid_jam", "variant": "offset", "magnitude": 1.8})
    expected = R_MM * math.sin(math.radians(0.018 * RANGE_DEG))
    assert np.abs(mags) == pytest.approx(np.full(60, expected), rel=1e-12)
    assert both_directions(mags)


def test_a_runaway_rate_keeps_both_directions_unless_a_sign_is_given():
    mags = plan_of({"fault": "runaway", "magnitude": 5.0})
    assert set(np.abs(mags)) == {5.0}
    assert both_directions(mags)
    fixed = plan_of({"fault": "runaway", "magnitude": 5.0, "sign": "negative"})
    assert (fixed == -5.0).all()


def test_an_ofc_amplitude_has_no_direction():
    mags = plan_of({"fault": "ofc_solid", "magnitude": 0.7, "freq_hz": 2.0})
    assert (mags == 0.7).all()


def test_loading_says_how_a_fixed_magnitude_is_read():
    data = {
        "campaign": {"name": "mag", "seed": 3, "duration_s": 30.0},
        "group": [{"name": "g", "fault": "liquid_jam", "manoeuvres": ["cruise"],
                   "count": 2, "magnitude": 2.0}],
        "detector": [{"name": "position-monitor"}],
    }
    with pytest.warns(FutureWarning) as notes:
        CampaignConfig.from_dict(data)
    texts = [str(n.message) for n in notes]
    assert any("% of the deflection range" in t for t in texts)
    assert any("direction is drawn per run" in t and 'sign = "positive"' in t for t in texts)
    data["group"][0]["sign"] = "positive"
    with pytest.warns(FutureWarning) as notes:
        CampaignConfig.from_dict(data)
    assert not any("direction" in str(n.message) for n in notes)
