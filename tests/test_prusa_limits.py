"""Prusa-Firmware-Buddy holds M201 and M203 to its model's compiled hardware limits
(``HWLIMIT_NORMAL_*``, ``Planner::apply_settings``): a job naming its model (``M862.3 P "MK4"``)
is planned as the firmware runs it, and ``tune`` searches only accelerations the printer can take.

Independent truth: the same job with its M201/M203 lines written at the lower of each value and the
MK4's limits (7000 mm/s², 300 mm/s on X and Y, from Configuration_MK4.h) and no model named — what
Buddy's min() gives — plans to the same moves.
"""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from ringtune.agents.cli.main import main
from ringtune.envs.printer import load_printer
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.config_plan import plan_with_config
from ringtune.shaping.gcode import read_gcode
from ringtune.shaping.prusa_limits import hardware_limits, job_model


def _job(model_line: str, m201: str = "X12000 Y12000", m203: str = "X400 Y400", feed: int = 24000) -> str:
    """A zigzag of solid infill at ``feed`` mm/min asked (400 mm/s), 0.5 mm apart, its outer wall first."""
    lines = [model_line, "G90", "M83", f"M201 {m201}", f"M203 {m203}", "M204 P12000 T12000",
             ";TYPE:External perimeter", "G1 X10 Y10 F6000", "G1 X190 Y10 E6 F6000", "G1 X190 Y40 E1",
             ";TYPE:Solid infill"]
    y = 11.0
    for i in range(24):
        lines.append(f"G1 X{10 if i % 2 else 190} Y{y:.1f} E1 F{feed}")
        y += 0.5
    return "\n".join(lines) + "\n"


@pytest.fixture
def limits():
    """The default printer's limits with a top speed above the MK4's 300 mm/s, so M203's hold shows."""
    return replace(load_printer(None).limits, velocity=500.0)


def test_the_model_is_read_from_the_printer_check_and_the_mk4_limits_are_buddys():
    assert job_model(read_gcode(_job('M862.3 P "MK4" ; printer model check'))) == "MK4"
    assert job_model(read_gcode(_job(";"))) is None
    hw = hardware_limits("MK4")
    assert hw.max_accel[:2] == (7000.0, 7000.0) and hw.max_velocity[:2] == (300.0, 300.0)
    assert hardware_limits("COREONE").max_accel[:2] == (10000.0, 10000.0)
    assert hardware_limits("XL") is None and hardware_limits(None) is None


def test_buddy_holds_m201_and_m203_to_the_mk4_limits(limits):
    cfg = TuneConfig(firmware="prusa", accel=12000.0)
    held = plan_with_config(read_gcode(_job('M862.3 P "MK4"')), limits, cfg, job_accel="respect").plan
    # Buddy's min() of each axis: the job's X/Y, the printer's Z (100 mm/s², 5 mm/s) and E (none)
    truth = plan_with_config(read_gcode(_job(";", "X7000 Y7000 Z100 E2500", "X300 Y300 Z5 E100")), limits, cfg,
                             job_accel="respect").plan
    assert held.print_time == pytest.approx(truth.print_time, rel=1e-12)
    np.testing.assert_allclose(held.moves.accel, truth.moves.accel, rtol=1e-12)
    np.testing.assert_allclose(held.moves.v_nominal, truth.moves.v_nominal, rtol=1e-12)
    assert 300.0 <= held.moves.v_nominal.max() < 301.0       # X at 300 mm/s, a little Y beside
    free = plan_with_config(read_gcode(_job(";")), limits, cfg, job_accel="respect").plan
    assert free.print_time < 0.95 * held.print_time          # the job as ringtune planned it before
    # a model it does not know, or another firmware: not held
    for text, fw in ((_job('M862.3 P "XL"'), "prusa"), (_job('M862.3 P "MK4"'), "marlin")):
        other = plan_with_config(read_gcode(text), limits, replace(cfg, firmware=fw), job_accel="respect").plan
        assert other.print_time == pytest.approx(free.print_time, rel=1e-12)


@pytest.mark.slow
def test_tune_for_an_mk4_searches_only_what_the_mk4_takes(tmp_path, capsys):
    job = tmp_path / "mk4.gcode"
    job.write_text(_job('M862.3 P "MK4"', feed=7200))      # 120 mm/s: the default printer's motors keep up
    assert main(["tune", "--json", "--firmware", "prusa", "--gcode", str(job), "--trials", "3", "--no-refine",
                 "--per-feature", "on", "--out", str(tmp_path / "out")]) == 0
    out, err = capsys.readouterr()
    res = json.loads(out)
    assert res["accel"]["range"][1] <= 7000.0
    assert "Prusa-Firmware-Buddy on the MK4 (the job's M862.3) holds M201 X/Y to 7000/7000 mm/s²" in err
    ranges = res["per_feature"]["ranges"]
    assert ranges and all(r["range"][1] <= 7000.0 for r in ranges.values())
    cfg = res["chosen"]["config"]
    assert cfg["accel"] <= 7000.0 and all(a <= 7000.0 for a in (cfg.get("feature_accel") or {}).values())
    # without a model named: said, and not held
    job.write_text(_job(";", feed=7200))
    assert main(["tune", "--json", "--firmware", "prusa", "--gcode", str(job), "--trials", "3", "--no-refine",
                 "--out", str(tmp_path / "out2")]) == 0
    assert "the job names no model (M862.3)" in capsys.readouterr().err


@pytest.mark.parametrize("accel, feature, held", [
    (9000.0, {}, "on the MK4, and on any of them in stealth mode,"),           # above the MK4's 7000 only
    (4800.0, {"infill": 12400.0}, "on the MK4 and the COREONE, and"),         # a feature's, above both
    (3000.0, {}, "in stealth mode the printer runs at its limit"),             # above stealth mode's 2500
    (2000.0, {}, None),
])
def test_export_for_prusa_says_where_the_hardware_limit_holds_the_config(accel, feature, held):
    from ringtune.hardware.dialects import export_config

    cfg = TuneConfig(firmware="prusa", shaper_x="mzv", shaper_y="mzv", freq_x=50.0, freq_y=40.0, accel=accel,
                     feature_accel=feature)
    said = [n for n in export_config(cfg).notes if "hardware limit" in n]
    assert (said[0].count(held) == 1) if held else not said
    assert not [n for n in export_config(replace(cfg, firmware="klipper")).notes if "hardware limit" in n]


def test_buddy_holds_m205_jerk_to_the_mk4_limit(limits):
    """Classic jerk (Prusa's M205 X/Y): X/Y at most 10 mm/s on the MK4 (HWLIMIT_NORMAL_JERK), Z 2, E 10."""
    jerky = replace(limits, junction="jerk", jerk=(8.0, 8.0, 0.4, 5.0))
    cfg = TuneConfig(firmware="prusa", accel=5000.0)

    def planned(model_line, m205, *caps):
        text = _job(model_line, *caps, feed=9000).replace("M204 P12000 T12000", f"M204 P12000 T12000\nM205 {m205}")
        return plan_with_config(read_gcode(text), jerky, cfg, job_accel="respect").plan

    held = planned('M862.3 P "MK4"', "X20 Y20")
    # Buddy's min() of each: jerk X/Y 10 (the printer's Z 0.4 and E 5 under 2 and 10), M201 and M203 as above
    truth = planned(";", "X10 Y10 Z0.4 E5", "X7000 Y7000 Z100 E2500", "X300 Y300 Z5 E100")
    assert held.print_time == pytest.approx(truth.print_time, rel=1e-12)
    assert planned(";", "X20 Y20", "X7000 Y7000 Z100 E2500", "X300 Y300 Z5 E100").print_time < held.print_time


def test_the_corner_search_stays_under_the_mk4_jerk_limit(tmp_path):
    from ringtune.agents.tune.feature_space import CORNER_RANGE, HIDDEN_CORNER_RANGE, feature_space
    from ringtune.agents.tune.space import default_space

    from ringtune.envs.printer import printer_from_dict

    base = load_printer(None).to_dict()
    printer = printer_from_dict({**base, "limits": {**base["limits"], "junction": "jerk"}}, "jerk printer")
    job = tmp_path / "mk4.gcode"
    for line, top in (('M862.3 P "MK4"', 10.0), (";", None)):
        job.write_text(_job(line, feed=7200))
        space = feature_space(default_space(printer, "prusa"), printer, str(job))
        assert CORNER_RANGE["jerk"][1] > 10.0 and HIDDEN_CORNER_RANGE["jerk"][1] > 10.0   # the case: they reach above
        want = top or CORNER_RANGE["jerk"][1]
        assert space.corner[1] == want
        assert space.hidden_corner is None or space.hidden_corner[1] == (top or HIDDEN_CORNER_RANGE["jerk"][1])
