"""G-code reader: modes, arcs, line numbers and checksums, Klipper commands, events, errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.gcode import read_gcode
from ringtune.shaping.klipper_reading import klipper_rests
from ringtune.shaping.slicer import slicer_estimate


def test_absolute_relative_and_g92():
    job = read_gcode("G90\nM83\nG1 X10 Y0 E1 F600\nG91\nG1 X5 E1\nG90\nM82\nG92 E0\nG1 X20 E2\n")
    assert job.n_moves == 3
    np.testing.assert_allclose(job.end[0], [10, 0, 0, 1])
    np.testing.assert_allclose(job.end[1], [15, 0, 0, 2])            # G91: relative X and E
    np.testing.assert_allclose(job.end[2], [20, 0, 0, 4])            # G92 E0 then absolute E2
    np.testing.assert_allclose(job.feed, [10, 10, 10])               # F600 mm/min = 10 mm/s, modal
    np.testing.assert_array_equal(job.start[1:], job.end[:-1])       # machine coordinates continuous


def test_g92_xy_shifts_logical_not_machine_coordinates():
    job = read_gcode("G1 X10 F600\nG92 X0\nG1 X5\n")
    np.testing.assert_allclose(job.end[:, 0], [10, 15])


def test_m220_scales_requested_speed():
    job = read_gcode("G1 X10 F600\nM220 S50\nG1 X20\n")
    np.testing.assert_allclose(job.feed, [10, 5])


def test_zero_length_and_feed_only_lines_are_not_moves():
    job = read_gcode("G1 F3000\nG1 X0 Y0\nG1 X1\n")
    assert job.n_moves == 1 and job.feed[0] == 50


@pytest.mark.parametrize("tol", [0.1, 0.01, 0.001])
def test_arc_chords_stay_within_tolerance(tol):
    # quarter circle radius 10 around (0,0) from (10,0) to (0,10), counter-clockwise
    job = read_gcode("G1 X10 Y0 F600\nG3 X0 Y10 I-10 J0 E2\n", arc_tolerance=tol)
    arc = job.arc
    pts = np.vstack([job.start[arc][:1], job.end[arc]])
    np.testing.assert_allclose(pts[-1, :2], [0, 10], atol=1e-12)
    r = np.hypot(pts[:, 0], pts[:, 1])
    np.testing.assert_allclose(r, 10, atol=1e-9)                     # vertices on the arc
    ang = np.arctan2(pts[:, 1], pts[:, 0])
    assert np.all(np.diff(ang) > 0)                                  # counter-clockwise
    half = np.diff(ang) / 2
    sagitta = 10 * (1 - np.cos(half))
    assert sagitta.max() <= tol * (1 + 1e-9)
    assert sagitta.max() > tol / 4                                   # not needlessly fine
    np.testing.assert_allclose(job.end[arc][-1, 3], 2.0)            # E interpolated to the end


def test_arc_clockwise_full_circle_and_radius_form():
    job = read_gcode("G1 X10 Y0 F600\nG2 X10 Y0 I-10 J0\n", arc_tolerance=0.01)
    pts = job.end[job.arc][:, :2]
    ang = np.unwrap(np.arctan2(pts[:, 1], pts[:, 0]))
    assert ang[-1] == pytest.approx(-2 * np.pi, abs=1e-9)          # one full turn clockwise
    job = read_gcode("G1 X0 Y0 F600\nG2 X10 Y0 R5\n", arc_tolerance=0.01)
    pts = job.end[job.arc][:, :2]
    np.testing.assert_allclose(np.hypot(pts[:, 0] - 5, pts[:, 1]), 5, atol=1e-9)
    assert pts[:, 1].max() > 4.9                                     # clockwise from the left: over the top


def test_line_numbers_and_checksums():
    def cs(s):
        x = 0
        for ch in s.encode():
            x ^= ch
        return f"{s}*{x}"

    text = "\n".join([cs("N1 G28"), cs("N2 G1 X10 F600"), "N3 G1 X20", cs("N4 G1 X30")]) + "\n"
    job = read_gcode(text)
    np.testing.assert_allclose(job.end[:, 0], [10, 20, 30])
    with pytest.raises(RingtuneError, match=r"<gcode>:1: checksum mismatch"):
        read_gcode("N1 G1 X10*1\n")


@pytest.mark.parametrize("line, what", [
    ("G1 X1.2.3 F600", "not a number"),
    ("SET_VELOCITY_LIMIT ACCEL=nan", "finite"),
    ("SET_VELOCITY_LIMIT VELOCITY=inf", "finite"),
    ("G1 Xnan", "needs a value"),
    ("G1 X5,0", "not a number"),
    ("G1 X123456789", "absurd"),
    ("G1 X10 F0", "> 0"),
    ("G1 X", "needs a value"),
    ("G2 X10 Y0", "I/J or R"),
    ("SET_VELOCITY_LIMIT ACCEL=fast", "not a number"),
    ("M204 S-5", ">= 0"),
])
def test_malformed_values_name_file_and_line(tmp_path, line, what):
    path = tmp_path / "bad.gcode"
    path.write_text("G28\nG1 X5 F600\n" + line + "\n")
    with pytest.raises(RingtuneError) as err:
        read_gcode(path)
    assert "bad.gcode:3" in str(err.value)
    assert what in str(err.value)


def test_klipper_limits_shaper_events_and_unknown_commands():
    text = ("SET_VELOCITY_LIMIT ACCEL=500 SQUARE_CORNER_VELOCITY=1 VELOCITY=200 MINIMUM_CRUISE_RATIO=0.3\n"
            "START_PRINT BED_TEMP=55 EXTRUDER_TEMP=200\n"
            "G1 X10 F6000\n"
            "SET_INPUT_SHAPER SHAPER_FREQ_X=40 SHAPER_TYPE_X=mzv\n"
            "M593 X F37.5 D0.1\n"
            "M493 S1 X C8 A40\n"
            "G1 X20\n"
            "M117 Layer 2, Z=0.4\n"
            "FROBNICATE\n")
    job = read_gcode(text)
    assert job.file_setting("accel_klipper") == 500
    assert job.file_setting("square_corner_velocity") == 1
    assert job.file_setting("velocity") == 200
    assert job.file_setting("min_cruise_ratio") == pytest.approx(0.3)
    shaper = job.shaper_events()
    assert [e.command for e in shaper] == ["SET_INPUT_SHAPER", "M593", "M493"]
    assert all(e.move == 1 for e in shaper)                           # before the second move
    assert shaper[0].params["SHAPER_FREQ_X"] == 40 and shaper[0].params["SHAPER_TYPE_X"] == "mzv"
    assert shaper[1].params["F"] == 37.5 and math.isnan(shaper[1].params["X"])
    assert job.stop_before[1]                                         # a shaper change drains the queue
    others = [e.command for e in job.events if e.kind == "other"]
    assert others == ["START_PRINT", "M117", "FROBNICATE"]


def test_marlin_limit_commands_and_features():
    text = ("M201 X1500 Y1200 Z100 E5000 F40 S30\nM203 X500 Y400\nM204 P1500 R1000 T2000\n"
            "M205 X8 Y9 E5 J0.02\n;TYPE:External perimeter\nG1 X10 E1 F600\n; feature solid layer\n"
            "G1 X20 E2\n;FEATURE:Inner wall\nG1 X30 E3\n")
    job = read_gcode(text)
    fs = job.file_setting
    assert (fs("max_accel_x"), fs("max_accel_y"), fs("max_accel_e")) == (1500, 1200, 5000)
    assert (fs("max_vel_x"), fs("max_vel_y")) == (500, 400)
    assert (fs("accel_print"), fs("accel_retract"), fs("accel_travel")) == (1500, 1000, 2000)
    assert (fs("jerk_x"), fs("jerk_y"), fs("jerk_e"), fs("junction_deviation")) == (8, 9, 5, 0.02)
    assert fs("freq_limit_hz") == 40 and fs("freq_limit_min_factor") == pytest.approx(0.3)
    assert [job.features[i] for i in job.feature] == ["External perimeter", "solid layer", "Inner wall"]


def test_dwell_and_homing_stop_the_planner():
    job = read_gcode("G1 X10 F600\nG4 P500\nG4 S1\nG1 X20\nG28 X\nG1 X5\n")
    np.testing.assert_allclose(job.dwell_before, [0, 1.5, 0])
    np.testing.assert_array_equal(job.stop_before, [True, True, True])
    np.testing.assert_allclose(job.start[2], [0, 0, 0, 0])           # homed X -> 0


def test_motors_off_stops_the_planner_unless_it_only_sets_the_idle_timeout():
    # Marlin's and RRF's M84 S… sets the idle timeout and does not wait for the moves; M84 and M18
    # without it drain the queue first, as G4 does; Klipper (klipper_reading) stops at both
    job = read_gcode("G1 X10 F600\nM84 S30\nG1 X20\nM84\nG1 X30\nM18 X Y\nG1 X40\n")
    np.testing.assert_array_equal(job.stop_before, [True, False, True, True])
    np.testing.assert_allclose(job.dwell_before, 0.0)
    stop, dwell, after = klipper_rests(job)
    np.testing.assert_array_equal(stop, [True, True, True, True])
    # each finds a motor on (a move since the last): 0.1 s before and after, and two 1 ms step flushes
    np.testing.assert_allclose(dwell, [0, 0.202, 0.202, 0.202])
    again = read_gcode("G28\nM84\nM84\nG1 X5 F600\nG1 E1\nM18\nM84\n")     # G28 turns them on
    np.testing.assert_allclose(klipper_rests(again)[1], [0.202, 0.0])
    assert klipper_rests(again)[2] == pytest.approx(0.202)                # after the last move


def test_real_files_parse(data_dir):
    marlin = read_gcode(data_dir / "gcode/ianalexis_ender3_marlin/ringing_tower.gcode")
    assert marlin.n_moves > 10000
    m593 = [e for e in marlin.shaper_events() if e.command == "M593"]
    assert len(m593) == 300
    freqs = [e.params["F"] for e in m593]
    assert freqs[:3] == [0, 0, 15] or freqs[0] == 0
    assert max(freqs) == 60
    assert all(a.move <= b.move for a, b in zip(m593, m593[1:]))
    klipper = read_gcode(data_dir / "gcode/bassco_ender3/ringing_tower.gcode")
    assert klipper.n_moves > 10000
    assert {"START_PRINT", "END_PRINT"} <= {e.command for e in klipper.events}
    assert "outer perimeter" in klipper.features


def test_slicer_estimates(data_dir):
    assert slicer_estimate(data_dir / "gcode/ianalexis_ender3_marlin/ringing_tower.gcode") == 40 * 60 + 28
    assert slicer_estimate(data_dir / "gcode/bassco_ender3/ringing_tower.gcode") == 3600 + 4 * 60


def test_klipper_tuning_tower_reruns_the_command_by_height():
    lines = ["M83", "TUNING_TOWER COMMAND=SET_VELOCITY_LIMIT PARAMETER=ACCEL START=1250 FACTOR=100 BAND=5"]
    z = 0.0
    for layer in range(1, 41):                                   # 0.25 mm layers up to 10 mm
        z = 0.25 * layer
        lines += [f"G1 Z{z:.2f} F600", f"G1 X{10 * (layer % 2)} Y5 E0.5 F3000"]
    job = read_gcode("\n".join(lines) + "\n")
    ext = job.extruding
    zs = job.end[ext, 2]
    accel = job.setting("accel_klipper")[ext]
    expected = 1250 + 100 * (np.floor(zs / 5) + 0.5) * 5          # Klipper's BAND quantisation
    np.testing.assert_allclose(accel, expected)
    assert sorted(set(accel.tolist())) == [1500.0, 2000.0, 2500.0]


def test_tuning_tower_of_the_shaper_frequency_makes_shaper_events():
    lines = ["M83", "TUNING_TOWER COMMAND=SET_INPUT_SHAPER PARAMETER=SHAPER_FREQ_X START=20 "
             "STEP_DELTA=10 STEP_HEIGHT=1"]
    for layer in range(1, 13):
        lines += [f"G1 Z{0.25 * layer:.2f} F600", f"G1 X{10 * (layer % 2)} Y5 E0.5 F3000"]
    job = read_gcode("\n".join(lines) + "\n")
    ev = job.shaper_events()
    assert [e.params["SHAPER_FREQ_X"] for e in ev] == [20, 30, 40, 50]
    assert all(job.stop_before[e.move] for e in ev)


def test_streaming_in_chunks_gives_the_same_job(data_dir, monkeypatch):
    import ringtune.shaping.gcode as gcode

    path = data_dir / "gcode/ianalexis_ender3_marlin/ringing_tower.gcode"
    whole = read_gcode(path)
    monkeypatch.setattr(gcode, "_CHUNK", 777)
    chunked = read_gcode(path)
    for name in ("line", "start", "end", "feed", "feature", "settings", "stop_before", "dwell_before"):
        np.testing.assert_array_equal(getattr(chunked, name), getattr(whole, name))
    assert [e.move for e in chunked.events] == [e.move for e in whole.events]


def test_inch_units():
    job = read_gcode("G20\nG1 X1 Y2 F60\nG92 X0\nG1 X1\nG21\nG1 X30\n")
    np.testing.assert_allclose(job.end[:, :2], [[25.4, 50.8], [50.8, 50.8], [55.4, 50.8]])
    np.testing.assert_allclose(job.feed, 25.4)             # 60 in/min = 25.4 mm/s


@pytest.mark.parametrize("line, klipper", [("M204 S900", 900), ("M204 P1500 T2000", 1500), ("M204 T800 P1200", 800),
                                           ("M204 P1500", None), ("M204 T2000", None), ("M204 R700", None)])
def test_klipper_takes_m204_s_or_p_and_t_together_and_ignores_a_lone_p_or_t(line, klipper):
    # Klipper's and Kalico's toolhead.cmd_M204: S, else the lower of P and T when both are given;
    # a lone P or T is answered "Invalid M204 command" and the acceleration stays (what PrusaSlicer
    # and OrcaSlicer write per feature for Marlin 2 / RRF, run on a Klipper printer)
    job = read_gcode(line + "\nG1 X10 F600\n")
    got = job.file_setting("accel_klipper")
    assert (math.isnan(got) if klipper is None else got == klipper), got
    words = dict((w[0], float(w[1:])) for w in line.split()[1:])
    want = words.get("P", words.get("S"))
    got = job.file_setting("accel_print")
    assert (math.isnan(got) if want is None else got == want), got            # Marlin's roles as given


def test_a_vendors_own_commands_with_words_that_are_no_numbers_are_kept_not_refused(tmp_path):
    """Every Bambu Studio job holds ``M1002 judge_flag timelapse_record_flag`` (its firmware's own
    command): the reader refused the whole file at that line. A command the planner does not act on
    is recorded with its text; what it acts on stays strict (test above)."""
    path = tmp_path / "vendor.gcode"
    path.write_text("G90\nM83\nM1002 judge_flag timelapse_record_flag\nM622.1 S1\nM991 S0 P0\n"
                    "G1 X10 Y10 F6000\n; FEATURE: Outer wall\nM204 S500\nG1 X20 Y10 E0.5 F3000\n"
                    "G17\nG3 Z.6 I1.5 J0 P1 F42000\n")
    job = read_gcode(path)
    vendor = [e for e in job.events if e.command == "M1002"]
    assert len(vendor) == 1 and vendor[0].params == {"text": "judge_flag timelapse_record_flag"}
    wall = np.flatnonzero(job.extruding)[0]
    assert job.features[job.feature[wall]] == "Outer wall" and job.setting("accel_print")[wall] == 500.0
    # the spiral lift: a full circle of radius 1.5 mm about (11.5, 10) rising 0.4 mm, back where it began
    arc = np.flatnonzero(job.arc)
    assert job.start[arc[0], :3] == pytest.approx([20, 10, 0]) and job.end[arc[-1], :3] == pytest.approx([20, 10, 0.6])
    centre = np.array([21.5, 10.0])
    assert np.hypot(*(job.end[arc, :2] - centre).T) == pytest.approx(1.5, abs=0.01)
