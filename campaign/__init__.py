"""Campaign engine: configuration, designs, runner, storage and the command line.

``campaign.run(config, out, jobs=2)`` runs a campaign from Python (see
:func:`campaign.runner.run`); ``campaign.config.load_config`` reads a preset or a file.
"""


def run(config, out, **kwargs):
    """Run *config* into directory *out*; see :func:`campaign.runner.run`."""
    from .runner import run as _run

    return _run(config, out, **kwargs)
