"""Aircraft in the loop (docs/physics.md §7 phase 2): rigid-body LPV dynamics, normal-law-like
control laws, every primary surface with its own servo-loop and aircraft-level sensors.

- :mod:`.data` — parameter tables: the Boeing 747 stability derivatives of the reference
  flight condition, the A330-class mass/inertia scaling, the surface layout, the laws'
  tuning and the aircraft sensors;
- :mod:`.lpv` — linear models built at each run's flight point and their exact ZOH
  discretisation, batched over runs;
- :mod:`.laws` — pitch (load factor with integral action, short period scheduled on the
  control anticipation parameter), roll (roll-rate command with bank hold) and yaw (damper
  and turn coordination) laws at Ts, with filtered measurements and rate-limited orders
  (docs/aircraft.md §4);
- :mod:`.loop` — the closed loop of a batch of runs (``simulate_aircraft``).
"""
