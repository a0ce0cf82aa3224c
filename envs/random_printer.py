"""Random printers for the randomised environment (``ringtune/Tune-v0``): a description drawn from
the randomisation ranges (:func:`random_printer_dict`)."""

from __future__ import annotations

import math

import numpy as np


def random_printer_dict(rng: np.random.Generator, base: dict | None = None) -> dict:
    """A printer description (TOML mapping) drawn from the randomisation ranges.

    Per axis: primary mode 20–130 Hz (log-uniform), damping 0.02–0.2 (log-uniform); with
    probability 1/2 one extra mode at 1.3–3× the primary carrying 5–30 % of the response; moving
    mass 0.3–1.5 kg (X) / 0.5–2.5 kg (Y). Print mass 0–0.5 kg, motor force 15–60 N, kinematics
    cartesian (3/4) or corexy with belt mismatch ±0.1. Limits are ``base``'s (so plans are shared).
    """
    def logu(lo, hi):
        return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))

    def axis(mass_lo, mass_hi):
        f = logu(20.0, 130.0)
        modes = [{"freq": f, "damping": logu(0.02, 0.2)}]
        if rng.uniform() < 0.5:
            share = float(rng.uniform(0.05, 0.3))
            modes[0]["share"] = 1.0 - share
            modes.append({"freq": f * float(rng.uniform(1.3, 3.0)), "damping": logu(0.02, 0.2),
                          "share": share})
        return {"mass": float(rng.uniform(mass_lo, mass_hi)), "modes": modes}

    corexy = rng.uniform() < 0.25
    d = {
        "name": "random",
        "kinematics": "corexy" if corexy else "cartesian",
        "limits": dict((base or {}).get("limits", {})),
        "x": axis(0.3, 1.5),
        "y": axis(0.5, 2.5),
        "print_mass": float(rng.uniform(0.0, 0.5)),
        "motor": {"force": float(rng.uniform(15.0, 60.0))},
    }
    if corexy:
        d["belts"] = {"mismatch": float(rng.uniform(-0.1, 0.1))}
    return d
