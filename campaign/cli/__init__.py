"""The ``fdd-campaign`` command line: parsing, the sub-commands' options, exit codes.

The executable is :func:`console_main` (``python -m campaign.cli`` too); importing this
package loads nothing else, so that it starts before NumPy.
"""


def console_main() -> None:
    """The ``fdd-campaign`` executable. Before NumPy loads: one BLAS thread exported to the
    process (:func:`campaign.startup.export_one_blas_thread`) and the garbage collector off
    until ``run`` has loaded its libraries and kernels (:func:`campaign.startup.defer_collection`);
    then the command (:func:`campaign.cli.commands.main`) and an exit without the
    interpreter's teardown when nothing else is running (:func:`campaign.cli.commands.leave`)."""
    from ..startup import defer_collection, export_one_blas_thread

    export_one_blas_thread()
    defer_collection()
    from .commands import leave, main

    leave(main())


def __getattr__(name):
    # the console script of an installation made before the commands moved to
    # campaign.cli.commands imports main from here
    if name == "main":
        from .commands import main

        return main
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
