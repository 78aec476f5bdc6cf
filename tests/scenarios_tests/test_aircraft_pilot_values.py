"""scenarios.aircraft.pilot by value (docs/physics.md §7 phase 2, docs/aircraft.md): each
manoeuvre's stick and pedal inputs at hand-chosen times of one run, recomputed from the
module docstring and the pilot table :data:`scenarios.aircraft.data.PILOT`.

Each input rises and falls with the cubic smoothstep s²·(3 − 2s), s = (t − t0)/rise clipped
to [0, 1]: 0 before t0, 0.15625 a quarter into the rise, 0.5 half-way, 0.84375 three
quarters in, 1 after; the times below sit on those points. A range (lo, hi) drawn with the
uniform u gives lo + (hi − lo)·u. The run's eight uniforms are all different, so a draw
read from the wrong position changes the value. Tolerance 1e-12 (absolute, on values of
0.01-0.5): the values are a few floating-point operations on exact inputs; a wrong constant
moves them by at least 1e-3."""

from __future__ import annotations

import math

import numpy as np
import pytest

from scenarios.aircraft import pilot
from scenarios.aircraft.data import PILOT, PilotParams

#: The run's uniforms: start 3 + 5·0.2 = 4 s; the others as each manoeuvre reads them.
U = np.array([0.2, 0.4, 0.6, 0.8, 0.3, 0.05, 0.95, 0.15])
T0 = 4.0
Q, H, TQ = 0.15625, 0.5, 0.84375          # the smoothstep at 1/4, 1/2, 3/4 of its rise
TOL = 1e-12


def _inputs(manoeuvre, times, u=U, params=PILOT):
    return pilot.pilot_inputs(manoeuvre, np.asarray(times, float), u, params)


def _check(got, want):
    np.testing.assert_allclose(got, want, rtol=0, atol=TOL)


def test_cruise_has_no_input():
    t = np.linspace(0.0, 60.0, 601)
    for x in _inputs("cruise", t):
        _check(x, np.zeros_like(t))


def test_nose_up_is_a_smoothed_pull_held_then_released():
    """Pull 0.15 + 0.15·0.4 = 0.21 g from t0 = 4 s, rise 0.5 s, held 5 + 5·0.6 = 8 s after
    the rise, released over 0.5 s (from 12.5 s to 13 s)."""
    a = 0.21
    t = [3.9, 4.0, 4.125, 4.25, 4.5, 8.0, 12.5, 12.625, 12.75, 12.875, 13.0, 20.0]
    want = a * np.array([0, 0, Q, H, 1, 1, 1, TQ, H, Q, 0, 0])
    nz, p, beta = _inputs("nose_up", t)
    _check(nz, want)
    _check(p, np.zeros(len(t)))
    _check(beta, np.zeros(len(t)))


def test_aoa_protection_is_a_slow_ramp_held_then_released():
    """Pull 0.2 + 0.15·0.4 = 0.26 g over a ramp of 2 + 2·0.6 = 3.2 s (in and out), held
    2 + 3·0.8 = 4.4 s: up from 4 s to 7.2 s, down from 11.6 s to 14.8 s."""
    a = 0.26
    t = [4.0, 4.8, 5.6, 6.4, 7.2, 9.0, 11.6, 12.4, 13.2, 14.0, 14.8, 16.0]
    want = a * np.array([0, Q, H, TQ, 1, 1, 1, TQ, H, Q, 0, 0])
    nz, p, beta = _inputs("aoa_protection", t)
    _check(nz, want)
    _check(p + beta, np.zeros(len(t)))


def test_pitch_protection_pulls_then_pushes_after_the_gap():
    """Pull 0.3 + 0.15·0.4 = 0.36 g held 1 + 1·0.6 = 1.6 s (4 s to 6.6 s with its edges),
    a 2-s gap, then a push of 0.3 + 0.15·0.8 = 0.42 g (its own draw) held as long, from
    t1 = 4 + 2·0.5 + 1.6 + 2 = 8.6 s to 8.6 + 2·0.5 + 1.6 = 11.2 s."""
    t = [4.25, 5.3, 6.35, 6.6, 7.6, 8.6, 8.85, 9.9, 10.95, 11.2, 12.0]
    want = [0.18, 0.36, 0.18, 0.0, 0.0, 0.0, -0.21, -0.42, -0.21, 0.0, 0.0]
    nz, p, beta = _inputs("pitch_protection", t)
    _check(nz, want)
    _check(p + beta, np.zeros(len(t)))


@pytest.mark.parametrize("u4, sign", [(0.3, 1.0), (0.5, -1.0), (0.7, -1.0), (0.0, 1.0)])
def test_yaw_angle_mode_is_a_pedal_sideslip_order_of_either_sign(u4, sign):
    """Sideslip order 2 + 2·0.4 = 2.8° held 5 + 5·0.6 = 8 s, positive when the fifth draw
    is below 1/2 (a draw of exactly 1/2 is negative: each sign has probability 1/2)."""
    u = U.copy()
    u[4] = u4
    b = sign * math.radians(2.8)
    t = [4.0, 4.25, 8.0, 12.5, 12.75, 13.0]
    nz, p, beta = _inputs("yaw_angle_mode", t, u)
    _check(beta, b * np.array([0, H, 1, 1, H, 0]))
    _check(nz + p, np.zeros(len(t)))


@pytest.mark.parametrize("u4, sign", [(0.3, 1.0), (0.5, -1.0), (0.7, -1.0)])
def test_turn_coordination_rolls_in_turns_and_rolls_out(u4, sign):
    """Roll rate 7.5 °/s to a bank of 25 + 8·0.4 = 28.2° (roll-in 28.2/7.5 = 3.76 s), each
    edge over the turn's own 1.5 s; turn held 4 + 3·0.6 = 5.8 s; the roll-out, of the
    opposite rate, starts at t1 = 4 + 3.76 + 5.8 = 13.56 s. Right turn when the fifth draw
    is below 1/2."""
    u = U.copy()
    u[4] = u4
    rate = sign * math.radians(7.5)
    t = [4.0, 4.75, 5.5, 7.76, 8.51, 9.26, 12.0, 13.56, 14.31, 15.06, 17.32, 18.07, 18.82, 20.0]
    want = rate * np.array([0, H, 1, 1, H, 0, 0, 0, -H, -1, -1, -H, 0, 0])
    nz, p, beta = _inputs("turn_coordination", t, u)
    _check(p, want)
    _check(nz + beta, np.zeros(len(t)))


def test_the_stress_turn_rolls_at_full_stick_over_the_short_edges():
    """PILOT_STRESS: 15 °/s to 33° (every draw at the range's top), edges of 0.5 s: the
    roll-in lasts 33/15 = 2.2 s; the turn is held 4 + 3·0.6 = 5.8 s; the roll-out starts at
    4 + 2.2 + 5.8 = 12 s."""
    rate = math.radians(15.0)
    t = [4.0, 4.25, 4.5, 6.2, 6.45, 6.7, 12.0, 12.25, 12.5, 14.2, 14.45, 14.7]
    want = rate * np.array([0, H, 1, 1, H, 0, 0, -H, -1, -1, -H, 0])
    _, p, _ = _inputs("turn_coordination", t, params=pilot.PILOT_STRESS)
    _check(p, want)


def test_the_stress_set_flies_the_top_of_each_range():
    """PILOT_STRESS nose-up: the 0.3 g top of the range whatever the draw."""
    nz, _, _ = _inputs("nose_up", [4.5, 8.0], params=pilot.PILOT_STRESS)
    _check(nz, [0.3, 0.3])
    assert pilot.set_params("stress") is pilot.PILOT_STRESS
    assert pilot.set_params("normal") is PILOT
    with pytest.raises(ValueError, match="normal"):
        pilot.set_params("gentle")


def test_an_unknown_manoeuvre_is_refused_with_the_allowed_names():
    with pytest.raises(ValueError, match="unknown manoeuvre 'loop'.*nose_up"):
        _inputs("loop", [0.0])


def test_a_batch_draws_eight_uniforms_a_run_and_stacks_each_run():
    """inputs_for_runs: each generator advanced by exactly N_DRAWS = 8 uniforms, whatever
    the manoeuvre (the ninth uniform of a fresh generator is the next one drawn); each row
    is the run's own pilot_inputs, with one table for every run or one per run."""
    assert pilot.N_DRAWS == 8
    t = np.arange(0.0, 30.0, 0.5)
    mans = ["nose_up", "cruise", "turn_coordination"]
    gens = [np.random.default_rng(s) for s in (1, 2, 3)]
    tables = [PILOT, PILOT, pilot.PILOT_STRESS]
    nz, p, beta = pilot.inputs_for_runs(np.array(mans), t, gens, tables)
    assert nz.shape == p.shape == beta.shape == (3, len(t))
    for i, (m, s, table) in enumerate(zip(mans, (1, 2, 3), tables)):
        draws = np.random.default_rng(s).uniform(size=9)
        want = pilot.pilot_inputs(m, t, draws[:8], table)
        for got, w in zip((nz, p, beta), want):
            np.testing.assert_array_equal(got[i], w)
        assert gens[i].uniform() == draws[8]
    one = pilot.inputs_for_runs(mans, t, [np.random.default_rng(s) for s in (1, 2, 3)], PILOT)
    np.testing.assert_array_equal(one[0][:2], nz[:2])
    assert not np.array_equal(one[1][2], p[2])          # the stress table's turn differs


def test_a_batch_needs_one_table_or_one_per_run():
    t = np.zeros(3)
    gens = [np.random.default_rng(0), np.random.default_rng(1)]
    with pytest.raises(ValueError, match=r"one per run \(2\), got 1"):
        pilot.inputs_for_runs(["cruise", "cruise"], t, gens, [PILOT])
    assert isinstance(PILOT, PilotParams)
