"""Setting and firmware-extension commands of the G-code reader (mixin of its reader class):
Marlin's M201/M203/M204/M205/M220, RepRapFirmware's M566 (mm/min), Klipper's extended commands (SET_VELOCITY_LIMIT,
SET_INPUT_SHAPER, TUNING_TOWER and any other ``NAME KEY=VALUE`` command, kept as an event).
Units: mm, mm/s, mm/s², Hz."""

from __future__ import annotations

import math
import re

from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.job import AXES

_EXT_PARAM = re.compile(r"(\w+)\s*=\s*(\"[^\"]*\"|\S*)")


#: Largest magnitude accepted per parameter letter (anything larger is surely an error).
BOUNDS = {"X": 1e5, "Y": 1e5, "Z": 1e5, "E": 1e6, "I": 1e5, "J": 1e5, "R": 1e5, "F": 1e7}


def number_or_none(value) -> float | None:
    """A stored word's value as a finite float; None where it is absent or not one."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def num(value: str, letter: str, where: str) -> float:
    """A finite, not absurdly large number from a G-code word value (else RingtuneError)."""
    try:
        x = float(value)
    except ValueError:
        raise RingtuneError(f"{letter}{value!r} is not a number", where) from None
    if not math.isfinite(x):
        raise RingtuneError(f"{letter}{value} is not a finite number", where)
    if abs(x) > BOUNDS.get(letter, 1e9):
        raise RingtuneError(f"{letter}{value} is absurdly large", where)
    return x


def _non_negative(cmd: str, w: dict[str, float], letter: str, where: str) -> float | None:
    """Word ``letter`` of a limit command (None when absent or without a value); negative refused."""
    if letter not in w or math.isnan(w[letter]):
        return None
    if w[letter] < 0:
        raise RingtuneError(f"{cmd} {letter}{w[letter]:g} must be >= 0", where)
    return w[letter]


def _per_axis(prefix: str) -> tuple:
    return tuple((ax, f"{prefix}_{ax.lower()}", None) for ax in AXES)


#: Marlin limit commands whose words each set one setting: command -> ((letter, setting, clamp or
#: None), …), in the order they are set; M201 F is Marlin's XY_FREQUENCY_LIMIT (at most 100 Hz)
WORD_SETTINGS = {
    "M201": (*_per_axis("max_accel"), ("F", "freq_limit_hz", lambda v: min(v, 100.0))),
    "M203": _per_axis("max_vel"),
    "M205": (*_per_axis("jerk"), *_per_axis("m205_jerk"), ("J", "junction_deviation", None)),
    # RepRapFirmware's "jerk" (instantaneous speed change) is in mm/min
    "M566": tuple((ax, f"jerk_{ax.lower()}", lambda v: v / 60.0) for ax in AXES),
}

#: Klipper's SET_VELOCITY_LIMIT parameters -> the settings they set: Klipper's own, which Marlin and
#: RRF, who do not have the command, never read
VELOCITY_LIMIT_SETTINGS = {
    "VELOCITY": ("velocity",), "ACCEL": ("accel_klipper",),
    "SQUARE_CORNER_VELOCITY": ("square_corner_velocity",),
    "ACCEL_TO_DECEL": ("accel_to_decel",), "MINIMUM_CRUISE_RATIO": ("min_cruise_ratio",),
    # Kalico's limited_* kinematics (toolhead.py: only when the kinematics has them)
    "X_ACCEL": ("limited_accel_x",), "Y_ACCEL": ("limited_accel_y",)}


class SettingCommands:
    """Mixin: needs ``_where``, ``_set``, ``_event``, ``speed_factor``, ``stop`` and ``tower*``
    attributes of the reader."""

    def _limits(self, cmd: str, w: dict[str, float], where: str) -> None:
        def pos(letter: str) -> float | None:
            return _non_negative(cmd, w, letter, where)

        for letter, key, clamp in WORD_SETTINGS.get(cmd, ()):
            if (v := pos(letter)) is not None:
                self._set(key, clamp(v) if clamp else v)
        if cmd == "M201":
            s = pos("S") if "S" in w else pos("G")
            if s is not None:
                self._set("freq_limit_min_factor", min(max(s, 1.0), 100.0) / 100.0)
        elif cmd == "M204":
            self._m204(pos("S"), pos("P"), pos("T"), pos("R"))
        elif cmd == "M220" and (v := pos("S")) is not None:
            if v == 0:
                raise RingtuneError("M220 S0 would stop every move", where)
            self.speed_factor = v / 100.0

    def _m204(self, s, p, t, r) -> None:
        """M204 S (print, travel and Klipper's one acceleration), P (print), T (travel), R (retract);
        without S, Klipper's acceleration is the lower of P and T, given together: Klipper and
        Kalico answer a lone P or T (what PrusaSlicer and OrcaSlicer write for Marlin 2 and RRF,
        one per feature) with "Invalid M204 command" and keep their acceleration (toolhead.py
        cmd_M204)."""
        klipper = s if s is not None else (min(p, t) if p is not None and t is not None else None)
        given = (("accel_print", p if p is not None else s), ("accel_travel", t if t is not None else s),
                 ("accel_retract", r), ("accel_klipper", klipper))
        for key, v in given:
            if v is not None:
                self._set(key, v)

    def _extended(self, code: str, lineno: int) -> None:
        where = self._where(lineno)
        parts = code.split(None, 1) + [""]          # the command, and its parameters or nothing
        cmd, rest = parts[0].upper(), parts[1]
        params: dict = {}
        for key, value in _EXT_PARAM.findall(rest):
            params[key.upper()] = value.strip('"')
        if cmd == "SET_VELOCITY_LIMIT":
            self._velocity_limit(params, where)
            self._event("limits", cmd, params, lineno, code)
        elif cmd == "TUNING_TOWER":
            self._tower_start(params, lineno, code)
        elif cmd == "SET_INPUT_SHAPER":
            for k, v in list(params.items()):
                if k.startswith(("SHAPER_FREQ", "DAMPING")):
                    params[k] = num(v, k + "=", where)
            self.stop = True
            self._event("shaper", cmd, params, lineno, code)
        else:
            if cmd == "SET_RETRACTION":
                self.retraction.reset()
            self._event("other", cmd, params, lineno, code)

    def _velocity_limit(self, params: dict, where: str) -> None:
        """SET_VELOCITY_LIMIT: each known parameter sets its setting (ACCEL also the print and travel
        accelerations) and is turned into a number in ``params``."""
        for k, v in params.items():
            if k not in VELOCITY_LIMIT_SETTINGS:
                continue
            x = num(v, k + "=", where)
            if x < 0 or (k == "MINIMUM_CRUISE_RATIO" and x >= 1):
                raise RingtuneError(f"SET_VELOCITY_LIMIT {k}={v} is out of range", where)
            for key in VELOCITY_LIMIT_SETTINGS[k]:
                self._set(key, x)
            params[k] = x

    # -- Klipper TUNING_TOWER: a command re-run with a parameter that follows the print height --
    def _tower_start(self, params: dict, lineno: int, code: str) -> None:
        where = self._where(lineno)
        if not {"COMMAND", "PARAMETER"} <= params.keys():
            raise RingtuneError("TUNING_TOWER needs COMMAND= and PARAMETER=", where)
        nums = {}
        for key in ("START", "FACTOR", "BAND", "SKIP", "STEP_DELTA", "STEP_HEIGHT"):
            nums[key] = num(params[key], key + "=", where) if key in params else 0.0
        if nums["FACTOR"] and nums["STEP_HEIGHT"]:
            raise RingtuneError("TUNING_TOWER takes FACTOR or STEP_DELTA/STEP_HEIGHT, not both", where)
        self.tower = (params["COMMAND"].upper(), params["PARAMETER"].upper(), nums)
        self.tower_z = math.nan
        self.tower_value = math.nan
        self._event("other", "TUNING_TOWER", dict(params, **nums), lineno, code)

    def _tower_step(self, z: float, lineno: int) -> None:
        """As klippy/extras/tuning_tower.py: on extrusion moves at a new height, run the command
        again when the value changes (value = START + FACTOR·z, BAND-quantised, or stepped)."""
        command, parameter, k = self.tower
        self.tower_z = z
        if k["SKIP"]:
            z = max(0.0, z - k["SKIP"])
        if k["STEP_HEIGHT"]:
            value = k["START"] + k["STEP_DELTA"] * math.floor(z / k["STEP_HEIGHT"])
        else:
            if k["BAND"]:
                z = (math.floor(z / k["BAND"]) + 0.5) * k["BAND"]
            value = k["START"] + z * k["FACTOR"]
        if value != self.tower_value:
            self.tower_value = value
            self._extended(f"{command} {parameter}={value:.9f}", lineno)
