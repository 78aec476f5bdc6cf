"""Fitted detectors across two campaigns (docs/thresholds.md): identified by the SHA-256 of
their files (:meth:`campaign.store.directory.CampaignDir.fitted_sha256`, recorded in the summary's
metadata), ``compare`` says whether two campaigns share them or which thresholds were
re-learned. Taking the detectors of another campaign (``run --fitted-from DIR``) is
:func:`campaign.runner.adopt_fitted`."""

from __future__ import annotations

from reports.scoring.compare import threshold_changes, threshold_text

from .directory import CampaignDir

__all__ = ["compare_fitted", "fitted_digest"]


def fitted_digest(camp) -> str | None:
    """:meth:`CampaignDir.fitted_sha256` of the fitted detectors of a loaded campaign
    (:class:`campaign.result.Campaign`): from its summary's metadata, or computed from its
    files for a directory written before the digest was recorded there."""
    digest = camp.provenance.fitted_sha256
    if digest:
        return digest
    return CampaignDir(camp.root).fitted_sha256([d.label for d in camp.config.detectors])


def compare_fitted(a, b, log) -> dict[str, str]:
    """Say (on *log*) whether the loaded campaigns A and B evaluated the same fitted detectors (same
    :func:`fitted_digest`), and when not, which learned thresholds differ, both values;
    returns detector label → that text for the detectors whose thresholds were re-learned
    (printed beside each of their flagged cells)."""
    da, db = fitted_digest(a), fitted_digest(b)
    if da is not None and da == db:
        log(f"fitted detectors: shared (SHA-256 {da[:12]}…): A and B evaluated the same "
            "thresholds")
        for label, det in a.fitted.items():
            same = {k: v for k, v in det.fitted_state().items() if "threshold" in k}
            log(f"  {label}: " + "; ".join(f"{k} = {threshold_text(v)}"
                                           for k, v in same.items()))
        return {}
    log(f"fitted detectors: not shared (SHA-256 {(da or '-')[:12]}… vs {(db or '-')[:12]}…): "
        "the thresholds were re-learned")
    fitted_a, fitted_b = a.fitted, b.fitted
    notes = {}
    for label in list(dict.fromkeys([*fitted_a, *fitted_b])):
        if label not in fitted_a or label not in fitted_b:
            log(f"  {label}: only in {'A' if label in fitted_a else 'B'}")
            continue
        changes = threshold_changes(fitted_a[label].fitted_state(),
                                    fitted_b[label].fitted_state())
        if changes:
            log(f"  {label}: thresholds re-learned: " + "; ".join(changes))
            notes[label] = "thresholds re-learned: " + "; ".join(changes)
        else:
            same = {k: v for k, v in fitted_a[label].fitted_state().items() if "threshold" in k}
            log(f"  {label}: other learned values differ; thresholds the same "
                + "; ".join(f"{k} = {threshold_text(v)}" for k, v in same.items()))
    return notes
