"""``ringtune tune`` and acceleration: a job's own acceleration commands (issue 14: --job-accel) and
tuning within the motors' means (issue 13: the range from the motors, the motor reserve)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from ringtune.agents.cli.main import main

TOWER = Path(__file__).resolve().parent / "data" / "gcode" / "ianalexis_ender3_marlin" / "ringing_tower.gcode"


def _file_caps(path: Path) -> float:
    """The acceleration the file's own M201 X/Y and M204 P/T lines allow a print or travel move
    (the smallest of them), read from the text."""
    vals = []
    for line in path.read_text().splitlines():
        words = line.split(";")[0].split()
        if words and words[0] in ("M201", "M204"):
            keys = "XY" if words[0] == "M201" else "PTS"
            vals += [float(w[1:]) for w in words[1:] if w[0] in keys]
    return min(vals)


def test_respect_says_the_file_caps_acceleration_and_does_not_search_it(tmp_path, capsys):
    out = tmp_path / "out"
    rc = main(["tune", "--json", "--gcode", str(TOWER), "--out", str(out), "--trials", "2", "--no-baselines",
               "--max-path-error", "0", "--backend", "lti", "--job-accel", "respect"])
    assert rc == 0
    cap = _file_caps(TOWER)
    assert cap == 1500.0
    res = json.loads((cap_out := capsys.readouterr()).out)
    assert f"the file caps acceleration at {cap:.0f} mm/s²" in cap_out.err
    assert "not searched" in cap_out.err
    ja = res["job_accel"]
    assert ja["mode"] == "respect" and ja["cap_mm_s2"] == cap and ja["searched"] is False
    assert res["accel"]["searched"] is False
    rows = (out / "trials.csv").read_text().strip().splitlines()
    col = rows[0].split(",").index("accel")
    assert len({r.split(",")[col] for r in rows[1:]}) == 1            # no trial spent on acceleration
    summary = (out / "summary.txt").read_text()
    assert f"the file caps acceleration at {cap:.0f} mm/s²" in summary
    assert "--job-accel respect (the print as sliced)" in summary


def test_replace_says_what_re_slicing_at_the_chosen_acceleration_saves(tmp_path, capsys):
    """The saving equals the planner's time of the file as sliced minus that of the file with its
    M204 lines and M201's X/Y caps taken out, planned at the chosen acceleration (both with the
    chosen frequency limit)."""
    from ringtune.envs.printer import load_printer
    from ringtune.shaping import freqlimit, gcode, planner
    from ringtune.shaping.config import TuneConfig

    out = tmp_path / "out"
    rc = main(["tune", "--json", "--gcode", str(TOWER), "--out", str(out), "--trials", "2", "--no-baselines",
               "--max-path-error", "0", "--backend", "lti", "--job-accel", "replace", "--accel-range", "2500,5000",
               "--per-feature", "off"])     # one acceleration: what re-slicing at it gives
    assert rc == 0
    res = json.loads(capsys.readouterr().out)
    ja = res["job_accel"]
    assert ja["mode"] == "replace" and ja["cap_mm_s2"] == 1500.0 and ja["searched"] is True
    cfg = TuneConfig.from_dict(res["chosen"]["config"])
    assert ja["replaced_accel"] == cfg.accel and 2500 <= cfg.accel <= 5000
    limits = load_printer(None).limits
    # the default printer is Klipper's, which has no M593: the tower's M593 per layer (Marlin's) is
    # answered "Unknown command" and neither stops nor shapes anything there, as no line would
    text = "\n".join(";" if ln.startswith("M593") else ln for ln in TOWER.read_text().splitlines())

    def strip(line):       # re-sliced: no M204, and M201 keeps only its Z and E caps
        words = line.split(";")[0].split()
        if words[:1] == ["M204"]:
            return ";"
        if words[:1] == ["M201"]:
            return " ".join(["M201"] + [w for w in words[1:] if w[0] in "ZE"])
        return line
    stripped = "\n".join(strip(ln) for ln in text.splitlines())

    def planned(src, accel):
        job = gcode.read_gcode(src)
        if cfg.freq_limit_hz > 0:
            job = freqlimit.apply_freq_limit(job, cfg.freq_limit_hz, method=cfg.freq_limit_method,
                                             min_speed_factor=cfg.min_speed_factor)
        lim = limits if accel is None else type(limits)(**{**limits.__dict__, "accel": accel})
        return planner.plan(job, lim).print_time

    sliced = planned(text, cfg.accel)      # the file's own lines rule (machine accel where none)
    resliced = planned(stripped, cfg.accel)
    assert ja["print_time_as_sliced_s"] == pytest.approx(sliced, rel=1e-9)
    assert ja["print_time_replaced_s"] == pytest.approx(resliced, rel=1e-9)
    assert ja["saved_s"] == pytest.approx(sliced - resliced, rel=1e-9) and ja["saved_s"] > 0
    summary = (out / "summary.txt").read_text()
    assert f"Re-slicing at {cfg.accel:.0f} mm/s²" in summary and f"would save {sliced - resliced:.1f} s" in summary


# -- within the motors' means (issue 13) -----------------------------------------------------------
def _printer(path: Path, force: float, mass_x: float, mass_y: float, fx: float, fy: float, zx=0.06, zy=0.05,
             corner=150.0) -> Path:
    path.write_text(f"""name = "{path.stem}"
kinematics = "cartesian"
[limits]
accel = 3000
velocity = 300
square_corner_velocity = 5
[x]
mass = {mass_x}
modes = [{{ freq = {fx}, damping = {zx} }}]
[y]
mass = {mass_y}
modes = [{{ freq = {fy}, damping = {zy} }}]
[motor]
force = {force}
corner_speed = {corner}
""")
    return path


def _tune(tmp_path, capsys, toml: Path, trials: int = 4) -> dict:
    out = tmp_path / f"out-{toml.stem}"
    rc = main(["tune", "--json", "--printer", str(toml), "--out", str(out), "--trials", str(trials),
               "--backend", "lti", "--seed", "2"])
    assert rc == 0, capsys.readouterr().err
    res = json.loads(capsys.readouterr().out)
    rows = [r.split(",") for r in (out / "front.csv").read_text().strip().splitlines()]
    col = rows[0].index("motor_load")
    res["_front_loads"] = [float(r[col]) for r in rows[1:]]
    return res


def _check_within_reserve(res: dict, toml: Path) -> None:
    from ringtune.envs.evaluate import evaluate_many
    from ringtune.shaping.config import TuneConfig

    assert res["motor_reserve"] == 0.2
    assert res["chosen"]["motor_load"] <= 0.8
    assert all(load <= 0.8 for load in res["_front_loads"])
    # re-simulated from scratch, judged as the study judges: within the reserve
    m, = evaluate_many([TuneConfig.from_dict(res["chosen"]["config"])], str(toml), None, backend="lti",
                       freq_margin=0.05)
    assert not m.step_loss and m.motor_load <= 0.8


@pytest.mark.slow
def test_weak_and_strong_motor_on_the_same_frame(tmp_path, capsys):
    """Masses and modes unlike the defaults; only the motor differs. The acceleration range's top is
    where the motor would need all its force (rigid: (F − friction)/(m_y + m_rotor) below the corner
    speed), the choice never breaks the 20 % reserve, and the weak motor's choice is slower."""
    weak = _printer(tmp_path / "weak.toml", 7.0, 0.8, 1.6, 42.0, 36.0)
    strong = _printer(tmp_path / "strong.toml", 60.0, 0.8, 1.6, 42.0, 36.0)
    rw, rs = _tune(tmp_path, capsys, weak), _tune(tmp_path, capsys, strong)
    for res, toml, force in ((rw, weak, 7.0), (rs, strong, 60.0)):
        _check_within_reserve(res, toml)
        # no job given: the printer's velocity limit (300 mm/s), above the 150 mm/s corner speed,
        # where the motor has force·150/300; pure Y (the heavier axis) is the worst direction
        top = (force * 150.0 / 300.0 - 1.0) / (1.6 + 0.13) * 1000.0
        assert res["accel"]["range"][1] == math.floor(top / 100.0) * 100.0
        assert res["accel"]["defaults"] == []      # motor force and both masses given
    assert rw["chosen"]["config"]["accel"] < rs["chosen"]["config"]["accel"]


@pytest.mark.slow
@pytest.mark.parametrize("seed", [11, 12])
def test_held_out_random_printers_never_choose_beyond_the_reserve(tmp_path, capsys, seed):
    """Seeded random printers with known motors, masses and modes, none of them seen while building
    tune: the chosen configuration and every front point keep the motor reserve."""
    rng = np.random.default_rng(seed)
    toml = _printer(tmp_path / f"held-out-{seed}.toml", force=float(rng.uniform(6.0, 40.0)),
                    mass_x=float(rng.uniform(0.3, 1.2)), mass_y=float(rng.uniform(0.6, 2.5)),
                    fx=float(rng.uniform(30.0, 80.0)), fy=float(rng.uniform(25.0, 70.0)),
                    zx=float(rng.uniform(0.03, 0.12)), zy=float(rng.uniform(0.03, 0.12)),
                    corner=float(rng.uniform(60.0, 200.0)))
    _check_within_reserve(_tune(tmp_path, capsys, toml), toml)


# -- a new user's run on a real configuration (v24: per-axis caps, named motor, default masses) ---
V24 = Path(__file__).resolve().parent / "data" / "klipper_config" / "v24" / "printer.cfg"


def _cfg_value(path: Path, key: str) -> float:
    """``key: value`` of the [printer] section, read from the file's text (comments dropped)."""
    for line in path.read_text().splitlines():
        k, sep, v = line.partition(":")
        if sep and k.strip() == key:
            return float(v.split("#")[0])
    raise KeyError(key)


@pytest.fixture(scope="module")
def v24_run(tmp_path_factory):
    """``printer from-klipper`` on the Voron 2.4 configuration, then a 3-trial ``tune`` of it."""
    import contextlib
    import io

    tmp = tmp_path_factory.mktemp("v24")
    toml, out = tmp / "v24.toml", tmp / "out"
    with contextlib.redirect_stderr(io.StringIO()):
        assert main(["printer", "from-klipper", str(V24), "-o", str(toml)]) == 0
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            assert main(["tune", "--json", "--printer", str(toml), "--out", str(out), "--trials", "3",
                         "--backend", "lti"]) == 0
    return json.loads(buf.getvalue()), (out / "summary.txt").read_text(), toml


@pytest.mark.slow
def test_per_axis_cap_does_not_cap_the_tuned_acceleration(v24_run):
    """max_y_accel (4130, a cap the planner applies to Y moves) is not the top of the search: the
    tuned value becomes max_accel, so the range reaches the motor bound, above the 8994 mm/s² of
    max_accel the baselines run at, judged at the printer's velocity limit (500 mm/s: no job was
    given, the built-in print stands in for prints that may run that fast)."""
    from ringtune.agents.tune.motor_bound import motor_accel_limit
    from ringtune.envs.printer import load_printer

    res, summary, toml = v24_run
    y_cap, accel = _cfg_value(V24, "max_y_accel"), _cfg_value(V24, "max_accel")
    lo, hi = res["accel"]["range"]
    assert hi > accel > y_cap
    a, _who = motor_accel_limit(load_printer(toml), _cfg_value(V24, "max_velocity"))
    assert hi == math.floor(a / 100.0) * 100.0
    assert "at 500 mm/s (the printer's velocity limit)" in summary
    chosen = res["chosen"]["config"]["accel"]
    share = round(chosen / a * 100)          # the motor's share at the velocity limit, rigid machine
    assert (f"At the printer's velocity limit 500 mm/s (no job given; the built-in print runs slower) "
            f"{chosen:.0f} mm/s² asks the {_who} for {share:.0f} % of its force there") in summary
    assert "the the" not in summary and "max_accel)" not in summary


def test_range_edge_is_named_as_the_edge_with_its_distance_from_the_choice(v24_run):
    res, summary, _ = v24_run
    hi, a = res["accel"]["range"][1], res["chosen"]["config"]["accel"]
    assert hi > a
    assert "the top of the range" not in summary
    assert f"range edge: {hi:.0f} mm/s² (" in summary or f"Stopped by the range edge: {hi:.0f} mm/s² (" in summary
    assert f"{hi - a:.0f} mm/s² above the choice" in summary


def test_summary_says_the_motor_bound_rests_on_default_masses(v24_run):
    """The v24 TOML names its motor (autotune's ldo-42sth40-2004mah) but no [x]/[y] mass."""
    from ringtune.envs.printer_defaults import DEFAULTS

    res, summary, toml = v24_run
    text = toml.read_text()
    assert 'name = "ldo-42sth40-2004mah"' in text and "\nmass" not in text
    assert res["accel"]["defaults"] == ["x.mass", "y.mass"]
    assert (f"The motor bound comes from default masses (X {DEFAULTS['mass_x']:g} kg, Y {DEFAULTS['mass_y']:g} kg): "
            "give them (see ringtune identify --motor/--mass, or ringtune printer from-klipper).") in summary
    assert "default motor" not in summary


@pytest.mark.parametrize("desc, defaulted", [
    ({}, ("x.mass", "y.mass", "x.motor", "y.motor")),
    ({"x": {"mass": 0.6}, "motor": {"force": 40.0}}, ("y.mass",)),
    ({"y": {"mass": 1.2, "motor": {"name": "ldo-42sth48-2504ac"}}}, ("x.mass", "x.motor")),
    ({"motor": {"run_current": 0.8, "rotation_distance": 40.0}}, ("x.mass", "y.mass", "x.motor", "y.motor")),
])
def test_loader_records_what_the_description_leaves_to_defaults(desc, defaulted):
    from ringtune.agents.tune.motor_bound import defaults_note
    from ringtune.envs.printer import printer_from_dict

    p = printer_from_dict({"x": {"modes": [{"freq": 50.0, "damping": 0.05}]},
                           "y": {"modes": [{"freq": 40.0, "damping": 0.05}]}} | {
        k: ({**v, "modes": [{"freq": 45.0, "damping": 0.05}]} if k in "xy" else v) for k, v in desc.items()})
    assert p.defaulted == defaulted
    note = defaults_note(p)
    assert ("default motor (30 N)" in note) == ("x.motor" in defaulted and "y.motor" in defaulted)
    assert ("default Y motor" in note) == ("y.motor" in defaulted and "x.motor" not in defaulted)
    assert ("default X motor" in note) == ("x.motor" in defaulted and "y.motor" not in defaulted)


@pytest.mark.parametrize("firmware, method, rewrite", [
    ("klipper", "sections", True),        # Klipper has no frequency limit (firmware.md §1.5)
    ("marlin", "marlin", False),          # Marlin's own M201 F S runs Marlin's method
    ("marlin", "nophead", True),          # ... but not another one
])
def test_chosen_block_says_every_job_needs_ringtune_limit(tmp_path, firmware, method, rewrite):
    from ringtune.agents.tune import report
    from ringtune.agents.tune.choice import Choice
    from ringtune.agents.tune.pareto import Point
    from ringtune.shaping.config import TuneConfig

    cfg = TuneConfig(firmware=firmware, shaper_x="mzv", shaper_y="mzv", freq_x=50.0, freq_y=40.0,
                     freq_limit_hz=20.0, freq_limit_method=method, accel=3000.0)
    p = Point(cfg, 10.0, 0.01, metrics={"path_error_mm": 0.02, "overshoot_mm": 0.01})
    res = report.write_report(tmp_path, points=[p], front=[p], choice=Choice(p, "knee", None, "the knee"),
                              baselines={}, quality="overshoot_mm", printer_name="p", job_name="j",
                              firmware=firmware, n_trials=1, storage="journal:x", study_name="s")
    chosen_block = res["summary_text"].split("\n\n")[1]
    assert chosen_block.startswith("CHOSEN")
    said = [ln for ln in chosen_block.splitlines() if "rewrite every job with `ringtune limit FILE.gcode" in ln]
    assert len(said) == (1 if rewrite else 0)
    assert (res["chosen"]["rewrite_jobs"] is not None) == rewrite
    if rewrite:
        assert "--freq-limit 20" in said[0] and f"--method {method}" in said[0]
        assert res["chosen"]["rewrite_jobs"].startswith("ringtune limit FILE.gcode --freq-limit 20")


def test_every_cap_the_summary_names_is_checked_against_the_planner_without_it(v24_run):
    """The chosen configuration carries Kalico's caps (kept: they are the owner's); each binding
    limit the summary names costs exactly the print time the planner gives with that limit removed
    (limits built here by hand from the TOML), and a cap that lowers no move is not named."""
    from dataclasses import replace

    from ringtune.envs.printer import load_printer
    from ringtune.shaping.testprints import builtin_test_print
    from ringtune.shaping.config import TuneConfig
    from ringtune.shaping.config_plan import plan_with_config
    from ringtune.shaping.planner import plan

    res, summary, toml = v24_run
    printer = load_printer(toml)
    cfg = TuneConfig.from_dict(res["chosen"]["config"])
    assert (cfg.max_accel_x, cfg.max_accel_y) == (_cfg_value(V24, "max_x_accel"), _cfg_value(V24, "max_y_accel"))
    lim = replace(printer.limits, accel=cfg.accel)
    job = builtin_test_print()
    plain = replace(cfg, max_accel_x=None, max_accel_y=None)     # the per-feature settings; caps from ``lim``
    base = plan_with_config(job, lim, plain).plan.print_time
    named = res["accel"]["binding"]
    assert named, summary
    for b in named:
        i = {"max_x_accel": 0, "max_y_accel": 1, "max_z_accel": 2}[b["name"]]
        caps = list(lim.max_accel)
        assert caps[i] == b["value"]
        caps[i] = 0.0
        without = plan_with_config(job, replace(lim, max_accel=tuple(caps)), plain).plan.print_time
        assert b["time_s"] == pytest.approx(base, rel=1e-12)
        assert b["time_without_s"] == pytest.approx(without, rel=1e-12)
        assert without < base
        assert f"{b['name']} {b['value']:.0f} mm/s² binds on {b['moves']} " in summary
    assert "max_y_accel" in {b["name"] for b in named}
    # the baselines too: Klipper's pick at its own acceleration runs under the same Kalico caps, and
    # its summary lines name each cap that holds some of its moves, at the planner's figures
    seen = 0
    for k, base_res in res["baselines"].items():
        bcfg = TuneConfig.from_dict(base_res["config"])
        if bcfg.accel is None:
            continue
        blim = replace(printer.limits, accel=bcfg.accel)
        caps_b = [bcfg.max_accel_x or blim.max_accel[0], bcfg.max_accel_y or blim.max_accel[1], *blim.max_accel[2:]]
        blim = replace(blim, max_accel=tuple(caps_b))
        with_caps = plan(job, blim, accel=bcfg.accel).print_time
        for b in base_res["binding"]:
            i = {"max_x_accel": 0, "max_y_accel": 1, "max_z_accel": 2}[b["name"]]
            caps = list(blim.max_accel)
            caps[i] = 0.0
            without = plan(job, replace(blim, max_accel=tuple(caps)), accel=bcfg.accel).print_time
            assert b["time_s"] == pytest.approx(with_caps, rel=1e-12)
            assert b["time_without_s"] == pytest.approx(without, rel=1e-12) and without < with_caps
            assert f"    {b['name']} {b['value']:.0f} mm/s² binds on {b['moves']} " in summary
            seen += 1
    assert seen, "no baseline names the Kalico cap that holds it"


@pytest.mark.slow
def test_with_a_job_the_range_is_judged_at_the_jobs_own_top_speed(tmp_path, capsys):
    """A job whose fastest XY move is 250 mm/s (under the printer's 300 mm/s limit, above the motor's
    150 mm/s corner speed): the range top is where the motor needs all its force at 250 mm/s (rigid:
    (F·150/250 − friction)/(m_y + m_rotor)), not at the velocity limit, and the JSON records 250."""
    toml = _printer(tmp_path / "p.toml", 20.0, 0.8, 1.6, 42.0, 36.0)
    job = tmp_path / "fast.gcode"
    job.write_text("G90\nM83\nG1 X20 Y20 Z0.3 F6000\n;TYPE:Outer wall\n"
                   + "".join(f"G1 X{x} Y{y} E2 F15000\n" for x, y in ((220, 20), (220, 220), (20, 220), (20, 20)))
                   + "G1 X40 Y40 E1 F3000\n")
    out = tmp_path / "out"
    assert main(["tune", "--json", "--printer", str(toml), "--gcode", str(job), "--out", str(out), "--trials", "3",
                 "--backend", "lti", "--seed", "2"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["chosen"]["config"]["top_speed_mm_s"] == pytest.approx(250.0)
    top = (20.0 * 150.0 / 250.0 - 1.0) / (1.6 + 0.13) * 1000.0
    assert res["accel"]["range"][1] == math.floor(top / 100.0) * 100.0
