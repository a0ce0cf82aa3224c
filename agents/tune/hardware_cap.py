"""A firmware's compiled ceilings on the accelerations and classic jerk the search may choose:
Prusa-Firmware-Buddy's hardware limits for the model the job names (:mod:`ringtune.shaping.prusa_limits`).

A value above them is not an option on that printer (M201 and M205 cannot raise them), so the
search range, each feature group's range and the jerk's stop there, and ``tune`` says what it
holds to (or that the job names no model it knows, and nothing is held).
"""

from __future__ import annotations

import dataclasses
from typing import Any, Callable

from ringtune.agents.tune.space import SearchSpace
from ringtune.envs.planned_job import resolve_job
from ringtune.shaping.config_plan import as_read_by, for_firmware
from ringtune.shaping.prusa_limits import HardwareLimits, hardware_limits, hardware_note, job_model


def job_hardware(printer: Any, job: Any, firmware: str) -> tuple[HardwareLimits | None, str | None]:
    """(the model's hardware limits or None, the model the job names or None) on ``firmware`` (only
    ``prusa`` has them) for ``job`` (a path, text, parsed job, or None: the built-in print, which
    names no model)."""
    if firmware != "prusa":
        return None, None
    _, parsed = resolve_job(job, for_firmware(printer.limits, as_read_by(firmware)))
    model = job_model(parsed)
    return hardware_limits(model), model


def accel_ceiling(hw: HardwareLimits | None) -> float | None:
    """The X/Y acceleration ceiling of ``hw``, mm/s² (None: none)."""
    return None if hw is None else float(min(hw.max_accel[:2]))


def corner_ceiling(hw: HardwareLimits | None, junction: str) -> float | None:
    """The ceiling on the corner rule's value under ``junction`` (classic jerk X/Y, mm/s), or None."""
    return float(min(hw.jerk[:2])) if hw is not None and junction == "jerk" else None


def held_range(rng: tuple | None, top: float | None) -> tuple | None:
    """``rng`` (lo, hi) with its top held to ``top`` (None: not held; a range above it: at it)."""
    if rng is None or top is None:
        return rng
    return (min(rng[0], top), min(rng[1], top))


def held_to_ceiling(space: SearchSpace, printer: Any, job: Any, note: Callable[[str], None]) -> SearchSpace:
    """``space`` with its acceleration range held under the firmware's ceiling for ``job`` (said in a
    note, as is a Prusa job whose model ringtune does not know); unchanged on other firmwares."""
    if space.firmware != "prusa":
        return space
    hw, model = job_hardware(printer, job, space.firmware)
    top = accel_ceiling(hw)
    note(f"ringtune tune: {hardware_note(model)}")
    if top is None or space.accel[1] <= top:
        return space
    return dataclasses.replace(space, accel=held_range(space.accel, top), accel_basis=(
        f"Prusa-Firmware-Buddy's hardware limit on the {model} (HWLIMIT_NORMAL_MAX_ACCELERATION X/Y, "
        f"{top:.0f} mm/s²; M201 cannot raise it)"))
