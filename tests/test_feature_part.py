"""Issue 22 on the built-in part (PrusaSlicer 2.5, a current Ender-3-class profile): Klipper's pick
from the default printer's files, and the same with the infill, then the travel, at the top of its
range (the weakest motor keeps 20 % of its force at the group's own top speed).

Judged as tune judges (the printer and its resonances ±5 %), each configuration simulated on its
own. The infill at its top keeps every visible measure the pick's (1 µm or 5 %; 0.5 points of
extrusion), the motors within their reserve, the infill's show-through inside the gap the job's
slicer left between it and the outer wall (:mod:`ringtune.shaping.wall_gap`), and the job faster.
The travel at its top does not: the hop from the inner wall into the outer wall's start runs at
the travel's acceleration, and the outer wall under-extrudes at its seam (the seam windows,
:mod:`ringtune.shaping.seams`) — a person sees it, so tune may not take it.
"""

from __future__ import annotations

import dataclasses

from ringtune.agents.tune.baselines import recorded_klipper
from ringtune.agents.tune.feature_space import feature_space
from ringtune.agents.tune.space import ACCEL_GROUPS, default_space
from ringtune.envs.evaluate import evaluate_many
from ringtune.envs.printer import load_printer
from ringtune.shaping.builtin_jobs import job_path
from ringtune.shaping.features import VISIBLE
from ringtune.shaping.wall_gap import infill_wall_gap

RESERVE = 0.2
SEEN = ("ripple_mm", "ripple_p90_mm", "corner_in_mm", "corner_out_mm")


def _judged(printer, pick, levels):
    fa = {c: a for g, a in levels.items() for c in ACCEL_GROUPS[g]}
    return evaluate_many([pick, dataclasses.replace(pick, feature_accel=fa)], printer, "part", freq_margin=0.05)


def test_infill_at_its_motor_top_keeps_the_parts_visible_measures_and_reserve():
    printer = load_printer(None)
    pick, _ = recorded_klipper(printer, "klipper")
    space = feature_space(default_space(printer, "klipper"), printer, "part", RESERVE,
                          corner=False, min_cruise_ratio=False)
    tops = {g: hi for g, _lo, hi in space.feature_accel if g in ("infill", "travel")}
    assert len(tops) == 2 and min(tops.values()) > 2 * pick.accel
    ref, m = _judged(printer, pick, {"infill": tops["infill"]})
    for k in SEEN:
        a, b = getattr(m, k), getattr(ref, k)
        assert a <= b + max(1e-3, 0.05 * b), k
    for k in ("extrusion_over_pct", "extrusion_under_pct"):
        for cls in set(m.features) & VISIBLE:
            assert m.features[cls][k] <= ref.features.get(cls, {}).get(k, 0.0) + 0.5, (cls, k)
    assert m.motor_load <= 1 - RESERVE and not m.step_loss
    gap = infill_wall_gap(job_path("part"))
    assert gap is not None and m.features["infill"]["show_through_mm"] < gap.gap_mm
    assert m.print_time_s < 0.95 * ref.print_time_s
    # the travel at its top: the motors allow it, the outer wall's seam does not
    ref, m = _judged(printer, pick, {"travel": tops["travel"]})
    assert m.motor_load <= 1 - RESERVE and m.print_time_s < ref.print_time_s
    wall, wall_ref = m.features["outer_wall"], ref.features["outer_wall"]
    assert wall["extrusion_under_pct"] > wall_ref["extrusion_under_pct"] + 5.0
