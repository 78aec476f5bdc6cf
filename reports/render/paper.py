"""Published evaluation tables to print beside a campaign's own: [CHEN] Tables 3–4.

[CHEN] (Chen, Patton, Goupil) evaluates its LPV fault estimator on three faults of the left
inboard aileron: Table 3 (parametric simulation) and Table 4 (Monte Carlo campaign) give
FA (%), MD (%) and min/mean/max DTP per fault; §6.2 gives the mean and variance of the
fault-estimation error f̂ − f of the two jams (Monte Carlo, from its normalised figures:
the normalisation is not stated; the jam sizes are stated as shares of the deflection
range, 1.3 % and 1.8 %, so the range is the reading used here, docs/chen-estimator.md §8).
Read each fault on the row of the estimator [CHEN] uses for it (:data:`CHEN_ESTIMATOR`).

**[CHEN]'s delays in seconds (inferred).** [CHEN] prints DTP = delay / required time and
not the required times, but every DTP extreme it prints is a whole multiple of 1/12000
(to its six printed digits): Table 3 0.00758333 = 91/12000, 0.0584167 = 701/12000;
Table 4 0.008 = 96/12000, 0.0376667 = 452/12000; the jams 0.00116667 = 14/12000 and
0.001 = 12/12000 (and no coarser grain fits: 0.00758333 × 6000 = 45.5). The means fit the
same grain over the runs: 0.0191682 × 12000 × 158 = 36342.9 and 0.0152707 × 12000 × 334 =
61203.6, whole within the rounding of the printed digits (± 0.09 and ± 0.2). ADDSAFE's
detectors run at the FCC's 10 ms step ([COMB]'s T = 10 ms; [VANEK] §5: "0.01 sec fixed
step size"), so a delay is a whole number of 10 ms steps and the denominator is 12000
steps = 120 s (:data:`CHEN_DTP_DENOMINATOR_S`): liquid jam 14 steps = 0.14 s, solid jam
12 steps = 0.12 s, disconnection 91–701 steps = 0.91–7.01 s (Table 3) and 96–452 steps =
0.96–4.52 s (Table 4). This is an inference from the printed numbers, not a value [CHEN]
states; :meth:`PaperTable.delays_s` applies it.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["ADDSAFE_STEP_S", "CHEN_DTP_DENOMINATOR_S", "CHEN_ESTIMATOR", "PAPER_TABLES",
           "PaperRow", "PaperTable"]

#: The step at which ADDSAFE's detectors decide [s] (the FCC period: [COMB]'s T = 10 ms,
#: [VANEK] §5's 0.01 s fixed step size).
ADDSAFE_STEP_S = 0.01

#: The denominator of [CHEN]'s DTP [s], inferred (module docstring): 12000 steps of
#: :data:`ADDSAFE_STEP_S`.
CHEN_DTP_DENOMINATOR_S = 12000 * ADDSAFE_STEP_S


@dataclass(frozen=True)
class PaperRow:
    """One fault of a published table: rates [%], DTP min/mean/max [-] and, where the paper
    gives them, the mean and variance of the normalised estimation error (None: not
    given)."""

    fa_pct: float
    md_pct: float
    dtp: tuple[float, float, float]
    err_mean: float | None = None
    err_var: float | None = None


@dataclass(frozen=True)
class PaperTable:
    """A published table: its citation, one :class:`PaperRow` per fault type and the DTP
    denominator [s] that turns its DTP into delays (None: not known), with how it was
    obtained."""

    cite: str
    rows: dict
    dtp_denominator_s: float | None = None
    denominator_note: str = ""

    def delays_s(self, fault: str) -> tuple[float, float, float] | None:
        """The paper's min/mean/max detection delay of *fault* [s]: its DTP × the
        denominator, each rounded to the ADDSAFE step it is a multiple of (the mean to
        1 ms); None without a denominator."""
        if self.dtp_denominator_s is None:
            return None
        lo, mean, hi = (v * self.dtp_denominator_s for v in self.rows[fault].dtp)
        return (round(lo, 2), round(mean, 3), round(hi, 2))


#: Fault → the detector variant whose row estimates it ([CHEN] §2.1: jams at the local
#: level, the disconnection at the global level).
CHEN_ESTIMATOR: dict[str, str] = {
    "liquid_jam": "chen-local[liquid]",
    "solid_jam": "chen-local[solid]",
    "disconnection": "chen-global",
}

_LIQ_DTP = (0.00116667, 0.00116667, 0.00116667)
_SOL_DTP = (0.001, 0.001, 0.001)

_CHEN_NOTE = ("[CHEN]'s delays are inferred, not printed: every DTP extreme of Tables 3–4 "
              "is a whole multiple of 1/12000 (0.00116667 = 14/12000, 0.001 = 12/12000, "
              "0.00758333 = 91/12000, 0.0584167 = 701/12000, 0.008 = 96/12000, 0.0376667 = "
              "452/12000) and ADDSAFE decides at the 10 ms FCC step, so its DTP denominator "
              "is 12000 steps = 120 s and delay = DTP × 120 s (e.g. 0.00116667 × 120 s = "
              "0.14 s)")

#: Reference tables by name (the ``reference`` key of a suite member, docs/suites.md).
PAPER_TABLES: dict[str, PaperTable] = {
    "chen-table-3": PaperTable(
        cite="[CHEN] Table 3 (parametric simulation)",
        rows={"liquid_jam": PaperRow(0.0, 0.0, _LIQ_DTP),
              "solid_jam": PaperRow(0.0, 0.0, _SOL_DTP),
              "disconnection": PaperRow(0.0, 0.0, (0.00758333, 0.0191682, 0.0584167))},
        dtp_denominator_s=CHEN_DTP_DENOMINATOR_S, denominator_note=_CHEN_NOTE),
    "chen-table-4": PaperTable(
        cite="[CHEN] Table 4 (Monte Carlo campaign); error mean/variance: [CHEN] §6.2",
        rows={"liquid_jam": PaperRow(0.0, 0.0, _LIQ_DTP, 0.0013, 3.039e-08),
              "solid_jam": PaperRow(0.0, 0.0, _SOL_DTP, 0.0014, 2.7972e-08),
              "disconnection": PaperRow(0.0, 0.0, (0.008, 0.0152707, 0.0376667))},
        dtp_denominator_s=CHEN_DTP_DENOMINATOR_S, denominator_note=_CHEN_NOTE),
}
