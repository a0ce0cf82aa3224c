"""The motors of a Klipper configuration: each stepper's motor table (mm, A RMS, V, Ω, H, N·m).

What is taken (Klipper's option -> description key), per motor (``stepper_x`` -> ``[x.motor]``,
``stepper_y`` -> ``[y.motor]``, one ``[motor]`` when both are the same; the rest of the printer:
:mod:`ringtune.hardware.klipper_config`): ``rotation_distance`` (mm of belt per *motor* revolution:
divided by ``gear_ratio``; from the old ``step_distance``: ``step_distance ·
full_steps_per_rotation · microsteps``), ``microsteps``, ``full_steps_per_rotation`` ->
``steps_per_revolution``, ``[tmc… stepper_x] run_current`` (A RMS, any TMC driver),
``[autotune_tmc stepper_x] motor`` -> ``name`` and ``voltage``; a ``[motor_constants NAME]`` of the
user's files gives ``resistance``, ``inductance``, ``holding_torque``, ``max_current`` ->
``rated_current`` (they take precedence over a built-in table entry of that name).

Every default taken and every mapping made is a note; nothing is guessed silently.
"""

from __future__ import annotations

import re

from ringtune.hardware.firmware_facts import to_number, without_motor
from ringtune.hardware.klipper_source import KLIPPER_DEFAULTS, Source
from ringtune.shaping.errors import RingtuneError

_MOTOR_CONSTANTS = (("resistance", "resistance"), ("inductance", "inductance"),
                    ("holding_torque", "holding_torque"), ("max_current", "rated_current"))


def _gearing(src: Source, stepper: str) -> float:
    """The stepper's gear_ratio (``a:b[, c:d…]``, or Moonraker's list of pairs) as one factor."""
    raw = src.get(stepper, "gear_ratio")
    if raw in (None, "", ()):
        return 1.0
    where = src.where(stepper, "gear_ratio")
    pairs = raw if isinstance(raw, (list, tuple)) else [p.split(":") for p in str(raw).split(",") if p.strip()]
    g = 1.0
    for pair in pairs:
        if len(pair) != 2:
            raise RingtuneError(f"gear_ratio must be 'a:b[, c:d…]', not {raw!r}", where)
        g *= to_number(pair[0], where) / to_number(pair[1], where)
    return g


def _tmc_section(src: Source, stepper: str) -> str | None:
    found = [s for s in src.sections if re.fullmatch(rf"tmc\w+\s+{re.escape(stepper)}", s, re.I)]
    if len(found) > 1:
        src.notes.append(f"{stepper}: several driver sections ({', '.join(found)}); {found[-1]} is read")
    return found[-1] if found else None


def _motor_constants(src: Source, name: str) -> str | None:
    want = f"motor_constants {name}".lower()
    return next((s for s in src.sections if " ".join(s.split()).lower() == want), None)


def stepper_motor(src: Source, stepper: str) -> dict:
    """The motor table of one stepper (see the module docstring)."""
    if src.name(stepper) is None:
        src.notes.append(f"no [{stepper}] section: its rotation_distance and microsteps are unknown")
        return {}
    table: dict = {}
    micro = src.number(stepper, "microsteps", integer=True)
    tmc = _tmc_section(src, stepper)
    if micro is None and tmc is not None:
        micro = src.number(tmc, "microsteps", integer=True)      # old configurations kept it there
    full = src.number(stepper, "full_steps_per_rotation", KLIPPER_DEFAULTS["full_steps_per_rotation"],
                      integer=True)
    rd = _rotation_distance(src, stepper, micro, full)
    if rd is not None:
        table["rotation_distance"] = rd
    if micro is not None:
        table["microsteps"] = int(micro)
    table["steps_per_revolution"] = int(full)
    if tmc is None:
        src.notes.append(f"no [tmc… {stepper}] section: {stepper}'s run current is unknown")
    elif (rc := src.number(tmc, "run_current")) is not None:
        table["run_current"] = rc
    return _named_motor(src, stepper, full, table)


def _rotation_distance(src: Source, stepper: str, micro: int | None, full: int) -> float | None:
    """mm of belt per motor revolution: rotation_distance (or the old step_distance × full steps ×
    microsteps) over the gear ratio; None (said in a note) when unknown."""
    rd = _given_rotation_distance(src, stepper, micro, full)
    gearing = _gearing(src, stepper)
    if rd is None or gearing == 1.0:
        return rd
    src.notes.append(f"{src.where(stepper, 'gear_ratio')}: gear_ratio {gearing:g}: the motor turns "
                     f"{gearing:g}× per rotation_distance, so {rd / gearing:g} mm of belt per motor "
                     "revolution")
    return rd / gearing


def _given_rotation_distance(src: Source, stepper: str, micro: int | None, full: int) -> float | None:
    """The stepper's rotation_distance, or the old step_distance × full steps × microsteps."""
    rd = src.number(stepper, "rotation_distance")
    if rd is not None:
        return rd
    if src.get(stepper, "step_distance") is None:
        src.notes.append(f"[{stepper}] has no rotation_distance")
        return None
    sd = src.number(stepper, "step_distance")
    if micro is None:
        src.notes.append(f"{src.where(stepper, 'step_distance')}: old step_distance {sd:g} mm but no "
                         "microsteps: rotation_distance unknown")
        return None
    rd = sd * full * micro
    src.notes.append(f"{src.where(stepper, 'step_distance')}: old step_distance {sd:g} mm -> "
                     f"rotation_distance = {sd:g} × {full} × {micro} = {rd:g} mm")
    return rd


def _named_motor(src: Source, stepper: str, full: int, table: dict) -> dict:
    """``table`` with the motor [autotune_tmc] names: its name, the supply voltage and the constants
    of a motor defined in the configuration (unnamed: what is assumed, said)."""
    auto = f"autotune_tmc {stepper}"
    motor = src.get(auto, "motor")
    if motor is None:
        src.notes.append(f"no [autotune_tmc {stepper}] motor: {stepper}'s motor is not named")
        without_motor(table, src.notes, stepper)
        return table
    motor = str(motor).strip()
    table["name"] = motor
    volts = src.number(auto, "voltage")
    if volts is not None:
        table["voltage"] = volts
    else:
        src.notes.append(f"[autotune_tmc {stepper}] gives no voltage: the supply voltage is unknown")
    inline = _motor_constants(src, motor)
    if inline is not None:
        _inline_constants(src, stepper, motor, inline, full, table)
    return table


def _inline_constants(src: Source, stepper: str, motor: str, inline: str, full: int, table: dict) -> None:
    """The constants of a motor defined in the configuration (section ``inline``) into ``table``."""
    for key, out in _MOTOR_CONSTANTS:
        v = src.number(inline, key)
        if v is None:
            raise RingtuneError(f"[{inline}] has no {key}", src.label)
        table[out] = v
    steps = src.number(inline, "steps_per_revolution", integer=True)
    src.notes.append(f"{stepper}: motor {motor}: constants from [{inline}] at "
                     f"{src.where(inline, 'resistance')}")
    if steps not in (None, full):
        src.notes.append(f"{stepper}: [{inline}] steps_per_revolution {steps} but full_steps_per_rotation "
                         f"{full}; {full} is written (it is how Klipper steps the motor)")

