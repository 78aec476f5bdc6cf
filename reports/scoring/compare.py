"""What changed between two campaigns: rates with a significance test, DTP shifts, per cell.

A cell is one detector × fault × manoeuvre (plus the fault's ``manoeuvre = "all"``
aggregate when either campaign ran the fault in several manoeuvres). For each cell, from the scored
(``status == "ok"``) result rows of campaign A and campaign B:

* FA and MD rates of both, and a two-sided test of "is the rate of B different from the
  rate of A?";
* the DTP distributions of the detected runs, a two-sided test of a shift, and the shift of
  the median;

The tests depend on whether the two cells hold the same runs (the same ``run_id`` set: the
same plan, e.g. a detector change rerun on one campaign file):

* **paired** (same runs): exact McNemar test on the discordant runs (alarm in one campaign
  only; ``scipy.stats.binomtest`` of the B-only count among them at ½) for FA and MD, and the
  Wilcoxon signed-rank test (``scipy.stats.wilcoxon``) on the DTP of the runs detected in
  both. Runs that agree carry no evidence of a change, so a few changed outcomes among
  hundreds of shared runs are not drowned in the cell's sampling spread;
* **independent** (other runs): Fisher exact test of the 2 × 2 table
  (``scipy.stats.fisher_exact``) for FA and MD, Mann–Whitney U (``scipy.stats.mannwhitneyu``)
  for DTP.

Then a flag: ``worse`` when some test has p < α and B is the worse side (more false alarms,
more misses, larger DTP), else ``better`` when some test has p < α the other way, else
``unchanged``; ``only in A`` / ``only in B`` for cells one campaign lacks. The column
``test`` says which tests a cell got.

A cell with too few runs for its test to reach α is flagged ``too few runs``, not
``unchanged``: an exact test on n runs has a smallest p-value it can give, reached when the
outcomes differ as much as they can (every run of the cell changed its outcome, paired:
2·2⁻ⁿ; all of A's runs one way and all of B's the other, Fisher: 1/C(n_a + n_b, n_a) for
each extreme); when that floor is ≥ α no outcome is ever flagged, so the test has no power
at any size of change and "unchanged" would claim what it cannot tell (:func:`p_floor`).

Each test is read on its own at level α (no correction for the number of cells: the flag
is a pointer to look at, the table prints every p-value).
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pandas as pd
from scipy import stats

from .metrics import FAULT_FREE
from .summary import ALL_MANOEUVRES, natural_key
from .text import number_text

__all__ = ["COMPARE_COLUMNS", "TOO_FEW", "ScoredRows", "compare_results", "compare_scored",
           "differing_keys", "format_compare", "p_floor", "runs_needed", "threshold_changes",
           "threshold_text", "too_few_summary"]

#: Default significance level of the flags.
ALPHA = 0.01

COMPARE_COLUMNS: tuple[str, ...] = (
    "detector", "fault", "manoeuvre", "n_a", "n_b",
    "fa_a", "fa_b", "fa_rate_a", "fa_rate_b", "fa_p",
    "md_a", "md_b", "md_rate_a", "md_rate_b", "md_p",
    "dtp_median_a", "dtp_median_b", "dtp_shift", "dtp_p",
    "test", "flag", "reasons",
)

_KEYS = ["detector", "fault", "manoeuvre"]

#: The flag of a cell whose test cannot reach α (:func:`p_floor`).
TOO_FEW = "too few runs"


def _scored(results: pd.DataFrame) -> pd.DataFrame:
    need = ["run_id", "detector", "fault", "manoeuvre", "status", "false_alarm", "detected",
            "dtp"]
    missing = [c for c in need if c not in results.columns]
    if missing:
        raise ValueError(f"results lack column(s) {', '.join(missing)}; pass the result rows "
                         "of a campaign (reports.scoring.metrics.RESULT_COLUMNS)")
    ok = results[results["status"].astype(str) == "ok"]
    return pd.DataFrame({
        "run_id": ok["run_id"].astype(str), "detector": ok["detector"].astype(str),
        "fault": ok["fault"].astype(str), "manoeuvre": ok["manoeuvre"].astype(str),
        "fa": ok["false_alarm"].astype("boolean").fillna(False).astype(bool),
        "det": ok["detected"].astype("boolean").fillna(False).astype(bool),
        "dtp": pd.to_numeric(ok["dtp"], errors="coerce"),
    })


class ScoredRows:
    """The scored rows :func:`compare_scored` reads of one campaign, gathered a batch of
    result rows at a time (:meth:`add`) in a compact form: the run as an integer key given
    by the caller (the same run the same key in both campaigns), the detector, fault and
    manoeuvre as categories, the outcomes as booleans and the DTP: 8 + 3 + 2 + 8 = 21 bytes
    per scored run × detector, where the result rows take about 1 KB. The paired tests need
    one outcome per run (which runs changed), so this is what compare keeps of every run."""

    def __init__(self):
        self._labels = {k: {} for k in _KEYS}
        self._parts: list[pd.DataFrame] = []

    def add(self, results: pd.DataFrame, run_keys) -> None:
        """Take in result rows *results* whose runs have the integer keys *run_keys* (one
        per row)."""
        rows = _scored(results)
        keys = np.asarray(run_keys, dtype=np.int64)[
            (results["status"].astype(str) == "ok").to_numpy()]
        part = {"run_id": keys}
        for k in _KEYS:
            codes, values = pd.factorize(rows[k])
            labels = self._labels[k]
            known = np.array([labels.setdefault(v, len(labels)) for v in values], np.int16)
            part[k] = known[codes]
        part.update(fa=rows["fa"].to_numpy(bool), det=rows["det"].to_numpy(bool),
                    dtp=rows["dtp"].to_numpy(float))
        self._parts.append(pd.DataFrame(part))

    def table(self) -> pd.DataFrame:
        """The rows taken in, in order, as :func:`compare_scored` reads them."""
        cols = ["run_id", *_KEYS, "fa", "det", "dtp"]
        if not self._parts:
            return pd.DataFrame({c: [] for c in cols})
        out = pd.concat(self._parts, ignore_index=True)
        self._parts = [out]
        for k in _KEYS:
            out[k] = pd.Categorical.from_codes(out[k], categories=list(self._labels[k]))
        return out


def _several(rows: pd.DataFrame) -> set:
    """(detector, fault) pairs run in more than one manoeuvre."""
    n = rows.groupby(["detector", "fault"], observed=True)["manoeuvre"].nunique()
    return set(n[n > 1].index)


class _Cells:
    """The cells of one campaign's scored rows: (detector, fault, manoeuvre), plus the
    aggregate over manoeuvres (``manoeuvre = "all"``) of the (detector, fault) pairs in
    *aggregate*. A cell's rows are copied out when asked for (:meth:`get`), in their order,
    from the positions of its (detector, fault) pair: 8 bytes a row are held, not a copy of
    every cell."""

    def __init__(self, rows: pd.DataFrame, aggregate: set):
        self.rows, self.aggregate = rows, aggregate
        self.pairs = rows.groupby(["detector", "fault"], sort=True, observed=True).indices
        self.keys = set()
        for (detector, fault), at in self.pairs.items():
            self.keys |= {(detector, fault, m) for m in pd.unique(rows["manoeuvre"].iloc[at])}
            if (detector, fault) in aggregate:
                self.keys.add((detector, fault, ALL_MANOEUVRES))

    def get(self, key) -> pd.DataFrame | None:
        """The rows of cell *key*; None when the campaign has none."""
        if key not in self.keys:
            return None
        detector, fault, manoeuvre = key
        at = self.pairs[(detector, fault)]
        if not (manoeuvre == ALL_MANOEUVRES and (detector, fault) in self.aggregate):
            at = at[(self.rows["manoeuvre"].iloc[at] == manoeuvre).to_numpy()]
        return self.rows.iloc[at]


def _fisher(k_a: int, n_a: int, k_b: int, n_b: int) -> float:
    if n_a == 0 or n_b == 0:
        return math.nan
    return float(stats.fisher_exact([[k_a, n_a - k_a], [k_b, n_b - k_b]])[1])


def _mcnemar(only_a: int, only_b: int) -> float:
    """Exact McNemar p-value (two-sided) from the discordant counts."""
    n = only_a + only_b
    if n == 0:
        return 1.0            # every run agrees: no evidence of a change
    return float(stats.binomtest(only_b, n, 0.5).pvalue)


def _wilcoxon(a: np.ndarray, b: np.ndarray) -> float:
    """Two-sided Wilcoxon signed-rank p-value of the paired differences b − a."""
    if len(a) == 0:
        return math.nan
    if np.all(a == b):
        return 1.0            # no run changed its DTP
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", (RuntimeWarning, UserWarning))
        return float(stats.wilcoxon(b, a, alternative="two-sided").pvalue)


def _paired_order(ga: pd.DataFrame, gb: pd.DataFrame) -> np.ndarray | None:
    """When two cells hold the same runs, each once: the positions in *gb* of the runs of
    *ga*, in the order of *ga*; None otherwise (sorted run ids compared, no set of them)."""
    a, b = ga["run_id"].to_numpy(), gb["run_id"].to_numpy()
    if len(a) != len(b):
        return None
    sa, sb = np.argsort(a, kind="stable"), np.argsort(b, kind="stable")
    a_sorted = a[sa]
    if not np.array_equal(a_sorted, b[sb]) or (a_sorted[1:] == a_sorted[:-1]).any():
        return None
    at = np.empty(len(a), dtype=np.int64)
    at[sa] = sb
    return at


def _mannwhitney(a: np.ndarray, b: np.ndarray) -> float:
    if len(a) == 0 or len(b) == 0:
        return math.nan
    if np.all(a == a[0]) and np.all(b == a[0]):
        return 1.0  # identical constant samples: no shift at all
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return float(stats.mannwhitneyu(a, b, alternative="two-sided").pvalue)


def p_floor(paired: bool, n_a: int, n_b: int) -> float:
    """The smallest two-sided p-value the cell's rate test can give with *n_a* and *n_b*
    runs, whatever the outcomes: paired (n_a = n_b = n runs), the exact McNemar test with
    every run discordant and all one way, ``binomtest(n, n, ½)`` = 2·2⁻ⁿ; independent, the
    Fisher exact test of the table [[n_a, 0], [0, n_b]] (every run of A one way, every run
    of B the other: 1/C(n_a + n_b, n_a) when n_a ≠ n_b, twice that when equal). The DTP
    tests of the cell run on at most as many runs and have floors no lower (Wilcoxon
    signed-rank 2·2⁻ᵐ on m pairs, Mann–Whitney U 2/C(n_a + n_b, n_a) on untied samples), so
    a cell whose floor is ≥ α can be flagged by none of its tests."""
    if n_a == 0 or n_b == 0:
        return 1.0
    if paired:
        return float(stats.binomtest(n_a, n_a, 0.5).pvalue)
    return float(stats.fisher_exact([[n_a, 0], [0, n_b]])[1])


def runs_needed(alpha: float) -> int:
    """The fewest runs a paired cell needs for its exact test to reach p < *alpha*
    (2·2⁻ⁿ < α)."""
    n = 1
    while 2.0 * 0.5 ** n >= alpha:
        n += 1
    return n


def _too_few_text(paired: bool, n_a: int, n_b: int, floor: float, alpha: float) -> str:
    """Why a cell is ``too few runs``: the exact test, its floor and its power."""
    if paired:
        test = (f"the exact McNemar test on its {n_a} shared run{'s' * (n_a != 1)} gives "
                f"p ≥ {floor:.2g} even when every run changes its outcome the same way")
        need = f"; a paired cell needs ≥ {runs_needed(alpha)} runs"
    else:
        test = (f"Fisher's exact test on {n_a} and {n_b} runs gives p ≥ {floor:.2g} even when "
                "every run of A has one outcome and every run of B the other")
        need = ""
    return (f"too few runs to compare: {test}, not below α = {alpha:g}: no change can be "
            f"detected here (power 0 at any size of change){need}")


def _rate(k: int, n: int) -> float:
    return k / n if n else math.nan


def compare_results(results_a: pd.DataFrame, results_b: pd.DataFrame, *,
                    alpha: float = ALPHA) -> pd.DataFrame:
    """Compare the result rows of two campaigns cell by cell (see the module docstring).

    Parameters
    ----------
    results_a, results_b : result rows (:data:`reports.scoring.metrics.RESULT_COLUMNS`)
    alpha : significance level of the flags, in (0, 1)

    Returns
    -------
    DataFrame with :data:`COMPARE_COLUMNS`, one row per cell, sorted by detector, fault,
    manoeuvre. Rates are fractions; ``dtp_shift`` is median(B) − median(A) over detected
    runs; p-values are NaN where a test has no data.
    """
    return compare_scored(_scored(results_a), _scored(results_b), alpha=alpha)


def compare_scored(rows_a: pd.DataFrame, rows_b: pd.DataFrame, *,
                   alpha: float = ALPHA) -> pd.DataFrame:
    """:func:`compare_results` of the scored rows of two campaigns (``run_id``, ``detector``,
    ``fault``, ``manoeuvre``, ``fa``, ``det``, ``dtp``; the run ids of any type that names
    one run the same in both, the names str or categories): :meth:`ScoredRows.table`."""
    if not 0.0 < float(alpha) < 1.0:
        raise ValueError(f"alpha must be a significance level in (0, 1), got {alpha}")
    aggregate = _several(rows_a) | _several(rows_b)
    cells_a, cells_b = _Cells(rows_a, aggregate), _Cells(rows_b, aggregate)
    rows = []
    # detectors in the one order of every output (reports.scoring.summary.detector_order)
    for key in sorted(cells_a.keys | cells_b.keys,
                      key=lambda k: (natural_key(str(k[0])), *map(str, k[1:]))):
        ga, gb = cells_a.get(key), cells_b.get(key)
        row = dict(zip(_KEYS, key))
        if ga is None or gb is None:
            only = "only in B" if ga is None else "only in A"
            g = gb if ga is None else ga
            side = "b" if ga is None else "a"
            row.update({f"n_{side}": len(g), "flag": only,
                        "reasons": f"cell {only}: the other campaign has no scored run here"})
            rows.append(row)
            continue
        faulty = key[1] != FAULT_FREE
        n_a, n_b = len(ga), len(gb)
        order = _paired_order(ga, gb)
        paired = order is not None
        if paired:
            gb = gb.iloc[order]                                           # A's run order
        fa_a, fa_b = int(ga["fa"].sum()), int(gb["fa"].sum())

        def rate_p(x_a, x_b):
            """p-value of a change of a per-run outcome (bool arrays, A and B)."""
            if paired:
                return _mcnemar(int((x_a & ~x_b).sum()), int((x_b & ~x_a).sum()))
            return _fisher(int(x_a.sum()), n_a, int(x_b.sum()), n_b)

        fa_x_a, fa_x_b = ga["fa"].to_numpy(bool), gb["fa"].to_numpy(bool)
        row.update(n_a=n_a, n_b=n_b, fa_a=fa_a, fa_b=fa_b, fa_rate_a=_rate(fa_a, n_a),
                   fa_rate_b=_rate(fa_b, n_b), fa_p=rate_p(fa_x_a, fa_x_b),
                   test="paired" if paired else "independent")
        worse, better = [], []

        def judge(name, p, a, b):
            if np.isfinite(p) and p < alpha and a != b:
                (worse if b > a else better).append(f"{name} {a:.4g} → {b:.4g} (p = {p:.2g})")

        judge("FA rate", row["fa_p"], row["fa_rate_a"], row["fa_rate_b"])
        if faulty:
            det_a, det_b = ga["det"].to_numpy(bool), gb["det"].to_numpy(bool)
            md_a, md_b = int((~det_a).sum()), int((~det_b).sum())
            da = ga.loc[ga["det"], "dtp"].dropna().to_numpy(float)
            db = gb.loc[gb["det"], "dtp"].dropna().to_numpy(float)
            med_a = float(np.median(da)) if len(da) else math.nan
            med_b = float(np.median(db)) if len(db) else math.nan
            if paired:
                both = det_a & det_b & ga["dtp"].notna().to_numpy() & gb["dtp"].notna().to_numpy()
                dtp_p = _wilcoxon(ga["dtp"].to_numpy(float)[both],
                                  gb["dtp"].to_numpy(float)[both])
            else:
                dtp_p = _mannwhitney(da, db)
            row.update(md_a=md_a, md_b=md_b, md_rate_a=_rate(md_a, n_a),
                       md_rate_b=_rate(md_b, n_b), md_p=rate_p(~det_a, ~det_b),
                       dtp_median_a=med_a, dtp_median_b=med_b, dtp_shift=med_b - med_a,
                       dtp_p=dtp_p)
            judge("MD rate", row["md_p"], row["md_rate_a"], row["md_rate_b"])
            judge("median DTP", row["dtp_p"], med_a, med_b)
        row["flag"] = "worse" if worse else ("better" if better else "unchanged")
        row["reasons"] = "; ".join(
            ([f"worse: {', '.join(worse)}"] if worse else [])
            + ([f"better: {', '.join(better)}"] if better else []))
        floor = p_floor(paired, n_a, n_b)
        if floor >= alpha:                  # no outcome could have been flagged
            row["flag"] = TOO_FEW
            row["reasons"] = _too_few_text(paired, n_a, n_b, floor, alpha)
        rows.append(row)
    out = pd.DataFrame(rows, columns=list(COMPARE_COLUMNS))
    for c in ("n_a", "n_b", "fa_a", "fa_b", "md_a", "md_b"):
        out[c] = out[c].astype("Int64")
    return out


def format_compare(table: pd.DataFrame, *, alpha: float = ALPHA,
                   notes: dict[str, str] | None = None) -> str:
    """Fixed-width text of :func:`compare_results` output, with a count of flags.

    *notes*: detector label → a text printed beside every flagged cell of that detector
    (its variants ``label[…]`` included), e.g. that its thresholds were re-learned."""
    notes = notes or {}
    if table.empty:
        return "no cell to compare"
    header = ["detector", "fault", "manoeuvre", "n A/B", "FA % A→B", "p(FA)", "MD % A→B",
              "p(MD)", "med DTP A→B", "p(DTP)", "flag"]
    body = []
    for r in table.itertuples(index=False):
        n = f"{'-' if pd.isna(r.n_a) else r.n_a}/{'-' if pd.isna(r.n_b) else r.n_b}"
        body.append([r.detector, r.fault, r.manoeuvre, n,
                     f"{number_text(100 * r.fa_rate_a, '.2f')}→"
                     f"{number_text(100 * r.fa_rate_b, '.2f')}",
                     number_text(r.fa_p, '.2g'),
                     f"{number_text(100 * r.md_rate_a, '.2f')}→"
                     f"{number_text(100 * r.md_rate_b, '.2f')}"
                     if r.fault != FAULT_FREE else "",
                     number_text(r.md_p, '.2g'),
                     f"{number_text(r.dtp_median_a, '.4g')}→{number_text(r.dtp_median_b, '.4g')}"
                     if r.fault != FAULT_FREE else "",
                     number_text(r.dtp_p, '.2g'), r.flag])
    widths = [max(len(str(c)) for c in col) for col in zip(header, *body)]
    lines = ["  ".join(str(c).ljust(w) for c, w in zip(line, widths)).rstrip()
             for line in [header, ["-" * w for w in widths], *body]]
    counts = table["flag"].value_counts()
    lines.append("")
    lines.append(f"{len(table)} cells: " + ", ".join(f"{int(counts.get(k, 0))} {k}" for k in
                 ("worse", "better", "unchanged", TOO_FEW, "only in A", "only in B")
                 if counts.get(k, 0)) + f" (two-sided tests at p < {alpha:g}; same runs: "
                 "exact McNemar for FA/MD, Wilcoxon signed-rank for DTP; other runs: Fisher "
                 "exact, Mann–Whitney U)")
    for r in table.itertuples(index=False):
        if r.flag in ("worse", "better") and r.reasons:
            note = notes.get(str(r.detector).split("[", 1)[0])
            lines.append(f"  {r.detector} / {r.fault} / {r.manoeuvre}: {r.reasons}"
                         + (f" [{note}]" if note else ""))
    few = table[table["flag"] == TOO_FEW]
    if len(few):
        lines.append(too_few_summary(few, alpha))
    return "\n".join(lines)


def too_few_summary(few: pd.DataFrame, alpha: float) -> str:
    """One line on the cells flagged ``too few runs`` (*few*: rows of the compare table):
    why none of them can be flagged, grouped by their test and run counts."""
    parts = []
    groups = few.groupby(["test", "n_a", "n_b"], sort=True, observed=True).size()
    for (test, n_a, n_b), count in groups.items():
        paired = test == "paired"
        floor = p_floor(paired, int(n_a), int(n_b))
        cells = f"{count} cell{'s' * (count != 1)}"
        parts.append(f"{cells} of {n_a} shared run{'s' * (n_a != 1)} (exact McNemar: "
                     f"p ≥ {floor:.2g})" if paired else
                     f"{cells} of {n_a} and {n_b} runs (Fisher exact: p ≥ {floor:.2g})")
    need = (f"; a paired cell needs ≥ {runs_needed(alpha)} runs"
            if (few["test"] == "paired").any() else "")
    return (f"too few runs to compare ({len(few)} cells): even the largest difference their "
            f"runs can show gives no p below α = {alpha:g}, so no change can be detected there "
            f"(power 0 at any size of change): {', '.join(parts)}{need}")


def threshold_text(value) -> str:
    """A learned threshold as text: numbers with 6 significant digits, a dict key by key, an
    array by its length, first and last values (a threshold schedule)."""
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k}: {threshold_text(v)}" for k, v in value.items()) + "}"
    arr = np.asarray(value) if not isinstance(value, str) else None
    if arr is not None and arr.dtype.kind in "biuf":
        if arr.ndim == 0:
            return f"{float(arr):.6g}"
        flat = arr.ravel()
        if flat.size == 0:
            return "[]"
        return (f"[{float(flat[0]):.6g} … {float(flat[-1]):.6g}] ({flat.size} values)"
                if flat.size > 3 else "[" + ", ".join(f"{float(v):.6g}" for v in flat) + "]")
    return repr(value)


def threshold_changes(learned_a: dict, learned_b: dict) -> list[str]:
    """The learned thresholds of one detector that differ between two fittings: for every
    learned attribute whose name contains ``threshold`` (``thresholds_mm_``, ``threshold_``,
    …), ``name: A → B`` (:func:`threshold_text`), key by key for a dict."""
    out = []
    for name in sorted(set(learned_a) | set(learned_b)):
        if "threshold" not in name:
            continue
        a, b = learned_a.get(name), learned_b.get(name)
        if isinstance(a, dict) and isinstance(b, dict):
            for key in list(dict.fromkeys([*a, *b])):
                if not _same(a.get(key), b.get(key)):
                    out.append(f"{name}[{key!r}]: {threshold_text(a.get(key))} → "
                               f"{threshold_text(b.get(key))}")
        elif not _same(a, b):
            out.append(f"{name}: {threshold_text(a)} → {threshold_text(b)}")
    return out


def _same(a, b) -> bool:
    try:
        return bool(np.array_equal(np.asarray(a), np.asarray(b)))
    except (TypeError, ValueError):
        return a == b


def differing_keys(a, b, prefix: str = "") -> list[str]:
    """The dotted keys where two campaign-file dicts differ, each with both values
    (``campaign.seed: 0 → 1``, ``detector[1].params.kappa: … → …``, ``group[2]: only in
    B``); tables are compared key by key, arrays of tables element by element."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in list(dict.fromkeys([*a, *b])):
            path = f"{prefix}.{k}" if prefix else str(k)
            if k not in a or k not in b:
                out.append(f"{path}: only in {'B' if k not in a else 'A'}")
            else:
                out += differing_keys(a[k], b[k], path)
        return out
    if (isinstance(a, list) and isinstance(b, list) and a and b
            and all(isinstance(x, dict) for x in a + b)):
        out = []
        for i in range(max(len(a), len(b))):
            path = f"{prefix}[{i}]"
            if i >= len(a) or i >= len(b):
                out.append(f"{path}: only in {'B' if i >= len(a) else 'A'}")
            else:
                out += differing_keys(a[i], b[i], path)
        return out
    return [] if a == b else [f"{prefix}: {a!r} → {b!r}"]
