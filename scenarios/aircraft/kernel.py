"""Compiled time loop of the aircraft in the loop: the rigid body and the seven servo-loops of
a block of runs in one kernel (docs/physics.md §2, §3, §7).

:func:`integrate_block` runs the recursion of :func:`scenarios.aircraft.loop.integrate_reference`
(the NumPy reference, kept as the specification) with the steps outside and the runs and
surfaces of the block inside, on contiguous float64 arrays. Bit for bit the same numbers:

- the same equations in the same order of floating-point operations, no ``fastmath``,
  ``error_model="numpy"`` (as :mod:`scenarios.compiled`);
- ``arcsin`` and ``power`` are NumPy's own inner loops, called from the kernel through the
  ufunc loop interface (``ufunc._resolve_dtypes_and_context`` / ``_get_strided_loop``,
  NEP 43): on CPUs where NumPy evaluates them with its SIMD routines they differ from the C
  library by up to 1 ulp, which the closed loop would carry into the quantised sensors;
- the two matrix–vector products of the aircraft (``step_matrix @ [x; u; Δδ]`` and
  ``load_matrix @ [x; u]``) call the BLAS ``dgemv`` that ``numpy.matmul`` calls, with the
  arguments it passes (column-major, transposed), so the summation order is the library's.

``sin``, ``cos`` and ``sqrt`` are the C library's: ``sqrt`` is correctly rounded in both,
and :func:`available` checks on a sample that NumPy's ``sin`` and ``cos`` equal the C
library's on this machine before the kernel is first used. When they differ, or NumPy's
inner loops or BLAS cannot be found (another NumPy build), the loop falls back to the
NumPy reference.
"""

from __future__ import annotations

import ctypes
import glob
import math
import os

import numpy as np

from ..compiled import (HAVE_NUMBA, P_HM0, P_HMD, P_IMAX, P_K, P_KA, P_KCI, P_R, P_SDP,
                       P_SDPREF, P_XMAX, P_XMIN, clip, invalidate_stale_cache, njit, sign)
from .lpv import IA, IB, IP, IPHI, IQ, IR, ITH

__all__ = ["available", "integrate_block"]

_MM_PER_M = 1000.0
_COL_MAJOR, _TRANS = 102, 112          # CBLAS_ORDER, CBLAS_TRANSPOSE


def _capsule_pointer(capsule) -> int:
    get = ctypes.pythonapi.PyCapsule_GetPointer
    get.restype = ctypes.c_void_p
    get.argtypes = [ctypes.py_object, ctypes.c_char_p]
    return get(capsule, b"numpy_1.24_ufunc_call_info")


def _ufunc_loop(ufunc, nin: int):
    """(capsule, [loop, context, auxdata]) of *ufunc*'s float64 inner loop (NEP 43)."""
    f8 = np.dtype(np.float64)
    _, info = ufunc._resolve_dtypes_and_context((f8,) * nin + (None,))
    ufunc._get_strided_loop(info)
    fields = (ctypes.c_void_p * 3).from_address(_capsule_pointer(info))
    return info, [int(v or 0) for v in fields]


def _numpy_blas() -> ctypes.CDLL | None:
    """NumPy's bundled OpenBLAS (the library ``numpy.matmul`` calls), or None."""
    root = os.path.dirname(os.path.dirname(np.__file__))
    for path in sorted(glob.glob(os.path.join(root, "numpy.libs", "*openblas*"))):
        try:
            return ctypes.CDLL(path)
        except OSError:  # pragma: no cover - unreadable library
            continue
    return None


def _resolve():
    """[arcsin loop, ctx, aux, power loop, ctx, aux, dgemv] addresses, or None."""
    try:
        asin_info, asin = _ufunc_loop(np.arcsin, 1)
        pow_info, pw = _ufunc_loop(np.power, 2)
        lib = _numpy_blas()
        gemv = getattr(lib, "scipy_cblas_dgemv64_", None) if lib is not None else None
    except (AttributeError, TypeError, ValueError):  # pragma: no cover - other NumPy builds
        return None, ()
    if gemv is None or not asin[0] or not pw[0]:
        return None, ()
    addr = ctypes.cast(gemv, ctypes.c_void_p).value
    return np.array(asin + pw + [addr], dtype=np.int64), (asin_info, pow_info, lib)


#: Addresses of NumPy's inner loops and BLAS gemv (the objects that own them are kept alive).
LOOPS, _KEEP = _resolve() if HAVE_NUMBA else (None, ())


if HAVE_NUMBA:
    from llvmlite import ir
    from numba import types
    from numba.extending import intrinsic

    @intrinsic
    def _call_loop(typingctx, fn, ctx, data, dims, steps, aux):
        """``fn(ctx, data, dims, steps, aux)``: a NumPy strided inner loop (addresses)."""
        sig = types.int32(fn, ctx, data, dims, steps, aux)

        def codegen(context, builder, signature, args):
            i8p = ir.IntType(8).as_pointer()
            i64p = ir.IntType(64).as_pointer()
            fnty = ir.FunctionType(ir.IntType(32), [i8p, i8p.as_pointer(), i64p, i64p, i8p])
            f = builder.inttoptr(args[0], fnty.as_pointer())
            return builder.call(f, [builder.inttoptr(args[1], i8p),
                                    builder.inttoptr(args[2], i8p.as_pointer()),
                                    builder.inttoptr(args[3], i64p),
                                    builder.inttoptr(args[4], i64p),
                                    builder.inttoptr(args[5], i8p)])
        return sig, codegen

    @intrinsic
    def _call_gemv(typingctx, fn, rows, cols, a, lda, x, y):
        """``cblas_dgemv(ColMajor, Trans, cols, rows, 1, a, lda, x, 1, 0, y, 1)`` (ILP64):
        y = A·x for the row-major (rows, cols) matrix at *a*, as ``numpy.matmul`` calls it."""
        sig = types.void(fn, rows, cols, a, lda, x, y)

        def codegen(context, builder, signature, args):
            i32, i64, f64 = ir.IntType(32), ir.IntType(64), ir.DoubleType()
            dp = f64.as_pointer()
            fnty = ir.FunctionType(ir.VoidType(), [i32, i32, i64, i64, f64, dp, i64, dp, i64,
                                                   f64, dp, i64])
            f = builder.inttoptr(args[0], fnty.as_pointer())
            one = ir.Constant(i64, 1)
            builder.call(f, [ir.Constant(i32, _COL_MAJOR), ir.Constant(i32, _TRANS),
                             args[2], args[1],
                             ir.Constant(f64, 1.0), builder.inttoptr(args[3], dp),
                             args[4], builder.inttoptr(args[5], dp), one,
                             ir.Constant(f64, 0.0), builder.inttoptr(args[6], dp), one])
            return context.get_dummy_value()
        return sig, codegen


@njit(nogil=True, cache=True, error_model="numpy")
def _asin(loops, src, dst, m, scratch):
    """dst[:m] = numpy.arcsin(src[:m]) with NumPy's loop; *scratch* int64 (5,)."""
    scratch[0] = src.ctypes.data
    scratch[1] = dst.ctypes.data
    scratch[2] = m
    scratch[3] = 8
    scratch[4] = 8
    _call_loop(loops[0], loops[1], scratch.ctypes.data, scratch.ctypes.data + 16,
               scratch.ctypes.data + 24, loops[2])


@njit(nogil=True, cache=True, error_model="numpy")
def _pow_scalar(loops, src, e, dst, m, scratch):
    """dst[:m] = numpy.power(src[:m], e) (*e* a float64 (1,) array: a broadcast scalar)."""
    scratch[0] = src.ctypes.data
    scratch[1] = e.ctypes.data
    scratch[2] = dst.ctypes.data
    scratch[3] = m
    scratch[4] = 8
    scratch[5] = 0
    scratch[6] = 8
    _call_loop(loops[3], loops[4], scratch.ctypes.data, scratch.ctypes.data + 24,
               scratch.ctypes.data + 32, loops[5])


@njit(nogil=True, cache=True, error_model="numpy")
def _rod_rates(loops, xa, cur, plant, loaded, out, s, asn, scratch):
    """out = scenarios.servo.rod_rate(xa, cur, plant, loaded) for every row (docs/physics.md §3)."""
    m = xa.shape[0]
    for j in range(m):
        s[j] = clip(xa[j] / plant[j, P_R], -0.999, 0.999)
    _asin(loops, s, asn, m, scratch)
    for j in range(m):
        p = plant[j]
        i = cur[j]
        v0 = p[P_KCI] * i
        if loaded[j]:
            cos_d = math.sqrt(1.0 - s[j] * s[j])
            hm = p[P_HM0] + p[P_HMD] * asn[j]
            f_aero = -hm / (p[P_R] / _MM_PER_M * cos_d)
            ka = p[P_KA]
        else:
            f_aero = 0.0
            ka = 0.0
        num = p[P_SDP] - sign(i) * f_aero
        num = clip(num, 0.0, 2.0 * p[P_SDP])
        v = v0 * math.sqrt(num / (p[P_SDPREF] + ka * v0 * v0))
        if xa[j] >= p[P_XMAX] and v > 0.0:
            v = 0.0
        if xa[j] <= p[P_XMIN] and v < 0.0:
            v = 0.0
        out[j] = v


@njit(nogil=True, cache=True, error_model="numpy")
def integrate_block(loops, mon, x, delta, trim_rad, trim_deg, lo_deg, hi_deg, plant,
                    pitch, roll, yaw, elevators, step_deg, step_matrix, load_matrix, gains, law,
                    theta0,
                    nz_c_in, p_c_in, beta_c_in, gust_alpha, gust_beta, nse,
                    com_scale, com_bias, com_noise, com_add, com_osc, k_osc, cur_add, cur_force,
                    k_jam, jam_offset, k_disc, flags, ramp_deg, scal,
                    rods, surf, states, meas_rec, xs, icmd, iapp, u_rec, sp_rec):
    """The closed loop of :func:`scenarios.aircraft.loop.integrate_reference` on a block of
    n runs and S surfaces (arrays surface-major, index s·n + i, as there).

    *x*, *delta* (S·n,) hold the initial rod positions [mm] and deflections [rad] and are
    advanced in place. *gains* (9, n) are the fields of :class:`laws.Gains` (k_n, k_q, k_i,
    L_p, L_da, N_dr, nz_de, tas_ms, omega_sp; the last unused here); *law* the scalars
    (bank_max [rad], bank_gain, roll_bandwidth, yaw_damping, sideslip_gain,
    sideslip_integral, g0, the pitch, roll and yaw filter gains c of
    :func:`laws.filter_coefficient` and the spoilers' largest step per period [rad]);
    *step_deg* (S,) the largest step of each surface order per period [deg]
    (docs/aircraft.md §4.4); *scal* (ts,
    rod_quant, r_mm of the monitored actuator, runaway order limits lo/hi [deg], d_min,
    d_max [rad], roll limit [rad]). *flags* as :func:`scenarios.compiled.integrate_block`
    (has com_add, com_osc, cur_add, cur_force, any jam, any disconnection); absent fault
    arrays may be empty. Writes the recorded series in place.
    """
    S = trim_rad.shape[0]
    n = trim_rad.shape[1]
    T = nz_c_in.shape[1]
    N = S * n
    ns = step_matrix.shape[1]
    nxu = load_matrix.shape[2]
    nw = step_matrix.shape[2]
    i_spoiler, i_ga, i_gb = S, S + 1, S + 2
    ts, quant, r_m_act = scal[0], scal[1], scal[2]
    run_lo, run_hi, d_min, d_max, roll_lim = scal[3], scal[4], scal[5], scal[6], scal[7]
    bank_max, bank_gain, roll_bw, yaw_damp, beta_gain, beta_int, g0 = (
        law[0], law[1], law[2], law[3], law[4], law[5], law[6])
    c_pitch, c_roll, c_yaw, sp_step = law[7], law[8], law[9], law[10]
    has_com_add, has_com_osc, has_cur_add, has_cur_force, any_jam, any_disc = (
        flags[0], flags[1], flags[2], flags[3], flags[4], flags[5])
    base = mon * n
    scratch = np.zeros(8, dtype=np.int64)
    xu = np.zeros((n, nw))
    xa_new = np.zeros(ns)
    loads = np.zeros(2)
    i_prev = np.zeros(N)
    i_app = np.zeros(N)
    y = np.empty(N)
    u_loop = np.empty(N)
    x_next = np.empty(N)
    delta_next = np.empty(N)
    loaded = np.ones(N, dtype=np.bool_)
    kk = np.empty((4, N))
    xarg = np.empty(N)
    sbuf = np.empty(N)
    abuf = np.empty(N)
    y_hold = np.zeros(n)
    z_pitch = np.zeros(n)
    phi_ref = np.zeros(n)
    z_beta = np.zeros(n)
    nz_f = np.zeros(n)
    q_f = np.zeros(n)
    p_f = np.zeros(n)
    r_f = np.zeros(n)
    beta_f = np.zeros(n)
    order_prev = trim_deg.copy()
    pitch_clipped = np.zeros(n, dtype=np.bool_)
    da_prev = np.zeros(n)
    order = np.empty(S)
    one = np.empty(1)
    one_out = np.empty(1)
    three = np.full(1, 3.0)
    e_f = np.empty(n)
    cos3 = np.empty(n)
    rm3 = np.empty(n)
    rmv = np.empty(n)
    floating = np.empty(n)
    for i in range(n):   # r_m ** 3 of the monitored surface's runs (float_rate_coef)
        rmv[i] = plant[base + i, P_R] / _MM_PER_M
    _pow_scalar(loops, rmv, three, rm3, n, scratch)
    for k in range(T):
        # an "offset" solid jam: the rod jumps at its onset (faults.jam_onset_position)
        if any_jam:
            for i in range(n):
                j = base + i
                if k_jam[i] == k and jam_offset[i] != 0.0:
                    xj = clip(x[j] + jam_offset[i], plant[j, P_XMIN], plant[j, P_XMAX])
                    if xj != x[j]:
                        one[0] = xj / plant[j, P_R]
                        _asin(loops, one, one_out, 1, scratch)
                        delta[j] = one_out[0]
                    x[j] = xj
        # COM acquisitions at t_k (acquire_com), every surface
        for j in range(N):
            v = x[j] * (1.0 + com_scale[j]) + com_bias[j] + com_noise[j, k]
            y[j] = quant * np.rint(v / quant)
        for i in range(n):
            j = base + i
            yi = y[j]
            if has_com_add:
                yi = yi + com_add[i, k]
            if has_com_osc:
                if k == k_osc[i]:
                    y_hold[i] = yi
                if k >= k_osc[i]:
                    osc = com_osc[i, k]
                    yi = y_hold[i] + (0.0 if math.isnan(osc) else osc)
            y[j] = yi
        # measured elevator deflection from the COM rods
        for j in range(N):
            sbuf[j] = clip(y[j] / plant[j, P_R], -1.0, 1.0)
        _asin(loops, sbuf, abuf, N, scratch)
        for i in range(n):
            row = xu[i]
            # aircraft sensors at t_k
            for s in range(S):
                row[ns + s] = delta[s * n + i] - trim_rad[s, i]
            row[ns + i_spoiler] = da_prev[i]
            row[ns + i_ga] = gust_alpha[i, k]
            row[ns + i_gb] = gust_beta[i, k]
            _call_gemv(loops[6], 2, nxu, load_matrix[i].ctypes.data, nxu, row.ctypes.data,
                       loads.ctypes.data)
            mp = row[IP] + nse[0, i, k]
            mq = row[IQ] + nse[1, i, k]
            mr = row[IR] + nse[2, i, k]
            mphi = row[IPHI] + nse[3, i, k]
            mtheta = theta0[i] + row[ITH] + nse[4, i, k]
            mdnz = loads[0] + nse[5, i, k]
            mny = loads[1] + nse[6, i, k]
            mbeta = row[IB] + gust_beta[i, k] + nse[7, i, k]
            de_sum = 0.0
            n_el = 0
            for s in range(S):
                if elevators[s]:
                    d = abuf[s * n + i] - trim_rad[s, i]
                    de_sum = d if n_el == 0 else de_sum + d
                    n_el += 1
            de_meas = de_sum / n_el
            # laws (laws.step) and surface orders
            nz_c = nz_c_in[i, k] + (1.0 / math.cos(clip(mphi, -bank_max, bank_max)) - 1.0)
            p_c = p_c_in[i, k]
            dnz_p = mdnz - gains[6, i] * de_meas
            nz_f[i] = nz_f[i] + c_pitch * (dnz_p - nz_f[i])
            q_f[i] = q_f[i] + c_pitch * (mq - q_f[i])
            de = -gains[0, i] * nz_f[i] - gains[1, i] * q_f[i] - gains[2, i] * z_pitch[i]
            z_pitch[i] = z_pitch[i] + (0.0 if pitch_clipped[i] else ts * (mdnz - nz_c))
            phi_ref[i] = phi_ref[i] + ts * p_c
            p_dem = p_c + bank_gain * (phi_ref[i] - mphi)
            p_f[i] = p_f[i] + c_roll * (mp - p_f[i])
            da = (roll_bw * (p_dem - p_f[i]) - gains[3, i] * p_f[i]) / gains[4, i]
            r_turn = g0 * math.sin(clip(mphi, -bank_max, bank_max)) / gains[7, i]
            r_f[i] = r_f[i] + c_yaw * (mr - r_f[i])
            beta_f[i] = beta_f[i] + c_yaw * (mbeta - beta_f[i])
            e_beta = beta_f[i] - beta_c_in[i, k]
            dr = (-yaw_damp * (r_f[i] - r_turn) + beta_gain * e_beta
                  + beta_int * z_beta[i]) / gains[5, i]
            z_beta[i] = z_beta[i] + ts * e_beta
            clipped = False
            for s in range(S):
                raw = trim_deg[s, i] + (pitch[s] * de + roll[s] * da + yaw[s] * dr) * (
                    180.0 / math.pi)
                o = clip(raw, lo_deg[s, i], hi_deg[s, i])      # authority, then rate limit
                o = order_prev[s, i] + clip(o - order_prev[s, i], -step_deg[s], step_deg[s])
                order_prev[s, i] = o
                if elevators[s] and o != raw:
                    clipped = True
                order[s] = o
            pitch_clipped[i] = clipped
            u_rec[i, k] = r_m_act * math.sin(order[mon] * (math.pi / 180.0))
            order[mon] = clip(order[mon] + ramp_deg[i, k], run_lo, run_hi)
            for s in range(S):
                j = s * n + i
                u_loop[j] = plant[j, P_R] * math.sin(order[s] * (math.pi / 180.0))
            # record t_k
            for s in range(ns):
                states[s, i, k] = row[s]
            meas_rec[0, i, k] = mp
            meas_rec[1, i, k] = mq
            meas_rec[2, i, k] = mr
            meas_rec[3, i, k] = mphi
            meas_rec[4, i, k] = mtheta
            meas_rec[5, i, k] = 1.0 + mdnz
            meas_rec[6, i, k] = mny
            meas_rec[7, i, k] = mbeta
            meas_rec[8, i, k] = theta0[i] + row[IA] + gust_alpha[i, k] + nse[8, i, k]
            sp_rec[i, k] = da_prev[i]
            # the spoilers' order of the next period (rate-limited as the ailerons')
            da_prev[i] = da_prev[i] + clip(clip(da, -roll_lim, roll_lim) - da_prev[i],
                                           -sp_step, sp_step)
        # servo-loops: currents
        for j in range(N):
            p = plant[j]
            i_new = clip(p[P_K] * (u_loop[j] - y[j]), -p[P_IMAX], p[P_IMAX])
            i_app[j] = i_prev[j]
            i_prev[j] = i_new
        for i in range(n):
            j = base + i
            ia = i_app[j]
            if has_cur_add:
                ia = ia + cur_add[i, k]
            if has_cur_force:
                force = cur_force[i, k]
                if math.isfinite(force):
                    ia = force
            i_app[j] = ia
            xs[i, k] = x[j]
            icmd[i, k] = i_prev[j]
            iapp[i, k] = ia
            if any_disc:
                loaded[j] = k < k_disc[i]
        for s in range(S):
            for i in range(n):
                rods[s, i, k] = y[s * n + i]
                surf[s, i, k] = delta[s * n + i]
        # advance the surfaces over [t_k, t_k+1) (servo.rk4_step)
        h = ts
        _rod_rates(loops, x, i_app, plant, loaded, kk[0], sbuf, abuf, scratch)
        for j in range(N):
            xarg[j] = x[j] + 0.5 * h * kk[0, j]
        _rod_rates(loops, xarg, i_app, plant, loaded, kk[1], sbuf, abuf, scratch)
        for j in range(N):
            xarg[j] = x[j] + 0.5 * h * kk[1, j]
        _rod_rates(loops, xarg, i_app, plant, loaded, kk[2], sbuf, abuf, scratch)
        for j in range(N):
            xarg[j] = x[j] + h * kk[2, j]
        _rod_rates(loops, xarg, i_app, plant, loaded, kk[3], sbuf, abuf, scratch)
        for j in range(N):
            xn = x[j] + (h / 6.0) * (kk[0, j] + 2.0 * kk[1, j] + 2.0 * kk[2, j] + kk[3, j])
            x_next[j] = clip(xn, plant[j, P_XMIN], plant[j, P_XMAX])
        if any_jam:
            for i in range(n):
                if k >= k_jam[i]:
                    x_next[base + i] = x[base + i]
        for j in range(N):
            sbuf[j] = x_next[j] / plant[j, P_R]
        _asin(loops, sbuf, delta_next, N, scratch)
        if any_disc:   # servo.float_step on the monitored surface
            for i in range(n):
                j = base + i
                cos3[i] = math.cos(delta[j])
            _pow_scalar(loops, cos3, three, cos3, n, scratch)
            for i in range(n):
                j = base + i
                p = plant[j]
                d_f = -p[P_HM0] / p[P_HMD]
                e = delta[j] - d_f
                c = math.sqrt(abs(p[P_HMD]) / (p[P_KA] * (_MM_PER_M ** 2.0) * rm3[i] * cos3[i]))
                root = math.sqrt(abs(e)) - 0.5 * h * c
                mx = max(root, 0.0)
                e_f[i] = sign(e) * (mx * mx)
                floating[i] = clip(d_f + e_f[i], d_min, d_max)
                if not loaded[j]:
                    delta_next[j] = floating[i]
        # advance the aircraft over [t_k, t_k+1): inputs of t_k held, the surfaces' motion
        # to t_k+1 as a ramp (lpv.discretise_ramp)
        for i in range(n):
            row = xu[i]
            for s in range(S):
                row[nxu + s] = delta_next[s * n + i] - delta[s * n + i]
            _call_gemv(loops[6], ns, nw, step_matrix[i].ctypes.data, nw, row.ctypes.data,
                       xa_new.ctypes.data)
            for s in range(ns):
                row[s] = xa_new[s]
        for j in range(N):
            x[j] = x_next[j]
            delta[j] = delta_next[j]


def available() -> bool:
    """Whether the compiled aircraft loop can run bit-identical to the NumPy reference here:
    numba compiling (not ``NUMBA_DISABLE_JIT``: the inner-loop calls are compiled
    intrinsics, which have no interpreted form), NumPy's inner loops and its BLAS found, and
    the C library's sin/cos equal NumPy's on a sample (else the reference runs)."""
    global _CHECKED
    if _CHECKED is None:
        _CHECKED = LOOPS is not None and _jit_enabled() and _self_check()
    return _CHECKED


def _jit_enabled() -> bool:
    from numba import config

    return not config.DISABLE_JIT


_CHECKED = None


def _self_check() -> bool:
    rng = np.random.default_rng(20261124)
    v = rng.uniform(-1.5, 1.5, 4096)
    libm = np.array([[math.sin(a), math.cos(a)] for a in v]).T
    if not (np.array_equal(libm[0], np.sin(v)) and np.array_equal(libm[1], np.cos(v))):
        return False
    return True


# the kernel compiles in the shared kernels and the state indices of lpv (IB, IP, …)
invalidate_stale_cache(__name__, depends=("scenarios.compiled", "scenarios.aircraft.lpv"))
