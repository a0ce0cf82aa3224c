"""``ringtune tune`` / ``ringtune study`` and the report: the output folder, resume through the CLI,
the Pareto bookkeeping, and acceptance 2 on the real simulation of the default printer."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from ringtune.agents.cli.main import main
from ringtune.agents.tune.choice import choose
from ringtune.agents.tune.pareto import Point, pareto_front
from ringtune.shaping.config import TuneConfig

TESTS = Path(__file__).resolve().parent


def _pt(t, q, loss=False, label=""):
    return Point(TuneConfig(), t, q, loss, {}, label)


def test_pareto_front_and_choice_on_a_known_set():
    pts = [_pt(1.0, 5.0, label="a"), _pt(2.0, 2.0, label="b"), _pt(2.5, 2.0, label="dominated"),
           _pt(3.0, 1.0, label="c"), _pt(0.5, 0.1, loss=True, label="infeasible"), _pt(4.0, 0.9, label="d")]
    front = pareto_front(pts)
    assert [p.label for p in front] == ["a", "b", "c", "d"]
    # knee: scaled to 0..1 -> a (0, 1), b (1/3, 0.268), c (2/3, 0.024), d (1, 0): b is closest to (0, 0)
    assert choose(front).label == "b"
    assert choose(front, weight=0.0).label == "a"          # only time counts
    assert choose(front, weight=100.0).label == "d"        # only quality counts
    assert front[1].dominates(pts[2]) and not front[0].dominates(front[1])


def test_path_error_bound_rules_out_corner_cutting_points():
    """A point whose nozzle leaves the path by more than the bound is infeasible, like step loss,
    even when its overshoot is the lowest (heavy smoothing cuts corners inwards)."""
    from ringtune.agents.tune.pareto import judge_path_error

    smooth = Point(TuneConfig(), 1.0, 0.001, False, {"path_error_mm": 0.40}, "3hump_ei low F")
    sharp = Point(TuneConfig(), 1.0, 0.003, False, {"path_error_mm": 0.07}, "ei on the peak")
    assert [p.label for p in pareto_front([smooth, sharp])] == ["3hump_ei low F"]
    for p in (smooth, sharp):
        judge_path_error(p, 0.1)
    assert smooth.too_rough and not smooth.feasible and sharp.feasible
    assert [p.label for p in pareto_front([smooth, sharp])] == ["ei on the peak"]
    judge_path_error(smooth, 0.0)          # 0 = no bound
    assert smooth.feasible


@pytest.fixture
def fake_evaluator(monkeypatch):
    monkeypatch.syspath_prepend(str(TESTS))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(TESTS), os.environ.get("PYTHONPATH", "")]))
    return "study_objective:evaluate"


@pytest.mark.slow
def test_tune_writes_the_output_folder_and_resumes(tmp_path, capsys, fake_evaluator):
    out = tmp_path / "out"
    t0 = time.time()
    rc = main(["tune", "--json", "--out", str(out), "--trials", "10", "--evaluator", fake_evaluator])
    wall = time.time() - t0
    assert rc == 0
    res = json.loads(capsys.readouterr().out)
    # each step's wall-clock time: the steps cover the whole run, which the clock around it holds
    laps = res["timings_s"]
    assert set(laps) == {"setup_s", "study_s", "choice_s", "refine_s", "report_s", "refine_parts"}
    assert sum(v for k, v in laps.items() if k != "refine_parts") == pytest.approx(res["elapsed_s"], abs=0.01)
    assert 0 < res["elapsed_s"] <= wall and min(v for k, v in laps.items() if k != "refine_parts") >= 0
    assert laps["study_s"] > 0 and sum(laps["refine_parts"].values()) <= laps["refine_s"] + 0.01
    for name in ("README.txt", "summary.txt", "pareto.png", "best.json", "apply.txt", "front.csv", "trials.csv"):
        assert (out / name).is_file() and (out / name).stat().st_size > 0, name
    assert (out / "pareto.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    best = TuneConfig.load(out / "best.json")
    assert best.to_dict()["shaper_x"] == res["chosen"]["config"]["shaper_x"]
    assert "SET_INPUT_SHAPER" in (out / "apply.txt").read_text() or "[input_shaper]" in (out / "apply.txt").read_text()
    readme = (out / "README.txt").read_text()
    assert readme.index("summary.txt") < readme.index("pareto.png") < readme.index("apply.txt")
    summary = (out / "summary.txt").read_text()
    assert "Klipper's rule" in summary and "no shaping" in summary and "CHOSEN" in summary
    assert set(res["baselines"]) == {"klipper", "none"} and res["trials"] == 10
    # the --json keys tune.py documents as stable
    assert set(res) == {"out", "trials", "front_size", "settled_on_model", "quality", "max_path_error_mm", "motor_reserve",
                        "judged_on", "max_show_through_mm", "freq_margin", "refined", "resolution", "chosen",
                        "baselines", "vs_baselines",
                        "versus", "stop", "shaper_ladder", "hidden_raise", "per_feature", "dominates_klipper", "dominates_current", "accel", "job_accel",
                        "plot_arrows", "files", "storage", "study", "completed_now", "interrupted", "elapsed_s",
                        "timings_s"}
    assert set(res["chosen"]) == {"config", "print_time_s", "quality_mm", "path_error_mm", "overshoot_mm",
                                  "motor_load", "measures", "chosen_by", "against", "held_to", "why", "rewrite_jobs"}
    assert set(res["accel"]) == {"range", "searched", "basis", "chosen", "stopped_by", "headroom", "defaults",
                                 "binding"}
    assert set(res["vs_baselines"]["klipper"]) == {"baseline", "faster_s", "faster_pct", "better_mm",
                                                   "better_pct", "dominates", "metrics", "path_error_better_mm",
                                                   "path_error_better_pct"}
    assert set(res["vs_baselines"]["klipper"]["metrics"]) == {"print_time_s", "overshoot_mm", "path_error_mm",
                                                              "feasible"}
    assert set(res["files"]) == {"readme", "summary", "plot", "best", "apply", "front", "trials"}
    assert len((out / "front.csv").read_text().strip().splitlines()) == res["front_size"] + 1
    # the same command again, asking for more trials, resumes: 10 kept, 4 new
    rc = main(["tune", "--json", "--out", str(out), "--trials", "14", "--evaluator", fake_evaluator])
    res2 = json.loads(capsys.readouterr().out)
    assert rc == 0 and res2["trials"] == 14 and res2["completed_now"] == 4
    # a different firmware in the same folder is refused with one clear line
    rc = main(["tune", "--out", str(out), "--trials", "20", "--firmware", "rrf", "--evaluator", fake_evaluator])
    assert rc == 2 and "different firmware" in capsys.readouterr().err


@pytest.mark.slow
def test_max_path_error_is_a_constraint_of_the_study(tmp_path, capsys, fake_evaluator):
    """Every trial carries the constraint path_error_mm − bound; the front holds only trials within
    the bound; the bound can be changed when the results are read again (resume)."""
    import optuna

    from ringtune.agents.tune.storage import make_storage

    out = tmp_path / "out"
    argv = ["tune", "--json", "--out", str(out), "--trials", "25", "--evaluator", fake_evaluator,
            "--max-path-error", "0.004"]
    assert main(argv) == 0
    res = json.loads(capsys.readouterr().out)
    st = optuna.load_study(study_name="ringtune", storage=make_storage(res["storage"]))
    trials = [t for t in st.trials if t.state == optuna.trial.TrialState.COMPLETE]
    for t in trials:
        assert t.constraints["path_error"] == pytest.approx(t.user_attrs["metrics"]["path_error_mm"] - 0.004)
    within = sum(t.user_attrs["metrics"]["path_error_mm"] <= 0.004 and not t.user_attrs["metrics"]["step_loss"]
                 for t in trials)
    assert 0 < within < len(trials)
    front = [r.split(",") for r in (out / "front.csv").read_text().strip().splitlines()]
    col = front[0].index("path_error_mm")
    assert front[1:] and all(float(r[col]) <= 0.004 for r in front[1:])
    assert main(argv[:-1] + ["0"]) == 0          # resumed, judged without a bound: a wider front
    loose = json.loads(capsys.readouterr().out)
    assert loose["max_path_error_mm"] == 0 and loose["completed_now"] == 0
    assert main(["tune", "--max-path-error", "-1", "--out", str(out)]) == 2


@pytest.mark.slow
def test_a_study_judged_before_the_damped_twins_is_not_resumed_under_them(tmp_path, capsys, fake_evaluator):
    """A study stored before the twins' damping was recorded was judged with the twins' damping
    ratios unchanged (×1): resuming it under today's ×0.75 would mix two judgements in one front, so
    it is refused with one line; with --freq-margin 0 (no twins) the same study resumes."""
    import optuna

    from ringtune.agents.tune.storage import make_storage

    out = tmp_path / "out"
    argv = ["tune", "--json", "--out", str(out), "--trials", "8", "--evaluator", fake_evaluator, "--no-baselines"]
    assert main(argv) == 0
    res = json.loads(capsys.readouterr().out)
    st = optuna.load_study(study_name="ringtune", storage=make_storage(res["storage"]))
    assert st.user_attrs["settings"]["twin_damping"] == 0.75
    st.set_user_attr("settings", {k: v for k, v in st.user_attrs["settings"].items() if k != "twin_damping"})
    assert main(argv + ["--trials", "10"]) == 2
    assert "twins' damping ratios ×1; now twins' damping ratios ×0.75" in capsys.readouterr().err

    zero = tmp_path / "zero"
    argv0 = ["tune", "--json", "--out", str(zero), "--evaluator", fake_evaluator, "--no-baselines", "--freq-margin", "0"]
    assert main(argv0 + ["--trials", "8"]) == 0
    st0 = optuna.load_study(study_name="ringtune", storage=make_storage(json.loads(capsys.readouterr().out)["storage"]))
    st0.set_user_attr("settings", {k: v for k, v in st0.user_attrs["settings"].items() if k != "twin_damping"})
    assert main(argv0 + ["--trials", "10"]) == 0
    assert json.loads(capsys.readouterr().out)["completed_now"] == 2


@pytest.mark.slow
def test_ctrl_c_on_tune_then_rerun_resumes(tmp_path, fake_evaluator):
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "ringtune.agents.cli.main", "tune", "--out", str(out), "--trials", "14", "--no-baselines",
           "--evaluator", fake_evaluator, "--json"]
    env = dict(os.environ, RINGTUNE_TEST_SLEEP="0.15")
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    journal = out / "study.journal"
    t0 = time.time()
    while _complete_in(journal) < 3:
        assert proc.poll() is None and time.time() - t0 < 60
        time.sleep(0.1)
    proc.send_signal(signal.SIGINT)
    stdout, _ = proc.communicate(timeout=60)
    assert proc.returncode == 130
    first = json.loads(stdout)
    assert first["interrupted"] and 3 <= first["trials"] < 14
    done = subprocess.run(cmd, env=dict(os.environ), capture_output=True, text=True, timeout=120)
    second = json.loads(done.stdout)
    assert done.returncode == 0 and second["trials"] == 14
    assert second["completed_now"] == 14 - first["trials"]
    rows = (out / "trials.csv").read_text().strip().splitlines()[1:]
    configs = [r.split(",", 2)[2] for r in rows]          # everything after label, time
    assert len(rows) == 14 and len(set(configs)) == 14


def _complete_in(journal: Path) -> int:
    import optuna

    from ringtune.agents.tune.storage import make_storage

    if not journal.exists():
        return 0
    try:
        st = optuna.load_study(study_name="ringtune", storage=make_storage(f"journal:{journal}"))
    except KeyError:
        return 0
    return sum(1 for t in st.get_trials(deepcopy=False) if t.state.name == "COMPLETE")


def test_study_command_frequency_error_sweep(tmp_path, capsys):
    png = tmp_path / "fe.png"
    rc = main(["study", "--json", "--factor", "freq-error", "--values", "0,0.3", "--shapers", "none,zv,mzv",
               "-o", str(png)])
    res = json.loads(capsys.readouterr().out)
    assert rc == 0 and png.is_file() and Path(res["csv"]).is_file()
    s = res["shapers"]
    # nothing to mistune without a shaper; print time does not depend on the shaper frequency
    assert s["none"]["quality_mm"][0] == pytest.approx(s["none"]["quality_mm"][1])
    assert s["zv"]["print_time_s"][0] == pytest.approx(s["zv"]["print_time_s"][1])
    # a tuned shaper beats no shaping; ZV (narrowest band) suffers from a 30 % error
    assert s["zv"]["quality_mm"][0] < 0.5 * s["none"]["quality_mm"][0]
    assert s["mzv"]["quality_mm"][0] < 0.5 * s["none"]["quality_mm"][0]
    assert s["zv"]["quality_mm"][1] > 1.5 * s["zv"]["quality_mm"][0]


@pytest.mark.slow
def test_default_printer_choice_is_no_worse_than_klippers_recommendation_on_what_is_seen(tmp_path, capsys, data_dir):
    """Issue 14's acceptance 2 as issue 21 judges (40 trials on issue 14's built-in print, kept in
    tests/data: a square, a zigzag and a circle at 80-100 mm/s): the choice, re-simulated from
    scratch as the study judges (the printer and its ±5 % twins), has no visible measure worse than
    Klipper's recorded pick (1 µm or 5 % for distances, 1 point or 5 % for extrusion) and is no
    slower; any front point the report says dominates it really does. (The overshoot-and-path-error
    front of issue 14 dominated it at 40 trials; judged by ripple, corners and extrusion together,
    40 trials here find nothing faster and the measured stop says why.)"""
    out = tmp_path / "out"
    job = data_dir / "gcode" / "ringtune_builtin_2025" / "test_print.gcode"
    rc = main(["tune", "--json", "--out", str(out), "--trials", "40", "--workers", "1", "--seed", "2",
               "--gcode", str(job)])
    res = json.loads(capsys.readouterr().out)
    assert rc == 0
    from ringtune.envs.evaluate import evaluate_many

    assert res["freq_margin"] == 0.05
    k = res["baselines"]["klipper"]
    cfgs = [TuneConfig.from_dict(res["chosen"]["config"]), TuneConfig.from_dict(k["config"])]
    if res["dominates_klipper"]:
        cfgs.append(TuneConfig.from_dict(res["dominates_klipper"]["config"]))
    mine, klip, *dom = evaluate_many(cfgs, None, str(job), freq_margin=0.05)
    assert not mine.step_loss and not klip.step_loss

    def val(m, key):                  # a job's figure, or a class's own ("outer_wall:ripple_mm")
        cls, _, k = key.rpartition(":")
        return m.features[cls][k] if cls else getattr(m, k)

    def worse(a, b, key):
        big = max(abs(val(a, key)), abs(val(b, key)))
        tol = max(1.0, 0.05 * big) if key.endswith("_pct") else max(1e-3, 0.05 * big)
        return val(a, key) - val(b, key) > tol

    keys = ("ripple_mm", "ripple_p90_mm", "corner_in_mm", "corner_out_mm", "extrusion_over_pct", "extrusion_under_pct")
    seen = ("outer_wall", "top_surface", "bridge_overhang", "other")      # each visible class on its own too
    for p in [mine, *dom]:
        assert not any(worse(p, klip, key) for key in keys)
        assert not any(worse(p, klip, f"{c}:{k}") for c in seen if c in p.features and c in klip.features
                       for k in keys if k != "ripple_p90_mm")
        assert p.print_time_s <= klip.print_time_s * 1.005
    summary = (out / "summary.txt").read_text()
    assert "WHAT A PERSON SEES" in summary and res["stop"]["sentence"] in summary
    if res["stop"]["kind"] == "measure":      # the stop's step, re-simulated, is worse on that measure
        up, = evaluate_many([TuneConfig.from_dict(res["stop"]["config"])], None, str(job), freq_margin=0.05)
        assert worse(up, klip, res["stop"]["key"])


def test_study_command_mass_and_accel_sweeps(tmp_path, capsys):
    """`ringtune study --factor mass|accel`: print mass on the bed detunes shapers fitted to the empty
    bed (worse quality), and a higher acceleration never makes the print slower."""
    rc = main(["study", "--json", "--factor", "mass", "--values", "0,1", "--shapers", "zv,mzv", "--backend", "lti",
               "-o", str(tmp_path / "mass.png")])
    s = json.loads(capsys.readouterr().out)["shapers"]
    assert rc == 0
    for name in ("zv", "mzv"):
        assert s[name]["quality_mm"][1] > 1.5 * s[name]["quality_mm"][0]
    rc = main(["study", "--json", "--factor", "accel", "--values", "1000,3000,6000", "--shapers", "none,mzv",
               "--backend", "lti", "-o", str(tmp_path / "acc.png")])
    res = json.loads(capsys.readouterr().out)
    assert rc == 0 and res["unit"] == "mm/s²" and (tmp_path / "acc.png").is_file()
    for name in ("none", "mzv"):
        t = res["shapers"][name]["print_time_s"]
        assert t[0] > t[1] > t[2]
        assert res["shapers"][name]["quality_mm"][2] > res["shapers"][name]["quality_mm"][0]
