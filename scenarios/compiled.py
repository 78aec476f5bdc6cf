"""Compiled kernels of the hot loops (numba), with the NumPy code as their reference.

The closed-loop time loop of :func:`scenarios.simulate.integrate` and the nominal-model
recursions of the position monitor (one model, or a band of them at several hinge moments
integrated together: :func:`servo_band_step`) advance every run step by step; in NumPy each step is
a few dozen array operations on arrays of shape ``(n_runs,)``, so the interpreter overhead
dominates. The kernels here run the same recursions compiled (``@njit(nogil=True,
cache=True)``), on a block of runs at once: the outer loop goes over the steps, the inner
loop over the runs of the block, whose computations are independent (so the processor
overlaps them); a run computed alone equals the same run inside any block.

Same equations, same order of floating-point operations as the NumPy reference
(:mod:`scenarios.servo`, :mod:`scenarios.simulate`): no ``fastmath`` (it would reorder
sums and contract multiply–adds), ``error_model="numpy"`` (a division by zero gives ±inf or
NaN as in NumPy instead of raising, and costs no check per division), ``x ** 3`` written as
``x ** 3.0`` so that both call the C library ``pow``, and the stops and saturations as
``min(max(·))`` like ``np.clip``. The tests check compiled against NumPy bit for bit
(tests/scenarios_tests/test_kernels.py).

Engine selection
----------------
``"compiled"`` (default) or ``"numpy"`` (the reference). :func:`simulate` takes an explicit
``engine=`` argument; detectors read :func:`current_engine`, which the campaign runner sets
for the duration of a chunk with :func:`use_engine` (from the ``[runner] engine`` key of the
campaign file). When numba cannot be imported, ``"compiled"`` falls back to NumPy.

Adding a detector recursion
---------------------------
A detector with its own recursion writes it as an ``@njit(nogil=True, cache=True,
error_model="numpy")`` function of plain arrays in its own module, calls the scalar plant functions
of this module from it (:func:`rod_rate_1`, :func:`rk4_step_1`) with the parameter vector of
:func:`plant_matrix`, keeps its NumPy version as the reference, dispatches on :func:`current_engine`
and lists its kernel with :func:`register_warmup` (with ``kernels=`` its compiled functions) so that
:func:`warm_up` compiles it before the campaign starts and says so when its cache is cold.
Importing the detector module registers it (the built-in detectors are imported by the
registry).
"""

from __future__ import annotations

import contextvars
import hashlib
import importlib.util
import json
import math
import os
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from .signals import read_only_view

try:  # numba is a core dependency; the guard only keeps the NumPy reference usable without it
    from numba import njit

    HAVE_NUMBA = True
except ImportError:  # pragma: no cover - exercised only on installations without numba
    HAVE_NUMBA = False

    def njit(*args, **kwargs):
        def wrap(func):
            return func
        return wrap(args[0]) if args and callable(args[0]) else wrap

ENGINES = ("compiled", "numpy")
_ENGINE: contextvars.ContextVar[str] = contextvars.ContextVar("fdd_engine", default="compiled")

_MM_PER_M = 1000.0

#: Order of the per-run plant parameters in :func:`plant_matrix` (fields of PlantArrays).
PLANT_FIELDS = ("K", "Kci", "i_max", "SdP", "SdP_ref", "Ka", "r_mm", "x_min", "x_max",
                "hm_delta", "hm_0")
(P_K, P_KCI, P_IMAX, P_SDP, P_SDPREF, P_KA, P_R, P_XMIN, P_XMAX, P_HMD, P_HM0) = range(11)
#: Row of :func:`plant_fields` after the fields: the lever arm in metres, r/1000 [m],
#: computed once (the same IEEE division the rate law would make at every evaluation).
P_RM = len(PLANT_FIELDS)
#: Rows of :func:`plant_fields`.
FIELD_ROWS = P_RM + 1


def check_engine(engine: str) -> str:
    """Return *engine* if known, else raise ``ValueError`` naming the choices."""
    if engine not in ENGINES:
        raise ValueError(f"unknown engine {engine!r}; choose one of {', '.join(ENGINES)}")
    return engine


def current_engine() -> str:
    """The engine in effect: ``"compiled"`` unless :func:`use_engine` says otherwise (and
    ``"numpy"`` when numba is not installed)."""
    engine = _ENGINE.get()
    return engine if HAVE_NUMBA else "numpy"


def resolve_engine(engine: str | None) -> str:
    """*engine* when given (checked), else :func:`current_engine`."""
    if engine is None:
        return current_engine()
    check_engine(engine)
    return engine if HAVE_NUMBA else "numpy"


@contextmanager
def use_engine(engine: str):
    """Make *engine* the default of :func:`current_engine` inside the ``with`` block."""
    token = _ENGINE.set(check_engine(engine))
    try:
        yield
    finally:
        _ENGINE.reset(token)


def plant_matrix(plant) -> np.ndarray:
    """Per-run plant parameters as one C-contiguous (n_runs, 11) array, columns in the
    order of :data:`PLANT_FIELDS` (units as in :class:`scenarios.servo.PlantArrays`)."""
    return np.ascontiguousarray(np.stack([np.asarray(getattr(plant, f), dtype=float)
                                          for f in PLANT_FIELDS], axis=1))


# ---- scalar plant functions (docs/physics.md §3; scenarios.servo holds the NumPy reference) ------
@njit(nogil=True, cache=True, error_model="numpy")
def clip(v, lo, hi):
    """v limited to [lo, hi] (a select: no branch)."""
    return min(max(v, lo), hi)


@njit(nogil=True, cache=True, error_model="numpy")
def sign(v):
    """np.sign of a scalar: ±1, and ±0 or NaN as they are."""
    if v > 0.0:
        return 1.0
    if v < 0.0:
        return -1.0
    return v  # ±0 (and NaN) like np.sign


@njit(nogil=True, cache=True, error_model="numpy")
def rod_rate_1(x, i, p, loaded):
    """Rod speed ẋ [mm/s] of one run ([COMB] eq. 2, [CHEN] eq. 11, as
    :func:`scenarios.servo.rod_rate`); *p* is one row of :func:`plant_matrix`."""
    return rod_rate_known(x, i, p, loaded, False, 0.0)


@njit(nogil=True, cache=True, error_model="numpy")
def rod_rate_known(x, i, p, loaded, known, asin_x):
    """:func:`rod_rate_1` given, when *known*, ``asin_x`` = asin(x / r) already computed
    (the surface angle δ of the step): used when x/r lies inside the ±0.999 clip, where it
    is the very asin the rate law evaluates, so the result is the same bits with one
    ``asin`` call (the costliest operation of the step) fewer."""
    v0 = p[P_KCI] * i
    if loaded:
        r = p[P_R]
        q = x / r
        s = clip(q, -0.999, 0.999)
        cos_d = math.sqrt(1.0 - s * s)
        a = asin_x if (known and s == q) else math.asin(s)
        hm = p[P_HM0] + p[P_HMD] * a                       # hinge moment [N·m]
        f_aero = -hm / (r / _MM_PER_M * cos_d)               # rod force [N]
        ka = p[P_KA]
    else:
        f_aero = 0.0
        ka = 0.0
    num = p[P_SDP] - sign(i) * f_aero
    num = clip(num, 0.0, 2.0 * p[P_SDP])                    # stall at 0; aiding load capped
    v = v0 * math.sqrt(num / (p[P_SDPREF] + ka * v0 * v0))
    if x >= p[P_XMAX] and v > 0.0:                           # no motion further into a stop
        v = 0.0
    if x <= p[P_XMIN] and v < 0.0:
        v = 0.0
    return v


@njit(nogil=True, cache=True, error_model="numpy")
def rk4_step_1(x, i, p, loaded, h):
    """One RK4 step of the rod over *h* [s] with the current *i* [mA] held, inside the
    stops (as :func:`scenarios.servo.rk4_step`)."""
    return rk4_step_known(x, i, p, loaded, h, False, 0.0)


@njit(nogil=True, cache=True, error_model="numpy")
def rk4_step_known(x, i, p, loaded, h, known, asin_x):
    """:func:`rk4_step_1` whose first stage reuses ``asin_x`` = asin(x / r) when *known*
    (:func:`rod_rate_known`); the same bits."""
    k1 = rod_rate_known(x, i, p, loaded, known, asin_x)
    k2 = rod_rate_1(x + 0.5 * h * k1, i, p, loaded)
    k3 = rod_rate_1(x + 0.5 * h * k2, i, p, loaded)
    k4 = rod_rate_1(x + h * k3, i, p, loaded)
    x_new = x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return clip(x_new, p[P_XMIN], p[P_XMAX])


@njit(nogil=True, cache=True, error_model="numpy")
def float_step_1(delta, p, h, d_min, d_max):
    """Floating surface after a disconnection over *h* [s] (closed form of
    :func:`scenarios.servo.float_step`, docs/physics.md §5); angles [rad]."""
    d_f = -p[P_HM0] / p[P_HMD]
    e = delta - d_f
    r_m = p[P_R] / _MM_PER_M
    ka_si = p[P_KA] * _MM_PER_M ** 2.0
    cos_d = math.cos(delta)
    c = math.sqrt(abs(p[P_HMD]) / (ka_si * r_m ** 3.0 * cos_d ** 3.0))
    root = math.sqrt(abs(e)) - 0.5 * h * c
    m = max(root, 0.0)
    e_new = sign(e) * (m * m)
    return clip(d_f + e_new, d_min, d_max)


# ---- the closed-loop time loop (scenarios.simulate.integrate) --------------------------------
#: Rows of the per-block scratch array of :func:`integrate_block`.
_PLANT_WORK_ROWS = 16


@njit(nogil=True, cache=True, error_model="numpy")
def plant_rates(xs, cur, pf, r0, b, loaded, reuse, asin_x, s_buf, q_buf, a_buf, out):
    """:func:`rod_rate_known` for the runs ``r0 … r0 + b − 1`` into ``out[:b]`` [mm/s]:
    rod positions ``xs[:b]`` [mm], held currents ``cur[:b]`` [mA], parameters *pf* of
    :func:`plant_fields`, ``loaded[:b]`` (1.0 loaded, 0.0 disconnected); with *reuse*,
    ``asin_x[:b]`` = asin(x/r) stands for the rate law's asin wherever x/r is inside the
    clip (the surface angle of the step, as :func:`rk4_step_known`). The same expressions in
    the same order as the scalar functions, in three loops over the block: the clipped sine
    (packed), the C library's ``asin`` one by one, and the rest of the law (packed, the
    loaded/disconnected alternatives and the stops as selects)."""
    for t in range(b):
        q = xs[t] / pf[P_R, r0 + t]
        q_buf[t] = q
        s_buf[t] = clip(q, -0.999, 0.999)
    for t in range(b):
        s = s_buf[t]
        if reuse and loaded[t] != 0.0 and s == q_buf[t]:
            a_buf[t] = asin_x[t]
        else:
            a_buf[t] = math.asin(s)
    for t in range(b):
        r = r0 + t
        x = xs[t]
        i = cur[t]
        v0 = pf[P_KCI, r] * i
        s = s_buf[t]
        cos_d = math.sqrt(1.0 - s * s)
        hm = pf[P_HM0, r] + pf[P_HMD, r] * a_buf[t]           # hinge moment [N·m]
        f_loaded = -hm / (pf[P_RM, r] * cos_d)              # rod force [N]
        on = loaded[t] != 0.0
        f_aero = f_loaded if on else 0.0
        ka = pf[P_KA, r] if on else 0.0
        num = pf[P_SDP, r] - sign(i) * f_aero
        num = clip(num, 0.0, 2.0 * pf[P_SDP, r])
        v = v0 * math.sqrt(num / (pf[P_SDPREF, r] + ka * v0 * v0))
        v = 0.0 if (x >= pf[P_XMAX, r] and v > 0.0) else v
        v = 0.0 if (x <= pf[P_XMIN, r] and v < 0.0) else v
        out[t] = v


@njit(nogil=True, cache=True, error_model="numpy")
def integrate_block(x0, u_loop, plant, com_scale, com_bias, com_noise, com_add, com_osc, k_osc,
                    cur_add, cur_force, k_jam, jam_offset, k_disc, flags, ts, d_min, d_max,
                    rod_quant, xs, ds, icmd, iapp, ycom):
    """Closed loop of a batch of runs (docs/physics.md §2: acquire, i_k = sat(K·(u_k − y_k)), hold
    over the next period; RK4 plant step; faults of docs/physics.md §5 at step boundaries).

    *x0* (n,) is the initial rod order [mm]; *plant* the :func:`plant_fields` of
    the runs; the other inputs are (n, T) or (n,) as in
    :class:`scenarios.simulate.Prepared`; optional fault arrays are (n, T) when ``flags``
    says the batch has them, else may be empty. ``flags`` = (has com_add, has com_osc, has cur_add,
    has cur_force, any jam, any disconnection). *jam_offset* (n,) [mm] is the jump of an "offset"
    solid jam at its onset step (0: seized where it stands; docs/physics.md §5).
    Writes the outputs *xs*, *ds* [rad], *icmd*, *iapp*, *ycom* (n, T) in place.

    SIMD-friendly form: blocks of :data:`BLOCK` runs, steps outer, and every stage of a
    step one loop over the block without branches (faults as masks and selects; the RK4
    stages in :func:`plant_rates`); each run's arithmetic is that of the scalar functions
    (:func:`rk4_step_known`, :func:`float_step_1`), so a run computed alone equals the same
    run inside any block. A seized rod's RK4 result is computed and discarded (a select).
    """
    n, T = u_loop.shape
    has_com_add, has_com_osc, has_cur_add, has_cur_force, any_jam, any_disc = (
        flags[0], flags[1], flags[2], flags[3], flags[4], flags[5])
    x = np.empty(n)
    delta = np.empty(n)
    i_prev = np.zeros(n)
    y_hold = np.zeros(n)
    for r in range(n):
        x[r] = clip(x0[r], plant[P_XMIN, r], plant[P_XMAX, r])  # trimmed: x(0) = order
        delta[r] = math.asin(x[r] / plant[P_R, r])
    w = np.empty((_PLANT_WORK_ROWS, BLOCK))
    xb, cur, k1, k2, k3, k4, xst = w[0], w[1], w[2], w[3], w[4], w[5], w[6]
    s_buf, q_buf, a_buf, loaded = w[7], w[8], w[9], w[10]
    dl, i_new, y_b, xn = w[11], w[12], w[13], w[14]
    for b0 in range(0, n, BLOCK):
        b = min(b0 + BLOCK, n) - b0
        for k in range(T):
            # an "offset" solid jam: the rod jumps at its onset (faults.jam_onset_position)
            if any_jam:
                for t in range(b):
                    r = b0 + t
                    if k == k_jam[r] and jam_offset[r] != 0.0:
                        xr = clip(x[r] + jam_offset[r], plant[P_XMIN, r], plant[P_XMAX, r])
                        x[r] = xr
                        delta[r] = math.asin(xr / plant[P_R, r])
            for t in range(b):
                r = b0 + t
                xr = x[r]
                xb[t] = xr
                dl[t] = delta[r]
                # COM acquisition (acquire_com)
                y = xr * (1.0 + com_scale[r]) + com_bias[r] + com_noise[r, k]
                y = rod_quant * np.rint(y / rod_quant)
                if has_com_add:
                    y = y + com_add[r, k]
                if has_com_osc:
                    hold = y if k == k_osc[r] else y_hold[r]
                    y_hold[r] = hold
                    osc = com_osc[r, k]
                    y = hold + (0.0 if osc != osc else osc) if k >= k_osc[r] else y
                y_b[t] = y
                i_new[t] = clip(plant[P_K, r] * (u_loop[r, k] - y), -plant[P_IMAX, r],
                                 plant[P_IMAX, r])
                # applied current (applied_current)
                i_app = i_prev[r]
                if has_cur_add:
                    i_app = i_app + cur_add[r, k]
                if has_cur_force:
                    force = cur_force[r, k]
                    i_app = force if (force - force == 0.0) else i_app
                cur[t] = i_app
                loaded[t] = 0.0 if (any_disc and k >= k_disc[r]) else 1.0
            for t in range(b):
                r = b0 + t
                xs[r, k] = xb[t]
                ds[r, k] = dl[t]
                icmd[r, k] = i_new[t]
                iapp[r, k] = cur[t]
                ycom[r, k] = y_b[t]
            # RK4 over the period with the applied current held (rk4_step_known); while
            # loaded, delta = asin(x/r) of this very x: the first stage reuses it
            plant_rates(xb, cur, plant, b0, b, loaded, True, dl, s_buf, q_buf, a_buf, k1)
            for t in range(b):
                xst[t] = xb[t] + 0.5 * ts * k1[t]
            plant_rates(xst, cur, plant, b0, b, loaded, False, dl, s_buf, q_buf, a_buf, k2)
            for t in range(b):
                xst[t] = xb[t] + 0.5 * ts * k2[t]
            plant_rates(xst, cur, plant, b0, b, loaded, False, dl, s_buf, q_buf, a_buf, k3)
            for t in range(b):
                xst[t] = xb[t] + ts * k3[t]
            plant_rates(xst, cur, plant, b0, b, loaded, False, dl, s_buf, q_buf, a_buf, k4)
            for t in range(b):
                r = b0 + t
                x_new = xb[t] + (ts / 6.0) * (k1[t] + 2.0 * k2[t] + 2.0 * k3[t] + k4[t])
                x_new = clip(x_new, plant[P_XMIN, r], plant[P_XMAX, r])
                xn[t] = xb[t] if (any_jam and k >= k_jam[r]) else x_new   # seized rod
            for t in range(b):
                r = b0 + t
                if loaded[t] != 0.0:
                    delta[r] = math.asin(xn[t] / plant[P_R, r])
                else:
                    delta[r] = float_step_1(dl[t], plant[:, r], ts, d_min, d_max)
                x[r] = xn[t]
                i_prev[r] = i_new[t]


def integrate_compiled(p, sensors):
    """:func:`scenarios.simulate.integrate` through :func:`integrate_block`; returns the
    same :class:`scenarios.simulate.Trajectory`."""
    from .faults import NEVER
    from .acquisition import Trajectory

    n, T = p.u.shape
    fa, act = p.faults, p.act
    empty = np.zeros((0, 0))
    xs = np.empty((n, T))
    ds = np.empty((n, T))
    icmd = np.empty((n, T))
    iapp = np.empty((n, T))
    ycom = np.empty((n, T))

    def arr2(a):
        return empty if a is None else np.ascontiguousarray(a, dtype=float)

    flags = np.array([fa.com_add is not None, fa.com_osc is not None, fa.cur_add is not None,
                      fa.cur_force is not None, bool((fa.k_jam < NEVER).any()),
                      bool((fa.k_disc < NEVER).any())])
    integrate_block(
        np.ascontiguousarray(p.u[:, 0], dtype=float), np.ascontiguousarray(fa.u_loop, dtype=float),
        plant_fields(p.plant),
        np.ascontiguousarray(p.com_scale, dtype=float),
        np.ascontiguousarray(p.com_bias, dtype=float),
        np.ascontiguousarray(p.com_noise, dtype=float), arr2(fa.com_add), arr2(fa.com_osc),
        np.ascontiguousarray(fa.k_osc, dtype=np.int64), arr2(fa.cur_add), arr2(fa.cur_force),
        np.ascontiguousarray(fa.k_jam, dtype=np.int64),
        np.ascontiguousarray(fa.jam_offset, dtype=float),
        np.ascontiguousarray(fa.k_disc, dtype=np.int64), flags, float(p.ts),
        float(np.radians(act.stop_min_deg)), float(np.radians(act.stop_max_deg)),
        float(sensors.rod_quant_mm), xs, ds, icmd, iapp, ycom)
    return Trajectory(x=xs, delta=ds, i_cmd=icmd, i_app=iapp, y_com=ycom)


# ---- a run's sensor errors from its own generator (scenarios.acquisition.sensor_draws) -------
@njit(nogil=True, cache=True)
def sensor_draws_1(rng, uniforms, noise, i):
    """Run *i*'s sensor draws from its generator *rng* (a ``numpy.random.Generator``), in
    the order of :func:`scenarios.acquisition.sensor_draws`: ``uniforms.size`` uniforms on
    [−1, 1) into *uniforms*, then the series ``noise[0, i]``, ``noise[1, i]``, … of standard
    normals, one after the other. numba draws from the generator's own bit generator with
    NumPy's algorithms (the uniform as low + (high − low)·U, the normals by NumPy's
    ziggurat), so the values are NumPy's bit for bit (tests/scenarios_tests/
    test_sensor_draws.py); it runs without the GIL, in one call per run instead of one per
    series, and without NumPy's per-call overhead. The ``draw_run`` of
    :func:`scenarios.acquisition.sensor_draws`."""
    for j in range(uniforms.size):
        uniforms[j] = rng.uniform(-1.0, 1.0)
    for r in range(noise.shape[0]):
        for k in range(noise.shape[2]):
            noise[r, i, k] = rng.standard_normal()


@njit(nogil=True, cache=True)
def filtered_normals_1(rng, b, a, z, out):
    """``out[:] = scipy.signal.lfilter(b, a, x, zi=z)[0]`` of ``x = rng.standard_normal(out.size)``,
    the normals drawn one by one and filtered as they come, compiled: the transposed direct
    form II as scipy evaluates it (y = z₀ + b₀·x; zₙ = zₙ₊₁ + x·bₙ₊₁ − y·aₙ₊₁; the last
    z = x·b_m − y·a_m), so the same bits. *b*, *a*: the same length m ≥ 2, a[0] = 1 (scipy
    divides both by a[0], which then changes nothing); *z*: the m − 1 initial states,
    left as the final ones. One GIL-free call instead of a draw and a filter."""
    m = b.size
    for k in range(out.size):
        x = rng.standard_normal()
        y = z[0] + b[0] * x
        for n in range(m - 2):
            z[n] = z[n + 1] + x * b[n + 1] - y * a[n + 1]
        z[m - 2] = x * b[m - 1] - y * a[m - 1]
        out[k] = y


# ---- nominal servo-loop models of the position monitor (SIMD-friendly block form) ------------
#: Runs a block kernel advances together: steps outer, a contiguous block of runs inner, so
#: that every stage of a step is one branch-free loop over the block that the compiler turns
#: into packed (SIMD) instructions; 64 float64 per work row stay in the L1 cache (est.:
#: blocks of 32, 64 and 256 runs measured on this 2-core machine under load, 64 the fastest
#: for the plant and within the noise of 32 for the position monitor's band).
BLOCK = 64

#: Rows of the scratch array of :func:`servo_band_step` (see there).
BAND_WORK_ROWS = 10


def plant_fields(plant) -> np.ndarray:
    """Per-run plant parameters as one C-contiguous (:data:`FIELD_ROWS`, n_runs) array: the
    rows of :data:`PLANT_FIELDS` in order, then r/1000 [m] (:data:`P_RM`). The field-major
    layout of the block kernels (the runs of a block are contiguous for each field)."""
    m = plant_matrix(plant)
    out = np.empty((FIELD_ROWS, m.shape[0]))
    out[:P_RM] = m.T
    out[P_RM] = m[:, P_R] / _MM_PER_M
    return out


@njit(nogil=True, cache=True, error_model="numpy")
def loaded_rates(xs, cur, pf, r0, b, s_buf, a_buf, out):
    """:func:`rod_rate_1` of a loaded rod for the runs ``r0 … r0 + b − 1`` (rod positions
    ``xs[:b]`` [mm], held currents ``cur[:b]`` [mA], parameters *pf* of
    :func:`plant_fields`) into ``out[:b]`` [mm/s]: the same expressions in the same order,
    in three loops over the block — the clipped sine (packed), the ``asin`` calls (the C
    library's, one by one, as the scalar function makes them) and the rest of the rate law
    (packed: sqrt and division are exact IEEE operations, min/max/sign are selects, no
    branch)."""
    for t in range(b):
        s_buf[t] = clip(xs[t] / pf[P_R, r0 + t], -0.999, 0.999)
    for t in range(b):
        a_buf[t] = math.asin(s_buf[t])
    for t in range(b):
        r = r0 + t
        x = xs[t]
        i = cur[t]
        v0 = pf[P_KCI, r] * i
        s = s_buf[t]
        cos_d = math.sqrt(1.0 - s * s)
        hm = pf[P_HM0, r] + pf[P_HMD, r] * a_buf[t]           # hinge moment [N·m]
        f_aero = -hm / (pf[P_RM, r] * cos_d)                # rod force [N]
        ka = pf[P_KA, r]
        num = pf[P_SDP, r] - sign(i) * f_aero
        num = clip(num, 0.0, 2.0 * pf[P_SDP, r])
        v = v0 * math.sqrt(num / (pf[P_SDPREF, r] + ka * v0 * v0))
        v = 0.0 if (x >= pf[P_XMAX, r] and v > 0.0) else v
        v = 0.0 if (x <= pf[P_XMIN, r] and v < 0.0) else v
        out[t] = v


@njit(nogil=True, cache=True, error_model="numpy")
def loaded_rates_all(xs, cur, pf, out):
    """:func:`loaded_rates` of *S* samples of each of the n runs of *pf*
    (:func:`plant_fields`): rod positions *xs* (S, n) [mm] and held currents *cur* (S, n)
    [mA] into *out* (S, n) [mm/s], block by block of :data:`BLOCK` runs and sample by sample,
    as the band and the predictor evaluate it in their time loops. The rate law alone
    (``fdd-campaign bench`` times it for the arithmetic floor of a campaign)."""
    S, n = xs.shape
    s_buf = np.empty(BLOCK)
    a_buf = np.empty(BLOCK)
    for b0 in range(0, n, BLOCK):
        b = min(b0 + BLOCK, n) - b0
        for k in range(S):
            loaded_rates(xs[k, b0:b0 + b], cur[k, b0:b0 + b], pf, b0, b, s_buf, a_buf,
                         out[k, b0:b0 + b])


@njit(nogil=True, cache=True, error_model="numpy")
def servo_band_step(u, k, r0, r1, plants, x, i_prev, ts, lo, hi, work, stages):
    """Advance runs ``r0 … r1 − 1`` (at most :data:`BLOCK`) of every model of a band by
    step *k* of the nominal closed loop (docs/physics.md §2–3, as
    :meth:`detectors.builtin.position_monitor.PositionMonitor.model_output`: x_{k+1} = one RK4,
    Heun or Euler step of the rod with i_{k−1} held, i_k = sat(K·(u_k − x_k))); write the (low,
    high) [mm] of the models' outputs x_k (the rod positions at the start of the step) to
    ``lo[r − r0]``, ``hi[r − r0]``.

    *u* (n, T): the order [mm]; *plants* (m, :data:`FIELD_ROWS`, n): model j's
    :func:`plant_fields`;
    *x*, *i_prev* (m, n): the models' rod positions [mm] and held currents [mA], updated in
    place; *work* (:data:`BAND_WORK_ROWS`, ≥ r1 − r0): scratch. *stages*: the rate-law
    evaluations of a model's step (:data:`detectors.builtin.position_monitor.MODEL_STEPS`).
    4: each model's arithmetic is :func:`rk4_step_1`'s, stage by stage over the block
    (:func:`loaded_rates`); 2: Heun's step, x_{k+1} = clip(x_k + ts/2·(k₁ + k₂)) with
    k₁ = ẋ(x_k), k₂ = ẋ(x_k + ts·k₁) (the current i_{k−1} held), as
    :func:`detectors.builtin.position_monitor.heun_step`; 1: one explicit Euler step per
    period, x_{k+1} = clip(x_k + ts·ẋ(x_k, i_{k−1})), as
    :func:`detectors.builtin.position_monitor.euler_step`. low/high are
    ``np.minimum``/``np.maximum`` reduced over the models in order (a NaN output makes both NaN).
    """
    b = r1 - r0
    x0 = work[0]
    cur = work[1]
    k1 = work[2]
    k2 = work[3]
    k3 = work[4]
    k4 = work[5]
    xs = work[6]
    s_buf = work[7]
    a_buf = work[8]
    i_new = work[9]
    for j in range(plants.shape[0]):
        pf = plants[j]
        xj = x[j]
        ij = i_prev[j]
        if j == 0:
            for t in range(b):
                lo[t] = xj[r0 + t]
                hi[t] = xj[r0 + t]
        else:
            for t in range(b):
                xr = xj[r0 + t]
                lo[t] = xr if (xr < lo[t] or xr != xr) else lo[t]
                hi[t] = xr if (xr > hi[t] or xr != xr) else hi[t]
        for t in range(b):
            r = r0 + t
            xr = xj[r]
            x0[t] = xr
            cur[t] = ij[r]
            i_new[t] = clip(pf[P_K, r] * (u[r, k] - xr), -pf[P_IMAX, r], pf[P_IMAX, r])
        loaded_rates(x0, cur, pf, r0, b, s_buf, a_buf, k1)
        if stages == 1:
            for t in range(b):
                r = r0 + t
                xj[r] = clip(x0[t] + ts * k1[t], pf[P_XMIN, r], pf[P_XMAX, r])
                ij[r] = i_new[t]
            continue
        if stages == 2:
            for t in range(b):
                xs[t] = x0[t] + ts * k1[t]
            loaded_rates(xs, cur, pf, r0, b, s_buf, a_buf, k2)
            for t in range(b):
                r = r0 + t
                x_new = x0[t] + (0.5 * ts) * (k1[t] + k2[t])
                xj[r] = clip(x_new, pf[P_XMIN, r], pf[P_XMAX, r])
                ij[r] = i_new[t]
            continue
        for t in range(b):
            xs[t] = x0[t] + 0.5 * ts * k1[t]
        loaded_rates(xs, cur, pf, r0, b, s_buf, a_buf, k2)
        for t in range(b):
            xs[t] = x0[t] + 0.5 * ts * k2[t]
        loaded_rates(xs, cur, pf, r0, b, s_buf, a_buf, k3)
        for t in range(b):
            xs[t] = x0[t] + ts * k3[t]
        loaded_rates(xs, cur, pf, r0, b, s_buf, a_buf, k4)
        for t in range(b):
            r = r0 + t
            x_new = x0[t] + (ts / 6.0) * (k1[t] + 2.0 * k2[t] + 2.0 * k3[t] + k4[t])
            xj[r] = clip(x_new, pf[P_XMIN, r], pf[P_XMAX, r])
            ij[r] = i_new[t]


@njit(nogil=True, cache=True, error_model="numpy")
def servo_band_block(u, x0, plants, ts, lo, hi, stages):
    """Band of nominal servo models driven by the order *u* (n, T) [mm] from rod position
    *x0* (n,) [mm]: every model of *plants* (m ≥ 1, :data:`FIELD_ROWS`, n; :func:`plant_fields`)
    integrated in one time loop per block of :data:`BLOCK` runs (:func:`servo_band_step`; *stages*
    4: RK4, 2: Heun, 1: Euler, per period). Writes only the element-wise *lo* = min and
    *hi* = max of the m outputs (n, T) [mm]."""
    m = plants.shape[0]
    n, T = u.shape
    x = np.empty((m, n))
    for j in range(m):
        x[j] = x0
    i_prev = np.zeros((m, n))
    lo_k = np.empty(BLOCK)
    hi_k = np.empty(BLOCK)
    work = np.empty((BAND_WORK_ROWS, BLOCK))
    for b0 in range(0, n, BLOCK):
        b1 = min(b0 + BLOCK, n)
        for k in range(T):
            servo_band_step(u, k, b0, b1, plants, x, i_prev, ts, lo_k, hi_k, work, stages)
            for r in range(b0, b1):
                lo[r, k] = lo_k[r - b0]
                hi[r, k] = hi_k[r - b0]


@njit(nogil=True, cache=True, error_model="numpy")
def servo_model_block(u, x0, plant, ts, out, stages):
    """Nominal closed loop driven by the order *u* (n, T) [mm] from rod position *x0* (n,)
    [mm] (docs/physics.md §2–3, as
    :meth:`detectors.builtin.position_monitor.PositionMonitor.model_output`): out[:, k] = x_k; i_k =
    sat(K·(u_k − x_k)) applied over the next period. *plant* (n, 11): rows of :func:`plant_matrix`;
    *stages*: 4 the plant's RK4 step, 2 Heun's, 1 one Euler step per period. The band of one model
    (:func:`servo_band_block`)."""
    plants = np.empty((1, FIELD_ROWS, plant.shape[0]))
    plants[0, :P_RM] = plant.T
    for r in range(plant.shape[0]):
        plants[0, P_RM, r] = plant[r, P_R] / _MM_PER_M
    servo_band_block(u, x0, plants, ts, out, out, stages)


def servo_model(u, x0, plant, ts: float, stages: int = 4) -> np.ndarray:
    """(n, T) output [mm] of :func:`servo_model_block` for *plant* (PlantArrays); *stages*
    (:func:`check_stages`): 4 the plant's RK4 step, 2 Heun's, 1 one Euler step per period."""
    u = np.ascontiguousarray(u, dtype=float)
    out = np.empty(u.shape)
    servo_model_block(u, np.ascontiguousarray(x0, dtype=float), plant_matrix(plant),
                      float(ts), out, check_stages(stages))
    return out


#: Rate-law evaluations per step of each integrator of the servo models (a model's
#: ``model_step``, :class:`detectors.builtin.position_monitor.PositionMonitor`).
STEP_STAGES = {"euler": 1, "heun": 2, "rk4": 4}
#: The numbers of stages :func:`servo_band_step` takes.
STAGES = tuple(STEP_STAGES.values())


def check_stages(stages) -> int:
    """*stages* as an int, when it is one of :data:`STAGES`; else ValueError."""
    if isinstance(stages, bool) or stages not in STAGES:
        raise ValueError(f"stages must be one of {STAGES} (Euler, Heun, RK4), got {stages!r}")
    return int(stages)


def band_plants(plants) -> np.ndarray:
    """The (m, :data:`FIELD_ROWS`, n_runs) C-contiguous stack of :func:`plant_fields` of each
    PlantArrays in *plants* (the models of a band, in order)."""
    return np.ascontiguousarray(np.stack([plant_fields(p) for p in plants]))


def servo_band(u, x0, plants, ts: float, stages: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """(low, high), each (n, T) [mm]: the element-wise min and max of the outputs of
    :func:`servo_model` (with the same *stages*) for each PlantArrays of *plants*, bit for bit,
    in one pass (:func:`servo_band_block`) without the m output arrays."""
    u = np.ascontiguousarray(u, dtype=float)
    lo, hi = np.empty(u.shape), np.empty(u.shape)
    servo_band_block(u, np.ascontiguousarray(x0, dtype=float), band_plants(plants),
                     float(ts), lo, hi, check_stages(stages))
    return lo, hi


# ---- compile / load from the cache before a campaign -----------------------------------------
_WARMUPS: list = []
_CACHED: list = []   # compiled functions of other modules whose cache state warm_up reports


def register_warmup(func, kernels=()) -> None:
    """Add *func* (no arguments; calls its kernels once on tiny inputs) to :func:`warm_up`;
    *kernels*: the compiled functions it calls, so that :func:`warm_up` says when their
    cache is cold too."""
    if func not in _WARMUPS:
        _WARMUPS.append(func)
    _CACHED.extend(k for k in kernels if k not in _CACHED)


def _warm_simulation() -> None:
    """Load (or compile) the kernels every campaign of the servo-loop plant calls: the
    plant's, the per-run draws and the model band of the position monitor. The single
    model (:func:`servo_model_block`), which only some detectors and the rod-measurement
    truth of jams call, is loaded when first called: 23 ms of each campaign's start that
    does not use it (addsafe-mc)."""
    n, T = 1, 2
    z2, z1, zi = np.zeros((n, T)), np.zeros(n), np.zeros(n, dtype=np.int64)
    outs = [np.zeros((n, T)) for _ in range(5)]
    fields = np.ones((FIELD_ROWS, n))
    fields[P_XMIN] = -1.0
    integrate_block(z1, z2, fields, z1, z1, z2, np.zeros((0, 0)), np.zeros((0, 0)), zi,
                    np.zeros((0, 0)), np.zeros((0, 0)), zi, z1, zi, np.zeros(6, dtype=np.bool_),
                    0.01, -0.5, 0.5, 0.01, *outs)
    servo_band_block(z2, z1, np.stack([fields, fields]), 0.01, outs[0], outs[1], 4)
    # the command as a detector reads it (read-only: the position monitor's model band)
    servo_band_block(read_only_view(z2), z1, np.stack([fields, fields]), 0.01, outs[0],
                     outs[1], 4)
    sensor_draws_1(np.random.default_rng(0), np.empty(5), np.empty((3, 1, T)), 0)
    filtered_normals_1(np.random.default_rng(0), np.ones(3), np.ones(3), np.zeros(2),
                       np.empty(T))


register_warmup(_warm_simulation)

#: The kernels :func:`_warm_simulation` loads: the ones whose cache :func:`_cache_is_warm`
#: reads (a kernel that loads at its first call would make every start say "compiling").
_KERNELS = ("integrate_block", "servo_band_block", "sensor_draws_1", "filtered_normals_1")


def _cache_is_warm() -> bool:
    """Whether numba's on-disk cache holds this module's kernels for the current source
    (best effort: numba's cache index, whose stamp goes stale when the source changes)."""
    try:
        return all(bool(func._cache._cache_file._load_index())
                   for func in [globals()[name] for name in _KERNELS] + _CACHED)
    except (AttributeError, KeyError, TypeError, OSError):  # a numba without these internals
        return False


def sources_digest(modules) -> str:
    """SHA-256 of the source files of *modules* (found without importing them)."""
    digest = hashlib.sha256()
    for name in modules:
        origin = importlib.util.find_spec(name).origin
        digest.update(name.encode() + b"\0" + Path(origin).read_bytes())
    return digest.hexdigest()


def invalidate_stale_cache(name: str, depends=(__name__,), stamp: Path | None = None) -> bool:
    """Flush numba's on-disk cache of the compiled functions of module *name* when it was
    built from other sources of the modules *depends* than those there are now; returns
    whether it flushed. Every module with cached kernels calls it on its last line, so
    before any of its functions is loaded, naming the modules whose compiled functions or
    constants its kernels use (default: this one, where they all come from today).
    *stamp*: the JSON file {module: digest of the sources its cache was built from};
    default: beside the module's cache.

    numba checks a cached function against its own source file only, so a kernel that calls
    a compiled function of another module (the position monitor's decision calls
    :func:`servo_band_step` of this one) would be loaded as it was compiled before that
    module changed — the old arithmetic, silently. A flushed function is compiled again on
    its next call. Best effort: nothing happens without numba, with a numba without these
    internals or with a cache that cannot be written."""
    try:
        funcs = [v for v in vars(sys.modules[name]).values()
                 if getattr(getattr(v, "py_func", None), "__module__", None) == name
                 and hasattr(v, "_cache")]
        if not funcs:
            return False
        stamp = stamp or Path(funcs[0]._cache._cache_path) / "fdd-kernel-sources.json"
        digest = sources_digest(depends)
        stamps = json.loads(stamp.read_text()) if stamp.is_file() else {}
        if stamps.get(name) == digest:
            return False
        for func in funcs:
            func._cache.flush()
        stamps[name] = digest
        stamp.parent.mkdir(parents=True, exist_ok=True)
        part = stamp.with_name(f"{stamp.name}.{os.getpid()}.part")
        part.write_text(json.dumps(stamps, indent=1, sort_keys=True))
        os.replace(part, stamp)
        return True
    except (AttributeError, KeyError, OSError, TypeError, ValueError):  # pragma: no cover
        return False


def warm_up(log=None) -> float:
    """Compile every registered kernel (or load it from numba's cache) now; returns the
    seconds it took. Says so on *log* when the cache is cold (first use)."""
    if not HAVE_NUMBA:
        return 0.0
    t0 = time.perf_counter()
    cold = not _cache_is_warm()
    if cold and log is not None:
        log("compiling kernels (first use; numba caches them for the next runs)…")
    for func in list(_WARMUPS):
        func()
    elapsed = time.perf_counter() - t0
    if cold and log is not None:
        log(f"kernels compiled in {elapsed:.1f} s")
    return elapsed


invalidate_stale_cache(__name__)   # numba cache built from other kernel sources: flushed
