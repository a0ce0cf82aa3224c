"""``ringtune simulate``: stable JSON keys, consistency with evaluate(), plots, one-line errors."""

from __future__ import annotations

import json
import math

import pytest

from ringtune.agents.cli.main import main
from ringtune.envs.evaluate import evaluate
from ringtune.envs.whole_job import whole_job_metrics
from ringtune.shaping.testprints import builtin_test_gcode
from ringtune.shaping.config import TuneConfig

METRIC_KEYS = {"print_time_s", "path_error_mm", "overshoot_mm", "ringing_mm", "peak_accel", "step_loss", "motor_load",
               "ripple_mm", "ripple_p90_mm", "corner_in_mm", "corner_out_mm", "extrusion_over_pct",
               "extrusion_under_pct", "e_lag_mm", "show_through_mm"}
NESTED_KEYS = {"features", "extrusion_if_synced"}


def run_cli(argv, capsys):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def test_json_matches_evaluate_and_shaping_helps(capsys):
    code, out, _ = run_cli(["simulate", "--json", "--backend", "lti", "--shaper", "mzv",
                            "--freq", "45.5,38.9", "--damping", "0.1", "--freq-margin", "0"], capsys)
    assert code == 0
    res = json.loads(out)
    assert set(res) == {"printer", "job", "backend", "config", "metrics", "freq_margin", "judgement",
                        "variants", "windows", "plots", "e_timing", "e_sync",
                        "job_shapers", "job_accel", "binding", "baselines", "versus"}
    assert set(res["metrics"]) == METRIC_KEYS | NESTED_KEYS and res["plots"] == []
    assert res["e_timing"] == "neither" and res["e_sync"] == ""   # Klipper: centred X/Y, E unshaped
    cfg = TuneConfig(shaper_x="mzv", shaper_y="mzv", freq_x=45.5, freq_y=38.9, damping_x=0.1, damping_y=0.1)
    m = evaluate(cfg, backend="lti")
    for key in METRIC_KEYS:
        assert res["metrics"][key] == pytest.approx(getattr(m, key))
    # the job's figures are the worst window's
    assert res["metrics"]["overshoot_mm"] == pytest.approx(max(w["overshoot_mm"] for w in res["windows"]))
    code, out, _ = run_cli(["simulate", "--json", "--backend", "lti", "--freq-margin", "0"], capsys)  # off
    off = json.loads(out)["metrics"]
    assert off["print_time_s"] == pytest.approx(res["metrics"]["print_time_s"])
    assert off["overshoot_mm"] > 5 * res["metrics"]["overshoot_mm"]
    assert off["ringing_mm"] > 5 * res["metrics"]["ringing_mm"]


def test_whole_job_puts_the_windows_beside_all_of_the_job(capsys):
    """--whole-job: the configuration and Klipper's pick on the windows and over the whole job (the
    printer as modelled, the exact linear backend), each verdict the reports' rule (1 µm or 5 %
    for distances, 1 point or 5 % for extrusion) applied here to the printed figures."""
    code, out, _ = run_cli(["simulate", "--json", "--shaper", "mzv", "--freq", "45.5,38.9", "--damping", "0.1",
                            "--accel", "6000", "--whole-job"], capsys)
    assert code == 0
    check = json.loads(out)["whole_job"]
    assert set(check) == {"where", "seconds", "baseline", "measures", "differ", "worse", "outer_wall_worst"}
    assert check["baseline"]
    cfg = TuneConfig(shaper_x="mzv", shaper_y="mzv", freq_x=45.5, freq_y=38.9, damping_x=0.1, damping_y=0.1,
                     accel=6000.0)
    whole, windows = whole_job_metrics(cfg), evaluate(cfg, backend="lti")
    ripple = check["measures"]["ripple_mm"]
    assert ripple["whole"][0] == pytest.approx(whole.ripple_mm) and ripple["windows"][0] == pytest.approx(windows.ripple_mm)
    assert check["measures"]["outer_wall:corner_in_mm"]["whole"][0] == pytest.approx(
        whole.features["outer_wall"]["corner_in_mm"])

    def rule(k, mine, theirs):
        tol = max(0.05 * max(mine, theirs), 1.0 if k.endswith("_pct") else 1e-3)
        return "worse" if mine - theirs > tol else "better" if theirs - mine > tol else "same"
    for k, v in check["measures"].items():
        assert v["verdict_windows"] == rule(k, *v["windows"]) and v["verdict_whole"] == rule(k, *v["whole"]), k
    assert check["worse"] == [k for k, v in check["measures"].items() if v["verdict_whole"] == "worse"]
    assert check["differ"] == [k for k, v in check["measures"].items() if v["verdict_windows"] != v["verdict_whole"]]
    # where the outer wall's worst corners are: the whole job's figure, at a corner of the move on the
    # line named (the built-in print's text: the move from the line before's X/Y to its own)
    lines = builtin_test_gcode().splitlines()
    for k, at in check["outer_wall_worst"].items():
        assert at["value"] == pytest.approx(check["measures"][k]["whole"][0])
        ends = [[float(w[1:]) for w in lines[n - 1].split() if w[0] in "XY"] for n in (at["line"] - 1, at["line"])]
        assert min(math.dist((at["x"], at["y"]), p) for p in ends) < 1.0, (k, at, ends)
    code, text, _ = run_cli(["simulate", "--shaper", "mzv", "--freq", "45.5,38.9", "--accel", "6000",
                             "--whole-job", "--no-baselines"], capsys)
    assert code == 0 and "over the whole job" in text and "no Klipper's pick to compare" in text


@pytest.mark.slow
def test_config_file_and_plots(tmp_path, capsys):
    cfg = tmp_path / "best.json"
    TuneConfig(firmware="rrf", shaper_x="zvd", shaper_y="zvd", freq_x=45.0, freq_y=40.0,
               freq_limit_hz=15.0).save(cfg)
    code, out, _ = run_cli(["simulate", "--backend", "lti", "--config", str(cfg),
                            "--plot", str(tmp_path / "plots")], capsys)
    assert code == 0 and "print time" in out
    for name in ("path.png", "ringing.png", "accel.png"):
        f = tmp_path / "plots" / name
        assert f.is_file() and f.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("argv,where", [
    (["--shaper", "zv"], "--freq"),
    (["--shaper", "zv", "--freq", "40", "--firmware", "rrf"], "--shaper"),
    (["--gcode", "no-such.gcode"], "no-such.gcode"),
    (["--freq", "40,x", "--shaper", "zv"], "--freq"),
    (["--printer", "no-such.toml"], "no-such.toml"),
])
def test_bad_input_is_one_line_and_exit_2(argv, where, capsys):
    code, out, err = run_cli(["simulate", "--backend", "lti"] + argv, capsys)
    lines = [ln for ln in err.splitlines() if "error" in ln]
    assert code == 2 and len(lines) == 1 and where in lines[0] and "Traceback" not in err


def test_plot_folder_that_cannot_be_made_fails_before_simulating(tmp_path, capsys, monkeypatch):
    import ringtune.envs.evaluate as evaluate_module

    def no_simulation(*a, **k):
        raise AssertionError("simulated before checking --plot")

    monkeypatch.setattr(evaluate_module, "simulate_batch", no_simulation)
    blocker = tmp_path / "plots"
    blocker.write_text("a file, not a folder")
    code, out, err = run_cli(["simulate", "--backend", "lti", "--plot", str(blocker / "sub")], capsys)
    lines = [ln for ln in err.splitlines() if "error" in ln]
    assert code == 2 and len(lines) == 1 and "--plot" in lines[0] and "Traceback" not in err


def test_the_accelerometer_plot_is_in_mm_per_s2_as_every_text(tmp_path, monkeypatch):
    """Issue 25: the plot was in m/s² while every text says mm/s²: the curves are the values given."""
    from types import SimpleNamespace

    import numpy as np

    import ringtune.envs.plots as plots

    seen = {}

    def keep(plt, fig, out, title="", data=None):
        seen["axes"] = [(ax.get_ylabel(), [line.get_ydata() for line in ax.get_lines()]) for ax in fig.axes]
        plt.close(fig)
        return out

    monkeypatch.setattr(plots, "_save", keep)
    t = np.linspace(0.0, 0.1, 11)
    sim = SimpleNamespace(t=t, accel_sensor=np.column_stack([3000 * t, -2000 * t, 0 * t]),
                          head_accel=np.column_stack([4000 * np.ones_like(t), 3000 * np.ones_like(t)]))
    plots.plot_accel(sim, tmp_path / "a.png")
    (lab0, lines0), (lab1, lines1) = seen["axes"]
    assert lab0 == lab1 == "acceleration (mm/s²)"
    assert np.allclose(lines0[0], 3000 * t) and np.allclose(lines1[0], 5000.0)


@pytest.mark.parametrize("firmware, shaper, said", [("marlin", "zv", True), ("rrf", "zvd", True),
                                                    ("klipper", "zv", False)])
def test_a_firmware_without_the_printers_corner_rule_is_said(firmware, shaper, said, capsys):
    """The embedded printer corners by Klipper's square_corner_velocity; simulating it for Marlin or
    RepRapFirmware says the corners are planned that way (as tune says), for Klipper nothing."""
    assert main(["simulate", "--firmware", firmware, "--shaper", shaper, "--freq", "50", "--no-baselines",
                 "--freq-margin", "0", "--json"]) == 0
    err = capsys.readouterr().err
    assert ("corners by Klipper's square-corner velocity" in err) is said
