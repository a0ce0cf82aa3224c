"""Built-in test print and quality windows."""

from __future__ import annotations

import numpy as np
import pytest

from ringtune.shaping.gcode import read_gcode
from ringtune.shaping.planner import MachineLimits, plan
from ringtune.shaping.testprints import (ZIGZAG_FREQS, ZIGZAG_SPEED, ZIGZAG_STEP, builtin_test_print,
                                         direction_change_frequencies, quality_windows,
                                         zigzag_stroke_width)


def test_builtin_is_a_few_seconds_with_all_three_parts():
    job = builtin_test_print()
    p = plan(job, MachineLimits())
    assert 4.0 < p.print_time < 12.0
    feats = p.time_by_feature()
    assert {"External perimeter", "Internal infill", "Perimeter"} <= set(feats)
    assert not job.arc.any()                    # the curve is short straight segments, as slicers write


def test_builtin_is_a_modern_job_in_miniature():
    """Long straight walls, a 90° corner before each, an acute corner, a curve of short segments,
    a zigzag, labelled as PrusaSlicer labels them, at speeds a current printer uses."""
    job = builtin_test_print()
    label = np.array(job.features)[job.feature]
    d = job.delta[:, :2]
    length = np.hypot(d[:, 0], d[:, 1])
    ext = job.extruding
    outer = ext & (label == "External perimeter")
    inner = ext & (label == "Perimeter")
    assert length[outer].max() >= 60 and length[inner].max() >= 60       # long straight walls
    assert np.sum(outer & (length > 0.5) & (length < 3)) >= 10            # a curve of short chords
    u = d / np.maximum(length, 1e-12)[:, None]
    turn = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", u[1:], u[:-1]), -1, 1)))
    both = outer[1:] & outer[:-1]
    assert turn[both].max() > 115                                         # an acute corner
    assert np.sum(both & (np.abs(turn - 90) < 1)) >= 2                    # 90° corners
    assert job.feed[outer].max() >= 150 and job.feed[inner].max() >= 200 and job.feed[ext].max() >= 250


def test_zigzag_stroke_width_gives_the_frequency():
    for f in ZIGZAG_FREQS:
        w = zigzag_stroke_width(f)
        stroke = np.hypot(w, ZIGZAG_STEP)
        assert ZIGZAG_SPEED / (2 * stroke) == pytest.approx(f)


def test_direction_change_frequency_of_a_slow_zigzag_is_exact():
    # 2 mm strokes along X at 20 mm/s; the reversals stop, but at 1e6 mm/s² the ramps are negligible
    lines = ["M83", "G1 X0 Y0 F1200"]
    for k in range(20):
        lines.append(f"G1 X{2 if k % 2 == 0 else 0} Y{0.001 * (k + 1)} E0.1")
    p = plan(read_gcode("\n".join(lines) + "\n"), MachineLimits(accel=1e6, junction="scv"))
    t, f, line = direction_change_frequencies(p)
    # each stroke takes 2/20 s plus negligible ramps: 0.2 s per cycle -> 5 Hz
    assert f.max() == pytest.approx(5.0, rel=1e-2)


def test_quality_windows_pick_corners_and_fast_zigzags():
    p = plan(builtin_test_print(), MachineLimits(accel=3000))
    wins = quality_windows(p, max_windows=6, span=0.2, seams=0)
    # six by the shares, one more for each class with corners they left without a window
    shared = {w.feature for w in wins}
    assert 6 <= len(wins) <= 6 + 1 and shared == {"outer_wall", "inner_wall", "infill"}
    kinds = {w.kind for w in wins}
    assert kinds == {"corner", "zigzag"}
    for a, b in zip(wins, wins[1:]):
        assert a.t1 <= b.t0 + 1e-12                              # sorted, not overlapping
    for w in wins:
        assert 0 <= w.t0 < w.t1 <= p.print_time
        assert w.t1 - w.t0 == pytest.approx(0.2)
    # the zigzag windows are the fastest ones available
    t, f, _ = direction_change_frequencies(p)
    z = [w for w in wins if w.kind == "zigzag"]
    assert max(w.score for w in z) == pytest.approx(f.max())
    # corner windows sit on the walls' corners: the outer wall's first, then the hidden features'
    corners = [w for w in wins if w.kind == "corner"]
    assert all(w.score > 50 for w in corners)
    assert [w.feature for w in corners].count("outer_wall") >= 2
    # with the default eight windows, every labelled class with corners is judged somewhere
    eight = quality_windows(p, seams=0)
    assert {w.feature for w in eight} == {"outer_wall", "inner_wall", "infill"}


def test_quality_windows_on_a_long_real_job(data_dir):
    job = read_gcode(data_dir / "gcode/ianalexis_ender3_marlin/ringing_tower.gcode")
    p = plan(job, MachineLimits(junction="jd"))
    wins = quality_windows(p, max_windows=8, span=0.25, seams=0)
    assert 1 <= len(wins) <= 8
    assert sum(w.t1 - w.t0 for w in wins) < 0.01 * p.print_time
