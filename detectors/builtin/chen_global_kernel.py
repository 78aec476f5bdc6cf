"""The step loop of ``chen-global``'s recursion, compiled (:mod:`detectors.builtin.chen_global`).

One window of steps [a, b) of the estimator of [CHEN] eq. 16 at the global level and, with
*bounds*, of the five uncertainty filters of its activity bound
(:mod:`detectors.synthesis.chen_global_uncertainty`), for a block of runs: the same operations in
the same order as the NumPy loop of
:meth:`detectors.builtin.chen_global.ChenGlobalEstimator._recursion` (its reference, selected by
:func:`scenarios.compiled.use_engine`), so the two give the same bits
(``tests/detectors_tests/test_detector_kernels.py``). A sum over a short axis is written out left to
right, as NumPy reduces it; no fused multiply-add (numba's default, no ``fastmath``).

The NumPy loop spends about 30 array operations per step on arrays of a block's runs, and
forms the drives of a window with about 20 passes over (4, n, window) arrays; at the
aircraft plant's blocks of 25 runs that is mostly interpreter overhead, about 7 ms of CPU
per run of 60 s (``fdd-campaign bench --campaign chen-mc``). Here each run's window is one
pass, the drives formed step by step in the reference's order (a sum started at 0.0, the
inputs then the ramps' increments, as its ``+=`` over a zero array does).
"""

from __future__ import annotations

import numpy as np

from scenarios import compiled as kernels

@kernels.njit(nogil=True, cache=True, error_model="numpy")
def recursion_window(y, u, a, b, xh, rows, L2, PhiT, Gam, Gam1, ramp, f_hat, bounds, e, C_L2,
                     ZxT, Zu, z_f, z_g, GmT, w):
    """Steps a … b − 1 of the recursion, in place, run after run.

    y (3, n, T) outputs [φ, p, r]; u (6, n, ≥ b − a) the inputs from step a on (one step
    more when b < T: the ramps' last increment); xh (4, n) the state x̂ at step a (updated
    to step b); rows (3,) the state each output reads (C_b selects); L2 (q, 3); PhiT
    (4, 4, n) Φ per run; Gam (n, 4, 9) and Gam1 (n, 4, len(ramp)) the input matrices on
    [u; y] and on the increments of the inputs *ramp* (indices into [u; y]); f_hat (n, T)
    written at the window's steps. With *bounds*: e (5, 4, n) the
    uncertainty filters' state (updated), C_L2 (4,) the f̂ row of L2·C, ZxT (5, 4, n) and
    Zu (n, 5, 6) the state and input parts of the uncertainty signals, z_f, z_g (5, n) their
    parts per degree of f̂ and of the gust estimate, GmT (5, 4, n) Γ_M per signal, w (5, n,
    T) written at the window's steps (unused arrays may be empty when *bounds* is False).
    The four states of x_b (docs/chen-estimator.md §5) are unrolled in the sums, so the loops
    over states run to 4.
    """
    n, T = f_hat.shape
    q = L2.shape[0]
    n_s = e.shape[0]
    n_u = u.shape[0]
    n_in = Gam.shape[2]
    f_all = np.empty(q)
    z = np.empty(n_s)
    x = np.empty(4)
    x_new = np.empty(4)
    es = np.empty((n_s, 4))
    e_new = np.empty((n_s, 4))
    uy = np.empty(n_in)                 # [u; y] at step k
    du = np.empty(ramp.shape[0])        # the ramps' increments u_{k+1} − u_k
    for r in range(n):
        for i in range(4):
            x[i] = xh[i, r]
        for s in range(n_s):
            for i in range(4):
                es[s, i] = e[s, i, r]
        for k in range(a, b):
            kw = k - a
            for j in range(n_in):
                uy[j] = u[j, r, kw] if j < n_u else y[j - n_u, r, k]
            for m in range(ramp.shape[0]):
                j = ramp[m]
                du[m] = 0.0
                if k + 1 < T:
                    if j < n_u:
                        du[m] = u[j, r, kw + 1] - uy[j]
                    else:
                        du[m] = y[j - n_u, r, k + 1] - uy[j]
            i0 = y[0, r, k] - x[rows[0]]
            i1 = y[1, r, k] - x[rows[1]]
            i2 = y[2, r, k] - x[rows[2]]
            for i in range(q):
                f_all[i] = L2[i, 0] * i0 + L2[i, 1] * i1 + L2[i, 2] * i2
            f_hat[r, k] = f_all[0]
            if bounds:
                for s in range(n_s):
                    w[s, r, k] = (C_L2[0] * es[s, 0] + C_L2[1] * es[s, 1]
                                  + C_L2[2] * es[s, 2] + C_L2[3] * es[s, 3])
                x0, x1, x2, x3 = x[0], y[1, r, k], y[2, r, k], y[0, r, k]   # [β̂, p, r, φ]
                for s in range(n_s):
                    zu = 0.0                                    # the rods' part of z
                    for j in range(n_u):
                        zu += Zu[r, s, j] * uy[j]
                    zs = (ZxT[s, 0, r] * x0 + ZxT[s, 1, r] * x1 + ZxT[s, 2, r] * x2
                          + ZxT[s, 3, r] * x3) + zu + z_f[s, r] * f_all[0]
                    if q > 1:                                   # gust channel: β_a
                        zs = zs + z_g[s, r] * f_all[1]
                    z[s] = zs
                for s in range(n_s):
                    for i in range(4):
                        e_new[s, i] = (PhiT[i, 0, r] * es[s, 0] + PhiT[i, 1, r] * es[s, 1]
                                       + PhiT[i, 2, r] * es[s, 2]
                                       + PhiT[i, 3, r] * es[s, 3]) + GmT[s, i, r] * z[s]
                for s in range(n_s):
                    for i in range(4):
                        es[s, i] = e_new[s, i]
            for i in range(4):
                drive = 0.0                 # Γ u_k + Γ1 (u_{k+1} − u_k), in [u; y] order
                for j in range(n_in):
                    drive += Gam[r, i, j] * uy[j]
                for m in range(ramp.shape[0]):
                    drive += Gam1[r, i, m] * du[m]
                x_new[i] = (PhiT[i, 0, r] * x[0] + PhiT[i, 1, r] * x[1]
                            + PhiT[i, 2, r] * x[2] + PhiT[i, 3, r] * x[3]) + drive
            for i in range(4):
                x[i] = x_new[i]
        for i in range(4):
            xh[i, r] = x[i]
        for s in range(n_s):
            for i in range(4):
                e[s, i, r] = es[s, i]


def _warm_kernels() -> None:
    """Compile (or load from the cache) the kernel of this module on tiny inputs."""
    n, T, q, s = 1, 2, 2, 5
    recursion_window(np.zeros((3, n, T)), np.zeros((6, n, T)), 0, T, np.zeros((4, n)),
                     np.arange(3), np.zeros((q, 3)), np.zeros((4, 4, n)), np.zeros((n, 4, 9)),
                     np.zeros((n, 4, 8)), np.arange(8), np.zeros((n, T)), True,
                     np.zeros((s, 4, n)), np.zeros(4), np.zeros((s, 4, n)), np.zeros((n, s, 6)),
                     np.zeros((s, n)), np.zeros((s, n)), np.zeros((s, 4, n)), np.zeros((s, n, T)))


kernels.register_warmup(_warm_kernels, kernels=(recursion_window,))


kernels.invalidate_stale_cache(__name__)   # numba cache built from other kernel sources: flushed
