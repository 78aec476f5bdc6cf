"""The values ``campaign.plan`` writes into a run table, pinned one by one.

docs/design.md §3 step 2 and §9: every sampled value is a column of the run table, the
table is fixed before any run, and the same campaign file gives the same table on every
machine and in every version of the same model. What is checked here, independent of the
sampling code: each sampled value lies in its documented range and scales over all of it;
each fixed group key (onset, magnitude, frequency, sign, flight point, manoeuvre start)
replaces its sampled value; explicit ``[[run]]`` entries keep every value and their stream;
and a golden digest of whole run tables pins the sampling scheme (the design's spawn keys,
the Sobol sequence, the scaling), so that a change of it, which would silently change every
campaign's runs, is made knowingly.
"""

from __future__ import annotations

import hashlib
import math

import numpy as np
import pandas as pd
import pytest

from campaign.plant_setup import resolve
from campaign.config import CampaignConfig
from campaign.plan import (LEARNING_STREAM_BASE, MODEL_VERSION, PLAN_COLUMNS,
                             build_learning_plan, build_plan, explicit_plan, explicit_rows,
                             plan_counts, run_id)
from scenarios.catalog import MANOEUVRES
from scenarios.faults import liquid_jam_bias_mm, solid_jam_offset_mm
from scenarios.params import ELEVATOR

TS = 0.01                                   # campaign ts_s default [s]


def config(groups, **over) -> CampaignConfig:
    data = {
        "campaign": {"name": "values", "seed": 5, "duration_s": 40.0},
        "faults": {"onset_min_s": 6.0, "onset_before_end_s": 12.0,
                   "liquid_jam": {"bias_pct_range": [1.0, 2.0]},
                   "solid_jam": {"offset_pct_range": [1.0, 3.0]}},
        "group": groups,
        "detector": [{"name": "position-monitor"}],
        "learning": {"runs_per_manoeuvre": 7, "manoeuvres": ["cruise", "nose_up"]},
    }
    for key, value in over.items():
        data[key] = {**data.get(key, {}), **value} if isinstance(value, dict) else value
    return CampaignConfig.from_dict(data)


ALL_FAULTS = [
    {"name": "ff", "fault": "none", "manoeuvres": ["cruise", "nose_up"], "count": 5},
    {"name": "ra", "fault": "runaway", "manoeuvres": ["cruise"], "count": 5},
    {"name": "ho", "fault": "hardover", "manoeuvres": ["cruise"], "count": 5},
    {"name": "lj", "fault": "liquid_jam", "manoeuvres": ["cruise"], "count": 5},
    {"name": "sj", "fault": "solid_jam", "manoeuvres": ["cruise"], "count": 5},
    {"name": "so", "fault": "solid_jam", "variant": "offset", "manoeuvres": ["cruise"],
     "count": 5},
    {"name": "dc", "fault": "disconnection", "manoeuvres": ["cruise"], "count": 5},
    {"name": "ol", "fault": "ofc_liquid", "manoeuvres": ["cruise"], "count": 5},
    {"name": "os", "fault": "ofc_solid", "manoeuvres": ["cruise"], "count": 5},
]


def digest(plan: pd.DataFrame) -> str:
    """First 16 hex digits of the sha256 of the run ids in order (a run id hashes every
    value of its row, so this pins the whole table)."""
    return hashlib.sha256("\n".join(plan["run_id"]).encode()).hexdigest()[:16]


@pytest.fixture(scope="module")
def plan():
    return build_plan(config(ALL_FAULTS))


# ---- golden tables: the sampling scheme ------------------------------------------------------
#: Digests of whole run tables (see :func:`digest`). They change when the sampling scheme
#: (spawn keys, sequence, scaling of the unit samples), a default range, the run-id scheme or
#: MODEL_VERSION changes: each such change gives every campaign other runs, so update these
#: literals knowingly, together with MODEL_VERSION where the model changed (servo-3: each
#: table's digest under servo-2 was checked equal to the literal it replaces, so only the
#: version in the ids changed; servo-4: with the version alone changed, only the onsets of
#: the disconnection rows differ, all now ≤ duration − its 15 s detection budget; servo-5:
#: each table's digest under servo-4 was checked equal to the literal it replaces, so only
#: the version in the ids changed; servo-6: each table's digest under servo-5 was checked
#: equal to the literal it replaces and each table equal but for its ids).
GOLDEN = {
    "mc": "1ce82be4064853a1",
    "learning": "ac7f5d76d1bc2889",
    "random": "0a6ed589904fa4aa",
    "grid": "41a1b9c9ee67e7aa",
    "not-realistic-only": "65fa1bb76a383fea",
}


def test_golden_monte_carlo_plan(plan):
    assert MODEL_VERSION == "servo-6"
    assert digest(plan) == GOLDEN["mc"]


def test_golden_learning_plan():
    assert digest(build_learning_plan(resolve(config(ALL_FAULTS)))) == GOLDEN["learning"]


def test_golden_random_sampler_plan():
    cfg = config(ALL_FAULTS[:4], campaign={"sampler": "random"})
    assert digest(build_plan(cfg)) == GOLDEN["random"]


def test_golden_grid_plan():
    cfg = config([{"name": "g", "fault": "runaway", "manoeuvres": ["cruise"]}],
                 campaign={"design": "grid"})
    assert digest(build_plan(cfg)) == GOLDEN["grid"]


def test_golden_plan_without_the_realistic_rule():
    cfg = config(ALL_FAULTS[:2], campaign={"realistic_only": False})
    assert digest(build_plan(cfg)) == GOLDEN["not-realistic-only"]


# ---- sampled values: ranges and scaling ------------------------------------------------------
def test_columns_streams_and_cells(plan):
    assert tuple(plan.columns) == PLAN_COLUMNS
    assert plan.index.equals(pd.RangeIndex(len(plan)))
    assert list(plan["stream"]) == list(range(len(plan)))
    assert (plan["seed"] == 5).all() and (plan["duration_s"] == 40.0).all()
    assert (plan["level"] == "mc").all() and (plan["point"] == -1).all()
    assert plan["point"].dtype == np.int64 and plan["realistic"].dtype == bool
    assert plan["realistic"].all()
    assert plan["manoeuvre_start_s"].isna().all() and (plan["manoeuvre_set"] == "normal").all()
    counts = plan_counts(plan)
    assert list(counts.columns) == ["group", "fault", "manoeuvre", "runs"]
    assert list(counts["runs"]) == [5] * 10
    assert list(counts["group"])[:3] == ["ff", "ff", "ra"]
    assert list(counts["manoeuvre"])[:2] == ["cruise", "nose_up"]


def test_flight_points_span_the_envelope_box():
    """Without the realistic rule the Monte Carlo points fill [min, max] of each envelope
    axis: 64 scrambled Sobol points reach within 5 % of both ends (a stratified sequence
    has a point in each 1/64 of every axis)."""
    cfg = config([{"name": "ff", "fault": "none", "manoeuvres": ["cruise"], "count": 64}],
                 campaign={"realistic_only": False})
    plan = build_plan(cfg)
    env = cfg.envelope
    for col in ("alt_ft", "vcas_kt", "mass_t", "cg_pct"):
        lo, hi = min(getattr(env, col)), max(getattr(env, col))
        v = plan[col].to_numpy()
        assert v.min() >= lo and v.max() <= hi, col
        assert v.min() < lo + 0.05 * (hi - lo) and v.max() > hi - 0.05 * (hi - lo), col
    # realistic flags are the rule's verdicts, not all True
    assert not plan["realistic"].all() and plan["realistic"].any()


def test_design_falsify_and_certify_share_one_run_variable_space():
    """The mc design draws the run variables in the ranges of variable_ranges, falsify
    searches them there (held where a range is one value) and certify re-samples those that
    vary among the fault-free runs there: one space, so a run any of them makes is one the
    design could have drawn."""
    from campaign.evidence.certify import run_variables
    from campaign.plan import RUN_VARIABLES, variable_ranges
    from campaign.evidence.falsify import search_space

    cfg = config([{"name": "ff", "fault": "none", "manoeuvres": ["cruise"], "count": 64}],
                 campaign={"realistic_only": False},
                 uncertainty={"aero": 0.05, "vcas": 0.1, "alt": 0.1, "mass": 0.1, "cg": 0.0})
    ranges = variable_ranges(cfg)
    assert tuple(ranges) == RUN_VARIABLES
    assert ranges["alt_ft"] == (min(cfg.envelope.alt_ft), max(cfg.envelope.alt_ft))
    assert ranges["d_vcas"] == (-0.1, 0.1) and ranges["d_cg"] == (-0.0, 0.0)
    plan = build_plan(cfg)
    for col, (lo, hi) in ranges.items():            # every drawn value inside its range
        assert plan[col].between(lo, hi).all(), col
    space = search_space(cfg)
    searched = {**space.bounds, **{k: (v, v) for k, v in space.held.items()}}
    assert {k: searched[k] for k in ranges if k in space.bounds} == \
        {k: ranges[k] for k in space.bounds if k in ranges}
    assert space.held["d_cg"] == 0.0                # a zero half-width is held, not searched
    sampled = run_variables(cfg, plan)
    assert "d_cg" not in sampled and sampled == {k: ranges[k] for k in sampled}
    assert set(sampled) == set(RUN_VARIABLES) - {"d_cg"}


def test_onsets_fill_their_interval_on_the_time_grid(plan):
    """docs/physics.md §5: onset uniform in [onset_min_s, duration_s − onset_before_end_s] =
    [6, 28] s, rounded to the sampling grid."""
    onset = plan.loc[plan["fault"] != "none", "onset_s"].to_numpy()
    assert onset.min() >= 6.0 and onset.max() <= 28.0
    assert onset.min() < 6.0 + 4.0 and onset.max() > 28.0 - 4.0
    np.testing.assert_array_equal(onset, np.round(onset / TS) * TS)


def test_disconnection_onsets_leave_its_detection_budget():
    """docs/physics.md §5, "Onsets that leave time to detect": a disconnection's onset is drawn
    in [onset_min_s, duration_s − 15 s] = [6, 25] s (its budget, twice [CHEN]'s slowest
    delay of 7.01 s, is above onset_before_end_s = 12 s); the other faults keep [6, 28] s.
    The tolerances are the 4 s a Sobol draw of 40 points leaves at most at either end."""
    cfg = config([{"name": "dc", "fault": "disconnection", "manoeuvres": ["cruise"],
                   "count": 40},
                  {"name": "ra", "fault": "runaway", "manoeuvres": ["cruise"], "count": 40}])
    plan = build_plan(cfg)
    dc = plan.loc[plan["fault"] == "disconnection", "onset_s"].to_numpy()
    ra = plan.loc[plan["fault"] == "runaway", "onset_s"].to_numpy()
    assert dc.min() >= 6.0 and dc.max() <= 25.0 and dc.max() > 25.0 - 4.0
    assert ra.max() <= 28.0 and ra.max() > 25.0     # the budget is the disconnection's only


def _mags(plan, group):
    return plan.loc[plan["group"] == group, "magnitude"].to_numpy()


def test_runaway_rate_and_hardover_sign(plan):
    ra = _mags(plan, "ra")
    assert ((np.abs(ra) >= 1.0) & (np.abs(ra) <= 10.0)).all()
    assert np.ptp(np.abs(ra)) > 3.0                          # scaled over the range
    assert set(_mags(plan, "ho")) <= {-1.0, 1.0}
    assert plan.loc[plan["group"].isin(["ra", "ho", "lj", "so"]), "freq_hz"].isna().all()


def test_jam_magnitudes_are_rod_millimetres_of_their_percent_ranges(plan):
    """liquid jam: bias_pct_range (here 1–2 %) of the deflection range as rod mm;
    solid jam with variant offset: offset_pct_range (here 1–3 %) as rod mm; the seized variant and a
    disconnection have no magnitude."""
    cfg = config(ALL_FAULTS)
    lj = np.abs(_mags(plan, "lj"))
    lo, hi = (liquid_jam_bias_mm(ELEVATOR, p) for p in cfg.faults.liquid_jam.bias_pct_range)
    assert lo < hi and (lj >= lo - 1e-12).all() and (lj <= hi + 1e-12).all()
    assert np.ptp(lj) > 0.3 * (hi - lo)
    so = np.abs(_mags(plan, "so"))
    lo, hi = (solid_jam_offset_mm(ELEVATOR, p) for p in cfg.faults.solid_jam.offset_pct_range)
    assert lo < hi and (so >= lo - 1e-12).all() and (so <= hi + 1e-12).all()
    assert np.ptp(so) > 0.3 * (hi - lo)
    for group in ("sj", "dc", "ff"):
        assert np.isnan(_mags(plan, group)).all(), group


def test_ofc_amplitude_and_frequency_in_their_ranges(plan):
    cfg = config(ALL_FAULTS)
    for group, sub, amp_key in (("ol", cfg.faults.ofc_liquid, "amplitude_mA"),
                                ("os", cfg.faults.ofc_solid, "amplitude_mm")):
        rows = plan[plan["group"] == group]
        (alo, ahi), (flo, fhi) = getattr(sub, amp_key), sub.freq_hz
        amp, freq = rows["magnitude"].to_numpy(), rows["freq_hz"].to_numpy()
        assert ((amp >= alo) & (amp <= ahi)).all() and np.ptp(amp) > 0.3 * (ahi - alo), group
        assert ((freq >= flo) & (freq <= fhi)).all() and np.ptp(freq) > 0.3 * (fhi - flo), group
        # amplitude and frequency are separate dimensions of the design
        assert not np.allclose((amp - alo) / (ahi - alo), (freq - flo) / (fhi - flo)), group


def test_signs_are_drawn_both_ways():
    cfg = config([{"name": "ra", "fault": "runaway", "manoeuvres": ["cruise"], "count": 40}])
    ra = build_plan(cfg)["magnitude"].to_numpy()
    # 40 fair signs: 8 ≤ positives ≤ 32 fails with probability 1e-4 (binomial)
    assert 8 <= int((ra > 0).sum()) <= 32


def test_a_single_run_cell_and_an_odd_count():
    for count in (1, 3, 17):
        cfg = config([{"name": "ra", "fault": "runaway", "manoeuvres": ["cruise"],
                       "count": count}])
        plan = build_plan(cfg)
        assert len(plan) == count and plan["run_id"].is_unique
        assert plan["alt_ft"].nunique() == count


def test_a_large_group_draws_as_many_points_as_it_needs():
    """About 59 % of the default envelope box is realistic: 800 realistic runs need more
    than 1 300 points of the sequence, which the design draws by doubling its candidates."""
    plan = build_plan(config([{"name": "ff", "fault": "none", "manoeuvres": ["cruise"],
                               "count": 800}]))
    assert len(plan) == 800 and plan["realistic"].all() and plan["alt_ft"].is_unique
    # a box that is about 8 % realistic: 20 runs need two doublings of the first 80 points
    box = {"alt_ft": [10000.0, 41000.0], "vcas_kt": [180.0, 240.0], "mass_t": [200.0, 242.0]}
    plan = build_plan(config([{"name": "ff", "fault": "none", "manoeuvres": ["cruise"],
                               "count": 20}], envelope=box))
    assert len(plan) == 20 and plan["realistic"].all()


def test_all_manoeuvres():
    cfg = config([{"name": "ff", "fault": "none", "manoeuvres": ["all"], "count": 2}])
    assert list(dict.fromkeys(build_plan(cfg)["manoeuvre"])) == list(MANOEUVRES)


def test_too_few_realistic_points_is_refused_with_the_fix():
    """An envelope box entirely outside the realistic envelope (slow and heavy: buffet)."""
    cfg = config([{"name": "ff", "fault": "none", "manoeuvres": ["cruise"], "count": 3}],
                 envelope={"alt_ft": [40000.0, 41000.0], "vcas_kt": [180.0, 185.0],
                           "mass_t": [240.0, 242.0]})
    with pytest.raises(ValueError, match="group 'ff': fewer than 3 realistic flight points.*"
                                         "realistic_only = false"):
        build_plan(cfg)
    # the same box is accepted without the rule
    plan = build_plan(config([{"name": "ff", "fault": "none", "manoeuvres": ["cruise"],
                               "count": 3}],
                             envelope={"alt_ft": [40000.0, 41000.0], "vcas_kt": [180.0, 185.0],
                                       "mass_t": [240.0, 242.0]},
                             campaign={"realistic_only": False}))
    assert len(plan) == 3 and not plan["realistic"].any()


# ---- fixed group keys --------------------------------------------------------------------------
def test_fixed_group_keys_replace_the_sampled_values():
    cfg = config([{"name": "ra", "fault": "runaway", "manoeuvres": ["cruise"], "count": 6,
                   "onset_s": 12.345, "magnitude": 4.0, "manoeuvre_start_s": 3.5,
                   "alt_ft": 21000.0, "vcas_kt": 250.0, "mass_t": 170.0, "cg_pct": 28.0},
                  {"name": "ol", "fault": "ofc_liquid", "manoeuvres": ["cruise"], "count": 4,
                   "freq_hz": 2.5, "magnitude": 3.0}])
    plan = build_plan(cfg)
    ra, ol = plan[plan["group"] == "ra"], plan[plan["group"] == "ol"]
    assert (ra["onset_s"] == round(12.345 / TS) * TS).all()      # on the time grid
    assert (np.abs(ra["magnitude"]) == 4.0).all()
    assert (ra["manoeuvre_start_s"] == 3.5).all()
    for key, value in (("alt_ft", 21000.0), ("vcas_kt", 250.0), ("mass_t", 170.0),
                       ("cg_pct", 28.0)):
        assert (ra[key] == value).all(), key
    assert (ol["freq_hz"] == 2.5).all() and (ol["magnitude"] == 3.0).all()
    assert ol["manoeuvre_start_s"].isna().all()


def test_a_fixed_sign_applies_to_a_fixed_magnitude():
    groups = [{"name": "ra", "fault": "runaway", "manoeuvres": ["cruise"], "count": 10,
               "magnitude": 4.0}]
    for sign, expected in (("negative", -4.0), ("positive", 4.0)):
        plan = build_plan(config([{**groups[0], "sign": sign}]))
        assert (plan["magnitude"] == expected).all(), sign


def test_a_fixed_magnitude_keeps_each_runs_drawn_direction():
    """A group fixing ``magnitude`` keeps, run by run, the direction the same group draws
    without it (the sign of the drawn value, however small it is: liquid jams of the
    elevator draw biases from about 0.5 to 1.9 mm)."""
    group = {"name": "lj", "fault": "liquid_jam", "manoeuvres": ["cruise"], "count": 200}
    drawn = build_plan(config([group]))["magnitude"].to_numpy()
    with pytest.warns(FutureWarning):
        fixed = build_plan(config([{**group, "magnitude": 2.0}]))["magnitude"].to_numpy()
    assert ((drawn > 0) & (drawn < 1)).any() and ((drawn < 0) & (drawn > -1)).any()
    np.testing.assert_array_equal(np.sign(fixed), np.sign(drawn))
    assert set(np.abs(fixed)) == {liquid_jam_bias_mm(ELEVATOR, 2.0)}


def test_solid_jam_offset_fixed_percent_is_rod_millimetres_with_the_drawn_sign():
    groups = [{"name": "so", "fault": "solid_jam", "variant": "offset",
               "manoeuvres": ["cruise"], "count": 30, "magnitude": 1.8}]
    mags = build_plan(config(groups))["magnitude"].to_numpy()
    mm = solid_jam_offset_mm(ELEVATOR, 1.8)
    assert set(np.round(np.abs(mags), 12)) == {round(mm, 12)}
    assert (mags > 0).any() and (mags < 0).any()


def test_a_fault_free_group_has_no_onset_nor_magnitude():
    plan = build_plan(config([{"name": "ff", "fault": "none", "manoeuvres": ["cruise"],
                               "count": 4, "manoeuvre_start_s": 2.0}]))
    assert plan["onset_s"].isna().all() and plan["magnitude"].isna().all()
    assert plan["freq_hz"].isna().all() and (plan["manoeuvre_start_s"] == 2.0).all()


# ---- the learning set ---------------------------------------------------------------------------
def test_learning_plan_rows():
    cfg = config(ALL_FAULTS, learning={"duration_s": 25.0, "runs_per_manoeuvre": 7})
    learn = build_learning_plan(resolve(cfg))
    assert len(learn) == 14 and (learn["group"] == "learning").all()
    assert list(learn["stream"]) == list(range(LEARNING_STREAM_BASE, LEARNING_STREAM_BASE + 14))
    assert (learn["duration_s"] == 25.0).all() and (learn["fault"] == "none").all()
    assert learn["onset_s"].isna().all() and learn["magnitude"].isna().all()
    assert list(learn["manoeuvre"]) == ["cruise"] * 7 + ["nose_up"] * 7
    # without its own duration the learning runs last as long as the evaluation runs
    assert (build_learning_plan(resolve(config(ALL_FAULTS)))["duration_s"] == 40.0).all()


# ---- explicit runs -------------------------------------------------------------------------------
RUNS = [
    {"group": "worst", "manoeuvre": "nose_up", "fault": "runaway", "onset_s": 11.0,
     "magnitude": -3.5, "alt_ft": 30000.0, "vcas_kt": 280.0, "mass_t": 190.0, "cg_pct": 32.0,
     "draws": {"d_cm": 0.03, "d_supply": -0.02}, "stream": 77, "manoeuvre_start_s": 4.0},
    {"group": "worst", "manoeuvre": "cruise", "fault": "none", "alt_ft": 10000.0,
     "vcas_kt": 250.0, "mass_t": 150.0, "cg_pct": 25.0, "stream": 3},
]


def test_explicit_runs_keep_every_value_and_their_stream():
    cfg = config([{"name": "ff", "fault": "none", "manoeuvres": ["cruise"], "count": 4}],
                 run=RUNS)
    plan = build_plan(cfg)
    assert list(plan["stream"]) == [0, 1, 2, 3, 77, 3]
    a, b = plan.iloc[4], plan.iloc[5]
    assert (a["group"], a["manoeuvre"], a["fault"]) == ("worst", "nose_up", "runaway")
    assert (a["onset_s"], a["magnitude"], a["manoeuvre_start_s"]) == (11.0, -3.5, 4.0)
    assert (a["alt_ft"], a["vcas_kt"], a["mass_t"], a["cg_pct"]) == (30000.0, 280.0, 190.0, 32.0)
    assert (a["d_cm"], a["d_supply"], a["d_cx"]) == (0.03, -0.02, 0.0)
    assert (a["level"], a["point"], a["duration_s"], a["seed"]) == ("run", -1, 40.0, 5)
    assert np.isnan(a["freq_hz"]) and np.isnan(b["onset_s"]) and np.isnan(b["magnitude"])
    assert np.isnan(b["manoeuvre_start_s"])
    assert bool(b["realistic"]) is True
    assert run_id(a.to_dict()) == a["run_id"]


def test_explicit_rows_take_dicts_or_objects_and_judge_realism():
    from types import SimpleNamespace

    cfg = config(ALL_FAULTS[:1])
    obj = SimpleNamespace(**{**RUNS[1], "onset_s": None, "magnitude": None, "freq_hz": None,
                             "draws": None, "manoeuvre_start_s": None})
    slow_heavy = {**RUNS[1], "alt_ft": 40000.0, "vcas_kt": 180.0, "mass_t": 240.0}
    rows = explicit_rows(resolve(cfg), [RUNS[1], obj, slow_heavy])
    assert list(rows["explicit_stream"]) == [3, 3, 3]
    assert list(rows["realistic"]) == [True, True, False]
    assert "run_id" not in rows and "stream" not in rows
    # two equal explicit runs keep one run id (no uniqueness check here)
    plan = explicit_plan(cfg, [RUNS[1], obj])
    assert plan["run_id"].iloc[0] == plan["run_id"].iloc[1]
    assert list(plan["stream"]) == [3, 3]


def test_duplicate_runs_are_refused_naming_the_group():
    cfg = config([{"name": "ff", "fault": "none", "manoeuvres": ["cruise"], "count": 1}],
                 run=[RUNS[1], RUNS[1]])
    with pytest.raises(ValueError, match="duplicate runs in group 'worst'"):
        build_plan(cfg)


# ---- the run id ---------------------------------------------------------------------------------
def test_run_id_leaves_out_only_default_optional_columns():
    row = build_plan(config(ALL_FAULTS[:1])).iloc[0].to_dict()
    base = run_id(row)
    assert run_id({**row, "manoeuvre_set": "normal"}) == base
    assert run_id({k: v for k, v in row.items() if k != "manoeuvre_set"}) == base
    assert run_id({k: v for k, v in row.items() if k != "manoeuvre_start_s"}) == base
    assert run_id({**row, "manoeuvre_set": "stress"}) != base
    assert run_id({**row, "manoeuvre_start_s": 0.0}) != base
    assert run_id({**row, "run_id": "anything"}) == base
    assert len(base) == 20 and all(ch in "0123456789abcdef" for ch in base)
    assert not math.isnan(row["alt_ft"])


def test_the_drawn_direction_splits_the_unit_interval_at_one_half():
    """A fault's sign is −1 on [0, 0.5) and +1 on [0.5, 1) of its unit sample: each half of
    the interval, so both directions are equally likely; exactly 0.5 belongs to +1."""
    from types import SimpleNamespace

    from campaign import plan as design

    below = np.nextafter(0.5, 0.0)
    sign, freq = design._fault_values("hardover", np.zeros(4), np.array([0.0, below, 0.5, 0.75]),
                                      np.zeros(4), SimpleNamespace(faults=None), None)
    np.testing.assert_array_equal(sign, [-1.0, -1.0, 1.0, 1.0])
    assert np.isnan(freq).all()


def _sliver(vcas_max: float, seed: int, count: int):
    """A box on the edge of the realistic envelope (high, slow, heavy): about 0.07–0.3 % of
    its points are realistic, so a Monte Carlo cell needs several doublings of its draw."""
    return config([{"name": "ff", "fault": "none", "manoeuvres": ["cruise"], "count": count}],
                  campaign={"seed": seed},
                  envelope={"alt_ft": [30000.0, 38000.0], "vcas_kt": [160.0, vcas_max],
                            "mass_t": [200.0, 233.0]})


def test_a_rare_realistic_region_is_drawn_up_to_six_doublings_and_no_further():
    """A cell draws max(4·n, 16) unit points, doubled at most six times (1024 for one run)
    until n of them are realistic; the first n are kept (a Sobol sequence's prefix does not
    depend on its length). The cases below were found by scanning seeds for where the
    realistic points of each cell's sequence fall (indices in the comments)."""
    # one run, the only realistic point of the first 1024 at index 889: the sixth doubling
    plan = build_plan(_sliver(252.0, 3, 1))
    assert len(plan) == 1 and bool(plan["realistic"].iloc[0])
    # one run, the first realistic point at 1043: beyond the sixth doubling (1024)
    with pytest.raises(ValueError, match="group 'ff': fewer than 1 realistic flight points"):
        build_plan(_sliver(252.0, 99, 1))
    # five runs: 4·5 = 20 points doubled six times is 1280; the fifth realistic is at 1496
    with pytest.raises(ValueError, match="group 'ff': fewer than 5 realistic flight points"):
        build_plan(_sliver(256.0, 41, 5))
