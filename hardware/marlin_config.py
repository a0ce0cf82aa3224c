"""The printer from Marlin's ``M503`` report: steps/mm, limits, motor currents and the ZV shaper.

``M503`` prints the settings in force as G-code lines, each after ``echo:`` and a heading comment
(``MarlinFirmware/MarlinDocumentation:_gcode/M503.md``; the lines are those of ``settings.cpp``'s
report). Read here, in Marlin's units:

| line | meaning | description key |
|---|---|---|
| ``M92 X Y Z E`` | steps per mm | ``motor.steps_per_mm`` (X, Y) |
| ``M203 X Y Z E`` | max feedrate, mm/s | ``limits.max_velocity`` (x, y, z, e); ``limits.velocity`` = max(X, Y) |
| ``M201 X Y Z E`` | max acceleration, mm/s² | ``limits.max_accel`` (x, y, z, e) |
| ``M204 P R T`` (old: ``S T``) | print / retract / travel acceleration, mm/s² | ``limits.accel`` = P (else S), ``limits.retract_accel`` = R (E-only moves), ``limits.travel_accel`` = T |
| ``M205 J`` or ``M205 X Y Z E`` | junction deviation, mm, or classic jerk, mm/s | ``limits.junction`` = ``jd`` / ``jerk`` and its value |
| ``M906 X Y`` | TMC driver current, mA RMS | ``motor.run_current`` (A) |
| ``M207 S F Z``, ``M208 S F`` | firmware retraction (FWRETRACT): length mm, speed mm/min, Z hop mm; extra restore mm, its speed mm/min | ``limits.retract_length``, ``retract_speed`` (mm/s), ``retract_zlift``, ``unretract_extra_length``, ``unretract_speed`` (mm/s) |
| ``M593 X/Y F D`` | ZV input shaper (``firmware.md`` §2.1): F Hz (0 = off), D damping | ``[current]`` shaper ``zv`` |

``M503`` does not report the kinematics; the caller gives it (or it stays unknown, with a note).
"""

from __future__ import annotations

import re
from pathlib import Path

from ringtune.hardware.config_dialect import console_line, refuse_other_dialect
from ringtune.hardware.firmware_facts import (KINEMATICS, FirmwareFacts, axis_numbers, gcode_words,
    place_gcode_motors, to_number)
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.textfile import read_text_file

_READ = ("M92", "M201", "M203", "M204", "M205", "M906", "M593", "M207", "M208")
#: what Marlin (``echo:``) or a host (``//``) puts before a report line, possibly repeated
_REPORT_PREFIX = re.compile(r"^(?:(?:echo:|//)\s*)+", re.I)


def _lines(text: str):
    """(line number, G-code words) of each command line of an M503 capture, as a terminal or host
    saved it (timestamps, ``Recv:``, ``echo:``, ``//`` prefixes removed; lines the host sent skipped)."""
    for n, raw in enumerate(text.splitlines(), 1):
        line = console_line(raw)
        if line is None:                       # what the host sent (Send: M503), not the report
            continue
        line = _REPORT_PREFIX.sub("", line, count=1).split(";", 1)[0]
        words = gcode_words(line)
        if words is not None:
            yield n, words


#: lines whose words add up over several lines (an axis per line in some reports)
_MERGED = ("M906", "M203", "M201", "M92")


def _skipped(cmd: str, words: dict, where: str) -> str | None:
    """The note for a line that is not read (a second stepper's current, FT_MOTION's M493), else None."""
    if cmd == "M906" and words.get("I", "0") not in ("", "0"):
        return f"{where}: M906 I{words['I']} (a second stepper of an axis) is not read"
    if cmd == "M493":
        return f"{where}: M493 (fixed-time motion) is not read; [current] is the classic M593 ZV shaper"
    return None


class _Report:
    """The lines of an M503 report that are read: ``seen[code] = (line number, words)``, M593 per
    axis as ``"M593 X"``; ``notes`` collects the lines skipped."""

    def __init__(self, text: str, path: str, notes: list[str]):
        self.path, self.seen = path, {}
        for n, (cmd, words) in _lines(text):
            note = _skipped(cmd, words, f"{path}:{n}")
            if note:
                notes.append(note)
            elif cmd == "M593":
                for a in [a for a in "XY" if a in words] or ["X", "Y"]:    # no axis letter: every shaped axis
                    self.seen[f"M593 {a}"] = (n, words)
            elif cmd in _READ:
                prev = self.seen.get(cmd, (n, {}))[1] if cmd in _MERGED else {}
                self.seen[cmd] = (n, {**prev, **words})
        if not any(k in self.seen for k in _READ):
            raise RingtuneError("no M92/M201/M203/M204/M205/M906/M593 line: not an M503 report", path)

    def num(self, cmd: str, letter: str) -> float | None:
        """The number of ``cmd``'s word ``letter``, None when not reported."""
        if self.seen.get(cmd, (0, {}))[1].get(letter) in (None, ""):
            return None
        n, words = self.seen[cmd]
        return to_number(words[letter].split(":")[0], f"{self.path}:{n}: {cmd} {letter}")


def _kinematics(kinematics: str | None, notes: list[str]) -> dict:
    """The description's kinematics as the caller gives it (M503 does not say)."""
    if kinematics is None:
        notes.append("M503 does not report the kinematics: not written, so the description loads as cartesian "
                     "(a CoreXY or CoreXZ machine: give --kinematics, or add kinematics = \"corexy\")")
        return {}
    if kinematics not in KINEMATICS:
        raise RingtuneError(f"must be one of {', '.join(KINEMATICS)}, not {kinematics!r}", "kinematics")
    return {"kinematics": kinematics}


def _accels(report: _Report, notes: list[str]) -> dict:
    """``limits`` from M204: print (P, old S), travel (T) and retract (R) accelerations."""
    limits = {}
    accel = report.num("M204", "P") or report.num("M204", "S")
    if accel is None:
        notes.append("no M204 P (print acceleration): limits.accel unknown")
    else:
        limits["accel"] = accel
    if report.num("M204", "T"):
        limits["travel_accel"] = report.num("M204", "T")
    if report.num("M204", "R"):
        limits["retract_accel"] = report.num("M204", "R")
    else:
        notes.append("no M204 R (retract acceleration): retractions are planned at the print acceleration")
    return limits


def _caps_and_junction(report: _Report, notes: list[str]) -> dict:
    """``limits`` from M203 (per-axis speeds, their X/Y maximum), M201 (per-axis accelerations) and
    M205 (junction deviation J, else classic jerk)."""
    limits: dict = {}
    vmax = axis_numbers(report.num, "M203")
    if vmax is not None:
        limits.update(max_velocity=vmax, velocity=max(vmax[0], vmax[1]))
        notes.append(f"limits.velocity = {limits['velocity']:g} mm/s, the larger of M203 X and Y (Marlin has "
                     "no overall speed limit; the G-code's F decides)")
    if axis_numbers(report.num, "M201") is not None:
        limits["max_accel"] = axis_numbers(report.num, "M201")
    if report.num("M205", "J") is not None:
        limits.update(junction="jd", junction_deviation=report.num("M205", "J"))
    elif axis_numbers(report.num, "M205") is not None:
        limits.update(junction="jerk", jerk=axis_numbers(report.num, "M205"))
    else:
        notes.append("no M205 J or X/Y jerk: the junction rule is unknown")
    return limits


def _retraction(report: _Report, notes: list[str]) -> dict:
    """``limits`` from FWRETRACT's M207 (S length, F speed mm/min, Z hop mm) and M208 (S extra restore, F
    its speed mm/min): what a job's G10/G11 move. Not reported (FWRETRACT off, or not captured): said."""
    values = {"retract_length": report.num("M207", "S"), "retract_speed": report.num("M207", "F"),
              "unretract_extra_length": report.num("M208", "S"), "unretract_speed": report.num("M208", "F")}
    if any(v is None for v in values.values()):
        notes.append("no M207 S F and M208 S F (firmware retraction, FWRETRACT): what a job's G10/G11 move is "
                     "unknown; a job that uses them is planned with stops there that take no time")
        return {}
    for k in ("retract_speed", "unretract_speed"):
        values[k] /= 60.0                       # mm/min
    zlift = report.num("M207", "Z")
    return {**values, "retract_zlift": zlift} if zlift else values


def _current_shaper(report: _Report, ax: str, notes: list[str]) -> dict:
    """``[current]``'s keys for axis ``ax`` from its M593 (F 0 or none: no shaping)."""
    a = ax.lower()
    if f"M593 {ax}" not in report.seen:
        notes.append(f"no M593 for {ax}: no input shaping on {ax} (or the firmware has none)")
        return {f"shaper_{a}": "none"}
    n, words = report.seen[f"M593 {ax}"]
    f = to_number(words["F"], f"{report.path}:{n}: M593 F") if words.get("F") else None
    d = to_number(words["D"], f"{report.path}:{n}: M593 D") if words.get("D") else None
    if not f:
        return {f"shaper_{a}": "none"}
    if d is None:
        notes.append(f"{report.path}:{n}: M593 gives no D: the damping ratio on {ax} is unknown")
        return {f"shaper_{a}": "zv", f"freq_{a}": f}
    return {f"shaper_{a}": "zv", f"freq_{a}": f, f"damping_{a}": d}


def printer_facts_from_marlin(path: str | Path, kinematics: str | None = None) -> FirmwareFacts:
    """Facts from a saved ``M503`` answer (see the module docstring)."""
    path = str(path)
    text = read_text_file(path, "M503 report")
    refuse_other_dialect(text, path, "marlin")
    notes: list[str] = []
    report = _Report(text, path, notes)
    description: dict = _kinematics(kinematics, notes)
    description["limits"] = {**_accels(report, notes), **_caps_and_junction(report, notes),
                             **_retraction(report, notes)}
    place_gcode_motors(description, report.num, 1e-3)          # Marlin's M906: mA RMS
    if "M906" not in report.seen:
        notes.append("no M906 (TMC driver current): the run current is unknown")
    notes.append("M503 names no motor and gives steps/mm only: rotation_distance, microsteps and the "
                 "motor's constants are unknown")
    current: dict = {"source": path, "firmware": "marlin"}
    for ax in "XY":
        current.update(_current_shaper(report, ax, notes))
    if "accel" in description["limits"]:
        current["accel"] = description["limits"]["accel"]
    description["current"] = current
    return FirmwareFacts(description, notes, path)
