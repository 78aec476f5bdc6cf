"""Detection systems, declared coverage and the one detector order (docs/design.md §5,
Detection systems; docs/report.md): a ``[[system]]`` is scored as the first alarm of its
members, the gate holds each detector to the faults it covers and a system's members to
none of the MD/DTP limits, and every output lists detectors in one order."""

from __future__ import annotations

import contextlib
import io
import re
import xml.etree.ElementTree as ET

import numpy as np
import pandas as pd
import pytest

from campaign.cli.commands import main
from campaign.config import CampaignConfig, ConfigError
from campaign.isolation import roles_of
from campaign.store.directory import CampaignDir
from detectors import Detection, make_detector
from detectors.system import DetectionSystem
from reports.scoring.gate import evaluate_gate
from reports.scoring.summary import detector_order, summarize

from small_campaigns import campaign_toml, small_campaign

MEMBERS = ["pm", "comb-interval[a=0.9]"]
#: the one order: by name, numbers by value ("a=0.9" before "a=0.95", which text order
#: reverses), the system among the detectors by its name
ORDER = ["comb-interval[a=0.6]", "comb-interval[a=0.9]", "comb-interval[a=0.95]",
         "fdd-system", "pm"]


def _config(seed: int) -> dict:
    cfg = small_campaign("system", seed, [{"name": "comb-interval",
                                           "params": {"poles": [0.6, 0.95, 0.9]}}])
    cfg["group"].append({"name": "dc", "fault": "disconnection", "manoeuvres": ["cruise"],
                         "count": 2})
    cfg["faults"]["onset_before_end_s"] = 0.5
    cfg["system"] = [{"name": "fdd-system", "members": MEMBERS}]
    return cfg


@pytest.fixture(scope="module")
def system_run(tmp_path_factory):
    """The campaign directory and what ``run`` printed."""
    root = tmp_path_factory.mktemp("system")
    path = root / "system.toml"
    path.write_text(campaign_toml(_config(seed=808)))
    out = root / "out"
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        code = main(["run", str(path), "--out", str(out), "--quiet", "--jobs", "1"])
    assert code in (0, 1)
    return out, printed.getvalue()


@pytest.fixture(scope="module")
def system_dir(system_run):
    return system_run[0]


def test_system_rows_are_the_first_alarm_of_its_members(system_dir):
    r = CampaignDir(system_dir).read_results()
    assert (r["status"] == "ok").all()
    members = r[r["detector"].isin(MEMBERS)].groupby("run_id")
    system = r[r["detector"] == "fdd-system"].set_index("run_id")
    assert len(system) == r["run_id"].nunique()
    expected = pd.DataFrame({
        "false_alarm": members["false_alarm"].any(), "detected": members["detected"].any(),
        "first_alarm_s": members["first_alarm_s"].min(), "dtp": members["dtp"].min(),
        "margin": members["margin"].max()})
    got = system.loc[expected.index, list(expected.columns)]
    for column in ("false_alarm", "detected"):
        assert got[column].astype(bool).tolist() == expected[column].tolist(), column
    for column in ("first_alarm_s", "dtp", "margin"):   # exact: a min/max of the same floats
        np.testing.assert_array_equal(got[column].to_numpy(float),
                                      expected[column].to_numpy(float), err_msg=column)
    # not a copy of one member: each gives the system something the other does not — the
    # monitor the only detection of a run (a disconnection, which the rod-sensor interval
    # detector cannot see), the interval detector the larger margin of a run
    pm = r[r["detector"] == "pm"].set_index("run_id").loc[system.index]
    comb = r[r["detector"] == "comb-interval[a=0.9]"].set_index("run_id").loc[system.index]
    assert (pm["detected"].astype(bool) & ~comb["detected"].astype(bool)).any()
    assert (system["margin"] == comb["margin"]).any() and (comb["margin"] > pm["margin"]).any()


def test_gate_holds_the_system_and_the_faults_each_detector_covers(system_dir, capsys):
    code = main(["gate", str(system_dir), "--all-requirements",
                 "--junit", str(system_dir / "gate.xml")])
    text = capsys.readouterr().out
    lines = text.splitlines()
    # the rod-sensor interval detector is not designed for disconnections: reported, not failed
    not_for = [ln for ln in lines if ln.startswith("INFO not designed for: comb-interval[a=0.6]"
                                                   ", disconnection")]
    assert len(not_for) == 1 and "docs/physics.md §5" in not_for[0]
    assert not any(ln.startswith("FAIL") and "comb-interval" in ln and "disconnection" in ln
                   for ln in lines)
    # members are reported for the system, which carries the MD and DTP requirements
    assert any(ln.startswith("INFO member of fdd-system: pm, runaway") for ln in lines)
    assert not any(ln.startswith(("PASS missed", "FAIL missed")) and ", pm," in ln
                   for ln in lines)
    assert any(re.match(r"(PASS|FAIL) missed detections: fdd-system, disconnection", ln)
               for ln in lines)
    suite = ET.parse(system_dir / "gate.xml").getroot().find("testsuite")
    informative = [ln for ln in lines if ln.startswith("INFO")]
    assert int(suite.get("skipped")) == len(informative) > 0
    assert code == (1 if any(ln.startswith("FAIL") for ln in lines) else 0)


def _first_positions(text: str, names) -> list[str]:
    """*names* in the order of their first appearance as a whole word in *text*."""
    found = {}
    for name in names:
        m = re.search(r"(?<![\w\[.=-])" + re.escape(name) + r"(?![\w\].=-])", text)
        if m:
            found[name] = m.start()
    return sorted(found, key=found.get)


def test_one_detector_order_in_run_gate_certify_and_report(system_run, tmp_path, capsys):
    system_dir, printed = system_run
    outputs = {"run": printed}
    main(["gate", str(system_dir)])
    outputs["gate"] = capsys.readouterr().out
    main(["certify", str(system_dir), "--jobs", "1"])
    outputs["certify"] = capsys.readouterr().out
    main(["report", str(system_dir), "--html", str(tmp_path / "report.html"), "--jobs", "1"])
    capsys.readouterr()
    outputs["report"] = (tmp_path / "report.html").read_text()
    for what, text in outputs.items():
        assert _first_positions(text, ORDER) == ORDER, what
    # the overview's MD cells say which faults a detector is not held to, and why
    page = outputs["report"]
    assert re.search(r"not designed for: disconnection \([0-2]/2 detected\)", page)
    assert "member of fdd-system: its MD and DTP are the system&#x27;s requirement" in page \
        or "member of fdd-system: its MD and DTP are the system's requirement" in page


def test_detector_order_puts_numbers_by_value():
    assert detector_order(["pm", "c[a=0.9]", "c[a=0.95]", "c[a=0.6]", "pm"]) == \
        ["c[a=0.6]", "c[a=0.9]", "c[a=0.95]", "pm"]


# ---- the combination, value by value -----------------------------------------------------
class _Fixed:
    """A fitted detector that returns fixed detections (for the combination's algebra)."""

    def __init__(self, out, scaled=True):
        from detectors import Capabilities

        self.out = out
        self.capabilities = Capabilities(needs_fit=False, threshold_scale=scaled)

    def detect(self, signals):
        return self.out

    def coverage(self, variant=None):
        return make_detector("comb-interval", {}).coverage(variant)


def _det(decision, residual=None):
    decision = np.atleast_2d(np.asarray(decision, float))
    alarm = np.maximum.accumulate(np.nan_to_num(decision, nan=0.0) >= 1.0, axis=1)
    return Detection(alarm=alarm, residual=decision if residual is None else residual,
                     decision=decision)


def test_combination_is_the_earliest_alarm_and_the_largest_decision():
    a = _det([[0.2, np.nan, 0.5, 1.2, 0.1]])
    b = _det([[np.nan, 0.4, 1.0, 0.3, 0.2]])
    system = DetectionSystem(("a", "b"), {"a": _Fixed(a), "b": _Fixed(b)})
    out = system.combine({"a": a, "b": b})
    np.testing.assert_array_equal(out.decision, [[0.2, 0.4, 1.0, 1.2, 0.2]])
    assert out.alarm.tolist() == [[False, False, True, True, True]]     # b's, at step 2
    assert system.capabilities.threshold_scale
    # at threshold × 1.1 only a alarms (1.2 ≥ 1.1 at step 3): the system's decision says so
    assert int(np.argmax(out.decision[0] >= 1.1)) == 3


def test_a_member_without_a_decision_leaves_the_system_without_one():
    a = _det([[0.2, 1.5]])
    b = Detection(alarm=np.array([[False, False]]), residual=np.array([[0.1, 0.3]]))
    system = DetectionSystem(("a", "b"), {"a": _Fixed(a), "b": _Fixed(b, scaled=False)})
    assert system.combine({"a": a, "b": b}).decision is None
    assert not system.capabilities.threshold_scale


def test_a_bare_label_stands_for_every_variant_and_a_wrong_variant_is_named():
    system = DetectionSystem(("c",), {"c": _Fixed(None)})
    assert system.member_names(["c[a=0.6]", "c[a=0.9]", "d"]) == ["c[a=0.6]", "c[a=0.9]"]
    wrong = DetectionSystem(("c[a=0.7]",), {"c": _Fixed(None)})
    with pytest.raises(ValueError, match=r"'c\[a=0.7\]' is no result of detector 'c', whose "
                                         r"results are c\[a=0.6\], c\[a=0.9\]"):
        wrong.member_names(["c[a=0.6]", "c[a=0.9]"])


def test_the_campaign_file_refuses_a_system_that_names_no_detector():
    cfg = _config(seed=1)
    cfg["system"] = [{"name": "pm", "members": ["pm", "comb-intervall"]}]
    with pytest.raises(ConfigError) as err:
        CampaignConfig.from_dict(cfg)
    text = str(err.value)
    assert "system[0].name: 'pm' is already a [[detector]] label" in text
    assert "system[0].members[1]: 'comb-intervall' names no detector" in text
    assert "did you mean 'comb-interval'" in text


# ---- coverage in the gate, without simulation ------------------------------------------
def _summary(detected_disconnections: int) -> pd.DataFrame:
    rows = []
    for i in range(4):
        rows.append({"run_id": f"f{i}", "fault": "none", "manoeuvre": "cruise",
                     "detected": False, "dtp": np.nan, "delay_s": np.nan})
    for i in range(4):
        hit = i < detected_disconnections
        rows.append({"run_id": f"d{i}", "fault": "disconnection", "manoeuvre": "cruise",
                     "detected": hit, "dtp": 0.5 if hit else np.nan,
                     "delay_s": 0.5 if hit else np.nan})
    r = pd.DataFrame(rows).assign(detector="comb-interval[a=0.9]", status="ok",
                                  false_alarm=False, margin=0.3, error="")
    return summarize(r), r


def test_a_fault_outside_the_declared_coverage_never_fails_the_gate():
    summary, results = _summary(detected_disconnections=0)
    config = CampaignConfig.from_dict(small_campaign("cov", 1, [{"name": "comb-interval"}]))
    roles = roles_of(config)
    held = evaluate_gate(summary, results=results, max_md=0.0, max_dtp=1.0, roles=roles)
    assert held.passed
    info = [c for c in held.checks if c.informative]
    assert [(c.name, c.fault, c.value) for c in info] == \
        [("not_designed_for", "disconnection", 0.0)]
    assert info[0].message.startswith("INFO not designed for: comb-interval[a=0.9], "
                                      "disconnection: 0/4 detected")
    # without the roles, the same rows fail: the coverage is what lets them pass
    assert not evaluate_gate(summary, results=results, max_md=0.0, max_dtp=1.0).passed
    # on the surface sensor the detector covers disconnections and is held to them
    surface = small_campaign("cov", 1, [{"name": "comb-interval",
                                         "params": {"sensor": "surface"}}])
    roles = roles_of(CampaignConfig.from_dict(surface))
    assert not evaluate_gate(summary, results=results, max_md=0.0, roles=roles).passed


def test_a_member_variant_the_detector_does_not_give_is_refused_before_any_run():
    cfg = _config(seed=1)
    cfg["system"] = [{"name": "s", "members": ["pm", "comb-interval[a=0.85]"]}]
    with pytest.raises(ConfigError) as err:
        CampaignConfig.from_dict(cfg)
    assert ("system[0].members[1]: 'comb-interval[a=0.85]' is no variant of detector "
            "'comb-interval', whose results are comb-interval[a=0.6], comb-interval[a=0.95], "
            "comb-interval[a=0.9]") in str(err.value)
    cfg["system"] = [{"name": "s", "members": ["pm", "comb-interval[a=0.95]"]}]
    assert CampaignConfig.from_dict(cfg).systems[0].members[1] == "comb-interval[a=0.95]"


def test_a_worst_case_search_may_name_a_detection_system():
    """``falsify --detector`` and ``gate --worst-case`` search a system as a detector (its
    margin is the largest of its members'); an unknown name lists the systems too."""
    from campaign.evidence.falsify import FalsifyError, check_label

    config = CampaignConfig.from_dict(_config(seed=1))
    check_label(config, "fdd-system")
    check_label(config, "comb-interval[a=0.9]")
    with pytest.raises(FalsifyError, match="its detection systems: fdd-system"):
        check_label(config, "fdd-systen")
