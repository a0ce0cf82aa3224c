"""Calibration prints (issue 16, acceptance 2 and 4): the ringing tower's band commands are the
lines `ringtune export` writes, in effect over exactly their layers of the parsed job; the
acceleration ladder reaches the tuned acceleration and 20 % beyond in the planned motion, every
rung starting and ending at the reference point, set with the firmware's own commands."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from ringtune.agents.cli.main import main
from ringtune.envs.printer import load_printer
from ringtune.hardware.dialects import export_config
from ringtune.shaping import planner
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.gcode import read_gcode

FIRMWARES = ["klipper", "marlin", "marlin-ftm", "rrf", "rrf35", "prusa"]


def run_json(argv, capsys):
    code = main(argv + ["--json"])
    out, err = capsys.readouterr()
    assert code == 0, err
    return json.loads(out), err


def frequencies_after(event, state: dict) -> None:
    """Apply one parsed shaper command to {axis: Hz} (0 = off), read by firmware.md's rules:
    Klipper SET_INPUT_SHAPER SHAPER_FREQ_<A>; Marlin/Prusa M593 [X][Y] F (no axis = all);
    RRF M593 P"type" F (one shaper for all axes, "none" = off); Marlin FT M493 [X][Y] C A (C0 = off)."""
    p = event.params
    if event.command == "SET_INPUT_SHAPER":
        for ax in ("x", "y"):
            if f"SHAPER_FREQ_{ax.upper()}" in p:
                state[ax] = float(p[f"SHAPER_FREQ_{ax.upper()}"])
    elif event.command == "M593" and "P" in p:                      # RepRapFirmware
        f = 0.0 if str(p["P"]).lower() == "none" else float(p["F"])
        state.update(x=f, y=f)
    elif event.command == "M593":                                  # Marlin, Prusa
        axes = [a for a in ("x", "y") if a.upper() in p] or ["x", "y"]
        for a in axes:
            state[a] = float(p["F"])
    elif event.command == "M493":
        axes = [a for a in ("x", "y") if a.upper() in p] or ["x", "y"]
        if "C" in p:
            for a in axes:
                state[a] = 0.0 if p["C"] == 0 else float(p.get("A", state[a]))


@pytest.mark.parametrize("fw", FIRMWARES)
def test_tower_bands_are_exports_in_effect_over_exactly_their_layers(fw, tmp_path, capsys):
    g = tmp_path / "tower.gcode"
    res, err = run_json(["testprint", "ringing", "--firmware", fw, "--bands", "30:70:5", "--band-height", "0.6",
                         "-o", str(g)], capsys)
    bands = res["bands"]
    assert [b["freq_x"] for b in bands] == pytest.approx([30, 40, 50, 60, 70])
    text = g.read_text()
    job = read_gcode(g)
    # 1. each band's lines are what export writes for that shaper, frequency and damping
    cfg_fw = fw
    for b in bands:
        cfg = TuneConfig(firmware=cfg_fw, shaper_x=b["shaper"], shaper_y=b["shaper"], freq_x=b["freq_x"],
                         freq_y=b["freq_y"], damping_x=b["damping"], damping_y=b["damping"])
        assert b["lines"] == export_config(cfg, fw).lines       # no accel in cfg: shaper lines only
        block = "\n".join(b["lines"])
        assert text.count(block) == 1
    # 2. on the parsed job, the frequency in force at every extruding move is its band's
    events = sorted(job.shaper_events(), key=lambda e: (e.move, e.line))
    assert events, "no shaper commands parsed"
    state = {"x": math.nan, "y": math.nan}
    k = 0
    z = job.end[:, 2]
    checked = set()
    for i in range(job.n_moves):
        while k < len(events) and events[k].move <= i:
            frequencies_after(events[k], state)
            k += 1
        if not job.extruding[i]:
            continue
        band = next(b for b in bands if b["z0"] < z[i] + 1e-9 <= b["z1"] + 2e-9)
        assert (state["x"], state["y"]) == pytest.approx((band["freq_x"], band["freq_y"])), (i, z[i], band)
        checked.add(band["number"])
    assert checked == {b["number"] for b in bands}
    # 3. the job plans (the shaper changes stop the motion at the layer change)
    planned = planner.plan(job, load_printer(None).limits)
    assert planned.print_time > 0
    # 4. band table and what to look for are in the file and printed
    assert text.count("; ringtune band ") == 5 and "what to look for" in text
    assert "identify --tower-band" in "\n".join(res["measure"])


def test_tower_band_identifies_the_band_frequency(tmp_path, capsys):
    g = tmp_path / "tower.gcode"
    run_json(["testprint", "ringing", "--firmware", "marlin", "--bands", "30:70:5", "-o", str(g)], capsys)
    res, err = run_json(["identify", "--tower-band", "X=2,Y=4", "--tower", str(g)], capsys)
    assert res["modes"]["x"]["freq"] == pytest.approx(40) and res["modes"]["y"]["freq"] == pytest.approx(60)
    # not measured: a typical printer's damping (not the firmware's shaper setting), said with its source
    assert res["modes"]["x"]["damping"] == pytest.approx(0.12) and "typical printer" in err and "tests/data" in err
    assert res["measurement"]["source"] == "tower"


def test_no_shaping_tower_turns_shaping_off_and_says_what_to_measure(tmp_path, capsys):
    g = tmp_path / "r.gcode"
    res, _ = run_json(["testprint", "ringing", "--firmware", "rrf", "--no-shaping", "-o", str(g)], capsys)
    assert res["bands"][0]["lines"] == ['M593 P"none"']
    text = g.read_text()
    assert "identify --ripples" in text and "skip the first two ripples" in text


@pytest.mark.parametrize("argv, where", [
    (["--bands", "70:30:5"], "--bands"),
    (["--bands", "5:20:3", "--firmware", "prusa"], "--bands"),     # Prusa clamps to 10-100 Hz
    (["--speed", "900"], "--speed"),
])
def test_bad_tower_requests_are_one_line_errors(argv, where, capsys):
    base = ["testprint", "ringing"] + (["--firmware", "klipper"] if "--firmware" not in argv else [])
    assert main(base + argv) == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]        # notes first, then one error line
    assert last.startswith("ringtune testprint: error: " + where), last


# -- the acceleration ladder ----------------------------------------------------------------------------
ACCEL_LINE = {"klipper": "SET_VELOCITY_LIMIT ACCEL={a}"}       # firmware.md; Marlin, RRF, Prusa: M204 P T


@pytest.mark.parametrize("fw", FIRMWARES)
def test_accel_ladder_reaches_tuned_and_beyond_and_returns_to_the_reference(fw, tmp_path, capsys):
    shaper = {"marlin": "zv"}.get(fw, "mzv")
    freq_y = 45.0 if fw.startswith("rrf") else 40.0
    cfg = TuneConfig(firmware=fw, shaper_x=shaper, shaper_y=shaper, freq_x=45.0, freq_y=freq_y, accel=6000.0)
    cfg.save(tmp_path / "best.json")
    g = tmp_path / "accel.gcode"
    res, err = run_json(["testprint", "accel", "--firmware", fw, "--config", str(tmp_path / "best.json"),
                         "--centre", "110,110", "-o", str(g)], capsys)
    accels = [r["accel"] for r in res["rungs"]]
    assert accels[0] == 3000 and 6000 in accels and accels[-1] == pytest.approx(7200)   # from the printer's
    assert "3000" in err                                                                  # said aloud
    text = g.read_text()
    lines = text.splitlines()
    for ln in export_config(cfg, fw, accel=False).lines:         # the tuned shaper is on, as exported
        assert ln in lines
    printer = load_printer(None)
    job = read_gcode(g)
    plan = planner.plan(job, printer.limits)
    mv = plan.moves
    for k, a in enumerate(accels, 1):
        start = lines.index(f"; rung {k} start: {a:.0f} mm/s²") + 1
        end = lines.index(f"; rung {k} end") + 1
        own = ACCEL_LINE.get(fw, "M204 P{a} T{a}").format(a=f"{a:.0f}")
        assert lines[start] == own or lines[start + 1] == own
        sel = np.flatnonzero((mv.line > start) & (mv.line < end) & (mv.length > 0))
        # planned acceleration of the fast moves is the rung's (the marks run at the safe one)
        fast = sel[mv.feed[sel] > 100]
        assert mv.accel[fast].max() == pytest.approx(a, rel=1e-6)
        # the rung starts and ends at the reference point, in the planned motion
        t0, t1 = mv.t_start[sel[0]], mv.t_start[sel[-1]] + mv.duration[sel[-1]]
        p0, p1 = plan.motion.position(np.array([t0, t1]))[:, :2]
        assert p0 == pytest.approx([110, 110], abs=1e-9) and p1 == pytest.approx([110, 110], abs=1e-9)
        # and the fast pattern itself leaves from and comes back to it
        pf0 = mv.start[fast[0], :2]
        pf1 = mv.end[fast[-1], :2]
        assert pf0 == pytest.approx([110, 110]) and pf1 == pytest.approx([110, 110])
    assert "ladder table:" in text and "what to look for:" in text and "skipped" in text
    assert f"; {len(accels):>4}  {accels[-1]:>11.0f}" in text


def test_accel_ladder_needs_a_tuned_acceleration(tmp_path, capsys):
    TuneConfig().save(tmp_path / "best.json")
    assert main(["testprint", "accel", "--firmware", "klipper", "--config", str(tmp_path / "best.json")]) == 2
    assert "accel" in capsys.readouterr().err


# -- the arithmetic of seed 000 ------------------------------------------------------------------------
def test_ripple_arithmetic_matches_seed_000_and_the_logarithmic_decrement():
    from ringtune.envs.ripples import damping_from_ratio, mode_from_ripples

    # seed 000: frequency = perimeter speed / distance between adjacent ripple peaks (damped ringing)
    m = mode_from_ripples("x", 2.0, 100.0, 0.0, "none")
    assert m.freq == pytest.approx(50.0) and m.damped_freq == pytest.approx(50.0)
    m = mode_from_ripples("x", 2.0, 100.0, 0.1, "given")
    assert m.freq == pytest.approx(50.0 / math.sqrt(1 - 0.01))
    # a free decay x(t) = exp(-ζωt)cos(ω_d t): successive maxima one damped period apart
    zeta, f = 0.08, 40.0
    w, wd = 2 * math.pi * f, 2 * math.pi * f * math.sqrt(1 - zeta ** 2)
    t = np.linspace(0, 0.3, 300001)
    x = np.exp(-zeta * w * t) * np.cos(wd * t)
    i = np.flatnonzero((x[1:-1] > x[:-2]) & (x[1:-1] >= x[2:])) + 1
    r = x[i[0]] / x[i[1]]
    assert damping_from_ratio(r) == pytest.approx(zeta, rel=1e-3)
    with pytest.raises(RingtuneError, match="grow"):                       # ripples that grow: no decay
        damping_from_ratio(1 / r)


@pytest.mark.parametrize("argv, where", [
    (["--ripples", "X=2"], "--speed"),
    (["--ripples", "X=0", "--speed", "100"], "--ripples"),
    (["--ripples", "X=2", "--speed", "100", "--decay", "X=1"], "--decay"),
    (["--ripples", "Z=2", "--speed", "100"], "--ripples"),
    (["--tower-band", "X=2"], "--tower"),
    (["--ripples", "X=2", "--speed", "100", "--plot", "f.png"], "--plot"),
    (["--ripples", "X=2", "--speed", "-1"], "--speed"),          # was blamed on --ripples X
    (["--ripples", "X=2", "--speed", "nan"], "--speed"),
    (["--tower-band", "X=2", "--tower", "."], "--tower . : is a directory".replace(" :", ":")),
])
def test_bad_ripple_input_is_a_one_line_error(argv, where, capsys):
    assert main(["identify"] + argv) == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert last.startswith("ringtune identify: error: " + where), last


def test_trace_of_a_long_job_is_its_quality_windows(tmp_path, monkeypatch, capsys):
    """A job longer than the whole-job limit is traced over the windows the metrics judged: the
    rows carry their window number and the nozzle stays near the commanded path."""
    from ringtune.envs import trace
    from ringtune.envs.planned_job import planned_job
    from ringtune.envs.printer import load_printer

    monkeypatch.setattr(trace, "WHOLE_JOB_MAX_S", 0.5)      # the command reads it when called
    out = tmp_path / "t.csv"
    assert main(["simulate", "--backend", "lti", "--trace", str(out)]) == 0
    assert "quality windows" in capsys.readouterr().err
    tr = trace.read_trace(out)
    judged = len(planned_job(load_printer(None)).windows)      # 8 by the shares and a seam
    assert judged == 9 and set(np.unique(tr["window"])) == set(range(1, judged + 1))
    dev = np.hypot(tr["x_nozzle"] - tr["x_shaped"], tr["y_nozzle"] - tr["y_shaped"])
    assert 0 < dev.max() < 1.0


# -- what a new user gets wrong (QA) -------------------------------------------------------------------
@pytest.mark.parametrize("argv, where", [
    (["ringing", "--hotend", "900"], "--hotend"),                    # no hotend reaches 900 °C
    (["ringing", "--bed", "-20"], "--bed"),
    (["ringing", "--centre", "20,20"], "--side"),                    # the tower would start below X0/Y0
    (["accel", "--reach", "500"], "--reach"),                        # fast moves to X-390
])
def test_implausible_prints_are_one_line_errors(argv, where, tmp_path, capsys):
    TuneConfig(firmware="klipper", shaper_x="mzv", shaper_y="mzv", freq_x=45.0, freq_y=40.0,
               accel=6000.0).save(tmp_path / "best.json")
    extra = ["--config", str(tmp_path / "best.json")] if argv[0] == "accel" else []
    assert main(["testprint", *argv, "--firmware", "klipper", *extra, "-o", str(tmp_path / "x.gcode")]) == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert last.startswith("ringtune testprint: error: " + where), last
    assert not (tmp_path / "x.gcode").exists()


def test_accel_ladder_above_the_tuned_value_does_not_call_the_current_one_the_first_rung(tmp_path, capsys):
    # the Voron 2.4 of tests/data runs 8994 mm/s²; a tune that chose 4100 makes the ladder start at half
    # of 4100, and stderr must not also say that the first rung is 8994
    TuneConfig(firmware="klipper", shaper_x="mzv", shaper_y="mzv", freq_x=53.0, freq_y=37.6,
               accel=4100.0).save(tmp_path / "best.json")
    (tmp_path / "p.toml").write_text('[limits]\naccel = 3000\nvelocity = 300\n[current]\naccel = 8994.0\n'
                                     '[x]\nmodes = [{ freq = 50.0 }]\n[y]\nmodes = [{ freq = 40.0 }]\n')
    res, err = run_json(["testprint", "accel", "--firmware", "klipper", "--config", str(tmp_path / "best.json"),
                         "--printer", str(tmp_path / "p.toml")], capsys)
    assert res["rungs"][0]["accel"] == 2050
    assert "first rung 8994" not in err and "8994" in err


def test_ringing_tower_says_its_acceleration_stays_after_the_print(tmp_path, capsys):
    g = tmp_path / "r.gcode"
    run_json(["testprint", "ringing", "--firmware", "marlin", "--bands", "30:40:2", "-o", str(g)], capsys)
    tail = g.read_text().splitlines()[-3:]
    assert any("M201 X3000 Y3000" in ln and "M204 P3000 T3000" in ln and "stays" in ln for ln in tail), tail


def test_ripples_on_a_base_without_masses_say_the_masses_are_defaults(data_dir, tmp_path, capsys):
    # a description from `printer from-klipper` has no masses (a configuration does not know them);
    # identify --ripples --base must not write the loader's defaults as if they were the printer's
    base = tmp_path / "v24.toml"
    assert main(["printer", "from-klipper", str(data_dir / "klipper_config" / "v24" / "printer.cfg"),
                 "-o", str(base)]) == 0
    capsys.readouterr()
    out = tmp_path / "v24r.toml"
    res, err = run_json(["identify", "--ripples", "X=2.1,Y=2.6", "--speed", "100", "--base", str(base),
                         "-o", str(out)], capsys)
    text = out.read_text()
    assert "masses X 0.55 kg, Y 1.1 kg are defaults" in err and "--base to use" not in err
    assert "# still defaults: masses X 0.55 kg, Y 1.1 kg" in text
    # a base that gives its masses gets no such note
    base.write_text(base.read_text().replace("[x]\n", "[x]\nmass = 0.4\n").replace("[y]\n", "[y]\nmass = 0.6\n"))
    res, err = run_json(["identify", "--ripples", "X=2.1,Y=2.6", "--speed", "100", "--base", str(base)], capsys)
    assert "are defaults" not in err and "still defaults" not in res["toml"]


@pytest.mark.parametrize("fw", ["klipper", "marlin"])
def test_ringing_tower_travels_from_home_clear_of_the_bed(fw, tmp_path, capsys):
    # after G28 the head is at the homed corner; the first travel to the prime line crosses the bed
    # and must not run at first-layer height (bed clips, an unlevel bed's high side)
    g = tmp_path / "r.gcode"
    run_json(["testprint", "ringing", "--firmware", fw, "--no-shaping", "-o", str(g)], capsys)
    layer = 0.2
    first_xy = next(i for i, ln in enumerate(g.read_text().splitlines())
                    if ln.startswith("G1 X") and "E" not in ln)
    z_before = [float(w[1:]) for ln in g.read_text().splitlines()[:first_xy] if ln.startswith("G1 Z")
                for w in ln.split() if w.startswith("Z")]
    assert z_before and z_before[-1] >= layer + 1.0, z_before
