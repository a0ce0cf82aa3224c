"""``simulate`` runs a job as the printer would: the job's own shaper commands change the shaping
from where they stand (a ringing test print's ``SET_INPUT_SHAPER SHAPER_FREQ_X=0`` turns it off
even on a printer whose ``[current]`` section shapes), those of another firmware (a Marlin job's
``M593``, which Klipper does not have) change nothing and are named, and its own acceleration
commands stand unless replaced; every TuneConfig key has its option, so ``--config best.json`` and
the same values as options agree."""

from __future__ import annotations

import contextlib
import io
import json

import numpy as np
import pytest

from ringtune.agents.cli.main import main
from ringtune.envs.printer import load_printer
from ringtune.envs.trace import trace_job
from test_ripples_closed_loop import LAYER_Z, SIDE, SPEED, caliper_measure, dominant_mode, load_trace, wall_profile

CURRENT = '\n[current]\nsource = "printer.cfg"\nfirmware = "klipper"\nshaper_x = "ei"\nfreq_x = 45.5\n' \
          'damping_x = 0.1\nshaper_y = "mzv"\nfreq_y = 38.9\ndamping_y = 0.1\naccel = 3000\n'


@pytest.fixture(scope="module")
def ripple_run(tmp_path_factory):
    from importlib import resources

    d = tmp_path_factory.mktemp("ripples")
    toml = d / "ender3-current.toml"
    toml.write_text((resources.files("ringtune.envs.data") / "ender3.toml").read_text() + CURRENT)
    g, trace = d / "ripples.gcode", d / "trace.csv"
    for fw in ("marlin", "klipper"):
        gf = d / f"ripples-{fw}.gcode"
        assert main(["testprint", "ringing", "--firmware", fw, "--no-shaping", "--height", str(LAYER_Z),
                     "--side", str(SIDE), "--printer", str(toml), "-o", str(gf)]) == 0
    g = d / "ripples-klipper.gcode"          # the [current] firmware's own commands
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert main(["simulate", "--printer", str(toml), "--gcode", str(g), "--trace", str(trace),
                     "--backend", "lti", "--freq-margin", "0", "--json"]) == 0
    res = json.loads(buf.getvalue())
    return toml, g, load_trace(trace), d, res


def test_the_ripple_print_shows_ripples_on_a_printer_with_a_current_section(ripple_run, capsys):
    toml, g, tr, _, res = ripple_run
    printer = load_printer(str(toml))
    # the job's SET_INPUT_SHAPER SHAPER_FREQ_X=0 SHAPER_FREQ_Y=0 turned shaping off: from there on (its
    # last change, plus the [current] shaper's tail) the motors follow the G-code path itself
    off = res["job_shapers"][-1]
    assert off["config"]["shaper_x"] == off["config"]["shaper_y"] == "none"
    moving = tr["t"] > off["time"] + 0.1
    assert np.max(np.abs(tr["x_shaped"][moving] - tr["x_cmd"][moving])) < 1e-9
    assert np.max(np.abs(tr["y_shaped"][moving] - tr["y_cmd"][moving])) < 1e-9
    # ripples as a person measures them, at the spacing of the printer's dominant mode
    for ax in ("x", "y"):
        spacing, _ratio = caliper_measure(*wall_profile(tr, ax))
        f = SPEED / spacing
        assert abs(f / dominant_mode(printer, ax).freq - 1) < 0.03, (ax, f)
    # the printer's own shaper ([current]), had the job's commands been ignored, flattens them
    ignored = trace_job(printer.current and _current_config(printer), printer, str(g), "lti", job_shapers=False)
    names = ("t", "x_cmd", "y_cmd", "z", "extruding", "x_shaped", "y_shaped", "x_nozzle", "y_nozzle", "window")
    flat = {n: ignored[:, i] for i, n in enumerate(names)}
    for ax in ("x", "y"):          # peak-to-peak across the wall, past the corner, before the next one
        shown, hidden = (_ripple(wall_profile(t, ax)) for t in (tr, flat))
        assert shown > 3 * hidden, (ax, shown, hidden)


def _ripple(profile) -> float:
    pos, dev = profile
    mid = (pos > 2.0) & (pos < SIDE / 2)
    return float(np.ptp(dev[mid]))


def _current_config(printer):
    from ringtune.agents.tune.baselines import current_config

    return current_config(printer, "klipper")[0]


def test_simulate_says_it_applies_the_jobs_shaper_commands(ripple_run, capsys):
    toml, g, _, _, _ = ripple_run
    assert main(["simulate", "--printer", str(toml), "--gcode", str(g), "--backend", "lti",
                 "--freq-margin", "0", "--json"]) == 0
    cap = capsys.readouterr()
    res = json.loads(cap.out)
    assert "the job's own shaper commands are applied" in cap.err and "SET_INPUT_SHAPER SHAPER_FREQ_X=0" in cap.err
    assert [c["config"]["shaper_x"] for c in res["job_shapers"]][-1] == "none"
    assert res["job_shapers"][-1]["config"]["shaper_y"] == "none"


def test_another_firmwares_shaper_commands_change_nothing_and_are_named(ripple_run, capsys):
    """The same print sliced for Marlin (M593 X F0, M593 Y F0) on the Klipper printer: Klipper has no
    M593, so the [current] shaper stays on, said with the lines; on Marlin the same file turns it off."""
    toml, _, _, d, _ = ripple_run
    g = d / "ripples-marlin.gcode"
    lines = [n for n, ln in enumerate(g.read_text().splitlines(), 1) if ln.startswith("M593")]
    assert len(lines) == 2
    assert main(["simulate", "--printer", str(toml), "--gcode", str(g), "--backend", "lti",
                 "--freq-margin", "0", "--json"]) == 0
    cap = capsys.readouterr()
    assert json.loads(cap.out)["job_shapers"] == []
    assert f"Klipper has no M593: the job's M593 ×2 (first on line {lines[0]}) change nothing there" in cap.err
    assert main(["simulate", "--printer", str(toml), "--gcode", str(g), "--firmware", "marlin", "--shaper", "zv",
                 "--freq", "45.5,38.9", "--no-baselines", "--backend", "lti", "--freq-margin", "0", "--json"]) == 0
    cap = capsys.readouterr()
    last = json.loads(cap.out)["job_shapers"][-1]["config"]
    assert last["shaper_x"] == last["shaper_y"] == "none" and "has no M593" not in cap.err


def test_klipper_set_input_shaper_in_a_job_is_applied_too(ripple_run, capsys):
    toml, _, _, d, _ = ripple_run
    g = d / "ripples-klipper.gcode"
    assert "SHAPER_FREQ_X=0" in g.read_text()
    assert main(["simulate", "--printer", str(toml), "--gcode", str(g), "--backend", "lti",
                 "--freq-margin", "0", "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    last = res["job_shapers"][-1]["config"]
    assert last["shaper_x"] == last["shaper_y"] == "none"


def test_every_tuneconfig_key_on_the_command_line_matches_the_file(tmp_path, capsys):
    cfg = {"firmware": "marlin", "shaper_x": "zv", "shaper_y": "zv", "freq_x": 45.5, "freq_y": 38.9,
           "damping_x": 0.07, "damping_y": 0.12, "freq_limit_hz": 30.0, "min_speed_factor": 0.4,
           "freq_limit_method": "nophead", "accel": 2500.0, "max_accel_x": 2500.0, "max_accel_y": 1800.0,
           "job_accel": "respect"}
    f = tmp_path / "best.json"
    f.write_text(json.dumps(cfg))
    assert main(["simulate", "--config", str(f), "--backend", "lti", "--freq-margin", "0", "--json"]) == 0
    from_file = json.loads(capsys.readouterr().out)
    assert main(["simulate", "--firmware", "marlin", "--shaper", "zv", "--freq", "45.5,38.9", "--damping",
                 "0.07,0.12", "--freq-limit", "30", "--min-speed-factor", "0.4", "--freq-limit-method",
                 "nophead", "--accel", "2500", "--max-accel", "2500,1800", "--job-accel", "respect",
                 "--backend", "lti", "--freq-margin", "0", "--json"]) == 0
    from_options = json.loads(capsys.readouterr().out)
    assert from_options["config"] == from_file["config"]
    assert from_options["metrics"] == from_file["metrics"]
    assert from_file["job_accel"] == "respect"
