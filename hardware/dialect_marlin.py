"""Marlin's dialects and Prusa Buddy's (a Marlin fork): one shaping line per axis.

Syntax and ranges: ``shared/reference/firmware.md`` §2 (Marlin), §4 (Prusa):

- ``marlin``: ``M593 X F40 D0.15`` (ZV only; ``F0`` turns an axis off);
- ``marlin-ftm``: ``M493 S1`` (FT_MOTION on), then ``M493 X C<mode> A<Hz> I<zeta> [Q<vtol>]``;
- ``prusa``: ``M593 X T<type> F<Hz> D<zeta> [R<reduction>]`` (``F0`` turns an axis off).

Marlin stores them with ``M500``, Prusa with ``M593 W`` (the record's ``save`` lines).
"""

from __future__ import annotations

from typing import Callable

from ringtune.hardware.export import Export
from ringtune.hardware.firmware_check import check_axis, check_value, fmt
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.firmware import FIRMWARES, Firmware, Span

_FTM_MODE = {"none": 0, "zv": 1, "zvd": 2, "zvdd": 3, "zvddd": 4, "ei": 5, "2hump_ei": 6, "3hump_ei": 7,
             "mzv": 8}
_PRUSA_TYPE = {"zv": 0, "zvd": 1, "mzv": 2, "ei": 3, "2hump_ei": 4, "3hump_ei": 5}

#: (firmware, axis, base name, parameters, freq Hz, damping) -> (the axis's line, values read back)
AxisLine = Callable[[Firmware, str, str, dict, float, float], "tuple[str, dict[str, object]]"]


def _axis_lines(config: TuneConfig, fw: Firmware, axis_line: AxisLine,
                first: tuple[str, ...] = ()) -> tuple[list[str], dict, dict]:
    """(lines, values read back, setting -> index of its line): ``first``, then each axis's line
    from ``axis_line`` once the axis passed :func:`check_axis`."""
    lines, expected, setting_lines = list(first), {}, {}
    for ax in ("x", "y"):
        line, values = axis_line(fw, ax, *check_axis(config, fw, ax))
        setting_lines.update(dict.fromkeys(values, len(lines)))
        expected.update(values)
        lines.append(line)
    return lines, expected, setting_lines


def _zeta_words(fw: Firmware, freq: float, damping: float, f: str, d: str) -> str:
    """`` F40 D0.1`` (the frequency's and the damping's letters as given) at the record's precision."""
    return f" {f}{fmt(freq, fw.freq.decimals)} {d}{fmt(damping, fw.damping.decimals)}"


def _vtol(params: dict, where: str, title: str) -> float | None:
    """The EI vibration tolerance (the only shaper parameter Marlin FT_MOTION and Prusa take)."""
    if not params:
        return None
    return check_value(float(params["v_tol"]), Span(0.001, 1.0, 3), "vibration tolerance v_tol", "", where, title)


def _marlin_line(fw: Firmware, ax: str, base: str, params: dict, freq: float, damping: float):
    """``M593 X F40 D0.15``; ``M593 X F0`` for an axis without shaping."""
    if base == "none":
        return f"M593 {ax.upper()} F0", {f"{ax}.freq": 0.0}
    return (f"M593 {ax.upper()}" + _zeta_words(fw, freq, damping, "F", "D"),
            {f"{ax}.freq": freq, f"{ax}.damping": damping})


def _ftm_line(fw: Firmware, ax: str, base: str, params: dict, freq: float, damping: float):
    """``M493 X C<mode> A<Hz> I<zeta> [Q<vtol>]``; only ``C0`` for an axis without shaping."""
    line, values = f"M493 {ax.upper()} C{_FTM_MODE[base]}", {f"{ax}.mode": _FTM_MODE[base]}
    if base == "none":
        return line, values
    values.update({f"{ax}.freq": freq, f"{ax}.damping": damping})
    vtol = _vtol(params, f"config: shaper_{ax}", fw.title)
    if vtol is not None:
        values[f"{ax}.vtol"] = vtol
    return line + _zeta_words(fw, freq, damping, "A", "I") + ("" if vtol is None else f" Q{fmt(vtol, 3)}"), values


def _prusa_line(fw: Firmware, ax: str, base: str, params: dict, freq: float, damping: float):
    """``M593 X T<type> F<Hz> D<zeta> [R<1/vtol>]``; ``M593 X F0`` for an axis without shaping."""
    if base == "none":
        return f"M593 {ax.upper()} F0", {f"{ax}.type": "none"}
    vtol = _vtol(params, f"config: shaper_{ax}", fw.title)
    line = (f"M593 {ax.upper()} T{_PRUSA_TYPE[base]}" + _zeta_words(fw, freq, damping, "F", "D")
            + ("" if vtol is None else f" R{fmt(1 / vtol, 3)}"))
    return line, {f"{ax}.type": base, f"{ax}.freq": freq, f"{ax}.damping": damping}


def marlin_export(config: TuneConfig, dialect: str) -> Export:
    """Marlin's classic ZV shaper, ``M593`` per axis; a note when a frequency is below what a stock
    build shapes."""
    fw = FIRMWARES[dialect]
    lines, expected, setting_lines = _axis_lines(config, fw, _marlin_line)
    exp = Export(dialect, lines, list(fw.save), None, None, ["M593"], expected, setting_lines,
                 ["Marlin's minimum F depends on the board (the echo delay must fit its timer)"])
    low = [f"{ax.upper()} {fmt(config.axis(ax)[1], 2)} Hz" for ax in "xy"
           if config.axis(ax)[0] != "none" and 0 < config.axis(ax)[1] < fw.build_min_freq]
    if low:
        exp.notes.append(f"{', '.join(low)} is below {fw.build_min_freq:g} Hz, {fw.build_min_freq_why}: "
                         f"build with SHAPING_MIN_FREQ at or below it (Configuration_adv.h), or tune with "
                         f"--shaping-min-freq your build's value")
    return exp


def marlin_ftm_export(config: TuneConfig, dialect: str) -> Export:
    """Marlin FT_MOTION: ``M493 S1``, then ``M493`` per axis."""
    fw = FIRMWARES[dialect]
    lines, expected, setting_lines = _axis_lines(config, fw, _ftm_line, ("M493 S1",))
    notes = ["M493 S1 turns FT_MOTION on"]
    if any(v > 0.25 for k, v in expected.items() if k.endswith(".damping")):
        notes.append("some FT_MOTION builds cap damping I at FTM_MAX_DAMPENING 0.25")
    return Export(dialect, lines, list(fw.save), None, None, ["M493"], expected, setting_lines, notes)


def prusa_export(config: TuneConfig, dialect: str) -> Export:
    """Prusa Buddy: ``M593`` per axis with the shaper's type number."""
    fw = FIRMWARES[dialect]
    lines, expected, setting_lines = _axis_lines(config, fw, _prusa_line)
    return Export(dialect, lines, list(fw.save), None, None, ["M593"], expected, setting_lines,
                  ["Prusa keeps M593 settings only after M593 W (written to EEPROM)"])
