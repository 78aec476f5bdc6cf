"""The worst-case gate's steps by value (campaign/evidence/worst_case.py, docs/evidence.md
"Worst-case gate"), without a simulation: the budget and seed checks at their boundaries,
which detectors are gated, the false alarms named worst first, the corpus files' runs, and
a stored search read back (reused) with its false alarms that the corpus did not name. The
searches and replays themselves are run by test_worst_case_gate.py."""

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from campaign.config import load_config
from campaign.config.schema import CampaignConfig
from campaign.evidence.falsify import MIN_BUDGET, worst_toml
from campaign.evidence.worst_case import (
    DEFAULT_SEED,
    KEEP,
    Alarm,
    WorstCase,
    WorstCaseError,
    WorstCaseOptionError,
    _alarms,
    _corpus_rows,
    _owner,
    check_budget,
    gated_names,
    replay_corpus,
    search_detector,
    worst_case,
)
from campaign.plan import explicit_plan
from campaign.store.directory import CampaignDir, SearchDir
from scenarios import envelope

SMOKE = load_config("smoke")


# ---- the budget and the seed --------------------------------------------------------------
def test_defaults():
    assert (DEFAULT_SEED, KEEP, MIN_BUDGET) == (0, 10, 10)


@pytest.mark.parametrize("given, runs", [(10, 10), ("10", 10), (" 300 ", 300), (np.int64(11), 11)])
def test_budget_of_at_least_ten_whole_runs(given, runs):
    assert check_budget(given) == runs and type(check_budget(given)) is int


@pytest.mark.parametrize("given, needle", [
    (9, "budget=9: the search needs at least 10 runs (screening, then the worst cell); "
        "fix: e.g. budget=300, or any other ≥ 10"),
    ("-3", "budget=-3: the search needs at least 10 runs"),
    ("abc", "budget 'abc': not a whole number of runs; fix: the runs each detector's "
            "worst-case search spends, e.g. budget 300"),
    ("2.5", "budget '2.5': not a whole number of runs"),
])
def test_budget_refused_below_ten_or_not_whole(given, needle):
    with pytest.raises(WorstCaseOptionError) as info:
        check_budget(given)
    assert needle in str(info.value)
    assert isinstance(info.value, WorstCaseError) and isinstance(info.value, ValueError)


def _no_free(config):
    data = config.to_dict()
    data["group"] = [g for g in data["group"] if g["fault"] != "none"]
    return CampaignConfig.from_dict(data)


@pytest.mark.parametrize("seed", [-1, True])
def test_seed_refused_when_negative_or_a_flag(seed, tmp_path):
    camp = SimpleNamespace(root=tmp_path, config=SMOKE)
    with pytest.raises(WorstCaseOptionError, match="seed=.*must be a whole number ≥ 0; "
                                                   "fix: e.g. seed=0"):
        worst_case(camp, 30, ["position-monitor"], seed=seed, log=lambda m: None)
    assert not (tmp_path / "worst-case").exists()


def test_seed_zero_is_taken_and_a_campaign_the_search_cannot_cover_is_refused(tmp_path):
    # seed 0 passes its check; the campaign without a fault-free group fails the next one
    camp = SimpleNamespace(root=tmp_path, config=_no_free(SMOKE))
    with pytest.raises(WorstCaseError) as info:
        worst_case(camp, "10", ["position-monitor"], seed=0, log=lambda m: None)
    assert not isinstance(info.value, WorstCaseOptionError)
    assert str(info.value).startswith(f"worst-case search of {tmp_path}: campaign ")
    assert "has no fault-free [[group]]" in str(info.value)
    with pytest.raises(WorstCaseOptionError, match="budget=9"):
        worst_case(camp, 9, ["position-monitor"], seed=-1, log=lambda m: None)


# ---- the detectors gated ------------------------------------------------------------------
def _summary():
    """pm: fault-free runs, gated at 0; ci[a=0.9]: a variant with fault-free runs; fa: its
    false alarms allowed; nf: no fault-free run scored (zero runs); jam-only: no fault-free
    row at all."""
    return pd.DataFrame({
        "detector": ["pm", "pm", "ci[a=0.9]", "fa", "nf", "nf", "jam-only"],
        "fault": ["none", "jam", "none", "none", "none", "jam", "jam"],
        "n_runs": [20, 5, 20, 20, 0, 5, 5],
    })


def test_gated_names_are_the_zero_rate_detectors_with_fault_free_runs():
    searched, left = gated_names(_summary(), {"fa": 1e-3, "pm": 0.0})
    assert searched == ["pm", "ci[a=0.9]"]
    assert left == [
        "fa: its false alarms are allowed up to a rate of 0.001 (detector_max_fa_rate), not "
        "gated at zero",
        "nf: no fault-free run scored, nothing to search around",
        "jam-only: no fault-free run scored, nothing to search around"]


def test_only_the_names_asked_for_each_a_detector_of_the_results():
    assert gated_names(_summary(), {}, only=["ci[a=0.9]", "nf"]) == (
        ["ci[a=0.9]"], ["nf: no fault-free run scored, nothing to search around"])
    assert gated_names(_summary(), {}, only=[]) == gated_names(_summary(), {})
    with pytest.raises(WorstCaseOptionError) as info:
        gated_names(_summary(), {}, only=["pm", "ci"])
    assert ("only='ci': not a detector of these results; choose among pm, ci[a=0.9], fa, nf, "
            "jam-only (a variant is named as in the results, e.g. comb-interval[a=0.9])"
            in str(info.value))


def test_a_variant_belongs_to_its_detector_label():
    labels = ["comb", "comb-interval", "pm"]
    assert _owner("comb-interval[a=0.9]", labels) == "comb-interval"
    assert _owner("comb", labels) == "comb" and _owner("pm", labels) == "pm"
    assert _owner("comb[x=1]", labels) == "comb"


# ---- the false alarms ---------------------------------------------------------------------
def _rows(n):
    return pd.DataFrame({"run_id": [f"r{i}" for i in range(n)],
                         "manoeuvre": [f"m{i}" for i in range(n)],
                         "alt_ft": 10000.0 + np.arange(n), "vcas_kt": 250.25 + np.arange(n),
                         "mass_t": 180.0 + 0.5 * np.arange(n), "cg_pct": 25.0 + np.arange(n)},
                        index=np.arange(n) + 100)        # a chunk's index, not 0…n-1


def test_alarms_of_the_flagged_rows_worst_margin_first():
    rows = _rows(5)
    flags = np.array([True, False, True, True, False])
    margin = np.array([1.2, 3.0, 1.5, 1.2, 0.1])
    files = [Path(f"w{i}.toml") for i in range(5)]
    alarms = _alarms(rows, flags, margin, files, "corpus")
    # 1.5 first; the two 1.2 in the rows' order (a stable sort)
    assert [a.run_id for a in alarms] == ["r2", "r0", "r3"]
    a = alarms[0]
    assert a == Alarm("r2", "m2", {"alt_ft": 10002.0, "vcas_kt": 252.25, "mass_t": 181.0,
                                   "cg_pct": 27.0}, 1.5, Path("w2.toml"), "corpus")
    assert a.describe() == ("run r2 (m2, 10002 ft, 252.2 kt, 181.0 t, cg 27.0 %), "
                            "margin 1.5")
    assert _alarms(rows, np.zeros(5, bool), margin, files, "search") == []


def test_a_worst_case_passes_without_alarms():
    found = WorstCase("pm", 30, 0, Path("d"))
    assert found.passed and np.isnan(found.worst_margin) and not found.reused
    found.alarms.append(Alarm("r", "m", {}, 1.0, Path("w"), "search"))
    assert not found.passed
    assert WorstCase("pm", 30, 0, Path("d")).alarms == []      # not shared


# ---- the corpus ---------------------------------------------------------------------------
def _runs(streams, manoeuvre="pitch_protection"):
    return [{"group": "falsify", "manoeuvre": manoeuvre, "fault": "none", "alt_ft": 18000.0,
             "vcas_kt": 220.0, "mass_t": 180.0, "cg_pct": 30.0,
             "draws": {d: 0.0 for d in envelope.DRAW_COLUMNS}, "stream": s,
             "manoeuvre_start_s": 5.5} for s in streams]


def test_corpus_rows_hold_each_run_once_at_its_first_file(tmp_path):
    a, b = tmp_path / "a.toml", tmp_path / "b.toml"
    a.write_text(worst_toml(SMOKE, _runs([11, 12]), label="position-monitor", note="a"))
    b.write_text(worst_toml(SMOKE, _runs([12, 13, 14]), label="position-monitor", note="b"))
    rows, files = _corpus_rows(SMOKE, [a, b])
    assert list(rows["stream"]) == [11, 12, 13, 14] and list(rows.index) == [0, 1, 2, 3]
    assert files == [a, a, b, b]
    assert rows["run_id"].is_unique
    # the run-table's own columns, no index column left behind
    assert list(rows.columns) == list(explicit_plan(SMOKE, _runs([11])).columns)


def test_no_corpus_no_replay(tmp_path):
    outcomes = {"position-monitor": WorstCase("position-monitor", 30, 0, tmp_path / "s")}
    camp = SimpleNamespace(root=tmp_path, config=SMOKE)
    replay_corpus(camp, outcomes, jobs=1, log=lambda m: None)
    found = outcomes["position-monitor"]
    assert (found.corpus_files, found.corpus_runs, found.alarms) == (0, 0, [])
    assert not CampaignDir(tmp_path).worst_case_replay_dir().exists()


# ---- a stored search, reused --------------------------------------------------------------
def _stored(tmp_path, name="position-monitor", budget=30, seed=0, config=SMOKE):
    """A finished search of *name* stored under *tmp_path*: five runs, r1 and r3 false
    alarms, r2 the largest margin (no alarm: shorter than the confirmation), r4 in error."""
    search = _rows(5).reset_index(drop=True).assign(
        margin=[0.5, 1.1, 1.3, 1.05, np.nan],
        false_alarm=[False, True, False, True, None])
    path = CampaignDir(tmp_path).worst_case_search_dir(name, budget, seed)
    path.mkdir(parents=True)
    stored = SearchDir(path)
    stored.write_search(search, config.to_json(), detector=name, budget=budget, seed=seed)
    stored.write_worst("# stored")
    return path, stored


def test_a_stored_search_is_read_back_with_its_false_alarms(tmp_path):
    path, stored = _stored(tmp_path)
    camp = SimpleNamespace(root=tmp_path, config=SMOKE)
    found = WorstCase("position-monitor", 30, 0, path)
    said = []
    search_detector(camp, found, jobs=1, log=said.append)
    assert found.reused and "is stored in" in said[0] and "reused, not run again" in said[0]
    assert (found.searched, found.search_alarms) == (5, 2)
    assert (found.worst_margin, found.worst_run, found.worst_manoeuvre) == (1.3, "r2", "m2")
    assert [(a.run_id, a.margin, a.source, a.worst_toml) for a in found.alarms] == [
        ("r1", 1.1, "stored search", stored.worst_path),
        ("r3", 1.05, "stored search", stored.worst_path)]
    assert not found.passed


def test_alarms_the_corpus_named_are_not_named_again(tmp_path):
    path, _ = _stored(tmp_path)
    camp = SimpleNamespace(root=tmp_path, config=SMOKE)
    found = WorstCase("position-monitor", 30, 0, path)
    found.alarms.append(Alarm("r3", "m3", {}, 1.05, Path("corpus.toml"), "corpus"))
    search_detector(camp, found, jobs=1, log=lambda m: None)
    assert [(a.run_id, a.source) for a in found.alarms] == [("r3", "corpus"),
                                                             ("r1", "stored search")]
    assert found.search_alarms == 2


def test_a_stored_search_of_every_run_in_error_names_no_worst_run(tmp_path):
    path = CampaignDir(tmp_path).worst_case_search_dir("position-monitor", 30, 0)
    path.mkdir(parents=True)
    stored = SearchDir(path)
    search = _rows(2).reset_index(drop=True).assign(margin=np.nan, false_alarm=None)
    stored.write_search(search, SMOKE.to_json(), detector="position-monitor", budget=30,
                        seed=0)
    stored.write_worst("# stored")
    found = WorstCase("position-monitor", 30, 0, path)
    search_detector(SimpleNamespace(root=tmp_path, config=SMOKE), found, jobs=1,
                    log=lambda m: None)
    assert found.reused and (found.searched, found.search_alarms) == (2, 0)
    assert np.isnan(found.worst_margin) and found.worst_run == "" and found.passed


# ---- the corpus replay and the search, the simulation replaced by a recorder ---------------
# The orchestration of the gate on its own: the runner's pipeline (campaign.runner.prepare
# and evaluate_rows) and the search (falsify) are replaced by recorders that answer with
# result rows chosen here (margin and false alarm per stream); test_worst_case_gate.py runs
# the real pipeline.
class _Pipeline:
    """Recorder of the runner's pipeline: each run's margin and false alarm by its stream."""

    def __init__(self, outcome):
        self.outcome, self.prepared, self.evaluated, self.closed = outcome, [], [], 0

    def prepare(self, config, out, **kwargs):
        self.prepared.append((config, out, kwargs))
        return SimpleNamespace(close=self.close), {"position-monitor": "pm-object",
                                                   "comb": "comb-object"}

    def close(self):
        self.closed += 1

    def evaluate_rows(self, setup, rows, detectors, log=None):
        self.evaluated.append((list(rows["run_id"]), dict(detectors)))
        (label,) = detectors
        names = [label, f"{label}[safety=2]"]
        return pd.DataFrame([{"run_id": r, "detector": name, "status": "ok",
                              "margin": self.outcome[s][0], "false_alarm": self.outcome[s][1]}
                             for r, s in zip(rows["run_id"], rows["stream"]) for name in names])


def _store(root, name, streams, budget=30, seed=0):
    """A finished search of *name* under campaign directory *root* whose worst.toml holds
    the runs of *streams*."""
    path = CampaignDir(root).worst_case_search_dir(name, budget, seed)
    path.mkdir(parents=True)
    stored = SearchDir(path)
    stored.write_search(pd.DataFrame({"run_id": ["x"], "margin": [0.0]}), SMOKE.to_json(),
                        detector=name, budget=budget, seed=seed)
    stored.write_worst(worst_toml(SMOKE, _runs(streams), label=name, note="stored"))
    return stored.worst_path


@pytest.fixture
def pipeline(monkeypatch):
    import campaign.runner

    rec = _Pipeline({11: (0.4, False), 12: (1.3, True), 13: (1.6, True), 14: (0.9, False)})
    monkeypatch.setattr(campaign.runner, "prepare", rec.prepare)
    monkeypatch.setattr(campaign.runner, "evaluate_rows", rec.evaluate_rows)
    return rec


def test_the_corpus_of_each_name_is_replayed_with_its_owners_fitted_detector(tmp_path,
                                                                             pipeline):
    first = _store(tmp_path, "position-monitor", [11, 12], budget=30)
    second = _store(tmp_path, "position-monitor", [12, 13, 14], budget=40)
    variant = _store(tmp_path, "position-monitor[safety=2]", [14])
    names = ["comb", "position-monitor", "position-monitor[safety=2]"]    # comb: no corpus
    outcomes = {n: WorstCase(n, 30, 0, tmp_path / n) for n in names}
    said = []
    camp = SimpleNamespace(root=tmp_path, config=SMOKE)
    replay_corpus(camp, outcomes, jobs=3, scheduler="tcp://s", tls="t", log=said.append)
    # one set-up for every name, on the campaign's fitted detectors, closed after
    ((config, out, kwargs),) = pipeline.prepared
    assert config is SMOKE and out == CampaignDir(tmp_path).worst_case_replay_dir()
    assert kwargs == {"jobs": 3, "scheduler": "tcp://s", "tls": "t", "fitted_from": tmp_path,
                      "log": said.append}
    assert pipeline.closed == 1
    rows, _ = _corpus_rows(SMOKE, [first, second])
    (ids, dets), (vids, vdets) = pipeline.evaluated
    assert ids == list(rows["run_id"]) and dets == {"position-monitor": "pm-object"}
    assert vdets == {"position-monitor": "pm-object"} and len(vids) == 1
    pm = outcomes["position-monitor"]
    assert (pm.corpus_files, pm.corpus_runs) == (2, 4)
    # the corpus's false alarms, worst first, each with the file that holds it
    assert [(a.margin, a.source, a.worst_toml) for a in pm.alarms] == [
        (1.6, "corpus", second), (1.3, "corpus", first)]
    assert outcomes["position-monitor[safety=2]"].corpus_runs == 1
    assert outcomes["position-monitor[safety=2]"].alarms == []
    assert outcomes["position-monitor[safety=2]"].corpus_files == 1 and variant.is_file()
    comb = outcomes["comb"]
    assert (comb.corpus_files, comb.corpus_runs, comb.alarms) == (0, 0, [])
    assert "worst case position-monitor: replaying the corpus first, 4 runs of 2 stored " \
           "search(es)" in said


def test_the_replay_set_up_is_closed_when_a_replay_fails(tmp_path, pipeline, monkeypatch):
    import campaign.runner

    _store(tmp_path, "position-monitor", [11])

    def broken(*args, **kwargs):
        raise RuntimeError("worker lost")

    monkeypatch.setattr(campaign.runner, "evaluate_rows", broken)
    outcomes = {"position-monitor": WorstCase("position-monitor", 30, 0, tmp_path / "s")}
    with pytest.raises(RuntimeError, match="worker lost"):
        replay_corpus(SimpleNamespace(root=tmp_path, config=SMOKE), outcomes, jobs=1,
                      log=lambda m: None)
    assert pipeline.closed == 1


class _Search:
    """Recorder of falsify: a search of four runs, r1 and r2 false alarms."""

    def __init__(self, fail=None):
        self.calls, self.fail = [], fail

    def __call__(self, config, label, **kwargs):
        self.calls.append((config, label, kwargs))
        if self.fail:
            raise self.fail
        return SimpleNamespace(search=_rows(4).reset_index(drop=True).assign(
            margin=[0.2, 1.4, 1.1, 0.8], false_alarm=[False, True, True, None]))


def test_a_search_not_stored_is_run_with_the_campaigns_detectors(tmp_path, monkeypatch):
    import campaign.evidence.worst_case as wc

    search = _Search()
    monkeypatch.setattr(wc, "falsify", search)
    path = CampaignDir(tmp_path).worst_case_search_dir("position-monitor", 30, 4)
    found = WorstCase("position-monitor", 30, 4, path)
    found.alarms.append(Alarm("r2", "m2", {}, 1.1, Path("c.toml"), "corpus"))
    said = []
    search_detector(SimpleNamespace(root=tmp_path, config=SMOKE), found, jobs=2,
                    scheduler="tcp://s", tls="t", log=said.append)
    ((config, label, kwargs),) = search.calls
    assert config is SMOKE and label == "position-monitor"
    assert kwargs == {"budget": 30, "out": path, "jobs": 2, "seed": 4, "scheduler": "tcp://s",
                      "tls": "t", "fitted_from": tmp_path, "against": tmp_path, "keep": KEEP,
                      "log": said.append}
    assert said == [f"worst case position-monitor: searching 30 fault-free runs (seed 4) -> "
                    f"{path}"]
    assert not found.reused and (found.searched, found.search_alarms) == (4, 2)
    assert (found.worst_margin, found.worst_run, found.worst_manoeuvre) == (1.4, "r1", "m1")
    assert [(a.run_id, a.source) for a in found.alarms] == [("r2", "corpus"), ("r1", "search")]
    assert found.alarms[1].worst_toml == SearchDir(path).worst_path


def test_a_search_that_cannot_start_is_a_worst_case_error(tmp_path, monkeypatch):
    import campaign.evidence.worst_case as wc
    from campaign.evidence.falsify import FalsifyError

    monkeypatch.setattr(wc, "falsify", _Search(FalsifyError("every run failed")))
    found = WorstCase("position-monitor", 30, 0, tmp_path / "s")
    with pytest.raises(WorstCaseError, match="^worst case position-monitor: every run "
                                             "failed$"):
        search_detector(SimpleNamespace(root=tmp_path, config=SMOKE), found, jobs=1,
                        log=lambda m: None)


def test_the_gate_replays_the_corpus_then_searches_each_name(tmp_path, pipeline, monkeypatch,
                                                             capsys):
    import campaign.evidence.worst_case as wc

    search = _Search()
    monkeypatch.setattr(wc, "falsify", search)
    _store(tmp_path, "position-monitor", [12], budget=50)
    camp = SimpleNamespace(root=tmp_path, config=SMOKE)
    out = worst_case(camp, " 30 ", ["position-monitor", "comb"], seed=np.int64(5), jobs=1)
    assert [(w.name, w.budget, w.seed) for w in out] == [("position-monitor", 30, 5),
                                                         ("comb", 30, 5)]
    assert type(out[0].seed) is int
    assert out[0].search_dir == CampaignDir(tmp_path).worst_case_search_dir(
        "position-monitor", 30, 5)
    assert [c[1] for c in search.calls] == ["position-monitor", "comb"]
    # the corpus run (stream 12) first, then the search's alarms
    assert [(a.source, a.margin) for a in out[0].alarms] == [("corpus", 1.3),
                                                             ("search", 1.4),
                                                             ("search", 1.1)]
    assert not out[0].passed and not out[1].passed
    # without a log the progress goes to stderr
    err = capsys.readouterr().err
    assert "worst case position-monitor: replaying the corpus first, 1 runs" in err
    assert "worst case comb: searching 30 fault-free runs (seed 5)" in err


def test_options_are_keyword_only_and_a_fresh_outcome_has_counted_nothing():
    import inspect

    for fn, options in ((worst_case, ("seed", "jobs", "scheduler", "tls", "log")),
                        (replay_corpus, ("jobs", "scheduler", "tls", "log")),
                        (search_detector, ("jobs", "scheduler", "tls", "log"))):
        params = inspect.signature(fn).parameters
        assert all(params[o].kind is inspect.Parameter.KEYWORD_ONLY for o in options), fn
    found = WorstCase("pm", 30, 0, Path("d"))
    assert (found.searched, found.search_alarms, found.corpus_files, found.corpus_runs) == (
        0, 0, 0, 0)
    assert (found.worst_run, found.worst_manoeuvre) == ("", "")
    alarm = Alarm("r", "m", {}, 1.0, Path("w"), "search")
    import dataclasses

    with pytest.raises(dataclasses.FrozenInstanceError):
        alarm.margin = 2.0


def test_a_detector_with_a_single_fault_free_run_is_gated():
    summary = pd.DataFrame({"detector": ["pm"], "fault": ["none"], "n_runs": [1]})
    assert gated_names(summary, {}) == (["pm"], [])


def test_the_gate_searches_on_two_workers_by_default(tmp_path, pipeline, monkeypatch):
    import campaign.evidence.worst_case as wc

    search = _Search()
    monkeypatch.setattr(wc, "falsify", search)
    worst_case(SimpleNamespace(root=tmp_path, config=SMOKE), 30, ["comb"], log=lambda m: None)
    ((_, _, kwargs),) = search.calls
    assert kwargs["jobs"] == 2 and kwargs["seed"] == DEFAULT_SEED
