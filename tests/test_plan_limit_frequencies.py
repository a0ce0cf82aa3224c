"""`plan` and `limit` name the frequency they report and agree on it (issue 14).

`plan` said the ringing tower's highest direction change is 12.6 Hz; `limit --freq-limit 20` then
slowed 50 moves, and the limited file still planned at 12.5 Hz: the limit acts on the frequency at
the G-code's commanded speeds (35.4 Hz there), the plan reported the planned one, neither named.
Both commands now give both figures through the same functions; the truths checked here are the
definitions (a limit L brings every commanded frequency down to L; the planner never runs faster
than commanded) and the slicer's own estimate written in the file.
"""

from __future__ import annotations

import json

import pytest

from ringtune.agents.cli.main import main

TOWER = "gcode/bassco_ender3/ringing_tower.gcode"
MARLIN_TOWER = "gcode/ianalexis_ender3_marlin/ringing_tower.gcode"


def _json(capsys, argv):
    assert main(argv + ["--json"]) == 0
    return json.loads(capsys.readouterr().out)


@pytest.mark.parametrize("printer", [[], ["--printer", "ender3"]])
def test_limit_and_plan_report_the_same_commanded_and_planned_frequencies(data_dir, tmp_path, capsys, printer):
    src, dst = str(data_dir / TOWER), str(tmp_path / "limited.gcode")
    before = _json(capsys, ["plan", src, *printer])
    lim = _json(capsys, ["limit", src, "--freq-limit", "20", "-o", dst, *printer])
    after = _json(capsys, ["plan", dst, *printer])
    f = lim["frequencies"]
    assert f["commanded_hz"]["before"] == before["max_commanded_freq_hz"]
    assert f["planned_hz"]["before"] == before["max_planned_freq_hz"]
    assert f["commanded_hz"]["after"] == after["max_commanded_freq_hz"]
    assert f["planned_hz"]["after"] == after["max_planned_freq_hz"]
    assert f["junction"] == before["junction"] == after["junction"]
    # the limit slowed moves because the commanded figure was over 20 Hz, and brought it to 20 Hz
    # (F words are written to 0.1 mm/min); the planner never runs faster than commanded
    assert lim["moves_slowed"] > 0 and before["max_commanded_freq_hz"] > 20.0
    assert after["max_commanded_freq_hz"] == pytest.approx(20.0, abs=0.01)
    for res in (before, after):
        assert res["max_planned_freq_hz"] < res["max_commanded_freq_hz"]
        assert res["max_planned_freq_hz"] == res["top_frequencies"][0]["freq_hz"]
        assert res["max_commanded_freq_hz"] == res["top_commanded_frequencies"][0]["freq_hz"]


def test_plan_and_limit_text_name_which_frequency(data_dir, tmp_path, capsys):
    src = str(data_dir / TOWER)
    assert main(["plan", src]) == 0
    text = capsys.readouterr().out
    assert "commanded, at the G-code's F (what a frequency limit acts on)" in text
    assert "planned with scv" in text
    assert main(["limit", src, "--freq-limit", "20", "-o", str(tmp_path / "o.gcode")]) == 0
    text = capsys.readouterr().out
    assert "commanded at F 35.4 -> 20.0 Hz" in text and "planned with scv 12.6 -> 12.5 Hz" in text


def test_plan_of_a_marlin_job_uses_its_rule_and_says_why(data_dir, capsys):
    """The PrusaSlicer tower for Marlin sets M205 X/Y: planned with jerk it lands within 1 % of the
    slicer's own estimate written in the file; a printer without a junction rule of its own no
    longer turns it into Klipper's square-corner velocity (-3 %) silently."""
    src = str(data_dir / MARLIN_TOWER)
    for printer in ([], ["--printer", "ender3"]):
        res = _json(capsys, ["plan", src, *printer])
        assert res["junction"] == "jerk" and "M205 X/Y" in res["junction_reason"]
        assert abs(res["vs_slicer"]) < 0.01
    forced = _json(capsys, ["plan", src, "--junction", "scv"])
    assert forced["junction_reason"] == "--junction" and forced["vs_slicer"] < -0.02
    assert main(["plan", src]) == 0
    assert "planned with jerk (classic jerk): the job sets a jerk (M205 X/Y" in capsys.readouterr().out


def test_plan_reads_the_slicer_flavour_when_the_job_sets_no_corner_rule(tmp_path, capsys):
    body = "G90\nM82\nG1 X0 Y0 F6000\n" + "".join(
        f"G1 X{10 * (i % 2)} Y{i} E{i + 1} F3000\n" for i in range(1, 12))
    for flavor, junction in (("marlin2", "jd"), ("klipper", "scv"), ("reprapfirmware", "jerk")):
        job = tmp_path / f"{flavor}.gcode"
        job.write_text(body + f"; gcode_flavor = {flavor}\n")
        res = _json(capsys, ["plan", str(job)])
        assert res["junction"] == junction and flavor in res["junction_reason"]
    plain = tmp_path / "plain.gcode"
    plain.write_text(body)
    res = _json(capsys, ["plan", str(plain)])
    # nothing in the job names a rule: the embedded default printer's corner setting does
    assert res["junction"] == "scv"
    assert res["junction_reason"] == "the printer gives square_corner_velocity (the embedded default printer)"
    # Klipper's own command names Klipper's rule, before the flavour a Marlin 2 profile wrote
    orca = tmp_path / "orca.gcode"
    orca.write_text("SET_VELOCITY_LIMIT ACCEL=5000 ACCEL_TO_DECEL=2500\n" + body + "; gcode_flavor = marlin2\n")
    res = _json(capsys, ["plan", str(orca)])
    assert res["junction"] == "scv" and "SET_VELOCITY_LIMIT" in res["junction_reason"]
