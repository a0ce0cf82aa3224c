"""Prusa-Firmware-Buddy's hardware limits: the ceilings its planner holds M201, M203 and M205 to, per model.

Buddy's ``Planner::apply_settings`` (``lib/Marlin/Marlin/src/module/planner.cpp``) runs with the lower
of each user setting — M201's per-axis acceleration, M203's per-axis speed, M205's classic jerk — and
the model's compiled ``HWLIMIT_NORMAL_MAX_ACCELERATION`` / ``_MAX_FEEDRATE`` / ``_JERK``
(``HWLIMIT_STEALTH_*`` in stealth mode), from ``include/marlin/Configuration_<MODEL>.h``: an
``M201 X12000`` on a model held to 7000 runs at 7000, and with it every move whose X share would
need more. A job sliced for a Prusa names
its model in PrusaSlicer's printer check, ``M862.3 P "MK4"``; the firmware's mode (normal or
stealth) is the printer's own setting, which no file says.

The table holds the models whose limits were read from Buddy's source (MK4 at commit 0908c808,
CORE One at 21c125d6; other versions may differ): X, Y, Z, E in mm/s² and mm/s. Other models (MK4S,
MK3.9, MK3.5, MINI, XL) are not held here: the versions read of their configurations define no
HWLIMIT, and their limits are not guessed.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class HardwareLimits:
    """A model's ceilings (x, y, z, e): acceleration in mm/s², speed and classic jerk in mm/s, for
    one mode."""

    max_accel: tuple
    max_velocity: tuple
    jerk: tuple


#: model (as ``M862.3 P`` names it) -> mode -> ceilings
PRUSA_HARDWARE_LIMITS: dict[str, dict[str, HardwareLimits]] = {
    "MK4": {"normal": HardwareLimits((7000.0, 7000.0, 200.0, 2500.0), (300.0, 300.0, 40.0, 100.0),
                                     (10.0, 10.0, 2.0, 10.0)),
            "stealth": HardwareLimits((2500.0, 2500.0, 200.0, 2500.0), (160.0, 160.0, 40.0, 100.0),
                                      (8.0, 8.0, 2.0, 10.0))},
    "COREONE": {"normal": HardwareLimits((10000.0, 10000.0, 1000.0, 6000.0), (350.0, 350.0, 35.0, 100.0),
                                         (10.0, 10.0, 2.0, 10.0)),
                "stealth": HardwareLimits((2500.0, 2500.0, 200.0, 2500.0), (160.0, 160.0, 12.0, 100.0),
                                          (8.0, 8.0, 2.0, 10.0))},
}
#: the mode ringtune plans in: the firmware's default (stealth is a setting on the printer)
MODE = "normal"
#: mm/s²: the lowest X acceleration ceiling of stealth mode over the models held
STEALTH_ACCEL = min(h["stealth"].max_accel[0] for h in PRUSA_HARDWARE_LIMITS.values())


def job_model(job) -> str | None:
    """The printer model a parsed job (:class:`ringtune.shaping.job.Job`) names in its first
    ``M862.3 P "…"`` (PrusaSlicer's printer check), upper case; None where it names none."""
    for e in getattr(job, "events", ()) or ():
        if e.command == "M862.3" and isinstance(e.params.get("P"), str):
            return e.params["P"].strip().upper()
    return None


def hardware_limits(model: str | None, mode: str = MODE) -> HardwareLimits | None:
    """The ceilings of ``model`` in ``mode``; None for a model the table does not hold."""
    return PRUSA_HARDWARE_LIMITS.get((model or "").upper(), {}).get(mode)


def hardware_note(model: str | None) -> str:
    """One sentence on what Buddy's hardware limits mean for a job of ``model`` (None: it names none)
    and what ringtune does with them."""
    held = " and ".join(f"{m} {h['normal'].max_accel[0]:.0f}" for m, h in PRUSA_HARDWARE_LIMITS.items())
    lim = hardware_limits(model)
    if lim is not None:
        return (f"Prusa-Firmware-Buddy on the {model} (the job's M862.3) holds M201 X/Y to "
                f"{lim.max_accel[0]:.0f}/{lim.max_accel[1]:.0f} mm/s² and M203 X/Y to {lim.max_velocity[0]:.0f}/"
                f"{lim.max_velocity[1]:.0f} mm/s, M205 X/Y jerk to {lim.jerk[0]:g}/{lim.jerk[1]:g} mm/s in normal mode "
                f"(HWLIMIT_NORMAL_*; stealth mode: "
                f"{hardware_limits(model, 'stealth').max_accel[0]:.0f} mm/s²): planned with them, "
                "the accelerations searched within them; a print in stealth mode runs slower than planned")
    which = f"the {model} the job's M862.3 names is not among those ringtune knows" if model else \
        "the job names no model (M862.3)"
    return (f"Prusa-Firmware-Buddy holds M201 X/Y and M203 X/Y to its model's hardware limits (normal mode, "
            f"mm/s²: {held}; stealth mode {STEALTH_ACCEL:.0f}), and {which}: planned without them, so an "
            "acceleration above your model's limit runs at that limit, slower than planned")
