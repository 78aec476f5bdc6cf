"""The nonlinear hydraulic servo-loop plant (docs/physics.md §3), vectorised over runs.

Every function takes arrays of shape ``(n_runs,)`` (or broadcastable) and a
:class:`PlantArrays` holding the *true* per-run parameters of the batch, so one call
advances every run of a chunk. Nothing here loops over runs.

Equations
---------
Rod speed, turbulent servo-valve flow with the adjacent actuator in damping mode
([COMB] eq. 1–2, [CHEN] eq. 11; docs/physics.md §3)::

    ẋ = Kci·i·sqrt( max(0, S·ΔP − sign(i)·F_aero) / (S·ΔP_ref + Ka·(Kci·i)²) )

with the aiding-load numerator capped at 2·S·ΔP, ẋ = 0 when the opposing load exceeds the
stall force S·ΔP, and x held inside the mechanical stops.

Hinge moment and the rod force it creates (docs/physics.md §3)::

    HM = q̄·S_c·c_c·(Ch0 + Chα·α_s + Chδ·δ),     F_aero = −HM / (r·cos δ)

F_aero > 0 opposes extension (+x). Chα and Chδ carry the Prandtl–Glauert factor
1/sqrt(1 − M²), held above M = 0.75.

Floating surface after a disconnection (docs/physics.md §5): the surface is held only by the
damping-mode neighbour, Ka·ẋ_s|ẋ_s| = −F_aero with x_s = r·sin δ. With HM affine in δ,
HM = H·(δ − δ_f), this is δ̇|δ̇| = H·(δ − δ_f)/(Ka·r³·cos³δ) (H < 0), whose solution with
cos δ frozen over a step is exact: sqrt|δ − δ_f| decreases linearly at the rate
sqrt(|H|/(Ka·r³·cos³δ))/2 (:func:`float_step`). The square-root law reaches δ_f in finite
time, which an explicit scheme would turn into chatter; the closed form does not.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .params import ActuatorParams

_MM_PER_M = 1000.0


@dataclass(frozen=True)
class PlantArrays:
    """True plant parameters of a batch, one value per run (shape ``(n_runs,)``).

    Built by :func:`plant_arrays` from the nominal :class:`ActuatorParams`, the flight
    condition and the run's uncertainty draws.
    """

    K: np.ndarray            # servo gain [mA/mm]
    Kci: np.ndarray          # servo-valve gain [(mm/s)/mA]
    i_max: np.ndarray        # current saturation [mA]
    SdP: np.ndarray          # stall force S·ΔP [N]
    SdP_ref: np.ndarray      # S·ΔP_ref [N]
    Ka: np.ndarray           # damping neighbour [N/(mm/s)²]
    r_mm: np.ndarray         # lever arm [mm]
    x_min: np.ndarray        # lower mechanical stop [mm]
    x_max: np.ndarray        # upper mechanical stop [mm]
    hm_delta: np.ndarray     # ∂HM/∂δ = q̄·S_c·c_c·Chδ [N·m/rad]
    hm_0: np.ndarray         # HM at δ = 0: q̄·S_c·c_c·(Ch0 + Chα·α_s) [N·m]

    @property
    def delta_float_rad(self) -> np.ndarray:
        """Zero-hinge-moment (floating) angle δ_f [rad]."""
        return -self.hm_0 / self.hm_delta


def compressibility_factor(mach, cap: float) -> np.ndarray:
    """Prandtl–Glauert factor 1/sqrt(1 − M²), with M held at *cap* above it (docs/physics.md §3)."""
    m = np.minimum(np.asarray(mach, dtype=float), cap)
    return 1.0 / np.sqrt(1.0 - m * m)


def plant_arrays(act: ActuatorParams, *, qbar_pa, alpha_deg, mach, d_ch0=0.0, d_cha=0.0,
                 d_chd=0.0, d_supply=0.0, d_kci=0.0) -> PlantArrays:
    """True per-run plant parameters.

    Parameters
    ----------
    act : nominal actuator parameters.
    qbar_pa : dynamic pressure [Pa]; alpha_deg : trimmed wing angle of attack [deg];
    mach : Mach number [-].
    d_ch0, d_cha, d_chd : relative mismatch of Ch0, Chα and Chδ, each drawn on its own
    (docs/physics.md §6, ±20 % est.): Ch* × (1 + d_ch*).
    d_supply : relative supply-pressure mismatch (±5 % est.); d_kci : servo-valve gain
    mismatch (±5 % est.).
    """
    qbar = np.asarray(qbar_pa, dtype=float)
    n = qbar.shape
    ones = np.ones(n)
    ch0 = act.Ch0 * (1.0 + np.asarray(d_ch0, float)) * ones
    ch_alpha = act.Ch_alpha * (1.0 + np.asarray(d_cha, float)) * ones
    ch_delta = act.Ch_delta * (1.0 + np.asarray(d_chd, float)) * ones
    pg = compressibility_factor(mach, act.mach_compress_cap)
    alpha_s = np.radians(np.asarray(alpha_deg, float)) * (1.0 - act.downwash)
    qsc = qbar * act.Sc_m2 * act.cc_m
    dP = act.dP_Pa * (1.0 + np.asarray(d_supply, float)) * ones
    return PlantArrays(
        K=act.K_mA_per_mm * ones,
        Kci=act.Kci_mm_s_per_mA * (1.0 + np.asarray(d_kci, float)) * ones,
        i_max=act.i_max_mA * ones,
        SdP=act.S_m2 * dP,
        SdP_ref=act.S_m2 * act.dP_ref_Pa * ones,
        Ka=act.Ka_N_per_mm_s2 * ones,
        r_mm=act.r_mm * ones,
        x_min=act.x_min_mm * ones,
        x_max=act.x_max_mm * ones,
        hm_delta=qsc * ch_delta * pg,
        hm_0=qsc * (ch0 + ch_alpha * pg * alpha_s),
    )


def aero_force(x_mm, p: PlantArrays) -> np.ndarray:
    """Rod force F_aero [N] created by the hinge moment at rod position *x_mm* (docs/physics.md §3).

    Positive values oppose extension. δ = asin(x/r); cos δ = sqrt(1 − (x/r)²).
    """
    s = np.clip(x_mm / p.r_mm, -0.999, 0.999)
    cos_d = np.sqrt(1.0 - s * s)
    hm = p.hm_0 + p.hm_delta * np.arcsin(s)                 # [N·m]
    return -hm / (p.r_mm / _MM_PER_M * cos_d)               # [N]


def rod_rate(x_mm, i_mA, p: PlantArrays, loaded) -> np.ndarray:
    """Rod speed ẋ [mm/s] for a held current *i_mA* ([COMB] eq. 2, [CHEN] eq. 11).

    *loaded* (bool array) is False for a disconnected rod: no aerodynamic load and no
    damping neighbour, so ẋ = Kci·i·sqrt(S·ΔP/S·ΔP_ref).
    """
    v0 = p.Kci * i_mA
    f_aero = np.where(loaded, aero_force(x_mm, p), 0.0)
    ka = np.where(loaded, p.Ka, 0.0)
    num = p.SdP - np.sign(i_mA) * f_aero
    num = np.clip(num, 0.0, 2.0 * p.SdP)                   # stall at 0; aiding load capped
    v = v0 * np.sqrt(num / (p.SdP_ref + ka * v0 * v0))
    # mechanical stops: no motion further into a stop
    v = np.where((x_mm >= p.x_max) & (v > 0.0), 0.0, v)
    v = np.where((x_mm <= p.x_min) & (v < 0.0), 0.0, v)
    return v


def rk4_step(x_mm, i_mA, p: PlantArrays, loaded, h: float) -> np.ndarray:
    """Advance the rod over one FCC period *h* with the current held (RK4), inside the stops."""
    k1 = rod_rate(x_mm, i_mA, p, loaded)
    k2 = rod_rate(x_mm + 0.5 * h * k1, i_mA, p, loaded)
    k3 = rod_rate(x_mm + 0.5 * h * k2, i_mA, p, loaded)
    k4 = rod_rate(x_mm + h * k3, i_mA, p, loaded)
    x_new = x_mm + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return np.clip(x_new, p.x_min, p.x_max)


def float_rate_coef(delta_rad, p: PlantArrays) -> np.ndarray:
    """sqrt(|∂HM/∂δ| / (Ka·r³·cos³δ)) [1/(s·sqrt(rad))] of the floating-surface law."""
    r_m = p.r_mm / _MM_PER_M
    ka_si = p.Ka * _MM_PER_M ** 2                           # N/(mm/s)² → N/(m/s)²
    cos_d = np.cos(delta_rad)
    return np.sqrt(np.abs(p.hm_delta) / (ka_si * r_m ** 3 * cos_d ** 3))


def float_step(delta_rad, p: PlantArrays, h: float, d_min_rad, d_max_rad) -> np.ndarray:
    """Advance a disconnected (floating) surface over *h* with the closed form of the module
    docstring: sqrt|δ − δ_f| decreases by h·c/2, c = :func:`float_rate_coef`."""
    e = delta_rad - p.delta_float_rad
    root = np.sqrt(np.abs(e)) - 0.5 * h * float_rate_coef(delta_rad, p)
    e_new = np.sign(e) * np.maximum(root, 0.0) ** 2
    return np.clip(p.delta_float_rad + e_new, d_min_rad, d_max_rad)


def authority_limits(p: PlantArrays, act: ActuatorParams, n_grid: int = 721):
    """Deflections [deg] reachable in normal flight, per run: the widest interval around the
    floating angle, inside the electrical limits, where the hinge load stays below
    ``act.order_load_limit`` × S·ΔP (docs/physics.md §3: the actuator never stalls in normal
    flight, so the flight control laws do not order such deflections)."""
    grid = np.linspace(act.delta_min_deg, act.delta_max_deg, n_grid)            # (G,)
    x = act.deg_to_mm(grid)
    col = PlantArrays(**{k: np.asarray(v)[:, None] for k, v in vars(p).items()})
    ok = np.abs(aero_force(x[None, :], col)) <= act.order_load_limit * col.SdP   # (n, G)
    d_f = np.degrees(p.delta_float_rad)[:, None]
    below = grid[None, :] <= d_f
    # lowest reachable: the lowest grid point from which every point up to δ_f is ok
    bad_below = ~ok & below
    lo_idx = np.where(bad_below.any(axis=1),
                      n_grid - np.argmax(bad_below[:, ::-1], axis=1), 0)
    bad_above = ~ok & ~below
    hi_idx = np.where(bad_above.any(axis=1), np.argmax(bad_above, axis=1) - 1, n_grid - 1)
    lo = grid[np.clip(lo_idx, 0, n_grid - 1)]
    hi = grid[np.clip(hi_idx, 0, n_grid - 1)]
    return np.minimum(lo, hi), np.maximum(lo, hi)
