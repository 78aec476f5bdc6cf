"""The JSBSim plant (scenarios/jsbsim, docs/aircraft.md §9): its surfaces drive JSBSim's
aerodynamics, its aircraft file opens no socket, a point it cannot fly is a run error with
its reason, its design model is not the plant, and its runs are functions of their rows."""

import sys

import numpy as np
import pandas as pd
import pytest

jsbsim = pytest.importorskip("jsbsim")

from scenarios.aircraft import lpv
from scenarios.jsbsim import fdm as F
from scenarios.jsbsim.loop import JsbsimPlant, integrate_jsbsim, prepare_jsbsim
from scenarios.simulate import single_run

MODEL = F.AIRCRAFT["737"]


def _trimmed(alt=28000.0, vcas=280.0, mass=47.0, cg=20.0):
    f = F.Fdm(MODEL, 0.01)
    f.trim(alt, vcas, mass, cg)
    return f


def _runs(manoeuvre, fault="none", surface="left_inboard_aileron", seed=0, n=1,
          duration_s=20.0):
    rows = []
    for s in range(n):
        r = single_run("aileron" if "aileron" in surface else "elevator", manoeuvre, fault,
                       seed=seed + s, duration_s=duration_s, onset_s=8.0)
        r["surface"] = surface
        r["run_id"] = f"{manoeuvre}-{seed + s}"
        rows.append(r)
    return pd.concat(rows, ignore_index=True)


def test_written_positions_are_the_surfaces_jsbsim_flies():
    """Each written position is what the aerodynamics read after the step, the rudder with
    the yaw damper taken out while the aircraft yaws (r ≠ 0 after an aileron input)."""
    f = _trimmed()
    f.read()
    r_max = 0.0
    for k in range(300):
        want = (-0.02 + 0.01 * np.sin(k / 20), 0.05 * np.cos(k / 30), 0.02 * np.sin(k / 15))
        f.set_surfaces(*want)
        f.step()
        got = [f.fdm[p] for p in ("fcs/elevator-pos-rad", "fcs/left-aileron-pos-rad",
                                  "fcs/rudder-pos-rad")]
        np.testing.assert_allclose(got, want, atol=1e-12)
        r_max = max(r_max, abs(f.fdm["velocities/r-aero-rad_sec"]))
    assert r_max > 1e-2           # rad/s: the damper added up to 0.35·r_max rad to the rudder


def test_trimmed_point_is_the_one_asked_for():
    """Mass, CG (through the aerodynamic reference point) and speed as set, in level flight."""
    f = _trimmed(alt=18000.0, vcas=250.0, mass=50.0, cg=28.0)
    assert f.fdm["inertia/weight-lbs"] * F.LB_KG / 1000.0 == pytest.approx(50.0, rel=1e-9)
    cg = 25.0 + (f.fdm["inertia/cg-x-in"] - f.fdm["metrics/aero-rp-x-in"]) / f.cbar_in * 100.0
    assert cg == pytest.approx(28.0, abs=1e-9)
    assert f.fdm["velocities/vc-kts"] == pytest.approx(250.0, abs=0.5)
    assert abs(f.fdm["velocities/h-dot-fps"]) < 0.1
    # a forward CG needs more nose-up (trailing edge up, negative) elevator: the arm moved
    fwd = _trimmed(alt=18000.0, vcas=250.0, mass=50.0, cg=12.0)
    assert fwd.trim_surfaces[0] < f.trim_surfaces[0]


def test_the_aircraft_file_is_loaded_without_its_sockets():
    """JSBSim's 737.xml declares input sockets (ports 5137, 5139); the copy we load has no
    top-level <input> or <output>, and everything else of the file is kept."""
    import xml.etree.ElementTree as ET
    from pathlib import Path

    root = jsbsim.get_default_root_dir()
    shipped = ET.parse(Path(root) / "aircraft" / "737" / "737.xml").getroot()
    loaded = ET.parse(Path(F.sanitised_aircraft_dir(MODEL, root)) / "737" / "737.xml").getroot()
    assert [c.get("port") for c in shipped if c.tag == "input"] == ["5137", "5139"]
    assert not [c for c in loaded if c.tag in ("input", "output")]
    assert ([c.tag for c in shipped if c.tag not in ("input", "output")]
            == [c.tag for c in loaded])


def test_a_point_the_aircraft_cannot_trim_is_a_run_error_naming_it():
    with pytest.raises(F.JsbsimRunError, match=r"trim failed at 8000 ft, 150 kt, 53.0 t"):
        _trimmed(alt=8000.0, vcas=150.0, mass=53.0, cg=20.0)


def test_jsbsims_console_text_is_kept_off_the_console_and_named_in_a_failed_trim(capsys):
    # JSBSim's trim writes its search notes on its console (sys.stdout, from C++); at
    # 35 000 ft, 250 kt, 60 t and 10 % MAC the 737 cannot reach the speed, and says so
    with pytest.raises(F.JsbsimRunError) as failed:
        _trimmed(alt=35000.0, vcas=250.0, mass=60.0, cg=10.0)
    assert "(JSBSim said: Sorry, udot doesn't appear to be trimmable" in str(failed.value)
    # nothing of it reached the console, and the console works again afterwards
    print("after the trim")
    assert capsys.readouterr().out == "after the trim\n"


def test_the_console_is_kept_for_the_calling_thread_only(capsys):
    import threading

    other = threading.Thread(target=print, args=("another thread's line",))
    with F.jsbsim_console() as outer:
        print("outer", end=" ")
        with F.jsbsim_console() as inner:
            print("inner", end="")
        other.start()
        other.join()
        print("again", end="")
    print("console")
    assert (outer, inner) == (["outer again"], ["inner"])
    assert capsys.readouterr().out == "another thread's line\nconsole\n"


def test_a_missing_jsbsim_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "jsbsim", None)
    with pytest.raises(F.JsbsimMissingError, match=r'pip install -e "\.\[jsbsim\]"'):
        F.jsbsim_module()
    from campaign.cli.commands import main
    assert main(["simulate", "--plant", "jsbsim", "--surface", "aileron"]) == 2


def test_unknown_aircraft_lists_the_known_ones():
    with pytest.raises(ValueError, match=r"unknown JSBSim aircraft 'B747'.*; allowed: 737"):
        JsbsimPlant(aircraft="B747")


def _one_step_error(manoeuvre, seed):
    """RMS over a 40 s calm-air fault-free run of the design model's one-step prediction
    error of each state (lpv.STATES) [deg or deg/s]: x_k+1 − (Φ·x_k + Γ·u_k + Γ₁·Δu_k) with
    JSBSim's own states and the surfaces it flew."""
    jp = prepare_jsbsim(_runs(manoeuvre, seed=seed, duration_s=40.0), turbulence=None)
    model = F.design_model(jp.fdms)
    traj = integrate_jsbsim(jp)
    phi, gam, ramp = lpv.discretise_ramp(model, jp.base.ts)
    x = traj.states[:, 0, :]                                   # (7, T)
    u = np.zeros((lpv.N_INPUTS, x.shape[1]))
    u[:lpv.N_SURFACES] = traj.surfaces[:, 0, :] - np.radians(jp.base.trim_deg)[:, :1]
    pred = (phi[0] @ x[:, :-1] + gam[0] @ u[:, :-1]
            + ramp[0] @ (u[:lpv.N_SURFACES, 1:] - u[:lpv.N_SURFACES, :-1]))
    return np.degrees(np.sqrt(((x[:, 1:] - pred) ** 2).mean(axis=1)))


@pytest.mark.slow
def test_the_design_model_is_not_the_plant():
    """JSBSim's linearisation at the trim point (speed held: the laws' design model)
    predicts one step of a fault-free cruise better than one of a fault-free turn, in every
    state: the 30° bank (θ̇ = q·cos φ − r·sin φ, gravity along the wing), the speed and the
    nonlinear aerodynamics of the turn are outside it. Measured (mdeg, mdeg/s; seeds 0, 5
    and 11, docs/aircraft.md §9): cruise α 0.011, θ 0.020, β 0.0014, φ 0.0016; turn α
    1.3–1.8, θ 2.8–4.0, β 0.33–0.52, φ 0.11; r the closest, 0.060 against 0.10–0.14."""
    for seed in (0, 5):
        cruise, turn = _one_step_error("cruise", seed), _one_step_error("turn_coordination", seed)
        assert (turn > 1.3 * cruise).all(), (cruise, turn)
        big = [lpv.IA, lpv.ITH, lpv.IB, lpv.IPHI]
        assert (turn[big] > 10.0 * cruise[big]).all(), (cruise, turn)
        # near trim the model is close: a cruise step to within 0.001° (0.001°/s)
        assert cruise.max() < 1e-3


def test_a_run_is_a_function_of_its_row():
    """A run simulated alone or in a block of three gives the same series, bit for bit."""
    runs = _runs("turn_coordination", "disconnection", n=3, duration_s=12.0)
    plant = JsbsimPlant(turbulence="moderate")
    block, _ = plant.simulate(runs)
    alone, _ = plant.simulate(runs.iloc[[1]].reset_index(drop=True))
    np.testing.assert_array_equal(block.rod_com[1], alone.rod_com[0])
    np.testing.assert_array_equal(block.aircraft["phi"][1], alone.aircraft["phi"][0])
    assert not np.array_equal(block.aircraft["phi"][0], block.aircraft["phi"][1])


def _moments(f):
    """Rolling and yawing moment derivatives of an FDM's linearisation, rows (L, N), columns
    (β, δa, δr) [ft·lbf per rad or per command unit]: its (ṗ, ṙ) rows times the inertia
    matrix [[Ixx, Ixz], [Ixz, Izz]] (JSBSim's sign of Ixz)."""
    x, u = f.lin_x, f.lin_u
    rows = [x.index("P"), x.index("R")]
    acc = np.column_stack([f.lin_A[rows, x.index("Beta")], f.lin_B[rows, u.index("DaCmd")],
                           f.lin_B[rows, u.index("DrCmd")]])
    ix, iz, ixz = (f.fdm[f"inertia/{k}-slugs_ft2"] for k in ("ixx", "izz", "ixz"))
    return np.array([[ix, ixz], [ixz, iz]]) @ acc


def test_a_coefficient_error_scales_its_axis_and_no_other():
    """[CHEN] Table 2's error d on the rolling moment multiplies every function of JSBSim's
    ROLL axis by 1 + d: the rolling moment per aileron and per rudder by 1.05 for d = +0.05,
    the yawing moment per sideslip and per rudder not at all. (L_β moves by 3 % only: part
    of it is the side force acting below the CG, which belongs to the SIDE axis.) The lateral
    errors do not move the wings-level trim, so both linearisations are taken at the same
    state; tolerance 1e-6, that of FGLinearization's finite differences (the two trims agree
    to 1e-9, measured). d = 0 gives the file's aircraft bit for bit."""
    nominal, zero, rolled = _trimmed(), F.Fdm(MODEL, 0.01), F.Fdm(MODEL, 0.01)
    zero.trim(28000.0, 280.0, 47.0, 20.0, aero={c: 0.0 for c in F.AERO_AXES.values()})
    rolled.trim(28000.0, 280.0, 47.0, 20.0, aero={"cl": 0.05})
    np.testing.assert_array_equal(zero.lin_A, nominal.lin_A)
    np.testing.assert_array_equal(zero.lin_B, nominal.lin_B)
    ratio = _moments(rolled) / _moments(nominal)
    np.testing.assert_allclose(ratio[0, 1:], [1.05, 1.05], rtol=1e-6)
    np.testing.assert_allclose(ratio[1, [0, 2]], [1.0, 1.0], rtol=1e-6)
    assert 1.01 < ratio[0, 0] < 1.05
    assert rolled.alpha0 == pytest.approx(nominal.alpha0, abs=1e-9)


def test_a_lift_error_is_trimmed_at_a_lower_angle_of_attack():
    """+5 % on the lift coefficient: the same weight is carried at about 1/1.05 of the
    angle of attack measured from zero lift (the 737's lift is nearly linear in α there;
    measured 2.37° → 2.13°, the zero-lift α about −2.4°, est. from the two)."""
    nominal, lifted = _trimmed(), F.Fdm(MODEL, 0.01)
    lifted.trim(28000.0, 280.0, 47.0, 20.0, aero={"cz": 0.05})
    a0, a1 = np.degrees(nominal.alpha0), np.degrees(lifted.alpha0)
    assert a1 < a0 - 0.15
    zero_lift = (a1 * 1.05 - a0) / 0.05            # α_0L from (a0 − α_0L) = 1.05 (a1 − α_0L)
    assert -6.0 < zero_lift < 0.0


def test_an_unknown_coefficient_is_refused():
    with pytest.raises(ValueError, match="unknown aerodynamic coefficient 'cq'"):
        F.Fdm(MODEL, 0.01).trim(28000.0, 280.0, 47.0, 20.0, aero={"cq": 0.05})


def test_the_laws_know_the_measured_point_not_the_truth():
    """The laws' gains are placed on the nominal 737 trimmed at the run's measured point: a
    run whose aerodynamic errors alone differ gets the same gains, bit for bit, and so does a
    run whose true point differs under the same measurements; a measurement error changes
    them (docs/aircraft.md §9.1, as on the aircraft plant)."""
    base = _runs("cruise", duration_s=1.0)
    aero = base.copy()
    for c in ("d_cz", "d_cm", "d_cl", "d_cn"):
        aero[c] = 0.04
    measured = base.copy()
    measured["d_vcas"] = -0.02         # the default point is the 737's fastest: not above
    g = {name: prepare_jsbsim(r, turbulence=None).base.gains
         for name, r in (("base", base), ("aero", aero), ("measured", measured))}
    for field in ("k_n", "k_q", "L_da", "N_dr"):
        np.testing.assert_array_equal(getattr(g["aero"], field), getattr(g["base"], field))
        assert not np.array_equal(getattr(g["measured"], field), getattr(g["base"], field))
    # the plant itself flies with the errors: its trimmed α is not the nominal one
    jp_base, jp_aero = prepare_jsbsim(base, turbulence=None), prepare_jsbsim(aero, turbulence=None)
    assert jp_aero.fdms[0].alpha0 != jp_base.fdms[0].alpha0
    assert jp_aero.base.airframe == "jsbsim:737"


def test_the_gains_are_scheduled_within_the_aircrafts_ranges():
    """A measured point outside the 737's ranges (a 41 t aircraft measured 10 % light, below
    its 37.6 t empty weight; 10 % above its highest speed) is held at the range's end, as a
    gain schedule's lookup holds at its end breakpoints; one inside is kept as measured."""
    measured = {"alt_ft": np.array([20000.0, 40000.0]), "vcas_kt": np.array([250.0, 319.0]),
                "mass_t": np.array([36.9, 45.0]), "cg_pct": np.array([20.0, 8.0])}
    got = F.scheduled_point(measured, MODEL)
    np.testing.assert_array_equal(got["alt_ft"], [20000.0, MODEL.alt_ft[1]])
    np.testing.assert_array_equal(got["vcas_kt"], [250.0, MODEL.vcas_kt[1]])
    np.testing.assert_array_equal(got["mass_t"], [MODEL.mass_t[0], 45.0])
    np.testing.assert_array_equal(got["cg_pct"], [20.0, MODEL.cg_pct[0]])
    assert MODEL.mass_t[0] * 1000.0 / F.LB_KG > MODEL.empty_lbs     # the lowest is flyable
