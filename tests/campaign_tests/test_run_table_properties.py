"""Properties of the run table and its seeding (docs/design.md §9, docs/physics.md §5–6).

What the documents promise of ``campaign.plan.build_plan`` / ``build_learning_plan`` and
``scenarios.runs.run_streams``: learning and evaluation runs share neither a simulation
stream nor a flight point; the uncertainty draws are symmetric around 0 with the documented
half-widths; a fault with a direction comes in both directions; and a run id is the hash of
the row and the model version, pinned here as a literal.
"""

from __future__ import annotations

import hashlib
import json
import math

import numpy as np
import pytest

from campaign.plant_setup import resolve
from campaign.config import CampaignConfig
from campaign.plan import LEARNING_STREAM_BASE, build_learning_plan, build_plan, run_id
from scenarios.faults import liquid_jam_bias_mm
from scenarios.params import ELEVATOR
from scenarios.runs import run_streams

#: docs/physics.md §6: Table-2 half-widths and the mismatch half-widths
HALF_WIDTHS = {"d_cx": 0.05, "d_cy": 0.05, "d_cz": 0.05, "d_cl": 0.05, "d_cm": 0.05,
               "d_cn": 0.05, "d_vcas": 0.10, "d_alt": 0.10, "d_mass": 0.10, "d_cg": 0.10,
               "d_supply": 0.05, "d_kci": 0.05, "d_ch0": 0.20, "d_cha": 0.20, "d_chd": 0.20}


def config(**over) -> CampaignConfig:
    data = {
        "campaign": {"name": "props", "seed": 11, "duration_s": 30.0},
        "faults": {"onset_min_s": 5.0, "onset_before_end_s": 10.0,
                   "liquid_jam": {"bias_pct_range": [1.0, 2.0]}},
        "group": [
            {"name": "ff", "fault": "none", "manoeuvres": ["cruise", "nose_up"], "count": 100},
            {"name": "ra", "fault": "runaway", "manoeuvres": ["cruise"], "count": 60},
            {"name": "ho", "fault": "hardover", "manoeuvres": ["cruise"], "count": 60},
            {"name": "lj", "fault": "liquid_jam", "manoeuvres": ["cruise"], "count": 60},
        ],
        "detector": [{"name": "position-monitor"}],
        "learning": {"runs_per_manoeuvre": 40, "manoeuvres": ["cruise", "nose_up"]},
    }
    data.update(over)
    return CampaignConfig.from_dict(data)


@pytest.fixture(scope="module")
def plans():
    cfg = config()
    resolved = resolve(cfg)
    return cfg, build_plan(resolved), build_learning_plan(resolved)


POINT = ["alt_ft", "vcas_kt", "mass_t", "cg_pct"]


def test_learning_and_evaluation_share_no_stream_and_no_flight_point(plans):
    _, plan, learn = plans
    # docs/design.md §9: evaluation run i uses stream i, the learning set 2³² + j
    assert list(plan["stream"]) == list(range(len(plan)))
    assert list(learn["stream"]) == list(range(LEARNING_STREAM_BASE,
                                               LEARNING_STREAM_BASE + len(learn)))
    assert LEARNING_STREAM_BASE == 2 ** 32
    # the design streams too: no flight point (nor uncertainty draw) appears in both sets
    # (continuous draws: a shared value can only come from a shared design stream)
    key = POINT + list(HALF_WIDTHS)
    ev = set(map(tuple, plan[key].to_numpy()))
    le = set(map(tuple, learn[key].to_numpy()))
    assert not ev & le
    for col in POINT:
        assert not set(plan[col]) & set(learn[col]), col
    # nor two cells of the evaluation plan, nor two learning manoeuvres
    per_cell = plan.groupby(["group", "manoeuvre"])["alt_ft"].apply(frozenset)
    cells = list(per_cell)
    assert all(not (a & b) for i, a in enumerate(cells) for b in cells[i + 1:])
    lm = list(learn.groupby("manoeuvre")["alt_ft"].apply(frozenset))
    assert not (lm[0] & lm[1])
    assert not set(learn["run_id"]) & set(plan["run_id"])


def test_run_streams_are_the_documented_seed_sequences():
    # docs/design.md §9: SeedSequence(seed, spawn_key=(stream,)) spawned into a manoeuvre
    # stream and a sensor stream, in that order
    man, sens = run_streams(11, 5)
    ss = np.random.SeedSequence(11, spawn_key=(5,))
    a, b = ss.spawn(2)
    assert man.random() == np.random.default_rng(a).random()
    assert sens.random() == np.random.default_rng(b).random()
    # made without the parent, they are its spawned children exactly: the same states, for
    # small and large seeds and streams (the plan's seeds, and LEARNING_STREAM_BASE's range)
    for seed in (0, 1, 9091, 2**31 - 1, 2**63 - 1):
        for stream in (0, 1, 2399, 10**6, 2**32, 2**32 + 299, 2**40 + 7):
            kids = np.random.SeedSequence(seed, spawn_key=(stream,)).spawn(2)
            assert ([g.bit_generator.state for g in run_streams(seed, stream)]
                    == [np.random.default_rng(k).bit_generator.state for k in kids])
    # the two streams of a run, and the same stream of two runs, differ
    m0, s0 = run_streams(11, 5)
    m1, _ = run_streams(11, 6)
    m2, _ = run_streams(12, 5)
    draws = [g.random(4).tolist() for g in (m0, s0, m1, m2)]
    assert len({tuple(d) for d in draws}) == 4


def test_uncertainty_draws_are_symmetric_with_the_documented_half_widths(plans):
    _, plan, learn = plans
    for frame in (plan, learn):
        n = len(frame)
        for col, w in HALF_WIDTHS.items():
            v = frame[col].to_numpy()
            assert (np.abs(v) <= w + 1e-12).all(), col
            # both signs, reaching near both ends: for n ≥ 80 iid uniforms P(max < 0.9 w)
            # = 0.95^n < 2e-2, and the scrambled Sobol points fill the range better
            assert v.min() < -0.8 * w and v.max() > 0.8 * w, col
            # mean of U(−w, w): standard error w/sqrt(3n); 4 standard errors (one false
            # failure in 15 000 for iid draws; Sobol means are closer still)
            assert abs(v.mean()) < 4 * w / math.sqrt(3 * n), col


def test_monte_carlo_draws_each_coefficient_independently(plans):
    """docs/physics.md §6: the six aerodynamic and the three hinge-moment draws are separate
    dimensions of the design, not one factor: no two are equal, and their sample
    correlations stay within 4/sqrt(n) of 0 (independent uniforms: standard error 1/sqrt(n))."""
    _, plan, _ = plans
    cols = [c for c in HALF_WIDTHS
            if c[2:] in ("cx", "cy", "cz", "cl", "cm", "cn", "ch0", "cha", "chd")]
    assert len(cols) == 9
    corr = np.corrcoef(plan[cols].to_numpy().T)
    off = corr[~np.eye(len(cols), dtype=bool)]
    assert np.abs(off).max() < 4 / math.sqrt(len(plan)), np.abs(off).max()


def test_a_coefficient_key_wins_over_its_shorthand():
    """[uncertainty] aero / [mismatch] hinge set every coefficient not given by its own key
    (docs/campaign-file.md); a campaign file without the new keys keeps its meaning."""
    cfg = config(uncertainty={"aero": 0.02, "cm": 0.08}, mismatch={"hinge": 0.1, "ch0": 0.4})
    plan = build_plan(cfg)
    assert np.abs(plan["d_cm"]).max() > 0.9 * 0.08
    for c in ("d_cx", "d_cy", "d_cz", "d_cl", "d_cn"):
        assert np.abs(plan[c]).max() <= 0.02 and np.abs(plan[c]).max() > 0.9 * 0.02, c
    assert np.abs(plan["d_ch0"]).max() > 0.9 * 0.4
    assert 0.9 * 0.1 < np.abs(plan["d_chd"]).max() <= 0.1
    old = build_plan(config(uncertainty={"aero": 0.02}))
    assert all(0.9 * 0.02 < np.abs(old[f"d_{c}"]).max() <= 0.02
               for c in ("cx", "cy", "cz", "cl", "cm", "cn"))


def test_grid_levels_put_every_deviation_at_its_bound():
    cfg = config(campaign={"name": "g", "seed": 3, "duration_s": 30.0, "design": "grid"},
                 group=[{"name": "ff", "fault": "none", "manoeuvres": ["cruise"]}])
    plan = build_plan(cfg)
    for level, factor in (("min", -1.0), ("nominal", 0.0), ("max", 1.0)):
        rows = plan[plan["level"] == level]
        assert len(rows) == 53                        # docs/physics.md §6: 53 realistic points
        for col, w in HALF_WIDTHS.items():
            assert (rows[col] == factor * w).all(), (level, col)


def test_fault_magnitudes_come_in_both_directions_within_their_ranges(plans):
    _, plan, _ = plans
    ra = plan.loc[plan["fault"] == "runaway", "magnitude"].to_numpy()
    # docs/physics.md §5: rate U(1, 10) °/s with a random sign
    assert ((np.abs(ra) >= 1.0) & (np.abs(ra) <= 10.0)).all()
    ho = plan.loc[plan["fault"] == "hardover", "magnitude"].to_numpy()
    assert set(ho) == {-1.0, 1.0}
    lj = plan.loc[plan["fault"] == "liquid_jam", "magnitude"].to_numpy()
    lo, hi = liquid_jam_bias_mm(ELEVATOR, 1.0), liquid_jam_bias_mm(ELEVATOR, 2.0)
    assert ((np.abs(lj) >= lo - 1e-12) & (np.abs(lj) <= hi + 1e-12)).all()
    assert lo == pytest.approx(120 * math.sin(math.radians(0.45)), rel=1e-12)
    for name, mags in (("runaway", ra), ("hardover", ho), ("liquid_jam", lj)):
        pos = int((mags > 0).sum())
        # 60 fair signs: 15 ≤ positives ≤ 45 fails with probability 1e-4 (binomial)
        assert 15 <= pos <= 45, name


@pytest.mark.parametrize("sign, expected", [("positive", 1.0), ("negative", -1.0)])
def test_a_fixed_sign_is_applied(sign, expected):
    cfg = config(group=[{"name": "ra", "fault": "runaway", "manoeuvres": ["cruise"],
                         "count": 20, "sign": sign}])
    mags = build_plan(cfg)["magnitude"].to_numpy()
    assert (np.sign(mags) == expected).all()


def test_onsets_are_on_the_time_grid_inside_the_documented_interval(plans):
    cfg, plan, _ = plans
    onset = plan.loc[plan["fault"] != "none", "onset_s"].to_numpy()
    # docs/physics.md §5: uniform in [onset_min, duration − onset_before_end] = [5, 20] s
    assert onset.min() >= 5.0 and onset.max() <= 20.0
    assert onset.max() - onset.min() > 10.0            # spread over the interval
    steps = onset / cfg.campaign.ts_s
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-6)
    assert plan.loc[plan["fault"] == "none", "onset_s"].isna().all()


#: A fixed run row (no run_id) and its id: sha256 of "servo-6|" + canonical JSON, first 20
#: hex digits. If the model version or the hashing scheme must change, every stored result
#: becomes a different run: update this literal knowingly. Changed with model version 2
#: (servo-2: one draw per aerodynamic and per hinge-moment coefficient, in place of d_aero
#: and d_hinge; surface coupling; aft-loaded aileron hinge moment, docs/physics.md) and 3
#: (servo-3: the aircraft laws' gains of a run independent of its block at round-off) and 4
#: (servo-4: drawn onsets leave the fault's detection budget, campaign.plan; the aircraft
#: plant's angle-of-attack sensor) and 5 (servo-5: the aircraft laws' scheduled short period,
#: filters and rate limits, docs/aircraft.md §4) and 6 (servo-6: the JSBSim plant flies the
#: coefficient errors and places its laws at the measured point, docs/aircraft.md §9.1).
GOLDEN_ROW = {"group": "g", "surface": "elevator", "manoeuvre": "cruise", "fault": "runaway",
              "onset_s": 12.5, "magnitude": -4.0, "freq_hz": float("nan"), "alt_ft": 28000.0,
              "vcas_kt": 300.0, "mass_t": 180.0, "cg_pct": 30.0, "level": "mc",
              "realistic": True, "point": -1, "d_cx": 0.01, "d_cy": -0.01, "d_cz": 0.02,
              "d_cl": 0.0, "d_cm": -0.03, "d_cn": 0.04, "d_vcas": -0.02, "d_alt": 0.0,
              "d_mass": 0.0, "d_cg": 0.0, "d_supply": 0.0, "d_kci": 0.0, "d_ch0": 0.1,
              "d_cha": -0.1, "d_chd": 0.05, "seed": 7, "stream": 3, "duration_s": 30.0}
GOLDEN_ID = "52a89b7dd0c7b23a5fe4"


def test_golden_run_id():
    assert run_id(dict(GOLDEN_ROW)) == GOLDEN_ID
    # a NaN optional column (manoeuvre_start_s) leaves the id unchanged; its id field too
    assert run_id({**GOLDEN_ROW, "manoeuvre_start_s": float("nan"), "run_id": "x"}) == GOLDEN_ID
    # the scheme, by hand: NaN → null, sorted keys, compact separators, "servo-6|" prefix
    payload = {k: (None if isinstance(v, float) and math.isnan(v) else v)
               for k, v in GOLDEN_ROW.items()}
    text = json.dumps(payload, sort_keys=True, separators=(",", ":"))
    assert hashlib.sha256(("servo-6|" + text).encode()).hexdigest()[:20] == GOLDEN_ID


@pytest.mark.parametrize("field, value", [("stream", 4), ("seed", 8), ("magnitude", 4.0),
                                          ("onset_s", 12.51), ("manoeuvre_start_s", 4.0)])
def test_every_field_is_part_of_the_id(field, value):
    assert run_id({**GOLDEN_ROW, field: value}) != GOLDEN_ID


def test_plan_ids_are_the_ids_of_their_rows(plans):
    _, plan, learn = plans
    for frame in (plan, learn):
        rows = frame.head(5).to_dict(orient="records")
        assert [run_id(r) for r in rows] == list(frame["run_id"].head(5))
        assert frame["run_id"].is_unique
