"""How far an infill excursion may go before it reaches the outer wall, from what the slicer states.

nophead's serrated edge is infill that overshoots its turning points far enough to push into the
outer wall. Between the two lie the inner perimeters, less what the infill is told to overlap them.
PrusaSlicer-family slicers (PrusaSlicer, SuperSlicer, OrcaSlicer) write the numbers it takes into
the job's comments: ``; perimeters = N``, ``; perimeters extrusion width = Wmm``, ``; infill_overlap
= P%`` (or mm), ``; layer_height = H``. Beads lie at PrusaSlicer's *spacing* s = w − h·(1 − π/4)
(its Flow model: a bead is a rectangle with round ends), so the gap from the edge of an infill bead
at its turning point to the edge of the outer wall's bead is

    gap = (N − 1)·s − overlap,     overlap = P·w (a percentage of the perimeter width) or P mm,

at least 0 (one perimeter: the infill overlaps the outer wall itself). Worked example (the built-in
part: N = 2, w = 0.45 mm, h = 0.2 mm, 25 %): s = 0.4071 mm, overlap 0.1125 mm, gap 0.295 mm; the
part's own coordinates put its infill ends' bead edges a median 0.305 mm from the outer wall's.
Inner walls abut the outer wall (gap 0): any excursion of theirs towards it pushes it. Units: mm.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

from ringtune.shaping.builtin_jobs import job_path
from ringtune.shaping.gcode_file import gcode_text_or_none

_NUM = r"([\d.]+)"
_RX = {
    "perimeters": re.compile(r"^;\s*(?:perimeters|wall_loops)\s*=\s*(\d+)\s*$", re.M),
    "width": re.compile(r"^;\s*perimeters extrusion width\s*=\s*" + _NUM + r"\s*mm", re.M),
    "overlap": re.compile(r"^;\s*infill_overlap\s*=\s*" + _NUM + r"\s*(%?)", re.M),
    "layer": re.compile(r"^;\s*layer_height\s*=\s*" + _NUM, re.M),
}


@dataclass(frozen=True)
class WallGap:
    """The gap (mm) between an infill bead's edge at its turning point and the outer wall's bead,
    and what it was computed from (perimeter count, width and spacing mm, overlap mm, layer mm)."""

    gap_mm: float
    perimeters: int
    width_mm: float
    spacing_mm: float
    overlap_mm: float
    layer_mm: float

    def describe(self) -> str:
        return (f"{self.gap_mm * 1000:.0f} µm: ({self.perimeters} − 1) perimeters × {self.spacing_mm:.3f} mm "
                f"spacing ({self.width_mm:g} mm wide at {self.layer_mm:g} mm layers) − {self.overlap_mm:.3f} mm "
                f"infill overlap, as the job states them")


def spacing(width_mm: float, layer_mm: float) -> float:
    """PrusaSlicer's centre-to-centre spacing of touching beads, mm: w − h·(1 − π/4)."""
    return width_mm - layer_mm * (1.0 - math.pi / 4.0)


def infill_wall_gap(path) -> WallGap | None:
    """The gap from what the job's comments state (PrusaSlicer family), or None when it does not
    state all of perimeter count, perimeter width, infill overlap and layer height."""
    text = gcode_text_or_none(path)
    if text is None:
        return None
    found = {k: rx.search(text) for k, rx in _RX.items()}
    if not all(found.values()):
        return None
    n = int(found["perimeters"].group(1))
    w = float(found["width"].group(1))
    h = float(found["layer"].group(1))
    pct = found["overlap"].group(2) == "%"
    ov = float(found["overlap"].group(1)) * (w / 100.0 if pct else 1.0)
    if w <= 0 or h <= 0:
        return None
    s = spacing(w, h)
    return WallGap(max(0.0, (n - 1) * s - ov), n, w, s, ov, h)


def show_through_bound(job, given_mm: float | None, default_mm: float) -> tuple[float, str]:
    """(bound mm, where it comes from) for hidden features reaching the outer wall: ``given_mm``
    when the user gave one; else the job's own infill-to-wall gap (:func:`infill_wall_gap`) where
    the job states it; else ``default_mm``, said to be an assumption."""
    if given_mm is not None:
        return given_mm, f"show-through bound {given_mm * 1000:g} µm (--max-show-through)"
    gap = infill_wall_gap(job_path(job)) if job else None
    if gap is not None and gap.gap_mm > 0:
        return gap.gap_mm, (f"show-through bound {gap.describe()}: the job's own gap between its infill and "
                            "its outer wall (--max-show-through overrides)")
    why = "the job does not state its perimeters, widths and infill overlap" if job else "the built-in print"
    return default_mm, (f"show-through bound {default_mm * 1000:g} µm, assumed ({why}; about 10 % of a "
                        "0.45 mm line; --max-show-through sets it)")
