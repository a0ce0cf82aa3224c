"""Every acceleration the firmware applies, move by move, against the firmware's own rules:

- Marlin (``Marlin/src/module/planner.cpp``, ``_populate_block``): a move with no X/Y/Z steps (a
  retraction or its recovery) runs at ``settings.retract_acceleration`` (M204 R) and skips the
  per-axis ``LIMIT_ACCEL`` caps; a move with E steps starts from ``settings.acceleration`` (M204 P),
  any other from ``travel_acceleration`` (M204 T); then each axis caps it:
  ``accel ≤ max_acceleration[axis]·step_event_count/steps[axis]`` (M201).
- Kalico (``klippy/kinematics/limited_corexy.py``, ``check_move``): ``max_a = move_d /
  max(|x/max_x_accel + y/max_y_accel|, |x/max_x_accel − y/max_y_accel|)``, ``max_v = max_velocity ·
  move_d / max(|x + y|, |x − y|)``, then ``Move.limit_speed`` keeps the smaller of those and the
  toolhead's; ``limited_cartesian.py``: ``max_a = min(max_x_accel/|x_r|, max_y_accel/|y_r|)``.

The expected values are computed here from those formulas, written out literally, and checked
against what the planner plans; a move between two full stops (``G4 P0``) is a rest-to-rest
trapezoid whose duration follows from its acceleration and top speed alone.
"""

from __future__ import annotations

import math

import pytest

from ringtune.envs.printer import printer_from_dict
from ringtune.hardware.marlin_config import printer_facts_from_marlin
from ringtune.shaping.gcode import read_gcode
from ringtune.shaping.planner import plan

M503_R500 = """\
echo:  M92 X80.00 Y80.00 Z400.00 E93.00
echo:  M203 X500.00 Y500.00 Z5.00 E60.00
echo:  M201 X2000.00 Y2000.00 Z100.00 E400.00
echo:  M204 P1500.00 R500.00 T3000.00
echo:  M205 B20000.00 S0.00 T0.00 J0.013
"""


def _rest_to_rest(length: float, speed: float, accel: float) -> float:
    """Seconds of a trapezoid from rest to rest (triangle when the top speed is not reached)."""
    if speed * speed / accel >= length:
        return 2.0 * math.sqrt(length / accel)
    return length / speed + speed / accel


def _marlin_accel(steps: dict, esteps: bool, retract: bool, p: float, r: float, t: float,
                  max_accel: dict) -> float:
    """planner.cpp's choice with steps per mm equal on all axes: steps ∝ |distance|."""
    if retract:
        return r
    accel = p if esteps else t
    total = max(steps.values())                       # step_event_count
    for ax, n in steps.items():
        if n and max_accel[ax] < accel:
            accel = min(accel, max_accel[ax] * total / n)
    return accel


@pytest.fixture
def marlin_printer(tmp_path):
    f = tmp_path / "m503.txt"
    f.write_text(M503_R500)
    facts = printer_facts_from_marlin(f, "cartesian")
    desc = dict(facts.description)
    desc.update(x={"modes": [{"freq": 45.0, "damping": 0.07}]}, y={"modes": [{"freq": 38.0, "damping": 0.07}]})
    desc.pop("current", None)
    return printer_from_dict(desc)


def test_a_retraction_at_r500_plans_as_marlin_plans_it(marlin_printer):
    lim = marlin_printer.machine_limits()
    assert lim.retract_accel == 500.0 and lim.travel_accel == 3000.0 and lim.accel == 1500.0
    job = read_gcode("G90\nM83\nG1 X10 Y10 Z0.3 F6000\nG4 P0\nG1 E-5 F2400\nG4 P0\nG1 X60 Y10 F9000\n"
                     "G4 P0\nG1 E5 F2400\nG4 P0\nG1 X30 Y40 E2 F3000\n")
    pl = plan(job, lim)
    moves = pl.moves
    # (length mm, speed mm/s, steps per axis, esteps, retract) of moves 1..4 (move 0 leaves the origin)
    cases = [(5.0, 40.0, {"x": 0, "y": 0, "e": 5.0}, True, True),              # retract: R500, no E cap
             (50.0, 150.0, {"x": 50.0, "y": 0, "e": 0}, False, False),        # travel: T3000, X cap 2000
             (5.0, 40.0, {"x": 0, "y": 0, "e": 5.0}, True, True),              # recovery: R500
             (math.hypot(30, 30), 50.0, {"x": 30.0, "y": 30.0, "e": 2.0}, True, False)]   # print: P1500
    for i, (length, speed, steps, esteps, retract) in enumerate(cases, start=1):
        want = _marlin_accel(steps, esteps, retract, 1500.0, 500.0, 3000.0,
                             {"x": 2000.0, "y": 2000.0, "e": 400.0})
        assert moves.accel[i] == pytest.approx(want, rel=1e-12), i
        assert moves.duration[i] == pytest.approx(_rest_to_rest(length, speed, want), rel=1e-9), i
    assert moves.accel[1] == 500.0            # not the E cap (400), not P (1500)
    assert moves.accel[2] == 2000.0           # travel at T3000, capped by M201 X2000


def test_without_m204_r_the_retraction_runs_as_before_and_the_import_says_so(tmp_path):
    f = tmp_path / "m503.txt"
    f.write_text(M503_R500.replace(" R500.00", ""))
    facts = printer_facts_from_marlin(f, "cartesian")
    assert "retract_accel" not in facts.description["limits"]
    assert any("no M204 R" in n for n in facts.notes)


def _kalico(rule: str | None, caps=(10010.0, 4130.0), accel=20000.0, velocity=500.0, scale=False):
    limits = {"accel": accel, "velocity": velocity, "square_corner_velocity": 5.0, "min_cruise_ratio": 0.0,
              "max_accel": [caps[0], caps[1], 0.0, 0.0]}
    if rule:
        limits["axis_rule"] = rule
    if scale:
        limits["scale_xy_accel"] = True
    return printer_from_dict({"kinematics": "corexy", "limits": limits,
                              "x": {"modes": [{"freq": 53.0, "damping": 0.05}]},
                              "y": {"modes": [{"freq": 42.0, "damping": 0.07}]}}).machine_limits()


def _limited_corexy(dx, dy, caps, max_v, max_a, scale=False):
    """Kalico limited_corexy.check_move, then Move.limit_speed against the toolhead's values."""
    move_d = math.hypot(dx, dy)
    ab_linf = max(abs(dx + dy), abs(dx - dy))
    v = max_v * move_d / ab_linf
    x_o_a, y_o_a = dx / caps[0], dy / caps[1]
    if scale:
        a = max_a * move_d / (max(abs(x_o_a + y_o_a), abs(x_o_a - y_o_a)) * max(caps))
    else:
        a = move_d / max(abs(x_o_a + y_o_a), abs(x_o_a - y_o_a))
    return min(v, max_v), min(a, max_a)


def _limited_cartesian(dx, dy, caps, max_a):
    move_d = math.hypot(dx, dy)
    x_r = max(abs(dx / move_d), 2.220446049250313e-16)
    y_r = max(abs(dy / move_d), 2.220446049250313e-16)
    return min(min(caps[0] / x_r, caps[1] / y_r), max_a)


DIRECTIONS = [(60.0, 0.0), (0.0, 60.0), (50.0, 50.0), (60.0, -20.0), (-15.0, 45.0), (40.0, 23.0)]


@pytest.mark.parametrize("scale", [False, True])
def test_a_limited_corexy_printers_moves_are_capped_at_their_own_limits(scale):
    caps = (10010.0, 4130.0)
    lim = _kalico("limited_corexy", caps, scale=scale)
    gcode = ["G91"] + [f"G1 X{dx:g} Y{dy:g} F60000\nG4 P0" for dx, dy in DIRECTIONS]
    moves = plan(read_gcode("\n".join(gcode) + "\n"), lim).moves
    for i, (dx, dy) in enumerate(DIRECTIONS):
        v, a = _limited_corexy(dx, dy, caps, 500.0, 20000.0, scale)
        assert moves.accel[i] == pytest.approx(a, rel=1e-12), (dx, dy)
        assert moves.v_nominal[i] == pytest.approx(v, rel=1e-12), (dx, dy)
        assert moves.duration[i] == pytest.approx(_rest_to_rest(math.hypot(dx, dy), v, a), rel=1e-9)
    # the caps bind as Kalico's own words say: X moves at max_x_accel, Y moves at max_y_accel, and
    # the least on the diagonals atan2(max_x_accel, max_y_accel) (SET_KINEMATICS_LIMIT's message)
    if not scale:
        assert moves.accel[0] == caps[0] and moves.accel[1] == caps[1]


def test_limited_cartesian_caps_each_axis_share():
    caps = (9000.0, 6000.0)
    lim = _kalico(None, caps, accel=12000.0)
    moves = plan(read_gcode("G91\n" + "\n".join(f"G1 X{dx:g} Y{dy:g} F60000\nG4 P0"
                                                for dx, dy in DIRECTIONS) + "\n"), lim).moves
    for i, (dx, dy) in enumerate(DIRECTIONS):
        assert moves.accel[i] == pytest.approx(_limited_cartesian(dx, dy, caps, 12000.0), rel=1e-12)


def test_a_cap_above_todays_acceleration_binds_once_the_acceleration_is_raised():
    """The Voron 2.4's max_x_accel 10010 is above its max_accel 8994: at 8994 it does not bind, at
    the 20000 a tuning may choose it holds X moves at 10010 (it was once dropped as 'no cap')."""
    low, high = _kalico("limited_corexy", accel=8994.0), _kalico("limited_corexy", accel=20000.0)
    job = read_gcode("G91\nG1 X60 F60000\nG4 P0\n")
    assert plan(job, low).moves.accel[0] == 8994.0
    assert plan(job, high).moves.accel[0] == 10010.0


def test_kalicos_set_velocity_limit_x_accel_y_accel_in_a_job_set_the_caps():
    lim = _kalico("limited_corexy", accel=20000.0)
    job = read_gcode("G91\nSET_VELOCITY_LIMIT X_ACCEL=6000 Y_ACCEL=3000\nG1 X60 F60000\nG4 P0\nG1 Y60\nG4 P0\n")
    moves = plan(job, lim).moves
    assert (moves.accel[0], moves.accel[1]) == (6000.0, 3000.0)
    assert plan(job, lim, use_job_limits=False).moves.accel[:2].tolist() == [10010.0, 4130.0]


def test_the_summary_names_marlins_retract_acceleration_as_the_planner_measures_it(marlin_printer):
    """binding_limits: M204 R binds on the job's retractions, and the time it names without it is
    the planner's with the retractions at the tuned acceleration (limits built here by hand)."""
    from dataclasses import replace

    from ringtune.agents.tune.binding import binding_limits, binding_sentences
    from ringtune.shaping.config import TuneConfig

    text = ("G90\nM83\nG1 X10 Y10 Z0.3 F6000\nG1 X60 Y10 E2 F3000\nG1 E-5 F2400\nG1 X10 Y50 F9000\n"
            "G1 E5 F2400\nG1 X60 Y50 E2 F3000\n")
    cfg = TuneConfig(firmware="marlin", shaper_x="zv", shaper_y="zv", freq_x=45.0, freq_y=40.0, accel=3000.0,
                     max_accel_x=3000.0, max_accel_y=3000.0)
    found = {b.name: b for b in binding_limits(marlin_printer, text, cfg)}
    assert set(found) == {"M204 R"}          # X/Y caps raised to 3000, travel at the tuned 3000
    r = found["M204 R"]
    lim = replace(marlin_printer.machine_limits(), accel=3000.0, travel_accel=None,
                  max_accel=(3000.0, 3000.0, 100.0, 400.0))
    job = read_gcode(text)
    assert r.moves == 2 and r.value == 500.0
    assert r.time_s == pytest.approx(plan(job, lim, accel=3000.0).print_time, rel=1e-12)
    assert r.time_without_s == pytest.approx(plan(job, replace(lim, retract_accel=3000.0), accel=3000.0).print_time,
                                              rel=1e-12)
    assert r.time_without_s < r.time_s
    assert "M204 R 500 mm/s² binds on 2 retractions" in binding_sentences([r], 3000.0)[1]
    assert "M204 R 500 mm/s² binds on 1 retraction (E-only move): " in replace(r, moves=1).sentence()


def test_klipper_gives_its_e_caps_to_the_extruder_alone_and_says_when_it_has_none():
    """Klipper (``toolhead.py``, ``extruder.py`` ``check_move``): a move of the extruder alone runs
    at max_extrude_only_accel / _velocity alone, above the toolhead's if they are higher; an
    extruding move has no E limit. Without them in the description, the note says so."""
    from ringtune.shaping.extruder_alone import extruder_alone_note
    from ringtune.shaping.planner import MachineLimits
    lines = "G90\nM83\nG1 X30 Y0 E1.2 F3000\nG4 P0\nG1 E-1.5 F6000\nG4 P0\nG1 X0 Y0 E40 F3000\n"
    job = read_gcode(lines)
    base = dict(accel=2000.0, velocity=60.0, junction="scv", square_corner_velocity=5, min_cruise_ratio=0.0)
    bare, capped = MachineLimits(**base), MachineLimits(**base, extrude_only_velocity=80, extrude_only_accel=9000)
    # the retraction, rest to rest: 1.5 mm at min(100, 80) mm/s and 9000 mm/s² (not the toolhead's 60 and
    # 2000), its peak no higher than the toolhead's 2000 mm/s² × (1 − minimum_cruise_ratio 0) reaches
    # (Klipper's mcr_pseudo_accel, even at a ratio of 0; real Klipper gives 0.033 s for it)
    moves = plan(job, capped).moves
    assert moves.duration[1] == pytest.approx(_lone_move(1.5, 80.0, 9000.0, 2000.0), rel=1e-9)
    assert plan(job, bare).moves.duration[1] == pytest.approx(_lone_move(1.5, 60.0, 2000.0, 2000.0), rel=1e-9)
    # the extruding moves (the last pushes 40 mm of filament over 30 mm) are the same either way
    assert moves.duration[[0, 2]] == pytest.approx(plan(job, bare).moves.duration[[0, 2]], rel=1e-12)
    note = extruder_alone_note(job, bare)
    assert "the job's 1 retractions" in note and "0.266 × max_accel" in note
    assert extruder_alone_note(job, capped) is None
    assert extruder_alone_note(job, MachineLimits(**{**base, "junction": "jd"}, klipper_reading=False)) is None
    assert extruder_alone_note(read_gcode("G90\nG1 X10 Y0 F3000\n"), bare) is None


def _lone_move(d: float, v: float, a: float, a_smooth: float) -> float:
    """s for ``d`` mm from rest to rest at top speed ``v`` and acceleration ``a`` (trapezoid or
    triangle), the peak no higher than v² = a_smooth·d (Klipper's lone move under its cruise ratio)."""
    top = min(v, math.sqrt(min(a, a_smooth) * d))
    return 2 * top / a + (d - top * top / a) / top
