"""Issue 25: the files and mistakes real users bring, across the commands. Each case: the command
line, the exit status, the words its one stderr line must contain; a refusal (exit 2) prints that
one line and nothing before it, no traceback, and writes nothing (the folder it runs in is
unchanged). A few inputs are accepted (exit 0) with the warning that says what the tool decided.

Placeholders: {d} the real data folder (tests/data), {t} the case's own folder (the working
directory), which holds the prepared files below."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from ringtune.agents.cli.main import main
from ringtune.envs.printer import printer_from_dict
from ringtune.envs.sim import resonance_test

E3 = "{d}/accel/klipper_psd/bassco_ender3"
X, Y = f"{E3}/resonances_x_20210821_152037.csv", f"{E3}/resonances_y_20210630_230110.csv"
CFG = "{d}/klipper_config/ender3/printer.cfg"
RIP = ["--ripples", "X=2.2,Y=2.6", "--speed", "100"]

RRF_CONFIG = """; Configuration file for Duet 3 (firmware version 3.5)
G90
M550 P"My Printer"
M669 K1
M584 X0.0 Y0.1 Z0.2 E0.3
M569 P0.0 S1
M92 X80.00 Y80.00 Z400.00 E420.00
M203 X30000.00 Y30000.00 Z180.00 E1200.00
M201 X3000.00 Y3000.00 Z20.00 E250.00
M906 X800 Y800 Z800 E800 I30
M593 P"zvd" F40.5 S0.1
"""
#: an M503 answer as OctoPrint's serial log saves it (timestamps, Send:/Recv:)
M503_HOST = """2024-03-02 10:11:12,345 - Send: M503
2024-03-02 10:11:12,400 - Recv: echo:; Steps per unit:
2024-03-02 10:11:12,401 - Recv: echo: M92 X80.00 Y80.00 Z400.00 E93.00
2024-03-02 10:11:12,403 - Recv: echo:  M203 X500.00 Y500.00 Z5.00 E25.00
2024-03-02 10:11:12,404 - Recv: echo:  M201 X500.00 Y500.00 Z100.00 E5000.00
2024-03-02 10:11:12,405 - Recv: echo:  M204 P500.00 R500.00 T1000.00
2024-03-02 10:11:12,406 - Recv: echo:  M593 X F40.00 D0.15
2024-03-02 10:11:12,407 - Recv: ok
"""
#: and as Pronterface / Repetier show it
M503_CONSOLE = """>>> M503
SENDING:M503
[12:00:01] echo: M92 X80.00 Y80.00 Z400.00 E93.00
12:00:01.234 : echo:  M203 X500.00 Y500.00 Z5.00 E25.00
12:00:01.240 : echo:  M204 P1500.00 R1500.00 T3000.00
"""
QUERY = "Send: ACCELEROMETER_QUERY\nRecv: // adxl345 values (x, y, z): 470.719200, 941.438400, 9728.883664\n"


def _tower(t):
    assert main(["testprint", "ringing", "--firmware", "marlin", "--bands", "30:70:5", "-o", str(t / "tower.gcode")]) == 0


def _other_state(t):
    """A second resonance test of the same state (another noise draw), named as a loaded test."""
    pr = printer_from_dict({"name": "p", "x": {"mass": 0.6, "modes": [{"freq": 52.0, "damping": 0.06}]},
                            "y": {"mass": 1.2, "modes": [{"freq": 38.0, "damping": 0.08}]}})
    for name, seed in (("resonances_x_base.csv", 3), ("resonances_x_loaded.csv", 4)):
        f, p = resonance_test(pr, "x", rng=np.random.default_rng(seed))
        rows = np.column_stack([f, p, np.full_like(p, 50.0), np.full_like(p, 50.0), p + 100.0])
        np.savetxt(t / name, rows, fmt="%.6g", delimiter=",", header="freq,psd_x,psd_y,psd_z,psd_xyz", comments="")


def _files(t, d):
    (t / "config.g").write_text(RRF_CONFIG)
    (t / "config_calls.g").write_text(RRF_CONFIG.replace('M593 P"zvd" F40.5 S0.1\n', 'M98 P"shaper.g"\n'))
    (t / "m503_host.txt").write_text(M503_HOST)
    (t / "m503_console.txt").write_text(M503_CONSOLE)
    (t / "query.txt").write_text(QUERY)
    (t / "empty.csv").write_text("")
    shutil.copy(d / "accel/klipper_psd/bassco_ender3/resonances_x_20210821_152037.csv", t / "resonances_x_copy.csv")
    for name in ("resonances_axis=1.000,1.000,0.000_a.csv", "resonances_axis=1.000,-1.000,0.000_a.csv"):
        shutil.copy(d / "accel/klipper_psd/bassco_voron_v24/resonances_x_20230306_224517.csv", t / name)   # one copied
    (t / "resonances_x_semicolons.csv").write_text(        # a European spreadsheet's re-save
        (d / "accel/klipper_psd/bassco_ender3/resonances_x_20210821_152037.csv").read_text().replace(",", ";"))
    (t / "binary.csv").write_bytes(bytes(range(256)) * 8)
    (t / "folder").mkdir()
    shutil.copy(d / "accel/klipper_psd/bassco_voron_v24/resonances_x_20230306_224517.csv", t / "voron_sweep_1.csv")
    shutil.copy(d / "accel/klipper_psd/bassco_ender3/resonances_x_20210821_152037.csv",
                t / "resonances_z_20210821_152037.csv")
    (t / "best.json").write_text(json.dumps({"firmware": "klipper", "shaper_x": "ei", "shaper_y": "mzv",
                                             "freq_x": 51.4, "freq_y": 46.6, "accel": 4800}))
    (t / "wild.json").write_text(json.dumps({"firmware": "klipper", "shaper_x": "mzv", "shaper_y": "mzv",
                                             "freq_x": 2500, "freq_y": 46.6, "accel": 4800}))
    (t / "broken.json").write_text("{\"firmware\": \"klipper\", ")
    (t / "bad_mass.toml").write_text('name = "b"\n[x]\nmass = -1\nmodes = [{ freq = 40, damping = 0.1 }]\n'
                                     '[y]\nmodes = [{ freq = 40, damping = 0.1 }]\n')
    (t / "not.toml").write_text("name = [unclosed\n")
    (t / "tiny.toml").write_text('name = "t"\n[x]\nmass = 0.01\nmodes = [{ freq = 40, damping = 0.1 }]\n'
                                 '[y]\nmodes = [{ freq = 40, damping = 0.1 }]\n')
    (t / "job.gcode").write_text("G28\nG1 X10 Y10 F3000\nG1 X20 Y10 E1\n")
    missing = t / "e3_missing_include.cfg"
    text = (d / "klipper_config/ender3/printer.cfg").read_text().splitlines()
    keep = [ln for ln in text if not ln.startswith(("[input_shaper]", "shaper_", "damping_ratio"))]
    missing.write_text("[include shaper.cfg]\n" + "\n".join(keep) + "\n")


R = 2   # the exit status of bad input
CASES = [
    # -- identify: accelerometer files ---------------------------------------------------------------
    ("added-mass-same-files", ["identify", X, Y, "--added-mass", "0.2", X, Y], R, ["--added-mass", "same spectrum"]),
    ("added-mass-no-shift", ["identify", "resonances_x_base.csv", "--added-mass", "X=0.2", "resonances_x_loaded.csv"],
     R, ["--added-mass", "not down beyond", "resolution"]),
    ("added-mass-no-files", ["identify", X, "--added-mass", "0.2"], R, ["--added-mass", "KG"]),
    ("added-mass-zero", ["identify", X, "--added-mass", "X=0", X], R, ["--added-mass", "between 0 and 100"]),
    ("added-mass-axis-not-measured", ["identify", X, "--added-mass", "Y=0.2", Y], R, ["--added-mass", "Y"]),
    ("mass-10-grams", ["identify", X, Y, "--mass", "X=0.01,Y=1.2"], R, ["--mass", "0.01 kg", "10 g"]),
    ("mass-40-kg", ["identify", X, Y, "--mass", "X=0.5,Y=40"], R, ["--mass", "40 kg"]),
    ("mass-no-axis", ["identify", X, Y, "--mass", "0.6"], R, ["--mass", "per axis"]),
    ("mass-not-a-number", ["identify", X, "--mass", "X=heavy"], R, ["--mass", "heavy"]),
    ("mass-axis-twice", ["identify", X, "--mass", "X=0.5,X=0.6"], R, ["--mass", "twice"]),
    ("renamed-file-no-axis", ["identify", "voron_sweep_1.csv"], R, ["voron_sweep_1.csv", "cannot tell which axis",
                                                                     "--axis"]),
    ("z-resonance-test", ["identify", "resonances_z_20210821_152037.csv"], R, ["Z resonance test"]),
    ("accelerometer-query-paste", ["identify", "query.txt"], R, ["query.txt", "ACCELEROMETER_QUERY", "TEST_RESONANCES"]),
    ("semicolon-csv", ["identify", "resonances_x_semicolons.csv"], R, ["resonances_x_semicolons.csv", "semicolons",
                                                                        "commas"]),
    ("empty-file", ["identify", "empty.csv"], R, ["empty.csv", "empty"]),
    ("binary-file", ["identify", "binary.csv"], R, ["binary.csv"]),
    ("missing-file", ["identify", "nowhere.csv"], R, ["nowhere.csv", "no such file"]),
    ("folder-as-file", ["identify", "folder"], R, ["folder", "directory"]),
    ("max-modes-9", ["identify", X, "--max-modes", "9"], R, ["--max-modes", "1 to 5"]),
    ("fmin-above-fmax", ["identify", X, "--fmin", "200", "--fmax", "100"], R, ["--fmin"]),
    ("plot-not-an-image", ["identify", X, "--plot", "fit.txt"], R, ["--plot", ".png"]),
    ("output-folder-missing", ["identify", X, "-o", "no/p.toml"], R, ["-o", "no such directory", "make it first"]),
    ("unknown-motor", ["identify", X, "--motor", "nosuch-motor-42"], R, ["--motor", "nosuch-motor-42"]),
    ("motor-current-negative", ["identify", X, "--motor", "ldo-42sth48-2504ac:-1"], R, ["--motor", "run_current"]),
    ("rrf-config-as-marlin", ["identify", X, "--marlin", "config.g"], R, ["config.g", "RepRapFirmware", "--rrf"]),
    ("m503-as-rrf", ["identify", X, "--rrf", "m503_host.txt"], R, ["m503_host.txt", "Marlin", "--marlin"]),
    ("m503-as-klipper", ["identify", X, "--klipper-config", "m503_console.txt"], R, ["Marlin", "--marlin"]),
    ("klipper-cfg-as-rrf", ["identify", X, "--rrf", CFG], R, ["Klipper", "--klipper-config"]),
    # -- identify without an accelerometer -------------------------------------------------------------
    ("ripples-that-grow", ["identify", *RIP, "--decay", "X=0.8"], R, ["--decay", "grow"]),
    ("ripples-that-die-at-once", ["identify", *RIP, "--decay", "X=50"], R, ["--decay X", "damping 0.53",
                                                                          "0.04-0.23"]),
    ("ripples-of-2-hz", ["identify", "--ripples", "X=40,Y=2.6", "--speed", "100"], R, ["--ripples X", "2.5 Hz",
                                                                                    "5-300 Hz"]),
    ("ripples-of-1000-hz", ["identify", "--ripples", "X=0.1", "--speed", "100"], R, ["--ripples X", "1e+03 Hz"]),
    ("ripples-equal-heights", ["identify", *RIP, "--decay", "X=1"], R, ["--decay", "no decay"]),
    ("ripples-no-speed", ["identify", "--ripples", "X=2.2"], R, ["--speed"]),
    ("ripples-negative-spacing", ["identify", "--ripples", "X=-2", "--speed", "100"], R, ["--ripples", "positive"]),
    ("ripples-z-axis", ["identify", "--ripples", "Z=2", "--speed", "100"], R, ["--ripples", "AXIS=VALUE"]),
    ("ripples-decay-without-spacing", ["identify", "--ripples", "X=2", "--speed", "100", "--decay", "Y=1.5"], R,
     ["--decay", "Y"]),
    ("ripples-with-marlin-report", ["identify", *RIP, "--marlin", "m503_host.txt"], R,
     ["--marlin", "--base", "printer from-marlin"]),
    ("ripples-with-rrf-config", ["identify", *RIP, "--rrf", "config.g"], R, ["--rrf", "printer from-rrf"]),
    ("ripples-with-klipper-config", ["identify", *RIP, "--klipper-config", CFG], R, ["printer from-klipper"]),
    ("ripples-with-mass", ["identify", *RIP, "--mass", "X=0.5"], R, ["--mass", "--base"]),
    ("ripples-and-tower", ["identify", *RIP, "--tower-band", "X=2"], R, ["--tower-band"]),
    ("tower-band-without-tower", ["identify", "--tower-band", "X=2"], R, ["--tower"]),
    ("tower-band-fraction", ["identify", "--tower-band", "X=2.5", "--tower", "tower.gcode"], R,
     ["--tower-band", "whole number"]),
    ("tower-band-beyond-the-tower", ["identify", "--tower-band", "X=99", "--tower", "tower.gcode"], R,
     ["--tower-band", "99"]),
    ("tower-is-a-folder", ["identify", "--tower-band", "X=2", "--tower", "folder"], R, ["--tower", "directory"]),
    ("tower-missing", ["identify", "--tower-band", "X=2", "--tower", "none.gcode"], R, ["--tower", "no such file"]),
    # -- printer from-… --------------------------------------------------------------------------------
    ("from-marlin-on-rrf-config", ["printer", "from-marlin", "config.g"], R, ["config.g", "RepRapFirmware",
                                                                             "from-rrf"]),
    ("from-klipper-on-rrf-config", ["printer", "from-klipper", "config.g"], R, ["RepRapFirmware", "from-rrf"]),
    ("from-rrf-on-klipper-cfg", ["printer", "from-rrf", CFG], R, ["Klipper", "from-klipper"]),
    ("from-marlin-on-klipper-cfg", ["printer", "from-marlin", CFG], R, ["Klipper", "from-klipper"]),
    ("from-klipper-on-m503", ["printer", "from-klipper", "m503_host.txt"], R, ["Marlin", "from-marlin"]),
    ("from-rrf-on-m503", ["printer", "from-rrf", "m503_console.txt"], R, ["Marlin", "from-marlin"]),
    ("from-marlin-empty", ["printer", "from-marlin", "empty.csv"], R, ["empty.csv", "M503"]),
    ("from-marlin-binary", ["printer", "from-marlin", "binary.csv"], R, ["binary.csv", "not a text file"]),
    ("from-klipper-missing", ["printer", "from-klipper", "none.cfg"], R, ["none.cfg", "no such file"]),
    ("from-klipper-nothing", ["printer", "from-klipper"], R, ["printer.cfg", "--moonraker"]),
    ("from-klipper-folder", ["printer", "from-klipper", "folder"], R, ["folder", "directory"]),
    ("from-klipper-output-folder-missing", ["printer", "from-klipper", CFG, "-o", "no/p.toml"], R,
     ["no such directory"]),
    ("from-marlin-bad-kinematics", ["printer", "from-marlin", "m503_host.txt", "--kinematics", "delta"], R,
     ["--kinematics", "delta"]),
    # -- testprint --------------------------------------------------------------------------------------
    ("bands-5-to-300", ["testprint", "ringing", "--firmware", "klipper", "--bands", "5:300:9", "-o", "t.gcode"], R,
     ["--bands", "5 Hz", "10-150 Hz"]),
    ("bands-two-numbers", ["testprint", "ringing", "--firmware", "klipper", "--bands", "30:70", "-o", "t.gcode"], R,
     ["--bands", "F0:F1:N"]),
    ("bands-words", ["testprint", "ringing", "--firmware", "marlin", "--bands", "a:b:c"], R, ["--bands"]),
    ("bands-and-no-shaping", ["testprint", "ringing", "--firmware", "marlin", "--bands", "30:70:5",
                              "--no-shaping"], R, ["--no-shaping"]),
    ("testprint-unknown-firmware", ["testprint", "ringing", "--firmware", "smoothieware"], R,
     ["--firmware", "smoothieware"]),
    ("testprint-speed-negative", ["testprint", "ringing", "--firmware", "marlin", "--speed", "-5"], R, ["--speed"]),
    ("testprint-speed-too-high", ["testprint", "ringing", "--firmware", "marlin", "--speed", "900"], R,
     ["--speed", "top speed"]),
    ("testprint-off-the-bed", ["testprint", "ringing", "--firmware", "marlin", "--centre", "5,5"], R,
     ["--centre", "off the bed"]),
    ("testprint-output-folder-missing", ["testprint", "ringing", "--firmware", "marlin", "-o", "no/t.gcode"], R,
     ["-o", "no such directory"]),
    ("accel-ladder-without-config", ["testprint", "accel", "--firmware", "marlin", "-o", "a.gcode"], R,
     ["--config"]),
    # -- simulate -------------------------------------------------------------------------------------
    ("simulate-margin-80", ["simulate", "--freq-margin", "80"], R, ["--freq-margin", "80"]),
    ("simulate-config-missing", ["simulate", "--config", "none.json"], R, ["none.json", "no such file"]),
    ("simulate-config-broken", ["simulate", "--config", "broken.json"], R, ["broken.json"]),
    ("simulate-printer-missing", ["simulate", "--printer", "none.toml"], R, ["none.toml"]),
    ("simulate-printer-negative-mass", ["simulate", "--printer", "bad_mass.toml"], R, ["bad_mass.toml", "mass"]),
    ("printer-toml-10-grams", ["simulate", "--printer", "tiny.toml"], R, ["tiny.toml", "[x].mass", "10 g"]),
    ("simulate-printer-is-printer-cfg", ["simulate", "--printer", CFG], R, ["not valid TOML", "Klipper's printer.cfg",
                                                                           "printer from-klipper"]),
    ("tune-printer-is-m503", ["tune", "--printer", "m503_host.txt", "--out", "o"], R, ["Marlin's M503 report",
                                                                                    "printer from-marlin"]),
    ("recommend-printer-is-config-g", ["recommend", "--printer", "config.g"], R, ["RepRapFirmware's config.g",
                                                                                "printer from-rrf"]),
    ("simulate-printer-not-toml", ["simulate", "--printer", "not.toml"], R, ["not.toml", "TOML"]),
    ("simulate-gcode-missing", ["simulate", "--gcode", "none.gcode", "--shaper", "mzv", "--freq", "40"], R,
     ["none.gcode"]),
    ("simulate-unknown-shaper", ["simulate", "--shaper", "supershaper", "--freq", "40"], R, ["supershaper"]),
    ("simulate-plot-is-a-file", ["simulate", "--config", "best.json", "--plot", "best.json"], R, ["--plot"]),
    # -- export / push -----------------------------------------------------------------------------------
    ("export-config-missing", ["export", "none.json", "--firmware", "klipper"], R, ["none.json", "no such file"]),
    ("export-unknown-firmware", ["export", "best.json", "--firmware", "smoothieware"], R, ["smoothieware"]),
    ("export-output-folder-missing", ["export", "best.json", "-o", "no/x.cfg"], R,
     ["-o", "no such directory", "make it first"]),
    ("export-ei-to-rrf", ["export", "best.json", "--firmware", "rrf"], R, ["ei", "RepRapFirmware"]),
    ("export-2500-hz", ["export", "wild.json", "--firmware", "klipper"], R, ["2500", "Hz"]),
    ("export-broken-json", ["export", "broken.json", "--firmware", "klipper"], R, ["broken.json"]),
    ("push-without-port", ["push", "best.json", "--firmware", "klipper"], R, ["--port"]),
    ("push-config-missing", ["push", "none.json", "--firmware", "marlin", "--port", "/tmp/none"], R, ["none.json"]),
    # -- recommend ---------------------------------------------------------------------------------------
    ("recommend-nothing", ["recommend"], R, ["--accel", "--printer"]),
    ("recommend-renamed-file", ["recommend", "--accel", "voron_sweep_1.csv"], R, ["cannot tell which axis", "--axes"]),
    ("recommend-query-paste", ["recommend", "--accel", "query.txt"], R, ["ACCELEROMETER_QUERY"]),
    ("recommend-files-and-printer", ["recommend", "--accel", X, "--printer", "default"], R, ["--printer"]),
    ("recommend-axes-count", ["recommend", "--accel", X, "--axes", "x,y"], R, ["--axes", "one axis"]),
    ("recommend-smoothing-tiny", ["recommend", "--accel", X, "--max-smoothing", "0.01"], R, ["--max-smoothing"]),
    # -- tune, plan, limit, shaper, motor ------------------------------------------------------------------
    ("tune-zero-trials", ["tune", "--trials", "0", "--out", "o"], R, ["--trials"]),
    ("tune-accel-range-reversed", ["tune", "--accel-range", "5000,1000", "--out", "o"], R, ["--accel-range"]),
    ("tune-printer-missing", ["tune", "--printer", "none.toml", "--out", "o"], R, ["none.toml"]),
    ("tune-margin-60", ["tune", "--freq-margin", "60", "--out", "o"], R, ["--freq-margin"]),
    ("tune-path-error-negative", ["tune", "--max-path-error", "-1", "--out", "o"], R, ["--max-path-error"]),
    ("tune-unknown-firmware", ["tune", "--firmware", "smoothieware", "--out", "o"], R, ["smoothieware"]),
    ("plan-missing", ["plan", "none.gcode"], R, ["none.gcode"]),
    ("plan-folder", ["plan", "folder"], R, ["folder", "directory"]),
    ("plan-binary", ["plan", "binary.csv"], R, ["binary.csv", "not a text file"]),
    ("limit-binary", ["limit", "binary.csv", "--accel", "3000", "-o", "out.gcode"], R, ["binary.csv"]),
    ("limit-negative-limit", ["limit", "job.gcode", "--freq-limit", "-5", "-o", "out.gcode"], R, ["--freq-limit"]),
    ("shaper-unknown", ["shaper", "supershaper", "--freq", "40"], R, ["supershaper"]),
    ("shaper-negative-freq", ["shaper", "mzv", "--freq", "-1"], R, ["frequency", "-1"]),
    # -- graph: Klipper users' graphs ---------------------------------------------------------------
    ("belts-from-axis-tests", ["graph", "belts", X, Y, "-o", "b.png"], R, ["a test of the X axis", "AXIS=1,1"]),
    ("belts-same-test-twice", ["graph", "belts", "resonances_axis=1.000,1.000,0.000_a.csv",
                               "resonances_axis=1.000,-1.000,0.000_a.csv", "-o", "b.png"], R, ["the same test twice"]),
    ("belts-identify-same-test", ["identify", X, "--kinematics", "corexy", "--belts",
                                  "resonances_axis=1.000,1.000,0.000_a.csv", "resonances_axis=1.000,-1.000,0.000_a.csv"],
     R, ["--belts", "the same test twice"]),
    ("shapers-graph-of-an-m956-capture", ["graph", "shapers", "{d}/accel/rrf_m956/owendare_cartesian_duet2/"
                                          "1-T0-X54-161-0-none.csv", "-o", "g.png"], R, ["M956", "not a sweep"]),
    ("shapers-graph-of-an-m503", ["graph", "shapers", "m503_host.txt", "-o", "g.png"], R, ["m503_host.txt"]),
    ("speeds-graph-not-an-image", ["graph", "speeds", "-o", "s.txt"], R, ["-o", ".png"]),
    ("speeds-graph-printer-missing", ["graph", "speeds", "--printer", "none.toml", "-o", "s.png"], R, ["none.toml"]),
    ("motor-unknown", ["motor", "nosuch-motor-42"], R, ["nosuch-motor-42"]),
    # -- accepted, with what the tool decided said aloud ---------------------------------------------
    ("m503-from-a-host-log", ["printer", "from-marlin", "m503_host.txt", "-o", "m.toml"], 0, ["M503 does not report"]),
    ("m503-from-a-console", ["printer", "from-marlin", "m503_console.txt", "-o", "m.toml"], 0, ["limits.velocity"]),
    ("missing-include-is-unknown", ["printer", "from-klipper", "e3_missing_include.cfg", "-o", "p.toml"], 0,
     ["shaper.cfg", "unknown"]),
    ("rrf-config-runs-a-macro", ["printer", "from-rrf", "config_calls.g", "-o", "p.toml"], 0,
     ["shaper.g", "unknown"]),
    ("same-test-twice-is-read-once", ["identify", X, "resonances_x_copy.csv", "-o", "p.toml"], 0,
     ["resonances_x_copy.csv: the same data as", "read once"]),
    ("two-printers-x-tests", ["identify", X, "{d}/accel/klipper_psd/bassco_voron_v24/resonances_x_20230306_224517.csv",
                              "-o", "p.toml"], 0, ["X: 2 tests", "the best fit", "more than 10 %", "not the same printer"]),
    ("recommend-same-test-twice", ["recommend", "--accel", X, "resonances_x_copy.csv"], 0, ["read once"]),
    ("ripples-damping-not-measured", ["identify", *RIP, "-o", "p.toml"], 0, ["typical printer", "tests/data"]),
]


@pytest.fixture(scope="module")
def workdir(tmp_path_factory, data_dir):
    """The prepared files, made once (each case copies them into its own folder)."""
    t = tmp_path_factory.mktemp("hostile")
    _files(t, data_dir)
    _tower(t)
    _other_state(t)
    return t


def _snapshot(folder):
    return {p.relative_to(folder): (p.stat().st_size, p.stat().st_mtime_ns) for p in folder.rglob("*")}


@pytest.mark.parametrize("name, argv, status, words", CASES, ids=[c[0] for c in CASES])
def test_hostile_input(name, argv, status, words, workdir, data_dir, tmp_path, monkeypatch, capsys):
    t = tmp_path / "run"
    shutil.copytree(workdir, t)
    monkeypatch.chdir(t)
    argv = [a.format(d=data_dir, t=t) for a in argv]
    before = _snapshot(t)
    capsys.readouterr()
    assert main(argv) == status
    err = capsys.readouterr().err
    assert "Traceback" not in err
    if status == 2:
        assert err.count("\n") == 1 and err.startswith(f"ringtune {argv[0]}") and ": error: " in err, err
        after = _snapshot(t)
        assert after == before, sorted(set(after) ^ set(before))     # nothing written, nothing changed
    for w in words:
        assert w in err, (w, err)


def test_the_table_is_large_enough_and_spans_the_commands():
    commands = {c[1][0] for c in CASES}
    assert len(CASES) >= 80
    assert {"identify", "printer", "testprint", "simulate", "export", "push", "recommend", "tune", "plan",
            "limit", "shaper", "motor", "graph"} <= commands


@pytest.mark.parametrize("kind", ["resonances", "printer.cfg", "m503"])
def test_files_saved_by_a_windows_editor_read_as_the_plain_files(kind, data_dir, tmp_path, capsys):
    """A byte-order mark and CRLF line ends (Notepad, Excel's "CSV UTF-8") change nothing: the same
    JSON as the plain file's, apart from the file names."""
    plain = {"resonances": data_dir / "accel/klipper_psd/bassco_ender3/resonances_x_20210821_152037.csv",
             "printer.cfg": data_dir / "klipper_config/ender3/printer.cfg"}.get(kind)
    if plain is None:
        plain = tmp_path / "m503.txt"
        plain.write_text(M503_HOST)
    win = tmp_path / "win" / plain.name
    win.parent.mkdir()
    win.write_bytes(b"\xef\xbb\xbf" + plain.read_bytes().replace(b"\r\n", b"\n").replace(b"\n", b"\r\n"))
    argv = {"resonances": ["identify", "--name", "p"], "printer.cfg": ["printer", "from-klipper", "--name", "p"],
            "m503": ["printer", "from-marlin", "--name", "p"]}[kind]
    got = []
    for path in (plain, win):
        assert main([*argv, str(path), "-o", str(tmp_path / "out.toml"), "--json"]) == 0, capsys.readouterr().err
        text = capsys.readouterr().out.replace(str(path.parent), "DIR")
        got.append(json.loads(text))
    for d in got:
        for key in ("files", "notes", "warnings", "output"):
            d.pop(key, None)
        if "toml" in d:                                  # the files' SHA-256 differ, nothing else
            d["toml"] = "\n".join(ln for ln in d["toml"].splitlines() if "sha256" not in ln)
    assert got[0] == got[1]
