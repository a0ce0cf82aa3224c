"""Parse what a firmware reports about its input shaping, and compare it with what was meant.

Report formats (``shared/reference/firmware.md``):

- Klipper ``SET_INPUT_SHAPER`` (no args): ``// shaper_type_x:mzv shaper_freq_x:40.000 damping_ratio_x:0.100000``
- RRF ``M593``: ``Input shaping 'zvd' at 40.0Hz damping factor 0.10, ...`` / ``Input shaping is disabled``
- Marlin ``M593``: ``  M593 X F40.00 D0.15`` per axis (may be prefixed ``echo:``)
- Marlin FT_MOTION ``M493``: ``M493 X C8 A40.00 F0.00 I0.10 Q0.05`` per axis
- Prusa ``M593``: ``axis X type=MZV freq=50.70 damp=0.10 vr=20.00`` or ``axis Z disabled``
- acceleration: Klipper ``SET_VELOCITY_LIMIT`` (no args): ``// max_accel: 3000.000000`` (and
  ``// minimum_cruise_ratio: 0.500000``, ``// square_corner_velocity: 5.000000``); Marlin and
  Prusa ``M204``: ``  M204 P3000.00 R3000.00 T3000.00``; RRF ``M204``: ``Maximum printing
  acceleration 3000.0, maximum travel acceleration 3000.0``
- per-axis caps: Kalico ``SET_VELOCITY_LIMIT`` (no args): ``// max_x_accel: 10010.000000``;
  Marlin and Prusa ``M201``: ``  M201 X500.00 Y500.00 Z100.00 E5000.00`` (``M201_report``); RRF
  ``M201``: ``Accelerations (mm/sec^2): X: 3000.0, Y: 3000.0, Z: 100.0, E: 5000.0``

Values are returned with the number of decimals printed, so a comparison can allow for the
firmware's rounding.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from ringtune.shaping.firmware import FIRMWARES

_NUM = r"(-?[0-9]+(?:\.[0-9]*)?)"


@dataclass(frozen=True)
class Reported:
    value: object          # float or str
    decimals: int = 6      # digits after the point as printed (tolerance = half a unit there)


def _num(s: str) -> Reported:
    return Reported(float(s), len(s.split(".")[1]) if "." in s else 0)


def _klipper_shapers(text: str) -> dict[str, Reported]:
    """SET_INPUT_SHAPER's report: ``shaper_type_x:mzv shaper_freq_x:40.000 damping_ratio_x:0.100000``,
    or for Kalico's smoothers ``shaper_type_x:smooth_mzv smoother_freq_x:40.000``."""
    out: dict[str, Reported] = {}
    for ax in ("x", "y", "z"):
        m = re.search(rf"shaper_type_{ax}:(\S+)\s+shaper_freq_{ax}:{_NUM}\s+damping_ratio_{ax}:{_NUM}", text)
        if m:
            out[f"{ax}.damping"] = _num(m.group(3))
        m = m or re.search(rf"shaper_type_{ax}:(\S+)\s+smoother_freq_{ax}:{_NUM}", text)
        if m:
            out[f"{ax}.type"] = Reported(m.group(1).lower())
            out[f"{ax}.freq"] = _num(m.group(2))
    return out


def parse_report(firmware: str, text: str) -> dict[str, Reported]:
    """Settings found in the firmware's reply text (keys as :attr:`Export.expected`)."""
    dialect = FIRMWARES[firmware].family
    out = _acceleration_fields(dialect, text)
    out.update(_SHAPER_READERS[dialect](text))
    return out


def _rrf_shapers(text: str) -> dict[str, Reported]:
    """RepRapFirmware's M593 answer: one shaper for all axes, or disabled."""
    out = {}
    if re.search(r"Input shaping is disabled", text, re.I):
        out["all.type"] = Reported("none")
    m = re.search(rf"Input shaping '([^']+)' at {_NUM}\s*Hz damping factor {_NUM}", text, re.I)
    if m:
        out.update({"all.type": Reported(m.group(1).lower()), "all.freq": _num(m.group(2)),
                    "all.damping": _num(m.group(3))})
    return out


def _marlin_shapers(text: str) -> dict[str, Reported]:
    """Marlin's classic M593 report, per axis (a damping only where the shaper is on)."""
    out = {}
    for m in re.finditer(rf"M593\s+([XYZ])\s+F{_NUM}(?:\s+D{_NUM})?", text):
        ax = m.group(1).lower()
        out[f"{ax}.freq"] = _num(m.group(2))
        if m.group(3) is not None and float(m.group(2)) != 0:
            out[f"{ax}.damping"] = _num(m.group(3))
    return out


def _ftm_shapers(text: str) -> dict[str, Reported]:
    """Marlin FT_MOTION's M493 report, per axis: its mode (C) and, when on, frequency, damping, vtol."""
    out = {}
    for m in re.finditer(r"M493[ \t]+([XYZE])((?:[ \t]+[A-Z]-?[0-9.]+)+)", text):
        ax = m.group(1).lower()
        fields = dict(re.findall(r"([A-Z])(-?[0-9.]+)", m.group(2)))
        if "C" in fields:
            out[f"{ax}.mode"] = Reported(int(float(fields["C"])), 0)
        if int(float(fields.get("C", 0))):
            out.update({f"{ax}.{key}": _num(fields[letter])
                        for key, letter in (("freq", "A"), ("damping", "I"), ("vtol", "Q")) if letter in fields})
    return out


def _prusa_shapers(text: str) -> dict[str, Reported]:
    """Prusa Buddy's M593 report, per axis: disabled, or type, frequency and damping."""
    out = {}
    for m in re.finditer(r"axis\s+([XYZ])\s+disabled", text, re.I):
        out[f"{m.group(1).lower()}.type"] = Reported("none")
    for m in re.finditer(rf"axis\s+([XYZ])\s+type=(\w+)\s+freq={_NUM}\s+damp={_NUM}", text, re.I):
        ax = m.group(1).lower()
        out[f"{ax}.type"] = Reported(m.group(2).lower().replace("ei_2hump", "2hump_ei").replace("ei_3hump", "3hump_ei"))
        out[f"{ax}.freq"] = _num(m.group(3))
        out[f"{ax}.damping"] = _num(m.group(4))
    return out


#: setting -> dialect ("marlin" also for Marlin FT_MOTION and Prusa) -> the pattern whose first group
#: is its value in the reply (None: the dialect does not report it)
_ACCEL_REPORTS = {
    "accel": {"klipper": re.compile(rf"max_accel:\s*{_NUM}"),
              "rrf": re.compile(rf"Maximum printing acceleration {_NUM}", re.I),
              "marlin": re.compile(rf"M204(?:\s+S-?[0-9]+(?:\.[0-9]*)?)?\s+P{_NUM}")},
    # Klipper's corner rule, in the same SET_VELOCITY_LIMIT report (the others' are not read back)
    "square_corner_velocity": {"klipper": re.compile(rf"square_corner_velocity:\s*{_NUM}"), "rrf": None,
                               "marlin": None},
    "minimum_cruise_ratio": {"klipper": re.compile(rf"minimum_cruise_ratio:\s*{_NUM}"), "rrf": None, "marlin": None},
    "travel_accel": {"klipper": None,
                     "rrf": re.compile(rf"maximum travel acceleration {_NUM}", re.I),
                     "marlin": re.compile(rf"M204\b[^\n]*?\sT{_NUM}")},
}


def _acceleration_fields(dialect: str, text: str) -> dict[str, Reported]:
    """``accel``, ``travel_accel`` (M204's T), ``max_accel_x``/``y`` where the reply reports them."""
    patterns = {key: by_dialect.get(dialect, by_dialect["marlin"]) for key, by_dialect in _ACCEL_REPORTS.items()}
    matched = {key: pattern.search(text) for key, pattern in patterns.items() if pattern is not None}
    return {**{key: _num(m.group(1)) for key, m in matched.items() if m}, **_axis_caps(dialect, text)}


#: RRF's and Marlin's (also Prusa's) M201 reports: X and Y caps in the first two groups
_CAPS_REPORTS = {"rrf": re.compile(rf"Accelerations \(mm/sec\^2\):\s*X:\s*{_NUM},\s*Y:\s*{_NUM}", re.I),
                 "marlin": re.compile(rf"M201\s+X{_NUM}\s+Y{_NUM}")}


def _axis_caps(dialect: str, text: str) -> dict[str, Reported]:
    """``max_accel_x`` / ``max_accel_y`` from the reply of the record's ``axis_accel_report``."""
    if dialect == "klipper":
        found = {ax: re.search(rf"max_{ax}_accel:\s*{_NUM}", text) for ax in "xy"}
        return {f"max_accel_{ax}": _num(m.group(1)) for ax, m in found.items() if m}
    m = _CAPS_REPORTS.get(dialect, _CAPS_REPORTS["marlin"]).search(text)
    return {"max_accel_x": _num(m.group(1)), "max_accel_y": _num(m.group(2))} if m else {}


def matches(expected: object, got: Reported) -> bool:
    """True if the reported value equals the intended one within the printed rounding."""
    if isinstance(expected, str) or isinstance(got.value, str):
        return str(expected).lower() == str(got.value).lower()
    tol = 0.5 * 10 ** (-got.decimals) + 1e-9
    return abs(float(expected) - float(got.value)) <= tol


def compare(expected: dict[str, object], reported: dict[str, Reported]) -> dict[str, dict]:
    """Per setting: ``{"meant": v, "reported": v|None, "ok": bool}``."""
    out = {}
    for key, want in expected.items():
        got = reported.get(key)
        out[key] = {"meant": want, "reported": None if got is None else got.value,
                    "ok": got is not None and matches(want, got)}
    return out


#: dialect -> the reader of its shaper report
_SHAPER_READERS = {"klipper": _klipper_shapers, "rrf": _rrf_shapers, "marlin": _marlin_shapers,
                   "marlin-ftm": _ftm_shapers, "prusa": _prusa_shapers}
