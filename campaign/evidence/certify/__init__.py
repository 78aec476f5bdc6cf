"""``fdd-campaign certify``: the per-run false-alarm probability of each detector beyond
counting (docs/evidence.md; docs/design.md §8). The certificate, its sampling and the command's
entry :func:`certify` (:mod:`.estimate`), the exceedance curve at several margin levels
(:mod:`.levels`), what certify reads of the result rows (:mod:`.rows`) and the curve checked by
brute force (:mod:`.validate`)."""

from .estimate import (
    CERTIFICATE_COLUMNS,
    SAMPLING_DIR,
    SAMPLING_STREAM_BASE,
    CertifyError,
    CertifyOptionError,
    certificate,
    certify,
    evt_estimate,
    run_variables,
    sample_fa_probability,
)

__all__ = ["CERTIFICATE_COLUMNS", "CertifyError", "CertifyOptionError", "SAMPLING_DIR",
           "SAMPLING_STREAM_BASE", "certificate", "certify", "evt_estimate", "run_variables",
           "sample_fa_probability"]
