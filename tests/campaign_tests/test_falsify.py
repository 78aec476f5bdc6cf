"""``fdd-campaign falsify`` (campaign/evidence/falsify.py) and the explicit ``[[run]]`` entries of a
campaign file: the search is deterministic for a seed at any --jobs, spends at most its
budget, stays within the campaign's bounds and the realistic envelope, exits 0/1/2 as
documented, and worst.toml replays its runs with the same margins."""

from __future__ import annotations

import math
import textwrap
import tomllib

import numpy as np
import pandas as pd
import pytest

from campaign.cli.commands import main
from campaign.config import ConfigError, load_config
from campaign.config.schema import CampaignConfig
from campaign.plan import build_plan, explicit_plan
from campaign.evidence.falsify import (
    STREAM_SPAN,
    FalsifyError,
    check_label,
    falsify,
    search_space,
    worst_toml,
)
from campaign.store.directory import CampaignDir
from scenarios import envelope

SMOKE = load_config("smoke")


@pytest.fixture(scope="module")
def searched(tmp_path_factory):
    """One small search of the smoke preset (budget 60: screening, two CMA-ES generations,
    stream sweep), shared by the checks below."""
    out = tmp_path_factory.mktemp("falsify") / "a"
    code = main(["falsify", "smoke", "--detector", "position-monitor", "--budget", "60",
                 "--jobs", "1", "--seed", "3", "--keep", "4", "--out", str(out)])
    return out, code, pd.read_parquet(out / "search.parquet")


def test_budget_respected_and_rows_complete(searched):
    _, code, search = searched
    assert len(search) <= 60
    assert {"run_id", "margin", "generation", "phase", *envelope.DRAW_COLUMNS} <= set(
        search.columns)
    assert list(dict.fromkeys(search["phase"])) == ["screen", "focus", "polish"]
    assert (search["fault"] == "none").all()
    assert search["generation"].min() == 0
    assert np.isfinite(search["margin"]).all()


def test_exit_code_says_whether_a_false_alarm_was_found(searched):
    _, code, search = searched
    assert search["false_alarm"].dtype == bool
    # an alarm needs the threshold exceeded; the exit code follows the detector's alarms
    assert (search.loc[search["false_alarm"], "margin"] >= 1.0).all()
    assert code == (1 if search["false_alarm"].any() else 0)


def test_bounds_respected(searched):
    _, _, search = searched
    widths = envelope.half_widths(SMOKE.uncertainty, SMOKE.mismatch)
    for col in envelope.DRAW_COLUMNS:
        assert (search[col].abs() <= widths[col]).all(), col
    for col in envelope.GridTable.columns:
        values = getattr(SMOKE.envelope, col)
        assert search[col].between(min(values), max(values)).all(), col
    assert search["realistic"].all()
    points = search[list(envelope.GridTable.columns)]
    assert envelope.realistic_rule(points, SMOKE.uncertainty)["realistic"].all()
    assert search["stream"].between(0, STREAM_SPAN - 1).all()
    lo, hi = search_space(SMOKE).bounds["manoeuvre_start_s"]
    assert search["manoeuvre_start_s"].between(lo, hi).all()
    assert set(search["manoeuvre"]) <= set(SMOKE.groups[0].manoeuvres)


def test_same_seed_same_search_at_any_jobs(searched, tmp_path):
    _, _, search = searched
    code = main(["falsify", "smoke", "--detector", "position-monitor", "--budget", "60",
                 "--jobs", "2", "--seed", "3", "--keep", "4", "--out", str(tmp_path / "b"),
                 "--fitted-from", str(searched[0] / "learned")])
    assert code in (0, 1)
    pd.testing.assert_frame_equal(pd.read_parquet(tmp_path / "b" / "search.parquet"), search)


def test_other_seed_other_runs(searched, tmp_path):
    _, _, search = searched
    main(["falsify", "smoke", "--detector", "position-monitor", "--budget", "10", "--seed",
          "4", "--jobs", "1", "--out", str(tmp_path / "c"),
          "--fitted-from", str(searched[0] / "learned")])
    other = pd.read_parquet(tmp_path / "c" / "search.parquet")
    assert not set(other["run_id"]) & set(search["run_id"])


def test_worst_toml_replays_the_worst_runs_exactly(searched, tmp_path):
    out, _, search = searched
    assert main(["run", str(out / "worst.toml"), "--jobs", "1", "--quiet",
                 "--out", str(tmp_path / "replay")]) in (0, 1)
    rows = CampaignDir(tmp_path / "replay").read_results()
    rows = rows[rows["detector"] == "position-monitor"].set_index("run_id")
    top = (search.sort_values("margin", ascending=False, kind="stable")
           .drop_duplicates("run_id").head(4).set_index("run_id"))
    assert list(rows.index) == list(top.index)
    np.testing.assert_array_equal(rows["margin"].to_numpy(), top["margin"].to_numpy())
    np.testing.assert_array_equal(rows["false_alarm"].to_numpy(bool),
                                  top["false_alarm"].to_numpy(bool))
    # the gate fails on a false alarm, not on a margin above 1 that lasts less than the
    # confirmation time (such a run is no alarm)
    assert main(["gate", str(tmp_path / "replay")]) == (1 if top["false_alarm"].any() else 0)


def test_bad_input_exits_2_before_any_work(tmp_path, capsys):
    for argv, words in (
            (["--detector", "nope", "--budget", "20"], "position-monitor"),
            (["--detector", "position-monitor", "--budget", "3"], "--budget 3"),
            (["--detector", "position-monitor", "--budget", "20", "--keep", "0"], "--keep"),
            (["--detector", "position-monitor", "--budget", "20", "--jobs", "0"], "--jobs")):
        out = tmp_path / "bad"
        assert main(["falsify", "smoke", *argv, "--out", str(out)]) == 2
        assert words in capsys.readouterr().err
        assert not (out / "learned" / "fitted").exists()


def test_unknown_variant_lists_the_result_names(tmp_path, capsys):
    assert main(["falsify", "smoke", "--detector", "position-monitor[x]", "--budget", "10",
                 "--jobs", "1", "--out", str(tmp_path / "v")]) == 2
    err = capsys.readouterr().err
    assert "position-monitor[x]" in err and "its results are named: position-monitor" in err
    assert not (tmp_path / "v" / "search.parquet").exists()


def test_labels_are_checked_against_the_campaign():
    check_label(SMOKE, "position-monitor")
    with pytest.raises(FalsifyError, match="its labels: position-monitor"):
        check_label(SMOKE, "comb-interval[a=0.9]")


def test_search_space_follows_the_campaign_bounds():
    data = SMOKE.to_dict()
    data["mismatch"]["enabled"] = False
    data["uncertainty"]["aero"] = 0.02
    space = search_space(CampaignConfig.from_dict(data))
    widths = envelope.half_widths(CampaignConfig.from_dict(data).uncertainty,
                                  CampaignConfig.from_dict(data).mismatch)
    for col in envelope.DRAW_COLUMNS:
        if widths[col] > 0:
            assert space.bounds[col] == (-widths[col], widths[col])
        else:
            assert space.held[col] == 0.0 and col not in space.bounds
    assert len(space.cells) == len(SMOKE.groups[0].manoeuvres)


def test_search_needs_a_fault_free_group():
    data = SMOKE.to_dict()
    data["group"] = [g for g in data["group"] if g["fault"] != "none"]
    with pytest.raises(FalsifyError, match="no fault-free"):
        falsify(CampaignConfig.from_dict(data), "position-monitor", budget=10, out="unused")


# ---- the [[run]] entries of a campaign file ------------------------------------------------
RUNS = textwrap.dedent("""\
    [campaign]
    name = "runs"
    duration_s = 30.0

    [[group]]
    fault = "none"
    manoeuvres = ["cruise"]
    count = 2

    [[run]]
    manoeuvre = "pitch_protection"
    alt_ft = 18000.0
    vcas_kt = 220.0
    mass_t = 180.0
    cg_pct = 30.0
    draws = { d_vcas = 0.05, d_chd = -0.2 }
    stream = 123456
    manoeuvre_start_s = 5.5

    [[detector]]
    name = "position-monitor"
    """)


def test_explicit_runs_follow_the_groups_with_their_own_streams(tmp_path):
    path = tmp_path / "runs.toml"
    path.write_text(RUNS)
    config = load_config(path)
    plan = build_plan(config)
    assert list(plan["stream"]) == [0, 1, 123456]
    row = plan.iloc[2]
    assert (row["group"], row["level"], row["d_vcas"], row["d_chd"], row["d_cm"]) == \
        ("runs", "run", 0.05, -0.2, 0.0)
    assert row["manoeuvre_start_s"] == 5.5
    assert row["run_id"] == explicit_plan(config, config.runs)["run_id"].iloc[0]
    # the groups' runs are those of the file without the [[run]]
    data = config.to_dict()
    data.pop("run")
    assert plan.iloc[:2].equals(build_plan(CampaignConfig.from_dict(data)))


def test_a_campaign_without_runs_keeps_its_canonical_form():
    assert "run" not in SMOKE.to_dict()
    assert '"run"' not in SMOKE.to_json()


@pytest.mark.parametrize("line, message", [
    ("draws = { d_vcs = 0.01 }", "run[0].draws.d_vcs: unknown draw column (did you mean "
                                 "'d_vcas'?)"),
    ("draws = { d_chd = 0.3 }", "run[0].draws.d_chd: 0.3 is outside the campaign's "
                                  "half-width ±0.2"),
    ('fault = "runaway"', "run[0].onset_s: missing"),
    ("onset_s = 3.0", "run[0].onset_s: a fault-free group (fault = \"none\") has no onset_s"),
    ("manoeuvre_start_s = 31.0", "run[0].manoeuvre_start_s: 31 s is not before the end"),
    ("alt_ft = 38000.0\nvcas_kt = 300.0", "fails the realistic-envelope rule"),
])
def test_explicit_runs_are_validated(tmp_path, line, message):
    body = "\n".join(ln for ln in RUNS.splitlines()
                     if not any(ln.startswith(k.split(" = ")[0] + " =")
                                for k in line.splitlines()))
    text = body.replace("stream = 123456", "stream = 123456\n" + line)
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ConfigError) as info:
        load_config(path)
    assert any(message in e for e in info.value.errors), info.value.errors


def test_worst_toml_round_trips_every_float():
    runs = [{"group": "falsify", "manoeuvre": "nose_up", "fault": "none",
             "alt_ft": 12345.678901234567, "vcas_kt": 201.00000000000003,
             "mass_t": 150.1, "cg_pct": 29.999999999999996,
             "draws": {d: 0.01 / 3 for d in envelope.DRAW_COLUMNS}, "stream": 2 ** 31 - 1,
             "manoeuvre_start_s": 7.123456789}]
    text = worst_toml(SMOKE, runs, label="position-monitor", note="a note")
    loaded = CampaignConfig.from_dict(tomllib.loads(text))
    assert loaded.runs[0].alt_ft == runs[0]["alt_ft"]
    assert loaded.runs[0].cg_pct == runs[0]["cg_pct"]
    assert loaded.groups == ()
    assert loaded.detectors == SMOKE.detectors and loaded.learning == SMOKE.learning


# ---- the strategy (campaign/evidence/falsify_search.py) ------------------------------------------
def _drive(strategy, objective):
    """Run *strategy* on *objective*(point) → margin; the batches and their margins."""
    seen = []
    while batch := strategy.ask():
        phase = strategy.phase
        margins = [objective(p) for p in batch]
        seen.append((phase, batch, margins))
        strategy.tell(batch, margins)
    return seen


def _corner(point):
    """A margin that rises towards one corner of the unit cube, in cell 2 most: the shape
    measured on addsafe-mc (a few variables decide, the worst run in a corner)."""
    u = np.array(point.unit)
    return (0.4 + 0.1 * (point.cell == 2) + 0.15 * u[0] + 0.1 * (1 - u[1]) + 0.05 * u[2]
            + 1e-3 * (point.stream % 7))


def test_strategy_spends_its_budget_in_three_phases_deterministically():
    from campaign.evidence.falsify_search import POLISH_SHARE, SCREEN_SHARE, Strategy

    def make(seed):
        return Strategy(n_dims=8, n_cells=4, budget=300, seed=seed, stream_span=STREAM_SPAN)

    seen = _drive(make(0), _corner)
    assert sum(len(b) for _, b, _ in seen) == 300
    phases = [p for p, _, _ in seen]
    assert phases[0] == "screen" and phases[-1] == "polish" and "focus" in phases
    assert len(seen[0][1]) == int(np.ceil(300 * SCREEN_SHARE))
    assert len(seen[-1][1]) >= int(300 * POLISH_SHARE)
    # the screening spreads over the cells; the focus holds each strategy's stream
    assert {p.cell for p in seen[0][1]} == {0, 1, 2, 3}
    focus = [p for ph, b, _ in seen if ph == "focus" for p in b]
    assert len({(p.cell, p.stream) for p in focus}) <= 2
    assert all(0.0 <= v <= 1.0 for p in focus for v in p.unit)
    # the concentrated search climbs beyond the screening's best, towards the corner
    screened = max(seen[0][2])
    best = max(m for _, _, ms in seen for m in ms)
    assert best > screened + 0.05
    # same seed → same points; another seed → other points
    again = _drive(make(0), _corner)
    assert [b for _, b, _ in again] == [b for _, b, _ in seen]
    assert [b for _, b, _ in _drive(make(1), _corner)][0] != seen[0][1]


def test_strategy_warm_start_comes_first_and_small_budgets_still_finish():
    from campaign.evidence.falsify_search import Point, Strategy

    warm = [Point((0.9, 0.1, math.nan), 1, 77), Point((0.5, 0.5, math.nan), 0, 78)]
    strategy = Strategy(n_dims=3, n_cells=3, budget=60, seed=3, stream_span=STREAM_SPAN,
                        warm=warm, start_dim=2, warm_start={0: 0.25})
    seen = _drive(strategy, lambda p: 0.5 + (p.stream == 77) * 0.3 + 0.1 * p.unit[0])
    assert seen[0][1][:2] == warm
    focus = [p for ph, b, _ in seen if ph == "focus" for p in b]
    assert focus and all(math.isfinite(v) for p in focus for v in p.unit)
    for budget in (10, 11, 25):
        small = Strategy(n_dims=20, n_cells=6, budget=budget, seed=0, stream_span=STREAM_SPAN)
        assert sum(len(b) for _, b, _ in _drive(small, _corner)) == budget


def test_against_warm_start_replays_the_campaign_worst_runs(searched, tmp_path):
    """With --against the screening opens with the campaign's worst fault-free runs as the
    campaign ran them (stream and drawn manoeuvre start): the same margins bit for bit."""
    camp = tmp_path / "camp"
    assert main(["run", "smoke", "--jobs", "1", "--quiet", "--out", str(camp)]) in (0, 1)
    assert main(["falsify", "smoke", "--detector", "position-monitor", "--budget", "20",
                 "--jobs", "1", "--keep", "3", "--against", str(camp), "--fitted-from",
                 str(camp), "--out", str(tmp_path / "w")]) in (0, 1)
    search = pd.read_parquet(tmp_path / "w" / "search.parquet")
    results = CampaignDir(camp).read_results()
    free = results[(results["detector"] == "position-monitor") & (results["fault"] == "none")]
    worst = free.sort_values("margin", ascending=False, kind="stable").head(3)
    first = search.iloc[:3]
    assert first["manoeuvre_start_s"].isna().all() and (first["phase"] == "screen").all()
    np.testing.assert_array_equal(first["margin"].to_numpy(), worst["margin"].to_numpy())


def test_scores_keep_the_flags_of_results_with_any_index():
    """The search's flag of a run is the campaign's ``false_alarm`` of that run, whatever
    the index of the result rows (a chunk's rows arrive with a non-default index; a flag
    taken by label through pandas' reindexing turned every one into False)."""
    from campaign.evidence.falsify import scores

    results = pd.DataFrame({
        "run_id": ["a", "b", "c", "d"], "detector": "m",
        "status": ["ok", "ok", "error", "ok"],
        "false_alarm": [True, False, False, True], "margin": [1.4, 0.7, np.nan, 1.1],
    }, index=[10, 11, 12, 13])
    rows = pd.DataFrame({"run_id": ["d", "c", "b", "a"]})
    margin, alarm = scores(results, rows, "m")
    np.testing.assert_array_equal(alarm, [True, False, False, True])
    np.testing.assert_array_equal(margin, [1.1, np.nan, 0.7, 1.4])
