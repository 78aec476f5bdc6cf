"""``fdd-campaign falsify``'s steps by value (campaign/evidence/falsify.py, docs/evidence.md
"Worst-case search (falsify)"), without a simulation: the search space of the smoke preset
and of an aircraft preset, the unit coordinates and the search vectors, the decoding of a
vector into a run (cells, streams, fixed values, the realistic-envelope repair and its
anchor), the margins read from result rows, the plain Monte Carlo's design, worst.toml, the
warm start and the argument checks before any work."""

import math
import tomllib
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from campaign.config import load_config
from campaign.config.schema import CampaignConfig
from campaign.evidence.falsify import (
    MIN_BUDGET,
    REPAIR_STEPS,
    SEARCH_GROUP,
    STREAM_SPAN,
    FalsifyError,
    FalsifyOptionError,
    FalsifyResult,
    _check_variant,
    _mc_size_text,
    _strategy,
    _write_worst,
    check_label,
    drawn_start_s,
    falsify,
    margin_kind,
    monte_carlo_config,
    scores,
    search_space,
    worst_toml,
)
from campaign.evidence.falsify_search import Point
from campaign.plan import build_plan, explicit_plan, variable_ranges
from scenarios import envelope
from scenarios.envelope import DRAW_COLUMNS, FLIGHT_COLUMNS
from scenarios.manoeuvres import MANOEUVRE_PARAMS
from scenarios.runs import run_streams

SMOKE = load_config("smoke")


def _with(config=SMOKE, **sections):
    """*config* with sections (or ``group``) replaced or updated."""
    data = config.to_dict()
    for name, value in sections.items():
        if isinstance(value, dict) and isinstance(data.get(name), dict):
            data[name].update(value)
        else:
            data[name] = value
    return CampaignConfig.from_dict(data)


#: the envelope of a corner: its centre (33000 ft, 230 kt) fails the Mach limit at 233 t
CORNER = {"alt_ft": [28000.0, 38000.0], "vcas_kt": [160.0, 300.0], "mass_t": [233.0],
          "cg_pct": [17.0]}


def _realistic(config, points):
    frame = pd.DataFrame(np.atleast_2d(points), columns=list(FLIGHT_COLUMNS))
    return envelope.realistic_rule(frame, config.uncertainty)["realistic"].to_numpy()


# ---- the search space ---------------------------------------------------------------------
def test_search_space_of_the_smoke_preset():
    space = search_space(SMOKE)
    ranges = variable_ranges(SMOKE)
    # the manoeuvre start: [lead_s, lead_s + start_spread_s] = [3, 13] s, 13 < 30 − 2
    assert (MANOEUVRE_PARAMS.lead_s, MANOEUVRE_PARAMS.start_spread_s,
            MANOEUVRE_PARAMS.tail_s) == (3.0, 10.0, 2.0)
    assert space.bounds == {**ranges, "manoeuvre_start_s": (3.0, 13.0)} and space.held == {}
    assert space.names == [*ranges, "manoeuvre_start_s", "cell", "stream"]
    assert space.vector_bounds() == [*ranges.values(), (3.0, 13.0), (0.0, 6.0),
                                     (0.0, float(2 ** 31))]
    assert [(c.group, c.manoeuvre, c.fixed) for c in space.cells] == [
        ("fault-free", m, ()) for m in SMOKE.groups[0].manoeuvres]
    assert space.realistic_only
    # the box centre is realistic: every cell's anchor
    np.testing.assert_array_equal(space.anchors, [[23000.0, 230.0, 176.5, 29.0]] * 6)


def test_an_aircraft_campaign_leaves_the_start_to_its_pilot_model():
    config = load_config("chen-mc")
    space = search_space(config)
    assert "manoeuvre_start_s" not in space.bounds and "manoeuvre_start_s" not in space.held
    assert space.bounds == {k: v for k, v in variable_ranges(config).items() if v[1] > v[0]}


def test_one_valued_ranges_are_held_and_groups_fix_their_values():
    free = {"name": "ff", "fault": "none", "manoeuvres": ["cruise", "nose_up"], "count": 1,
            "alt_ft": 18000.0, "manoeuvre_start_s": 5.0}
    free2 = {"name": "g2", "fault": "none", "manoeuvres": ["cruise"], "count": 1}
    jam = {"fault": "runaway", "manoeuvres": ["cruise"], "count": 1}
    config = _with(group=[free, jam, free2], envelope={"mass_t": [180.0]},
                   mismatch={"enabled": False})
    space = search_space(config)
    assert space.held["mass_t"] == 180.0 and "mass_t" not in space.bounds
    widths = envelope.half_widths(config.uncertainty, config.mismatch)
    for col in DRAW_COLUMNS:
        if widths[col] > 0:
            assert space.bounds[col] == (-widths[col], widths[col])
        else:
            assert space.held[col] == 0.0
    fixed = (("alt_ft", 18000.0), ("manoeuvre_start_s", 5.0))
    assert [(c.group, c.manoeuvre, c.fixed) for c in space.cells] == [
        ("ff", "cruise", fixed), ("ff", "nose_up", fixed), ("g2", "cruise", ())]
    # the fixed altitude in the anchor of the group's cells
    assert space.anchors[0][0] == 18000.0 and space.anchors[2][0] != 18000.0


def test_a_cell_is_frozen_and_a_search_space_keeps_to_the_realistic_envelope_by_default():
    import dataclasses
    import inspect

    from campaign.evidence.falsify import Cell, SearchSpace

    with pytest.raises(dataclasses.FrozenInstanceError):
        Cell("g", "cruise").manoeuvre = "nose_up"
    space = SearchSpace(SMOKE, {}, {}, (), np.empty((0, 4)))
    assert space.realistic_only is True and "anchors" not in repr(space)
    params = inspect.signature(falsify).parameters
    assert all(params[o].kind is inspect.Parameter.KEYWORD_ONLY
               for o in ("budget", "out", "jobs", "seed", "scheduler", "tls", "fitted_from",
                         "against", "keep", "log", "progress"))
    params = inspect.signature(worst_toml).parameters
    assert all(params[o].kind is inspect.Parameter.KEYWORD_ONLY for o in ("label", "note"))


def test_no_fault_free_group_is_refused():
    config = _with(group=[g for g in SMOKE.to_dict()["group"] if g["fault"] != "none"])
    with pytest.raises(FalsifyError, match="campaign 'smoke' has no fault-free"):
        search_space(config)


# ---- the anchor of the repair -------------------------------------------------------------
def test_anchor_is_the_realistic_point_nearest_the_centre():
    config = _with(envelope=CORNER)
    assert not _realistic(config, [33000.0, 230.0, 233.0, 17.0])[0]
    space = search_space(config)
    # of the four corners only (28000 ft, 300 kt) is realistic
    assert _realistic(config, [[28000, 160, 233, 17], [28000, 300, 233, 17],
                               [38000, 160, 233, 17], [38000, 300, 233, 17]]).tolist() == [
        False, True, False, False]
    np.testing.assert_array_equal(space.anchors[0], [28000.0, 300.0, 233.0, 17.0])


def test_anchor_distance_is_scaled_by_each_columns_span():
    # the centre (23000 ft, 210 kt, 206.5 t) is not realistic; of the realistic grid points
    # (8000 ft, 220 kt, 180 t) is the nearest in units of each column's span
    # (√(0.5² + 0.1² + 0.5²) = 0.714), (28000 ft, 260 kt, 180 t) the next
    # (√(0.167² + 0.5² + 0.5²) = 0.726); in unscaled units the altitude alone decides
    env = {"alt_ft": [8000.0, 28000.0, 38000.0], "vcas_kt": [160.0, 220.0, 260.0],
           "mass_t": [180.0, 233.0], "cg_pct": [17.0]}
    config = _with(envelope=env)
    assert not _realistic(config, [23000.0, 210.0, 206.5, 17.0])[0]
    assert _realistic(config, [[8000.0, 220.0, 180.0, 17.0], [28000.0, 260.0, 180.0, 17.0]]
                      ).all()
    space = search_space(config)
    np.testing.assert_array_equal(space.anchors[0], [8000.0, 220.0, 180.0, 17.0])
    lo = np.array([8000.0, 160.0, 180.0, 17.0])
    hi = np.array([38000.0, 260.0, 233.0, 17.0])
    grid = envelope.grid_points(envelope.GridTable(**{c: tuple(env[c]) for c in env}))[
        list(FLIGHT_COLUMNS)].to_numpy(float)
    points = np.vstack([(lo + hi) / 2, grid])
    ok = _realistic(config, points)
    span = np.where(hi > lo, hi - lo, 1.0)
    dist = np.linalg.norm((points[ok] - (lo + hi) / 2) / span, axis=1)
    np.testing.assert_array_equal(space.anchors[0], points[ok][int(np.argmin(dist))])


def test_a_one_valued_column_leaves_the_nearest_point_to_the_others():
    # cg held at 17 %: its span counts as 1, not 0 (0/0 would make every distance NaN and
    # pick the first realistic point, (8000 ft, 220 kt, 180 t))
    env = {"alt_ft": [8000.0, 18000.0, 28000.0], "vcas_kt": [160.0, 220.0, 260.0],
           "mass_t": [180.0, 233.0], "cg_pct": [17.0]}
    config = _with(envelope=env)
    assert not _realistic(config, [18000.0, 210.0, 206.5, 17.0])[0]
    np.testing.assert_array_equal(search_space(config).anchors[0],
                                  [18000.0, 220.0, 180.0, 17.0])


def test_anchor_without_the_realistic_rule_is_the_centre():
    space = search_space(_with(envelope=CORNER, campaign={"realistic_only": False}))
    np.testing.assert_array_equal(space.anchors[0], [33000.0, 230.0, 233.0, 17.0])
    assert not space.realistic_only


def test_no_realistic_point_is_refused():
    config = _with(envelope={"alt_ft": [38000.0], "vcas_kt": [300.0], "mass_t": [233.0],
                             "cg_pct": [17.0]})
    with pytest.raises(FalsifyError, match="cell fault-free/cruise: no realistic flight point"):
        search_space(config)


# ---- vectors and units --------------------------------------------------------------------
def test_vectors_map_unit_coordinates_into_run_table_units():
    space = search_space(SMOKE)
    n = len(space.bounds)
    pts = [Point(tuple(np.linspace(0.0, 1.0, n)), 2, 7), Point((0.25,) * n, 5, STREAM_SPAN - 1)]
    x = space.vectors(pts)
    assert x.shape == (n + 2, 2)
    lo = np.array([b[0] for b in space.bounds.values()])
    hi = np.array([b[1] for b in space.bounds.values()])
    np.testing.assert_allclose(x[:n, 0], lo + np.linspace(0, 1, n) * (hi - lo), rtol=0,
                               atol=1e-12)
    np.testing.assert_allclose(x[:n, 1], lo + 0.25 * (hi - lo), rtol=0, atol=1e-12)
    assert x[n].tolist() == [2.5, 5.5] and x[n + 1].tolist() == [7.5, STREAM_SPAN - 0.5]
    assert space.vectors([Point((), 0, 0)][:0]).shape == (n + 2, 0)


def test_unit_of_a_row_clipped_into_the_box_start_left_nan():
    space = search_space(SMOKE)
    row = {"alt_ft": 15500.0, "vcas_kt": 400.0, "mass_t": 100.0, "cg_pct": 29.0,
           "d_cx": 0.025, "manoeuvre_start_s": math.nan}
    u = space.unit_of(row)
    names = list(space.bounds)
    assert u[names.index("alt_ft")] == 0.25
    assert u[names.index("vcas_kt")] == 1.0 and u[names.index("mass_t")] == 0.0
    assert u[names.index("cg_pct")] == 0.5
    assert u[names.index("d_cx")] == pytest.approx(0.75, abs=1e-15)    # one rounded division
    assert math.isnan(u[names.index("manoeuvre_start_s")])
    assert math.isnan(u[names.index("d_cy")])            # a column the row lacks


# ---- decoding ----------------------------------------------------------------------------
def test_decode_gives_the_runs_of_the_vectors():
    space = search_space(SMOKE)
    n = len(space.bounds)
    names = list(space.bounds)
    x = space.vectors([Point((0.5,) * n, 1, 41), Point((0.0,) * n, 3, 42)])
    x[names.index("manoeuvre_start_s"), 1] = math.nan
    run, other = space.decode(x)
    assert (run["group"], run["manoeuvre"], run["fault"], run["stream"]) == (
        SEARCH_GROUP, "nose_up", "none", 41)
    assert {k: run[k] for k in FLIGHT_COLUMNS} == {"alt_ft": 23000.0, "vcas_kt": 230.0,
                                                   "mass_t": 176.5, "cg_pct": 29.0}
    assert run["draws"] == {d: 0.0 for d in DRAW_COLUMNS}
    assert run["manoeuvre_start_s"] == 8.0
    assert other["manoeuvre"] == SMOKE.groups[0].manoeuvres[3] and other["stream"] == 42
    assert other["manoeuvre_start_s"] is None
    lo = {k: v[0] for k, v in space.bounds.items()}
    assert other["draws"] == {d: lo[d] for d in DRAW_COLUMNS}
    # the runs are valid run-table rows
    assert len(explicit_plan(SMOKE, [run, other])) == 2


def test_decode_keeps_the_upper_ends_in_the_last_cell_and_stream():
    space = search_space(SMOKE)
    x = np.array([[0.5 * (lo + hi) for lo, hi in space.bounds.values()]
                  + [6.0, float(STREAM_SPAN)]]).T
    (run,) = space.decode(x)
    assert run["manoeuvre"] == SMOKE.groups[0].manoeuvres[5]
    assert run["stream"] == STREAM_SPAN - 1
    x[-2, 0], x[-1, 0] = 5.999, STREAM_SPAN - 1.5
    (run,) = space.decode(x)
    assert run["manoeuvre"] == SMOKE.groups[0].manoeuvres[5]
    assert run["stream"] == STREAM_SPAN - 2


def test_decode_fills_held_and_fixed_values():
    free = {"name": "ff", "fault": "none", "manoeuvres": ["cruise"], "count": 1,
            "alt_ft": 18000.0, "manoeuvre_start_s": 5.0}
    free2 = {"name": "g2", "fault": "none", "manoeuvres": ["nose_up"], "count": 1}
    config = _with(group=[free, free2], envelope={"mass_t": [180.0]},
                   mismatch={"enabled": False}, campaign={"realistic_only": False})
    space = search_space(config)
    names = list(space.bounds)
    x = space.vectors([Point((1.0,) * len(names), 0, 1), Point((1.0,) * len(names), 1, 2)])
    fixed, free_run = space.decode(x)
    assert fixed["alt_ft"] == 18000.0 and fixed["manoeuvre_start_s"] == 5.0
    assert fixed["mass_t"] == 180.0 and fixed["draws"]["d_supply"] == 0.0
    assert free_run["alt_ft"] == 38000.0 and free_run["manoeuvre_start_s"] == 13.0
    assert free_run["mass_t"] == 180.0
    assert fixed["draws"]["d_cx"] == space.bounds["d_cx"][1]


def test_decode_repairs_an_unrealistic_point_towards_the_anchor():
    config = _with(envelope=CORNER)
    space = search_space(config)
    names = list(space.bounds)
    p = np.array([38000.0, 300.0, 233.0, 17.0])
    a = space.anchors[0]
    unit = [{"alt_ft": 1.0, "vcas_kt": 1.0}.get(k, 0.5) for k in names]
    ok_unit = [{"alt_ft": 0.0, "vcas_kt": 1.0}.get(k, 0.5) for k in names]
    run, kept = space.decode(space.vectors([Point(tuple(unit), 0, 1),
                                            Point(tuple(ok_unit), 0, 2)]))
    got = np.array([run[k] for k in FLIGHT_COLUMNS])
    # on the segment from the anchor (28000 ft, 300 kt) towards (38000 ft, 300 kt)
    t = (got[0] - a[0]) / (p[0] - a[0])
    np.testing.assert_allclose(got, a + t * (p - a), rtol=0, atol=1e-9)
    assert 0.0 < t < 1.0 and _realistic(config, got)[0]
    # the last realistic point to 2^-REPAIR_STEPS of the segment: one step on is not
    assert REPAIR_STEPS == 40
    assert t * 2.0 ** REPAIR_STEPS == round(t * 2.0 ** REPAIR_STEPS)
    assert not _realistic(config, a + (t + 2.0 ** -REPAIR_STEPS) * (p - a))[0]
    # a realistic point is left as it is
    assert [kept[k] for k in FLIGHT_COLUMNS] == [28000.0, 300.0, 233.0, 17.0]
    # without the rule nothing is repaired
    space = search_space(_with(envelope=CORNER, campaign={"realistic_only": False}))
    (run,) = space.decode(space.vectors([Point(tuple(unit), 0, 1)]))
    assert [run[k] for k in FLIGHT_COLUMNS] == [38000.0, 300.0, 233.0, 17.0]


# ---- margins and labels -------------------------------------------------------------------
def test_scores_per_row_error_nan_and_first_row_of_a_run():
    results = pd.DataFrame({
        "run_id": ["a", "b", "c", "d", "a", "b"],
        "detector": ["m", "m", "m", "m", "m", "x"],
        "status": ["ok", "ok", "error", "ok", "ok", "ok"],
        "false_alarm": [True, None, True, True, False, True],
        "margin": [1.4, 0.7, 2.0, 1.1, 9.0, 5.0]}, index=[10, 11, 12, 13, 14, 15])
    rows = pd.DataFrame({"run_id": ["d", "c", "b", "a", "e"]})
    margin, alarm = scores(results, rows, "m")
    np.testing.assert_array_equal(margin, [1.1, np.nan, 0.7, 1.4, np.nan])
    np.testing.assert_array_equal(alarm, [True, False, False, True, False])
    assert alarm.dtype == bool


def test_labels_variants_and_systems():
    check_label(SMOKE, "position-monitor")
    check_label(SMOKE, "position-monitor[safety=2]")
    for bad in ("position-monitor[", "position", "comb-interval[a=0.9]"):
        with pytest.raises(FalsifyOptionError) as info:
            check_label(SMOKE, bad)
        assert (f"label={bad!r}: not a detector of campaign 'smoke'; its labels: "
                "position-monitor (a detector with variants" in str(info.value))
    systems = SimpleNamespace(campaign=SMOKE.campaign, detector_labels=("pm",),
                              system_names=("both",))
    check_label(systems, "both")
    with pytest.raises(FalsifyOptionError, match="its labels: pm; its detection systems: "
                                                 "both \\(a detector"):
        check_label(systems, "x")


def test_the_results_must_name_the_variant():
    _check_variant(pd.DataFrame({"detector": ["pm", "pm[a=1]"]}), "pm[a=1]", SMOKE)
    with pytest.raises(FalsifyOptionError, match="label='pm\\[a=2\\]': not a detector of "
                                                 "campaign 'smoke'; its results are named: "
                                                 "pm, pm\\[a=1\\]"):
        _check_variant(pd.DataFrame({"detector": ["pm", "pm[a=1]", "pm"]}), "pm[a=2]", SMOKE)


def test_margin_kind_follows_the_threshold_scale():
    scaled = SimpleNamespace(capabilities=SimpleNamespace(threshold_scale=True))
    plain = SimpleNamespace(capabilities=SimpleNamespace(threshold_scale=False))
    dets = {"pm": scaled, "ci": plain, "old": object()}
    assert margin_kind(dets, "pm") == "decision" and margin_kind(dets, "pm[a=1]") == "decision"
    assert margin_kind(dets, "ci") == "residual" and margin_kind(dets, "old") == "residual"
    assert margin_kind(dets, "nope") == "residual"


def test_result_counts_the_searched_false_alarms():
    search = pd.DataFrame({"false_alarm": [False, True, True]})
    res = FalsifyResult("pm", search, search.iloc[0], 0.5, 10, "mc", 0)
    assert res.false_alarms == 2 and res.false_alarm and res.margin_kind == "decision"
    res = FalsifyResult("pm", search.iloc[:1], search.iloc[0], 0.5, 10, "mc", 0)
    assert res.false_alarms == 0 and not res.false_alarm
    res = FalsifyResult("pm", search.iloc[:2], search.iloc[0], 0.5, 10, "mc", 0)
    assert res.false_alarms == 1 and res.false_alarm


# ---- the plain Monte Carlo ----------------------------------------------------------------
def test_monte_carlo_config_keeps_the_fault_free_groups_at_budget_per_cell():
    mc = monte_carlo_config(SMOKE, 600)
    assert [(g.fault, g.count) for g in mc.groups] == [("none", 100)]
    assert mc.campaign.design == "mc" and mc.campaign.sampler == "sobol"
    assert [(g.count) for g in monte_carlo_config(SMOKE, 5).groups] == [1]
    assert [(g.count) for g in monte_carlo_config(SMOKE, 13).groups] == [2]
    grid = load_config("addsafe-grid")
    mc = monte_carlo_config(grid, 30)
    assert mc.campaign.design == "mc" and mc.campaign.sampler == "sobol"
    assert all(g.fault == "none" for g in mc.groups)
    cells = sum(len(g.manoeuvres) for g in mc.groups)
    assert all(g.count == max(1, 30 // cells) for g in mc.groups)
    assert "(plain Monte Carlo)" in mc.source
    runs = _with(run=[_run(5)])
    assert monte_carlo_config(runs, 60).runs == ()


def test_monte_carlo_size_text():
    two = pd.DataFrame({"group": ["g"] * 4 + ["h"] * 2, "manoeuvre": ["a", "a", "b", "b",
                                                                      "a", "a"]})
    assert _mc_size_text(two, 6) == "6 fault-free runs"
    assert _mc_size_text(two.iloc[:1], 1) == "1 fault-free run"
    assert _mc_size_text(two, 7) == ("6 fault-free runs: the budget of 7 in whole runs per "
                                     "cell, 2 in each of 3 cells")
    assert _mc_size_text(two.iloc[:5], 7) == ("5 fault-free runs for the budget of 7, in "
                                              "whole runs per cell")


# ---- worst.toml ---------------------------------------------------------------------------
def _run(stream, manoeuvre="pitch_protection", start=5.5, alt=18000.0):
    return {"group": SEARCH_GROUP, "manoeuvre": manoeuvre, "fault": "none", "alt_ft": alt,
            "vcas_kt": 220.0, "mass_t": 180.0, "cg_pct": 30.0,
            "draws": {d: 0.01 for d in DRAW_COLUMNS}, "stream": stream,
            "manoeuvre_start_s": start}


def test_worst_toml_replays_its_runs_with_the_note_as_comments():
    runs = [_run(3), _run(4, start=None)]
    text = worst_toml(SMOKE, runs, label="pm", note="line one\nline two")
    assert text.startswith("# line one\n# line two\n\n")
    data = tomllib.loads(text)
    assert data["campaign"]["name"] == "smoke-worst"
    assert data["campaign"]["description"] == ("the 2 fault-free runs found by fdd-campaign "
                                               "falsify for pm: its false alarms first, then "
                                               "by largest margin")
    assert "group" not in data and len(data["run"]) == 2
    assert "manoeuvre_start_s" not in data["run"][1]
    assert data["run"][0]["manoeuvre_start_s"] == 5.5
    replay = CampaignConfig.from_dict(data)
    assert (explicit_plan(replay, replay.runs)["run_id"].tolist()
            == explicit_plan(SMOKE, runs)["run_id"].tolist())


def _search(margins, alarms):
    # the runs of even streams leave their manoeuvre start to the model (NaN)
    rows = explicit_plan(SMOKE, [_run(100 + i, alt=18000.0 + i,
                                      start=None if i % 2 == 0 else 5.5)
                                 for i in range(len(margins))])
    return rows.assign(margin=np.asarray(margins, float), false_alarm=alarms)


def test_write_worst_puts_false_alarms_first_then_the_largest_margins(tmp_path):
    search = _search([0.5, 1.2, 0.9, np.nan, 1.05, 0.95],
                     [False, False, True, False, True, False])
    search = pd.concat([search, search.iloc[[1]].assign(margin=0.1)], ignore_index=True)
    worst = _write_worst(SMOKE, search, "position-monitor", 3, tmp_path, None, 7, 60)
    assert worst["run_id"] == search["run_id"].iloc[1] and worst["margin"] == 1.2
    text = (tmp_path / "worst.toml").read_text()
    runs = tomllib.loads(text)["run"]
    # the two false alarms (1.05, 0.9), then the largest margin of the rest (1.2)
    assert [r["stream"] for r in runs] == [104, 102, 101]
    assert [r["alt_ft"] for r in runs] == [18004.0, 18002.0, 18001.0]
    assert [r.get("manoeuvre_start_s") for r in runs] == [None, None, 5.5]
    assert "(seed 7,\n# budget 60)" in text and "false alarm first (2)" in text
    assert "margins 1.05, 0.9, 1.2." in text
    assert "--fitted-from" in text and str(tmp_path / "learned") in text
    assert "fits the detectors again" in text
    _write_worst(SMOKE, search, "position-monitor", 10, tmp_path, "camp", 7, 60)
    text = (tmp_path / "worst.toml").read_text()
    assert len(tomllib.loads(text)["run"]) == 5              # run 101 once, NaN left out
    assert "taken from camp" in text


def test_write_worst_refuses_a_search_whose_every_run_failed(tmp_path):
    search = _search([np.nan, np.nan], [False, False])
    with pytest.raises(FalsifyError, match="every run of the search failed for 'pm'"):
        _write_worst(SMOKE, search, "pm", 3, tmp_path, None, 0, 10)
    assert not (tmp_path / "worst.toml").exists()


# ---- the warm start -----------------------------------------------------------------------
@pytest.mark.parametrize("seed, stream", [(0, 5), (11, 123456)])
def test_drawn_start_is_the_manoeuvre_generators_first_uniform(seed, stream):
    u0 = run_streams(seed, stream)[0].random()
    assert drawn_start_s(seed, stream, 30.0) == 3.0 + u0 * 10.0
    # capped tail_s before the end of a short record
    assert drawn_start_s(seed, stream, 4.0) == min(3.0 + u0 * 10.0, 2.0)


def test_warm_rows_open_the_strategy_as_they_ran():
    space = search_space(SMOKE)
    plan = build_plan(SMOKE)
    free = plan[plan["fault"] == "none"].reset_index(drop=True)
    warm = free.iloc[[3, 0, 7]].reset_index(drop=True).copy()
    warm.loc[1, "seed"] = 99                                 # another campaign seed: skipped
    strategy = _strategy(space, SMOKE, 60, 4, warm)
    names = list(space.bounds)
    k = names.index("manoeuvre_start_s")
    assert (strategy.n_dims, strategy.n_cells, strategy.budget, strategy.seed) == (
        len(names), 6, 60, 4)
    assert strategy.stream_span == STREAM_SPAN and strategy.start_dim == k
    assert len(strategy.warm) == 2
    for point, (_, row) in zip(strategy.warm, warm.iloc[[0, 2]].iterrows()):
        cells = [i for i, c in enumerate(space.cells) if c.manoeuvre == row["manoeuvre"]]
        assert point.cell == cells[0] and point.stream == int(row["stream"])
        np.testing.assert_array_equal(point.unit, space.unit_of(row))
    for i, (_, row) in enumerate(warm.iloc[[0, 2]].iterrows()):
        if math.isnan(row["manoeuvre_start_s"]):
            t0 = drawn_start_s(0, int(row["stream"]), 30.0)
            assert strategy.warm_start[i] == min(max((t0 - 3.0) / 10.0, 0.0), 1.0)
    (first,) = _strategy(space, SMOKE, 1, 4, warm).warm           # cut to the budget
    assert (first.cell, first.stream) == (strategy.warm[0].cell, strategy.warm[0].stream)
    np.testing.assert_array_equal(first.unit, strategy.warm[0].unit)
    none = _strategy(space, SMOKE, 60, 4, None)
    assert none.warm == [] and none.warm_start == {}


def test_warm_rows_of_an_unknown_manoeuvre_are_skipped():
    config = _with(group=[{"name": "ff", "fault": "none", "manoeuvres": ["cruise"],
                           "count": 1}])
    space = search_space(config)
    plan = build_plan(SMOKE)
    free = plan[plan["fault"] == "none"]
    strategy = _strategy(space, config, 60, 0, free)
    assert len(strategy.warm) == (free["manoeuvre"] == "cruise").sum() > 0


def test_an_aircraft_campaign_has_no_start_dimension():
    config = load_config("chen-mc")
    space = search_space(config)
    strategy = _strategy(space, config, 60, 0, None)
    assert strategy.start_dim is None
    plan = build_plan(config)
    warm = plan[plan["fault"] == "none"].head(2)
    strategy = _strategy(space, config, 60, 0, warm)
    assert len(strategy.warm) == 2 and strategy.warm_start == {}
    np.testing.assert_array_equal(strategy.warm[0].unit, space.unit_of(warm.iloc[0]))


# ---- arguments, before any work -----------------------------------------------------------
NO_FREE = _with(group=[g for g in SMOKE.to_dict()["group"] if g["fault"] != "none"])


@pytest.mark.parametrize("kwargs, needle", [
    ({"budget": 0}, "budget=0: must be a whole number of runs ≥ 10; fix: e.g. budget=600"),
    ({"budget": True}, "budget=True: must be a whole number of runs ≥ 10"),
    ({"budget": 20.0}, "budget=20.0: must be a whole number of runs ≥ 10"),
    ({"budget": 1}, "budget=1: too small; the search needs at least 10 runs"),
    ({"budget": 9}, "budget=9: too small; the search needs at least 10 runs (screening, then "
                    "the worst cell); fix: e.g. budget=600, or any other ≥ 10"),
    ({"budget": 20, "keep": 0}, "keep=0: must be a whole number ≥ 1 (runs written to "
                                "worst.toml); fix: e.g. keep=10"),
    ({"budget": 20, "keep": False}, "keep=False: must be a whole number ≥ 1"),
    ({"budget": 20, "keep": 2.0}, "keep=2.0: must be a whole number ≥ 1"),
])
def test_bad_arguments_are_refused_before_any_work(kwargs, needle, tmp_path):
    with pytest.raises(FalsifyOptionError) as info:
        falsify(SMOKE, "position-monitor", out=tmp_path / "o", **kwargs)
    assert needle in str(info.value)
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("budget, keep", [(MIN_BUDGET, 1), (np.int64(10), np.int64(1))])
def test_the_smallest_budget_and_keep_go_on_to_the_search_space(budget, keep, tmp_path):
    with pytest.raises(FalsifyError, match="no fault-free") as info:
        falsify(NO_FREE, "position-monitor", budget=budget, keep=keep, out=tmp_path / "o")
    assert not isinstance(info.value, FalsifyOptionError)
    assert not (tmp_path / "o").exists()


# ---- the search loop, the simulation replaced by a recorder -------------------------------
# The loop of falsify on its own: the runner's pipeline (campaign.runner.prepare and
# evaluate_rows) is replaced by a recorder whose margin is a function of each run's
# supply-pressure draw (a run of stream ≡ 0 mod 13 fails); test_falsify.py runs the real
# pipeline on the smoke preset.
def _margin(row):
    return 1.0 + 10.0 * float(row["d_supply"])          # d_supply in ±0.05: 0.5 … 1.5


class _Pipeline:
    def __init__(self):
        self.prepared, self.batches, self.closed = [], [], 0

    def prepare(self, config, out, **kwargs):
        from campaign.plant_setup import as_resolved

        self.prepared.append((config, out, kwargs))
        det = SimpleNamespace(capabilities=SimpleNamespace(threshold_scale=True))
        return (SimpleNamespace(campaign=as_resolved(config), close=self.close),
                {label: det for label in config.detector_labels})

    def close(self):
        self.closed += 1

    def evaluate_rows(self, setup, rows, detectors, log=None):
        self.batches.append(len(rows))
        out = []
        for _, row in rows.iterrows():
            error = int(row["stream"]) % 13 == 0
            m = math.nan if error else _margin(row)
            for name in detectors:
                out.append({"run_id": row["run_id"], "detector": name,
                            "status": "error" if error else "ok", "margin": m,
                            "false_alarm": None if error else m >= 1.3})
        return pd.DataFrame(out)


def install_pipeline(monkeypatch) -> _Pipeline:
    """The runner's pipeline (prepare, evaluate_rows) replaced by a :class:`_Pipeline`."""
    import campaign.runner

    rec = _Pipeline()
    monkeypatch.setattr(campaign.runner, "prepare", rec.prepare)
    monkeypatch.setattr(campaign.runner, "evaluate_rows", rec.evaluate_rows)
    return rec


@pytest.fixture
def pipeline(monkeypatch):
    return install_pipeline(monkeypatch)


def test_the_search_evaluates_its_batches_and_compares_with_a_plain_monte_carlo(tmp_path,
                                                                               pipeline):
    from campaign.store.files import read_metadata

    out = tmp_path / "s"
    out.mkdir()                                   # an existing directory is written into
    said = []
    res = falsify(SMOKE, "position-monitor", budget=30, out=out, jobs=3, seed=3, keep=4,
                  log=said.append, progress=False)
    ((config, learned, kwargs),) = pipeline.prepared
    assert config is SMOKE and learned == out / "learned"
    assert kwargs == {"jobs": 3, "scheduler": None, "tls": None, "fitted_from": None,
                      "log": said.append}
    assert pipeline.closed == 1
    search = res.search
    assert list(search.index) == list(range(30))            # one index over the batches
    # the budget in batches: screening (10 of 30), sweep; then the Monte Carlo's 30 runs
    assert len(search) == 30 == sum(pipeline.batches[:-1]) and pipeline.batches[-1] == 30
    assert list(dict.fromkeys(search["phase"])) == ["screen", "polish"]
    assert (search.loc[search["phase"] == "screen", "generation"] == 0).all()
    assert (search.loc[search["phase"] == "polish", "generation"] == 1).all()
    errors = search["stream"] % 13 == 0
    assert res.errors == int(errors.sum())
    want = np.where(errors, np.nan, [_margin(r) for _, r in search.iterrows()])
    np.testing.assert_array_equal(search["margin"].to_numpy(), want)
    np.testing.assert_array_equal(search["false_alarm"].to_numpy(bool),
                                  ~errors.to_numpy() & (want >= 1.3))
    assert res.false_alarms == int(np.nansum(want >= 1.3))
    assert res.worst["margin"] == np.nanmax(want) and res.margin_kind == "decision"
    # the plain Monte Carlo of the same budget: its worst margin is the baseline
    mc = build_plan(monte_carlo_config(SMOKE, 30)).iloc[:30]
    mc_margin = np.where(mc["stream"] % 13 == 0, np.nan, [_margin(r) for _, r in mc.iterrows()])
    assert res.baseline_margin == np.nanmax(mc_margin) and res.baseline_runs == 30
    assert res.baseline_source == ("a plain Monte Carlo of about the same budget (30 fault-free "
                                   "runs)")
    stored = pd.read_parquet(out / "monte-carlo.parquet")
    np.testing.assert_array_equal(stored["margin"].to_numpy(), mc_margin)
    assert "plain Monte Carlo of about the same budget: 30 fault-free runs" in said
    meta = read_metadata(out / "search.parquet")
    assert (meta["detector"], int(meta["budget"]), int(meta["seed"])) == (
        "position-monitor", 30, 3)
    assert list(meta["dimensions"]) == search_space(SMOKE).names
    runs = tomllib.loads((out / "worst.toml").read_text())["run"]
    assert len(runs) == 4


def test_a_variant_the_results_lack_is_refused_on_the_first_batch(tmp_path, pipeline):
    with pytest.raises(FalsifyOptionError, match="its results are named: position-monitor"):
        falsify(SMOKE, "position-monitor[x]", budget=30, out=tmp_path / "s", jobs=1,
                log=lambda m: None, progress=False)
    assert len(pipeline.batches) == 1 and pipeline.closed == 1


def test_the_search_reports_its_progress(tmp_path, pipeline, capsys):
    from campaign.store.files import read_metadata

    out = tmp_path / "a" / "b"                               # parents made as needed
    res = falsify(SMOKE, "position-monitor", budget=30, out=out)
    said = capsys.readouterr().err.splitlines()            # no log given: to stderr
    # the defaults: seed 0, two workers, the 10 worst runs kept, the progress shown
    assert int(read_metadata(out / "search.parquet")["seed"]) == 0
    assert pipeline.prepared[0][2]["jobs"] == 2
    assert len(tomllib.loads((out / "worst.toml").read_text())["run"]) == 10     # keep
    lines = [line for line in said if "worst margin so far" in line]
    # one line a batch, each with the largest margin of the batches so far (4 digits)
    assert [line.split(":")[0] for line in lines] == ["screen (batch 1)", "polish (batch 2)"]
    first = res.search["margin"].iloc[:10].max()
    assert lines[0].endswith(f"worst margin so far {first:.4g}")
    assert lines[-1].endswith(f"worst margin so far {res.search['margin'].max():.4g}")

