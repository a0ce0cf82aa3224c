"""The rewriter's Klipper lines against the real thing: Klipper 84104bb (session fixture
``real_klipper``, tests/real_klipper.py). Every line the rewrite inserts into a job (per feature
``SET_VELOCITY_LIMIT ACCEL= ACCEL_TO_DECEL=`` with the corner words where they change per class) is
answered ``ok`` with no error, and Klipper's own ``SET_VELOCITY_LIMIT`` report after them gives the
last feature's acceleration, minimum_cruise_ratio and square_corner_velocity. And what a job's own
ACCEL_TO_DECEL (OrcaSlicer's, beside each ACCEL) does on this Klipper: nothing, as the planner
plans it."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

from ringtune.shaping.config import TuneConfig  # noqa: E402
from ringtune.shaping.errors import RingtuneError  # noqa: E402
from ringtune.shaping.feature_settings import FeatureCommands  # noqa: E402
from ringtune.shaping.gcode import read_gcode  # noqa: E402
from ringtune.shaping.planner import MachineLimits, plan  # noqa: E402
from ringtune.shaping.rewrite import rewrite_job  # noqa: E402

pytestmark = [pytest.mark.timeout(600), pytest.mark.slow]

STATE = re.compile(r"(max_accel|minimum_cruise_ratio|square_corner_velocity):\s*(\S+)")

JOB = ("M83\n;TYPE:External perimeter\nG1 X20 Y0 E1 F3000\nG1 X20 Y20 E1\n"
       ";TYPE:Internal infill\nG1 X0 Y0 E1 F9000\nG1 X20 Y1 E1\n")


def test_klipper_takes_every_inserted_line_and_ends_on_the_last_features_settings(real_klipper):
    limits = MachineLimits(accel=3000, velocity=300, junction="scv", square_corner_velocity=5, min_cruise_ratio=0.5)
    cfg = TuneConfig(accel=2500.0, feature_accel={"infill": 9000.0}, feature_corner={"infill": 12.0},
                     feature_min_cruise_ratio={"infill": 0.0})
    out = rewrite_job(JOB.splitlines(keepends=True), "klipper", FeatureCommands.from_config(cfg, limits))
    inserted = [ln.split(";")[0].strip() for ln in out if ln not in JOB.splitlines(keepends=True)]
    assert [ln for ln in inserted if not ln.startswith("SET_VELOCITY_LIMIT")] == []
    assert any("ACCEL_TO_DECEL=1250" in ln for ln in inserted) and "ACCEL_TO_DECEL=9000" in inserted[-1]
    state = lambda: dict(STATE.findall(real_klipper.send("SET_VELOCITY_LIMIT")))  # noqa: E731
    before = state()
    try:
        transcript = real_klipper.send(*inserted)
        replies = [ln for ln in transcript.splitlines() if ln.startswith("< ")]
        assert len([r for r in replies if r == "< ok"]) == len(inserted), transcript
        assert "Unknown command" not in transcript and "!!" not in transcript, transcript
        now = {k: float(v) for k, v in state().items()}
        assert now == {"max_accel": 9000.0, "minimum_cruise_ratio": 0.0, "square_corner_velocity": 12.0}
    finally:      # the Klipper fixture is shared by the session: leave it as it was found
        real_klipper.send("SET_VELOCITY_LIMIT " + " ".join(f"{k.upper() if k != 'max_accel' else 'ACCEL'}={v}"
                                                           for k, v in before.items()))
    assert state() == before


def test_a_jobs_accel_to_decel_does_nothing_on_this_klipper_nor_in_the_plan(real_klipper):
    lines = ["SET_VELOCITY_LIMIT ACCEL=5000 ACCEL_TO_DECEL=1000 MINIMUM_CRUISE_RATIO=0.25",
             "SET_VELOCITY_LIMIT ACCEL=6000 ACCEL_TO_DECEL=300"]
    state = lambda: dict(STATE.findall(real_klipper.send("SET_VELOCITY_LIMIT")))  # noqa: E731
    before = state()
    try:
        transcript = real_klipper.send(*lines)
        assert "!!" not in transcript and "Unknown" not in transcript, transcript
        now = {k: float(v) for k, v in state().items()}
    finally:
        real_klipper.send("SET_VELOCITY_LIMIT " + " ".join(f"{k.upper() if k != 'max_accel' else 'ACCEL'}={v}"
                                                           for k, v in before.items()))
    assert now["max_accel"] == 6000 and now["minimum_cruise_ratio"] == 0.25
    zigzag = "".join(f"G1 X{50 + 5 * (i % 2)} Y{10 + 0.4 * i:.1f} E0.2 F12000\n" for i in range(40))
    limits = MachineLimits(accel=3000, velocity=300, junction="scv", square_corner_velocity=5, min_cruise_ratio=0.5)
    as_klipper = read_gcode("M83\nSET_VELOCITY_LIMIT ACCEL=6000 MINIMUM_CRUISE_RATIO=0.25\n" + zigzag)
    assert plan(read_gcode("M83\n" + "\n".join(lines) + "\n" + zigzag), limits).print_time == \
        pytest.approx(plan(as_klipper, limits).print_time, rel=1e-12)


#: commands a sliced job carries: Klipper's own (of the modules this printer.cfg loads: the G-code
#: core, the toolhead, [input_shaper]) and others (a start macro, a chamber heater, timelapse, a
#: Marlin object label, Marlin's linear advance, a tool change, a user's own macro)
KNOWN = ["G90", "M82", "M83", "G21", "M114", "M220 S100", "M221 S100", "M400", "G4 P1", "GET_POSITION",
         "SET_VELOCITY_LIMIT", "SET_INPUT_SHAPER"]
OTHERS = ["START_PRINT", "PRINT_END BED=0", "M141 S0", "TIMELAPSE_TAKE_FRAME", "M486 S1", "M900 K0.05", "T0",
          "_MY_MACRO"]


def test_klipper_answers_unknown_command_to_exactly_the_macro_calls_the_reader_finds(real_klipper):
    """``shaping/klipper_commands.py`` against the real Klipper, which has no macros here: each
    command the reader calls not Klipper's own is answered "Unknown command"; each of Klipper's own
    (of the modules this printer.cfg loads) is not."""
    from ringtune.shaping.klipper_commands import macro_calls

    transcript = real_klipper.send(*KNOWN, *OTHERS)
    unknown = set(re.findall(r'Unknown command:"([^"]+)"', transcript))
    assert transcript.count("< ok") == len(KNOWN) + len(OTHERS), transcript
    calls = macro_calls(read_gcode("\n".join(KNOWN + OTHERS) + "\n", source="job"))
    assert set(calls) == unknown == {line.split()[0] for line in OTHERS}


REPORT = re.compile(r"shaper_type_(x|y):(\S+) shaper_freq_\1:(\S+) damping_ratio_\1:(\S+)")

#: a job that turns shaping off, stores a damping and a type while it is off (no change of the
#: shaping), then turns it on by frequency alone (each axis with the type it kept or was given)
SHAPER_LINES = ["SET_INPUT_SHAPER SHAPER_FREQ_X=0 SHAPER_FREQ_Y=0",
                "SET_INPUT_SHAPER DAMPING_RATIO_X=0.15 SHAPER_TYPE_Y=zv",
                "SET_INPUT_SHAPER SHAPER_FREQ_X=48 SHAPER_FREQ_Y=40"]


def _shaping(report: str) -> dict:
    """{axis: (type, Hz, damping)} from Klipper's SET_INPUT_SHAPER report; (“none”,) where off."""
    out = {}
    for ax, kind, freq, damping in REPORT.findall(report):
        out[ax] = ("none",) if float(freq) == 0 else (kind, float(freq), float(damping))
    return out


def test_the_job_shaper_timeline_is_what_klipper_reports_after_each_command(real_klipper):
    """``shaping/job_shapers.py`` against Klipper's own InputShaperParams: after each job line the
    shaping the timeline holds is the one Klipper reports (an axis turned off keeps its type, a
    type or a damping set while it is off waits for it); a line that changes nothing the shaping
    does is no step."""
    from ringtune.shaping.config_plan import plan_with_config
    from ringtune.shaping.job_shapers import config_at, shaper_timeline

    start = _shaping(real_klipper.send("SET_INPUT_SHAPER"))
    assert start["x"] != ("none",) and start["y"] != ("none",), start
    (tx, fx, dx), (ty, fy, dy) = start["x"], start["y"]
    cfg = TuneConfig(shaper_x=tx, shaper_y=ty, freq_x=fx, freq_y=fy, damping_x=dx, damping_y=dy)
    try:
        reported = [_shaping(real_klipper.send(line)) for line in SHAPER_LINES]
    finally:      # the session's Klipper as it was found
        real_klipper.send(f"SET_INPUT_SHAPER SHAPER_TYPE_X={tx} SHAPER_TYPE_Y={ty} SHAPER_FREQ_X={fx} "
                          f"SHAPER_FREQ_Y={fy} DAMPING_RATIO_X={dx} DAMPING_RATIO_Y={dy}")
    assert _shaping(real_klipper.send("SET_INPUT_SHAPER")) == start
    moves = "".join(f"{line}\nG1 X{10 * (i + 1)} Y0 E1 F600\n" for i, line in enumerate(SHAPER_LINES))
    job = read_gcode("M83\n" + moves)
    events = plan_with_config(job, MachineLimits(), cfg).plan.events
    timeline = shaper_timeline(events, cfg)
    times = [ev.time for ev in events if ev.kind == "shaper"]
    for t, klipper in zip(times, reported):
        c = config_at(timeline, t)
        ours = {ax: c.axis(ax) for ax in "xy"}
        assert {ax: ("none",) if v[0] == "none" else (v[0], pytest.approx(v[1]), pytest.approx(v[2]))
                for ax, v in ours.items()} == klipper
    assert reported[-1] == {"x": (tx, 48.0, 0.15), "y": ("zv", 40.0, dy)}
    assert len(timeline) - 1 == 2          # off, then on again: the middle line changes no shaping
    # "none" is no type of Klipper's: it refuses the line (a print stops there), and so does the timeline
    # nor is a negative frequency: Klipper refuses both lines (a print stops there), and so does the timeline
    for line, said in (("SET_INPUT_SHAPER SHAPER_TYPE_X=none", "Unsupported shaper type"),
                       ("SET_INPUT_SHAPER SHAPER_FREQ_X=-5", "minimum of 0")):
        refused = real_klipper.send(line)
        assert said in refused and _shaping(real_klipper.send("SET_INPUT_SHAPER")) == start, refused
        bad = read_gcode(f"M83\nG1 X10 Y0 E1 F600\n{line}\nG1 X20 Y0 E1\n")
        with pytest.raises(RingtuneError, match="Unsupported shaper type|at least 0 Hz") as err:
            shaper_timeline(plan_with_config(bad, MachineLimits(), cfg).plan.events, cfg)
        assert err.value.where == "line 3"
