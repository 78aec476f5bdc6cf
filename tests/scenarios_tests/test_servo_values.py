"""The per-run plant parameters and the authority limits of scenarios/servo.py by value
(docs/physics.md §3 and §6), against hand computations and a plain-Python scan of the
deflection grid. The rate law, RK4 step and floating surface of the same module are pinned
in tests/scenarios_tests/test_kernel_values.py together with their compiled kernels."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from scenarios.params import AILERON, ELEVATOR
from scenarios.servo import PlantArrays, authority_limits, plant_arrays

#: Three flight conditions (dynamic pressure [Pa], wing α [deg], Mach) — one above the
#: Prandtl–Glauert cap (M = 0.8 > 0.75).
QBAR = np.array([4.0e3, 12.0e3, 20.0e3])
ALPHA = np.array([1.0, 3.5, -2.0])
MACH = np.array([0.3, 0.6, 0.8])


@pytest.mark.parametrize("act", [ELEVATOR, AILERON], ids=["elevator", "aileron"])
def test_every_field_of_plant_arrays_by_value(act):
    d_supply, d_kci = np.array([0.05, -0.03, 0.0]), np.array([-0.04, 0.02, 0.01])
    d_ch0, d_cha, d_chd = np.array([0.1, -0.2, 0.0]), np.array([0.2, 0.0, -0.1]), \
        np.array([-0.15, 0.1, 0.05])
    p = plant_arrays(act, qbar_pa=QBAR, alpha_deg=ALPHA, mach=MACH, d_ch0=d_ch0, d_cha=d_cha,
                     d_chd=d_chd, d_supply=d_supply, d_kci=d_kci)
    for j in range(3):
        pg = 1.0 / math.sqrt(1.0 - min(MACH[j], 0.75) ** 2)
        qsc = QBAR[j] * act.Sc_m2 * act.cc_m
        alpha_s = math.radians(ALPHA[j]) * (1.0 - act.downwash)
        # docs/physics.md §6: each drawn parameter × (1 + d); 1e-12: round-off of a few products
        assert p.SdP[j] == pytest.approx(act.S_m2 * act.dP_Pa * (1.0 + d_supply[j]), rel=1e-12)
        assert p.Kci[j] == pytest.approx(act.Kci_mm_s_per_mA * (1.0 + d_kci[j]), rel=1e-12)
        assert p.hm_delta[j] == pytest.approx(qsc * act.Ch_delta * (1.0 + d_chd[j]) * pg,
                                              rel=1e-12)
        assert p.hm_0[j] == pytest.approx(
            qsc * (act.Ch0 * (1.0 + d_ch0[j]) + act.Ch_alpha * (1.0 + d_cha[j]) * pg * alpha_s),
            rel=1e-12, abs=1e-9)
    # the undrawn fields are the nominal parameters, run by run
    assert p.SdP_ref.tolist() == [act.S_m2 * act.dP_ref_Pa] * 3
    for field, value in (("K", act.K_mA_per_mm), ("i_max", act.i_max_mA),
                         ("Ka", act.Ka_N_per_mm_s2), ("r_mm", act.r_mm),
                         ("x_min", act.x_min_mm), ("x_max", act.x_max_mm)):
        assert getattr(p, field).tolist() == [value] * 3, field


def test_plant_arrays_defaults_are_the_nominal_plant():
    nominal = plant_arrays(ELEVATOR, qbar_pa=QBAR, alpha_deg=ALPHA, mach=MACH)
    zero = plant_arrays(ELEVATOR, qbar_pa=QBAR, alpha_deg=ALPHA, mach=MACH, d_ch0=0.0,
                        d_cha=0.0, d_chd=0.0, d_supply=0.0, d_kci=0.0)
    for field in dataclasses.fields(PlantArrays):
        np.testing.assert_array_equal(getattr(nominal, field.name), getattr(zero, field.name))
    assert nominal.SdP.tolist() == [ELEVATOR.S_m2 * ELEVATOR.dP_Pa] * 3
    assert nominal.Kci.tolist() == [ELEVATOR.Kci_mm_s_per_mA] * 3
    with pytest.raises(dataclasses.FrozenInstanceError):
        nominal.K = nominal.K * 2.0
    # the flight condition and the draws are keyword-only: no positional mix-up possible
    with pytest.raises(TypeError, match="positional argument"):
        plant_arrays(ELEVATOR, QBAR, ALPHA, MACH)


# ---- authority limits ------------------------------------------------------------------------
def limits_by_scan(act, hm_delta, hm_0, sdp, n_grid=721):
    """The widest interval of grid deflections [deg] around δ_f whose hinge load
    |F| = |HM|/(r·cos δ) stays ≤ order_load_limit·S·ΔP (docs/physics.md §3), found by
    walking the grid (n_grid points from δ_min to δ_max) outward from δ_f in plain Python;
    a bound whose first point is already overloaded is the grid point next to it, inside the
    grid."""
    grid = np.linspace(act.delta_min_deg, act.delta_max_deg, n_grid)
    d_f = math.degrees(-hm_0 / hm_delta)

    def ok(j):
        d = math.radians(grid[j])
        hm = hm_0 + hm_delta * d
        return abs(hm / (act.r_mm / 1000.0 * math.cos(d))) <= act.order_load_limit * sdp

    lo = 0
    for j in range(n_grid - 1, -1, -1):
        if grid[j] <= d_f and not ok(j):
            lo = min(j + 1, n_grid - 1)
            break
    hi = n_grid - 1
    for j in range(n_grid):
        if grid[j] > d_f and not ok(j):
            hi = max(j - 1, 0)
            break
    return min(grid[lo], grid[hi]), max(grid[lo], grid[hi])


#: (∂HM/∂δ [N·m/rad], δ_f [deg]) of the elevator's hand-made runs; the load limit
#: 0.6·S·ΔP = 62 kN at r = 0.12 m is a hinge moment of about 7.4 kN·m.
CASES = {
    "light load: the whole range": (-1000.0, 2.0),
    "heavy load: limited on both sides": (-40000.0, 2.0),
    "limited below only": (-30000.0, 10.0),
    "floating above the range, overloaded at its top": (-200000.0, 20.0),
    "floating below the range, overloaded at its bottom": (-200000.0, -35.0),
}


def hand_plant(act, cases):
    n = len(cases)
    base = plant_arrays(act, qbar_pa=np.full(n, 1e4), alpha_deg=np.zeros(n), mach=np.full(n, 0.5))
    h = np.array([c[0] for c in cases])
    return dataclasses.replace(base, hm_delta=h,
                               hm_0=-h * np.radians(np.array([c[1] for c in cases])))


def test_authority_limits_by_scan():
    act = ELEVATOR
    p = hand_plant(act, list(CASES.values()))
    lo, hi = authority_limits(p, act)
    for j, name in enumerate(CASES):
        want = limits_by_scan(act, p.hm_delta[j], p.hm_0[j], p.SdP[j])
        assert (lo[j], hi[j]) == want, name
    # what the cases are: the whole range; an interval strictly inside around δ_f (grid of
    # 1/16°); one-sided; a single point at each end
    assert (lo[0], hi[0]) == (-30.0, 15.0)
    assert -30.0 < lo[1] < 2.0 < hi[1] < 15.0
    assert -30.0 < lo[2] < 10.0 and hi[2] == 15.0
    assert (lo[3], hi[3]) == (15.0, 15.0) and (lo[4], hi[4]) == (-30.0, -30.0)
    np.testing.assert_allclose(np.diff(np.linspace(-30.0, 15.0, 721)), 1 / 16, rtol=1e-9)
    # the bounds of the inside case are the last grid points under the load limit
    for bound, step in ((lo[1], -1 / 16), (hi[1], 1 / 16)):
        for d, inside in ((bound, True), (bound + step, False)):
            hm = p.hm_0[1] + p.hm_delta[1] * math.radians(d)
            load = abs(hm / (0.12 * math.cos(math.radians(d))))
            assert bool(load <= 0.6 * p.SdP[1]) is inside, (bound, d)


def test_authority_limits_grid_size():
    act = ELEVATOR
    p = hand_plant(act, [CASES["heavy load: limited on both sides"]])
    lo, hi = authority_limits(p, act, n_grid=46)           # a 1° grid
    want = limits_by_scan(act, p.hm_delta[0], p.hm_0[0], p.SdP[0], n_grid=46)
    assert (lo[0], hi[0]) == want
    assert lo[0] == round(lo[0]) and hi[0] == round(hi[0])
