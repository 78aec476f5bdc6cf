"""What ``certify`` reads of a campaign's result rows, gathered a batch of rows at a time
(:meth:`campaign.result.Campaign.result_batches`), so that it never holds every row
(docs/execution.md, "Memory independent of the number of runs").

Per detector (result-row name), of the rows with ``status = "ok"``:

* the fault-free runs (``fault = "none"``): their margins, manoeuvres and durations, one
  value each per run, because the tail fit of the exceedance curve
  (:func:`detectors.tail.exceedance_curve`) and the exposure (Σ of the durations) need
  every one of them: 8 + 8 + 2 bytes per fault-free run × detector (float64 margin and
  duration, an int16 code of the manoeuvre), 18 MB for 10⁶ runs of one detector;
* the faulty runs: per fault type, the counts of runs, of misses and of misses or late
  detections (DTP > 1), which the hazard table needs and nothing more.

Detectors are kept in the order of their first row, separately among the fault-free rows
(the certificate's and the curve's order) and among all the ``ok`` rows (the hazard table's),
as ``groupby(sort=False)`` of the whole table orders them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from reports.scoring.metrics import FAULT_FREE
from reports.scoring.summary import detector_order

__all__ = ["CERTIFY_COLUMNS", "CertifyRows", "FreeRuns"]

#: Result columns the certificate, its curve and the hazard table read.
CERTIFY_COLUMNS: tuple[str, ...] = ("fault", "manoeuvre", "status", "margin", "false_alarm",
                                    "detected", "dtp")


@dataclass(frozen=True)
class FreeRuns:
    """One detector's fault-free ``ok`` runs, in plan order: the margin, the manoeuvre
    (str) and the duration [s] (NaN for a run the plan does not hold) of each, and how many
    of them raised a false alarm (None for rows without ``false_alarm``)."""

    margin: np.ndarray
    manoeuvre: np.ndarray
    duration_s: np.ndarray
    false_alarms: int | None


class CertifyRows:
    """The part of a campaign's result rows that ``certify`` reads (module docstring), fed
    batch by batch with :meth:`add`; *durations_s*: the plan's ``duration_s`` in plan order,
    indexed by the batches' ``plan_pos``."""

    def __init__(self, durations_s=None):
        self._durations = (None if durations_s is None
                           else np.append(np.asarray(durations_s, float), np.nan))
        self._manoeuvres: dict[str, int] = {}
        self._free: dict[str, list] = {}           # name → [margins, codes, durations, k]
        self._faulty: dict[str, dict] = {}         # name → fault → [n, missed, late]

    @classmethod
    def of_table(cls, results: pd.DataFrame, plan: pd.DataFrame | None = None) -> CertifyRows:
        """The rows of a whole result table at once (its runs' durations from *plan*,
        ``run_id`` → ``duration_s``)."""
        rows = cls()
        if results.empty:
            return rows
        batch = results
        if plan is not None:
            duration = plan.set_index("run_id")["duration_s"]
            batch = results.assign(_duration_s=duration.reindex(results["run_id"]).to_numpy())
        rows.add(batch)
        return rows

    @classmethod
    def of_campaign(cls, camp, batch_runs: int | None = None) -> CertifyRows:
        """The rows of campaign *camp* (:class:`campaign.result.Campaign`), a batch of runs
        at a time (*batch_runs*: its default when None)."""
        rows = cls(camp.plan_column("duration_s"))
        extra = {} if batch_runs is None else {"batch_runs": int(batch_runs)}
        for batch in camp.result_batches(columns=list(CERTIFY_COLUMNS), positions=True,
                                         **extra):
            rows.add(batch)
        return rows

    def add(self, batch: pd.DataFrame) -> None:
        """Take in one batch of result rows (whole runs, in plan order)."""
        ok = batch[batch["status"].astype(str) == "ok"]
        if ok.empty:
            return
        faults = ok["fault"].astype(str)
        free = ok[(faults == FAULT_FREE).to_numpy()]
        if len(free):
            self._add_free(free)
        faulty = ok[(faults != FAULT_FREE).to_numpy()]
        for name in ok["detector"].drop_duplicates():
            self._faulty.setdefault(name, {})
        if len(faulty):
            detected = faulty["detected"].astype(bool)
            counts = pd.DataFrame({
                "detector": faulty["detector"], "fault": faulty["fault"].astype(str),
                "missed": ~detected, "late": detected & (faulty["dtp"] > 1.0)})
            for (name, fault), c in counts.groupby(["detector", "fault"], sort=False):
                acc = self._faulty[name].setdefault(fault, [0, 0, 0])
                missed = int(c["missed"].sum())
                acc[0] += len(c)
                acc[1] += missed
                acc[2] += missed + int(c["late"].sum())

    def _add_free(self, free: pd.DataFrame) -> None:
        if "_duration_s" in free:
            duration = free["_duration_s"].to_numpy(float)
        elif self._durations is not None and "plan_pos" in free:
            duration = self._durations[free["plan_pos"].to_numpy()]
        else:
            duration = np.full(len(free), np.nan)
        # a table of margins alone (a brute-force check of the curve) has one class and
        # no alarm count; one of alarms alone (the hazard's) no margin
        man = (free["manoeuvre"].astype(str).to_numpy() if "manoeuvre" in free
               else np.full(len(free), "", dtype=object))
        local, values = pd.factorize(man)
        codes = np.array([self._manoeuvres.setdefault(m, len(self._manoeuvres))
                          for m in values], dtype=np.int64)[local]
        margin = (free["margin"].to_numpy(float) if "margin" in free   # the hazard's rows
                  else np.full(len(free), np.nan))                      # need no margin
        alarm = (free["false_alarm"].astype(bool).to_numpy() if "false_alarm" in free
                 else None)
        names = free["detector"].to_numpy()
        for name in pd.unique(names):
            sel = names == name
            acc = self._free.setdefault(name, [[], [], [], 0])
            acc[0].append(margin[sel])
            acc[1].append(codes[sel].astype(np.int16))
            acc[2].append(duration[sel])
            acc[3] = None if alarm is None or acc[3] is None else acc[3] + int(alarm[sel].sum())

    def free_names(self) -> list[str]:
        """Detectors with fault-free ``ok`` runs, in the one order of every output
        (:func:`reports.scoring.summary.detector_order`)."""
        return detector_order(self._free)

    def ok_names(self) -> list[str]:
        """Detectors with ``ok`` runs, in the one order of every output
        (:func:`reports.scoring.summary.detector_order`)."""
        return detector_order(self._faulty)

    def free(self, name: str) -> FreeRuns:
        """Detector *name*'s fault-free runs (:class:`FreeRuns`)."""
        acc = self._free[name]
        for i in range(3):      # the batches' parts joined once (certify reads them thrice)
            if len(acc[i]) != 1:
                acc[i] = [np.concatenate(acc[i])]
        (margin,), (codes,), (durations,), k = acc
        labels = np.asarray(list(self._manoeuvres), dtype=object)
        return FreeRuns(margin=margin, manoeuvre=labels[codes.astype(np.int64)],
                        duration_s=durations, false_alarms=k)

    def faulty(self, name: str) -> dict[str, tuple[int, int, int]]:
        """Detector *name*'s faulty ``ok`` runs: fault type → (runs, missed, missed or late),
        fault types sorted."""
        return {f: tuple(c) for f, c in sorted(self._faulty.get(name, {}).items())}
