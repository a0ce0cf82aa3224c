"""A config's acceleration as a slicer's own profile settings, so the tuned value reaches the G-code.

A slicer writes acceleration commands into every sliced file (``M204`` from its machine limits and
per-feature accelerations; Klipper reads ``M204 S``/``P``+``T`` as ``SET_VELOCITY_LIMIT ACCEL``),
and those override what the printer was told. The setting keys are the slicers' own:

- PrusaSlicer (``PrintConfig.cpp``): printer profile ``machine_max_acceleration_extruding`` (emitted
  as ``M204 P``; two values: normal, stealth), ``machine_max_acceleration_travel`` (``M204 T``),
  ``machine_limits_usage = emit_to_gcode`` (the limits go into the G-code); print profile
  ``default_acceleration`` (the acceleration restored after the per-feature ones; 0 = not set).
- OrcaSlicer: machine profile ``machine_max_acceleration_extruding`` / ``_travel`` (string arrays:
  normal, silent), process profile ``default_acceleration`` ("Normal printing").
- Cura (``fdmprinter.def.json``): ``acceleration_enabled`` (without it Cura writes no M204),
  ``acceleration_print`` (the per-feature accelerations default to it), ``machine_acceleration``.

Per-feature accelerations a profile already sets (PrusaSlicer ``perimeter_acceleration``,
``infill_acceleration``…, Orca ``outer_wall_acceleration``…, Cura ``acceleration_wall``…) still
override these where non-zero: the notes say so.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field

from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.firmware import Firmware

SLICERS = ("prusaslicer", "orcaslicer", "cura")
#: Cura's "machine_gcode_flavor" / PrusaSlicer's "gcode_flavor" for each firmware family
_PRUSA_FLAVOR = {"klipper": "klipper", "rrf": "reprapfirmware", "marlin": "marlin2", "marlin-ftm": "marlin2",
                 "prusa": "marlin2"}


@dataclass
class SlicerProfile:
    """Settings for one slicer: ``settings`` key -> value as the slicer writes it; ``text`` is the
    fragment to paste (``.ini`` lines, a JSON object, Cura ``[values]``)."""

    slicer: str
    extension: str
    settings: dict[str, object]
    text: str
    notes: list[str] = field(default_factory=list)

    def render(self) -> str:
        c = "#" if self.extension in ("ini", "cfg") else None
        if c is None:           # JSON has no comments: the notes go in a "_ringtune" key
            return self.text
        return "\n".join([f"{c} {n}" for n in self.notes] + [self.text.rstrip("\n")]) + "\n"

    def to_dict(self) -> dict:
        return asdict(self)


def _n(a: float) -> str:
    return f"{a:.0f}" if a == int(a) else f"{a:g}"


def _caps_note(caps: dict) -> str:
    """What the slicer's M201 (machine_max_acceleration_x/_y, emitted to the G-code) must be."""
    if caps:
        return ("machine_max_acceleration_x/_y are the per-axis caps this config was planned with "
                "(the slicer writes them as M201 X Y)")
    return "machine_max_acceleration_x/_y must be at least this value, or M201 caps it"


def slicer_profile(config: TuneConfig, slicer: str, firmware: str | None = None) -> SlicerProfile:
    """The acceleration settings of ``slicer``'s profile for ``config.accel`` (mm/s²)."""
    if slicer not in SLICERS:
        raise RingtuneError(f"must be one of {', '.join(SLICERS)}, not {slicer!r}", "--slicer")
    if config.accel is None:
        raise RingtuneError("the config has no accel (mm/s²) to put in the slicer profile", "config: accel")
    fw = Firmware.named(firmware or config.firmware)
    a = _n(config.accel)
    common = [f"tuned acceleration {a} mm/s² for {fw.title}; per-feature accelerations already set "
              "in the profile override it where they are not 0: set them to 0 (or to this value)"]
    caps = {f"machine_max_acceleration_{ax}": _n(c) for ax, c in zip("xy", config.axis_caps) if c is not None}
    if slicer == "prusaslicer":
        machine = {"machine_limits_usage": "emit_to_gcode", "machine_max_acceleration_extruding": f"{a},{a}",
                   "machine_max_acceleration_travel": f"{a},{a}", **{k: f"{v},{v}" for k, v in caps.items()}}
        settings = {**machine, "default_acceleration": a}
        text = ("# printer profile (Printer Settings > Machine limits)\n"
                + "".join(f"{k} = {v}\n" for k, v in machine.items())
                + "# print profile (Print Settings > Speed > Acceleration control)\n"
                + f"default_acceleration = {a}\n")
        notes = common + [_caps_note(caps), f"gcode_flavor = {_PRUSA_FLAVOR[fw.family]} for {fw.title}"]
        return SlicerProfile(slicer, "ini", settings, text, notes)
    if slicer == "orcaslicer":
        settings = {"machine_max_acceleration_extruding": [a, a], "machine_max_acceleration_travel": [a, a],
                    **{k: [v, v] for k, v in caps.items()}, "default_acceleration": a}
        notes = common + ["machine profile: machine_max_acceleration_*; process profile: default_acceleration"]
        text = json.dumps({**settings, "_ringtune": notes}, indent=2) + "\n"
        return SlicerProfile(slicer, "json", settings, text, notes)
    settings = {"acceleration_enabled": "True", "acceleration_print": a, "machine_acceleration": a}
    text = "[values]\n" + "".join(f"{k} = {v}\n" for k, v in settings.items())
    notes = common + ["Cura writes M204 only with acceleration_enabled; the per-feature "
                      "accelerations (acceleration_wall, acceleration_infill, ...) default to acceleration_print"]
    return SlicerProfile(slicer, "cfg", settings, text, notes)
