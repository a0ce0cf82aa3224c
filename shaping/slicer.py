"""What slicers write about a job in its comments: their own print-time estimate."""

from __future__ import annotations

import re

from ringtune.shaping.gcode_file import gcode_text_or_none


_EST_PRUSA = re.compile(r";\s*(?:estimated printing time \(normal mode\)|total estimated time)\s*[=:]\s*(.+)", re.I)
_EST_S3D = re.compile(r";\s*Build time:\s*(.+)", re.I)
_EST_CURA = re.compile(r"^;TIME:\s*(\d+(?:\.\d+)?)\s*$", re.M)
_ELAPSED_CURA = re.compile(r";TIME_ELAPSED:\s*(\d+(?:\.\d+)?)")
#: the ``;TIME:`` CuraEngine writes before it has estimated anything; Cura's window puts its
#: estimate there afterwards, a job sliced by CuraEngine alone keeps it (111 min for any model)
CURA_TIME_PLACEHOLDER = 6666.0
_DURATION = re.compile(r"(\d+(?:\.\d+)?)\s*(d|days?|h|hours?|m|min|minutes?|s|sec|seconds?)\b", re.I)


def _duration_seconds(text: str) -> float | None:
    total, found = 0.0, False
    for value, unit in _DURATION.findall(text):
        u = unit.lower()[0]
        total += float(value) * {"d": 86400, "h": 3600, "m": 60, "s": 1}[u]
        found = True
    return total if found else None


def _text(path) -> str | None:
    """The file's text (undecodable bytes replaced), or None when it cannot be read."""
    return gcode_text_or_none(path)


def slicer_estimate(path) -> float | None:
    """The print time (s) the slicer wrote into the file (PrusaSlicer/Orca ``estimated printing
    time (normal mode)``, Simplify3D ``Build time``, Cura ``;TIME:``; where that is CuraEngine's
    placeholder, :data:`CURA_TIME_PLACEHOLDER`, or absent, its last ``;TIME_ELAPSED:``, the
    engine's own estimate at the last layer's end), or None."""
    text = _text(path)
    if text is None:
        return None
    for rx in (_EST_PRUSA, _EST_S3D):
        m = rx.search(text)
        if m:
            return _duration_seconds(m.group(1))
    m = _EST_CURA.search(text)
    if m and float(m.group(1)) != CURA_TIME_PLACEHOLDER:
        return float(m.group(1))
    last = _ELAPSED_CURA.match(text, max(text.rfind(";TIME_ELAPSED:"), 0))
    return float(last.group(1)) if last else (float(m.group(1)) if m else None)


#: the firmware a slicer says it wrote the job for: PrusaSlicer / SuperSlicer / OrcaSlicer
#: ``; gcode_flavor = marlin2``, Cura ``;FLAVOR:Marlin``
_FLAVOR_PRUSA = re.compile(r"^;\s*gcode_flavor\s*=\s*([\w-]+)", re.M | re.I)
_FLAVOR_CURA = re.compile(r"^;FLAVOR:\s*([\w-]+)", re.M | re.I)


def slicer_flavor(path) -> str | None:
    """The G-code flavour the slicer wrote into the file, lower case (``marlin2``, ``marlin``,
    ``klipper``, ``reprapfirmware``, ``griffin``...), or None."""
    text = _text(path)
    if text is None:
        return None
    for rx in (_FLAVOR_PRUSA, _FLAVOR_CURA):
        m = rx.search(text)
        if m:
            return m.group(1).lower()
    return None


#: the filament a slicer says it sliced for (first extruder): PrusaSlicer / SuperSlicer / OrcaSlicer
#: ``; filament_diameter = 1.75`` and ``; filament_density = 1.24`` (several extruders: ``1.24,1.27``
#: or ``1.24;1.27``), Simplify3D ``;   filamentDiameters,1.75|…`` and ``;   filamentDensities,1.25|…``
_FILAMENT = {
    "diameter_mm": (re.compile(r"^;\s*filament_diameter\s*=\s*([\d.]+)", re.M | re.I),
                    re.compile(r"^;\s*filamentDiameters,([\d.]+)", re.M)),
    "density_g_cm3": (re.compile(r"^;\s*filament_density\s*=\s*([\d.]+)", re.M | re.I),
                      re.compile(r"^;\s*filamentDensities,([\d.]+)", re.M)),
}


def slicer_filament(path) -> dict[str, float]:
    """The filament diameter (mm) and density (g/cm³) the slicer wrote into the file, as far as it
    wrote them: ``{"diameter_mm": …, "density_g_cm3": …}`` (keys absent when not found; a density
    of 0, a slicer's "unset", is left out)."""
    text = _text(path)
    out: dict[str, float] = {}
    for key, rxs in _FILAMENT.items():
        for rx in rxs if text is not None else ():
            m = rx.search(text)
            if m:
                try:
                    v = float(m.group(1))
                except ValueError:
                    continue
                if v > 0:
                    out[key] = v
                break
    return out
