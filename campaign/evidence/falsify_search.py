"""The search strategy of ``fdd-campaign falsify``: screening, CMA-ES on the worst cells, a
sweep of streams at the best point (docs/evidence.md, "Worst-case search (falsify)").

What drives a fault-free margin decides the scheme. Measured on ``addsafe-mc``
(``position-monitor``, docs/evidence.md): over the whole box the margin hardly correlates
with any single run variable (|r| < 0.2 per manoeuvre), yet around its largest values it is
a smooth, mostly monotone function of a few mismatch draws (speed and supply-pressure
errors, current gain, hinge-moment derivatives) and the worst runs sit in a corner of the
box; the random stream (sensor noise, turbulence, manoeuvre shape) changes a margin by about
±0.1 at a fixed point, and the manoeuvre (cell) sets the level. So:

1. **Screening** (:data:`SCREEN_SHARE` of the budget): a scrambled Sobol sample of the
   continuous dimensions, spread evenly over the cells, each run with a fresh stream; with a
   warm start (``--against DIR``) the campaign's worst fault-free runs are evaluated first,
   exactly as the campaign ran them (their stream, their drawn manoeuvre start).
2. **Concentration** on the :data:`FOCUS_CELLS` cells of largest screened margin: one
   CMA-ES each (Hansen and Ostermeier 2001, the ``cma`` package, ask/tell; after
   :data:`RACE_GENERATIONS` generations only the one whose cell holds the largest margin
   found goes on) in the unit cube of the continuous dimensions (bounds kept by ``cma``'s bound
   transform), started at the cell's best screened run with step :data:`CMA_SIGMA0`, the stream held
   at that run's stream (a fixed stream makes the objective deterministic, so the evolution path
   follows the variables, not the noise). Each generation of every strategy is one batch of runs.
3. **Stream sweep** (:data:`POLISH_SHARE`, and whatever the generations left): the best run
   found, repeated with fresh streams — the stream is searched where it pays, at the worst
   point, as a discrete draw, never as a continuous dimension.

Every random number comes from one ``numpy`` generator seeded with the search seed
(``cma`` is given it as its ``randn``), and the strategy sees margins only: the same seed
gives the same runs at any number of workers. A point is a vector of the continuous
dimensions in [0, 1] (unit coordinates), a cell index and a stream.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.stats import qmc

__all__ = ["CMA_SIGMA0", "FOCUS_CELLS", "POLISH_SHARE", "RACE_GENERATIONS", "SCREEN_SHARE",
           "Point", "Strategy"]

#: Share of the budget spent screening (est.: enough to rank the cells and find each one's
#: neighbourhood of large margins; 200 runs of a 600 budget).
SCREEN_SHARE: float = 1.0 / 3.0
#: Share kept for the stream sweep at the best point (est.).
POLISH_SHARE: float = 1.0 / 6.0
#: Cells the concentrated search is given to (est.: the worst manoeuvres of a campaign are
#: often close; two hedge a screening that ranked them wrongly).
FOCUS_CELLS: int = 2
#: Focus generations after which only the strategy of the largest margin found goes on
#: (est.; successive halving: the budget goes to the cell that rises).
RACE_GENERATIONS: int = 4
#: Initial CMA-ES step in unit coordinates (est.: a third of the box, so the corners are
#: within reach of the first generations).
CMA_SIGMA0: float = 0.3


@dataclass(frozen=True)
class Point:
    """A run of the search: unit coordinates of the continuous dimensions (NaN for the
    manoeuvre start means "drawn by the manoeuvre model", as in a Monte Carlo run), the
    cell index and the stream."""

    unit: tuple
    cell: int
    stream: int


@dataclass
class Strategy:
    """The three phases of the module docstring as batches: :meth:`ask` gives the next
    batch of points (empty when the budget is spent), :meth:`tell` their margins.

    n_dims : continuous dimensions; n_cells : cells; budget : runs in all; stream_span :
    streams are drawn in [0, stream_span); warm : points evaluated first (``--against``);
    start_dim : index of the manoeuvre-start dimension (or None), replaced by *warm_start*
    (unit coordinate) where a warm point leaves it to the model."""

    n_dims: int
    n_cells: int
    budget: int
    seed: int
    stream_span: int
    warm: list = field(default_factory=list)
    start_dim: int | None = None
    warm_start: dict = field(default_factory=dict)   # warm point index -> unit start

    def __post_init__(self):
        self.rng = np.random.default_rng(np.random.SeedSequence(self.seed))
        self.points: list[Point] = []
        self.margins: list[float] = []
        self.phase = "screen"
        self.generation = 0
        self.n_polish = int(self.budget * POLISH_SHARE)
        self.n_screen = min(self.budget - self.n_polish,
                            max(math.ceil(self.budget * SCREEN_SHARE), self.n_cells,
                                len(self.warm)))
        self.strategies: list = []
        self._pending: list = []
        self.lam = 4 + int(3 * math.log(max(self.n_dims, 1)))   # CMA-ES default λ

    # ---- phases -------------------------------------------------------------------------
    def left(self) -> int:
        return self.budget - len(self.points)

    def ask(self) -> list[Point]:
        """The next batch of points (an empty list: the search is over)."""
        if self.left() <= 0:
            return []
        if self.phase == "screen":
            return self._screen()
        if self.phase == "focus":
            batch = self._focus()
            if batch:
                return batch
            self.phase = "polish"
        return self._polish()

    def tell(self, batch: list[Point], margins) -> None:
        """The margins of *batch* (NaN: a run in error, worth nothing to the search)."""
        margins = [float(m) for m in margins]
        self.points += batch
        self.margins += margins
        if self.phase == "screen":
            self.phase = "focus"
            self._start_focus()
        elif self.phase == "focus":
            for es, part in self._pending:
                # cma minimises; a run in error scores as margin 0 (the least possible)
                es.tell(part["x"], [-(margins[i] if math.isfinite(margins[i]) else 0.0)
                                    for i in part["rows"]])
        self.generation += 1

    # ---- screening ----------------------------------------------------------------------
    def _screen(self) -> list[Point]:
        n = self.n_screen - len(self.warm)
        batch = list(self.warm)
        if n > 0:
            if self.n_dims:
                m = max(0, math.ceil(math.log2(n)))
                unit = qmc.Sobol(d=self.n_dims, scramble=True, seed=self.rng).random_base2(m)[:n]
            else:
                unit = np.empty((n, 0))
            offset = int(self.rng.integers(self.n_cells))
            streams = self.rng.integers(0, self.stream_span, n)
            batch += [Point(tuple(unit[j]), (j + offset) % self.n_cells, int(streams[j]))
                      for j in range(n)]
        return batch[:self.left()]

    # ---- concentration ------------------------------------------------------------------
    def _best_of_cell(self, cell: int) -> tuple[int, float]:
        idx = [i for i, p in enumerate(self.points) if p.cell == cell]
        vals = [_value(self.margins[i]) for i in idx]
        j = int(np.argmax(vals))
        return idx[j], vals[j]

    def _start_focus(self) -> None:
        import cma

        cells = sorted({p.cell for p in self.points},
                       key=lambda c: (-self._best_of_cell(c)[1], c))
        room = self.budget - len(self.points) - self.n_polish
        n_focus = min(FOCUS_CELLS, len(cells), room // (2 * self.lam))
        if n_focus < 1 or self.n_dims == 0:
            self.phase = "polish"
            return
        for cell in cells[:n_focus]:
            i, _ = self._best_of_cell(cell)
            x0 = np.clip(self._unit_of(i), 0.0, 1.0)
            state = np.random.get_state()    # cma seeds numpy's global generator: kept
            es = cma.CMAEvolutionStrategy(
                x0, CMA_SIGMA0,
                {"bounds": [0.0, 1.0], "popsize": self.lam, "verbose": -9, "verb_log": 0,
                 "verb_disp": 0, "seed": int(self.rng.integers(1, 2 ** 31)),
                 "randn": lambda *shape: self.rng.standard_normal(shape),
                 "tolfun": 0.0, "tolflatfitness": 10 ** 9, "tolx": 1e-9})
            np.random.set_state(state)
            self.strategies.append((es, cell, self.points[i].stream))

    def _focus(self) -> list[Point]:
        room = self.left() - self.n_polish
        if len(self.strategies) > 1 and self.generation > RACE_GENERATIONS:
            self.strategies = [max(self.strategies,
                                   key=lambda s: (self._best_of_cell(s[1])[1], -s[1]))]
        live = [s for s in self.strategies if not s[0].stop()]
        if not live or room < self.lam * len(live):
            return []
        batch, self._pending = [], []
        for es, cell, stream in live:
            x = es.ask()
            rows = list(range(len(batch), len(batch) + len(x)))
            batch += [Point(tuple(float(v) for v in xi), cell, stream) for xi in x]
            self._pending.append((es, {"x": x, "rows": rows}))
        return batch

    # ---- stream sweep -------------------------------------------------------------------
    def _polish(self) -> list[Point]:
        vals = [_value(m) for m in self.margins]     # the screening always comes first
        i = int(np.argmax(vals))
        unit = self._unit_of(i)
        streams = self.rng.integers(0, self.stream_span, self.left())
        return [Point(tuple(unit), self.points[i].cell, int(s)) for s in streams]

    def _unit_of(self, i: int) -> np.ndarray:
        """Unit coordinates of evaluated point *i*, a manoeuvre start left to the model
        (NaN, a warm point) replaced by the one it drew (*warm_start*, else mid-range)."""
        unit = np.array(self.points[i].unit, float)
        if self.start_dim is not None and not math.isfinite(unit[self.start_dim]):
            unit[self.start_dim] = self.warm_start.get(i, 0.5)
        return unit


def _value(margin: float) -> float:
    """A margin as the search ranks it: a run in error (NaN) ranks lowest."""
    return margin if math.isfinite(margin) else -math.inf
