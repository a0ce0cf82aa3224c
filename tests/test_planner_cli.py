"""`ringtune plan`: acceptance 4 through the command line, JSON keys, trajectory, errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from ringtune.agents.cli.main import main


def _plan_json(capsys, *args):
    assert main(["plan", *args, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_plan_ianalexis_matches_prusaslicer_estimate(data_dir, capsys):
    """Acceptance 4: the job's own header limits, classic jerk (inferred from its M205 X/Y)."""
    res = _plan_json(capsys, str(data_dir / "gcode/ianalexis_ender3_marlin/ringing_tower.gcode"))
    assert res["junction"] == "jerk"
    assert res["slicer_estimate_s"] == 2428
    assert abs(res["vs_slicer"]) < 0.03
    assert len(res["shaper_events"]) == 300
    assert set(res["time_by_feature"]) >= {"External perimeter", "Skirt/Brim"}
    assert sum(res["time_by_feature"].values()) <= res["print_time_s"]


def test_plan_bassco_parses_klipper_style_commands(data_dir, capsys):
    res = _plan_json(capsys, str(data_dir / "gcode/bassco_ender3/ringing_tower.gcode"),
                     "--junction", "scv")
    assert res["moves"] > 10000 and res["print_time_s"] > 0
    assert res["events"]["other"] > 0
    assert res["top_frequencies"] and res["top_frequencies"][0]["freq_hz"] > 0


def test_plan_builtin_with_config_and_trajectory(tmp_path, capsys):
    cfg = tmp_path / "c.json"
    cfg.write_text(json.dumps({"firmware": "klipper", "shaper_x": "none", "shaper_y": "none",
                               "freq_x": 40, "freq_y": 40, "freq_limit_hz": 25,
                               "freq_limit_method": "sections", "accel": 2000}))
    traj = tmp_path / "t.csv"
    res = _plan_json(capsys, "--config", str(cfg), "--trajectory", str(traj), "--rate", "500")
    assert res["job"] == "built-in test print"
    assert res["freq_limit"]["moves_slowed"] > 0
    assert res["limits"]["accel"] == 2000
    data = np.loadtxt(traj, delimiter=",", skiprows=1, usecols=range(5))
    assert data.shape[1] == 5
    np.testing.assert_allclose(np.diff(data[:, 0]), 1 / 500, atol=1e-6)
    assert data[-1, 0] == pytest.approx(res["print_time_s"], abs=2 / 500)
    # DAA selected like a shaper
    cfg.write_text(json.dumps({"firmware": "rrf", "shaper_x": "daa", "shaper_y": "daa",
                               "freq_x": 40, "freq_y": 40}))
    res_daa = _plan_json(capsys, "--config", str(cfg))
    assert res_daa["daa_hz"] == 40


def test_plan_errors_are_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.gcode"
    bad.write_text("G1 X10 F600\nG1 Xoops\n")
    assert main(["plan", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "bad.gcode:2" in err
    assert main(["plan", str(tmp_path / "none.gcode")]) == 2
    assert main(["plan", "--rate", "0", "--trajectory", str(tmp_path / "x.csv")]) == 2


def test_plan_trajectory_is_shaped_by_the_config(tmp_path, capsys):
    plain, shaped = tmp_path / "plain.csv", tmp_path / "shaped.csv"
    _plan_json(capsys, "--trajectory", str(plain), "--rate", "1000")
    cfg = tmp_path / "c.json"
    cfg.write_text(json.dumps({"firmware": "klipper", "shaper_x": "mzv", "shaper_y": "mzv",
                               "freq_x": 40, "freq_y": 40, "damping_x": 0.1, "damping_y": 0.1}))
    _plan_json(capsys, "--config", str(cfg), "--trajectory", str(shaped), "--rate", "1000")
    a = np.loadtxt(plain, delimiter=",", skiprows=1, usecols=range(5))
    b = np.loadtxt(shaped, delimiter=",", skiprows=1, usecols=range(5))
    n = min(len(a), len(b))
    # shaping smooths the corners (positions differ) but keeps where the job ends
    assert np.abs(a[:n, 1:3] - b[:n, 1:3]).max() > 0.01
    from ringtune.shaping.planner import MachineLimits, plan
    from ringtune.shaping.testprints import builtin_test_print

    end = plan(builtin_test_print(), MachineLimits()).motion.end_position
    np.testing.assert_allclose(b[-1, 1:], end, atol=1e-5)      # the shaped tail settles there


def test_plan_with_an_embedded_printer(capsys):
    res = _plan_json(capsys, "--printer", "ender3")
    assert res["junction"] in ("scv", "jd", "jerk")
    assert res["print_time_s"] > 0


def test_plan_applies_the_jobs_own_marlin_frequency_limit(tmp_path, capsys):
    """M201 F20 S50 in the job: Marlin's XY_FREQUENCY_LIMIT slows 1 mm X reversals at 50 mm/s
    (20 ms < 50 ms) from the fourth on to max(20/50, 50 %) = 25 mm/s (firmware.md §2.3)."""
    body = "M83\nG1 F3000\n" + "".join(f"G1 X{x} E0.05\n" for x in [10, 9, 10, 9, 10, 9, 10])
    limited, plain = tmp_path / "f.gcode", tmp_path / "p.gcode"
    limited.write_text("M201 F20 S50\n" + body)
    plain.write_text(body)
    a = _plan_json(capsys, str(limited), "--junction", "jd")
    b = _plan_json(capsys, str(plain), "--junction", "jd")
    assert a["freq_limit"] == {"hz": 20.0, "method": "marlin", "moves_slowed": 4, "source": "job M201 F"}
    assert b["freq_limit"] is None
    assert a["print_time_s"] > b["print_time_s"]
    off = _plan_json(capsys, str(limited), "--junction", "jd", "--no-job-limits")
    assert off["freq_limit"] is None


def test_trajectory_to_standard_output(tmp_path, capsys):
    """`--trajectory -`: the CSV is standard output (summary on stderr), ends where the G-code ends;
    with --json (which needs stdout) it is a one-line error."""
    import numpy as np

    job = tmp_path / "j.gcode"
    job.write_text("G28\nG1 X10 Y5 E1 F3000\nG1 X0 E2\n")
    assert main(["plan", str(job), "--trajectory", "-", "--rate", "200"]) == 0
    cap = capsys.readouterr()
    assert cap.out.startswith("t,x,y,z,e,feature\n") and "planned with" in cap.err
    data = np.loadtxt(cap.out.splitlines()[1:], delimiter=",", usecols=range(5))
    assert data[-1, 1:5] == pytest.approx([0.0, 5.0, 0.0, 2.0], abs=0.005)   # last 5 ms sample, decelerating
    assert np.allclose(np.diff(data[:, 0]), 0.005)
    assert main(["plan", str(job), "--trajectory", "-", "--json"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--trajectory" in err[0]


def test_plan_of_a_folder_says_it_is_a_folder(tmp_path, capsys):
    """A folder given as the G-code file is named as a folder, not as a missing file."""
    assert main(["plan", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and f"{tmp_path}: is a directory" in err, err
    assert "no such" not in err


def test_a_klipper_configuration_plans_with_klippers_corner_rule(tmp_path, capsys):
    """The part was sliced for Marlin 2 (junction deviation); a configuration made for Klipper is
    planned as Klipper runs it, with square_corner_velocity, so `plan --config best.json` gives
    tune's print time (tune plans the printer with its own rule); one for Marlin keeps the
    slicer's flavour."""
    from ringtune.envs.planned_job import planned_job
    from ringtune.envs.printer import load_printer
    from ringtune.shaping.config import TuneConfig
    times = {}
    for fw in ("klipper", "marlin"):
        cfg = TuneConfig(firmware=fw, shaper_x="zv", freq_x=50.0, shaper_y="zv", freq_y=40.0, accel=6000.0)
        path = tmp_path / f"{fw}.json"
        path.write_text(json.dumps(cfg.to_dict()))
        assert main(["plan", "part", "--config", str(path), "--json"]) == 0
        r = json.loads(capsys.readouterr().out)
        times[fw] = (r["junction"], r["print_time_s"])
    assert times["klipper"][0] == "scv" and times["marlin"][0] == "jd"
    klipper_cfg = TuneConfig(shaper_x="zv", freq_x=50.0, shaper_y="zv", freq_y=40.0, accel=6000.0)
    tuned = planned_job(load_printer(None), "part", klipper_cfg).plan.print_time
    assert times["klipper"][1] == pytest.approx(tuned, rel=1e-9)
    assert times["marlin"][1] != pytest.approx(tuned, rel=1e-3)


def test_plan_names_the_marlin_lines_klipper_does_not_act_on(data_dir, capsys):
    path = data_dir / "gcode/ianalexis_ender3_marlin/ringing_tower.gcode"
    lines = path.read_text(errors="replace").splitlines()
    want = {cmd: [i + 1 for i, ln in enumerate(lines) if ln.split(";")[0].split()[:1] == [cmd]]
            for cmd in ("M201", "M203", "M205")}
    res = _plan_json(capsys, str(path), "--junction", "scv")
    assert res["ignored_by_firmware"] == {k: v for k, v in want.items() if v}
    assert res["ignored_note"].startswith("Klipper does not act on")
    # as the Marlin it was sliced for plans it (its own classic jerk), nothing is ignored
    assert _plan_json(capsys, str(path))["ignored_by_firmware"] == {}
    assert main(["plan", str(path), "--junction", "scv"]) == 0
    assert "Klipper does not act on" in capsys.readouterr().out
