"""Frequency limit: nophead's worked example, the section method, Marlin's XY_FREQUENCY_LIMIT."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.freqlimit import apply_freq_limit, marlin_speed_factors, path_wavelengths
from ringtune.shaping.gcode import read_gcode
from ringtune.shaping.planner import MachineLimits, plan
from ringtune.shaping.testprints import (ZIGZAG_FREQS, ZIGZAG_SPEED, builtin_test_print)


def nophead_spring(loops: int = 1) -> str:
    """nophead's 2.4 mm wide part: 0.6 mm walls (perimeter centre line 0.3 mm in), the 1.2 mm gap
    filled by a zigzag whose strokes are 0.6 mm long, everything at 36 mm/s."""
    lines = ["G90", "M83", "G1 X0.3 Y0.3 F6000", ";TYPE:Perimeter", "G1 F2160"]
    for _ in range(loops):
        for x, y in ((0.3, 19.7), (2.1, 19.7), (2.1, 0.3), (0.3, 0.3)):
            lines.append(f"G1 X{x} Y{y} E0.5")
    lines += ["G1 X0.9 Y0.9 F6000", ";TYPE:Solid infill", "G1 F2160"]
    dy = 0.1
    dx = math.sqrt(0.6 ** 2 - dy ** 2)          # each stroke is 0.6 mm of path
    x, y = 0.9, 0.9
    for k in range(30):
        x = x + dx if k % 2 == 0 else x - dx
        y += dy
        lines.append(f"G1 X{x:.6f} Y{y:.6f} E0.03")
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("method", ["nophead", "sections"])
def test_nophead_worked_example(method):
    """Acceptance 1: a 30 Hz zigzag (0.6 mm strokes at 36 mm/s) under a 20 Hz limit runs at
    24 mm/s; the perimeters keep their speed."""
    job = read_gcode(nophead_spring())
    infill = np.array([job.features[i] == "Solid infill" for i in job.feature]) & job.extruding
    perim = np.array([job.features[i] == "Perimeter" for i in job.feature]) & job.extruding
    lam = path_wavelengths(job, method)
    # (the G-code carries 6 decimals: rtol 1e-6)
    np.testing.assert_allclose(lam[infill], 1.2, rtol=1e-6)            # two 0.6 mm strokes per cycle
    np.testing.assert_allclose(36.0 / lam[infill], 30.0, rtol=1e-6)    # 30 Hz
    assert np.all(np.isinf(lam[perim]))
    limited = apply_freq_limit(job, 20.0, method)
    np.testing.assert_allclose(limited.feed[infill], 24.0, rtol=1e-6)
    np.testing.assert_allclose(limited.feed[perim], 36.0)
    np.testing.assert_allclose(limited.feed[~infill], job.feed[~infill])


def test_perimeter_loops_in_one_path_are_low_frequency():
    job = read_gcode(nophead_spring(loops=3))
    perim = np.array([job.features[i] == "Perimeter" for i in job.feature]) & job.extruding
    lam = path_wavelengths(job, "nophead")
    # three 40 mm loops: each cycle is a whole loop -> 40 mm wavelength, 0.9 Hz at 36 mm/s
    np.testing.assert_allclose(lam[perim], 2 * (19.4 + 1.8), rtol=1e-9)
    np.testing.assert_allclose(apply_freq_limit(job, 20.0, "nophead").feed[perim], 36.0)


def mixed_path() -> str:
    """One extrusion path: ten long 30 mm strokes, then thirty 0.6 mm zigzag strokes (30 Hz)."""
    lines = ["G90", "M83", "G1 X0 Y0 F6000", "G1 F2160"]
    x, y = 0.0, 0.0
    for k in range(10):
        x = 30.0 if k % 2 == 0 else 0.0
        lines.append(f"G1 X{x} Y{y} E1")
        y += 0.45
        lines.append(f"G1 X{x} Y{y} E0.02")
    dy = 0.1
    dx = math.sqrt(0.36 - dy * dy)
    for k in range(30):
        x = x + dx if k % 2 == 0 else x - dx
        y += dy
        lines.append(f"G1 X{x:.6f} Y{y:.6f} E0.03")
    return "\n".join(lines) + "\n"


def test_sections_slow_only_the_high_frequency_part():
    """Acceptance 2."""
    job = read_gcode(mixed_path())
    long_strokes = job.extruding & (np.abs(job.end[:, 0] - job.start[:, 0]) > 10)
    zig = job.extruding & (np.abs(job.end[:, 1] - job.start[:, 1]) == pytest.approx(0.1))
    whole = apply_freq_limit(job, 20.0, "nophead")
    sect = apply_freq_limit(job, 20.0, "sections")
    np.testing.assert_allclose(whole.feed[job.extruding], 24.0, rtol=1e-6)  # the whole path pays
    np.testing.assert_allclose(sect.feed[long_strokes], 36.0)          # long strokes keep speed
    np.testing.assert_allclose(sect.feed[zig], 24.0, rtol=1e-6)        # the zigzag is limited
    lim = MachineLimits(accel=3000, junction="scv")
    t_whole, t_sect, t_none = plan(whole, lim).print_time, plan(sect, lim).print_time, plan(job, lim).print_time
    assert t_none < t_sect < t_whole


def _marlin(seq, limit=20.0, s=0.3):
    """Moves along X from 0 to each target at 50 mm/s."""
    text = "G1 F3000\n" + "".join(f"G1 X{x}\n" for x in seq)
    return marlin_speed_factors(read_gcode(text), limit, s)


def test_marlin_three_segment_rule():
    """Acceptance 3: F20 -> minimum interval 50 ms. 1 mm strokes at 50 mm/s take 20 ms. An axis is
    throttled only once it reversed in each of the last three short segments; the factor is the
    segment time over the interval (20/50 = 0.4)."""
    f = _marlin([10, 9, 10, 9, 10, 9])
    np.testing.assert_allclose(f, [1, 1, 1, 0.4, 0.4, 0.4])
    # two reversals, then a segment in the same direction: never three in a row
    f = _marlin([10, 9, 10, 11, 10, 9, 8])
    np.testing.assert_allclose(f, [1, 1, 1, 1, 1, 1, 1])
    # a long segment (> 50 ms) resets the history
    f = _marlin([10, 9, 10, 9, 30, 29, 30, 29])
    np.testing.assert_allclose(f, [1, 1, 1, 0.4, 1, 1, 1, 0.4])
    # very short strokes: 0.2 mm -> 4 ms -> 0.08, floored at S = 30 %
    f = _marlin([10, 9.8, 10, 9.8, 10])
    np.testing.assert_allclose(f, [1, 1, 1, 0.3, 0.3])


def test_marlin_y_axis_and_the_least_of_both_axes():
    text = "G1 F3000\nG1 Y10\n" + "".join(f"G1 X{0.5 * (k % 2)} Y{10 + (k % 2)}\n" for k in range(1, 7))
    f = marlin_speed_factors(read_gcode(text), 20.0, 0.1)
    seg = round(1e6 * math.hypot(0.5, 1) / 50)                         # us per diagonal stroke
    np.testing.assert_allclose(f[4:], seg / 50000)
    assert np.all(f[:4] == 1)


def test_marlin_method_in_apply_freq_limit_and_job_m201():
    text = "M201 F20 S50\nG1 F3000\n" + "".join(f"G1 X{x}\n" for x in [10, 9, 10, 9, 10])
    job = read_gcode(text)
    out = apply_freq_limit(job, None, "marlin")                        # the job's own M201 F20 S50
    np.testing.assert_allclose(out.feed, [50, 50, 50, 25, 25])         # 0.4 floored at 50 %


def test_builtin_zigzag_sweeps_the_frequencies():
    job = builtin_test_print()
    lam = path_wavelengths(job, "nophead", features=["infill"])
    infill = np.isfinite(lam)
    # the zigzag's worst three cycles are the narrowest block: 80 Hz at the commanded speed
    assert ZIGZAG_SPEED / lam[infill].min() == pytest.approx(max(ZIGZAG_FREQS), rel=1e-3)
    out = apply_freq_limit(job, 30.0, "sections", min_speed_factor=0.1)
    feed = out.feed[infill]
    assert feed[0] == pytest.approx(ZIGZAG_SPEED)                      # the 10 Hz block keeps speed
    assert feed[-1] == pytest.approx(ZIGZAG_SPEED * 30 / 80, rel=1e-3)  # the 80 Hz block: 30 Hz


def test_bad_arguments():
    job = builtin_test_print()
    with pytest.raises(RingtuneError, match="method"):
        apply_freq_limit(job, 20, "fancy")
    with pytest.raises(RingtuneError, match="limit_hz"):
        apply_freq_limit(job, -1, "sections")
    assert apply_freq_limit(job, 0, "sections") is job


def test_marlin_history_starts_at_zero_like_its_static_variables():
    # Marlin's xs0..ys2 are zero-initialised statics: a short first segment in -X is throttled
    # (X "changed direction" from the initial all-positive bits, and the history holds zeros)
    np.testing.assert_allclose(_marlin([-1]), [0.4])
    np.testing.assert_allclose(_marlin([1]), [1.0])            # +X: no direction change


def test_marlin_floor_is_the_files_m201_s_or_marlins_default_5_percent():
    """XY_FREQUENCY_MIN_PERCENT is 5 in Marlin's Configuration_adv.h; an M201 S in the job sets
    another (constrained to 1..100 %). 0.2 mm strokes at 50 mm/s take 4 ms of a 50 ms interval:
    the rule asks 0.08, above 5 % but below S10 -> 0.10."""
    moves = "G1 F3000\n" + "".join(f"G1 X{x}\n" for x in [10, 9.8, 10, 9.8, 10])
    plain = read_gcode(moves)
    np.testing.assert_allclose(apply_freq_limit(plain, 20.0, "marlin").feed, [50, 50, 50, 4, 4])
    with_s = read_gcode("M201 F20 S10\n" + moves)
    np.testing.assert_allclose(apply_freq_limit(with_s, None, "marlin").feed, [50, 50, 50, 5, 5])
    np.testing.assert_allclose(apply_freq_limit(with_s, 20.0, "marlin").feed, [50, 50, 50, 5, 5])
    np.testing.assert_allclose(apply_freq_limit(with_s, 20.0, "marlin", 0.5).feed, [50, 50, 50, 25, 25])
    s0 = read_gcode("M201 F20 S0\n" + moves)                         # constrain(S, 1, 100) -> 1 %
    np.testing.assert_allclose(apply_freq_limit(s0, None, "marlin").feed, [50, 50, 50, 4, 4])
