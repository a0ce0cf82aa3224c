"""A config's accelerations as a slicer's own profile settings, so re-slicing puts them in the G-code.

A slicer writes an acceleration command (``M204``) at each feature change from its per-feature
acceleration settings, and those override what the printer was told. A :class:`TuneConfig` has
one acceleration (``accel``) and, per feature class of :data:`ringtune.shaping.features.FEATURE_CLASSES`,
``feature_accel`` (mm/s²; a class absent takes ``accel``). Each slicer's keys (their own names)
and the classes each one governs:

- PrusaSlicer 2.6 and later (``PrintConfig.cpp``, Print Settings > Speed > Acceleration control):
  ``external_perimeter_acceleration``, ``perimeter_acceleration``,
  ``top_solid_infill_acceleration``, ``solid_infill_acceleration``, ``infill_acceleration``,
  ``bridge_acceleration``, ``travel_acceleration``, ``default_acceleration`` (everything else,
  and the value restored after each feature);
- PrusaSlicer 2.5 (Debian 12's ``prusa-slicer``; ``prusa-slicer --help-fff``) has only
  ``perimeter_acceleration`` (every perimeter, the external and overhang ones too),
  ``infill_acceleration`` (sparse, solid and top infill), ``bridge_acceleration`` and
  ``default_acceleration`` (restored after each feature, so travel moves take it);
- OrcaSlicer (process profile): ``outer_wall_acceleration``, ``inner_wall_acceleration``,
  ``top_surface_acceleration``, ``internal_solid_infill_acceleration``,
  ``sparse_infill_acceleration``, ``bridge_acceleration``, ``travel_acceleration``,
  ``default_acceleration``; it caps them at the machine profile's
  ``machine_max_acceleration_extruding`` / ``_travel``;
- Cura (``fdmprinter.def.json``): ``acceleration_enabled`` (without it Cura writes no M204),
  ``acceleration_wall_0``, ``acceleration_wall_x``, ``acceleration_topbottom``,
  ``acceleration_roofing``, ``acceleration_infill``, ``acceleration_travel``,
  ``acceleration_skirt_brim``, ``acceleration_support``, ``acceleration_print``; Cura has no
  bridge acceleration and labels no bridge or overhang (they are printed as walls and skin).

Where one key governs several classes, it takes the lowest of their accelerations (the visible
class is never printed faster than chosen) and :attr:`SlicerProfile.effective` says what each class
then gets. First-layer accelerations (``first_layer_acceleration``, ``initial_layer_acceleration``,
``acceleration_layer_0``) are left as the profile has them.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field

from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.features import FEATURE_CLASSES, LABELLED_VISIBLE
from ringtune.shaping.firmware import Firmware

SLICERS = ("prusaslicer", "orcaslicer", "cura")
#: Cura's "machine_gcode_flavor" / PrusaSlicer's "gcode_flavor" for each firmware family
_PRUSA_FLAVOR = {"klipper": "klipper", "rrf": "reprapfirmware", "marlin": "marlin2", "marlin-ftm": "marlin2",
                 "prusa": "marlin2"}

#: per slicer: (key, the feature classes it governs), in order; a class's own key is the first
#: that governs it (what :attr:`SlicerProfile.effective` reports for it)
KEYS: dict[str, tuple[tuple[str, tuple[str, ...]], ...]] = {
    "prusaslicer": (
        ("external_perimeter_acceleration", ("outer_wall",)),
        ("perimeter_acceleration", ("inner_wall",)),
        ("top_solid_infill_acceleration", ("top_surface",)),
        ("solid_infill_acceleration", ("solid_infill",)),
        ("infill_acceleration", ("infill",)),
        ("bridge_acceleration", ("bridge_overhang",)),
        ("travel_acceleration", ("travel",)),
        ("default_acceleration", ("other", "support")),
    ),
    "prusaslicer-2.5": (
        ("perimeter_acceleration", ("outer_wall", "inner_wall")),
        ("infill_acceleration", ("infill", "solid_infill", "top_surface")),
        ("bridge_acceleration", ("bridge_overhang",)),
        ("default_acceleration", ("travel", "other", "support")),
    ),
    "orcaslicer": (
        ("outer_wall_acceleration", ("outer_wall",)),
        ("inner_wall_acceleration", ("inner_wall",)),
        ("top_surface_acceleration", ("top_surface",)),
        ("internal_solid_infill_acceleration", ("solid_infill",)),
        ("sparse_infill_acceleration", ("infill",)),
        ("bridge_acceleration", ("bridge_overhang",)),
        ("travel_acceleration", ("travel",)),
        ("default_acceleration", ("other", "support")),
    ),
    "cura": (
        ("acceleration_wall_0", ("outer_wall",)),
        ("acceleration_wall_x", ("inner_wall",)),
        ("acceleration_topbottom", ("top_surface", "solid_infill")),
        ("acceleration_roofing", ("top_surface",)),
        ("acceleration_infill", ("infill",)),
        ("acceleration_travel", ("travel",)),
        ("acceleration_skirt_brim", ("support",)),
        ("acceleration_support", ("support",)),
        ("acceleration_print", ("other",)),
    ),
}
#: why a slicer's profile cannot carry the per-feature corner rule and minimum_cruise_ratio as judged
CORNER_KEYS_WHY = {
    "prusaslicer": "PrusaSlicer has no per-feature corner setting",
    "orcaslicer": ("OrcaSlicer's per-feature jerk, written as SQUARE_CORNER_VELOCITY on Klipper, puts bridge infill, "
                   "which is seen, under infill_jerk with the infill, and it has no minimum_cruise_ratio"),
    "cura": ("Cura's per-feature jerk (jerk_infill, jerk_travel...) is written as M205 X Y, which Klipper ignores and "
             "Marlin's junction deviation does not read, and it has no minimum_cruise_ratio"),
}
#: classes a slicer has no label or key for, and the key whose value they get
CARRIED = {"cura": {"bridge_overhang": "acceleration_wall_0"}}


@dataclass
class SlicerProfile:
    """Settings for one slicer: ``settings`` key -> value as the slicer writes it; ``text`` is the
    fragment to load or paste (``.ini`` lines, a JSON object, Cura ``[values]``); ``effective``:
    feature class -> the acceleration (mm/s²) the re-sliced G-code gives it."""

    slicer: str
    extension: str
    settings: dict[str, object]
    text: str
    notes: list[str] = field(default_factory=list)
    effective: dict[str, float] = field(default_factory=dict)
    version: str | None = None

    def render(self) -> str:
        if self.extension not in ("ini", "cfg"):     # JSON has no comments: the notes go in a "_ringtune" key
            return self.text
        return "\n".join([f"# {n}" for n in self.notes] + [self.text.rstrip("\n")]) + "\n"

    def to_dict(self) -> dict:
        return asdict(self)


def _n(a: float) -> str:
    return f"{a:.0f}" if a == int(a) else f"{a:g}"


def feature_accels(config: TuneConfig) -> dict[str, float]:
    """Class -> mm/s² the config asks for: its ``feature_accel`` (classes and values checked by
    :class:`TuneConfig`), ``accel`` for a class it leaves out."""
    given = config.feature_accel
    missing = [c for c in FEATURE_CLASSES if c not in given]
    if missing and config.accel is None:
        what = (f"for the classes feature_accel leaves out ({', '.join(missing)})" if given
                else "and no feature_accel to put in the slicer profile")
        raise RingtuneError(f"the config has no accel (mm/s²) {what}", "config: accel")
    return {c: float(given.get(c, config.accel)) for c in FEATURE_CLASSES}


def key_values(slicer: str, wanted: dict[str, float]) -> tuple[dict[str, float], dict[str, float]]:
    """({key: mm/s²}, {class: mm/s² the slicer then gives it}) for ``slicer`` (a key of :data:`KEYS`):
    each key at the lowest acceleration of the classes it governs, each class at its own key's."""
    values = {key: min(wanted[c] for c in classes) for key, classes in KEYS[slicer]}
    own = dict(CARRIED.get(slicer, {}))
    for key, classes in KEYS[slicer]:
        for c in classes:
            own.setdefault(c, key)
    return values, {c: values[own[c]] for c in FEATURE_CLASSES}


def _version_key(slicer: str, version: str | None) -> str:
    """The :data:`KEYS` entry for ``slicer`` at ``version`` ("2.5"; None: the current release)."""
    if version is None or slicer != "prusaslicer":
        return slicer
    try:
        major, minor = (int(p) for p in str(version).split(".")[:2])
    except ValueError:
        raise RingtuneError(f"must be a version such as 2.5 or 2.8, not {version!r}", "--slicer-version") from None
    return "prusaslicer-2.5" if (major, minor) < (2, 6) else "prusaslicer"


def _shared_notes(keys: str, wanted: dict, effective: dict) -> list[str]:
    """One note per class the slicer cannot give its own acceleration."""
    out = []
    for c in FEATURE_CLASSES:
        if c in CARRIED.get(keys, {}):
            out.append(f"{c}: no key of its own; printed as walls and skin ({CARRIED[keys][c]} for outer walls)")
        elif effective[c] != wanted[c]:
            key = next(k for k, cls in KEYS[keys] if c in cls)
            out.append(f"{c}: {_n(effective[c])} mm/s², not {_n(wanted[c])}: {key} also governs "
                       f"{', '.join(x for x in dict(KEYS[keys])[key] if x != c)} and takes the lowest")
    return out


def slicer_profile(config: TuneConfig, slicer: str, firmware: str | None = None,
                   version: str | None = None) -> SlicerProfile:
    """The per-feature acceleration settings of ``slicer``'s profile for ``config`` (mm/s²);
    ``version``: the slicer's (PrusaSlicer before 2.6 has fewer keys; None: the current release)."""
    if slicer not in SLICERS:
        raise RingtuneError(f"must be one of {', '.join(SLICERS)}, not {slicer!r}", "--slicer")
    fw = Firmware.named(firmware or config.firmware)
    keys = _version_key(slicer, version)
    wanted = feature_accels(config)
    values, effective = key_values(keys, wanted)
    top = max(values.values())
    common = [f"per-feature accelerations tuned for {fw.title} (mm/s²); the first-layer acceleration "
              "is left as the profile has it"] + _shared_notes(keys, wanted, effective)
    if config.feature_corner or config.feature_min_cruise_ratio:
        common.append("the corner rule and minimum_cruise_ratio per feature class (feature_corner, "
                      f"feature_min_cruise_ratio) are not in this profile ({CORNER_KEYS_WHY[slicer]}): `ringtune "
                      "rewrite` writes them into the sliced job at each feature change")
    seam = {c: wanted[c] for c in FEATURE_CLASSES if c in LABELLED_VISIBLE and wanted[c] < wanted["travel"]}
    if seam:
        common.append("the seam's travel (the hop onto a visible wall, the move off its end) was judged at the wall's "
                      f"acceleration ({', '.join(f'{c} {_n(a)}' for c, a in seam.items())}); a slicer gives every "
                      f"travel {_n(wanted['travel'])}: `ringtune rewrite` of the sliced job writes the seam's travel "
                      "as judged")
    caps = {f"machine_max_acceleration_{ax}": _n(c) for ax, c in zip("xy", config.axis_caps) if c is not None}
    build = {"prusaslicer": _prusaslicer, "orcaslicer": _orcaslicer, "cura": _cura}[slicer]
    prof = build({k: _n(v) for k, v in values.items()}, _n(top), caps, common, fw, keys)
    prof.effective, prof.version = effective, version
    return prof


def _caps_note(caps: dict, top: str) -> str:
    """What the machine's per-axis caps (M201 X Y, when the slicer emits its machine limits) must be."""
    if caps:
        return ("machine_max_acceleration_x/_y are the per-axis caps this config was planned with "
                "(the slicer writes them as M201 X Y)")
    return f"machine_max_acceleration_x/_y must be at least {top}, or M201 caps the features above it"


def _prusa_flavor(fw: Firmware, keys: str) -> tuple[str, str]:
    """(PrusaSlicer's gcode_flavor for ``fw``, why): Klipper takes M204 S, or P and T together, and
    answers the lone M204 P (print) and T (travel) that ``marlin2`` writes per feature with "Invalid
    M204 command"; PrusaSlicer 2.5 has no ``klipper`` flavour, and its legacy ``marlin`` writes M204 S."""
    flavor = _PRUSA_FLAVOR[fw.family]
    if keys == "prusaslicer-2.5" and flavor == "klipper":
        return "marlin", ("legacy Marlin: PrusaSlicer 2.5 has no klipper flavour, and marlin2's lone M204 P and T, "
                          "one per feature, Klipper answers with \"Invalid M204 command\"; legacy Marlin writes M204 S, "
                          "which Klipper takes")
    return flavor, ""


def _prusaslicer(values, top, caps, notes, fw, keys) -> SlicerProfile:
    flavor, why = _prusa_flavor(fw, keys)
    machine = {"gcode_flavor": flavor, "machine_max_acceleration_extruding": f"{top},{top}",
               "machine_max_acceleration_travel": f"{top},{top}", **{k: f"{v},{v}" for k, v in caps.items()}}
    text = ("# printer profile (Printer Settings > General: the G-code flavour; > Machine limits: no feature is "
            "capped below its value)\n"
            + "".join(f"{k} = {v}\n" for k, v in machine.items())
            + "# print profile (Print Settings > Speed > Acceleration control)\n"
            + "".join(f"{k} = {v}\n" for k, v in values.items()))
    notes = notes + [_caps_note(caps, top), f"gcode_flavor = {flavor} for {fw.title}" + (f" ({why})" if why else "")]
    return SlicerProfile("prusaslicer", "ini", {**machine, **values}, text, notes)


def _orcaslicer(values, top, caps, notes, fw, keys) -> SlicerProfile:
    settings = {"gcode_flavor": _PRUSA_FLAVOR[fw.family], "machine_max_acceleration_extruding": [top, top],
                "machine_max_acceleration_travel": [top, top], **{k: [v, v] for k, v in caps.items()}, **values}
    notes = notes + ["machine profile: gcode_flavor (on Klipper: klipper, whose SET_VELOCITY_LIMIT Klipper takes; "
                     "marlin2's lone M204 P and T it ignores) and machine_max_acceleration_* (Orca caps every feature "
                     "at them); process profile: the *_acceleration keys"]
    text = json.dumps({**settings, "_ringtune": notes}, indent=2) + "\n"
    return SlicerProfile("orcaslicer", "json", settings, text, notes)


def _cura(values, top, caps, notes, fw, keys) -> SlicerProfile:
    settings = {"acceleration_enabled": "True", **values, "machine_acceleration": top}
    text = "[values]\n" + "".join(f"{k} = {v}\n" for k, v in settings.items())
    notes = notes + ["Cura writes M204 only with acceleration_enabled; acceleration_roofing applies "
                     "where top surface skin layers (roofing_layer_count) are on"]
    return SlicerProfile("cura", "cfg", settings, text, notes)
