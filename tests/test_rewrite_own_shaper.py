"""A job that sets its own input shaper (a start G-code's ``SET_INPUT_SHAPER``, ``M593``, ``M493``):
tune judges the tuned shaper over the whole job, so the rewritten job carries the tuned shaper's
command in place of each of the job's own that would move the printer off it, and keeps those that
would not. Checked by reading the rewritten file back with the firmware's own semantics
(:mod:`ringtune.shaping.job_shapers`: what each command leaves the shaper at) and planning it."""

from __future__ import annotations

import json
from dataclasses import replace

import pytest

from ringtune.agents.cli.main import main
from ringtune.envs.job_rewrite import rewrite_gcode_bytes
from ringtune.envs.printer import load_printer
from ringtune.hardware.dialects import shaper_commands
from ringtune.shaping.builtin_jobs import job_path
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.config_plan import plan_with_config
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.gcode import read_gcode
from ringtune.shaping.job_shapers import (describe_timeline, foreign_shapers, foreign_shapers_note, overriding,
                                           prusa_weight_note, shaper_timeline)
from ringtune.shaping.planner import MachineLimits

#: a labelled square of walls, then infill: enough for a plan with a feature change
BODY = """G90
M83
G1 Z0.2 F600
;TYPE:External perimeter
G1 X20 Y20 F9000
G1 X45 Y20 E0.8 F3000
G1 X45 Y45 E0.8
G1 X20 Y45 E0.8
G1 X20 Y20 E0.8
;TYPE:Internal infill
G1 X22 Y22 F9000
G1 X43 Y43 E1.0 F6000
G1 X43 Y22 F9000
G1 X22 Y43 E1.0 F6000
"""

#: (firmware, its junction rule, the tuned shaper, a shaper command of the job's own that moves the
#: printer off it, one that does not, one that sets no shaper at all)
DIALECTS = [
    ("klipper", "scv", ("ei", "mzv", 51.4, 46.6),
     "SET_INPUT_SHAPER SHAPER_TYPE=zv SHAPER_FREQ_X=38 SHAPER_FREQ_Y=33",
     "SET_INPUT_SHAPER SHAPER_FREQ_X=51.4 DAMPING_RATIO_Y=0.1", "SET_INPUT_SHAPER"),
    ("marlin", "jerk", ("zv", "zv", 51.4, 46.6), "M593 F38 ; the slicer's own", "M593 X F51.4 D0.1", "M593"),
    ("prusa", "jd", ("mzv", "ei", 51.4, 46.6), "M593 X T0 F38", "M593 Y T3 F46.6 D0.1", "M593 W"),
    ("marlin-ftm", "jd", ("mzv", "mzv", 51.4, 46.6), "M493 X C1 A38", "M493 Y C8 A46.6", "M493 S1"),
    ("rrf", "jerk", ("mzv", "mzv", 51.4, 51.4), 'M593 P"zvd" F38 S0.1', 'M593 P"mzv" F51.4 S0.1', "M593"),
]


def _config(firmware: str, shaping: tuple) -> TuneConfig:
    sx, sy, fx, fy = shaping
    return TuneConfig(firmware=firmware, shaper_x=sx, shaper_y=sy, freq_x=fx, freq_y=fy, accel=5000.0,
                      feature_accel={"infill": 9000.0})


def _printer(junction: str):
    return replace(load_printer(None), limits_dict={"accel": 3000, "velocity": 300, "junction": junction})


@pytest.mark.parametrize("firmware, junction, shaping, moves_off, agrees, sets_none", DIALECTS,
                         ids=[d[0] for d in DIALECTS])
def test_the_jobs_own_shaper_commands_that_move_the_printer_off_the_tuned_one_are_replaced(
        firmware, junction, shaping, moves_off, agrees, sets_none):
    cfg = _config(firmware, shaping)
    # an end G-code's shaper command (after the last move) shapes nothing printed: kept as it is
    job_text = f"G28\n{moves_off}\n{agrees}\n{sets_none}\n" + BODY + moves_off + "\n"
    original = read_gcode(job_text, source="job")
    # lines 2 to 4: only the first moves the printer off the tuned shaper for a move
    assert [ev.line for ev in overriding(original, cfg)] == [2]
    printer = _printer(junction)
    done = rewrite_gcode_bytes(job_text.encode(), cfg, printer, "job", shaper_lines=shaper_commands)
    assert done.shaper_replaced == ((2, moves_off.split(";")[0].strip()),)
    assert "the job's own shaper command on line 2 replaced by the tuned shaper's" in done.header
    lines = done.data.decode().splitlines()[1:]          # the header aside
    want = shaper_commands(cfg)
    assert lines[1] == f"{want[0]} ; ringtune: in place of the job's own {moves_off}"
    assert lines[2:1 + len(want)] == want[1:]
    assert lines[1 + len(want):4 + len(want)] == [agrees, sets_none] + [lines[3 + len(want)]]
    assert lines[-1] == moves_off
    # read back as the firmware reads it: no command of the file moves the printer off the tuned
    # shaper for a move, so the tuned shaper rules every move (the timeline of what is in force
    # changes only once the last move is done, at the end G-code's command)
    rewritten = read_gcode(done.data, source="out")
    assert overriding(rewritten, cfg) == []
    planned = plan_with_config(rewritten, printer.limits, cfg).plan
    steps = shaper_timeline(planned.events, cfg)
    assert steps[0] == (float("-inf"), cfg) and [t for t, _c in steps[1:]] == [planned.print_time]
    # the original's own command would have changed it: the check above can fail
    before = plan_with_config(original, printer.limits, cfg).plan
    steps = shaper_timeline(before.events, cfg)
    assert len(steps) >= 2 and steps[1][1] != cfg
    # the replacement keeps the firmware's stop there: the file plans to the configuration's time
    assert done.after_s == pytest.approx(done.config_s, rel=1e-9)
    assert done.lines_inserted == len(lines) - len(job_text.splitlines()) - (len(want) - 1)


def test_without_the_tuned_shaper_to_write_a_job_with_its_own_is_refused_by_line():
    cfg = _config("klipper", ("ei", "mzv", 51.4, 46.6))
    job_text = "G28\nSET_INPUT_SHAPER SHAPER_FREQ_Y=0\n" + BODY
    with pytest.raises(RingtuneError, match=r"job, line 2: the job sets its own input shaper"):
        rewrite_gcode_bytes(job_text.encode(), cfg, _printer("scv"), "job")
    same = "G28\nSET_INPUT_SHAPER SHAPER_TYPE_X=ei SHAPER_FREQ_X=51.4\n" + BODY       # sets what cfg sets
    done = rewrite_gcode_bytes(same.encode(), cfg, _printer("scv"), "job")
    assert done.shaper_replaced == () and "SET_INPUT_SHAPER SHAPER_TYPE_X=ei SHAPER_FREQ_X=51.4\n" in done.data.decode()


def test_rewrite_command_says_which_line_it_replaced(tmp_path, capsys):
    cfg = _config("klipper", ("ei", "mzv", 51.4, 46.6))
    (tmp_path / "best.json").write_text(json.dumps(cfg.to_dict()))
    (tmp_path / "job.gcode").write_text("G28\nSET_INPUT_SHAPER SHAPER_TYPE=zv SHAPER_FREQ_X=38\n" + BODY)
    out = tmp_path / "out.gcode"
    assert main(["rewrite", str(tmp_path / "job.gcode"), "--config", str(tmp_path / "best.json"), "-o", str(out),
                 "--json"]) == 0
    got = capsys.readouterr()
    assert json.loads(got.out)["shaper_replaced"] == [{"line": 2, "text": "SET_INPUT_SHAPER SHAPER_TYPE=zv "
                                                                          "SHAPER_FREQ_X=38"}]
    assert "the job's own shaper command on line 2 replaced by the tuned shaper's" in got.err
    assert out.read_text().splitlines()[2].startswith("SET_INPUT_SHAPER SHAPER_FREQ_X=51.4 SHAPER_FREQ_Y=46.6")


def test_with_a_frequency_limit_the_command_is_replaced_where_it_now_stands(data_dir):
    """The limit's header and the moves it splits push the lines down: the job's own command is
    still the one replaced (named by its line in the input), and nothing else."""
    lines = (data_dir / "gcode/ringtune_builtin_2025/test_print.gcode").read_text().splitlines(keepends=True)
    lines.insert(1, "SET_INPUT_SHAPER SHAPER_TYPE=zv SHAPER_FREQ_X=21\n")
    cfg = replace(_config("klipper", ("ei", "mzv", 51.4, 46.6)), freq_limit_hz=20.0)
    done = rewrite_gcode_bytes("".join(lines).encode(), cfg, _printer("scv"), "job", shaper_lines=shaper_commands)
    assert done.f_lines_changed > 0 and done.shaper_replaced == ((2, "SET_INPUT_SHAPER SHAPER_TYPE=zv SHAPER_FREQ_X=21"),)
    out = done.data.decode()
    assert "SET_INPUT_SHAPER SHAPER_TYPE=zv SHAPER_FREQ_X=21" not in out.splitlines()
    assert out.count("; ringtune: in place of the job's own SET_INPUT_SHAPER SHAPER_TYPE=zv SHAPER_FREQ_X=21") == 1
    assert overriding(read_gcode(done.data, source="out"), cfg) == []
    assert done.after_s == pytest.approx(done.config_s, rel=1e-4)        # F words to 0.1 mm/min


def test_another_firmwares_shaper_command_is_kept_and_named():
    """A Marlin job's M593 on Klipper, which has no M593: it moves nothing there, so the rewrite keeps
    it and says it changes nothing; on Marlin the same line is the tuned shaper's to replace."""
    job_text = "G28\n" + BODY.replace("G1 X45 Y20 E0.8 F3000\n",          # mid-wall, straight on
                                       "G1 X32 Y20 E0.4 F3000\nM593 X F38\nG1 X45 Y20 E0.4\n")
    job = read_gcode(job_text, source="job")
    klipper = _config("klipper", ("ei", "mzv", 51.4, 46.6))
    done = rewrite_gcode_bytes(job_text.encode(), klipper, _printer("scv"), "job", shaper_lines=shaper_commands)
    assert done.shaper_replaced == () and "M593 X F38" in done.data.decode().splitlines()
    # "as sliced" is as Klipper runs it: no stop at the line it ignores, the same plan as without it
    without = read_gcode(job_text.replace("M593 X F38\n", ";\n"), source="j")
    assert done.before_s == pytest.approx(plan_with_config(without, _printer("scv").limits).plan.print_time, rel=1e-12)
    line = job_text.splitlines().index("M593 X F38") + 1
    assert foreign_shapers(job, "klipper") == {"M593": [line]} and foreign_shapers(job, "marlin") == {}
    assert foreign_shapers_note(foreign_shapers(job, "klipper"), "klipper").startswith(
        f"Klipper has no M593: the job's M593 ×1 (first on line {line}) change nothing there")
    marlin = _config("marlin", ("zv", "zv", 51.4, 46.6))
    done = rewrite_gcode_bytes(job_text.encode(), marlin, _printer("jerk"), "job", shaper_lines=shaper_commands)
    assert done.shaper_replaced == ((line, "M593 X F38"),)
    assert done.before_s > plan_with_config(without, _printer("jerk").limits).plan.print_time     # Marlin stops there


@pytest.mark.parametrize("firmware, junction, stopping, running", [
    ("klipper", "scv", "SET_INPUT_SHAPER SHAPER_FREQ_X=40", "M593 X F40"),
    ("marlin", "jerk", "M593 X F40", "SET_INPUT_SHAPER SHAPER_FREQ_X=40"),
    ("klipper", "scv", "SET_INPUT_SHAPER DAMPING_RATIO_X=0.1", "SET_INPUT_SHAPER"),
    ("marlin", "jerk", "M593 F40 D0.1", "M593 X D0.15"),
    ("marlin", "jerk", "M593 X F40", "M593"),
    ("rrf", "jerk", 'M593 P"zvd" F40 S0.15', "M593"),
    ("rrf", "jerk", "M593 S0.15", "M593 L10"),
    ("prusa", "jd", "M593 Y F40", "M593 A-10 M500"),
    ("prusa", "jd", "M74 W120", "M74 W0"),
    ("marlin", "jd", "M593 F40", "M74 W120"),
    ("marlin-ftm", "jd", "M493 S1", "M493 X C1 A40 I0.1")])
def test_a_firmware_stops_where_its_own_shaper_command_changes_the_shaping_and_nowhere_else(
        firmware, junction, stopping, running):
    """Between two collinear moves at speed, a shaper command the firmware waits at plans as an M400
    there, one it does not as no line: another firmware's (it does not know it); Klipper's
    SET_INPUT_SHAPER without parameters (a report; with them it flushes); Marlin's M593 without F
    (it syncs the planner when it sets F, not for D alone) or without parameters; RepRapFirmware's
    M593 without parameters or with L alone (it waits for standstill when it changes F, S, P, H or T,
    "changing just the minimum acceleration is OK", AxisShaper.cpp); Prusa's M593
    that sets only its weight rule (it empties the queues when it sets T, F, D or R), and its M74 W
    that gives no weight (with a weight it moves Y by the rule, emptying the queues first: a stop,
    which Marlin, without M74, does not make); Marlin's M493 that sets a shaper (it waits only, as
    assumed, where S switches fixed-time motion)."""
    cfg = _config(firmware, ("zv", "zv", 51.4, 46.6))
    limits = _printer(junction).limits

    def planned(middle: str) -> float:
        text = f"G90\nM83\nG1 X10 Y10 F9000\nG1 X60 Y10 E1 F6000\n{middle}G1 X110 Y10 E1\n"
        return plan_with_config(read_gcode(text, source="j"), limits, cfg).plan.print_time

    drained, straight = planned("M400\n"), planned("")
    assert drained > straight + 0.01                     # a full stop at 100 mm/s costs tens of ms
    assert planned(stopping + "\n") == pytest.approx(drained, rel=1e-12)
    assert planned(running + "\n") == pytest.approx(straight, rel=1e-12)
    assert planned(running + "\nM400\n") == pytest.approx(drained, rel=1e-12)     # another stop there stays


def test_prusa_stops_at_a_printed_weight_only_while_its_weight_rule_is_on_and_y_is_shaped():
    """M593 M0 turns Buddy's weight rule off (M74 then changes nothing, and waits for nothing), M593 A
    turns it back on; with Y unshaped the rule has no Y shaper to move."""
    limits = _printer("jd").limits
    body = "G90\nM83\n{}G1 X10 Y10 F9000\nG1 X60 Y10 E1 F6000\n{}G1 X110 Y10 E1\n"

    def planned(before: str, middle: str, shaping=("mzv", "mzv", 50.0, 40.0)) -> float:
        return plan_with_config(read_gcode(body.format(before, middle), source="j"), limits,
                                _config("prusa", shaping)).plan.print_time

    drained, straight = planned("", "M400\n"), planned("", "")
    assert drained > straight + 0.01
    assert planned("", "M74 W50\n") == pytest.approx(drained, rel=1e-12)
    assert planned("M593 M0\n", "M74 W50\n") == pytest.approx(straight, rel=1e-12)
    assert planned("M593 M0\nM593 A-15\n", "M74 W50\n") == pytest.approx(drained, rel=1e-12)
    assert planned("", "M74 W50\n", ("mzv", "none", 50.0, 0.0)) == pytest.approx(
        planned("", "", ("mzv", "none", 50.0, 0.0)), rel=1e-12)


def test_the_printed_weight_a_prusa_job_gives_its_firmware_is_said_with_the_shift_it_makes():
    """PrusaSlicer's MK4 profiles write M74 W<g> (the weight printed so far) at each layer change; Buddy
    moves Y's frequency by A·min(W/M, 1) (default A −20 Hz, M 800 g; M593 A M set them). ringtune
    judges at the description's print mass, and says so with the shift the rule makes."""
    layers = "G28\nG1 X10 Y10 F3000\nM74 W12.5\nG1 X20 E1\nM74 W143\nG1 X30 E1\n"
    note = prusa_weight_note(read_gcode(layers, source="j"), "prusa")
    assert f"by {-20 * 143 / 800:+.1f} Hz at its heaviest (143 g; -20 Hz at 800 g)" in note
    assert "M74 W ×2, first on line 3" in note and "ringtune judges the whole job at" in note
    own_rule = "M593 A-10 M500\n" + layers.replace("W143", "W600")
    assert "by -10.0 Hz at its heaviest (600 g; -10 Hz at 500 g)" in prusa_weight_note(read_gcode(own_rule, source="j"),
                                                                                        "prusa")
    for other in ("marlin", "klipper", "rrf"):
        assert prusa_weight_note(read_gcode(layers, source="j"), other) is None
    assert prusa_weight_note(read_gcode(BODY, source="j"), "prusa") is None


def test_a_marlin_m593_on_reprapfirmware_keeps_the_type_and_an_f_it_refuses_changes_nothing():
    """A Marlin ringing tower's ``M593 F0`` then ``M593 F15`` on RepRapFirmware: RRF's M593 without
    P keeps the shaper type and sets F (AxisShaper::Configure), and refuses an F below its minimum
    or above 1000 Hz (the command then changes nothing: F0 does not turn shaping off there); on
    Marlin, F0 turns it off and F15 is ZV at 15 Hz. The note names the line that made the first change."""
    text = ("G90\nM83\nG1 X0 Y0 F6000\nM593 F0\nG1 X20 Y0 E1\nM593 S0.2\nG1 X20 Y20 E1\n"
            "M593 F15\nG1 X0 Y20 E1\nM593 P\"zvd\" F40\nG1 X0 Y0 E1\n")
    job = read_gcode(text, source="tower")
    for fw, start, want in (
            ("rrf", ("mzv", 50.0), [("mzv", 50.0), ("mzv", 15.0), ("zvd", 40.0)]),
            ("marlin", ("zv", 50.0), [("none", None), ("zv", 15.0), ("zv", 40.0)])):
        cfg = TuneConfig(firmware=fw, shaper_x=start[0], shaper_y=start[0], freq_x=start[1], freq_y=start[1])
        events = plan_with_config(job, MachineLimits(), cfg).plan.events
        timeline = shaper_timeline(events, cfg)
        got = [(c.shaper_x, c.freq_x if c.shaper_x != "none" else None) for _t, c in timeline[1:]]
        assert got == want and all(c.axis("x") == c.axis("y") for _t, c in timeline), (fw, got)
        first = {"rrf": "line 6, M593 S0.2: X mzv 50 Hz", "marlin": "line 4, M593 F0: X off, Y off"}[fw]
        assert first in describe_timeline(timeline, events)
        if fw == "rrf":       # F0 refused, so the first change is S0.2's damping, kept with F15
            assert [c.damping_x for _t, c in timeline[1:]] == [0.2, 0.2, 0.2]
    rrf = TuneConfig(firmware="rrf", shaper_x="mzv", shaper_y="mzv", freq_x=50.0, freq_y=50.0)
    assert [ev.line for ev in overriding(job, rrf)] == [6, 8, 10]       # S0.2 sets RRF's damping
    above = read_gcode("G90\nM83\nG1 X0 Y0 F6000\nM593 F2000\nG1 X20 Y0 E1\nM593 F3\nG1 X0 Y0 E1\n", source="t")
    assert overriding(above, rrf) == []            # above 1000 Hz, below RRF 3.6's 4 Hz: refused, nothing changes


def test_rewrite_limit_and_schedule_take_the_built_in_part_by_name(tmp_path, capsys):
    """``part`` names the built-in sliced part for every command that reads a job, as for ``tune
    --gcode part``: the file read is the shipped one, and the rewritten job is written."""
    part = str(job_path("part"))
    cfg = tmp_path / "c.json"
    cfg.write_text(json.dumps({"firmware": "klipper", "shaper_x": "mzv", "freq_x": 50.0, "shaper_y": "mzv",
                               "freq_y": 45.0, "accel": 4000.0, "feature_accel": {"infill": 8000.0}}))
    assert main(["rewrite", "part", "--config", str(cfg), "-o", str(tmp_path / "r.gcode"), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["input"] == part and (tmp_path / "r.gcode").stat().st_size > 0
    assert main(["limit", "part", "--freq-limit", "50", "-o", str(tmp_path / "l.gcode"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["input"] == part


def test_a_klipper_job_turning_shaping_on_by_frequency_alone_gets_the_sections_default_type():
    """Shaping off from the start (``[input_shaper]`` with no frequency): ``SHAPER_FREQ_X=40`` alone
    turns X on with Klipper's default shaper_type, mzv; a type named while Y is off waits for its
    frequency; a damping stored while off is no change of the shaping."""
    text = ("G90\nM83\nG1 X0 Y0 F6000\nSET_INPUT_SHAPER DAMPING_RATIO_Y=0.2 SHAPER_TYPE_Y=ei\nG1 X20 Y0 E1\n"
            "SET_INPUT_SHAPER SHAPER_FREQ_X=40\nG1 X20 Y20 E1\nSET_INPUT_SHAPER SHAPER_FREQ_Y=35\nG1 X0 Y0 E1\n")
    cfg = TuneConfig(shaper_x="none", shaper_y="none")
    events = plan_with_config(read_gcode(text, source="t"), MachineLimits(), cfg).plan.events
    timeline = shaper_timeline(events, cfg)
    assert [(c.axis("x"), c.axis("y")[0]) for _t, c in timeline[1:]] == [
        (("mzv", 40.0, cfg.damping_x), "none"), (("mzv", 40.0, cfg.damping_x), "ei")]
    assert timeline[-1][1].axis("y") == ("ei", 35.0, 0.2)
    assert "2 changes; first at line 6, SET_INPUT_SHAPER SHAPER_FREQ_X=40" in describe_timeline(timeline, events)


def test_marlin_skips_a_damping_out_of_range_and_sets_the_rest_of_the_m593():
    """Marlin's M593 answers a D outside 0–1 "?Zeta (D) value out of range" and sets its F all the
    same, and skips a negative F likewise (M593.cpp); a damping within range set while the axis is off
    is no change of the shaping."""
    text = ("G90\nM83\nG1 X0 Y0 F6000\nM593 X D1.5 F45\nG1 X20 Y0 E1\nM593 X F-4\nM593 Y F0\nG1 X0 Y0 E1\nM593 Y D0.3\n"
            "G1 X5 Y5 E1\nM593 X F0 D0.25\nG1 X9 Y5 E1\nM593 F42\nG1 X0 Y0 E1\n")
    cfg = TuneConfig(firmware="marlin", shaper_x="zv", shaper_y="zv", freq_x=50.0, freq_y=40.0)
    events = plan_with_config(read_gcode(text, source="t"), MachineLimits(), cfg).plan.events
    timeline = shaper_timeline(events, cfg)
    # M593 X F-4 is skipped; M593 Y D0.3, stored while Y is off, is no step; nor is the D0.25 beside
    # X's F0: both apply at F42
    assert [(c.axis("x"), c.axis("y")) for _t, c in timeline[1:]] == [
        (("zv", 45.0, cfg.damping_x), ("zv", 40.0, cfg.damping_y)),
        (("zv", 45.0, cfg.damping_x), ("none", 40.0, cfg.damping_y)),
        (("none", 45.0, 0.25), ("none", 40.0, 0.3)), (("zv", 42.0, 0.25), ("zv", 42.0, 0.3))]


def test_prusa_turns_an_axis_on_again_from_its_defaults_and_skips_what_it_refuses():
    """Prusa-Firmware-Buddy's M593 (M593.cpp, input_shaper_config.hpp): F0 turns an axis off and it
    keeps nothing of it; the next change of that axis (here a D alone) turns it on from Buddy's
    defaults, MZV at 50.7 Hz on X and 40.6 Hz on Y, damping 0.1; a frequency is clamped to 10–100 Hz;
    a D outside 0–1 or a T past 3HUMP_EI (5) is skipped, so a line of nothing else changes nothing;
    M593 A M (the weight rule) changes no axis."""
    text = ("G90\nM83\nG1 X0 Y0 F6000\nM593 X F0\nG1 X20 Y0 E1\nM593 X D0.2\nG1 X0 Y0 E1\nM593 Y F150\n"
            "G1 X5 Y5 E1\nM593 X D1.5\nM593 T6\nM593 A-20 M800\nG1 X9 Y5 E1\nM593 F0\nG1 X0 Y0 E1\nM593 Y T3\n"
            "G1 X5 Y9 E1\n")
    cfg = TuneConfig(firmware="prusa", shaper_x="mzv", shaper_y="zvd", freq_x=48.0, freq_y=38.0, damping_x=0.12,
                     damping_y=0.08)
    events = plan_with_config(read_gcode(text, source="t"), MachineLimits(), cfg).plan.events
    timeline = shaper_timeline(events, cfg)
    assert [(c.axis("x"), c.axis("y")) for _t, c in timeline[1:]] == [
        (("none", 48.0, 0.12), ("zvd", 38.0, 0.08)),
        (("mzv", 50.7, 0.2), ("zvd", 38.0, 0.08)),
        (("mzv", 50.7, 0.2), ("zvd", 100.0, 0.08)),
        (("none", 50.7, 0.2), ("none", 100.0, 0.08)),
        (("none", 50.7, 0.2), ("ei", 40.6, 0.1))]


def test_marlin_ft_motion_turned_off_and_on_again_keeps_its_shapers_and_skips_what_it_refuses():
    """Marlin FT_MOTION's M493 (M493.cpp @00317b4): S0 turns fixed-time motion off and S1 on again with
    the shapers it had, an A given meanwhile included; a C outside its modes (0–8) fails the command;
    A and I set an axis only while it shapes, I within 0.01–1; a line that leaves the shaping as it
    was is no step."""
    lines = ["M493 S0", "M493 X A52", "M493 S1", "M493 C9 A30", "M493 Y C0", "M493 Y A45 I0.2", "M493 Y C5",
             "M493 X I0.005"]
    text = "G90\nM83\nG1 X0 Y0 F6000\n" + "".join(f"{ln}\nG1 X{5 * (k % 2)} Y{k} E1\n" for k, ln in enumerate(lines))
    cfg = TuneConfig(firmware="marlin-ftm", shaper_x="mzv", shaper_y="mzv", freq_x=48.0, freq_y=38.0)
    events = plan_with_config(read_gcode(text, source="t"), MachineLimits(), cfg).plan.events
    timeline = shaper_timeline(events, cfg)
    shown = [tuple(c.axis(ax) if c.axis(ax)[0] != "none" else "off" for ax in "xy") for _t, c in timeline[1:]]
    assert shown == [("off", "off"), (("mzv", 52.0, 0.1), ("mzv", 38.0, 0.1)), (("mzv", 52.0, 0.1), "off"),
                     (("mzv", 52.0, 0.1), ("ei", 38.0, 0.1))]
    assert [ev.text.split(";")[0].strip() for ev, _c in _changes_of(events, cfg)] == \
        ["M493 S0", "M493 S1", "M493 Y C0", "M493 Y C5"]


def _changes_of(events, cfg):
    """(event, configuration) of each step of the timeline, paired by time."""
    steps = shaper_timeline(events, cfg)[1:]
    by_time = {ev.time: ev for ev in events if ev.kind == "shaper"}
    return [(by_time[t], c) for t, c in steps]
