"""The printer from RepRapFirmware's ``config.g``: kinematics, steps/mm, limits, currents, shaper.

RRF's units differ between commands (``Duet3D/wiki-content:User_manual/Reference/Gcodes.md``):

| command | meaning, RRF units | description key (units of the description) |
|---|---|---|
| ``M669 K`` | kinematics: 0 / ``"cartesian"``, 1 / ``"coreXY"``, 2 / ``"coreXZ"`` | ``kinematics`` |
| ``M92 X Y`` | steps per mm | ``motor.steps_per_mm`` |
| ``M201 X Y Z E`` | max acceleration, mm/s² | ``limits.max_accel`` |
| ``M203 X Y Z E`` | max speed, **mm/min** | ``limits.max_velocity`` = /60, mm/s; ``limits.velocity`` = max(X, Y) |
| ``M204 P T`` | print / travel acceleration, mm/s² | ``limits.accel``, ``limits.travel_accel`` |
| ``M207 S R F T Z`` | firmware retraction: length, extra restore (mm), retract speed (and the restore's unless T), restore speed (mm/min), Z hop (mm) | ``limits.retract_length``, ``unretract_extra_length``, ``retract_speed``, ``unretract_speed`` (mm/s), ``retract_zlift`` |
| ``M566 X Y Z E`` | instantaneous speed change ("jerk"), **mm/min** | ``limits.jerk`` = /60, mm/s; ``junction = "jerk"`` |
| ``M906 X Y`` | motor current, mA **peak** | ``motor.run_current`` = mA / 1000 / √2, A RMS |
| ``M593 P"type" F S`` | the one shaper of every axis (``firmware.md`` §3.1): F Hz, S damping | ``[current]`` |

A later line replaces what an earlier one set (config.g runs top to bottom). ``E`` values with
colons (one per extruder) are read as their first entry.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

from ringtune.hardware.config_dialect import refuse_other_dialect
from ringtune.hardware.firmware_facts import FirmwareFacts, axis_numbers, gcode_words, place_gcode_motors, to_number
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.textfile import read_text_file

#: M669 K (number or RRF 3.7 name, lower case) -> kinematics of the model
_KINEMATICS = {"0": "cartesian", "1": "corexy", "2": "corexz",
               "cartesian": "cartesian", "corexy": "corexy", "corexz": "corexz"}
_READ = ("M669", "M92", "M201", "M203", "M204", "M566", "M906", "M593", "M207")


class _Config:
    """The words of config.g's lines that are read: ``seen[code][letter] = (line number, value)``,
    the last line setting a word winning."""

    def __init__(self, text: str, path: str):
        self.path, self.seen = path, {}
        for n, raw in enumerate(text.splitlines(), 1):
            words = gcode_words(raw.split(";", 1)[0])
            if words is not None and words[0] in _READ:
                for letter, value in words[1].items():
                    self.seen.setdefault(words[0], {})[letter] = (n, value)
        if not self.seen:
            raise RingtuneError("no M669/M92/M201/M203/M204/M566/M906/M593 line: not a config.g", path)

    def where(self, cmd: str, letter: str) -> str:
        """``config.g:<line>: <cmd> <letter>`` of a word that was read."""
        return f"{self.path}:{self.seen[cmd][letter][0]}: {cmd} {letter}"

    def num(self, cmd: str, letter: str) -> float | None:
        """The number of ``cmd``'s word ``letter`` (the first of a colon list), None when not set;
        an expression ``{…}`` is refused."""
        n_value = self.seen.get(cmd, {}).get(letter)
        if n_value is None or n_value[1] == "":
            return None
        value = n_value[1].split(":")[0]
        if value.startswith("{"):
            raise RingtuneError(f"an expression {value!r} cannot be read here; write the number",
                                self.where(cmd, letter))
        return to_number(value, self.where(cmd, letter))


def _kinematics(cfg: _Config, notes: list[str]) -> str:
    """M669 K, RepRapFirmware's default (Cartesian) when not given."""
    k = cfg.seen.get("M669", {}).get("K")
    if k is None:
        notes.append("no M669 K: RepRapFirmware's default kinematics, Cartesian")
        return "cartesian"
    kin = _KINEMATICS.get(k[1].strip().lower())
    if kin is None:
        raise RingtuneError(f"kinematics K{k[1]} is not one the printer model has (0/cartesian, "
                            "1/coreXY, 2/coreXZ)", cfg.where("M669", "K"))
    return kin


def _accels(cfg: _Config, notes: list[str]) -> dict:
    """``limits`` from M204 (P printing, T travel) and M201 (per-axis; the printing acceleration
    when M204 P is missing)."""
    limits: dict = {}
    accel = cfg.num("M204", "P")
    amax = axis_numbers(cfg.num, "M201")
    if accel is not None:
        limits["accel"] = accel
    elif amax is not None:
        limits["accel"] = min(amax[0], amax[1])
        notes.append(f"no M204 P: limits.accel = {limits['accel']:g} mm/s², the smaller of M201 X and Y "
                     "(RRF then limits printing moves by M201 only)")
    else:
        notes.append("no M204 P nor M201: the acceleration is unknown")
    if cfg.num("M204", "T"):
        limits["travel_accel"] = cfg.num("M204", "T")
    if amax is not None:
        limits["max_accel"] = amax
        notes.append("RepRapFirmware's M204 has no retract acceleration: retractions (E-only moves) are "
                     "planned at the printing acceleration under M201 E")
    return limits


def _speeds_and_jerk(cfg: _Config, notes: list[str]) -> dict:
    """``limits`` from M203 (per-axis speeds, mm/min) and M566 (per-axis jerk, mm/min)."""
    limits: dict = {}
    vmax = axis_numbers(cfg.num, "M203", 1 / 60)
    if vmax is not None:
        limits.update(max_velocity=vmax, velocity=max(vmax[0], vmax[1]))
    jerk = axis_numbers(cfg.num, "M566", 1 / 60)
    if jerk is not None:
        limits.update(junction="jerk", jerk=jerk)
    else:
        notes.append("no M566: the allowed speed change at corners is unknown")
    return limits


def printer_facts_from_rrf(path: str | Path) -> FirmwareFacts:
    """Facts from ``config.g`` (see the module docstring)."""
    path = str(path)
    text = read_text_file(path, "config.g")
    refuse_other_dialect(text, path, "rrf")
    cfg = _Config(text, path)
    notes: list[str] = []
    description: dict = {"kinematics": _kinematics(cfg, notes)}
    limits = {**_accels(cfg, notes), **_speeds_and_jerk(cfg, notes), **_retraction(cfg, notes)}
    description["limits"] = limits
    place_gcode_motors(description, cfg.num, 1e-3 / math.sqrt(2.0))   # RRF's M906: mA peak
    if "M906" in cfg.seen:
        notes.append("M906 currents are peak values (RRF); run_current = peak / √2 (RMS)")
    else:
        notes.append("no M906: the motor current is unknown")
    notes.append("config.g names no motor and gives steps/mm only: rotation_distance, microsteps and the "
                 "motor's constants are unknown")
    current = _current(path, text, cfg.seen, cfg.num, limits, notes)
    if current is not None:
        description["current"] = current
    return FirmwareFacts(description, notes, path)


def _retraction(cfg: _Config, notes: list[str]) -> dict:
    """``limits`` from M207 (S length, R extra restore, F retract and restore speed, T the restore's own,
    Z hop; mm, mm/min): what a job's G10/G11 move. None: said."""
    length, f, t = cfg.num("M207", "S"), cfg.num("M207", "F"), cfg.num("M207", "T")
    if length is None or (length and not f):
        notes.append("no M207 S and F (firmware retraction): what a job's G10/G11 move is unknown; a job that uses "
                     "them is planned with stops there that take no time")
        return {}
    speeds = {"retract_speed": f / 60.0, "unretract_speed": (t or f) / 60.0} if f else {}
    hop = {"retract_zlift": cfg.num("M207", "Z")} if cfg.num("M207", "Z") else {}
    return {"retract_length": length, "unretract_extra_length": cfg.num("M207", "R") or 0.0, **speeds, **hop}


#: lines of config.g that run other files (M98 P"file", M501 runs config-override.g): what they set is
#: not read here
_CALLS = re.compile(r'^\s*(?:M98\s+P"([^"]+)"|M501\b)', re.M | re.I)


def _current(path, text, seen, num, limits, notes) -> dict | None:
    """``[current]`` from M593; None (unknown) when config.g has no M593 but runs other files
    (``M98 P"…"``, ``M501``) that may set it."""
    calls = [m.group(1) or "config-override.g (M501)" for m in _CALLS.finditer(text)]
    if "M593" not in seen and calls:
        notes.append(f"no M593 in {path}, which runs {', '.join(calls)} (not read here): the input shaping the "
                     "printer runs today is unknown ([current] not written)")
        return None
    current: dict = {"source": path, "firmware": "rrf"}
    shaper = _m593(seen, num, notes)
    for ax in "xy":                       # RRF shapes every axis with the one shaper
        current.update({f"{key}_{ax}": value for key, value in shaper.items()})
    if "accel" in limits:
        current["accel"] = limits["accel"]
    return current


def _m593(seen, num, notes) -> dict:
    """The one shaper of config.g's M593 as ``{"shaper", "freq" (Hz), "damping" (when given)}``, with
    RRF's defaults said; ``{"shaper": "none"}`` for no shaping."""
    shaper = seen.get("M593", {}).get("P")
    if "M593" not in seen or (shaper is not None and shaper[1].strip().lower() == "none"):
        notes.append("no M593 (or P\"none\"): the printer runs without input shaping")
        return {"shaper": "none"}
    if shaper is None:
        name = "zvd"
        notes.append("M593 without P: RepRapFirmware uses zvd when a frequency is given")
    else:
        name = shaper[1].strip().lower().replace("-", "").replace("_", "")
    f = num("M593", "F")
    if f is None:
        f = 40.0
        notes.append("M593 without F: RepRapFirmware's default 40 Hz")
    found = {"shaper": name, "freq": f}
    d = num("M593", "S")
    if d is None:
        notes.append("M593 without S: the damping is RRF's default (0.1 up to 3.5, 0.05 in 3.6-dev)"
                     " and unknown here")
    else:
        found["damping"] = d
    return found
