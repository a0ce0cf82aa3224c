"""Planner against analytic trapezoids, the firmware junction formulas, DAA, a slicer's estimate."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ringtune.envs.printer import load_printer, printer_from_dict
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.config_plan import plan_with_config
from ringtune.shaping.gcode import read_gcode
from ringtune.shaping.lookahead import backward_pass, forward_pass
from ringtune.shaping.planner import MachineLimits, limits_from_job, plan
from ringtune.shaping.slicer import slicer_estimate


def test_min_plus_passes_match_the_recurrence():
    rng = np.random.default_rng(1)
    c = rng.uniform(0, 100, 50)
    delta = rng.uniform(0, 30, 49)
    w = forward_pass(c, delta)
    ref = [c[0]]
    for i in range(49):
        ref.append(min(c[i + 1], ref[-1] + delta[i]))
    np.testing.assert_allclose(w, ref)
    u = backward_pass(c, delta)
    ref = [c[-1]]
    for i in range(48, -1, -1):
        ref.append(min(c[i], ref[-1] + delta[i]))
    np.testing.assert_allclose(u, ref[::-1])


@pytest.mark.parametrize("junction", ["scv", "jd", "jerk"])
def test_single_move_trapezoid_and_triangle(junction):
    lim = MachineLimits(accel=1000, velocity=500, junction=junction, min_cruise_ratio=0.0,
                        jerk=(0, 0, 0, 0))
    # trapezoid: 100 mm at 50 mm/s, a = 1000: t = d/v + v/a
    p = plan(read_gcode("G1 X100 F3000\n"), lim)
    assert p.print_time == pytest.approx(100 / 50 + 50 / 1000, rel=1e-12)
    # triangle: 1 mm can't reach 50 mm/s: t = 2 sqrt(d/a)
    p = plan(read_gcode("G1 X1 F3000\n"), lim)
    assert p.print_time == pytest.approx(2 * math.sqrt(1 / 1000), rel=1e-12)
    assert p.moves.v_cruise[0] == pytest.approx(math.sqrt(1000 * 1), rel=1e-12)


def test_motion_evaluates_to_the_moves():
    job = read_gcode("G1 X10 Y0 F6000\nG1 X10 Y10 E1\nG1 X0 Y0 E2\nG4 P200\nG1 Z1 F600\n")
    p = plan(job, MachineLimits(accel=2000))
    m = p.moves
    starts = p.motion.position(m.t_start)
    ends = p.motion.position(m.t_start + m.duration)
    np.testing.assert_allclose(starts, m.start, atol=1e-9)
    np.testing.assert_allclose(ends, m.end, atol=1e-9)
    # the dwell: the toolhead rests 0.2 s before the Z move
    assert m.t_start[3] - (m.t_start[2] + m.duration[2]) == pytest.approx(0.2)
    assert p.print_time == pytest.approx(m.t_start[-1] + m.duration[-1])


def test_klipper_square_corner_is_the_square_corner_velocity():
    # a 90 degree corner between long moves: Klipper's junction speed is exactly scv
    lim = MachineLimits(accel=3000, junction="scv", square_corner_velocity=5, min_cruise_ratio=0)
    p = plan(read_gcode("G1 X50 F6000\nG1 X50 Y50\n"), lim)
    assert p.moves.v_exit[0] == pytest.approx(5.0, rel=1e-9)
    assert p.moves.v_entry[1] == pytest.approx(5.0, rel=1e-9)
    # a full reversal stops; a straight continuation keeps speed
    p = plan(read_gcode("G1 X50 F6000\nG1 X0\n"), lim)
    assert p.moves.v_exit[0] == 0
    p = plan(read_gcode("G1 X50 F6000\nG1 X100\n"), lim)
    assert p.moves.v_exit[0] == pytest.approx(100)


def test_marlin_junction_deviation_formula():
    # 90 degrees: v^2 = a * jd * sin(45)/(1 - sin(45))
    lim = MachineLimits(accel=1500, junction="jd", junction_deviation=0.02)
    p = plan(read_gcode("G1 X50 F6000\nG1 X50 Y50\n"), lim)
    s = math.sin(math.radians(45))
    assert p.moves.v_exit[0] ** 2 == pytest.approx(1500 * 0.02 * s / (1 - s), rel=1e-9)
    # 60 degree turn (120 between the lines): half angle of the inside 120 -> sin(60)
    p = plan(read_gcode(f"G1 X50 F6000\nG1 X{50 + 25} Y{25 * math.sqrt(3)}\n"), lim)
    s = math.sin(math.radians(60))
    assert p.moves.v_exit[0] ** 2 == pytest.approx(1500 * 0.02 * s / (1 - s), rel=1e-6)


def _polygon(side: float, turn: float, n: int) -> str:
    """G-code of ``n`` sides of ``side`` mm, each turning ``turn`` rad from the last, at 300 mm/s."""
    x = y = heading = 0.0
    lines = ["G1 X0 Y0 F18000"]
    for _ in range(n):
        x, y = x + side * math.cos(heading), y + side * math.sin(heading)
        lines.append(f"G1 X{x:.6f} Y{y:.6f}")
        heading += turn
    return "\n".join(lines) + "\n"


def test_marlin_small_segments_bound_the_speed_as_on_the_arc():
    # Marlin 2.1 / Prusa Buddy JD_HANDLE_SMALL_SEGMENTS: a segment under 1 mm turning by less than 45°
    # gets v² = length · a / turn, the turn by Marlin's MinMax polynomial: π/2 − asin(cos 0.3 rad)
    # = 0.30706 rad at a true 0.3 (a polygon of 0.9 mm sides, radius ≈ 3 mm: v² ≈ a·R)
    lim = MachineLimits(accel=2000, velocity=500, junction="jd", junction_deviation=0.05, min_cruise_ratio=0)
    p = plan(read_gcode(_polygon(0.9, 0.3, 40)), lim)
    turn = 0.30706459089839
    v2 = p.moves.v_exit[10:30] ** 2
    assert v2 == pytest.approx(np.full(20, 0.9 * 2000 / turn), rel=1e-4)      # coordinates to 1 µm
    assert v2[0] == pytest.approx(2000 * 0.9 / (2 * math.sin(0.15)), rel=0.03)     # a · R of the polygon
    # the junction rule alone would allow more here: sin(θ/2)/(1 − sin(θ/2)) with θ/2 = (π − 0.3)/2
    s = math.cos(0.15)
    assert 2000 * 0.05 * s / (1 - s) > 1.4 * v2[0]
    # 1.05 mm sides, or a turn of 50°: the junction rule alone
    for side, turn in ((1.05, 0.3), (0.9, math.radians(50))):
        p = plan(read_gcode(_polygon(side, turn, 12)), lim)
        s = math.cos(turn / 2)
        assert p.moves.v_exit[5] ** 2 == pytest.approx(2000 * 0.05 * s / (1 - s), rel=1e-4)


def test_classic_jerk_corner_and_start_from_rest():
    lim = MachineLimits(accel=1000, junction="jerk", jerk=(8, 8, 0.4, 5), min_cruise_ratio=0)
    p = plan(read_gcode("G1 X50 F6000\nG1 X50 Y50\n"), lim)
    assert p.moves.v_exit[0] == pytest.approx(8.0)                 # each axis jumps by at most 8
    assert p.moves.v_entry[0] == pytest.approx(8.0)                # from rest: the safe speed
    assert p.moves.v_exit[1] == pytest.approx(8.0)
    # analytic time: accelerate 8 -> 100, cruise, decelerate 100 -> 8 on each 50 mm side
    t_ramp = (100 - 8) / 1000
    d_ramp = (100 ** 2 - 8 ** 2) / 2000
    expected = 2 * (2 * t_ramp + (50 - 2 * d_ramp) / 100)
    assert p.print_time == pytest.approx(expected, rel=1e-12)


def test_per_axis_limits_scale_speed_and_accel():
    lim = MachineLimits(accel=3000, velocity=500, junction="jd", max_velocity=(500, 500, 5, 50),
                        max_accel=(3000, 3000, 100, 5000))
    p = plan(read_gcode("G1 Z10 F6000\nG1 X30 Z20 F6000\n"), lim)
    assert p.moves.v_nominal[0] == pytest.approx(5)
    assert p.moves.accel[0] == pytest.approx(100)
    uz = 10 / math.hypot(30, 10)
    assert p.moves.v_nominal[1] == pytest.approx(5 / uz)
    assert p.moves.accel[1] == pytest.approx(100 / uz)


def test_minimum_cruise_ratio_keeps_half_the_move_at_cruise():
    lim = MachineLimits(accel=1000, velocity=1000, junction="scv", min_cruise_ratio=0.5)
    p = plan(read_gcode("G1 X100 F60000\n"), lim)
    # peak capped at v^2 = a*d/2: accelerating and decelerating take a quarter of the move each
    assert p.moves.v_cruise[0] ** 2 == pytest.approx(1000 * 100 / 2)
    p0 = plan(read_gcode("G1 X100 F60000\n"), MachineLimits(accel=1000, velocity=1000, min_cruise_ratio=0))
    assert p0.moves.v_cruise[0] ** 2 == pytest.approx(1000 * 100)
    # job's SET_VELOCITY_LIMIT overrides the machine's ratio from its line on
    p1 = plan(read_gcode("SET_VELOCITY_LIMIT MINIMUM_CRUISE_RATIO=0\nG1 X100 F60000\n"), lim)
    assert p1.moves.v_cruise[0] ** 2 == pytest.approx(1000 * 100)


def test_daa_phases_last_one_or_two_ringing_periods():
    f = 40.0
    lim = MachineLimits(accel=3000, velocity=500, junction="jerk", jerk=(0, 0, 0, 0), min_cruise_ratio=0)
    # 0 -> 100 mm/s takes 33 ms at 3000 > one period (25 ms): DAA stretches it to two (50 ms)
    p = plan(read_gcode("G1 X100 F6000\n"), lim, daa_freq=f)
    assert p.moves.accel[0] == pytest.approx(100 / (2 / f))
    # 0 -> 50 mm/s takes 17 ms: stretched to one period
    p = plan(read_gcode("G1 X100 F3000\n"), lim, daa_freq=f)
    assert p.moves.accel[0] == pytest.approx(50 / (1 / f))
    assert p.moves.decel[0] == pytest.approx(50 / (1 / f))
    # the phases are visible in the motion: constant acceleration for exactly 1/f
    seg = np.diff(p.motion.t)
    acc = np.abs(p.motion.a[:, 0])
    np.testing.assert_allclose(seg[acc > 0], 1 / f)
    # a long phase (0 -> 200 mm/s at 3000 = 67 ms > 2 periods) is left alone
    p = plan(read_gcode("G1 X200 F12000\n"), lim, daa_freq=f)
    assert p.moves.accel[0] == pytest.approx(3000)


def test_events_get_times(data_dir):
    job = read_gcode(data_dir / "gcode/ianalexis_ender3_marlin/ringing_tower.gcode")
    p = plan(job, limits_from_job(job, junction="jerk"))
    times = [e.time for e in p.events if e.command == "M593"]
    assert len(times) == 300
    assert all(a <= b for a, b in zip(times, times[1:]))
    assert 0 < times[0] < times[-1] < p.print_time


def test_ianalexis_print_time_within_3_percent_of_prusaslicer(data_dir):
    """Acceptance 4: the file's own limits (M201/M203/M204/M205, jerk 0) and classic jerk."""
    path = data_dir / "gcode/ianalexis_ender3_marlin/ringing_tower.gcode"
    job = read_gcode(path)
    p = plan(job, MachineLimits(junction="jerk", min_cruise_ratio=0))
    estimate = slicer_estimate(path)
    assert estimate == 2428
    assert abs(p.print_time / estimate - 1) < 0.03


def test_daa_short_move_becomes_two_phases_of_one_period():
    """RRF DDA::AdjustAcceleration: stretched phases that no longer fit become an
    accelerate-decelerate move with both phases exactly one period: top = d/T - (s+e)/2."""
    f, T = 40.0, 1 / 40.0
    lim = MachineLimits(accel=3000, velocity=500, junction="jd", min_cruise_ratio=0)
    p = plan(read_gcode("G1 X1 F6000\n"), lim, daa_freq=f)
    assert p.moves.v_cruise[0] == pytest.approx(1 / T)
    assert p.moves.accel[0] == pytest.approx(2 * 1 / (2 * T * T))
    assert p.print_time == pytest.approx(2 * T)
    # a Z-only move is not adjusted (|u_x|, |u_y| <= 0.5)
    p = plan(read_gcode("G1 Z1 F600\n"), lim, daa_freq=f)
    assert p.moves.accel[0] == pytest.approx(3000)


def test_accel_override_replaces_job_accel_but_keeps_axis_caps():
    job = read_gcode("M204 P500 T500\nM201 X1000 Y4000\nG1 X100 F6000\nG1 Y100\n")
    lim = MachineLimits(accel=3000, junction="jd")
    np.testing.assert_allclose(plan(job, lim).moves.accel, [500, 500])          # the job's M204
    np.testing.assert_allclose(plan(job, lim, accel=2000).moves.accel, [1000, 2000])  # X capped by M201


def test_a_lone_m204_p_changes_nothing_on_klipper_but_sets_marlins_print_acceleration():
    # per-feature lines as PrusaSlicer writes them for Marlin 2: M204 P before extrusions, M204 T
    # before travel; Klipper ignores each (toolhead.cmd_M204 needs S, or P and T together)
    body = "G1 X50 E1 F6000\nG1 X50 Y50 E2\nG1 X70 Y50\nG1 X0 Y50 E3\n"
    lone = "M204 P500\n" + body.replace("G1 X70 Y50", "M204 T500\nG1 X70 Y50")
    klipper = MachineLimits(accel=3000, junction="scv", square_corner_velocity=5, min_cruise_ratio=0)
    assert plan(read_gcode(lone), klipper).print_time == pytest.approx(plan(read_gcode(body), klipper).print_time,
                                                                      rel=1e-12)
    both = plan(read_gcode("M204 P500 T500\n" + body), klipper).print_time
    marlin = MachineLimits(accel=3000, junction="jd", junction_deviation=0.013)
    slow = plan(read_gcode("M204 S500\n" + body), marlin).print_time
    assert both > plan(read_gcode(body), klipper).print_time
    # Marlin takes them: the extruding moves run at M204 P, the travel at M204 T, all at 500 here
    assert plan(read_gcode(lone), marlin).print_time == pytest.approx(slow, rel=1e-12)


@pytest.mark.parametrize("junction", ["jd", "jerk"])
def test_marlin_and_rrf_do_not_act_on_klippers_set_velocity_limit(junction):
    # SET_VELOCITY_LIMIT is Klipper's (and Kalico's) alone: Marlin and RRF answer it as an unknown
    # command, so under their corner rules it changes nothing; under Klipper's it rules
    body = "G1 X50 E1 F6000\nG1 X50 Y50 E2\nG1 X0 Y0 E3\n"
    klipperish = "SET_VELOCITY_LIMIT ACCEL=500 VELOCITY=20 SQUARE_CORNER_VELOCITY=1\n" + body
    lim = MachineLimits(accel=3000, junction=junction)
    assert plan(read_gcode(klipperish), lim).print_time == pytest.approx(plan(read_gcode(body), lim).print_time,
                                                                          rel=1e-12)
    scv = MachineLimits(accel=3000, junction="scv", min_cruise_ratio=0)
    assert plan(read_gcode(klipperish), scv).print_time > 2 * plan(read_gcode(body), scv).print_time


def test_rrf_reads_a_jobs_m203_in_mm_per_minute():
    """PrusaSlicer's RepRapFirmware flavour writes ``M203 X18000`` (mm/min, as RRF reads it); Marlin
    reads M203 in mm/s. One 100 mm move from rest to rest at F6000 (100 mm/s) under M203 X600:
    RRF caps it at 10 mm/s, d/v + v/a = 10.01 s at 1000 mm/s²; Marlin at 100 mm/s, 1.1 s. The
    firmware is the configuration's, else the printer's [current] one."""
    job = read_gcode("M203 X600 Y600 Z600 E600\nG1 X100 F6000\n")
    lim = MachineLimits(accel=1000, velocity=300, junction="jd")
    times = {fw: plan_with_config(job, lim, TuneConfig(firmware=fw)).plan.print_time for fw in ("rrf", "marlin")}
    assert times["rrf"] == pytest.approx(100 / 10 + 10 / 1000, rel=1e-9)
    assert times["marlin"] == pytest.approx(100 / 100 + 100 / 1000, rel=1e-9)
    d = load_printer(None).to_dict()
    d["limits"] = {**d["limits"], "junction": "jerk"}
    for fw, per_minute in (("rrf", True), ("marlin", False)):
        d["current"] = {**d.get("current", {}), "firmware": fw}
        assert printer_from_dict(d).machine_limits().m203_per_minute is per_minute


def test_marlin_has_no_m566_and_rrf_reads_both_jerk_commands():
    """RRF's M566 (mm/min) sets the jerk on RRF, which also takes M205 X Y (mm/s); Marlin and Prusa
    have no M566 (an unknown command): there only M205 sets it. A square of 20 mm sides at
    100 mm/s with the machine's jerk 1 mm/s: M566 X6000 Y6000 (100 mm/s) lets RRF take the corners
    near full speed, and leaves Marlin at its own 1 mm/s — as if the line were not there."""
    square = "G1 X20 Y0 F6000\nG1 X20 Y20\nG1 X0 Y20\nG1 X0 Y0\n" * 3
    lim = MachineLimits(accel=1000, velocity=300, junction="jerk", jerk=(1.0, 1.0, 0.4, 5.0))

    def t(text, fw):
        return plan_with_config(read_gcode(text), lim, TuneConfig(firmware=fw)).plan.print_time

    for fw in ("marlin", "prusa"):
        assert t("M566 X6000 Y6000\n" + square, fw) == t(square, fw)
        assert t("M205 X100 Y100\n" + square, fw) < 0.9 * t(square, fw)
    assert t("M566 X6000 Y6000\n" + square, "rrf") == pytest.approx(t("M205 X100 Y100\n" + square, "rrf"), rel=1e-12)
    assert t("M566 X6000 Y6000\n" + square, "rrf") < 0.9 * t(square, "rrf")
    assert t("M205 X100 Y100\nM566 X60 Y60\n" + square, "rrf") == pytest.approx(t(square, "rrf"), rel=1e-12)


@pytest.mark.parametrize("junction", ["scv", "jd"])
def test_the_firmware_not_its_corner_rule_reads_the_jobs_acceleration_commands(junction):
    """One 100 mm move from rest to rest at F6000 (100 mm/s) after ``M201 X500 Y500`` and a lone
    ``M204 P1000``, on a machine at 3000 mm/s² whose corners are described by ``junction``: Marlin
    (toolhead at M204 P, capped by M201: 500 mm/s²) takes 1 + 100/500 s; Klipper acts on neither
    line (no M201; a lone P needs T: toolhead.cmd_M204), 1 + 100/3000 s — whichever corner rule the
    printer description gives, since the firmware reads the file."""
    job = read_gcode("M201 X500 Y500\nM204 P1000\nG1 X100 E5 F6000\n")
    lim = MachineLimits(accel=3000, velocity=300, junction=junction, min_cruise_ratio=0.0)
    times = {fw: plan_with_config(job, lim, TuneConfig(firmware=fw, accel=None)).plan.print_time
             for fw in ("marlin", "rrf", "klipper", "kalico")}
    assert times["marlin"] == pytest.approx(1 + 100 / 500, rel=1e-9)
    assert times["rrf"] == pytest.approx(1 + 100 / 500, rel=1e-9)
    assert times["klipper"] == pytest.approx(1 + 100 / 3000, rel=1e-9)
    assert times["kalico"] == pytest.approx(1 + 100 / 3000, rel=1e-9)
