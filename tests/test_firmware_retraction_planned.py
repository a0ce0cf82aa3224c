"""Firmware retraction planned where its settings are known: each G10/G11 becomes the E-only move the
firmware makes. Independent truths: Klipper's firmware_retraction.py runs ``G1 E-length F%d`` (whole
mm/min) in relative mode and restores ``length + extra`` of its settings, so the same job
with those moves written out plans the same; an isolated retraction from rest to rest takes
``d/v + v/a`` (``2·sqrt(d/a)`` when it cannot reach ``v``); Marlin's fwretract.cpp restores the
length plus M208's extra, at speeds M220 does not scale; RRF's M207 F sets both speeds unless T
gives the restore's own; a Klipper without ``[firmware_retraction]`` moves nothing at a G10."""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest

from ringtune.agents.cli.main import main
from ringtune.hardware.klipper_config import printer_facts_from_klipper
from ringtune.hardware.marlin_config import printer_facts_from_marlin
from ringtune.hardware.rrf_config import printer_facts_from_rrf
from ringtune.shaping.config_plan import plan_with_config
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.firmware_retraction import firmware_retraction_note, retraction_plan
from ringtune.shaping.gcode import read_gcode
from ringtune.shaping.planner import MachineLimits

BASE = dict(accel=1000.0, velocity=300.0, square_corner_velocity=5.0, min_cruise_ratio=0.0)
KLIPPER = dict(BASE, junction="scv", klipper_reading=True)
MARLIN = dict(BASE, junction="jd", junction_deviation=0.02, klipper_reading=False, retract_accel=800.0)
RRF = dict(BASE, junction="jerk", jerk=(10.0, 10.0, 0.5, 20.0), klipper_reading=False, m203_per_minute=True)
SETTINGS = dict(retract_length=0.8, retract_speed=35.0, unretract_extra_length=0.1, unretract_speed=25.0)
JOB = ("M83\nG1 X10 Y10 F6000\nG1 X30 Y10 E1 F3000\nG10\nG1 X40 Y40 F6000\nG11\nG1 X60 Y40 E1 F3000\n"
       "G1 X60 Y0 E1\nG10\nG1 X0 Y0 F6000\nG11\nG1 X0 Y20 E1 F3000\n")


def _time(text: str, **limits) -> float:
    return plan_with_config(read_gcode(text), MachineLimits(**limits)).plan.print_time


def _written_out(text: str, out: str, back: str) -> str:
    """``text`` with each G10 and G11 replaced by the E-only move the firmware makes."""
    return text.replace("G10\n", out + "\n").replace("G11\n", back + "\n")


@pytest.mark.parametrize("limits", [KLIPPER, MARLIN, RRF], ids=["klipper", "marlin", "rrf"])
def test_a_known_retraction_plans_as_the_same_job_with_its_moves_written_out(limits):
    explicit = _written_out(JOB, "G1 E-0.8 F2100", "G1 E0.9 F1500")
    want = _time(explicit, **limits)
    assert _time(JOB, **limits, **SETTINGS) == pytest.approx(want, rel=1e-12)
    assert _time(JOB, **limits) < want            # unknown settings: stops that take no time


def test_klipper_speed_is_whole_mm_per_minute_and_m220_scales_it_marlin_does_not():
    odd = dict(SETTINGS, retract_speed=20.51)      # F%d: 1230.6 -> F1230
    explicit = _written_out(JOB, "G1 E-0.8 F1230", "G1 E0.9 F1500")
    assert _time(JOB, **KLIPPER, **odd) == pytest.approx(_time(explicit, **KLIPPER), rel=1e-12)
    half = "M220 S50\n" + JOB
    assert _time(half, **KLIPPER, **SETTINGS) == pytest.approx(
        _time(_written_out(half, "G1 E-0.8 F2100", "G1 E0.9 F1500"), **KLIPPER), rel=1e-12)
    # Marlin's internal moves run at 100 %: written out at twice the F they equal M220 S50's
    assert _time(half, **MARLIN, **SETTINGS) == pytest.approx(
        _time(_written_out(half, "G1 E-0.8 F4200", "G1 E0.9 F3000"), **MARLIN), rel=1e-12)


def test_an_isolated_retraction_takes_its_trapezoid_or_triangle():
    """G10 between two dwells (rest to rest): d/v + v/a when d ≥ v²/a, else 2·sqrt(d/a); the E cap
    (extrude_only_accel, Klipper's max_extrude_only_accel) sets a."""
    text = "M83\nG1 X10 E1 F3000\nG4 P0\nG10\nG4 P0\nG1 X20 E1\n"
    a = 500.0
    lim = dict(KLIPPER, extrude_only_accel=a)
    for length, v in ((3.0, 30.0), (0.5, 40.0)):
        d = length
        want = d / v + v / a if d >= v * v / a else 2 * math.sqrt(d / a)
        added = _time(text, **lim, retract_length=length, retract_speed=v, unretract_speed=10.0) - _time(text, **lim)
        assert added == pytest.approx(want, rel=1e-9)


def test_the_jobs_own_settings_rule_from_where_they_stand():
    """Klipper's SET_RETRACTION, Marlin's M207/M208, RRF's M207 S R F T: on a printer whose settings
    are unknown, the job's own make its retractions known from that line."""
    k = "SET_RETRACTION RETRACT_LENGTH=1.2 RETRACT_SPEED=30 UNRETRACT_EXTRA_LENGTH=0 UNRETRACT_SPEED=20\n" + JOB
    assert _time(k, **KLIPPER) == pytest.approx(_time(_written_out(k, "G1 E-1.2 F1800", "G1 E1.2 F1200"), **KLIPPER))
    m = "M207 S1.2 F1800\nM208 S0.2 F1200\n" + JOB
    assert _time(m, **MARLIN) == pytest.approx(_time(_written_out(m, "G1 E-1.2 F1800", "G1 E1.4 F1200"), **MARLIN))
    r = "M207 S1.2 R-0.1 F1800\n" + JOB        # F sets both speeds; R may be negative
    assert _time(r, **RRF) == pytest.approx(_time(_written_out(r, "G1 E-1.2 F1800", "G1 E1.1 F1800"), **RRF))
    # a length changed while retracted: Klipper's SET_RETRACTION forgets it is retracted (the G11 then moves
    # nothing)
    change = "M83\nG1 X10 E1 F3000\nG10\n{}\nG1 X20 F6000\nG11\nG1 X30 E1 F3000\n"
    kk = [p.e for p in retraction_plan(read_gcode(change.format("SET_RETRACTION RETRACT_LENGTH=2")),
                                       MachineLimits(**KLIPPER, **SETTINGS))]
    assert kk == [pytest.approx(-0.8)]


def test_a_klipper_without_firmware_retraction_moves_nothing_and_goes_on():
    plain = re.sub(r"G1[01]\n", "", JOB)
    assert _time(JOB, **KLIPPER, retract_length=0.0) == pytest.approx(_time(plain, **KLIPPER), rel=1e-12)
    # a dwell there still stops the head
    dwell = JOB.replace("G10\n", "G10\nG4 P0\n", 1)
    assert _time(dwell, **KLIPPER, retract_length=0.0) == pytest.approx(
        _time(dwell.replace("G10\n", "").replace("G11\n", ""), **KLIPPER), rel=1e-12)


def test_the_plans_moves_are_the_jobs_as_read_and_each_retraction_a_rest():
    """What reads a plan beside its job (tune's feature groups, binding limits, windows) finds the
    job's own moves; each E-only move is a rest before the next move, on Klipper from rest to rest at
    the E cap: d/v + v/a, or 2·sqrt(d/a) short of v — here 0.8 mm at 35 mm/s and 0.9 at 25, 500 mm/s²."""
    job = read_gcode(JOB)
    caps = dict(KLIPPER, extrude_only_accel=500.0)
    planned = plan_with_config(job, MachineLimits(**caps, **SETTINGS))
    assert planned.job.n_moves == job.n_moves and (planned.plan.moves.line == job.line).all()
    unknown = plan_with_config(job, MachineLimits(**caps)).plan        # the same stops, no time

    def rest_to_rest(d, v, a=500.0):
        return d / v + v / a if d >= v * v / a else 2 * math.sqrt(d / a)

    want = 2 * rest_to_rest(0.8, 35.0) + 2 * rest_to_rest(0.9, 25.0)
    assert planned.plan.print_time - unknown.print_time == pytest.approx(want, rel=1e-12)
    after = np.array([2, 3])                                       # the moves after the first G10 and G11
    assert np.diff(planned.plan.moves.t_start - unknown.moves.t_start)[after - 1] == pytest.approx(
        [rest_to_rest(0.8, 35.0), rest_to_rest(0.9, 25.0)], rel=1e-9)


def test_the_cura_job_with_a_printers_settings_plans_as_it_written_out(data_dir, tmp_path, capsys):
    """The real Cura UltiGCode job (absolute E, G10/G11 around travel moves without E): its
    retractions written out in relative E mode, each followed by moves that set their own F."""
    path = data_dir / "gcode" / "fastlb_cura_um2" / "platte_klein_cut.gcode"
    text = path.read_text()
    lines = text.splitlines()
    for i, ln in enumerate(lines):
        if ln.strip() in ("G10", "G11"):
            nxt = next(x for x in lines[i + 1:] if x.startswith(("G0", "G1")))
            assert " F" in nxt and " E" not in nxt or ln.strip() == "G11"
    explicit = tmp_path / "explicit.gcode"
    explicit.write_text(re.sub(r"^G10$", "M83\nG1 E-0.8 F2100", re.sub(r"^G11$", "G1 E0.8 F1500\nM82", text,
                                                                       flags=re.M), flags=re.M))
    printer = tmp_path / "p.toml"
    base = (data_dir.parent.parent / "envs" / "data" / "ender3.toml").read_text()
    printer.write_text(base.replace("[limits]", "[limits]\nretract_length = 0.8\nretract_speed = 35\n"
                                    "unretract_speed = 25", 1))
    assert main(["plan", str(path), "--printer", str(printer), "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert main(["plan", str(explicit), "--json", "--printer", str(data_dir.parent.parent / "envs" / "data"
                                                                   / "ender3.toml")]) == 0
    want = json.loads(capsys.readouterr().out)
    assert got["firmware_retraction_planned"] == 8 and want["firmware_retraction_planned"] == 0
    assert got["print_time_s"] == pytest.approx(want["print_time_s"], rel=1e-12)
    assert "8 planned as the E-only moves the firmware makes, by the printer's settings" in got["firmware_retraction_note"]


def test_firmware_configs_give_the_settings_in_their_units(tmp_path):
    m503 = tmp_path / "m503.txt"
    m503.write_text("echo:  M92 X80.00 Y80.00 Z400.00 E93.00\necho:  M204 P1500.00 R1000.00 T2500.00\n"
                    "echo:; Retract: S<length> F<units/m> Z<lift>\necho:  M207 S3.00 W13.00 F2700.00 Z0.00\n"
                    "echo:; Recover: S<length> F<units/m>\necho:  M208 S0.50 W0.00 F480.00\n")
    lim = printer_facts_from_marlin(m503, "cartesian").description["limits"]
    assert (lim["retract_length"], lim["retract_speed"], lim["unretract_extra_length"], lim["unretract_speed"]) == (
        3.0, 45.0, 0.5, 8.0)
    config = tmp_path / "config.g"
    config.write_text("M669 K0\nM92 X80 Y80\nM204 P1500 T2500\nM207 S0.6 R0.05 F3000 Z0.2 ; retraction\n")
    facts = printer_facts_from_rrf(config)
    lim = facts.description["limits"]
    assert (lim["retract_length"], lim["retract_speed"], lim["unretract_extra_length"], lim["unretract_speed"]) == (
        0.6, 50.0, 0.05, 50.0)
    assert lim["retract_zlift"] == 0.2 and not any("Z hop" in n for n in facts.notes)
    m503.write_text(m503.read_text().replace("Z0.00", "Z0.40"))
    assert printer_facts_from_marlin(m503, "cartesian").description["limits"]["retract_zlift"] == 0.4
    config.write_text("M669 K0\nM92 X80 Y80\nM207 S0.6 F3000 T1200\n")
    assert printer_facts_from_rrf(config).description["limits"]["unretract_speed"] == 20.0


def test_the_note_says_how_they_are_planned_and_a_half_description_is_refused(tmp_path, capsys, data_dir):
    job = read_gcode("M207 S1 F1800\n" + JOB)
    note = firmware_retraction_note(job, MachineLimits(**MARLIN))
    # M207 gives the G10s; the G11s need M208 too (Marlin's recover settings), not known here
    assert "2 planned as the E-only moves the firmware makes, by the job's own (line 1) settings" in note
    assert "2 planned as stops that take no time" in note and f"{2 * 1 / 10:.1f} s in all" in note
    printer = tmp_path / "p.toml"
    base = (data_dir.parent.parent / "envs" / "data" / "ender3.toml").read_text()
    printer.write_text(base.replace("[limits]", "[limits]\nretract_length = 0.8\nretract_speed = 35", 1))
    assert main(["plan", "--printer", str(printer)]) != 0
    err = capsys.readouterr().err
    assert "[limits].unretract_speed: needed with a retract_length above 0" in err and "Traceback" not in err


def test_klipper_configs_give_firmware_retraction_with_its_defaults_said(tmp_path):
    """klippy/extras/firmware_retraction.py: retract_length 0, retract_speed 20, unretract_extra_length 0,
    unretract_speed 10 where unset; without the section G10/G11 are unknown commands (length 0)."""
    base = ("[printer]\nkinematics: cartesian\nmax_velocity: 300\nmax_accel: 3000\n"
            "[stepper_x]\nmicrosteps: 16\nrotation_distance: 40\n[stepper_y]\nmicrosteps: 16\nrotation_distance: 40\n")
    cfg = tmp_path / "printer.cfg"
    cfg.write_text(base + "[firmware_retraction]\nretract_length: 0.6\nretract_speed: 45\nz_hop_height: 0.2\n")
    facts = printer_facts_from_klipper(cfg)
    lim = facts.description["limits"]
    assert (lim["retract_length"], lim["retract_speed"], lim["unretract_extra_length"], lim["unretract_speed"]) == (
        0.6, 45.0, 0.0, 10.0)
    assert any("unretract_speed not set: Klipper's default 10 mm/s" in n for n in facts.notes)
    assert lim["retract_zlift"] == 0.2
    cfg.write_text(base)
    facts = printer_facts_from_klipper(cfg)
    assert facts.description["limits"]["retract_length"] == 0.0
    assert "retract_speed" not in facts.description["limits"]
    assert any(n.startswith("no [firmware_retraction]: a job's G10/G11 are unknown commands") for n in facts.notes)
    cfg.write_text(base + "[firmware_retraction]\nretract_speed: 0.5\n")
    with pytest.raises(RingtuneError, match="must be ≥ 1 mm/s"):
        printer_facts_from_klipper(cfg)


@pytest.mark.slow
def test_tune_on_the_cura_job_with_a_printers_retraction_writes_a_job_that_plans_as_it_judged(data_dir, tmp_path,
                                                                                             capsys):
    """Everything tune reads beside the plan (feature groups, binding limits, the rewritten job) finds
    the job's own moves (a first version put the E-only moves into the plan, and tune failed there):
    the run ends, says how the retractions are planned, and job.gcode plans at the time it reports."""
    path = data_dir / "gcode" / "fastlb_cura_um2" / "platte_klein_cut.gcode"
    printer = tmp_path / "p.toml"
    base = (data_dir.parent.parent / "envs" / "data" / "ender3.toml").read_text()
    printer.write_text(base.replace("[limits]", "[limits]\nretract_length = 4.5\nretract_speed = 25\n"
                                    "unretract_speed = 25", 1))
    out = tmp_path / "out"
    assert main(["tune", "--gcode", str(path), "--printer", str(printer), "--trials", "3", "--workers", "1",
                 "-o", str(out), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert "8 planned as the E-only moves the firmware makes" in (out / "summary.txt").read_text()
    assert res["job_gcode"]["print_time_s"] == pytest.approx(res["chosen"]["print_time_s"], rel=1e-4)


def _z_trapezoid(d: float, v: float, a: float) -> float:
    """A move of d mm from rest to rest at top speed v, acceleration a."""
    return d / v + v / a if d >= v * v / a else 2 * math.sqrt(d / a)


@pytest.mark.parametrize("limits", [MARLIN, RRF], ids=["marlin", "rrf"])
def test_a_z_hop_rises_after_the_g10_and_comes_down_before_the_g11_at_the_z_top_speed(limits):
    """Marlin's fwretract.cpp and RRF's RetractFilament: the E move, then Z up by the hop at the Z axis's
    top speed; at the G11, Z down first, then the E move. The same job with those moves written out
    plans the same (the job stays at Z 0, so the hop is to Z 0.4 and back)."""
    caps = dict(max_velocity=(300.0, 300.0, 5.0, 60.0), max_accel=(1000.0, 1000.0, 100.0, 1000.0))
    job = "M207 Z0.4\n" + JOB
    up, down = "G1 Z0.4 F300", "G1 Z0 F300"
    explicit = "M207 Z0.4\n" + _written_out(JOB, "G1 E-0.8 F2100\n" + up, down + "\nG1 E0.9 F1500")
    got = _time(job, **limits, **caps, **SETTINGS)
    assert got == pytest.approx(_time(explicit, **limits, **caps), rel=1e-12)
    # four Z moves of 0.4 mm at 5 mm/s: at least 4 × 0.4/5 s more than without, at most 4 trapezoids from rest
    added = got - _time(JOB, **limits, **caps, **SETTINGS)
    assert 4 * 0.4 / 5 < added <= 4 * _z_trapezoid(0.4, 5.0, 100.0) + 1e-9
    # the printer's own hop (M207 Z read into [limits] retract_zlift) does the same
    assert _time(JOB, **limits, **caps, **SETTINGS, retract_zlift=0.4) == pytest.approx(got, rel=1e-12)
    # a length of 0 still hops (both firmwares move Z whatever the E move)
    none = dict(SETTINGS, retract_length=0.0, unretract_extra_length=0.0)
    assert _time(job, **limits, **caps, **none) == pytest.approx(
        _time("M207 Z0.4\n" + _written_out(JOB, up, down), **limits, **caps), rel=1e-12)


def test_marlin_hops_above_a_hundredth_of_a_mm_and_without_the_z_speed_the_hop_is_said():
    caps = dict(max_velocity=(300.0, 300.0, 5.0, 60.0))
    base = _time(JOB, **MARLIN, **caps, **SETTINGS)
    assert _time(JOB, **MARLIN, **caps, **SETTINGS, retract_zlift=0.01) == pytest.approx(base, rel=1e-12)
    assert _time(JOB, **RRF, **caps, **SETTINGS, retract_zlift=0.01) > _time(JOB, **RRF, **caps, **SETTINGS)
    lim = MachineLimits(**MARLIN, **SETTINGS, retract_zlift=0.4)
    plan = retraction_plan(read_gcode(JOB), lim)
    assert [p.hop for p in plan] == [0.4, -0.4, 0.4, -0.4] and all(p.hop_speed == 0 for p in plan)
    assert _time(JOB, **MARLIN, **SETTINGS, retract_zlift=0.4) == pytest.approx(_time(JOB, **MARLIN, **SETTINGS))
    note = firmware_retraction_note(read_gcode(JOB), lim)
    assert "the Z hop of 0.4 mm at 2 of them (up, and down at the G11) is left out" in note
    assert "[limits] max_velocity z" in note
    note = firmware_retraction_note(read_gcode(JOB), MachineLimits(**MARLIN, **SETTINGS, **caps, retract_zlift=0.4))
    assert "G10 -0.8 mm at 35 mm/s, Z +0.4 mm at 5 mm/s" in note and "left out" not in note


def test_kalicos_hop_is_its_g1_at_eight_tenths_of_max_velocity_scaled_by_m220_and_bound_by_the_z_caps():
    """Kalico's firmware_retraction.py: G10 runs ``G1 E-len F%d`` then ``G1 Z(z + hop) F(int(0.8 ·
    max_velocity · 60))``; G11 ``G1 Z-hop`` (relative) at that F, then the E move; none of it at a
    length of 0. Written out, the same job plans the same; the toolhead's Z caps bound the hop."""
    caps = dict(max_velocity=(0.0, 0.0, 15.0, 0.0), max_accel=(0.0, 0.0, 200.0, 0.0))
    f = int(0.8 * 300.0 * 60)
    up, down = f"G1 Z0.4 F{f}", f"G1 Z0 F{f}"
    for text in (JOB, "M220 S50\n" + JOB):
        explicit = _written_out(text, "G1 E-0.8 F2100\n" + up, down + "\nG1 E0.9 F1500")
        assert _time(text, **KLIPPER, **caps, **SETTINGS, retract_zlift=0.4) == pytest.approx(
            _time(explicit, **KLIPPER, **caps), rel=1e-12)
    # SET_RETRACTION Z_HOP_HEIGHT in the job does the same
    job = "SET_RETRACTION Z_HOP_HEIGHT=0.4\n" + JOB
    assert _time(job, **KLIPPER, **caps, **SETTINGS) == pytest.approx(
        _time(JOB, **KLIPPER, **caps, **SETTINGS, retract_zlift=0.4), rel=1e-12)
    # a length of 0: Kalico ignores the G10 and the G11, hop and all
    none = dict(SETTINGS, retract_length=0.0)
    assert _time(JOB, **KLIPPER, **caps, **none, retract_zlift=0.4) == pytest.approx(
        _time(JOB, **KLIPPER, **caps, **none), rel=1e-12)
