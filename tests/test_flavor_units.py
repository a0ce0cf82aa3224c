"""A job sliced for one firmware and run on another (shaping/flavor_units.py): the M203 speeds a
Marlin profile writes in mm/s are mm/min to RepRapFirmware (and the reverse), M566 is nothing to
Marlin; the planner reads them so and the notes say it, with the figures the planner uses."""

from __future__ import annotations

import json
from importlib import resources

import numpy as np
import pytest

from ringtune.agents.cli.main import main
from ringtune.shaping import gcode
from ringtune.shaping.firmware import job_reading
from ringtune.shaping.flavor_units import flavor_note, foreign_limit_lines
from ringtune.shaping.planner import MachineLimits, plan
from ringtune.shaping.slicer import slicer_flavor

RRF_HEADER = ("M201 X3000 Y3000 Z500 E10000 ; sets maximum accelerations, mm/sec^2\n"
              "M203 X30000 Y18000 Z720 E7200 ; sets maximum feedrates, mm / min\n"
              "M204 P3000 T3000 ; sets acceleration (P, T), mm/sec^2\n"
              "M566 X600.00 Y600.00 Z12.00 E150.00 ; sets the jerk limits, mm/min\n")


def _limits(firmware: str) -> MachineLimits:
    return MachineLimits(junction="jerk", **job_reading(firmware))


def test_a_marlin_towers_m203_caps_rrf_at_a_sixtieth_and_the_plan_runs_at_that_speed(data_dir):
    """The real PrusaSlicer tower for Marlin 2 (M203 X500 Y500 Z10 E60, line 13): on RepRapFirmware
    X and Y are capped at 500 mm/min = 8.33 mm/s, and no planned move runs either axis faster
    (a diagonal may run at √2 times that); on Marlin the
    same line is 500 mm/s and nothing is said."""
    path = data_dir / "gcode" / "ianalexis_ender3_marlin" / "ringing_tower.gcode"
    assert slicer_flavor(path) == "marlin2"
    job = gcode.read_gcode(path)
    found = foreign_limit_lines(job, _limits("rrf"), "marlin2")
    assert list(found) == ["M203"]
    line, speeds = found["M203"][0]
    assert line == 13 and np.allclose([speeds[a] for a in "XYZE"], [500 / 60, 500 / 60, 10 / 60, 60 / 60])
    moves = plan(job, _limits("rrf")).moves
    d = (moves.end - moves.start)[:, :2]
    length = np.linalg.norm((moves.end - moves.start)[:, :3], axis=1)
    xy = np.hypot(*d.T) > 0
    per_axis = moves.v_nominal[xy, None] * np.abs(d[xy]) / length[xy, None]
    assert per_axis.max() <= 500 / 60 + 1e-9 and per_axis.max() > 0.99 * 500 / 60
    note = flavor_note(job, _limits("rrf"), "rrf")
    assert note.startswith("the job was sliced for marlin2 (its gcode_flavor) and runs on RepRapFirmware")
    assert "written in mm/s, are read in mm/min there: line 13 caps X 8.33 mm/s, Y 8.33 mm/s" in note
    assert foreign_limit_lines(job, _limits("marlin"), "marlin2") == {}
    assert flavor_note(job, _limits("marlin"), "marlin") is None


def test_an_rrf_jobs_m203_is_uncapped_on_marlin_and_its_m566_sets_nothing(tmp_path):
    """PrusaSlicer's RepRapFirmware machine limits (its own header lines, M203 in mm/min, M566) on
    Marlin: 30000 read as mm/s, M566 not a Marlin command; on RRF itself nothing is said."""
    body = "G90\nM82\nG1 X0 Y0 F6000\n" + "".join(f"G1 X{10 * (i % 2)} Y{i} E{i + 1} F3000\n" for i in range(1, 12))
    path = tmp_path / "rrf.gcode"
    path.write_text(RRF_HEADER + body + "; gcode_flavor = reprapfirmware\n")
    job = gcode.read_gcode(path)
    found = foreign_limit_lines(job, _limits("marlin"), "reprapfirmware")
    assert found["M203"] == [(2, {"X": 30000.0, "Y": 18000.0, "Z": 720.0, "E": 7200.0})]
    assert found["M566"] == [4]
    note = flavor_note(job, _limits("marlin"), "marlin")
    assert "caps X 30000 mm/s, Y 18000 mm/s" in note
    assert "it has no M566 (RepRapFirmware's jerk): the one on line 4 sets nothing" in note
    assert flavor_note(job, _limits("rrf"), "rrf") is None
    # Klipper reads none of these lines: klipper_ignores says so, this does not repeat it
    assert foreign_limit_lines(job, MachineLimits(**job_reading("klipper")), "reprapfirmware") == {}
    # a flavour whose unit is not known, or none: nothing
    assert foreign_limit_lines(job, _limits("marlin"), "repetier") == {}
    assert foreign_limit_lines(job, _limits("marlin"), None) == {}


def test_plan_json_carries_the_note(tmp_path, capsys):
    """``ringtune plan --json`` has ``flavor_note`` (null where the flavour and the reading agree); on
    a printer that names no firmware (the embedded default), an RRF job's M203 is read in mm/min, as
    its slicer wrote it, and the reason says so."""
    body = "G90\nM82\nG1 X0 Y0 F6000\n" + "".join(f"G1 X{10 * (i % 2)} Y{i} E{i + 1} F3000\n" for i in range(1, 12))
    path = tmp_path / "rrf.gcode"
    path.write_text(RRF_HEADER + body + "; gcode_flavor = reprapfirmware\n")
    marlin = tmp_path / "marlin.toml"
    marlin.write_text((resources.files("ringtune.envs.data") / "ender3.toml").read_text()
                      + '\n[current]\nfirmware = "marlin"\nshaper_x = "zv"\nfreq_x = 45.5\nshaper_y = "zv"\n'
                      'freq_y = 38.9\n')
    assert main(["plan", str(path), "--printer", str(marlin), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["flavor_note"] and "line 2 caps X 30000 mm/s" in res["flavor_note"]
    assert main(["plan", str(path), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["flavor_note"] is None and "M203 speeds read in mm/min" in res["junction_reason"]
    # read so, M203 X6000 Y6000 caps a travel at F18000 to 100 mm/s: the time of the same job with
    # the caps written in mm/s, planned as Marlin reads it
    travel = "G90\nM82\nG1 X0 Y0 F6000\nG1 X0 Y200 F18000\nG1 X150 Y200 F18000\nG1 X0 Y0 E5 F3000\n"
    rrf = tmp_path / "rrf-caps.gcode"
    rrf.write_text("M203 X6000 Y6000 Z720 E7200\n" + travel + "; gcode_flavor = reprapfirmware\n")
    same = tmp_path / "marlin-caps.gcode"
    same.write_text("M203 X100 Y100 Z12 E120\nM205 X8 Y8\n" + travel + "; gcode_flavor = marlin2\n")
    times = []
    for job in (rrf, same):
        assert main(["plan", str(job), "--junction", "jerk", "--json"]) == 0
        times.append(json.loads(capsys.readouterr().out)["print_time_s"])
    assert times[0] == pytest.approx(times[1], rel=1e-12) and times[0] > 200 / 100
    plain = tmp_path / "plain.gcode"
    plain.write_text(body)
    assert main(["plan", str(plain), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["flavor_note"] is None
