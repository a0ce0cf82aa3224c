"""Klipper's rule applied per axis, per target firmware and to a modelled printer.

The baseline every ``ringtune tune`` report compares against: what a user gets today by running
``TEST_RESONANCES`` and ``calibrate_shaper.py`` (:mod:`ringtune.agents.klipper.rule`) and setting
the suggested ``max_accel``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ringtune.agents.klipper.rule import (AUTOTUNE_SHAPERS, DEFAULT_DAMPING_RATIO, VERSION_FLAVOR,
    KlipperRecommendation, default_shaper_factory, recommend_klipper)
from ringtune.envs.planned_job import resolve_printer
from ringtune.envs.sim import resonance_test
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.firmware import FIRMWARES
from ringtune.shaping.shapers import available_shapers


def axis_config(fits: dict[str, KlipperRecommendation], firmware: str = "klipper") -> dict[str, Any]:
    """TuneConfig fields for Klipper's picks per axis (``{"x": rec, "y": rec}``; missing axis: off).

    ``accel`` is the lower of the axes' suggested max_accel, rounded as Klipper prints it.
    """
    d: dict[str, Any] = {"firmware": firmware}
    accels = []
    for ax in ("x", "y"):
        rec = fits.get(ax)
        if rec is None:
            d.update({f"shaper_{ax}": "none", f"freq_{ax}": 0.0, f"damping_{ax}": DEFAULT_DAMPING_RATIO})
            continue
        d.update({f"shaper_{ax}": rec.best.name, f"freq_{ax}": round(float(rec.best.freq), 1),
                  f"damping_{ax}": DEFAULT_DAMPING_RATIO})
        accels.append(rec.best.max_accel_rounded)
    d["accel"] = min(accels) if accels and min(accels) > 0 else None
    return d


def firmware_rule_setup(firmware: str, version: str) -> tuple[str, tuple[str, ...]]:
    """(shaper flavour, autotune shapers) for Klipper's rule aimed at ``firmware``.

    Klipper (and Prusa, whose shapers are Klipper's legacy closed forms) use the rule's own
    shapers; other firmwares use their own formulas restricted to Klipper's autotune list (RRF:
    mzv, 2hump_ei, 3hump_ei; Marlin: zv; Marlin FTM: all five).
    """
    if firmware not in FIRMWARES:
        raise RingtuneError(f"firmware must be one of {', '.join(FIRMWARES)}, not {firmware!r}", "firmware")
    flavor = VERSION_FLAVOR[version] if FIRMWARES[firmware].family == "klipper" else FIRMWARES[firmware].flavor
    names = tuple(n for n in AUTOTUNE_SHAPERS if n in available_shapers(flavor))
    if not names:
        raise RingtuneError(f"{firmware} offers none of Klipper's autotuned shapers", "firmware")
    return flavor, names


def recommend_axes(psds_by_axis: dict[str, Any], firmware: str = "klipper", version: str = "head",
                   scv: float = 5.0, **kw) -> tuple[dict[str, KlipperRecommendation], dict[str, Any]]:
    """Klipper's rule per axis -> (recommendations by axis, TuneConfig fields).

    On RepRapFirmware (one shaper and frequency for all axes) the axes' PSDs are fitted together as
    datasets of one fit (HEAD: pessimised over them; 0.13: averaged) and the result goes to both.
    """
    flavor, names = firmware_rule_setup(firmware, version)
    factory = kw.pop("shaper_factory", None) or default_shaper_factory(flavor)
    kw.setdefault("shapers", names)
    if FIRMWARES[firmware].one_shaper:
        joint = [p for ax in sorted(psds_by_axis) for p in _as_list(psds_by_axis[ax])]
        rec = recommend_klipper(joint, version, scv, shaper_factory=factory, **kw)
        fits = {ax: rec for ax in ("x", "y")}
    else:
        fits = {ax: recommend_klipper(_as_list(p), version, scv, shaper_factory=factory, **kw)
                for ax, p in psds_by_axis.items()}
    return fits, axis_config(fits, firmware)


def _as_list(p: Any) -> list:
    return list(p) if isinstance(p, list) else [p]


def klipper_rule_on_simulated_test(printer: Any = None, firmware: str = "klipper", version: str = "head",
                          seed: int | None = None, **kw) -> tuple[dict[str, KlipperRecommendation], dict[str, Any]]:
    """Klipper's rule on a modelled printer's simulated resonance test (one per axis), as a user
    would run TEST_RESONANCES + calibrate_shaper.py; scv is the printer's square-corner velocity.

    Without ``seed`` the test is the model's expected spectrum (no measurement noise), so the pick
    is the model's own and does not move with any study's seed; with one, each bin is scattered as a
    Welch estimate (:func:`ringtune.envs.sim.resonance_test`)."""
    printer = resolve_printer(printer)
    rng = None if seed is None else np.random.default_rng(seed)
    psds = {ax: resonance_test(printer, ax, rng=rng) for ax in ("x", "y")}
    scv = float(getattr(printer.limits, "square_corner_velocity", 5.0) or 5.0)
    return recommend_axes(psds, firmware, version, scv, **kw)
