"""One JSBSim flight-dynamics model per run: load, trim, surfaces, linearisation.

What is JSBSim's (its package data, ``jsbsim.get_default_root_dir()``): the aircraft's
nonlinear 6-DOF equations, its table-driven aerodynamics, its engines, atmosphere, trim
(``simulation/do_simple_trim``, full trim) and linearisation (``jsbsim.FGLinearization``).
What is ours: the flight point each run trims at (:func:`flight_point`), how our seven
surfaces become the aircraft's three primary controls (:data:`SURFACE_MAP`), the gusts,
and the reduced design model (:func:`design_model`).

Surfaces. The 737 model's aerodynamics read ``fcs/elevator-pos-rad``,
``fcs/left-aileron-pos-rad`` (its rolling moment Clda; the right aileron is its mirror)
and ``fcs/rudder-pos-rad``, outputs of ``aerosurface_scale`` components of its FCS that
map a summed command in [−1, 1] linearly to [−0.3, 0.3] rad (elevator) and [−0.35, 0.35]
rad (ailerons, rudder), with no actuator dynamics. A position δ is written as the command
δ/range with every trim command at zero (:func:`set_surfaces`), so the FCS outputs exactly
δ (checked by tests/test_jsbsim.py); the rudder channel adds the 737's yaw damper
(``velocities/r-aero-rad_sec`` × 1 above Mach 0.11, in command units), which is subtracted
from the rudder command (the value of that property when the step starts, the one its FCS
reads). Positions beyond those ranges are clipped by JSBSim's FCS.

Signs (from the linearisations, theirs and ours, at cruise): a positive elevator, left
aileron or rudder (ours, trailing edge down / left) gives q̇ < 0, ṗ > 0, ṙ < 0 on both
models, so JSBSim's elevator is the mean of our two elevators, its (left) aileron the mean
of our left ailerons' antisymmetric part, (δ_li + δ_lo − δ_ri − δ_ro)/4, and its rudder ours.
The 737 has no roll spoilers in its aerodynamics: our spoilers' order is not applied.
"""

from __future__ import annotations

import io
import sys
import threading
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from ..aircraft import lpv
from ..aircraft.data import LAYOUT
from ..atmosphere import G0_MS2, ISA_CONSTANTS
from ..envelope import FLIGHT_COLUMNS, TABLE1
from ..errors import InputError

#: Feet to metres (the atmosphere's, :data:`scenarios.atmosphere.ISA_CONSTANTS`), pounds
#: to kilograms (the international pound, exact) and pounds-force per square foot to pascals
#: (NIST SP 811, B.8: 47.880 26 Pa) for JSBSim's English-unit properties.
FT_M = ISA_CONSTANTS.ft_m
LB_KG = 0.45359237
PSF_PA = 47.880258

#: Largest |α| a trim is accepted at [deg] (est.: above the stall of a clean airliner wing,
#: about 12–14°; a trim beyond it is a converged solution no aircraft flies level at).
TRIM_ALPHA_MAX_DEG = 15.0

#: The extra that installs JSBSim.
EXTRA = 'pip install -e ".[jsbsim]"'


class JsbsimMissingError(InputError, ImportError):
    """JSBSim is not installed (exit code 2, naming the extra)."""


class JsbsimAircraftError(InputError, ValueError):
    """An aircraft name the JSBSim plant does not know (exit code 2, with the known ones)."""


class JsbsimRunError(RuntimeError):
    """A run JSBSim cannot fly: its trim fails, or the aircraft diverges or returns NaN. The
    engine records it as the run's ``error`` (status ``error``), never a crash."""


def jsbsim_module():
    """The ``jsbsim`` package, or :class:`JsbsimMissingError` naming the extra."""
    try:
        import jsbsim
    except ImportError as exc:
        raise JsbsimMissingError(
            f"the jsbsim plant needs the JSBSim package, which is not installed ({exc}); "
            f"fix: {EXTRA} (or pip install 'jsbsim>=1.3')") from None
    return jsbsim


@dataclass(frozen=True)
class AircraftModel:
    """A JSBSim aircraft as a plant: its name in JSBSim's data and how our run columns map
    onto its flight envelope (every range est., from the type's published limits)."""

    name: str
    beta: bool                    # its authors mark the model as beta (warned)
    alt_ft: tuple[float, float]   # altitude range [ft] our grid's 8 000–38 000 ft maps to
    vcas_kt: tuple[float, float]  # VCAS range [kt] our grid's 160–300 kt maps to
    mass_t: tuple[float, float]   # mass range [t] our 120–233 t maps to
    cg_pct: tuple[float, float]   # CG range [% MAC] our 17–41 % maps to
    empty_lbs: float              # its empty weight in its file [lb]
    tanks: int                    # fuel tanks in its file (filled in equal shares)
    ranges_rad: tuple[float, float, float]   # FCS ranges: elevator, aileron, rudder [rad]
    yaw_damper: bool              # rudder channel adds r_aero above Mach 0.11


#: The aircraft a JSBSim plant can fly. 737: empty weight 83 000 lb and three tanks of
#: 10 200 + 10 200 + 15 000 lb (JSBSim's 737.xml), so 37.6–53.7 t; we use 41–53 t (est.). CG:
#: the 737's certified range is about 6–33 % MAC; 10–30 % (est.). Altitude: its ceiling
#: 37 000 ft (type data; est.).
AIRCRAFT: dict[str, AircraftModel] = {
    "737": AircraftModel(name="737", beta=False, alt_ft=(8000.0, 33000.0),
                         vcas_kt=(205.0, 290.0), mass_t=(41.0, 53.0),
                         cg_pct=(10.0, 30.0), empty_lbs=83000.0, tanks=3,
                         ranges_rad=(0.3, 0.35, 0.35), yaw_damper=True),
}

#: Our grid's ranges ([CHEN] Table 1, :data:`scenarios.envelope.TABLE1`) that
#: :func:`flight_point` maps from.
_GRID = {c: (min(TABLE1[c]), max(TABLE1[c])) for c in TABLE1.columns}


def aircraft_model(name: str) -> AircraftModel:
    if name not in AIRCRAFT:
        from ..catalog import suggest

        raise JsbsimAircraftError("unknown JSBSim aircraft "
                                  f"{name!r}{suggest(name, list(AIRCRAFT))}; "
                         f"allowed: {', '.join(AIRCRAFT)}")
    return AIRCRAFT[name]


def flight_point(alt_ft, vcas_kt, mass_t, cg_pct, model: AircraftModel) -> dict:
    """The run's flight point on the JSBSim aircraft: altitude, VCAS, mass and CG each mapped
    linearly from our grid's range ([CHEN] Table 1) to the aircraft's (:data:`AIRCRAFT`), so
    that a point's place in our envelope is its place in the 737's."""
    def lin(v, key, to):
        lo, hi = _GRID[key]
        return to[0] + (np.asarray(v, float) - lo) / (hi - lo) * (to[1] - to[0])

    return {"alt_ft": lin(alt_ft, "alt_ft", model.alt_ft),
            "vcas_kt": lin(vcas_kt, "vcas_kt", model.vcas_kt),
            "mass_t": lin(mass_t, "mass_t", model.mass_t),
            "cg_pct": lin(cg_pct, "cg_pct", model.cg_pct)}


#: The [CHEN] Table 2 coefficient (:data:`scenarios.envelope.AERO_COEFFICIENTS`) of each
#: of JSBSim's aerodynamic axes. JSBSim's forces are in wind axes (drag, side force, lift),
#: [CHEN]'s coefficients in body axes; at the trimmed α of 1–6° the two sets of axes are
#: within 6° of each other, so each force axis takes the draw of its body-axis coefficient
#: (est.).
AERO_AXES: dict[str, str] = {"DRAG": "cx", "SIDE": "cy", "LIFT": "cz", "ROLL": "cl",
                             "PITCH": "cm", "YAW": "cn"}
#: The property that scales one coefficient (1 + d), by coefficient name.
AERO_SCALE = "fdd/aero-scale/{}"

def scheduled_point(measured: dict, model: AircraftModel) -> dict:
    """The point the flight computer places its gains at from the *measured* one (``alt_ft``,
    ``vcas_kt``, ``mass_t``, ``cg_pct`` arrays on the JSBSim aircraft): each coordinate held
    within the aircraft's range (:data:`AIRCRAFT`), as a gain schedule's table lookup holds
    at its end breakpoints (JSBSim's own tables do the same). [CHEN] Table 2's ±10 % mass
    error puts a 41 t 737 at 36.9 t, below its 37.6 t empty weight: a point no FDM can trim
    and no mass estimate would give."""
    return {c: np.clip(np.asarray(measured[c], float), *getattr(model, c))
            for c in FLIGHT_COLUMNS}


#: Per process: the folder holding the sanitised copy of each aircraft's file.
_SANITISED: dict[str, str] = {}


def sanitised_aircraft_dir(model: AircraftModel, root: str) -> str:
    """A folder (per process, under the system's temporary folder) holding the JSBSim
    aircraft file of *model* as the plant loads it: without its top-level ``<input>`` and
    ``<output>`` elements, and with one scale factor per [CHEN] Table 2 coefficient.

    Sockets: JSBSim's 737.xml declares ``<input port="5137"/>`` and a QTJSBSIM input on
    port 5139: loaded as shipped, every FDM would open listening TCP and UDP sockets through
    which anyone who reaches them could set the model's properties (docs/security.md).

    Coefficient errors: every function of an aerodynamic axis is a product (checked here);
    the property ``fdd/aero-scale/<c>`` (declared with value 1, :data:`AERO_AXES`) is added
    to each product of its axis, so that axis's whole coefficient is (1 + d) times the
    file's when the run sets it to 1 + d ([CHEN] Table 2, docs/aircraft.md §9.1). At 1 the
    products are unchanged bit for bit (x·1 = x). Nothing else of the file changes: the
    aerodynamic tables, FCS, mass and engines are JSBSim's (its engines are still read from
    JSBSim's own engine folder)."""
    if model.name in _SANITISED:
        return _SANITISED[model.name]
    import atexit
    import shutil
    import tempfile
    import xml.etree.ElementTree as ET
    from pathlib import Path

    src = Path(root) / "aircraft" / model.name / f"{model.name}.xml"
    tree = ET.parse(src)
    top = tree.getroot()
    for child in [c for c in top if c.tag in ("input", "output")]:
        top.remove(child)
    _add_aero_scales(top.find("aerodynamics"), src)
    folder = Path(tempfile.mkdtemp(prefix="fdd-jsbsim-"))
    atexit.register(shutil.rmtree, folder, True)
    (folder / model.name).mkdir()
    tree.write(folder / model.name / f"{model.name}.xml", encoding="utf-8", xml_declaration=True)
    _SANITISED[model.name] = str(folder)
    return str(folder)


def _add_aero_scales(aero, src) -> None:
    """Declare the scale of each coefficient (value 1) and multiply every function of its
    axis by it (:func:`sanitised_aircraft_dir`); a function that is not a product, or an
    axis this plant does not know, is a :class:`JsbsimRunError` naming the file."""
    import xml.etree.ElementTree as ET

    for i, coefficient in enumerate(AERO_AXES.values()):
        declared = ET.Element("property", value="1.0")
        declared.text = AERO_SCALE.format(coefficient)
        aero.insert(i, declared)
    for axis in aero.findall("axis"):
        name = axis.get("name")
        if name not in AERO_AXES:
            raise JsbsimRunError(f"{src}: aerodynamic axis {name!r} is not one of "
                                 f"{list(AERO_AXES)}; its coefficient errors cannot be applied")
        for function in axis.findall("function"):
            body = [e for e in function if e.tag != "description"]
            if len(body) != 1 or body[0].tag != "product":
                raise JsbsimRunError(f"{src}: function {function.get('name')!r} of axis "
                                     f"{name} is not a product; its coefficient error cannot "
                                     "be applied")
            ET.SubElement(body[0], "property").text = AERO_SCALE.format(AERO_AXES[name])


#: One redirection of ``sys.stdout`` at a time (:func:`jsbsim_console`); nested ones in
#: one thread within each other.
_CONSOLE = threading.RLock()


class _ThreadRouted:
    """``sys.stdout`` while a thread keeps JSBSim's console text: that thread's writes go
    to its buffer, every other thread's to the stream it replaced (a log line printed
    meanwhile is not swallowed)."""

    def __init__(self, real, thread: int, buffer: io.StringIO):
        self.real, self.thread, self.buffer = real, thread, buffer

    def write(self, text: str) -> int:
        if threading.get_ident() == self.thread:
            return self.buffer.write(text)
        return self.real.write(text)

    def __getattr__(self, name):
        return getattr(self.real, name)


@contextmanager
def jsbsim_console():
    """Keep what JSBSim writes on its console while the block runs, instead of printing it
    on the user's; yields a list that holds that text (one string) once the block has run.
    JSBSim's Python module writes its C++ console (``std::cout``) through ``sys.stdout``;
    its trim writes its search notes there ("Sorry, udot doesn't appear to be trimmable")
    even when the trim then succeeds, and a trim that fails carries them in its error
    (:meth:`Fdm.trim`). Only the calling thread's writes are kept."""
    held: list[str] = []
    with _CONSOLE:
        real = sys.stdout
        buffer = io.StringIO()
        sys.stdout = _ThreadRouted(real, threading.get_ident(), buffer)
        try:
            yield held
        finally:
            sys.stdout = real
            held.append(buffer.getvalue())


def _said(held: list[str]) -> str:
    """JSBSim's console text of a block, as one clause of an error ('' when it said
    nothing)."""
    text = " ".join(" ".join(held).split())
    return f" (JSBSim said: {text})" if text else ""


class Fdm:
    """One trimmed JSBSim model (one run)."""

    def __init__(self, model: AircraftModel, dt: float):
        jsbsim = jsbsim_module()
        self.model = model
        self.jsbsim = jsbsim
        jsbsim.FGJSBBase().debug_lvl = 0        # no start-up banner on stdout
        root = jsbsim.get_default_root_dir()
        exec_ = jsbsim.FGFDMExec(root)
        exec_.set_debug_level(0)
        exec_.set_aircraft_path(sanitised_aircraft_dir(model, root))
        if not exec_.load_model(model.name):
            raise JsbsimRunError(f"JSBSim could not load aircraft {model.name!r}")
        exec_.set_dt(dt)
        self.fdm = exec_
        self.dt = dt
        pm = exec_.get_property_manager()
        self._node = lambda name: pm.get_node(name)
        self.cbar_in = exec_["metrics/cbarw-ft"] * 12.0
        self.rp0_in = exec_["metrics/aero-rp-x-in"]

    def trim(self, alt_ft: float, vcas_kt: float, mass_t: float, cg_pct: float,
             aero: dict | None = None) -> None:
        """Trim in wings-level flight at the point, with the coefficient errors *aero*
        (coefficient → d, [CHEN] Table 2; None or a coefficient left out: 0), which the
        aircraft keeps for the rest of its flight. Mass: the fuel in equal shares of the
        tanks (``propulsion/tank[i]/contents-lbs``) above the empty weight. CG: the
        aerodynamic reference point (``metrics/aero-rp-x-in``, taken as 25 % MAC, est.)
        placed (cg − 25 %)·c̄ ahead of the model's CG, which moves every aerodynamic moment
        as that CG shift would (the inertia stays the file's). :class:`JsbsimRunError`
        when JSBSim cannot trim."""
        f, m = self.fdm, self.model
        for coefficient, d in (aero or {}).items():
            if coefficient not in AERO_AXES.values():
                raise ValueError(f"unknown aerodynamic coefficient {coefficient!r}; allowed: "
                                 f"{', '.join(AERO_AXES.values())}")
            f[AERO_SCALE.format(coefficient)] = 1.0 + float(d)
        fuel = mass_t * 1000.0 / LB_KG - m.empty_lbs
        for i in range(m.tanks):
            f[f"propulsion/tank[{i}]/contents-lbs"] = fuel / m.tanks
        f["ic/h-sl-ft"] = alt_ft
        f["ic/vc-kts"] = vcas_kt
        f["ic/gamma-deg"] = 0.0
        f["ic/psi-true-deg"] = 0.0
        f["atmosphere/turb-type"] = 0
        f.run_ic()
        f["metrics/aero-rp-x-in"] = f["inertia/cg-x-in"] - (cg_pct - 25.0) / 100.0 * self.cbar_in
        f["propulsion/set-running"] = -1
        where = (f"{alt_ft:.0f} ft, {vcas_kt:.0f} kt, {mass_t:.1f} t, CG {cg_pct:.1f} % MAC "
                 f"on the JSBSim {m.name}")
        with jsbsim_console() as said:
            try:
                f["simulation/do_simple_trim"] = 1
                failure = None
            except Exception as exc:  # noqa: BLE001 - JSBSim's TrimFailureError and kin
                failure = exc
        if failure is not None:
            raise JsbsimRunError(f"trim failed at {where}: {failure}{_said(said)}") from None
        self.trim_surfaces = np.array([f["fcs/elevator-pos-rad"], f["fcs/left-aileron-pos-rad"],
                                       f["fcs/rudder-pos-rad"]])
        if (not np.isfinite(self.trim_surfaces).all()
                or abs(f["aero/alpha-deg"]) > TRIM_ALPHA_MAX_DEG):
            raise JsbsimRunError(f"trim failed at {where}: α {f['aero/alpha-deg']:.1f}°"
                                 f"{_said(said)}")
        self.alpha0 = f["aero/alpha-rad"]
        self.theta0 = f["attitude/theta-rad"]
        self.mach = f["velocities/mach"]
        self.qbar_pa = f["aero/qbar-psf"] * PSF_PA
        self.tas_ms = f["velocities/vt-fps"] * FT_M
        self.vc0_kt = f["velocities/vc-kts"]
        self.throttle0 = f["fcs/throttle-cmd-norm[0]"]
        self._linearise()
        # trim and FGLinearization leave the integration suspended (dt 0): resume it
        f.resume_integration()
        f.set_dt(self.dt)
        if f.integration_suspended() or f.holding():
            raise JsbsimRunError(f"JSBSim kept its integration suspended after the trim at {where}")
        for name in ("fcs/pitch-trim-cmd-norm", "fcs/roll-trim-cmd-norm", "fcs/yaw-trim-cmd-norm"):
            f[name] = 0.0
        self._cmd = [self._node(n) for n in ("fcs/elevator-cmd-norm", "fcs/aileron-cmd-norm",
                                             "fcs/rudder-cmd-norm")]
        self._r_aero = self._node("velocities/r-aero-rad_sec")
        self._gust = [self._node(f"atmosphere/gust-{d}-fps") for d in ("north", "east", "down")]
        self._read = [self._node(n) for n in READ]
        self._throttle = [self._node(f"fcs/throttle-cmd-norm[{i}]") for i in range(2)]

    def set_throttle(self, value: float) -> None:
        """Both engines' throttle command (0–1)."""
        for node in self._throttle:
            node.set_double_value(value)

    def _linearise(self) -> None:
        with jsbsim_console():
            lin = self.jsbsim.FGLinearization(self.fdm)
        self.lin_A = np.array(lin.system_matrix)
        self.lin_B = np.array(lin.input_matrix)
        self.lin_x = tuple(lin.x_names)
        self.lin_u = tuple(lin.u_names)

    def set_surfaces(self, elevator: float, aileron: float, rudder: float) -> None:
        """Write JSBSim's three surface positions [rad] for the next step (module docstring)."""
        re, ra, rr = self.model.ranges_rad
        self._cmd[0].set_double_value(elevator / re)
        self._cmd[1].set_double_value(aileron / ra)
        yd = (self._r_aero.get_double_value() if (self.model.yaw_damper and self.mach > 0.11)
              else 0.0)
        self._cmd[2].set_double_value(rudder / rr - yd)

    def set_gust_ned(self, north: float, east: float, down: float) -> None:
        """JSBSim's gust [ft/s] along the local NED axes (:func:`body_to_ned`)."""
        self._gust[0].set_double_value(north)
        self._gust[1].set_double_value(east)
        self._gust[2].set_double_value(down)

    def read(self) -> np.ndarray:
        """The properties of :data:`READ`, now."""
        self.values = np.array([n.get_double_value() for n in self._read])
        return self.values

    def step(self) -> None:
        if not self.fdm.run():
            raise JsbsimRunError("JSBSim stopped the simulation")


#: Properties read every period, in this order.
READ = ("aero/alpha-rad", "velocities/q-rad_sec", "attitude/theta-rad", "aero/beta-rad",
        "velocities/p-rad_sec", "velocities/r-rad_sec", "attitude/phi-rad", "accelerations/Nz",
        "accelerations/Ny", "attitude/psi-rad", "position/h-sl-ft", "velocities/vt-fps",
        "velocities/vc-kts")
(READ_ALPHA, READ_Q, READ_THETA, READ_BETA, READ_P, READ_R, READ_PHI, READ_NZ, READ_NY,
 READ_PSI, READ_H, READ_VT, READ_VC) = range(len(READ))


def body_to_ned(phi, theta, psi, body) -> np.ndarray:
    """Body-axis vectors *body* (3, n) in local NED axes (3, n), each run with its Euler
    angles (arrays (n,), rad): the 3-2-1 rotation (Etkin & Reid eq. 4.5,4)."""
    cf, sf, ct, st, cp, sp = (np.cos(phi), np.sin(phi), np.cos(theta), np.sin(theta),
                              np.cos(psi), np.sin(psi))
    x, y, z = body
    return np.array([ct * cp * x + (sf * st * cp - cf * sp) * y + (cf * st * cp + sf * sp) * z,
                     ct * sp * x + (sf * st * sp + cf * cp) * y + (cf * st * sp - sf * cp) * z,
                     -st * x + sf * ct * y + cf * ct * z])


#: Our states (lpv.STATES: α, q, θ, β, p, r, φ) among FGLinearization's
#: (Vt, Alpha, Theta, Q, Beta, Phi, P, Psi, R, …).
_LIN_STATES = ("Alpha", "Q", "Theta", "Beta", "P", "R", "Phi")
_LIN_INPUTS = ("DeCmd", "DaCmd", "DrCmd")


def jsbsim_surface_weights() -> np.ndarray:
    """(3, 7): JSBSim's elevator, aileron and rudder positions per rad of each of our seven
    surfaces (:data:`scenarios.aircraft.data.LAYOUT` order; module docstring)."""
    w = np.zeros((3, len(LAYOUT.names)))
    for j, (name, kind) in enumerate(zip(LAYOUT.names, LAYOUT.actuator)):
        if kind == "elevator":
            w[0, j] = 0.5
        elif kind == "aileron":
            w[1, j] = 0.25 if name.startswith("left") else -0.25
        else:
            w[2, j] = 1.0
    return w


SURFACE_MAP = jsbsim_surface_weights()


def design_model(fdms: list[Fdm]) -> lpv.ContinuousModel:
    """JSBSim's linearisations at each run's trim point in the layout of
    :class:`scenarios.aircraft.lpv.ContinuousModel` (the laws are designed on it):
    FGLinearization's A and B reduced to our seven states with the airspeed held (as our
    model holds it: no phugoid), the yaw damper taken out of A (it linearises the FCS with
    the aircraft: the rudder column per unit command times the damper's gain 1 per rad/s
    of r, subtracted from the r column), its B per command unit turned into per rad of each
    of our surfaces (:data:`SURFACE_MAP` and the FCS ranges), the spoiler column zero (no
    spoilers on the 737 model), the gust columns the α and β columns of A in the α, q and β,
    p, r rows (a gust angle acts on the aerodynamics as the air-relative angle does, est.:
    JSBSim's gust enters as wind), and the load factors of lpv.continuous_model."""
    n = len(fdms)
    A = np.zeros((n, lpv.N_STATES, lpv.N_STATES))
    B = np.zeros((n, lpv.N_STATES, lpv.N_INPUTS))
    V = np.empty(n)
    for i, f in enumerate(fdms):
        xi = [f.lin_x.index(s) for s in _LIN_STATES]
        ui = [f.lin_u.index(s) for s in _LIN_INPUTS]
        a = f.lin_A[np.ix_(xi, xi)].copy()
        b = f.lin_B[np.ix_(xi, ui)] / np.array(f.model.ranges_rad)      # per rad of JSBSim's
        if f.model.yaw_damper and f.mach > 0.11:
            a[:, lpv.IR] -= f.lin_B[np.ix_(xi, [ui[2]])][:, 0]
        A[i] = a
        B[i, :, :lpv.N_SURFACES] = b @ SURFACE_MAP
        B[i, [lpv.IA, lpv.IQ], lpv.I_GUST_ALPHA] = a[[lpv.IA, lpv.IQ], lpv.IA]
        B[i, [lpv.IB, lpv.IP, lpv.IR], lpv.I_GUST_BETA] = a[[lpv.IB, lpv.IP, lpv.IR], lpv.IB]
        V[i] = f.tas_ms
    C = np.zeros((n, 2, lpv.N_STATES))
    D = np.zeros((n, 2, lpv.N_INPUTS))
    k = (V / G0_MS2)[:, None]
    C[:, 0, :] = -k * A[:, lpv.IA, :]
    C[:, 0, lpv.IQ] += k[:, 0]
    D[:, 0, :] = -k * B[:, lpv.IA, :]
    C[:, 1, :] = k * A[:, lpv.IB, :]
    C[:, 1, lpv.IR] += k[:, 0]
    C[:, 1, lpv.IPHI] -= 1.0
    D[:, 1, :] = k * B[:, lpv.IB, :]
    return lpv.ContinuousModel(A=A, B=B, C=C, D=D, tas_ms=V)


def airframe_name(model: AircraftModel) -> str:
    """The JSBSim aircraft as :attr:`scenarios.signals.Signals.airframe` names it."""
    return f"jsbsim:{model.name}"


def nominal_models(model: AircraftModel, points: dict, dt: float) -> lpv.ContinuousModel:
    """:func:`design_model` of *model* without coefficient errors, trimmed at each point of
    *points* (``alt_ft``, ``vcas_kt``, ``mass_t``, ``cg_pct`` arrays on the JSBSim aircraft),
    each on a new FDM (a trim's result must not depend on an earlier one: a re-trimmed FDM
    differs from a new one by about 1e-9 in its linearisation, measured). About 0.15 CPU-s
    a point (docs/aircraft.md §9.5); a point that cannot trim raises
    :class:`JsbsimRunError` naming it."""
    values = np.broadcast_arrays(*(np.asarray(points[c], float) for c in FLIGHT_COLUMNS))
    fdms = []
    for i in range(values[0].size):
        f = Fdm(model, dt)
        f.trim(*(float(v.flat[i]) for v in values))
        fdms.append(f)
    return design_model(fdms)
