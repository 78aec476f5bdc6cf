"""The one-run table of ``fdd-campaign simulate --plant aircraft``."""

from __future__ import annotations

import pandas as pd

from scenarios.aircraft.data import AIRCRAFT_SURFACES, DEFAULT_MONITORED, LAYOUT
from scenarios.simulate import single_run


def aircraft_single_run(args) -> pd.DataFrame:
    """One run row for the monitored aircraft surface named by ``args.surface``
    (``elevator``/``aileron`` stand for their left surface), with the default fault
    magnitude of that surface's actuator type."""
    surface = DEFAULT_MONITORED.get(args.surface, args.surface)
    kind = LAYOUT.actuator[AIRCRAFT_SURFACES.index(surface)]
    magnitude = {} if args.magnitude is None else {"magnitude": args.magnitude}
    # the rudder's default magnitudes are computed with the elevator table when not given
    base = kind if kind in DEFAULT_MONITORED else "elevator"
    if base != kind and args.magnitude is None:
        from scenarios.aircraft.loop import surface_actuator
        from scenarios.faults import default_magnitude

        magnitude = {"magnitude": default_magnitude(args.fault, surface_actuator(surface))}
    runs = single_run(base, args.manoeuvre, args.fault, seed=args.seed, onset_s=args.onset,
                      duration_s=args.duration, **magnitude)
    runs["surface"] = surface
    runs["run_id"] = f"{surface}-{args.manoeuvre}-{args.fault}-{args.seed}"
    return runs
