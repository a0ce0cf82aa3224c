"""Which ends of moves ringtune knows to be where Klipper puts the head (shaping/klipper_refusals.py
``known_xy``), so that "Move out of range" is named only where it is sure: Klipper's G28 puts an axis
at its endstop (ringtune's reader at 0) and a G92 there keeps that unknown, while an absolute move
puts the head where it says. The expected positions are Klipper's, worked by hand in the comments."""

from __future__ import annotations

from ringtune.shaping.gcode import read_gcode
from ringtune.shaping.klipper_refusals import klipper_refusals, known_xy
from ringtune.shaping.planner import MachineLimits

LIMITS = MachineLimits(travel_x=(0.0, 100.0), travel_y=(0.0, 100.0))


def _named(text: str) -> list[tuple[int, str, float]]:
    return [(r["line"], r["kind"], r["value"]) for r in klipper_refusals(read_gcode(text), LIMITS)]


def test_relative_moves_after_homing_are_not_known_until_an_absolute_one():
    # G28 at an endstop E: X−10, Y+5 relative end at E−10, E+5 (unknown here, the reader says −10);
    # then X 20 / Y 20 absolute; X 120 is past 100
    text = "G28\nG91\nG1 X-10 Y5\nG90\nG1 X20 Y20\nG1 X120\n"
    assert known_xy(read_gcode(text)).tolist() == [[False, False], [True, True], [True, True]]
    assert _named(text) == [(6, "out_of_range_x", 120.0)]


def test_a_g92_while_the_position_is_unknown_stays_unknown_until_the_axis_is_homed_again():
    # G28, G92 X50: Klipper's X offset is E − 50, so X−20 ends at E − 70 (the reader: −20, not named);
    # Y was homed without G92: Y 10 absolute is known; G28 X clears the offset, X 150 is past 100
    text = "G28\nG92 X50\nG1 X-20 Y10\nG28 X\nG1 X150\n"
    assert known_xy(read_gcode(text)).tolist() == [[False, True], [True, True]]
    assert _named(text) == [(5, "out_of_range_x", 150.0)]


def test_a_g92_where_the_position_is_known_shifts_what_follows():
    # at X 10, G92 X0: X−5 ends at 5, inside; X 95 ends at 105, past 100
    text = "G90\nG1 X10 Y10\nG92 X0\nG1 X-5\nG1 X95\n"
    assert _named(text) == [(5, "out_of_range_x", 105.0)]


def test_nothing_is_named_without_the_printers_travel_or_off_klipper():
    text = "G90\nG1 X500 Y10\n"
    assert klipper_refusals(read_gcode(text), MachineLimits()) == []
    assert klipper_refusals(read_gcode(text), MachineLimits(travel_x=(0.0, 100.0), junction="jd")) == []
    assert _named(text) == [(2, "out_of_range_x", 500.0)]
