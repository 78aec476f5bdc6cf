"""Campaign engine: configuration, designs, runner, storage and the command line.

``campaign.run(config, out, jobs=2)`` runs a campaign from Python and returns its
:class:`Campaign`; ``campaign.load(DIR)`` reads a campaign directory back as the same object
(:mod:`campaign.result`); ``campaign.config.load_config`` reads a preset or a file.
"""

from __future__ import annotations

__all__ = ["Campaign", "Certificate", "load", "run"]


def run(config, out, *, jobs: int = 2, chunk_size: int | None = None, seed: int | None = None,
        progress: bool = True, backend: str | None = None, scheduler: str | None = None,
        tls=None, engine: str | None = None, fitted_from=None, log=None):
    """Run *config* (a :class:`campaign.config.CampaignConfig`) into directory *out*,
    resuming what it already holds; returns its :class:`Campaign`.

    Parameters
    ----------
    jobs : local workers (1 runs in-process)
    chunk_size : runs per chunk (default: the campaign file's ``[runner] chunk_size``;
        results do not depend on it)
    seed : the campaign seed (default: the campaign file's ``[campaign] seed``)
    progress : print a progress line with rate and ETA on stderr
    backend : ``"threading"`` or ``"loky"`` local workers (default: threading, or loky for
        ``[runner] run_timeout_s`` or an FMU plant)
    scheduler : ``tcp://HOST:PORT`` or ``tls://HOST:PORT`` of a dask.distributed
        scheduler to run the chunks on (*jobs* and *backend* are then not used)
    tls : :class:`campaign.execute.TlsFiles` for a ``tls://`` scheduler
    engine : ``"compiled"`` or ``"numpy"`` kernels (default: ``[runner] engine``)
    fitted_from : a campaign directory whose fitted detectors are used instead of learning
        them again (docs/thresholds.md)
    log : where notes go, one line each (default: stderr)

    Every option in full: :func:`campaign.runner.run`.
    """
    from .runner import run as _run

    return _run(config, out, jobs=jobs, chunk_size=chunk_size, seed=seed, progress=progress,
                backend=backend, scheduler=scheduler, tls=tls, engine=engine,
                fitted_from=fitted_from, log=log)


def load(directory):
    """The :class:`Campaign` of a campaign directory (``fdd-campaign run --out``), after
    checking its files against its manifest; see :func:`campaign.result.load`."""
    from .result import load as _load

    return _load(directory)


def __getattr__(name: str):
    """``campaign.Campaign`` and ``campaign.Certificate`` (imported on first use: importing
    ``campaign`` stays light)."""
    if name in ("Campaign", "Certificate"):
        from . import result

        return getattr(result, name)
    raise AttributeError(f"module 'campaign' has no attribute {name!r}")
