"""``ringtune tune`` says what is true (issue 14): "the same" and "dominates" at a stated resolution,
the default pick "same quality, faster", the baselines the user really has, progress in a log,
and the small errors found by trying it as a new user."""

from __future__ import annotations

import dataclasses

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from ringtune.agents.cli.main import main
from ringtune.agents.tune.baselines import current_config
from ringtune.agents.tune.choice import pick
from ringtune.agents.tune.pareto import Point, judge, pareto_front
from ringtune.agents.tune.versus import compare
from ringtune.envs.printer import load_printer
from ringtune.shaping.config import TuneConfig

TESTS = Path(__file__).resolve().parent


@pytest.fixture
def fake_evaluator(monkeypatch):
    monkeypatch.syspath_prepend(str(TESTS))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(TESTS), os.environ.get("PYTHONPATH", "")]))
    return "study_objective:evaluate"


def _pt(t, over, pe, label="", feasible=True):
    return Point(TuneConfig(), t, over, False, {"overshoot_mm": over, "path_error_mm": pe}, label,
                 too_rough=not feasible)


# -- acceptance 14.3 -------------------------------------------------------------------------------
def test_a_sub_micrometre_overshoot_gain_does_not_buy_70_percent_more_path_error():
    """0.4 µm less overshoot is the same (under 1 µm); +70 % path error is worse (over 5 %): neither
    dominates, and the JSON of the comparison says so per figure."""
    klipper = _pt(5.0, 0.0034, 0.0459, "klipper")
    mine = _pt(4.5, 0.0030, 0.0459 * 1.7, "mine")
    j = judge(mine, klipper)
    assert j.verdicts["overshoot_mm"] == "same" and j.verdicts["path_error_mm"] == "worse"
    assert j.verdicts["print_time_s"] == "better"          # 10 % faster, over 0.5 %
    assert not j.dominates and not judge(klipper, mine).dominates
    d = json.loads(json.dumps(compare(mine, klipper).to_dict()))
    assert d["dominates"] is False
    assert d["metrics"]["overshoot_mm"] == "same" and d["metrics"]["path_error_mm"] == "worse"
    assert "does not dominate it (worse path error)" in compare(mine, klipper).sentence("overshoot_mm")


def test_resolution_edges_one_micrometre_five_percent_half_a_percent_of_time():
    base = _pt(100.0, 0.010, 0.040)
    # 1 µm is larger than 5 % of 10 µm (0.5 µm): 0.9 µm is the same, 1.1 µm is not
    assert judge(_pt(100.0, 0.0109, 0.040), base).verdicts["overshoot_mm"] == "same"
    assert judge(_pt(100.0, 0.0111, 0.040), base).verdicts["overshoot_mm"] == "worse"
    # 5 % of 40 µm = 2 µm is larger than 1 µm: +1.9 µm is the same, +2.3 µm (5.5 % of 42.3) is worse
    assert judge(_pt(100.0, 0.010, 0.0419), base).verdicts["path_error_mm"] == "same"
    assert judge(_pt(100.0, 0.010, 0.0423), base).verdicts["path_error_mm"] == "worse"
    # time: 0.4 % faster is the same, 0.6 % faster is better
    assert judge(_pt(99.6, 0.010, 0.040), base).verdicts["print_time_s"] == "same"
    assert judge(_pt(99.4, 0.010, 0.040), base).verdicts["print_time_s"] == "better"
    assert judge(_pt(99.4, 0.010, 0.040), base).dominates
    # a point ruled out by a bound never dominates a baseline that keeps it
    assert not judge(_pt(90.0, 0.001, 0.001, feasible=False), base).dominates


# -- acceptance 14.4 -------------------------------------------------------------------------------
def test_default_pick_is_the_fastest_point_at_the_best_baselines_quality():
    klipper = _pt(10.0, 0.004, 0.040, "klipper")
    front = [_pt(8.0, 0.020, 0.090, "fast but rough"), _pt(9.0, 0.0042, 0.041, "same quality, faster"),
             _pt(9.5, 0.003, 0.030, "better, less fast"), _pt(12.0, 0.001, 0.020, "slow")]
    c = pick(front, {"klipper": klipper, "none": _pt(11.0, 0.07, 0.07, "none")})
    assert c.point.label == "same quality, faster" and c.by == "fastest-at-baseline-quality"
    assert c.baseline == "klipper"
    # nothing the study tried as fast with no worse quality: Klipper's pick itself, said so
    c = pick(front[:1] + front[3:], {"klipper": klipper})
    assert c.point is klipper and c.by == "fastest-at-baseline-quality"
    assert "no configuration the study tried is as fast as Klipper's rule with no worse" in c.sentence
    assert "Klipper's rule itself" in c.sentence
    # no usable baseline: the knee, and the sentence says why
    c = pick(front[:1] + front[3:], {})
    assert c.by == "knee" and "because there is no usable baseline" in c.sentence
    assert pick(front, {"klipper": klipper}, "knee").by == "knee"
    assert pick(front, {"klipper": klipper}, "weight", weight=0.0).point.label == "fast but rough"


def test_the_default_pick_searches_behind_the_front():
    """Over print time and overshoot a rough point hides one that matches Klipper's quality on every
    figure (path error too); the front is the rough one alone, yet the choice is the match when
    every point is a candidate, and Klipper's pick itself (said as such) when none is."""
    klipper = _pt(5.0, 0.0037, 0.0459, "klipper")
    rough = _pt(4.5, 0.0030, 0.095, "rough")
    match = _pt(4.8, 0.0036, 0.046, "match")
    front = pareto_front([rough, match])
    assert [p.label for p in front] == ["rough"]
    c = pick(front, {"klipper": klipper}, candidates=[rough, match])
    assert c.point is match and c.by == "fastest-at-baseline-quality" and "same quality, faster" in c.sentence
    c = pick(front, {"klipper": klipper}, candidates=[rough])
    assert c.point is klipper and c.by == "fastest-at-baseline-quality" and "Klipper's rule itself" in c.sentence


def test_the_front_keeps_a_point_with_less_path_error_so_the_pick_can_match_the_baseline():
    """Over print time and overshoot alone, a faster point with less overshoot but twice the path
    error hides the one that matches Klipper's quality; the front over both figures keeps it, and
    it is the choice ("same quality, faster")."""
    klipper = _pt(5.087, 0.0037, 0.0459, "klipper")
    rough_fast = _pt(4.5, 0.0030, 0.095, "rough")
    match = _pt(4.9, 0.0036, 0.047, "match")
    assert [p.label for p in pareto_front([rough_fast, match])] == ["rough"]
    front = pareto_front([rough_fast, match], also=("path_error_mm",))
    assert [p.label for p in front] == ["rough", "match"]
    c = pick(front, {"klipper": klipper})
    assert c.point is match and "same quality, faster" in c.sentence
    # the baseline's own configuration found again is not "faster": the sentence says so
    c = pick([rough_fast, _pt(5.087, 0.0037, 0.0459, "itself")], {"klipper": klipper})
    assert c.point.label == "itself" and "no configuration the study tried is faster than Klipper's rule" in c.sentence


def test_a_choice_as_fast_as_the_baseline_but_another_configuration_is_not_called_the_baseline():
    """Where every configuration plans the same time (the job's own accelerations rule), the choice
    is the best of those as fast, and the sentence says that, not "nothing better than Klipper's rule
    itself", which it is not."""
    klipper = _pt(5.0, 0.0037, 0.0459, "klipper")
    other = Point(TuneConfig(shaper_x="zv", freq_x=48.0, shaper_y="zv", freq_y=40.0), 5.0, 0.0020, False,
                  {"overshoot_mm": 0.0020, "path_error_mm": 0.030}, "other")
    c = pick([other], {"klipper": klipper})
    assert c.point is other and c.by == "fastest-at-baseline-quality"
    assert "of those as fast, one no other beats on a visible measure, then the best on the study's quality objective" in c.sentence
    assert "itself" not in c.sentence


def _no_worse(p, b):
    """Independent of pareto.judge: quality no worse than b's beyond 1 µm / 5 % of the larger."""
    def ok(a, c):
        return a - c <= max(0.001, 0.05 * max(abs(a), abs(c)))
    return ok(p["overshoot_mm"], b["overshoot_mm"]) and ok(p["path_error_mm"], b["path_error_mm"])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_with_40_trials_the_choice_is_as_fast_as_a_baseline_at_no_worse_quality(tmp_path, capsys, fake_evaluator,
                                                                               seed):
    out = tmp_path / "out"
    assert main(["tune", "--json", "--out", str(out), "--trials", "40", "--seed", str(seed), "--evaluator",
                 fake_evaluator]) == 0
    res = json.loads(capsys.readouterr().out)
    rows = [r.split(",") for r in (out / "front.csv").read_text().strip().splitlines()]
    cols = rows[0]
    front = [{k: float(v) for k, v in zip(cols, r) if k in ("print_time_s", "overshoot_mm", "path_error_mm")}
             for r in rows[1:]]
    shaped = {k: b for k, b in res["baselines"].items() if k != "none" and not b["breaks"]}
    exists = any(p["print_time_s"] <= b["print_time_s"] and _no_worse(p, b) for p in front for b in shaped.values())
    ch = res["chosen"]
    if exists:
        assert ch["chosen_by"] == "fastest-at-baseline-quality"
        b = res["baselines"][ch["against"]]
        assert ch["print_time_s"] <= b["print_time_s"] and _no_worse(ch, b)
    else:
        assert ch["chosen_by"] == "knee" and "because" in ch["why"]
    summary = (out / "summary.txt").read_text()
    assert ch["why"] in summary


# -- baselines: what the user really has (acceptance 14.1, unit part) ----------------------------
def _printer_toml(path: Path, klipper: dict | None = None, current: dict | None = None) -> Path:
    text = """name = "ender3-measured"
kinematics = "cartesian"
[limits]
accel = 3000
velocity = 300
square_corner_velocity = 5
[x]
modes = [{ freq = 51.0, damping = 0.06 }]
[y]
modes = [{ freq = 46.0, damping = 0.05 }]
"""
    if current:
        text += "[current]\n" + "".join(f"{k} = {json.dumps(v)}\n" for k, v in current.items())
    if klipper:
        text += '[measurement]\nsource = "accelerometer"\n[measurement.klipper]\n' + \
            "".join(f"{k} = {json.dumps(v)}\n" for k, v in klipper.items())
    path.write_text(text)
    return path


def test_klippers_rule_is_the_recommendation_recorded_from_the_files(data_dir, tmp_path, capsys, fake_evaluator):
    """The printer records Klipper's recommendation from its resonance files (computed here with the
    function `recommend --accel` uses): tune's Klipper baseline is exactly it, in the summary and the
    JSON, and nothing says "simulated"."""
    from ringtune.agents.identify.accelerometer import resonance_psds
    from ringtune.agents.klipper.baseline import recommend_axes

    d = data_dir / "accel" / "klipper_psd" / "bassco_ender3"
    psds, _ = resonance_psds([str(p) for p in sorted(d.glob("resonances_*.csv"))], None)
    fits, fields = recommend_axes(psds, "klipper", "head", 5.0)
    rec = {"shaper_x": fields["shaper_x"], "freq_x": fields["freq_x"], "shaper_y": fields["shaper_y"],
           "freq_y": fields["freq_y"], "max_accel": fields["accel"], "version": "head"}
    toml = _printer_toml(tmp_path / "p.toml", klipper=rec)
    out = tmp_path / "out"
    assert main(["tune", "--json", "--printer", str(toml), "--out", str(out), "--trials", "5", "--evaluator",
                 fake_evaluator]) == 0
    res = json.loads(capsys.readouterr().out)
    k = res["baselines"]["klipper"]
    assert k["source"] == "measurement" and "simulated" not in k["label"]
    for key in ("shaper_x", "freq_x", "shaper_y", "freq_y"):
        assert k["config"][key] == fields[key]
    assert k["config"]["accel"] == fields["accel"]
    summary = (out / "summary.txt").read_text()
    line = next(s for s in summary.splitlines() if s.strip().startswith("Klipper's rule from your resonance files"))
    assert (f"X {fields['shaper_x']} @ {fields['freq_x']:.1f} Hz, Y {fields['shaper_y']} @ {fields['freq_y']:.1f} Hz"
            in line and f"accel {fields['accel']:.0f} mm/s²" in line)
    assert "simulated resonance test" not in summary


def test_klippers_max_accel_is_judged_with_the_stored_axis_caps_raised_where_gcode_sets_them(tmp_path):
    """A Marlin printer whose M503 stored M201 X500 Y500: Klipper's rule at its max_accel is judged
    with the caps raised to it (as every trial and export run it: M201 X Y before M204), so its
    print time is the planner's at that acceleration, not at 500; what the printer runs now keeps its
    caps; on Klipper, which stores no caps to raise, nothing is added."""
    from ringtune.agents.tune.baselines import baseline_configs
    from ringtune.envs.planned_job import planned_job
    from ringtune.envs.printer import load_printer

    rec = {"shaper_x": "zv", "freq_x": 51.0, "shaper_y": "zv", "freq_y": 46.0, "max_accel": 7800.0}
    toml = _printer_toml(tmp_path / "p.toml", klipper=rec, current={"firmware": "marlin", "shaper_x": "zv",
                                                                    "freq_x": 40.0, "accel": 500.0})
    text = toml.read_text().replace("[limits]\n", "[limits]\nmax_accel = [500, 500, 100, 5000]\njunction = \"jd\"\n"
                                    "junction_deviation = 0.08\n")
    toml.write_text(text.replace("square_corner_velocity = 5\n", ""))
    printer = load_printer(str(toml))
    bl = baseline_configs(printer, "marlin")
    k = bl.configs["klipper"]
    assert (k.accel, k.max_accel_x, k.max_accel_y) == (7800.0, 7800.0, 7800.0)
    assert bl.configs["current"].max_accel_x is None
    t_raised = planned_job(printer, "part", k).print_time
    t_stored = planned_job(printer, "part", dataclasses.replace(k, max_accel_x=None, max_accel_y=None)).print_time
    assert t_raised < 0.75 * t_stored
    assert baseline_configs(printer, "klipper").configs["klipper"].max_accel_x is None


def test_without_a_recorded_recommendation_the_baseline_says_simulated_and_current_is_a_third(tmp_path, capsys,
                                                                                             fake_evaluator):
    toml = _printer_toml(tmp_path / "p.toml", current={"source": "printer.cfg", "shaper_x": "mzv", "freq_x": 48.2,
                                                       "shaper_y": "ei", "freq_y": 41.0, "damping_x": 0.1,
                                                       "damping_y": 0.1, "accel": 2500.0})
    out = tmp_path / "out"
    assert main(["tune", "--json", "--printer", str(toml), "--out", str(out), "--trials", "5", "--evaluator",
                 fake_evaluator, "--accel-range", "1000,5000"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert set(res["baselines"]) == {"klipper", "current", "none"}
    assert res["baselines"]["klipper"]["source"] == "simulated resonance test"
    assert "on a simulated resonance test" in res["baselines"]["klipper"]["label"]
    cur = res["baselines"]["current"]["config"]
    assert (cur["shaper_x"], cur["freq_x"], cur["shaper_y"], cur["freq_y"], cur["accel"]) == \
        ("mzv", 48.2, "ei", 41.0, 2500.0)
    summary = (out / "summary.txt").read_text()
    assert "Klipper's rule on a simulated resonance test of the model" in summary
    assert "what the printer runs now (printer.cfg): X mzv @ 48.2 Hz, Y ei @ 41.0 Hz" in summary
    assert "current" in res["vs_baselines"]


def test_what_a_klipper_printer_runs_now_is_left_out_where_the_target_firmware_cannot_run_it(tmp_path, capsys,
                                                                                             fake_evaluator):
    """A printer described from Klipper running EI on X (the real Switchwire's printer.cfg), tuned for
    Marlin (ZV only) or RepRapFirmware (one shaper for all axes, no plain EI): its [current] is no
    baseline there, and why is said; the tune runs on against Klipper's rule and no shaping. A
    shaper per axis that RRF has, on RRF's one shaper, is left out the same way; on Klipper it stands."""
    toml = _printer_toml(tmp_path / "p.toml", current={"source": "printer.cfg", "firmware": "klipper",
                                                       "shaper_x": "ei", "freq_x": 60.0, "shaper_y": "mzv",
                                                       "freq_y": 37.2, "accel": 5000.0})
    assert main(["tune", "--json", "--printer", str(toml), "--firmware", "marlin", "--out", str(tmp_path / "o"),
                 "--trials", "4", "--evaluator", fake_evaluator, "--accel-range", "1000,5000", "--no-refine"]) == 0
    cap = capsys.readouterr()
    assert set(json.loads(cap.out)["baselines"]) == {"klipper", "none"}
    said = [ln for ln in cap.err.splitlines() if "what the printer runs now ([current]) cannot be compared" in ln]
    assert len(said) == 1 and "on marlin" in said[0] and "has no 'ei' shaper" in said[0]
    printer = load_printer(str(toml))
    cfg, why = current_config(printer, "rrf")
    assert cfg is None and "on rrf" in why and "has no 'ei' shaper" in why
    assert current_config(printer, "klipper")[0].shaper_x == "ei"
    per_axis = load_printer(str(_printer_toml(tmp_path / "q.toml", current={
        "firmware": "klipper", "shaper_x": "mzv", "freq_x": 60.0, "shaper_y": "zvd", "freq_y": 37.2})))
    cfg, why = current_config(per_axis, "rrf")
    assert cfg is None and "rrf runs one shaper for all axes, the printer runs a different shaper per axis now" in why
    assert current_config(per_axis, "marlin")[0] is None and current_config(per_axis, "kalico")[0] is not None


# -- progress (acceptance 14.6, tune part) --------------------------------------------------------
def test_progress_goes_to_a_log_file_as_lines(tmp_path, fake_evaluator):
    out = tmp_path / "out"
    log = tmp_path / "log"
    env = dict(os.environ, RINGTUNE_PROGRESS_S="0")
    with open(log, "w") as err:
        done = subprocess.run([sys.executable, "-m", "ringtune.agents.cli.main", "tune", "--json", "--out", str(out),
                               "--trials", "6", "--no-baselines", "--evaluator", fake_evaluator],
                              env=env, stdout=subprocess.PIPE, stderr=err, text=True, timeout=120)
    assert done.returncode == 0
    json.loads(done.stdout)                      # stdout is only the JSON
    lines = [s for s in log.read_text().splitlines() if s.startswith("ringtune tune: ") and "/6 trials" in s]
    assert len(lines) >= 2 and "6/6 trials" in lines[-1] and "best so far" in lines[-1]
    assert "\r" not in log.read_text()          # no progress bar redraws in a log


# -- smaller things --------------------------------------------------------------------------------
def test_out_that_is_a_file_is_one_clear_line(tmp_path, capsys):
    f = tmp_path / "myprinter.toml"
    f.write_text("name = 'x'\n")
    assert main(["tune", "--out", str(f), "--trials", "1"]) == 2
    err = capsys.readouterr().err
    assert "--out" in err and "is a file, not a folder" in err and "Errno" not in err


@pytest.mark.parametrize("code", ["EROFS", "EACCES"])
def test_read_only_out_is_one_clear_line(tmp_path, capsys, monkeypatch, code):
    """A read-only mount (EROFS) or a folder without write permission (EACCES; simulated, since the
    suite runs as root in CI and root writes anywhere): the probe write fails; said in words."""
    import errno
    import tempfile

    def refuse(*a, **k):
        raise OSError(getattr(errno, code), os.strerror(getattr(errno, code)))
    monkeypatch.setattr(tempfile, "TemporaryFile", refuse)
    assert main(["tune", "--out", str(tmp_path / "res"), "--trials", "1"]) == 2
    err = capsys.readouterr().err
    assert "--out" in err and "cannot write" in err and os.strerror(getattr(errno, code)) in err
    assert "Errno" not in err and not (tmp_path / "res").exists()


def test_a_failed_tune_leaves_no_empty_out_folder(tmp_path, capsys):
    out = tmp_path / "res"
    assert main(["tune", "--out", str(out), "--trials", "2", "--evaluator", "no_such_module:f"]) == 2
    assert "--evaluator" in capsys.readouterr().err
    assert not out.exists()


def test_study_mismatch_names_the_default_printer_in_words(tmp_path, capsys, fake_evaluator):
    out = tmp_path / "out"
    assert main(["tune", "--out", str(out), "--trials", "3", "--no-baselines", "--evaluator", fake_evaluator,
                 "--accel-range", "1000,5000"]) == 0
    toml = _printer_toml(tmp_path / "p.toml")
    capsys.readouterr()
    assert main(["tune", "--out", str(out), "--trials", "3", "--no-baselines", "--printer", str(toml),
                 "--evaluator", fake_evaluator]) == 2
    err = capsys.readouterr().err
    assert "different printer (the built-in default printer; now" in err and "(None)" not in err


@pytest.mark.parametrize("name,expect", [("rrf34", "rrf34"), ("Klipper", "klipper"), ("RRF35", "rrf35")])
def test_tune_accepts_the_firmware_names_export_accepts_in_any_case(tmp_path, capsys, fake_evaluator, name, expect):
    from ringtune.shaping.firmware import FIRMWARES    # what export accepts

    assert expect in FIRMWARES
    out = tmp_path / "out"
    assert main(["tune", "--json", "--out", str(out), "--trials", "3", "--no-baselines", "--firmware", name,
                 "--evaluator", fake_evaluator, "--accel-range", "1000,5000"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["chosen"]["config"]["firmware"] == expect
    if expect == "rrf34":
        assert "M593" in (out / "apply.txt").read_text()


def test_the_firmware_is_the_printer_descriptions_unless_given(tmp_path, capsys, fake_evaluator):
    """A printer described from Marlin's M503 ([current] firmware = "marlin") is tuned for Marlin —
    its export, job and apply.txt in Marlin's commands —, said in a note; --firmware overrides it;
    a description naming none gets Klipper, said too."""
    toml = _printer_toml(tmp_path / "p.toml", current={"source": "m503.txt", "firmware": "marlin", "shaper_x": "zv",
                                                       "freq_x": 40.0, "shaper_y": "zv", "freq_y": 40.0,
                                                       "accel": 1500.0})
    args = ["--trials", "3", "--no-baselines", "--evaluator", fake_evaluator, "--accel-range", "1000,5000"]
    assert main(["tune", "--json", "--printer", str(toml), "--out", str(tmp_path / "a"), *args]) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out)["chosen"]["config"]["firmware"] == "marlin"
    assert "firmware marlin, as the printer description's [current] names it" in captured.err
    assert "M593" in (tmp_path / "a" / "apply.txt").read_text()
    assert main(["tune", "--json", "--printer", str(toml), "--firmware", "klipper", "--out", str(tmp_path / "b"),
                 *args]) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out)["chosen"]["config"]["firmware"] == "klipper" and "[current]" not in captured.err
    assert main(["tune", "--json", "--out", str(tmp_path / "c"), *args]) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out)["chosen"]["config"]["firmware"] == "klipper"
    assert "firmware klipper: the printer description names none" in captured.err


def test_recommend_aims_klippers_rule_at_the_printer_descriptions_firmware(tmp_path, capsys):
    """``recommend --printer`` of a Marlin printer (from its M503) gives Marlin's shapers (ZV only),
    said in a note, as tune does; --firmware overrides."""
    toml = _printer_toml(tmp_path / "p.toml", current={"source": "m503.txt", "firmware": "marlin"})
    assert main(["recommend", "--printer", str(toml), "--json"]) == 0
    captured = capsys.readouterr()
    res = json.loads(captured.out)
    assert res["firmware"] == "marlin" and res["config"]["firmware"] == "marlin"
    assert {res["config"]["shaper_x"], res["config"]["shaper_y"]} <= {"zv", "none"}
    assert "firmware marlin, as the printer description's [current] names it" in captured.err
    assert main(["recommend", "--printer", str(toml), "--firmware", "klipper", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["firmware"] == "klipper"


def test_per_feature_on_searches_the_acceleration_a_job_sets_itself_from_its_seen_walls(tmp_path):
    """A job with its own accelerations (walls 4000 mm/s² above a first layer at 1500, infill 9000)
    on a printer at 25000: --job-accel respect alone keeps them and searches no acceleration;
    --per-feature on overrules them as job.gcode does, so the walls' acceleration is searched, from
    the job's own for what is seen above the first layer (the printer's 0.3 × 25000 starts above it)."""
    from ringtune.agents.tune.job import job_accel_facts
    from ringtune.agents.tune.request import TuneRequest, check_request
    from ringtune.agents.tune.tuning import _space
    from ringtune.envs.printer import load_printer

    # M204 S, which Klipper takes (a lone M204 P it answers with "Invalid M204 command")
    layer = (";TYPE:External perimeter\nG1 X20 Y0 E1 F6000\nG1 X20 Y20 E1\n;TYPE:Internal infill\nM204 S9000\n"
             "G1 X0 Y20 E1 F9000\nG1 X0 Y0 E1\n")
    job = tmp_path / "own.gcode"
    job.write_text("G90\nM83\nM204 S1500\nG1 Z0.2 F600\n" + layer
                   + "".join(f"G1 Z{0.2 * k + 0.2:.1f}\nM204 S4000\n" + layer for k in range(1, 4)))
    toml = _printer_toml(tmp_path / "p.toml")
    toml.write_text(toml.read_text().replace("accel = 3000", "accel = 25000"))
    printer = load_printer(str(toml))
    facts = job_accel_facts(printer, str(job), "respect")
    assert facts.seen_low == 4000.0
    notes = []
    for mode, searched_from in (("auto", None), ("on", 4000.0)):
        req = TuneRequest(printer=str(toml), gcode=str(job), per_feature=mode)
        space, _floor, _why = _space(req, check_request(req), "klipper", printer, facts, notes.append)
        if searched_from is None:
            assert space.accel_fixed and space.accel == (25000.0, 25000.0)
        else:
            assert not space.accel_fixed and space.accel[0] == searched_from and space.per_feature
    assert any("searched from 4000 mm/s², the lowest the job gives what is seen" in n for n in notes)


def test_a_junction_rule_the_firmware_lacks_is_said(tmp_path, capsys, fake_evaluator):
    """The embedded printer corners by Klipper's square_corner_velocity; tuned for Marlin, which has
    no such rule, the tool says so (stderr and the summary's notes) rather than plan silently; for
    Klipper it says nothing of it."""
    from ringtune.shaping.firmware import FIRMWARES

    assert FIRMWARES["marlin"].junction_note("jd") == "" and FIRMWARES["rrf"].junction_note("jd") != ""
    args = ["--trials", "3", "--no-baselines", "--evaluator", fake_evaluator, "--accel-range", "1000,5000"]
    assert main(["tune", "--firmware", "marlin", "--out", str(tmp_path / "m"), *args]) == 0
    err = capsys.readouterr().err
    assert "corners by Klipper's square-corner velocity" in err and "which Marlin" in err
    assert "The printer description corners by Klipper's square-corner velocity" in \
        (tmp_path / "m" / "summary.txt").read_text()
    assert main(["tune", "--firmware", "klipper", "--out", str(tmp_path / "k"), *args]) == 0
    assert "square-corner velocity ([limits]" not in capsys.readouterr().err


def test_readme_same_command_keeps_the_trials_and_the_warm_start_sentence_reads(tmp_path, capsys, fake_evaluator):
    out = tmp_path / "out"
    assert main(["tune", "--out", str(out), "--trials", "7", "--seed", "3", "--evaluator", fake_evaluator]) == 0
    readme = (out / "README.txt").read_text()
    assert f"ringtune tune --trials 7 --seed 3 --out {out} --evaluator {fake_evaluator}" in readme
    summary = (out / "summary.txt").read_text()
    assert "and 0 neighbours" not in summary
    from ringtune.agents.cli.tune import command_line
    import argparse
    ns = argparse.Namespace(**{"trials": 200, "out": "ringtune-out", "job_accel": "replace"})
    assert command_line(ns) == "ringtune tune --job-accel replace"
    # a built-in job by its name, not the installed file's path
    from ringtune.shaping.builtin_jobs import job_path
    assert command_line(argparse.Namespace(gcode=str(job_path("part")))) == "ringtune tune --gcode part"
    assert command_line(argparse.Namespace(gcode="/tmp/my job.gcode")) == "ringtune tune --gcode '/tmp/my job.gcode'"


def test_the_command_that_resumes_carries_every_option_given(tmp_path):
    """README.txt's command (``command_line``) parsed again by tune's own parser gives every option
    as first given: each option of the parser set away from its default at once."""
    import argparse
    import shlex

    from ringtune.agents.cli.tune import add_arguments, command_line

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    job = tmp_path / "my job.gcode"
    job.write_text("G1 X1 Y1 F600\n")
    argv = ["--printer", "p.toml", "--gcode", str(job), "--firmware", "marlin", "--trials", "7",
            "--storage", "sqlite:///s.db", "--study", "s2", "--workers", "2", "--seed", "3", "--out", "o",
            "--pick", "weight", "--weight", "0.5", "--quality", "overshoot", "--max-show-through", "0.04",
            "--max-path-error", "0.2", "--motor-reserve", "30", "--freq-margin", "3", "--shaping-min-freq", "25",
            "--accel-range", "2000,9000", "--job-accel", "replace", "--per-feature", "off", "--backend", "lti",
            "--evaluator", "m:f", "--no-baselines", "--no-refine"]
    given = parser.parse_args(argv)
    defaults = parser.parse_args([])
    assert all(getattr(given, k) != getattr(defaults, k) for k in vars(given)), "an option left at its default"
    words = shlex.split(command_line(given))
    assert words[:2] == ["ringtune", "tune"]
    assert parser.parse_args(words[2:]) == given


@pytest.mark.slow
def test_no_refine_takes_the_studys_choice_as_it_left_it_and_the_same_study_refines_later(tmp_path, capsys,
                                                                                          fake_evaluator):
    """--no-refine: no walk runs (nothing "after the study"), the choice is a trial the study stored
    (its figures those of trials.csv), the summary says so and the command that resumes keeps the flag.
    The same folder without it resumes the same study (no new trial) and runs the walks."""
    import csv

    out = tmp_path / "out"
    args = ["tune", "--json", "--trials", "6", "--out", str(out), "--evaluator", fake_evaluator]
    assert main([*args, "--no-refine"]) == 0
    got, err = capsys.readouterr()
    res = json.loads(got)
    assert res["refined"] is False and res["stop"] is None and res["shaper_ladder"] is None
    assert res["hidden_raise"] is None and "after the study" not in err
    chosen = res["chosen"]
    rows = list(csv.DictReader((out / "trials.csv").open()))
    figures = {"print_time_s": chosen["print_time_s"], **chosen["measures"]}
    same = [r for r in rows if all(float(r[k]) == pytest.approx(figures[k], rel=1e-4, abs=1e-6)
                                   for k in ("print_time_s", "overshoot_mm", "path_error_mm"))
            and float(r["accel"]) == chosen["config"]["accel"] and r["shaper_x"] == chosen["config"]["shaper_x"]]
    assert same, "the choice is not a trial of the study"
    assert "taken as the study left it (--no-refine" in (out / "summary.txt").read_text()
    assert "--no-refine" in (out / "README.txt").read_text()
    assert main(args) == 0
    res2 = json.loads(capsys.readouterr()[0])
    assert res2["completed_now"] == 0 and res2["refined"] is True and res2["stop"] is not None


def test_warm_start_sentence_with_no_neighbour(tmp_path, capsys, fake_evaluator):
    """A recorded recommendation equal to the rule's pick on the model, a firmware without the EI
    family (Marlin: ZV only) and a fixed acceleration leave Klipper's pick alone to start from: the
    sentence says so without "and 0 neighbours"."""
    from ringtune.agents.klipper.baseline import klipper_rule_on_simulated_test
    from ringtune.envs.printer import load_printer

    toml = _printer_toml(tmp_path / "p.toml")
    _, f = klipper_rule_on_simulated_test(load_printer(toml), "marlin")
    toml = _printer_toml(tmp_path / "p.toml", klipper={"shaper_x": f["shaper_x"], "freq_x": f["freq_x"],
                                                       "shaper_y": f["shaper_y"], "freq_y": f["freq_y"],
                                                       "max_accel": 3000.0})
    out = tmp_path / "out"
    assert main(["tune", "--printer", str(toml), "--out", str(out), "--trials", "2", "--accel-range", "3000,3000",
                 "--firmware", "marlin", "--evaluator", fake_evaluator]) == 0
    summary = (out / "summary.txt").read_text()
    assert "The search was warm-started from Klipper's recommendation." in summary
    assert "neighbour" not in summary


def test_identify_then_tune_klipper_baseline_equals_recommend_on_the_same_files(data_dir, tmp_path, capsys,
                                                                               fake_evaluator):
    """Acceptance 14.1 end to end: identify on the real Ender 3 files, tune on that TOML: the
    summary's and JSON's Klipper baseline equal `recommend --accel` on the same files."""
    from ringtune.envs.printer import load_printer

    files = [str(p) for p in sorted((data_dir / "accel" / "klipper_psd" / "bassco_ender3").glob("resonances_*.csv"))]
    toml = tmp_path / "ender3.toml"
    assert main(["identify", *files, "-o", str(toml)]) == 0
    capsys.readouterr()
    if not load_printer(toml).measurement.get("klipper"):
        pytest.skip("identify does not record [measurement.klipper] yet (helper identify)")
    assert main(["recommend", "--json", "--accel", *files]) == 0
    want = json.loads(capsys.readouterr().out)["config"]
    out = tmp_path / "out"
    assert main(["tune", "--json", "--printer", str(toml), "--out", str(out), "--trials", "3", "--evaluator",
                 fake_evaluator]) == 0
    got = json.loads(capsys.readouterr().out)["baselines"]["klipper"]
    assert got["source"] == "measurement"
    for key in ("shaper_x", "freq_x", "shaper_y", "freq_y", "accel"):
        assert got["config"][key] == want[key], key
    summary = (out / "summary.txt").read_text()
    assert (f"X {want['shaper_x']} @ {want['freq_x']:.1f} Hz, Y {want['shaper_y']} @ {want['freq_y']:.1f} Hz"
            in summary and f"accel {want['accel']:.0f} mm/s²" in summary)


def test_pareto_plot_draws_every_ruled_out_point_and_marks_a_baseline_over_a_bound(tmp_path):
    """Ruled-out points far beyond the scale are drawn as arrows at the edge and counted (the legend's
    count is the number of such points, all drawn); a baseline over the path-error bound says so."""
    from ringtune.agents.tune.pareto_plot import plot_front

    front = [_pt(10.0, 0.004, 0.05), _pt(11.0, 0.003, 0.04), _pt(12.0, 0.002, 0.03)]
    far = [_pt(9.0 + i, 0.4 + i, 0.5 + i, feasible=False) for i in range(4)]        # 100× off the scale
    near = [_pt(10.5, 0.0035, 0.12, feasible=False)]
    klipper = _pt(11.5, 0.0035, 0.11, "klipper", feasible=False)
    drawn = plot_front(tmp_path / "p.png", front + far + near, front, front[1], {"klipper": klipper},
                       "overshoot_mm", "t", max_path_error_mm=0.1, baseline_labels={"klipper": "Klipper's rule"})
    assert (tmp_path / "p.png").read_bytes()[:4] == b"\x89PNG"
    assert list(drawn)[:1] == ["overshoot_mm"] and "path_error_mm" in drawn     # no ripple in these points
    assert drawn["overshoot_mm"]["above_scale"] == 4
    assert drawn["path_error_mm"]["above_scale"] == 5        # the near one is over 0.1 mm of path error too
    legend = drawn["overshoot_mm"]["legend"]                 # the large panel's legend names every group
    assert "path error over the bound, excluded (5)" in legend
    assert any(t.startswith("Klipper's rule") and "BREAKS A BOUND (path error over the bound)" in t for t in legend)


def test_pareto_plot_legend_is_short_below_the_points_and_its_rings_are_told_apart(tmp_path):
    """Issue 25: the legend covered points (full paths made it wide) and the two "dominates" rings
    looked the same. The legend now sits below the large panel, paths cut to the file name, each ring
    in its baseline's colour and size on every panel."""
    from ringtune.agents.tune.pareto_plot import STYLE, plot_front

    front = [_pt(10.0, 0.004, 0.05), _pt(11.0, 0.003, 0.04), _pt(12.0, 0.002, 0.03)]
    klipper, current = _pt(11.5, 0.0035, 0.05, "klipper"), _pt(10.2, 0.02, 0.06, "current")
    labels = {"klipper": "Klipper's rule",
              "current": "what the printer runs now (/home/pi/printer_data/config/printer.cfg)"}
    marked = {f"dominates {labels['klipper']}": front[1], f"dominates {labels['current']}": front[0]}
    drawn = plot_front(tmp_path / "p.png", front, front, front[1], {"klipper": klipper, "current": current},
                       "overshoot_mm", "t", max_path_error_mm=0.1, baseline_labels=labels, marked=marked)
    legend = drawn["overshoot_mm"]["legend"]
    assert any(t.startswith("what the printer runs now (printer.cfg): ") for t in legend)
    assert "dominates what the printer runs now (printer.cfg)" in legend
    for panel in drawn.values():
        assert not panel["legend_over_points"]
        assert not any("/" in t for t in panel["legend"]), panel["legend"]
        if panel["missing"]:
            continue
        assert panel["rings"] == {"dominates Klipper's rule": STYLE["klipper"][1],
                                  "dominates what the printer runs now (printer.cfg)": STYLE["current"][1]}
    assert STYLE["klipper"][1] != STYLE["current"][1]
    assert (tmp_path / "p.png").read_bytes()[:4] == b"\x89PNG"
