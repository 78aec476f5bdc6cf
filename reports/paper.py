"""Published evaluation tables to print beside a campaign's own: [CHEN] Tables 3–4.

[CHEN] (Chen, Patton, Goupil) evaluates its LPV fault estimator on three faults of the left
inboard aileron: Table 3 (parametric simulation) and Table 4 (Monte Carlo campaign) give
FA (%), MD (%) and min/mean/max DTP per fault; §6.2 gives the mean and variance of the
fault-estimation error f̂ − f of the two jams (Monte Carlo, from its normalised figures:
the normalisation is not stated; the jam sizes are stated as shares of the deflection
range, 1.3 % and 1.8 %, so the range is the reading used here, docs/chen-estimator.md §8).
Read each fault on the row of the estimator [CHEN] uses for it (:data:`CHEN_ESTIMATOR`).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["CHEN_ESTIMATOR", "PAPER_TABLES", "PaperRow", "PaperTable"]


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
    """A published table: its citation and one :class:`PaperRow` per fault type."""

    cite: str
    rows: dict


#: Fault → the detector variant whose row estimates it ([CHEN] §2.1: jams at the local
#: level, the disconnection at the global level).
CHEN_ESTIMATOR: dict[str, str] = {
    "liquid_jam": "chen-local[liquid]",
    "solid_jam": "chen-local[solid]",
    "disconnection": "chen-global",
}

_LIQ_DTP = (0.00116667, 0.00116667, 0.00116667)
_SOL_DTP = (0.001, 0.001, 0.001)

#: Reference tables by name (the ``reference`` key of a suite member, docs/suites.md).
PAPER_TABLES: dict[str, PaperTable] = {
    "chen-table-3": PaperTable(
        cite="[CHEN] Table 3 (parametric simulation)",
        rows={"liquid_jam": PaperRow(0.0, 0.0, _LIQ_DTP),
              "solid_jam": PaperRow(0.0, 0.0, _SOL_DTP),
              "disconnection": PaperRow(0.0, 0.0, (0.00758333, 0.0191682, 0.0584167))}),
    "chen-table-4": PaperTable(
        cite="[CHEN] Table 4 (Monte Carlo campaign); error mean/variance: [CHEN] §6.2",
        rows={"liquid_jam": PaperRow(0.0, 0.0, _LIQ_DTP, 0.0013, 3.039e-08),
              "solid_jam": PaperRow(0.0, 0.0, _SOL_DTP, 0.0014, 2.7972e-08),
              "disconnection": PaperRow(0.0, 0.0, (0.008, 0.0152707, 0.0376667))}),
}
