"""``ringtune simulate`` names every firmware limit that holds moves below the acceleration it
reports (issue 24): on a Marlin printer imported from M503 (``M201 X500 Y500``, ``M204 R500``),
``--accel 3000`` runs X and Y moves at 500 and retractions at 500; each limit named costs the print
time the planner gives with that limit removed (limits built here by hand), and the caps given with
``--max-accel`` (as export raises them) are no longer named."""

from __future__ import annotations

import json
from dataclasses import replace

import pytest

from ringtune.agents.cli.main import main
from ringtune.envs.printer import load_printer
from ringtune.shaping.gcode import read_gcode
from ringtune.shaping.planner import plan

M503 = """\
echo: M92 X80.00 Y80.00 Z400.00 E93.00
echo: M203 X500.00 Y500.00 Z5.00 E25.00
echo: M201 X500.00 Y500.00 Z100.00 E5000.00
echo: M204 P500.00 R500.00 T1000.00
echo: M205 B20000.00 S0.00 T0.00 J0.08
"""
#: walls along X and Y, a retraction and its recovery, a travel; no acceleration commands of its own
JOB = ("G90\nM83\nG1 X20 Y20 Z0.3 F6000\n;TYPE:Outer wall\nG1 X80 Y20 E2 F6000\nG1 X80 Y80 E2\n"
       "G1 X20 Y80 E2\nG1 X20 Y20 E2\nG1 E-5 F2400\nG1 X60 Y60 F9000\nG1 E5 F2400\nG1 X90 Y60 E1 F3000\n")


def _simulate(tmp_path, capsys, *extra):
    (tmp_path / "m503.txt").write_text(M503)
    toml, job = tmp_path / "m.toml", tmp_path / "job.gcode"
    job.write_text(JOB)
    assert main(["printer", "from-marlin", str(tmp_path / "m503.txt"), "-o", str(toml)]) == 0
    capsys.readouterr()
    assert main(["simulate", "--printer", str(toml), "--gcode", str(job), "--firmware", "marlin", "--shaper",
                 "zv", "--freq", "45", "--accel", "3000", "--backend", "lti", "--freq-margin", "0", *extra]) == 0
    text = capsys.readouterr().out
    assert main(["simulate", "--json", "--printer", str(toml), "--gcode", str(job), "--firmware", "marlin",
                 "--shaper", "zv", "--freq", "45", "--accel", "3000", "--backend", "lti", "--freq-margin", "0",
                 *extra]) == 0
    return json.loads(capsys.readouterr().out), text, load_printer(toml)


def test_the_caps_that_hold_the_acceleration_are_named_and_measured(tmp_path, capsys):
    res, text, printer = _simulate(tmp_path, capsys)
    named = {b["name"]: b for b in res["binding"]}
    assert {"M201 X", "M201 Y", "M204 R"} <= set(named)
    lim = replace(printer.limits, accel=3000.0)
    job = read_gcode(JOB)
    base = plan(job, lim, accel=3000.0).print_time
    assert res["metrics"]["print_time_s"] == pytest.approx(base, rel=1e-9)
    caps = list(lim.max_accel)
    for name, without in (("M201 X", replace(lim, max_accel=(0.0, *caps[1:]))),
                          ("M201 Y", replace(lim, max_accel=(caps[0], 0.0, *caps[2:]))),
                          ("M204 R", replace(lim, retract_accel=3000.0))):
        b = named[name]
        assert b["value"] == 500.0 and b["time_s"] == pytest.approx(base, rel=1e-12)
        assert b["time_without_s"] == pytest.approx(plan(job, without, accel=3000.0).print_time, rel=1e-12)
        assert b["time_without_s"] < b["time_s"]
        assert f"{name} 500 mm/s² binds on {b['moves']} " in text
    assert "Limits that hold some moves below 3000 mm/s²" in text
    assert "--max-accel X,Y runs it with other per-axis caps" in text


def test_caps_raised_with_the_configuration_are_not_named(tmp_path, capsys):
    res, text, _ = _simulate(tmp_path, capsys, "--max-accel", "3000,3000")
    names = {b["name"] for b in res["binding"]}
    assert "M201 X" not in names and "M201 Y" not in names and "M204 R" in names
    assert "M201 X 500" not in text and "--max-accel X,Y runs it" not in text
