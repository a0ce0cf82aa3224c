"""The gap an infill excursion must cross to reach the outer wall, from what the job states.

Truth: the job's own coordinates. On the built-in part (PrusaSlicer 2.5, 2 perimeters), the
distance from each infill line's ends to the nearest outer-wall segment of the same layer, less
half a spacing of each bead, is the gap the slicer actually left; the stated-settings formula must
match its median within 20 µm. The inner perimeter's centre lies one spacing from the outer one's.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from ringtune.shaping.builtin_jobs import job_path
from ringtune.shaping.gcode import read_gcode
from ringtune.shaping.wall_gap import infill_wall_gap, spacing

GCODE = Path(__file__).resolve().parent / "data" / "gcode"


def _distances(job, label: str, every: int = 6) -> np.ndarray:
    """Distances (mm) from the ends of ``label`` moves to the nearest outer-wall segment of their
    layer, over every ``every``-th layer that has both."""
    names = np.array(job.features)[job.feature]
    s, e = job.start, job.end
    z = np.round(e[:, 2], 3)
    moving = (np.hypot(*(e - s)[:, :2].T) > 1e-6) & job.extruding
    out = []
    for zz in sorted(set(z[moving & (names == label)]))[::every]:
        layer = (z == zz) & moving
        wall = layer & (names == "External perimeter")
        if not wall.any():
            continue
        a, b = s[wall, :2], e[wall, :2]
        sel = np.flatnonzero(layer & (names == label))
        p = np.concatenate([s[sel, :2], e[sel, :2]])
        ab = b - a
        t = np.clip(((p[:, None] - a[None]) * ab[None]).sum(-1) / (ab ** 2).sum(-1)[None], 0.0, 1.0)
        out.append(np.hypot(*(p[:, None] - (a[None] + t[..., None] * ab[None])).transpose(2, 0, 1)).min(1))
    return np.concatenate(out)


def test_the_stated_gap_is_the_gap_the_slicer_left_on_the_part():
    path = job_path("part")
    g = infill_wall_gap(path)
    assert g is not None and g.perimeters == 2 and g.width_mm == 0.45 and g.layer_mm == 0.2
    assert g.spacing_mm == pytest.approx(0.45 - 0.2 * (1 - math.pi / 4))
    assert g.overlap_mm == pytest.approx(0.25 * 0.45)                   # infill_overlap = 25 % of the width
    job = read_gcode(path)
    inner = _distances(job, "Perimeter")
    assert np.median(inner) == pytest.approx(g.spacing_mm, abs=0.005)    # beads one spacing apart
    ends = _distances(job, "Internal infill")
    measured = np.median(ends) - g.spacing_mm            # half a spacing of the infill bead and of the wall's
    assert g.gap_mm == pytest.approx(measured, abs=0.02)
    assert 0.25 < g.gap_mm < 0.35


def test_one_perimeter_leaves_no_gap_and_an_unstated_job_gives_none():
    one = infill_wall_gap(f"{GCODE}/ianalexis_ender3_marlin/ringing_tower.gcode")   # PrusaSlicer, 1 perimeter
    assert one is not None and one.perimeters == 1 and one.gap_mm == 0.0
    assert one.overlap_mm == pytest.approx(0.15 * 0.45)
    assert infill_wall_gap(f"{GCODE}/fastlb_cura_um2/platte_klein_cut.gcode") is None     # Cura states none
    assert infill_wall_gap("/nonexistent/job.gcode") is None
    assert spacing(0.45, 0.0) == 0.45


def test_tunes_show_through_bound_is_the_jobs_gap_or_a_stated_assumption():
    """The bound tune rules hidden features out with: the user's, else the job's own gap (the part:
    the gap computed in this test from the numbers the file states), else 0.05 mm said aloud."""
    from ringtune.shaping.builtin_jobs import job_path
    from ringtune.shaping.wall_gap import show_through_bound

    text = open(job_path("part"), encoding="utf-8").read()
    n = int(re.search(r"^; perimeters = (\d+)", text, re.M).group(1))
    w = float(re.search(r"^; perimeters extrusion width = ([\d.]+)mm", text, re.M).group(1))
    h = float(re.search(r"^; layer_height = ([\d.]+)", text, re.M).group(1))
    ov = float(re.search(r"^; infill_overlap = ([\d.]+)%", text, re.M).group(1)) / 100 * w
    expected = (n - 1) * (w - h * (1 - math.pi / 4)) - ov
    bound, why = show_through_bound("part", None, 0.05)
    assert bound == pytest.approx(expected, rel=1e-9) and "the job's own gap" in why
    assert show_through_bound("part", 0.2, 0.05) == (0.2, "show-through bound 200 µm (--max-show-through)")
    bound, why = show_through_bound(None, None, 0.05)
    assert bound == 0.05 and "assumed" in why and "built-in print" in why
