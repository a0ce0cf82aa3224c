"""Planned print time against the real Klipper's own (Klipper 84104bb, session fixture
``real_klipper``, tests/real_klipper.py): klippy in batch mode (``-i JOB -o OUT -d klipper.dict``)
runs a job through its own G-code parser, toolhead look-ahead and extruder checks and logs the
toolhead's print time on exit. Its time for an empty job (the start-up offset) taken off, that is
the job's planned time to the millisecond of the log. The printer is described with ``ringtune
printer from-klipper`` from the same printer.cfg, so the reader of the configuration (Z caps, the
extruder's limits on retractions and Klipper's defaults for them) is checked with the planner.

Jobs: the built-in PrusaSlicer part (40,163 moves, with its retractions and layer changes; its G28
becomes SET_KINEMATIC_POSITION, since batch mode cannot home, and its heat-and-wait lines and closing
M84 are left out: batch mode, whose MCU clock reads 0, adds 0.05 s at the step flush of a job's last
command that a printer does not), the same rewritten with a per-feature configuration
(SET_VELOCITY_LIMIT ACCEL, SQUARE_CORNER_VELOCITY and MINIMUM_CRUISE_RATIO at each feature
change), retractions on an extruder whose own limits exceed the toolhead's, wipes, M84/M18 mid-job, and
the two real ringing towers of tests/data (Simplify3D, PrusaSlicer for Marlin)."""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

from ringtune.agents.cli.main import main  # noqa: E402
from ringtune.shaping.builtin_jobs import job_path  # noqa: E402
from ringtune.shaping.config import TuneConfig  # noqa: E402

pytestmark = [pytest.mark.timeout(600), pytest.mark.slow]

#: a cartesian printer on the Linux-process MCU's pins; {printer} and {extruder} are filled in
CFG = """[mcu]
serial: /tmp/ringtune-batch-mcu

[printer]
kinematics: cartesian
{printer}

[stepper_x]
step_pin: gpio0
dir_pin: gpio1
enable_pin: !gpio2
microsteps: 16
rotation_distance: 40
endstop_pin: ^gpio3
position_endstop: 0
position_max: 235

[stepper_y]
step_pin: gpio4
dir_pin: gpio5
enable_pin: !gpio6
microsteps: 16
rotation_distance: 40
endstop_pin: ^gpio7
position_endstop: 0
position_max: 235

[stepper_z]
step_pin: gpio8
dir_pin: gpio9
enable_pin: !gpio10
microsteps: 16
rotation_distance: 8
endstop_pin: ^gpio11
position_endstop: 0
position_max: 250

[extruder]
step_pin: gpio12
dir_pin: gpio13
enable_pin: !gpio14
microsteps: 16
rotation_distance: 33.5
nozzle_diameter: 0.4
filament_diameter: 1.75
heater_pin: gpio15
sensor_type: EPCOS 100K B57560G104F
sensor_pin: analog0
control: watermark
min_temp: 0
max_temp: 260
min_extrude_temp: 0
{extruder}

[force_move]
enable_force_move: True
"""
#: Klipper's example Ender 3 limits (config/printer-creality-ender3-2018.cfg), its extruder at defaults
ENDER3 = "max_velocity: 300\nmax_accel: 3000\nmax_z_velocity: 5\nmax_z_accel: 100"
START = "SET_KINEMATIC_POSITION X=0 Y=0 Z=0\n"


def _klippy_log(svc, cfg: Path, path: Path, check: bool = True) -> str:
    """The log of klippy's batch-mode run of the job at ``path`` (``check``: a failed run fails)."""
    log = path.with_suffix(".log")
    subprocess.run([str(svc.dir / "kvenv" / "bin" / "python"), str(svc.dir / "k" / "klippy" / "klippy.py"),
                    str(cfg), "-i", str(path), "-o", str(path.with_suffix(".serial")),
                    "-d", str(svc.dir / "k" / "out" / "klipper.dict"), "-l", str(log)],
                   capture_output=True, timeout=300, check=check)
    return log.read_text()


def _klipper_time(svc, cfg: Path, job: Path) -> float:
    """The toolhead's print time (s) at the end of ``job`` in klippy's batch mode, its time for an
    empty job taken off."""
    def run(path: Path) -> float:
        text = _klippy_log(svc, cfg, path)
        found = re.findall(r"Exiting \(print time ([\d.]+)s\)", text)
        assert found, f"klippy wrote no print time: {text[-1500:]}"
        return float(found[-1])
    empty = job.parent / "empty.gcode"
    empty.write_text(START)
    return run(job) - run(empty)


def _planned(tmp_path: Path, cfg: Path, job: Path, capsys) -> float:
    """``ringtune plan`` of ``job`` on the printer ``printer from-klipper`` describes from ``cfg``."""
    toml = tmp_path / "printer.toml"
    assert main(["printer", "from-klipper", str(cfg), "-o", str(toml)]) == 0
    capsys.readouterr()
    assert main(["plan", str(job), "--printer", str(toml), "--json"]) == 0
    return json.loads(capsys.readouterr().out)["print_time_s"]


def _batch_part(tmp_path: Path, source: Path | None = None) -> Path:
    """The built-in part (or ``source``) as batch mode can run it (module docstring): its G28 (else
    its start) set the position instead, no heat-and-wait lines, no closing M84."""
    text = Path(source or job_path("part")).read_text()
    lines = [] if any(ln.startswith("G28") for ln in text.splitlines()) else [START]
    for line in text.splitlines(keepends=True):
        if line.startswith("G28"):
            lines.append(START)
        elif not line.startswith(("M109", "M190", "M84")):
            lines.append(line)
    out = tmp_path / "part.gcode"
    out.write_text("".join(lines))
    return out


def _cfg(tmp_path: Path, printer: str = ENDER3, extruder: str = "") -> Path:
    cfg = tmp_path / "printer.cfg"
    cfg.write_text(CFG.format(printer=printer, extruder=extruder))
    return cfg


def test_the_part_plans_at_real_klippers_time(real_klipper, tmp_path, capsys):
    cfg, job = _cfg(tmp_path), _batch_part(tmp_path)
    real = _klipper_time(real_klipper, cfg, job)
    assert _planned(tmp_path, cfg, job, capsys) == pytest.approx(real, abs=2e-3)
    assert real > 1300                     # the whole job ran (23 minutes)


def test_the_part_rewritten_per_feature_plans_at_real_klippers_time(real_klipper, tmp_path, capsys):
    cfg, job = _cfg(tmp_path), _batch_part(tmp_path)
    config = TuneConfig(accel=4800.0, feature_accel={"infill": 12400.0, "travel": 10800.0, "inner_wall": 6000.0},
                        corner=5.0, min_cruise_ratio=0.5, feature_corner={"infill": 30.0, "travel": 30.0,
                                                                          "solid_infill": 9.0},
                        feature_min_cruise_ratio={"infill": 0.0, "travel": 0.0, "solid_infill": 0.0})
    config_path, tuned = tmp_path / "best.json", tmp_path / "tuned.gcode"
    config.save(config_path)
    assert main(["rewrite", str(job), "--config", str(config_path), "-o", str(tuned)]) == 0
    capsys.readouterr()
    assert "SQUARE_CORNER_VELOCITY=30" in tuned.read_text()
    real = _klipper_time(real_klipper, cfg, tuned)
    assert _planned(tmp_path, cfg, tuned, capsys) == pytest.approx(real, abs=2e-3)


def _trapezoid(d: float, v: float, a: float, a_smooth: float) -> float:
    """s for a move of ``d`` mm from rest to rest at top speed ``v`` and acceleration ``a``, its
    peak no higher than minimum_cruise_ratio's smoothed acceleration ``a_smooth`` lets it reach:
    v² = a_smooth·d (half of 2·a_smooth·d, Klipper's peak of a lone move)."""
    top = min(v, (a_smooth * d) ** 0.5)
    return 2 * top / a + (d - top * top / a) / top


def test_retractions_run_at_the_extruders_own_limits_even_above_the_toolheads(real_klipper, tmp_path, capsys):
    # retractions of 2 mm at 100 mm/s (F6000): the extruder's 150 mm/s and 20000 mm/s² bind, not the
    # toolhead's 50 mm/s and 3000 mm/s²; minimum_cruise_ratio 0.5 smooths them at the toolhead's
    # 3000 × 0.5 = 1500 mm/s² (under the extruder's 20000)
    cfg = _cfg(tmp_path, printer="max_velocity: 50\nmax_accel: 3000",
               extruder="max_extrude_only_velocity: 150\nmax_extrude_only_accel: 20000")
    job = tmp_path / "retract.gcode"
    job.write_text(START + "M83\n" + "G1 X40 Y0 E2 F3000\nG1 E-2 F6000\nG1 X0 Y0 F3000\nG1 E2 F6000\n" * 5)
    real = _klipper_time(real_klipper, cfg, job)
    assert _planned(tmp_path, cfg, job, capsys) == pytest.approx(real, abs=2e-3)
    # by hand: every move starts and ends at rest (a move of the extruder alone has no junction speed)
    by_hand = 10 * _trapezoid(40.0, 50.0, 3000.0, 1500.0) + 10 * _trapezoid(2.0, 100.0, 20000.0, 1500.0)
    assert real == pytest.approx(by_hand, abs=2e-3)
    assert by_hand - 10 * _trapezoid(40.0, 50.0, 3000.0, 1500.0) < 10 * _trapezoid(2.0, 50.0, 3000.0, 1500.0)


def test_wipes_and_z_moves_that_extrude_take_the_extruders_limits_by_their_ratio(real_klipper, tmp_path, capsys):
    # Klipper's extruder.py check_move caps a move with E and no X/Y motion, or with E backwards (a
    # retraction while wiping), at max_extrude_only_velocity / _accel over its E ratio: a 2 mm wipe
    # taking back 0.8 mm (ratio 0.4) at 798 / 0.4 mm/s²; a move extruding forwards over X/Y is not capped
    cfg, job = _cfg(tmp_path), tmp_path / "wipes.gcode"
    job.write_text(START + "G90\nM83\n" + "".join(
        f"G1 X{10 + 20 * i} Y0 E0.5 F6000\nG1 X{12 + 20 * i} Y0 E-0.8 F6000\nG1 Z{0.3 * (i + 1):.1f} E0.05 F600\n"
        f"G1 X{20 * (i + 1)} Y5 F9000\nG1 E0.8 F2400\n" for i in range(6)))
    real = _klipper_time(real_klipper, cfg, job)
    assert _planned(tmp_path, cfg, job, capsys) == pytest.approx(real, abs=2e-3)


@pytest.mark.parametrize("tower", ["bassco_ender3", "ianalexis_ender3_marlin"])
def test_real_towers_of_two_more_slicers_plan_at_real_klippers_time(tower, real_klipper, tmp_path, capsys, data_dir):
    # Simplify3D's vase tower (START_PRINT, a macro); PrusaSlicer 2.9's, written for Marlin: M201/M203/
    # M205 and a lone M204 Klipper does not act on, an M593 F at every layer that Klipper does not
    # have (so it does not stop there) and a G4 S10 (Klipper's G4 waits for P alone)
    cfg, job = _cfg(tmp_path), _batch_part(tmp_path, data_dir / "gcode" / tower / "ringing_tower.gcode")
    real = _klipper_time(real_klipper, cfg, job)
    assert _planned(tmp_path, cfg, job, capsys) == pytest.approx(real, abs=2e-3)


def test_firmware_retraction_arcs_dwells_and_speed_factor_plan_at_real_klippers_time(real_klipper, tmp_path, capsys):
    # [firmware_retraction] (G10/G11 as Klipper's own G1 E moves), [gcode_arcs] (G2/G3 cut at its
    # resolution), G4 P, M220, M204 S and a SET_VELOCITY_LIMIT mid-job, relative moves
    extra = ("\n[gcode_arcs]\nresolution: 0.5\n\n[firmware_retraction]\nretract_length: 0.8\nretract_speed: 35\n"
             "unretract_extra_length: 0.1\nunretract_speed: 25\n")
    text = ("G90\nM83\nG1 X20 Y20 E1 F6000\nG2 X40 Y20 I10 J0 E2 F3000\nG3 X20 Y20 I-10 J0 E2\n"
            "G10\nG1 X60 Y0 F9000\nG11\nM220 S50\nG1 X80 Y0 E1 F6000\nG4 P500\nM220 S100\nM204 S1000\n"
            "G1 X80 Y40 E1\nSET_VELOCITY_LIMIT ACCEL=8000 SQUARE_CORNER_VELOCITY=20 MINIMUM_CRUISE_RATIO=0.2\n"
            "G91\nG1 X-10 Y5 E0.5 F4000\nG1 X-3 Y7 E0.3\nG90\nG1 X0 Y0 F12000\n")
    real, planned, _ = _both(real_klipper, tmp_path, capsys, text, extra)
    assert planned == pytest.approx(real, abs=2e-3)
    assert real > 3.0


def _both(svc, tmp_path: Path, capsys, text: str, extra_cfg: str = ""):
    """(Klipper's time, ringtune's planned time, the job's path) of ``text`` after START, on the
    Ender 3 configuration with ``extra_cfg`` appended."""
    cfg = _cfg(tmp_path)
    cfg.write_text(cfg.read_text() + extra_cfg)
    job = tmp_path / "job.gcode"
    job.write_text(START + text)
    return _klipper_time(svc, cfg, job), _planned(tmp_path, cfg, job, capsys), job


def test_motors_off_mid_job_rests_and_dwells_where_a_motor_is_on(real_klipper, tmp_path, capsys):
    # M84 after moves: a rest, 0.1 s before and after turning the motors off and the step flush; again
    # at once: a rest alone (nothing is on); M84 S30 (Marlin's idle timeout) turns them off all the same;
    # M18 after a retraction alone (the extruder's motor is on). Each M84 clears the homing: the position
    # is set again, where the head is, before the next move. Each is followed by a G4: batch mode, whose
    # MCU clock reads 0, adds 0.05 s to a move that restarts at once after a step flush, a printer not.
    text = ("G90\nM83\nG1 X40 Y0 E2 F6000\nM84\nG4 P300\nM84\nG4 P300\n"
            "SET_KINEMATIC_POSITION X=40 Y=0 Z=0\nG1 X40 Y30 E1.5 F6000\nM84 S30\nG4 P300\n"
            "SET_KINEMATIC_POSITION X=40 Y=30 Z=0\nG1 E-1 F2400\nM18\nG4 P300\n"
            "SET_KINEMATIC_POSITION X=40 Y=30 Z=0\nG1 X0 Y0 F9000\n")
    real, planned, job = _both(real_klipper, tmp_path, capsys, text)
    assert planned == pytest.approx(real, abs=2e-3)
    cfg = tmp_path / "printer.cfg"
    job.write_text("".join(line for line in job.read_text().splitlines(keepends=True)
                           if not line.startswith(("M84", "M18"))))
    assert planned - _planned(tmp_path, cfg, job, capsys) == pytest.approx(3 * 0.202, abs=1e-6)   # three on


def test_the_moves_klippers_extruder_refuses_are_named(real_klipper, tmp_path, capsys):
    # a line at 0.48 mm² of extrusion (Klipper's default limit for a 0.4 mm nozzle: 4 × 0.4² = 0.64 mm²),
    # one at 0.72 mm², a tiny one far over the rate but within nozzle × ratio, a 60 mm retraction (its
    # default max_extrude_only_distance: 50 mm): Klipper names the second and the fourth, and so does plan
    cfg = _cfg(tmp_path)
    job = tmp_path / "refused.gcode"
    job.write_text(START + "G90\nM83\nG1 X20 Y0 E1 F3000\nG1 X20 Y0.5 E0.1\nG1 X40 Y0 E6\nG1 X40.05 Y0 E0.1\n"
                   "G1 E-60 F3000\nG1 X0 Y0 E0.5 F6000\n")
    log = _klippy_log(real_klipper, cfg, job, check=False)
    wide = [float(a) for a, _ in re.findall(r"Move exceeds maximum extrusion \(([\d.]+)mm\^2 vs ([\d.]+)mm\^2\)", log)]
    far = [float(a) for a in re.findall(r"Extrude only move too long \(([-\d.]+)mm vs [\d.]+mm\)", log)]
    assert len(wide) == 1 and far == [-60.0]
    toml = tmp_path / "printer.toml"
    assert main(["printer", "from-klipper", str(cfg), "-o", str(toml)]) == 0
    capsys.readouterr()
    assert main(["plan", str(job), "--printer", str(toml), "--json"]) == 0
    found = json.loads(capsys.readouterr().out)["klipper_refusals"]
    assert [(r["line"], r["kind"]) for r in found] == [(6, "too_wide"), (8, "too_long")]
    area = math.pi * 1.75 ** 2 / 4                          # the filament's cross-section, mm²
    assert found[0]["value"] * area == pytest.approx(wide[0], abs=1e-3)
    assert found[0]["limit"] * area == pytest.approx(0.64) and found[1]["limit"] == 50.0


def test_the_moves_out_of_klippers_range_are_named(real_klipper, tmp_path, capsys):
    # X past stepper_x's position_max 235 (refused: Klipper stays at X 0, the plan goes on from 240),
    # Y alone (allowed: only the axes a move moves are checked), back, Y below its position_min 0,
    # then the far corner exactly (allowed): Klipper's batch mode refuses the first and the fourth
    # move, and so does plan, from the same printer.cfg
    cfg = _cfg(tmp_path)
    job = tmp_path / "range.gcode"
    job.write_text(START + "G90\nM83\nG1 X240 Y10 F6000\nG1 Y20\nG1 X10 Y10\nG1 X10 Y-1\nG1 X235 Y235\nG1 X0 Y0\n")
    log = _klippy_log(real_klipper, cfg, job, check=False)
    refused = [(float(x), float(y)) for x, y in re.findall(r"Move out of range: ([-\d.]+) ([-\d.]+) [-\d.]+", log)]
    assert refused == [(240.0, 10.0), (10.0, -1.0)]
    toml = tmp_path / "printer.toml"
    assert main(["printer", "from-klipper", str(cfg), "-o", str(toml)]) == 0
    capsys.readouterr()
    assert main(["plan", str(job), "--printer", str(toml), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    found = out["klipper_refusals"]
    assert [(r["line"], r["kind"], r["value"], r["limit"]) for r in found] == [
        (4, "out_of_range_x", 240.0, 235.0), (7, "out_of_range_y", -1.0, 0.0)]
    assert "line 4 moves X to 240.000 mm, past stepper_x's position_max 235 mm" in out["klipper_refusals_note"]
    assert "line 7 moves Y to -1.000 mm, past stepper_y's position_min 0 mm" in out["klipper_refusals_note"]


def test_a_move_from_where_the_reader_cannot_know_the_head_is_not_named(real_klipper, tmp_path, capsys):
    # Klipper puts the head at X 100 (as a G28 puts it at an endstop ringtune reads as 0); a relative
    # move of −50 ends at 50 there, which Klipper takes — ringtune reads −50, unknown, and names
    # nothing; the absolute move after it past position_max 235 both name
    cfg = _cfg(tmp_path)
    job = tmp_path / "unknown.gcode"
    job.write_text("SET_KINEMATIC_POSITION X=100 Y=0 Z=0\nG91\nG1 X-50 F6000\nG90\nG1 X240 Y10\nG1 X0 Y0\n")
    log = _klippy_log(real_klipper, cfg, job, check=False)
    refused = [float(x) for x, _y in re.findall(r"Move out of range: ([-\d.]+) ([-\d.]+) [-\d.]+", log)]
    assert refused == [240.0]
    toml = tmp_path / "printer.toml"
    assert main(["printer", "from-klipper", str(cfg), "-o", str(toml)]) == 0
    capsys.readouterr()
    assert main(["plan", str(job), "--printer", str(toml), "--json"]) == 0
    found = json.loads(capsys.readouterr().out)["klipper_refusals"]
    assert [(r["line"], r["kind"], r["value"]) for r in found] == [(5, "out_of_range_x", 240.0)]
