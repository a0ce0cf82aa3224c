"""What a firmware configuration says about the printer, as plain data.

The readers (:mod:`ringtune.hardware.klipper_config`, :mod:`ringtune.hardware.marlin_config`,
:mod:`ringtune.hardware.rrf_config`) return a :class:`FirmwareFacts`: a dict in the form of the
printer description (TOML; ``kinematics``, ``limits``, ``motor`` or ``x.motor``/``y.motor``,
``current``) and the notes on what could not be known or was mapped. ``hardware`` cannot import
``envs``: whether a motor name is in the built-in table is decided by the caller.

Units as in the description: mm, mm/s, mm/s², A (RMS), V, Ω, H, N·m, Hz.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

from ringtune.shaping.errors import RingtuneError

#: kinematics the printer model has
KINEMATICS = ("cartesian", "corexy", "corexz")


@dataclass
class FirmwareFacts:
    """``description``: printer-description dict; ``notes``: one line each, for stderr and TOML
    comments; ``source``: the file (or URL) read."""

    description: dict = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    source: str = ""


def to_number(value, where: str, integer: bool = False) -> float | int:
    """A finite number from a config value (string or number), else a RingtuneError at ``where``."""
    try:
        v = int(value) if integer and not isinstance(value, float) else float(value)
    except (TypeError, ValueError):
        kind = "an integer" if integer else "a number"
        raise RingtuneError(f"must be {kind}, not {value!r}", where) from None
    if not math.isfinite(v):
        raise RingtuneError(f"must be finite, not {value!r}", where)
    return v


def place_motors(description: dict, x: dict, y: dict) -> None:
    """Put the X and Y motor tables into ``description``: one ``[motor]`` when they are equal, else
    ``[x.motor]`` and ``[y.motor]`` (on CoreXY/CoreXZ: motor A and motor B / the Y motor)."""
    if x == y:
        if x:
            description["motor"] = dict(x)
        return
    for ax, table in (("x", x), ("y", y)):
        if table:
            description.setdefault(ax, {})["motor"] = dict(table)


def place_gcode_motors(description: dict, num, amps_per_m906_unit: float) -> None:
    """The X and Y motor tables of a Marlin M503 report or an RRF config.g, placed as
    :func:`place_motors` does: ``steps_per_mm`` from M92, ``run_current`` (A RMS) from M906 times
    ``amps_per_m906_unit`` (Marlin: mA RMS -> 1e-3; RRF: mA peak -> 1e-3/√2). ``num(code, letter)``
    gives a word's number or None."""
    motors = {}
    for ax in "XY":
        table = {}
        if num("M92", ax) is not None:
            table["steps_per_mm"] = num("M92", ax)
        if num("M906", ax) is not None:
            table["run_current"] = num("M906", ax) * amps_per_m906_unit
        motors[ax] = table
    place_motors(description, motors["X"], motors["Y"])


def axis_numbers(num, cmd: str, scale: float = 1.0) -> list[float] | None:
    """``cmd``'s X Y Z E numbers times ``scale`` (0 where missing), None when it gives none;
    ``num(code, letter)`` gives a word's number or None (an M503 report's, a config.g's)."""
    vals = [num(cmd, a) for a in "XYZE"]
    return None if all(v is None for v in vals) else [(v or 0.0) * scale for v in vals]


def motor_tables(description: dict) -> dict[str, dict]:
    """The motor tables of a description by where they sit: ``motor``, ``x.motor``, ``y.motor``."""
    parents = {"motor": description, "x.motor": description.get("x"), "y.motor": description.get("y")}
    return {where: parent["motor"] for where, parent in parents.items()
            if isinstance(parent, dict) and isinstance(parent.get("motor"), dict)}


def gcode_words(line: str) -> tuple[str, dict[str, str]] | None:
    """``("M92", {"X": "80.00", "Y": "80.00"})`` from a G-code line without its comment; a letter with
    no value maps to ``""``; a quoted string (RRF ``P"zvd"``) loses its quotes; ``None`` for a line
    without a command. Letters are upper-cased."""
    m = re.match(r"\s*([GMgm])(\d+(?:\.\d+)?)(.*)$", line)
    if not m:
        return None
    words: dict[str, str] = {}
    for letter, quoted, value in re.findall(r'([A-Za-z])\s*(?:"([^"]*)"|([^\sA-Za-z"]*))', m.group(3)):
        words[letter.upper()] = quoted if quoted else value
    return m.group(1).upper() + m.group(2), words


#: keys that describe the motor itself (a built-in ``name`` stands for all of them)
MOTOR_CONSTANTS = ("holding_torque", "rated_current", "resistance", "inductance")


def without_motor(table: dict, notes: list[str], where: str) -> None:
    """Make a motor table with no motor (no ``name``, no constants) a drive only, in place.

    The description counts ``steps_per_revolution`` among the motor's constants, so it cannot stand
    alone: it is dropped, and when it is not the 200 the loader then assumes, ``rotation_distance``
    (+ ``microsteps``) is replaced by the ``steps_per_mm`` they give, so the step size stays right.
    """
    if {"name", *MOTOR_CONSTANTS} & table.keys():
        return
    steps = table.pop("steps_per_revolution", None)
    rd, micro = table.get("rotation_distance"), table.get("microsteps")
    if steps not in (None, 200) and rd and micro:
        table["steps_per_mm"] = steps * micro / rd
        del table["rotation_distance"]
        notes.append(f"{where}: no motor named, so its {steps} steps per revolution are kept as "
                     f"steps_per_mm = {steps} × {micro} / {rd:g} = {table['steps_per_mm']:g}")
