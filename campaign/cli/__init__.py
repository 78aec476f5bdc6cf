"""The ``fdd-campaign`` command line: parsing, the sub-commands' options, exit codes."""


def __getattr__(name):
    # the console script of an installation made before the commands moved to
    # campaign.cli.commands imports main from here
    if name == "main":
        from .commands import main

        return main
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
