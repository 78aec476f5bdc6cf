"""The search strategy of ``fdd-campaign falsify`` by value (campaign/evidence/falsify_search.py,
docs/evidence.md "Worst-case search (falsify)"): the sizes of the three phases on the path
of the shipped presets (20 continuous dimensions, 6 cells, the documented budget of 600),
the screening batch written again from its generator, the cells and start points of the
CMA-ES strategies, what they are told, the race, and the stream sweep at the best run. No
simulation: the margins are functions of the points chosen here."""

import math

import numpy as np
import pytest
from scipy.stats import qmc

from campaign.evidence.falsify import STREAM_SPAN, search_space
from campaign.evidence.falsify_search import (
    CMA_SIGMA0,
    FOCUS_CELLS,
    POLISH_SHARE,
    RACE_GENERATIONS,
    SCREEN_SHARE,
    Point,
    Strategy,
)
from campaign.config import load_config

from test_falsify import _drive


def _screen_margins(batch, best_cell=None, value=0.5):
    """Margins of a screening batch: *value*, with 0.9 on the first point of *best_cell*."""
    out = [value] * len(batch)
    if best_cell is not None:
        out[next(i for i, p in enumerate(batch) if p.cell == best_cell)] = 0.9
    return out


# ---- the phases' sizes --------------------------------------------------------------------
def test_the_presets_search_twenty_dimensions_over_six_cells():
    space = search_space(load_config("addsafe-mc"))
    assert (len(space.bounds), len(space.cells)) == (20, 6)


def test_phase_sizes_at_the_documented_budget_of_600():
    s = Strategy(n_dims=20, n_cells=6, budget=600, seed=0, stream_span=STREAM_SPAN)
    # 200 screening runs of a 600 budget (SCREEN_SHARE's comment), a sixth for the sweep
    assert (SCREEN_SHARE, POLISH_SHARE) == (1.0 / 3.0, 1.0 / 6.0)
    assert (s.n_screen, s.n_polish) == (200, 100)
    # CMA-ES's default population 4 + ⌊3 ln n⌋ (Hansen 2016): 4 + ⌊8.99⌋ = 12 for 20 dims
    assert s.lam == 12
    assert len(s.ask()) == 200 and s.phase == "screen"


@pytest.mark.parametrize("n_dims, lam", [(0, 4), (1, 4), (2, 6), (20, 12), (21, 13)])
def test_population_is_cma_default(n_dims, lam):
    assert Strategy(n_dims=n_dims, n_cells=1, budget=60, seed=0, stream_span=10).lam == lam


@pytest.mark.parametrize("budget, n_cells, n_warm, screen, polish", [
    (600, 6, 0, 200, 100),
    (601, 6, 0, 201, 100),     # ⌈601/3⌉ = 201; ⌊601/6⌋ = 100
    (10, 6, 0, 6, 1),          # at least one screening run per cell
    (10, 3, 0, 4, 1),          # ⌈10/3⌉ = 4 over three cells
    (10, 6, 8, 8, 1),          # every warm point is screened
    (10, 6, 20, 9, 1),         # but the sweep keeps its share
])
def test_screening_size(budget, n_cells, n_warm, screen, polish):
    warm = [Point((0.5,), 0, i) for i in range(n_warm)]
    s = Strategy(n_dims=1, n_cells=n_cells, budget=budget, seed=0, stream_span=10, warm=warm)
    assert (s.n_screen, s.n_polish) == (screen, polish)


# ---- screening ----------------------------------------------------------------------------
@pytest.mark.parametrize("n_dims, n_cells, budget, seed", [(20, 6, 600, 4), (3, 5, 30, 9)])
def test_screening_batch_is_the_scrambled_sobol_sample_of_the_seed(n_dims, n_cells, budget,
                                                                   seed):
    s = Strategy(n_dims=n_dims, n_cells=n_cells, budget=budget, seed=seed, stream_span=1000)
    batch = s.ask()
    n = s.n_screen
    rng = np.random.default_rng(np.random.SeedSequence(seed))
    unit = qmc.Sobol(d=n_dims, scramble=True, seed=rng).random_base2(
        math.ceil(math.log2(n)))[:n]
    offset = int(rng.integers(n_cells))
    streams = rng.integers(0, 1000, n)
    assert batch == [Point(tuple(unit[j]), (j + offset) % n_cells, int(streams[j]))
                     for j in range(n)]
    # spread evenly over the cells
    counts = np.bincount([p.cell for p in batch], minlength=n_cells)
    assert counts.max() - counts.min() <= 1


def test_screening_with_warm_points_and_without_continuous_dimensions():
    warm = [Point((0.9, 0.1), 1, 77), Point((0.2, 0.3), 0, 78)]
    s = Strategy(n_dims=2, n_cells=2, budget=12, seed=1, stream_span=100, warm=warm)
    batch = s.ask()
    assert len(batch) == s.n_screen == 4 and batch[:2] == warm
    rng = np.random.default_rng(np.random.SeedSequence(1))
    unit = qmc.Sobol(d=2, scramble=True, seed=rng).random_base2(1)[:2]
    assert [p.unit for p in batch[2:]] == [tuple(u) for u in unit]
    # a single fresh run: a sample of 2⁰ points
    s = Strategy(n_dims=2, n_cells=1, budget=6, seed=1, stream_span=100,
                 warm=[Point((0.5, 0.5), 0, 1)])
    assert s.n_screen == 2 and len(s.ask()) == 2
    s = Strategy(n_dims=0, n_cells=3, budget=12, seed=1, stream_span=100)
    batch = s.ask()
    assert len(batch) == 4 and all(p.unit == () for p in batch)


def test_warm_points_beyond_the_budget_are_cut_to_it():
    warm = [Point((0.5,), 0, i) for i in range(12)]
    s = Strategy(n_dims=1, n_cells=1, budget=10, seed=0, stream_span=100, warm=warm)
    assert s.ask() == warm[:10]


# ---- concentration ------------------------------------------------------------------------
def test_focus_starts_on_the_two_best_cells_at_their_best_runs():
    s = Strategy(n_dims=3, n_cells=4, budget=120, seed=2, stream_span=STREAM_SPAN)
    batch = s.ask()
    margins = [0.1 * p.cell + 0.01 * p.unit[0] for p in batch]     # cell 3 best, then 2
    margins[0] = math.nan                                           # a run in error
    before = np.random.get_state()
    s.tell(batch, margins)
    after = np.random.get_state()
    # cma seeds numpy's global generator; the strategy puts it back
    assert before[0] == after[0] and np.array_equal(before[1], after[1])
    assert before[2:] == after[2:]
    assert s.phase == "focus" and len(s.strategies) == FOCUS_CELLS == 2
    for (es, cell, stream), want in zip(s.strategies, (3, 2)):
        idx = [i for i, p in enumerate(batch) if p.cell == want]
        best = max(idx, key=lambda i: margins[i] if math.isfinite(margins[i]) else -1)
        assert cell == want and stream == batch[best].stream
        np.testing.assert_array_equal(es.x0, batch[best].unit)
        assert es.sigma0 == CMA_SIGMA0 == 0.3 and es.popsize == s.lam
        assert list(es.opts["bounds"]) == [0.0, 1.0]
        assert (es.opts["tolfun"], es.opts["tolflatfitness"], es.opts["tolx"]) == \
            (0.0, 10 ** 9, 1e-9)


def test_cells_of_equal_margins_go_to_the_lower_index_and_an_error_ranks_lowest():
    s = Strategy(n_dims=2, n_cells=4, budget=120, seed=3, stream_span=100)
    batch = s.ask()
    # cells 1 and 3 tie at 0.7; cell 0's only finite values are below an error's NaN
    margins = [{0: -5.0, 1: 0.7, 2: 0.2, 3: 0.7}[p.cell] for p in batch]
    s.tell(batch, margins)
    assert [c for _, c, _ in s.strategies] == [1, 3]
    s = Strategy(n_dims=2, n_cells=2, budget=120, seed=3, stream_span=100)
    batch = s.ask()
    margins = [math.nan if p.cell == 1 else -5.0 for p in batch]
    s.tell(batch, margins)
    assert [c for _, c, _ in s.strategies] == [0, 1]


def test_a_warm_start_outside_the_box_and_a_start_left_to_the_model():
    warm = [Point((1.4, -0.2, math.nan), 0, 5), Point((0.5, 0.5, math.nan), 1, 6)]
    s = Strategy(n_dims=3, n_cells=2, budget=120, seed=0, stream_span=100, warm=warm,
                 start_dim=2, warm_start={1: 0.25})
    batch = s.ask()
    s.tell(batch, [0.95, 0.9] + [0.1] * (len(batch) - 2))
    (es0, c0, st0), (es1, c1, st1) = s.strategies
    assert (c0, st0, c1, st1) == (0, 5, 1, 6)
    # clipped into the unit cube; the start the model drew (warm_start), else mid-range
    np.testing.assert_array_equal(es0.x0, [1.0, 0.0, 0.5])
    np.testing.assert_array_equal(es1.x0, [0.5, 0.5, 0.25])


class _Recorder:
    """A CMA-ES strategy whose ``tell`` is recorded before it is passed on."""

    def __init__(self, es):
        self.es, self.told = es, []

    def ask(self):
        return self.es.ask()

    def stop(self):
        return self.es.stop()

    def tell(self, x, values):
        self.told.append(list(values))
        self.es.tell(x, values)


def test_cma_is_told_the_negated_margins_an_error_as_zero():
    s = Strategy(n_dims=2, n_cells=2, budget=200, seed=5, stream_span=100)
    batch = s.ask()
    s.tell(batch, [0.1 * p.cell for p in batch])
    s.strategies = [(_Recorder(es), c, st) for es, c, st in s.strategies]
    batch = s.ask()
    assert len(batch) == 2 * s.lam == 12
    margins = [0.25 + 0.01 * i for i in range(len(batch))]
    margins[1], margins[7] = math.nan, math.inf
    s.tell(batch, margins)
    first, second = (r.told for r, _, _ in s.strategies)
    # exact: each told value is a margin negated, or 0.0 for the NaN and the infinity
    assert first == [[-(0.25 + 0.01 * 0), 0.0, -(0.25 + 0.01 * 2), -(0.25 + 0.01 * 3),
                      -(0.25 + 0.01 * 4), -(0.25 + 0.01 * 5)]]
    assert second == [[-(0.25 + 0.01 * 6), 0.0, -(0.25 + 0.01 * 8), -(0.25 + 0.01 * 9),
                       -(0.25 + 0.01 * 10), -(0.25 + 0.01 * 11)]]
    assert s.generation == 2


def test_the_race_leaves_the_cell_of_the_largest_margin_after_four_generations():
    s = Strategy(n_dims=2, n_cells=2, budget=600, seed=6, stream_span=100)
    seen = _drive(s, lambda p: 0.5 + 0.1 * p.cell * (p.unit[0] > 2.0))   # flat: a tie
    focus = [(len(b), {p.cell for p in b}) for ph, b, _ in seen if ph == "focus"]
    assert RACE_GENERATIONS == 4
    assert focus[:4] == [(12, {0, 1})] * 4
    # tied at 0.5: the lower cell goes on; a flat objective does not stop CMA-ES
    assert focus[4:] and all(f == (6, {0}) for f in focus[4:])
    s = Strategy(n_dims=2, n_cells=2, budget=600, seed=6, stream_span=100)
    seen = _drive(s, lambda p: 0.5 + 0.1 * p.cell)
    focus = [{p.cell for p in b} for ph, b, _ in seen if ph == "focus"]
    assert focus[:4] == [{0, 1}] * 4 and focus[4:] and all(f == {1} for f in focus[4:])


def test_focus_runs_while_a_whole_generation_fits_before_the_sweep():
    # one dimension: λ = 4; budget 40: 14 screened, 6 for the sweep, room 20 = 5 generations
    s = Strategy(n_dims=1, n_cells=1, budget=40, seed=0, stream_span=100)
    seen = _drive(s, lambda p: p.unit[0])
    assert [(ph, len(b)) for ph, b, _ in seen] == [("screen", 14)] + [("focus", 4)] * 5 + [
        ("polish", 6)]
    # budget 41: 14 + 6 again, room 21: five generations, the sweep takes the odd run
    s = Strategy(n_dims=1, n_cells=1, budget=41, seed=0, stream_span=100)
    seen = _drive(s, lambda p: p.unit[0])
    assert [(ph, len(b)) for ph, b, _ in seen][-1] == ("polish", 7)


@pytest.mark.parametrize("n_warm, n_focus", [(26, 1), (27, 0)])
def test_a_strategy_is_started_only_with_room_for_two_generations(n_warm, n_focus):
    # λ = 12 (20 dims); budget 60: 10 for the sweep; 26 screened leave 24 = 2λ, 27 leave 23
    warm = [Point((0.5,) * 20, 0, i) for i in range(n_warm)]
    s = Strategy(n_dims=20, n_cells=2, budget=60, seed=0, stream_span=100, warm=warm)
    batch = s.ask()
    s.tell(batch, [0.5] * len(batch))
    assert len(s.strategies) == n_focus
    assert s.phase == ("focus" if n_focus else "polish")


def test_no_focus_without_continuous_dimensions():
    s = Strategy(n_dims=0, n_cells=2, budget=30, seed=0, stream_span=100)
    seen = _drive(s, lambda p: 0.1 * p.cell)
    assert [ph for ph, _, _ in seen] == ["screen", "polish"] and not s.strategies
    assert sum(len(b) for _, b, _ in seen) == 30


# ---- the stream sweep ---------------------------------------------------------------------
def test_sweep_repeats_the_best_run_with_fresh_streams():
    s = Strategy(n_dims=2, n_cells=3, budget=30, seed=8, stream_span=50)
    seen = _drive(s, lambda p: -abs(p.unit[0] - 0.3) + 0.2 * (p.cell == 1))
    points = [p for _, b, _ in seen for p in b]
    margins = [m for _, _, ms in seen for m in ms]
    sweep = seen[-1][1]
    assert seen[-1][0] == "polish" and len(points) == 30
    before = points[:len(points) - len(sweep)]
    best = before[int(np.argmax(margins[:len(before)]))]
    assert all(p.unit == best.unit and p.cell == best.cell == 1 for p in sweep)
    assert all(0 <= p.stream < 50 for p in sweep) and len({p.stream for p in sweep}) > 1


def test_sweep_of_a_warm_best_run_uses_its_drawn_start_and_skips_errors():
    warm = [Point((0.2, math.nan), 0, 3), Point((0.7, math.nan), 0, 4)]
    for starts, want in (({0: 0.8}, 0.8), ({1: 0.1}, 0.5)):
        s = Strategy(n_dims=2, n_cells=1, budget=12, seed=0, stream_span=50, warm=warm,
                     start_dim=1, warm_start=starts)
        batch = s.ask()
        assert len(batch) == 4
        # the first warm run is the best; an error (NaN) never is
        s.tell(batch, [-1.0, math.nan, -3.0, -2.0])
        sweep = s.ask()
        assert s.phase == "polish" and len(sweep) == 8
        assert all(p.unit == (0.2, want) and p.cell == 0 for p in sweep)


def test_no_points_once_the_budget_is_spent():
    s = Strategy(n_dims=1, n_cells=1, budget=12, seed=0, stream_span=50)
    seen = _drive(s, lambda p: p.unit[0])
    assert sum(len(b) for _, b, _ in seen) == 12 and s.left() == 0 and s.ask() == []


def test_a_single_run_left_is_still_spent():
    # nine cells: nine screening runs of a budget of 10, the sweep's one run last
    s = Strategy(n_dims=1, n_cells=9, budget=10, seed=0, stream_span=50)
    seen = _drive(s, lambda p: p.unit[0])
    assert [(ph, len(b)) for ph, b, _ in seen] == [("screen", 9), ("polish", 1)]


def test_a_point_is_frozen():
    import dataclasses

    p = Point((0.5,), 1, 2)
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.cell = 3
    assert hash(p) == hash(Point((0.5,), 1, 2))


def test_each_cma_seed_is_drawn_from_the_search_generator_and_cma_stays_quiet():
    import warnings

    s = Strategy(n_dims=4, n_cells=3, budget=200, seed=12, stream_span=1000)
    batch = s.ask()
    with warnings.catch_warnings():
        warnings.simplefilter("error")          # a cma warning (e.g. its unused seed) fails
        s.tell(batch, [0.1 * p.cell for p in batch])
        s.tell(s.ask(), [0.5] * (2 * s.lam))
    # the generator's draws written again: screening, then one seed per strategy in [1, 2³¹)
    rng = np.random.default_rng(np.random.SeedSequence(12))
    qmc.Sobol(d=4, scramble=True, seed=rng).random_base2(math.ceil(math.log2(s.n_screen)))
    rng.integers(3)
    rng.integers(0, 1000, s.n_screen)
    seeds = [int(rng.integers(1, 2 ** 31)) for _ in range(FOCUS_CELLS)]
    assert [es.opts["seed"] for es, _, _ in s.strategies] == seeds
    # and the first generation's samples come from it (cma's randn)
    again = Strategy(n_dims=4, n_cells=3, budget=200, seed=12, stream_span=1000)
    again.tell(again.ask(), [0.1 * p.cell for p in batch])
    assert again.rng.bit_generator.state == rng.bit_generator.state


def test_two_strategies_stop_when_both_generations_no_longer_fit():
    # one dimension, two cells: λ = 4; budget 40: 14 screened, 6 kept for the sweep, room
    # 20: two generations of both strategies (16), then 4 < 2λ: the sweep takes 4 + 6
    s = Strategy(n_dims=1, n_cells=2, budget=40, seed=0, stream_span=100)
    seen = _drive(s, lambda p: p.unit[0] + 0.1 * p.cell)
    assert [(ph, len(b)) for ph, b, _ in seen] == [("screen", 14), ("focus", 8), ("focus", 8),
                                                   ("polish", 10)]


def test_sweep_streams_start_at_zero():
    s = Strategy(n_dims=1, n_cells=1, budget=60, seed=0, stream_span=2)
    seen = _drive(s, lambda p: p.unit[0])
    sweep = [p.stream for ph, b, _ in seen if ph == "polish" for p in b]
    assert len(sweep) >= 10 and set(sweep) == {0, 1}
