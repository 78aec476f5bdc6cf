"""The industrial position monitor: the state of practice every other detector must beat.

Airbus-style servo-loop monitoring (Goupil 2010/2011, [CHEN] §1) compares redundant and
modelled views of the same position and raises an alarm when a discrepancy stays above a
threshold for a confirmation time. Three consistency checks, each optional:

``loop``
    the COM rod acquisition against the output of a *nominal* servo-loop model driven by the
    order u — the model of PHYSICS §3 with the nominal actuator parameters, loaded by the
    hinge moment at the *measured* flight point (the monitor never sees the true one). It
    catches runaways (the rod leaves the order) and solid jams (the rod stops following it).
``com_mon``
    COM against MON rod acquisition. A liquid jam biases the acquisition the loop closes on:
    the loop hides it on COM but MON keeps the offset (PHYSICS §5).
``surface``
    the surface sensor, converted to rod travel x = r·sin δ, against the MON rod position —
    a disconnection leaves the rod healthy while the surface floats away. Skipped when the
    surface has no sensor.

Thresholds are learned on fault-free learning runs: τ_c = ``safety`` × the largest |r_c| seen
(never below ``floor_mm``). The normalised residual is max_c |r_c|/τ_c; the alarm is raised
once it has been ≥ 1 for ``confirm_s`` and is then latched.
"""

from __future__ import annotations

import numpy as np

from scenarios.kernels import resolve_engine, servo_model
from scenarios.servo import plant_arrays, rk4_step
from scenarios.signals import Signals

from .base import Capabilities, Detection, Detector, confirm

CHECKS = ("loop", "com_mon", "surface")


class PositionMonitor(Detector):
    """Threshold-and-confirmation monitor on position discrepancies.

    Parameters
    ----------
    safety : float
        Threshold = safety × largest fault-free residual of the learning set (> 1).
    confirm_s : float
        Confirmation time [s]: the discrepancy must persist this long (≥ 0).
    checks : sequence of str
        Which consistency checks run: any of ``"loop"``, ``"com_mon"``, ``"surface"``.
    floor_mm : float
        Smallest threshold of a check [mm] (guards against a learning set without motion).
    """

    capabilities = Capabilities(needs_fit=True, needs_surface_sensor=False, causal=True)

    def __init__(self, safety=1.5, confirm_s=0.05, checks=CHECKS, floor_mm=0.05):
        self.safety = safety
        self.confirm_s = confirm_s
        self.checks = checks
        self.floor_mm = floor_mm

    def validate_params(self) -> None:
        if not (isinstance(self.safety, (int, float)) and self.safety > 1.0):
            raise ValueError(f"safety must be a number > 1, got {self.safety!r}")
        if not (isinstance(self.confirm_s, (int, float)) and self.confirm_s >= 0.0):
            raise ValueError(f"confirm_s must be ≥ 0 s, got {self.confirm_s!r}")
        checks = [self.checks] if isinstance(self.checks, str) else list(self.checks)
        bad = [c for c in checks if c not in CHECKS]
        if bad or not checks:
            raise ValueError(f"checks must be a non-empty list of {list(CHECKS)}, got {self.checks!r}")
        if not (isinstance(self.floor_mm, (int, float)) and self.floor_mm > 0.0):
            raise ValueError(f"floor_mm must be > 0 mm, got {self.floor_mm!r}")

    # ---- residuals ---------------------------------------------------------------------
    def _active_checks(self, signals: Signals) -> list[str]:
        checks = [self.checks] if isinstance(self.checks, str) else list(self.checks)
        if not signals.has_surface_sensor:
            checks = [c for c in checks if c != "surface"]
        return checks

    @staticmethod
    def model_output(signals: Signals, engine: str | None = None) -> np.ndarray:
        """Nominal closed-loop servo model driven by the order (PHYSICS §2–3) [mm].

        *engine*: ``"compiled"`` (:func:`scenarios.kernels.servo_model`) or ``"numpy"`` (the
        reference loop below); default :func:`scenarios.kernels.current_engine`.
        """
        act = signals.actuator
        sch = signals.schedule
        plant = plant_arrays(act, qbar_pa=sch["qbar_pa"], alpha_deg=sch["alpha_deg"],
                             mach=sch["mach"])
        if resolve_engine(engine) == "compiled":
            return servo_model(signals.command, signals.rod_com[:, 0], plant, signals.ts)
        n, T = signals.command.shape
        out = np.empty((n, T))
        x = signals.rod_com[:, 0].astype(float).copy()
        i_prev = np.zeros(n)
        loaded = np.ones(n, dtype=bool)
        u = signals.command
        for k in range(T):
            out[:, k] = x
            i_new = np.clip(plant.K * (u[:, k] - x), -plant.i_max, plant.i_max)
            x = rk4_step(x, i_prev, plant, loaded, signals.ts)
            i_prev = i_new
        return out

    def residuals(self, signals: Signals) -> dict[str, np.ndarray]:
        """The raw residual [mm] of each active check, shape (n_runs, n_steps)."""
        out = {}
        checks = self._active_checks(signals)
        if "loop" in checks:
            out["loop"] = signals.rod_com - self.model_output(signals)
        if "com_mon" in checks:
            out["com_mon"] = signals.rod_com - signals.rod_mon
        if "surface" in checks:
            act = signals.actuator
            out["surface"] = act.r_mm * np.sin(np.radians(signals.surface)) - signals.rod_mon
        return out

    # ---- contract ----------------------------------------------------------------------
    def _fit(self, signals: Signals) -> None:
        self.validate_params()
        res = self.residuals(signals)
        self.thresholds_mm_ = {
            name: float(max(self.safety * np.max(np.abs(r)), self.floor_mm))
            for name, r in res.items()
        }
        self.learning_runs_ = int(signals.n_runs)

    def _detect(self, signals: Signals) -> Detection:
        res = self.residuals(signals)
        missing = sorted(set(res) - set(self.thresholds_mm_))
        if missing:
            raise ValueError(f"no learned threshold for check(s) {missing}: the learning set "
                             "lacked the signals these checks need")
        norm = np.zeros((signals.n_runs, signals.n_steps))
        for name, r in res.items():
            np.maximum(norm, np.abs(r) / self.thresholds_mm_[name], out=norm)
        n_confirm = int(round(self.confirm_s / signals.ts)) + 1
        alarm = confirm(norm >= 1.0, n_confirm)
        return Detection(alarm=alarm, residual=norm)
