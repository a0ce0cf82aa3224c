"""A job sliced for one firmware and run on another: the limit lines the two read differently.

A slicer writes the machine limits in its flavour's units: PrusaSlicer, SuperSlicer and OrcaSlicer
write ``M203`` speeds in mm/s for Marlin (``; gcode_flavor = marlin2`` or ``marlin``, also
``klipper``) and in mm/min for RepRapFirmware (``reprapfirmware``), which also gets its jerk as
``M566`` (mm/min), a command Marlin and Prusa's firmware do not have. The planner reads every line
as the printer's firmware reads it — a Marlin job's ``M203 X500`` caps X at 500 mm/min, 8.3 mm/s,
on RepRapFirmware, and an RRF job's ``M203 X30000`` leaves Marlin uncapped at 30000 mm/s — so the
print time is the one the printer would take; this says why, line by line. (Klipper and Kalico read
none of these lines: :mod:`ringtune.shaping.klipper_ignores` says so.)
"""

from __future__ import annotations

from ringtune.shaping.firmware import FIRMWARES
from ringtune.shaping.slicer import slicer_flavor

#: slicer flavour -> whether its M203 speeds are written in mm/min (only the flavours whose unit is
#: known: PrusaSlicer's family writes machine limits for these)
FLAVOR_M203_PER_MINUTE = {"marlin": False, "marlin2": False, "marlinlegacy": False, "klipper": False,
                          "reprapfirmware": True}
#: the axes an M203 line sets
_AXES = ("X", "Y", "Z", "E")
#: M203's unit by whether it is per minute
_UNIT = {True: "mm/min", False: "mm/s"}


def foreign_limit_lines(job, limits, flavor: str | None) -> dict[str, list]:
    """The job's limit lines the printer reads otherwise than the slicer wrote them (``flavor``,
    :func:`ringtune.shaping.slicer.slicer_flavor`; ``limits``: the
    :class:`ringtune.shaping.planner.MachineLimits` it is planned with): ``{"M203": [(line, {axis:
    mm/s as the printer reads it}), …], "M566": [line, …]}``, each key only where it has lines;
    empty for an unknown flavour and under Klipper's reading."""
    written_per_minute = FLAVOR_M203_PER_MINUTE.get(str(flavor).lower())
    if written_per_minute is None or limits.reads_like_klipper:
        return {}
    m203 = _m203_lines(job, limits) if bool(limits.m203_per_minute) != written_per_minute else []
    m566 = [int(ev.line) for ev in _limit_lines(job, "M566")] if not limits.reads_m566 else []
    return {k: v for k, v in (("M203", m203), ("M566", m566)) if v}


def _limit_lines(job, command: str) -> list:
    """The job's ``command`` limit events."""
    return [ev for ev in job.events if ev.kind == "limits" and ev.command == command]


def _m203_lines(job, limits) -> list[tuple[int, dict]]:
    """(line, {axis: mm/s as ``limits`` read it}) of each M203 line setting a speed."""
    scale = 1.0 / 60.0 if limits.m203_per_minute else 1.0
    found = [(int(ev.line), {a: float(ev.params[a]) * scale for a in _AXES if a in ev.params})
             for ev in _limit_lines(job, "M203")]
    return [(line, speeds) for line, speeds in found if speeds]


def foreign_limit_note(found: dict[str, list], flavor: str | None, firmware_name: str) -> str | None:
    """One sentence on what :func:`foreign_limit_lines` found (None: nothing)."""
    if not found:
        return None
    parts = [_SAID[k](v, flavor) for k, v in found.items()]
    return (f"the job was sliced for {flavor} (its gcode_flavor) and runs on {firmware_name}: " + "; ".join(parts)
            + "; planned as the file runs there (re-slice for that firmware to print it as the slicer meant)")


def _more(lines: list) -> str:
    """`` (and N more)`` after the first of ``lines``, or nothing."""
    return f" (and {len(lines) - 1} more)" if len(lines) > 1 else ""


def _m203_said(lines: list, flavor: str | None) -> str:
    """The M203 lines read in the other unit, in words (the first one's figures)."""
    line, speeds = lines[0]
    per_minute = FLAVOR_M203_PER_MINUTE[str(flavor).lower()]
    caps = ", ".join(f"{a} {round(v, 2):g} mm/s" for a, v in speeds.items())
    return (f"its M203 speeds, written in {_UNIT[per_minute]}, are read in {_UNIT[not per_minute]} there: "
            f"line {line} caps {caps}{_more(lines)}")


def _m566_said(lines: list, _flavor: str | None) -> str:
    """The M566 lines a firmware without it skips, in words."""
    return f"it has no M566 (RepRapFirmware's jerk): the one on line {lines[0]}{_more(lines)} sets nothing"


_SAID = {"M203": _m203_said, "M566": _m566_said}


def flavor_note(job, limits, firmware: str | None) -> str | None:
    """:func:`foreign_limit_note` of a parsed job read from a file (its ``source``) on ``firmware`` (a
    key of :data:`ringtune.shaping.firmware.FIRMWARES`; None: the printer's own); None for a job with
    no file or no known flavour."""
    source = str(getattr(job, "source", "<"))
    if source.startswith("<"):
        return None
    flavor = slicer_flavor(source)
    record = FIRMWARES.get(str(firmware).lower())
    return foreign_limit_note(foreign_limit_lines(job, limits, flavor), flavor,
                              record.title if record else "the printer's firmware")
