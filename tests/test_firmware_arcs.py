"""Arcs as Marlin 2.1 cuts them (``plan_arc``, Marlin/src/gcode/motion/G2_G3.cpp, default build:
MIN_ARC_SEGMENT_MM 0.1, MAX_ARC_SEGMENT_MM 1.0, MIN_CIRCLE_SEGMENTS 72), as RepRapFirmware 3.5+ does
(``GCodes::DoArcMove``, Configuration.h: MaxArcDeviation 0.005, MinArcSegmentLength 0.02,
MaxArcSegmentLength 1.0, MaxArcSegmentsPerSec 200) and as Prusa Buddy does (its ``plan_arc``,
Configuration_MK4_adv.h and the other printers': MAX_ARC_DEVIATION 0.02, MIN_ARC_SEGMENT_MM 0.1,
MAX_ARC_SEGMENT_MM 2.0, MIN_ARC_SEGMENTS_PER_SEC 50, at the feed rate before M220): equal-angle segments,
their number worked out by hand below from those rules; a job read as the firmware reads it plans as
those segments written out in G1 moves."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from ringtune.agents.cli.main import main
from ringtune.shaping.arcs import MARLIN_ARCS, PRUSA_ARCS, RRF_ARCS, arc_resolution
from ringtune.shaping.config_plan import plan_with_config
from ringtune.shaping.firmware import job_reading
from ringtune.shaping.gcode import read_gcode
from ringtune.shaping.planner import MachineLimits

MARLIN = MachineLimits(accel=1500.0, velocity=200.0, junction="jd", junction_deviation=0.013,
                       klipper_reading=False, reads_m566=False, arc_firmware="marlin")


@pytest.mark.parametrize("radius, sweep, segments", [
    # a full 3 mm circle: 18.85 mm; 18 whole mm < the 72 a circle takes; 0.26 mm each
    (3.0, 2 * math.pi, 72),
    # a quarter of a 40 mm circle: 62.83 mm; 62 whole mm (≥ 18) would be 1.013 mm each, over the
    # 1 mm most: ceil(62.83) = 63
    (40.0, math.pi / 2, 63),
    # half a 0.5 mm circle: 1.571 mm; 36 by the circle's share, 0.044 mm each, under the 0.1 mm least:
    # floor(15.71) = 15
    (0.5, -math.pi, 15),
    # a tenth of a turn on 10 mm: 6.283 mm; 6 whole mm < ceil(7.2) = 8; 0.785 mm each
    (10.0, 2 * math.pi / 10, 8),
])
def test_marlins_segment_count(radius, sweep, segments):
    assert MARLIN_ARCS.segments(radius, sweep) == segments


def test_the_reader_cuts_arcs_into_marlins_segments_and_plans_them_as_written_out(tmp_path, capsys):
    r, n = 3.0, 20
    circles = f"G90\nM83\nG1 X{r} Y0 F6000\n" + f"G3 X{r} Y0 I{-r} J0 E1\n" * n
    job = read_gcode(circles, arc_resolution=arc_resolution(MARLIN))
    assert job.arcs[:2] == (n, MARLIN_ARCS)
    ends = job.end[1:73, :2]
    angles = np.arange(1, 73) * 2 * math.pi / 72
    assert np.abs(ends - r * np.column_stack([np.cos(angles), np.sin(angles)])).max() < 1e-9
    written = f"G90\nM83\nG1 X{r} Y0 F6000\n" + "".join(
        f"G1 X{r * math.cos(a):.9f} Y{r * math.sin(a):.9f} E{1 / 72:.9f}\n" for a in angles) * n
    marlin = plan_with_config(job, MARLIN).plan.print_time
    assert marlin == pytest.approx(plan_with_config(read_gcode(written), MARLIN).plan.print_time, rel=1e-9)
    # RR arcs too (Marlin takes R, which Klipper refuses): the same segments
    half = read_gcode("G90\nG1 X3 Y0 F6000\nG3 X-3 Y0 R3 E1\n", arc_resolution=MARLIN_ARCS)
    assert len(half.end) - 1 == 36
    # on the command line: a printer whose corner rule is Marlin's junction deviation says so
    path = tmp_path / "c.gcode"
    path.write_text(circles)
    assert main(["plan", str(path), "--junction", "jd", "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["arcs"] == n and "as Marlin 2.1 cuts them" in res["arcs_note"]
    assert "at least 72 to a full circle" in res["arcs_note"]


def test_which_firmware_cuts_arcs_how():
    assert arc_resolution(MARLIN) is MARLIN_ARCS
    assert arc_resolution(MachineLimits(junction="jd")) is MARLIN_ARCS            # firmware unknown: its rule's
    assert arc_resolution(MachineLimits(junction="jerk")) is None                  # Marlin, Prusa or RRF: chords
    assert arc_resolution(RRF) is RRF_ARCS
    assert arc_resolution(MachineLimits(junction="jerk", klipper_reading=False, arc_firmware="marlin")) is MARLIN_ARCS
    assert arc_resolution(PRUSA) is PRUSA_ARCS
    # each firmware record's own
    for name, rule in (("klipper", 1.0), ("kalico", 1.0), ("marlin", MARLIN_ARCS), ("marlin-ftm", MARLIN_ARCS),
                       ("prusa", PRUSA_ARCS), ("rrf", RRF_ARCS), ("rrf35", RRF_ARCS)):
        assert arc_resolution(MachineLimits(junction="jerk", **job_reading(name))) == rule, name


RRF = MachineLimits(accel=1500.0, velocity=300.0, junction="jerk", jerk=(10.0, 10.0, 0.5, 20.0),
                    klipper_reading=False, m203_per_minute=True, arc_firmware="rrf")


@pytest.mark.parametrize("radius, sweep, speed, segments", [
    # a 3 mm circle at 100 mm/s: sqrt(8·3·0.005) = 0.3464 mm (< 100/200); 18.85/0.3464 + 0.8 = 55.2
    (3.0, 2 * math.pi, 100.0, 55),
    # a quarter of a 40 mm circle at 100 mm/s: sqrt(1.6) = 1.26 > 100/200 = 0.5 mm; 125.7 + 0.8 → 126
    (40.0, math.pi / 2, 100.0, 126),
    # the same at 300 mm/s: 1.5 and 1.26 over the 1 mm most: 62.83 + 0.8 → 63
    (40.0, math.pi / 2, 300.0, 63),
    # half a 0.5 mm circle: sqrt(0.02) = 0.1414 mm; 1.571/0.1414 + 0.8 = 11.9 → 11
    (0.5, -math.pi, 100.0, 11),
    # a quarter of a 0.01 mm circle at 1 mm/s: 0.005 under the 0.02 mm least; 0.785 + 0.8 → 1
    (0.01, math.pi / 2, 1.0, 1),
])
def test_rrfs_segment_count(radius, sweep, speed, segments):
    assert RRF_ARCS.segments(radius, sweep, speed) == segments
    assert RRF_ARCS.segments(radius, sweep, 2 * speed, 0.5) == segments         # M220 S50 at twice the feed


def test_rrf_reads_arcs_into_its_segments_at_the_moves_speed_and_plans_them_as_written_out():
    r, n = 3.0, 10
    # at 50 mm/s (F3000, or F6000 under M220 S50) 50/200 = 0.25 mm is the shorter: 18.85/0.25 + 0.8 → 76
    for f, m220, want in ((6000, 100, 55), (3000, 100, 76), (6000, 50, 76)):
        circles = f"M220 S{m220}\nG90\nM83\nG1 X{r} Y0 F{f}\n" + f"G3 X{r} Y0 I{-r} J0 E1\n" * n
        job = read_gcode(circles, arc_resolution=arc_resolution(RRF))
        assert len(job.end) - 1 == n * want and job.arcs[:2] == (n, RRF_ARCS)
        angles = np.arange(1, want + 1) * 2 * math.pi / want
        written = f"M220 S{m220}\nG90\nM83\nG1 X{r} Y0 F{f}\n" + "".join(
            f"G1 X{r * math.cos(a):.9f} Y{r * math.sin(a):.9f} E{1 / want:.9f}\n" for a in angles) * n
        assert plan_with_config(job, RRF).plan.print_time == pytest.approx(      # the file's 1e-9 mm digits
            plan_with_config(read_gcode(written), RRF).plan.print_time, rel=1e-7)


PRUSA = MachineLimits(accel=1250.0, velocity=200.0, junction="jerk", jerk=(8.0, 8.0, 2.0, 5.0), **job_reading("prusa"))


@pytest.mark.parametrize("radius, sweep, feed, segments", [
    # a 3 mm circle at 100 mm/s: sqrt(8·3·0.02) = 0.6928 mm (< 100/50 = 2); 18.85/0.6928 + 0.8 = 28.0 → 28
    (3.0, 2 * math.pi, 100.0, 28),
    # a quarter of a 40 mm circle at 100 mm/s: sqrt(6.4) = 2.53 over the 2 mm most: 31.42 + 0.8 → 32
    (40.0, math.pi / 2, 100.0, 32),
    # the same at 50 mm/s: 50/50 = 1 mm is the shorter: 62.83 + 0.8 → 63
    (40.0, math.pi / 2, 50.0, 63),
    # half a 0.05 mm circle: sqrt(0.008) = 0.0894 under the 0.1 mm least: 1.571 + 0.8 → 2
    (0.05, -math.pi, 100.0, 2),
    # a tenth of a turn on 0.05 mm at 100 mm/s: 0.0314 mm / 0.1 + 0.8 → 1
    (0.05, 2 * math.pi / 10, 100.0, 1),
])
def test_prusa_buddys_segment_count(radius, sweep, feed, segments):
    assert PRUSA_ARCS.segments(radius, sweep, feed) == segments
    assert PRUSA_ARCS.segments(radius, sweep, feed, 0.5) == segments              # M220 does not reach them


def test_buddy_reads_arcs_into_its_segments_at_the_jobs_feed_and_plans_them_as_written_out(tmp_path, capsys):
    r, n = 40.0, 4
    # a quarter of a 40 mm circle: at F6000 (100 mm/s) 32 segments, at F3000 63, and under M220 S50 still 32
    for f, m220, want in ((6000, 100, 32), (3000, 100, 63), (6000, 50, 32)):
        ends = [(round(r * math.cos(k * math.pi / 2), 6), round(r * math.sin(k * math.pi / 2), 6)) for k in range(n + 1)]
        quarters = f"M220 S{m220}\nG90\nM83\nG1 X{r} Y0 F{f}\n" + "".join(
            f"G3 X{x:g} Y{y:g} I{-x0:g} J{-y0:g} E1\n" for (x0, y0), (x, y) in zip(ends, ends[1:]))
        job = read_gcode(quarters, arc_resolution=arc_resolution(PRUSA))
        assert len(job.end) - 1 == n * want and job.arcs[:2] == (n, PRUSA_ARCS)
        angles = np.arange(1, n * want + 1) * (math.pi / 2) / want
        written = f"M220 S{m220}\nG90\nM83\nG1 X{r} Y0 F{f}\n" + "".join(
            f"G1 X{r * math.cos(a):.9f} Y{r * math.sin(a):.9f} E{1 / want:.9f}\n" for a in angles)
        assert plan_with_config(job, PRUSA).plan.print_time == pytest.approx(      # the file's 1e-6 mm digits
            plan_with_config(read_gcode(written), PRUSA).plan.print_time, rel=1e-6)
