"""chen-global's compiled step loop (detectors/builtin/chen_global_kernel.py) pinned by value: one
window of the recursion of [CHEN] eq. 16 at the global level and of the activity bound's five
uncertainty filters (docs/chen-estimator.md §5), run on random arrays against a plain NumPy
loop written from the kernel's documented contract, independent of the detector's fit (no
LMI, no simulation: a few seconds, most of it compiling the kernel)."""

from __future__ import annotations

import functools

import numpy as np
import pytest


def plain_window(y, u, a, b, xh, rows, L2, PhiT, Gam, Gam1, ramp, bounds, e, C_L2, ZxT, Zu,
                 z_f, z_g, GmT):
    """Steps a … b − 1 of the compiled kernel's contract, one run at a time, in NumPy
    (module docstring of detectors/builtin/chen_global_kernel.py): v = [u; y] at step k, Δv its
    increment to step k + 1 over the ramp inputs (0 at a run's last step),
    f_all = L2 (y − x̂[rows]), w_s = C_L2 · e_s, z_s = ZxT_s [β̂, p, r, φ] + Zu_s u + z_f,s f̂
    (+ z_g,s f_all[1]), e_s ← Φ e_s + GmT_s z_s, x̂ ← Φ x̂ + Γ v + Γ1 Δv.
    Returns (f̂, w, x̂, e) over the window (f̂ (n, b − a), w (5, n, b − a))."""
    n, T = y.shape[1], y.shape[2]
    n_u, q = u.shape[0], L2.shape[0]
    f_out, w_out = np.zeros((n, b - a)), np.zeros((5, n, b - a))
    xh, e = xh.copy(), e.copy()
    for r in range(n):
        x, es, Phi = xh[:, r].copy(), e[:, :, r].copy(), PhiT[:, :, r]
        for k in range(a, b):
            kw = k - a
            v = np.concatenate([u[:, r, kw], y[:, r, k]])
            dv = np.zeros(len(ramp))
            if k + 1 < T:
                dv = (np.concatenate([u[:, r, kw + 1], y[:, r, k + 1]]) - v)[ramp]
            fa = L2 @ (y[:, r, k] - x[rows])
            f_out[r, kw] = fa[0]
            if bounds:
                w_out[:, r, kw] = es @ C_L2
                xt = np.array([x[0], y[1, r, k], y[2, r, k], y[0, r, k]])
                z = ZxT[:, :, r] @ xt + Zu[r] @ v[:n_u] + z_f[:, r] * fa[0]
                if q > 1:
                    z = z + z_g[:, r] * fa[1]
                es = es @ Phi.T + GmT[:, :, r] * z[:, None]
            x = Phi @ x + Gam[r] @ v + Gam1[r] @ dv
        xh[:, r], e[:, :, r] = x, es
    return f_out, w_out, xh, e


@functools.cache
def _kernel(checked: bool):
    """The compiled kernel, or (*checked*) its Python source compiled afresh with numba's
    bounds checks: an index past an array's end (which the production build, without
    checks, reads or writes silently) raises IndexError."""
    from detectors.builtin.chen_global_kernel import recursion_window

    if not checked:
        return recursion_window
    numba = pytest.importorskip("numba")
    source = getattr(recursion_window, "py_func", None)
    if source is None:
        pytest.skip("the kernels run interpreted (no numba)")
    return numba.njit(boundscheck=True, error_model="numpy")(source)


@pytest.mark.parametrize("checked", [False, True], ids=["cached", "bounds-checked"])
@pytest.mark.parametrize("q", [1, 2])
@pytest.mark.parametrize("bounds", [True, False])
def test_compiled_window_is_the_documented_step(q, bounds, checked):
    """recursion_window on random arrays (3 runs, 23 steps), run over windows [0, 9),
    [9, 23) and over the whole run at once, against the plain loop: f̂, w, and the states
    x̂, e it leaves for the next window; steps outside the window are not written; no index
    leaves its array (the bounds-checked build)."""
    recursion_window = _kernel(checked)

    rng = np.random.default_rng(11 + q)
    n, T = 3, 23
    y, u = rng.normal(size=(3, n, T)), rng.normal(size=(6, n, T))
    rows = np.array([3, 1, 2])
    ramp = np.array([0, 1, 2, 3, 4, 6, 7, 8])
    arrays = dict(L2=rng.normal(size=(q, 3)), PhiT=0.4 * rng.normal(size=(4, 4, n)),
                  Gam=rng.normal(size=(n, 4, 9)), Gam1=rng.normal(size=(n, 4, 8)),
                  C_L2=rng.normal(size=4), ZxT=rng.normal(size=(5, 4, n)),
                  Zu=rng.normal(size=(n, 5, 6)), z_f=rng.normal(size=(5, n)),
                  z_g=rng.normal(size=(5, n)), GmT=rng.normal(size=(5, 4, n)))
    xh0, e0 = rng.normal(size=(4, n)), rng.normal(size=(5, 4, n))
    order = ("L2", "PhiT", "Gam", "Gam1")
    tail = ("C_L2", "ZxT", "Zu", "z_f", "z_g", "GmT")
    for cuts in ((0, 9, T), (0, T)):
        xh, e = xh0.copy(), e0.copy()
        f_hat, w = np.full((n, T), np.nan), np.full((5, n, T), np.nan)
        for a, b in zip(cuts[:-1], cuts[1:]):
            window_u = np.ascontiguousarray(u[:, :, a:b + 1])
            ref_f, ref_w, ref_x, ref_e = plain_window(
                y, window_u, a, b, xh, rows, *(arrays[k] for k in order), ramp, bounds, e,
                *(arrays[k] for k in tail))
            recursion_window(y, window_u, a, b, xh, rows, *(arrays[k] for k in order), ramp,
                             f_hat, bounds, e, *(arrays[k] for k in tail), w)
            assert np.isnan(f_hat[:, b:]).all()             # later steps not yet written
            # the same products summed in another order: 1e-12 of the values' size
            np.testing.assert_allclose(f_hat[:, a:b], ref_f, rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(xh, ref_x, rtol=1e-12, atol=1e-12)
            if bounds:
                np.testing.assert_allclose(w[:, :, a:b], ref_w, rtol=1e-12, atol=1e-12)
                np.testing.assert_allclose(e, ref_e, rtol=1e-12, atol=1e-12)
            else:
                assert np.isnan(w).all()
                np.testing.assert_array_equal(e, e0)
        assert not np.isnan(f_hat).any()


def test_the_compiled_kernel_is_cached_on_disk():
    """cache=True: after a call, numba's on-disk index holds the kernel (what
    scenarios.compiled.warm_up reports on), so later runs load it instead of compiling."""
    numba = pytest.importorskip("numba")
    if numba.core.config.DISABLE_JIT:
        pytest.skip("the kernels run interpreted (NUMBA_DISABLE_JIT)")
    recursion_window = _kernel(False)
    n, T = 1, 2
    recursion_window(np.zeros((3, n, T)), np.zeros((6, n, T)), 0, T, np.zeros((4, n)),
                     np.array([3, 1, 2]), np.zeros((1, 3)), np.zeros((4, 4, n)),
                     np.zeros((n, 4, 9)), np.zeros((n, 4, 8)), np.arange(8), np.zeros((n, T)),
                     False, np.zeros((0, 4, n)), np.zeros(4), np.zeros((0, 4, n)),
                     np.zeros((n, 0, 0)), np.zeros((0, n)), np.zeros((0, n)),
                     np.zeros((0, 4, n)), np.zeros((0, n, T)))
    # numba's cache internals, as scenarios.compiled reads them (a NullCache without cache=True)
    assert recursion_window._cache._cache_file._load_index()
