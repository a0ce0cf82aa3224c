"""What tune says of a job's own acceleration commands depends on the firmware that runs it: Klipper
(and Kalico) take M204 S, or P and T together, and SET_VELOCITY_LIMIT — not M201, M203, M205 or a
lone M204 P or T (toolhead.py ``cmd_M204``: "Invalid M204 command") — so a job sliced for Marlin 2
sets no acceleration on a Klipper printer, and tune says which lines it ignores; on Marlin the same
lines are the job's own accelerations."""

from __future__ import annotations

from ringtune.agents.cli.main import main
from ringtune.agents.tune.job import job_accel_facts
from ringtune.envs.job_plan import limit_job
from ringtune.envs.printer import load_printer, printer_from_dict

LAYER = ";TYPE:External perimeter\nG1 X20 Y0 E1 F6000\nG1 X20 Y20 E1\n;TYPE:Internal infill\n{infill}\nG1 X0 Y20 E1\n"


def _job(tmp_path, header: str, infill: str):
    path = tmp_path / "own.gcode"
    path.write_text("G90\nM83\n" + header + "G1 Z0.2 F600\n" + LAYER.format(infill=infill))
    return str(path)


def test_a_marlin2_job_sets_nothing_on_klipper_and_tune_names_the_lines(tmp_path):
    klipper = load_printer(None)
    assert klipper.limits.junction == "scv"
    job = _job(tmp_path, "M201 X500 Y400\nM204 P1500\n", "M204 P9000")
    facts = job_accel_facts(klipper, job, "respect")
    assert facts.commands == {} and facts.cap is None
    (note,) = facts.notes("respect", None)
    assert note.startswith("Klipper does not act on 3 of the job's limit lines")
    assert "M201 ×1 (first on line 3)" in note and "M204 without S or both P and T ×2 (first on line 4)" in note


def test_klippers_own_forms_and_marlins_are_each_the_jobs_accelerations_on_their_firmware(tmp_path):
    klipper = load_printer(None)
    job = _job(tmp_path, "M204 S1500\nSET_VELOCITY_LIMIT X_ACCEL=500 Y_ACCEL=400\n", "M204 P9000 T9000")
    facts = job_accel_facts(klipper, job, "respect")
    assert facts.commands == {"accel_klipper": 9000.0, "limited_accel_x": 500.0, "limited_accel_y": 400.0}
    assert facts.described() == "SET_VELOCITY_LIMIT X_ACCEL=500 Y_ACCEL=400, SET_VELOCITY_LIMIT ACCEL=9000 (or M204 S)"
    d = klipper.to_dict()
    d["limits"] = {**d.get("limits", {}), "junction": "jd"}
    marlin = printer_from_dict(d)
    job = _job(tmp_path, "M201 X500 Y400\nM204 P1500\n", "M204 P9000")
    facts = job_accel_facts(marlin, job, "respect")
    assert facts.commands == {"accel_print": 9000.0, "max_accel_x": 500.0, "max_accel_y": 400.0}
    assert facts.described() == "M201 X500 Y400, M204 P9000"
    assert not any("Klipper" in n for n in facts.notes("replace", None))


def test_limit_says_a_scaled_lone_m204_still_does_nothing_on_klipper(tmp_path):
    d = load_printer(None).to_dict()
    d["limits"] = {**d.get("limits", {}), "junction": "scv"}
    klipper = printer_from_dict(d)
    job = _job(tmp_path, ";FLAVOR:Marlin 2\nM204 P1500\n", "M204 P3000")
    done = limit_job(job, accel=6000, printer=klipper)
    assert done.accel is not None and done.frequencies["junction"] == "scv"
    assert "M204 without S or both P and T ×2" in done.frequencies["ignored_note"]
    d["limits"]["junction"] = "jd"
    assert limit_job(job, accel=6000, printer=printer_from_dict(d)).frequencies["ignored_note"] is None


def test_simulate_says_it_too(tmp_path, capsys):
    job = _job(tmp_path, "M201 X500 Y400\nM204 P1500\n", "M204 P9000")
    assert main(["simulate", "--gcode", job, "--backend", "lti", "--no-baselines", "--freq-margin", "0"]) == 0
    assert "Klipper does not act on 3 of the job's limit lines" in capsys.readouterr().err
