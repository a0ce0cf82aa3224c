"""Firmware retraction said aloud: G10/G11 without parameters (the real Cura UltiGCode job retracts
only so) are counted with their lines, RRF's G10 P/L (tool offsets, temperatures) is not a
retraction, and plan says the moves are planned as stops that take no time, with the sum its
example settings would add: 1 mm at 20 mm/s out and 10 mm/s back, 0.05 + 0.1 s each. Each is an
E-only move, so the head comes to rest there, as at a slicer's own retraction."""

from __future__ import annotations

import json

from ringtune.agents.cli.main import main
from ringtune.agents.tune.job import job_accel_facts
from ringtune.envs.printer import load_printer
from ringtune.shaping.firmware_retraction import firmware_retraction_note, firmware_retractions
from ringtune.shaping.gcode import read_gcode
from ringtune.shaping.planner import MachineLimits, plan

import pytest


def test_the_cura_job_retracts_by_firmware_and_plan_says_what_that_leaves_out(data_dir, capsys):
    path = data_dir / "gcode" / "fastlb_cura_um2" / "platte_klein_cut.gcode"
    lines = path.read_text().splitlines()
    want = {c: [i for i, ln in enumerate(lines, 1) if ln.split(";")[0].strip() == c] for c in ("G10", "G11")}
    assert len(want["G10"]) == 4 == len(want["G11"])
    assert firmware_retractions(read_gcode(path)) == want
    assert main(["plan", str(path), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["firmware_retraction"] == want
    note = res["firmware_retraction_note"]
    assert "planned as stops that take no time" in note and f"{4 * (1 / 20 + 1 / 10):.1f} s in all" in note


def test_rrf_tool_offsets_are_not_retractions_and_a_job_without_any_says_nothing():
    job = read_gcode("G10 P0 S210 R150\nG10 L2 P1 X5\nM83\nG1 X10 E1 F1200\nG10\nG1 X0\nG11\n")
    assert firmware_retractions(job) == {"G10": [5], "G11": [7]}
    # only what moves the extruder is counted: a second G10, a G11 with nothing retracted
    again = read_gcode("M83\nG11\nG1 X10 E1 F1200\nG10\nG10\nG1 X0\nG11\nG11\n")
    assert firmware_retractions(again) == {"G10": [4], "G11": [7]}
    plain = read_gcode("M83\nG1 X10 E1 F1200\n")
    assert firmware_retractions(plain) == {} and firmware_retraction_note(plain, MachineLimits()) is None



def test_tune_says_it_too(tmp_path):
    path = tmp_path / "fw.gcode"
    path.write_text("M83\n;TYPE:External perimeter\nG1 X20 Y0 E1 F6000\nG10\nG1 X20 Y20 F9000\nG11\nG1 X0 Y20 E1\n")
    notes = job_accel_facts(load_printer(None), str(path), "respect").notes("respect", None)
    assert [n for n in notes if n.startswith("the job retracts by firmware — G10 ×1 (first on line 4), G11 ×1")]


@pytest.mark.parametrize("between, rests", [("G10", True), ("G11", False),
                                            ("G10 P0 S210", False), ("G10 L2 P1 X5", False), ("", False)])
def test_the_head_comes_to_rest_at_a_firmware_retraction_as_at_a_slicers_own(between, rests):
    """Two 20 mm moves in a line at 50 mm/s, 1000 mm/s²: straight through, d/v + v/a for both
    (0.85 s); at rest between them, twice that move's own d/v + v/a (0.9 s) — as a slicer's E-only
    retraction gives; a G11 with nothing retracted, and RRF's G10 with P or L (a tool's offset or
    temperature), do not."""
    text = f"M83\nG1 X0 Y0 F3000\nG1 X20 Y0 E1 F3000\n{between}\nG1 X40 Y0 E1\n"
    lim = MachineLimits(accel=1000.0, velocity=300.0, junction="scv", square_corner_velocity=5.0,
                        min_cruise_ratio=0.0)
    d, v, a = 20.0, 50.0, 1000.0
    want = 2 * (d / v + v / a) if rests else 2 * d / v + v / a
    assert plan(read_gcode(text), lim).print_time == pytest.approx(want, rel=1e-9)


def test_a_retraction_while_retracted_or_a_restore_while_not_moves_nothing():
    """The firmwares keep whether the filament is retracted (Klipper's is_retracted, Marlin's
    retracted[]): a second G10, or a G11 with nothing retracted, moves nothing, so the head goes
    straight through; Klipper's SET_RETRACTION clears the state. Each 20 mm move at 50 mm/s,
    1000 mm/s²: d/v + v/a from rest to rest, d/v through."""
    lim = MachineLimits(accel=1000.0, velocity=300.0, junction="scv", square_corner_velocity=5.0,
                        min_cruise_ratio=0.0)
    d, v, a = 20.0, 50.0, 1000.0

    def stops(*between: str) -> int:
        """Rests among the four junctions of five moves in a line with ``between`` before moves 2-5."""
        text = "M83\nG1 X0 Y0 F3000\nG1 X20 Y0 E1\n" + "".join(
            f"{b}\nG1 X{40 + 20 * i} Y0 E1\n" for i, b in enumerate(between))
        t = plan(read_gcode(text), lim).print_time
        n = round((t - (5 * d / v + v / a)) / (v / a))
        assert t == pytest.approx(5 * d / v + v / a + n * v / a, rel=1e-9)
        return n

    assert stops("G10", "G11", "", "") == 2
    assert stops("G10", "G10", "G11", "G11") == 2               # the second of each moves nothing
    assert stops("G11", "", "", "") == 0                        # nothing retracted to restore
    assert stops("G10", "SET_RETRACTION RETRACT_LENGTH=1", "G10", "G11") == 3


def test_tunes_summary_keeps_what_the_job_reading_leaves_out(data_dir, tmp_path, capsys):
    """The reading notes went to the terminal only; summary.txt, what a user opens later, says them
    too (here: the Cura job's firmware retractions)."""
    path = data_dir / "gcode" / "fastlb_cura_um2" / "platte_klein_cut.gcode"
    out = tmp_path / "out"
    assert main(["tune", "--gcode", str(path), "--trials", "2", "--workers", "1", "-o", str(out), "--no-refine"]) == 0
    said = capsys.readouterr().err
    note = firmware_retraction_note(read_gcode(path), load_printer(None).limits)
    assert note in said
    assert f"{note[0].upper()}{note[1:]}." in (out / "summary.txt").read_text()
