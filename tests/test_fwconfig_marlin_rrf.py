"""Marlin M503 and RepRapFirmware config.g in, with each firmware's own units.

The files are written here in the syntax of the references:
- Marlin: the M503 report as MarlinDocumentation `_gcode/M503.md` shows it (``echo:`` + heading
  comment + command line; M203 in mm/s, M201/M204 in mm/s², M205 J in mm, M906 in mA RMS) and
  ``M593 X F<Hz> D<zeta>`` of ``shared/reference/firmware.md`` §2.1 (classic ZV only);
- RRF: Duet3D/wiki-content `User_manual/Reference/Gcodes.md` (M201/M204 mm/s², M203 and M566 mm/min,
  M906 mA *peak* — "divide by 1.414 for RMS", M669 K0/1/2) and ``M593 P"type" F S`` of firmware.md §3.1.
"""

from __future__ import annotations

import math

import pytest

from ringtune.hardware.marlin_config import printer_facts_from_marlin
from ringtune.hardware.rrf_config import printer_facts_from_rrf
from ringtune.shaping.errors import RingtuneError

M503 = """\
echo:  G21    ; Units in mm (mm)
echo:; Steps per unit:
echo:  M92 X80.00 Y100.00 Z400.00 E93.00
echo:; Maximum feedrates (units/s):
echo:  M203 X500.00 Y450.00 Z5.00 E25.00
echo:; Maximum Acceleration (units/s2):
echo:  M201 X3000.00 Y2000.00 Z100.00 E5000.00
echo:; Acceleration (units/s2): P<print_accel> R<retract_accel> T<travel_accel>
echo:  M204 P1500.00 R1000.00 T2500.00
echo:; Advanced: B<min_segment_time_us> S<min_feedrate> T<min_travel_feedrate> J<junc_dev>
echo:  M205 B20000.00 S0.00 T0.00 J0.013
echo:; Stepper driver current:
echo:  M906 X580 Y620 Z580
echo:  M906 T0 E650
echo:; Input Shaping:
echo:  M593 X F40.00 D0.15
echo:  M593 Y F32.50 D0.10
ok
"""


def test_marlin_m503_units_and_keys(tmp_path):
    f = tmp_path / "m503.txt"
    f.write_text(M503)
    facts = printer_facts_from_marlin(f, "cartesian")
    d = facts.description
    assert d["kinematics"] == "cartesian"
    lim = d["limits"]
    assert lim["accel"] == 1500.0 and lim["travel_accel"] == 2500.0            # M204 P, T (mm/s²)
    assert lim["max_accel"] == [3000.0, 2000.0, 100.0, 5000.0]                 # M201 (mm/s²)
    assert lim["max_velocity"] == [500.0, 450.0, 5.0, 25.0]                    # M203 already mm/s
    assert lim["velocity"] == 500.0
    assert (lim["junction"], lim["junction_deviation"]) == ("jd", 0.013)      # M205 J (mm)
    # X and Y differ (steps/mm and current): one table each; M906 mA RMS -> A
    assert d["x"]["motor"] == {"steps_per_mm": 80.0, "run_current": 0.58}
    assert d["y"]["motor"] == {"steps_per_mm": 100.0, "run_current": 0.62}
    cur = d["current"]
    assert (cur["shaper_x"], cur["freq_x"], cur["damping_x"]) == ("zv", 40.0, 0.15)
    assert (cur["shaper_y"], cur["freq_y"], cur["damping_y"]) == ("zv", 32.5, 0.10)
    assert cur["firmware"] == "marlin" and cur["accel"] == 1500.0
    assert any("rotation_distance, microsteps" in n for n in facts.notes)


def test_marlin_classic_jerk_old_m204_s_and_shaping_off(tmp_path):
    f = tmp_path / "m503.txt"
    f.write_text("M92 X80 Y80\nM204 S1000 T1200\nM205 B20000 S0 T0 X10.00 Y8.00 Z0.30 E5.00\n"
                 "M593 X F0 D0.1\nM593 Y F0 D0.1\n")
    facts = printer_facts_from_marlin(f)
    lim = facts.description["limits"]
    assert lim["accel"] == 1000.0
    assert (lim["junction"], lim["jerk"]) == ("jerk", [10.0, 8.0, 0.3, 5.0])
    assert facts.description["current"]["shaper_x"] == facts.description["current"]["shaper_y"] == "none"
    assert "kinematics" not in facts.description
    assert any("does not report the kinematics" in n for n in facts.notes)


def test_marlin_without_any_setting_line_is_refused(tmp_path):
    f = tmp_path / "m503.txt"
    f.write_text("ok\necho:busy: processing\n")
    with pytest.raises(RingtuneError, match="not an M503 report"):
        printer_facts_from_marlin(f)


CONFIG_G = """\
; Configuration file for a CoreXY (config.g)
G90                                     ; absolute coordinates
M669 K1                                 ; CoreXY
M92 X80.00 Y80.00 Z400.00 E420:420      ; steps per mm
M566 X900 Y600 Z60 E120                 ; max instantaneous speed changes (mm/min)
M203 X18000 Y12000 Z900 E3600           ; max speeds (mm/min)
M201 X3000 Y2500 Z100 E1000             ; accelerations (mm/s^2)
M204 P2000 T3000                        ; print and travel accelerations (mm/s^2)
M906 X1200 Y1200 Z800 E500 I30          ; motor currents (mA) and idle factor
M593 P"mzv" F42.5 S0.08                 ; input shaping
"""


def test_rrf_config_g_units_and_keys(tmp_path):
    f = tmp_path / "config.g"
    f.write_text(CONFIG_G)
    facts = printer_facts_from_rrf(f)
    d = facts.description
    assert d["kinematics"] == "corexy"
    lim = d["limits"]
    assert lim["accel"] == 2000.0 and lim["travel_accel"] == 3000.0
    assert lim["max_accel"] == [3000.0, 2500.0, 100.0, 1000.0]
    assert lim["max_velocity"] == pytest.approx([18000 / 60, 12000 / 60, 900 / 60, 3600 / 60])   # 300, 200, 15, 60 mm/s
    assert lim["velocity"] == pytest.approx(300.0)
    assert lim["junction"] == "jerk"
    assert lim["jerk"] == pytest.approx([15.0, 10.0, 1.0, 2.0])                                  # mm/min / 60
    m = d["motor"]
    assert m["steps_per_mm"] == 80.0
    assert m["run_current"] == pytest.approx(1.2 / math.sqrt(2))               # 1200 mA peak -> 0.849 A RMS
    cur = d["current"]
    for ax in "xy":                                                            # one shaper for all axes
        assert (cur[f"shaper_{ax}"], cur[f"freq_{ax}"], cur[f"damping_{ax}"]) == ("mzv", 42.5, 0.08)
    assert cur["firmware"] == "rrf" and cur["accel"] == 2000.0


@pytest.mark.parametrize("line,kin", [('M669 K"coreXZ"', "corexz"), ("M669 K0", "cartesian"), ("", "cartesian")])
def test_rrf_kinematics(line, kin, tmp_path):
    f = tmp_path / "config.g"
    f.write_text(f"{line}\nM92 X80 Y80\n")
    facts = printer_facts_from_rrf(f)
    assert facts.description["kinematics"] == kin
    assert bool(line) or any("default kinematics, Cartesian" in n for n in facts.notes)


def test_rrf_unmodelled_kinematics_is_refused_naming_file_and_line(tmp_path):
    f = tmp_path / "config.g"
    f.write_text("M92 X80 Y80\nM669 K3   ; linear delta\n")
    with pytest.raises(RingtuneError) as exc:
        printer_facts_from_rrf(f)
    assert f"{f}:2: M669 K: kinematics K3 is not one the printer model has" in str(exc.value)
