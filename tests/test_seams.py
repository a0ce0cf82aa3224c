"""Seams (shaping/seams.py): the quality windows hold where a visible wall starts and ends next to
motion of another class, so settings per feature that land on the wall are judged there.

The candidates are checked against the trapezoid by hand; the judgement against the physics it
exposes: on the sliced part, inner walls driven harder ring into the outer wall's seam — which
windows on the sharpest corners alone do not see — while the seam's travel, run at the wall's own
acceleration (Klipper and RepRapFirmware alike), leaves the wall as it was."""

from __future__ import annotations

import dataclasses
import functools
import math

import pytest

from ringtune.envs import evaluate as ev
from ringtune.envs.planned_job import clear_cache
from ringtune.envs.printer import load_printer
from ringtune.shaping import testprints
from ringtune.shaping.builtin_jobs import job_path
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.feature_settings import effective_classes
from ringtune.shaping.features import FEATURE_CLASSES, LABELLED_VISIBLE, VISIBLE
from ringtune.shaping.gcode import read_gcode
from ringtune.shaping.planner import MachineLimits, plan
from ringtune.shaping.seams import job_seen_classes, seam_candidates

WALL = """G28
G1 Z0.2 F600
;TYPE:External perimeter
G1 X0 Y10 F15000
G1 X20 Y10 E1 F3000
G1 X20 Y30 E2
G1 X70 Y30 F15000
;TYPE:Internal infill
G1 X70 Y50 E3 F3000
"""


def test_a_wall_between_two_travels_has_one_seam_each_side_scored_by_the_travel_speed():
    accel, scv = 3000.0, 5.0
    p = plan(read_gcode(WALL), MachineLimits(accel=accel, square_corner_velocity=scv, min_cruise_ratio=0.0))
    span = 0.25
    c = seam_candidates(p, span)
    (t_in,), (s_in,), (l_in,), (k_in,) = c["seam-in"]
    (t_out,), (s_out,), (l_out,), (k_out,) = c["seam-out"]
    lines = WALL.splitlines()
    assert lines[l_in - 1] == "G1 X20 Y10 E1 F3000" and k_in == "outer_wall"     # the wall's first move
    assert lines[l_out - 1] == "G1 X20 Y30 E2" and k_out == "outer_wall"         # its last
    # the 10 mm hop from rest into a 90° corner: v² = v_corner²/2 + a·L, Klipper's corner speed at
    # 90° being square_corner_velocity itself
    assert s_in == pytest.approx(math.sqrt(scv ** 2 / 2 + accel * 10.0), rel=1e-3)
    # the 50 mm travel after it reaches its feed, 15000 mm/min (sqrt(a·L) = 387 mm/s is more)
    assert s_out == pytest.approx(250.0)
    # the entry window starts 0.2 span before the wall; the exit window ends 0.2 span after it
    mv = p.moves
    i_in, i_out = list(mv.line).index(l_in), list(mv.line).index(l_out)
    assert t_in == pytest.approx(mv.t_start[i_in] - 0.2 * span)
    assert t_out + span == pytest.approx(mv.t_start[i_out] + mv.duration[i_out] + 0.2 * span)
    # the infill after the travel is hidden: no seam of its own
    assert set(c["seam-in"][3]) == set(c["seam-out"][3]) == {"outer_wall"}


def test_a_purge_line_before_labelled_walls_is_not_seen_but_unlabelled_walls_are():
    limits = MachineLimits(accel=3000.0, square_corner_velocity=5.0, min_cruise_ratio=0.0)
    purge = "G28\nG1 Z0.2 F600\nG1 X0 Y0 F6000\nG1 X0 Y100 E5 F1500\n" + WALL.split("G1 Z0.2 F600\n", 1)[1]
    assert job_seen_classes(plan(read_gcode(purge), limits)) == LABELLED_VISIBLE
    bare = "\n".join(ln for ln in purge.splitlines() if not ln.startswith(";TYPE:"))
    assert job_seen_classes(plan(read_gcode(bare), limits)) == VISIBLE


def test_the_seams_travel_takes_the_walls_class_for_klippers_one_acceleration():
    """The travel landing on the wall and the one leaving it run with the wall's settings; a travel
    between two hidden extrusions stays travel."""
    job = read_gcode(WALL + "G1 X90 Y50 F15000\nG1 X90 Y70 E4 F3000\n")
    cls = [FEATURE_CLASSES[c] for c in effective_classes(job)]
    lines = WALL.splitlines() + ["G1 X90 Y50 F15000", "G1 X90 Y70 E4 F3000"]
    by_line = {lines[ln - 1]: c for ln, c in zip(job.line, cls)}
    assert by_line["G1 X0 Y10 F15000"] == "outer_wall"       # lands on the wall's seam
    assert by_line["G1 X70 Y30 F15000"] == "outer_wall"      # leaves the wall's end
    assert by_line["G1 X90 Y50 F15000"] == "travel"          # infill to infill
    assert by_line["G1 X70 Y50 E3 F3000"] == "infill"


def test_every_move_of_a_hop_onto_the_wall_takes_the_walls_class():
    """A hop in three travel moves (CuraEngine's G0s) onto the wall: all three run with the wall's
    settings, not only the last short one, after which the wall would ring from the long one's
    deceleration; a hop in two moves from the wall to the infill keeps travel after its first move."""
    gcode = ("G28\nG1 Z0.2 F600\n;TYPE:WALL-OUTER\nG1 X0 Y10 E1 F3000\nG0 X30 Y10 F9000\nG0 X30 Y40\nG0 X30.5 Y40\n"
             "G1 X50 Y40 E2 F3000\nG0 X50 Y60 F9000\nG0 X60 Y60\n;TYPE:FILL\nG1 X60 Y80 E3 F3000\n")
    job = read_gcode(gcode)
    cls = [FEATURE_CLASSES[c] for c in effective_classes(job)]
    by_line = dict(zip((gcode.splitlines()[ln - 1] for ln in job.line), cls))
    for hop in ("G0 X30 Y10 F9000", "G0 X30 Y40", "G0 X30.5 Y40"):
        assert by_line[hop] == "outer_wall", hop
    assert by_line["G0 X50 Y60 F9000"] == "outer_wall"       # leaves the wall's end
    assert by_line["G0 X60 Y60"] == "travel"                 # on to the infill
    assert by_line["G1 X60 Y80 E3 F3000"] == "infill"


def test_the_windows_hold_the_seams_and_keep_them_on_another_plan():
    p = plan(read_gcode(WALL), MachineLimits(accel=3000))
    wins = testprints.quality_windows(p, max_windows=2, span=0.1)
    assert {w.kind for w in wins} >= {"seam-in", "seam-out"}
    other = plan(read_gcode(WALL), MachineLimits(accel=9000))
    moved = testprints.relocate_windows(other, wins, span=0.1)
    assert [(w.kind, w.line) for w in moved] == [(w.kind, w.line) for w in wins]
    assert not [w for w in testprints.quality_windows(p, max_windows=2, span=0.1, seams=0) if w.kind.startswith("seam")]


PART_SINGLE = TuneConfig(firmware="klipper", shaper_x="zvd", shaper_y="mzv", freq_x=65.0, freq_y=42.7,
                         damping_x=0.145, damping_y=0.09, accel=6100.0)
FAST_HIDDEN = {"infill": 13800.0, "support": 13800.0, "travel": 10800.0}
QUALITY_WINDOWS = testprints.quality_windows


def _outer_wall(firmware: str, junction: str, seams: int, feature_accel: dict, monkeypatch):
    """The outer wall's judged figures of the part's single acceleration and of the same with
    ``feature_accel``, under ``firmware`` and its junction rule."""
    base = load_printer(None)
    printer = dataclasses.replace(base, limits_dict={**(base.limits_dict or {}), "junction": junction})
    single = dataclasses.replace(PART_SINGLE, firmware=firmware)
    fast = dataclasses.replace(single, feature_accel=dict(feature_accel))
    monkeypatch.setattr(testprints, "quality_windows", functools.partial(QUALITY_WINDOWS, seams=seams))
    clear_cache()
    try:
        ms = ev.evaluate_many([single, fast], printer, str(job_path("part")), freq_margin=0.05)
    finally:
        clear_cache()
    return [m.features["outer_wall"] for m in ms]


def test_inner_walls_driven_harder_show_on_the_outer_wall_at_its_seam(monkeypatch):
    # the inner wall ends 0.6 mm before the outer wall starts: at 13,800 mm/s² (walls 6100) its stop
    # rings into the seam
    with monkeypatch.context() as mp:
        single, fast = _outer_wall("klipper", "scv", 0, {"inner_wall": 13800.0}, mp)
    # on the sharpest corners alone the outer wall cannot tell the two apart
    for k in ("ripple_mm", "corner_in_mm", "corner_out_mm", "extrusion_under_pct"):
        assert fast[k] == pytest.approx(single[k], abs=1e-6), k
    with monkeypatch.context() as mp:
        single, fast = _outer_wall("klipper", "scv", testprints.SEAM_WINDOWS, {"inner_wall": 13800.0}, mp)
    # with its seams judged: ripple and overshoot beyond the reports' resolution (1 µm or 5 %)
    for k in ("ripple_mm", "corner_out_mm"):
        assert fast[k] > max(single[k] * 1.05, single[k] + 1e-3), k


@pytest.mark.parametrize("firmware,junction", [("klipper", "scv"), ("rrf", "jerk")])
def test_the_seams_travel_at_the_walls_acceleration_leaves_the_wall_as_it_was(firmware, junction, monkeypatch):
    """Infill at 13,800 and travel at 10,800 mm/s²: the hop onto the outer wall and the move off its
    end run at the wall's (Klipper's one acceleration by class; M204 T written around them), so the
    wall's judged figures, seams included, are the single acceleration's."""
    single, fast = _outer_wall(firmware, junction, testprints.SEAM_WINDOWS, FAST_HIDDEN, monkeypatch)
    for k in ("ripple_mm", "corner_in_mm", "corner_out_mm", "extrusion_over_pct", "extrusion_under_pct"):
        assert fast[k] == pytest.approx(single[k], rel=1e-6, abs=1e-9), k
