"""JSBSim as a third-party nonlinear aircraft plant (docs/aircraft.md §9).

- :mod:`.fdm` — one JSBSim ``FGFDMExec`` per run: its aircraft (the 737 of JSBSim's own
  data by default), the run's flight point mapped onto that aircraft, the trim, the surface
  positions written through its flight-control system, and its linearisation at the trim
  point as a design model in the layout of :mod:`scenarios.aircraft.lpv`;
- :mod:`.loop` — the closed loop: our servo-loops, sensors, faults and laws
  (:mod:`scenarios.aircraft`) flying JSBSim's nonlinear 6-DOF aircraft, ``JsbsimPlant``.

JSBSim is an optional extra (``pip install -e ".[jsbsim]"``); :func:`.fdm.jsbsim_module`
says so with exit code 2 when it is missing.
"""
