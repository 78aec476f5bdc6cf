"""LTI against LPV geometric filter on the scenarios of [VANEK] §5, run by
``python -m detectors.vanek_compare [--noise-scale S]``.

* isolation: left elevator runaway at 5 °/s from 20 s, 200 kt / 26 000 ft, left elevator
  monitored — peak of the aileron residual [deg of aileron-equivalent] and its ratio to the
  threshold ([VANEK] §5: LTI 0.175, LPV 0.105, normalised units);
* detection: left inboard aileron liquid jam at 20 s, 170 kt / 23 000 ft, rod bias 4.09 mm
  (0.134 of the 25° travel, [VANEK]'s normalised −0.134) — detection delay and DTP = delay /
  required detection time of the campaign defaults ([VANEK]: LTI 0.00725, LPV 0.00508);
* fault-free cruise in moderate turbulence — peak residual / threshold.

Variants lti, lpv and lpv-affine, and lti-hinf and one-step when python-control and slycot are
installed.

Each scenario is fitted on its own fault-free cruise learning set (same monitored surface,
moderate turbulence, :data:`LEARNING_POINTS`). ``noise_scale`` multiplies the σ of every
aircraft sensor (:class:`scenarios.aircraft.data.AircraftSensorParams`).
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np
import pandas as pd

#: Flight points (VCAS [kt], altitude [ft]) of the fault-free cruise learning runs (est.:
#: the cruise part of the realistic envelope, [VANEK] §5 "various cruise conditions").
LEARNING_POINTS = ((170.0, 23000.0), (200.0, 26000.0), (220.0, 20000.0), (240.0, 30000.0),
                   (260.0, 28000.0), (280.0, 33000.0))
#: Mass [t] and CG [% MAC] of every run ([VANEK] §5: 200 000 kg, x_cg = 0.3).
MASS_T, CG_PCT = 200.0, 30.0
#: Liquid-jam rod bias [mm] (module docstring).
JAM_MM = -4.09


def _rows(surface, fault, seed, vcas, alt, magnitude=None, duration_s=40.0, stream=0):
    from scenarios.simulate import single_run

    kind = "elevator" if "elevator" in surface else "aileron"
    r = single_run(kind, "cruise", fault, seed=seed, onset_s=20.0, magnitude=magnitude,
                   duration_s=duration_s, vcas_kt=vcas, alt_ft=alt, mass_t=MASS_T, cg_pct=CG_PCT)
    r["surface"] = surface
    r["stream"] = stream
    return r


def compare(noise_scale: float = 1.0, seed: int = 0) -> pd.DataFrame:
    """One row per scenario and variant: residual peak [deg], peak / threshold, threshold
    [deg], detection delay [s] (NaN: none) and DTP."""
    from campaign.config import REQUIRED_DETECTION_TIME_S
    from scenarios.aircraft.data import AIRCRAFT_SENSORS
    from scenarios.aircraft.loop import simulate_aircraft

    from .vanek_geometric import AFFINE_VARIANTS, HINF_VARIANTS, VARIANTS, VanekGeometric

    variants = VARIANTS + AFFINE_VARIANTS
    try:                                  # the H∞ variants when their extra is there
        import control  # noqa: F401
        import slycot  # noqa: F401
        variants += HINF_VARIANTS
    except ImportError:
        pass

    if not noise_scale > 0.0:
        raise ValueError(f"noise_scale must be > 0, got {noise_scale!r}")
    sensors = dataclasses.replace(AIRCRAFT_SENSORS, **{
        f.name: getattr(AIRCRAFT_SENSORS, f.name) * noise_scale
        for f in dataclasses.fields(AIRCRAFT_SENSORS)})
    scenarios = {
        "elevator runaway (isolation)": _rows("left_elevator", "runaway", seed + 1, 200.0,
                                              26000.0, magnitude=5.0),
        "aileron liquid jam": _rows("left_inboard_aileron", "liquid_jam", seed + 2, 170.0,
                                    23000.0, magnitude=JAM_MM),
        "fault-free cruise": _rows("left_inboard_aileron", "none", seed + 3, 250.0, 28000.0),
    }
    fitted = {}
    out = []
    for name, row in scenarios.items():
        surface = str(row["surface"].iloc[0])
        if surface not in fitted:
            learn = pd.concat([_rows(surface, "none", seed + 100 + i, v, h, stream=i)
                               for i, (v, h) in enumerate(LEARNING_POINTS)], ignore_index=True)
            fitted[surface] = VanekGeometric(variants=variants).fit(simulate_aircraft(learn,
                                                                     aircraft_sensors=sensors)[0])
        det = fitted[surface]
        sig, _ = simulate_aircraft(row, aircraft_sensors=sensors)
        detections = det.detect(sig)
        fault = str(row["fault"].iloc[0])
        for variant, d in detections.items():
            tau = det.thresholds_deg_[variant]
            delay = (np.argmax(d.alarm[0]) * sig.ts - 20.0) if d.alarm[0].any() else np.nan
            required = REQUIRED_DETECTION_TIME_S.get(fault, np.nan)
            out.append({"scenario": name, "variant": variant,
                        "peak_deg": float(d.residual[0].max() * tau),
                        "peak_over_threshold": float(d.residual[0].max()),
                        "threshold_deg": tau, "delay_s": delay,
                        "dtp": delay / required if fault != "none" else np.nan})
    return pd.DataFrame(out)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m detectors.vanek_compare",
                                description=__doc__.split("\n\n")[0])
    p.add_argument("--noise-scale", type=float, default=1.0,
                   help="factor on the σ of every aircraft sensor (default 1)")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    if not args.noise_scale > 0.0:
        p.error(f"--noise-scale must be > 0, got {args.noise_scale}")
    with pd.option_context("display.width", 120, "display.precision", 4):
        print(compare(args.noise_scale, args.seed).to_string(index=False))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
