"""Isolation in the gate: a detector that declares the surface whose faults it detects
(``Capabilities.fault_surfaces``, e.g. vanek-geometric) must stay silent on another surface's
faults; an alarm there is an isolation failure the gate names, not a detection
(campaign/isolation.py, reports/scoring/gate.py)."""

import numpy as np
import pandas as pd
import pytest

from campaign.config import load_config
from campaign.isolation import roles_of
from campaign.plant_setup import resolve
from reports.scoring.gate import evaluate_gate
from reports.scoring.metrics import ESTIMATE_COLUMNS
from reports.scoring.summary import summarize

DET = "vanek-geometric[lpv]"


def _rows(fault, detected):
    """One run per entry of *detected* (fault-free when fault is "none")."""
    n = len(detected)
    det = np.asarray(detected, bool)
    out = pd.DataFrame({
        "run_id": [f"{fault}-{i}" for i in range(n)], "detector": DET, "fault": fault,
        "manoeuvre": "cruise", "status": "ok", "error": "", "false_alarm": False,
        "pre_onset_alarm": False, "detected": det,
        "first_alarm_s": np.where(det, 23.0, np.nan), "delay_s": np.where(det, 3.0, np.nan),
        "dtp": np.where(det, 1.5, np.nan), "margin": 0.4})
    for column in ESTIMATE_COLUMNS:
        out[column] = 0 if column == "est_err_n" else np.nan
    return out


def _results(detected):
    return pd.concat([_rows("none", [False] * 3), _rows("runaway", detected)],
                     ignore_index=True)


def test_an_alarm_on_another_surfaces_fault_fails_isolation_and_names_the_run():
    results = _results([False, True, False, False])
    gate = evaluate_gate(summarize(results), max_md=0.0, max_dtp=1.0, results=results,
                         isolation={"vanek-geometric": "left_elevator"})
    iso = [c for c in gate.checks if c.name == "isolation"]
    assert len(iso) == 1 and not iso[0].passed
    assert iso[0].value == pytest.approx(0.25)            # 1 of 4 runs alarmed
    assert iso[0].run_ids == ("runaway-1",)
    assert "isolation" in iso[0].message and "1/4" in iso[0].message
    # not scored as detection: no missed-detection or DTP check for this detector
    assert not [c for c in gate.checks if c.name in ("missed_detection", "dtp")]
    assert not gate.passed


def test_silence_on_another_surfaces_fault_passes_isolation():
    results = _results([False] * 4)
    gate = evaluate_gate(summarize(results), max_md=0.0, results=results,
                         isolation={DET: "left_elevator"})          # by result-row name
    iso = [c for c in gate.checks if c.name == "isolation"]
    assert [c.passed for c in iso] == [True] and gate.passed
    # without the isolation requirement the same runs are missed detections (MD 100 %)
    plain = evaluate_gate(summarize(results), max_md=0.0, results=results)
    assert not plain.passed
    assert [c.name for c in plain.failures] == ["missed_detection"]


def test_the_presets_say_which_detector_is_checked_for_isolation():
    # vanek-geometric detects faults of the left inboard aileron only
    def isolation_of(source):
        return roles_of(source).isolation

    assert isolation_of(load_config("vanek-isolation")) == {"vanek-geometric": "left_elevator"}
    assert isolation_of(load_config("vanek-isolation-rudder")) == {"vanek-geometric": "rudder"}
    config = load_config("vanek-scenarios")
    assert isolation_of(config) == {}                # its own surface: detection
    assert isolation_of(load_config("smoke")) == {}  # detectors that declare no surface
    # the resolved campaign and the configuration stored with the results give the same
    # answer, through the same entry
    resolved = resolve(load_config("vanek-isolation"))
    assert resolved.isolation == {"vanek-geometric": "left_elevator"}
    assert isolation_of(resolved) == resolved.isolation
    stored = load_config("vanek-isolation").to_dict()
    assert isolation_of(stored) == {"vanek-geometric": "left_elevator"}
    assert isolation_of(None) == {} and roles_of({}).detectors == {}
