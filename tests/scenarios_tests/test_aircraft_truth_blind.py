"""What the simulated flight computer may know (docs/aircraft.md §4, scenarios/aircraft/laws.py):
its control laws are placed on the nominal model (every aerodynamic draw 0) at the *measured*
flight point, so the gains of a run change when its measured flight data change and never
when only the truth changes — the run's aerodynamic errors, or its true flight point under
the same measurements — while the truth does reach the simulated aircraft."""

from __future__ import annotations

import numpy as np
import pandas as pd

from scenarios.aircraft import laws, lpv
from scenarios.aircraft.loop import prepare_aircraft, tas_from_mach
from scenarios.envelope import AERO_COEFFICIENTS, measured_schedule
from scenarios.simulate import single_run

GAIN_FIELDS = ("k_n", "k_q", "k_i", "L_p", "L_da", "N_dr", "nz_de", "tas_ms", "omega_sp")

#: Measurement errors of the reference run (relative, within [CHEN] Table 2's ±10 %).
MEASURED_ERRORS = {"d_vcas": -0.02, "d_alt": 0.03, "d_mass": 0.05, "d_cg": 0.04}


def _run(**point) -> pd.DataFrame:
    r = single_run("elevator", "cruise", "none", duration_s=1.0, **point)
    r["surface"] = "left_elevator"
    return r


def _runs() -> pd.DataFrame:
    """0: the reference (mass 180 t, CG 30 %, FL280, 300 kt, measured with MEASURED_ERRORS);
    1: the same with every aerodynamic coefficient off by 3-8 %; 2: another true mass, 189 t,
    measured as the same 189 t (180 × 1.05); 3: the reference's truth with other measurement
    errors."""
    base = dict(mass_t=180.0, cg_pct=30.0, **MEASURED_ERRORS)
    aero = {f"d_{c}": 0.03 + 0.01 * i for i, c in enumerate(AERO_COEFFICIENTS)}
    moved = dict(base, mass_t=189.0, d_mass=0.0)
    other = dict(base, d_mass=-0.05, d_vcas=0.02)
    return pd.concat([_run(**base), _run(**base, **aero), _run(**moved), _run(**other)],
                     ignore_index=True)


def test_the_gains_do_not_change_when_only_the_truth_changes():
    runs = _runs()
    f = {c: runs[c].to_numpy(float) for c in ("alt_ft", "vcas_kt", "mass_t", "cg_pct", "d_alt",
                                              "d_vcas", "d_mass", "d_cg")}
    sched = measured_schedule(f["alt_ft"], f["vcas_kt"], f["mass_t"], f["cg_pct"], f["d_alt"],
                              f["d_vcas"], f["d_mass"], f["d_cg"])
    # the case is what it says: runs 0-2 are measured alike, run 2 flies another point
    for k in ("mass_t", "cg_pct", "mach", "qbar_pa"):
        assert sched[k][0] == sched[k][1] == sched[k][2], k
    assert runs["mass_t"][2] != runs["mass_t"][0] and sched["mass_t"][3] != sched["mass_t"][0]
    p = prepare_aircraft(runs)
    g = p.gains
    for name in GAIN_FIELDS:
        v = getattr(g, name)
        assert v[1] == v[0] and v[2] == v[0], name          # only the truth differs
    assert all(getattr(g, n)[3] != getattr(g, n)[0] for n in ("k_n", "k_q", "nz_de", "tas_ms"))
    # the truth reaches the aircraft flown (its discrete model differs in runs 1 and 2), the
    # measurement errors do not (run 3 flies the reference's aircraft)
    for i in (1, 2):
        assert not np.array_equal(p.step_matrix[i], p.step_matrix[0]), i
    np.testing.assert_array_equal(p.step_matrix[3], p.step_matrix[0])


def test_the_gains_are_placed_on_the_nominal_model_at_the_measured_point():
    """prepare_aircraft's gains are laws.gains of lpv.run_models(measured Mach, q̄, TAS,
    mass, CG; aerodynamic draws 0), bit for bit."""
    runs = _runs()
    f = {c: runs[c].to_numpy(float) for c in runs.columns if c.startswith(("d_", "alt", "vcas",
                                                                             "mass", "cg"))}
    sched = measured_schedule(f["alt_ft"], f["vcas_kt"], f["mass_t"], f["cg_pct"], f["d_alt"],
                              f["d_vcas"], f["d_mass"], f["d_cg"])
    measured = {"mass_t": sched["mass_t"], "cg_pct": sched["cg_pct"], "mach": sched["mach"],
                "qbar_pa": sched["qbar_pa"], "tas_ms": tas_from_mach(sched["mach"],
                                                                     sched["alt_ft"])}
    expected = laws.gains(lpv.run_models(measured, 0.0))
    got = prepare_aircraft(runs).gains
    for name in GAIN_FIELDS:
        np.testing.assert_array_equal(getattr(got, name), getattr(expected, name), err_msg=name)
