"""The commands of a job that are not Klipper's own (``shaping/klipper_commands.py``): macros of the
user's printer.cfg, whose commands are not in the job, said aloud where a job is read as Klipper
reads it. Checked on one owner's real files: the Simplify3D job for his Ender 3 calls two commands
that are not Klipper's, and his printer.cfg defines exactly those as macros (the real Klipper's own
answer to each command is checked in tests/test_rewrite_klipper.py)."""

from __future__ import annotations

import configparser
import json

from ringtune.agents.cli.main import main
from ringtune.shaping.gcode import read_gcode
from ringtune.shaping.klipper_commands import KLIPPER_COMMANDS, macro_calls, macro_note
from ringtune.shaping.planner import MachineLimits
from ringtune.shaping.reading_notes import reading_notes

JOB = "gcode/bassco_ender3/ringing_tower.gcode"           # Simplify3D 4.1.2, for bassco's Ender 3 (Klipper)
CFG = "klipper_config/ender3/printer.cfg"                  # the same owner's printer.cfg


def _macros(path) -> set[str]:
    """The [gcode_macro NAME] sections of a Klipper printer.cfg, upper-cased as Klipper calls them."""
    cp = configparser.RawConfigParser(strict=False, inline_comment_prefixes=("#", ";"))
    cp.read_string(path.read_text())
    return {s.split(None, 1)[1].upper() for s in cp.sections() if s.startswith("gcode_macro ")}


def test_a_real_jobs_macro_calls_are_the_macros_its_owners_printer_cfg_defines(data_dir):
    job = read_gcode(data_dir / JOB)
    calls = macro_calls(job)
    assert calls == {"START_PRINT": [197], "END_PRINT": [15549]}
    assert set(calls) <= _macros(data_dir / CFG)
    # every other command of the job is one Klipper has (or a limit command of another firmware)
    others = {ev.command for ev in job.events if ev.kind != "limits"} - set(calls)
    assert others and others <= KLIPPER_COMMANDS


def test_the_note_is_said_where_the_job_is_read_as_klipper_reads_it(data_dir):
    job = read_gcode(data_dir / JOB)
    note = macro_note(macro_calls(job))
    assert note.startswith("the job calls commands that are not Klipper's own — START_PRINT ×1 (line 197), "
                           "END_PRINT ×1 (line 15549): macros of your printer.cfg")
    klipper = MachineLimits(accel=3000, velocity=300, junction="scv")
    marlin = MachineLimits(accel=3000, velocity=300, junction="jerk", klipper_reading=False)
    assert note in reading_notes(job, klipper, "klipper") and note not in reading_notes(job, marlin, "marlin")
    assert macro_note({}) is None
    lines = "\n".join(f"MY_MACRO_{k}" for k in range(8)) + "\nM205 X10\nG1 X1 Y1 F600\n"
    many = macro_calls(read_gcode(lines, source="j"))
    assert list(many) == [f"MY_MACRO_{k}" for k in range(8)]        # M205: a limit command, said elsewhere
    assert "MY_MACRO_5 ×1 (line 6) and 2 more:" in macro_note(many)


def test_plan_json_names_the_macro_calls(data_dir, capsys):
    assert main(["plan", str(data_dir / JOB), "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["macro_calls"] == {"START_PRINT": [197], "END_PRINT": [15549]}
    assert got["macro_note"] == macro_note(got["macro_calls"])
