"""The one planning pipeline (shaping.config_plan) that `ringtune plan` and envs.evaluate share, and
the behaviours chosen where their two copies disagreed (issue 17):

- DAA (RepRapFirmware ≤ 3.3, seeds/000 M593): one setting for the whole machine, so ``"daa"`` on
  either axis plans with DAA at that axis's frequency (``plan`` used to look at X only);
- config -> shapers: ``"daa"`` and ``"none"`` (any case) are no shaper;
- Marlin's frequency limit sees the machine's maximum feedrates (firmware.md §2.4: the segment
  time is divided by the max-feedrate speed factor; ``evaluate`` used to leave them out).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import ringtune.envs
from ringtune.agents.cli.main import main
from ringtune.envs.planned_job import clear_cache, planned_job
from ringtune.envs.printer import load_printer
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.config_plan import plan_with_config
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.gcode import read_gcode
from ringtune.shaping.planner import MachineLimits, plan
from ringtune.shaping.shapers import shapers_from_config
from ringtune.shaping.testprints import builtin_test_print

RINGING_HZ = 40.0


def _daa_config(axis: str, name: str = "daa") -> TuneConfig:
    other = "y" if axis == "x" else "x"
    return TuneConfig(firmware="rrf", **{f"shaper_{axis}": name, f"freq_{axis}": RINGING_HZ,
                                         f"shaper_{other}": "none", f"freq_{other}": 0.0})


@pytest.mark.parametrize("axis", ["x", "y"])
@pytest.mark.parametrize("name", ["daa", "DAA"])
def test_daa_on_either_axis_is_the_machines_daa(axis, name):
    cfg = _daa_config(axis, name)
    assert cfg.daa_freq == RINGING_HZ
    assert shapers_from_config(cfg)[0] == {"x": None, "y": None}     # DAA is not an input shaper
    job = builtin_test_print()
    limits = MachineLimits(accel=3000.0)
    with_daa = plan_with_config(job, limits, cfg)
    assert with_daa.daa_hz == RINGING_HZ
    # RRF's M593 page: DAA "will only ever reduce acceleration" -> never a faster print
    plain = plan(job, limits)
    assert with_daa.plan.print_time > plain.print_time
    # the same as planning with DAA directly (the planner's own DAA, tested in the planner tests)
    assert with_daa.plan.print_time == plan(job, limits, daa_freq=RINGING_HZ).print_time


def test_daa_has_one_frequency_for_the_machine():
    TuneConfig(firmware="rrf", shaper_x="daa", shaper_y="daa", freq_x=40.0, freq_y=40.0)
    with pytest.raises(RingtuneError, match="freq_y.*one frequency"):
        TuneConfig(firmware="rrf", shaper_x="daa", shaper_y="daa", freq_x=40.0, freq_y=45.0)


def test_plan_command_and_evaluate_plan_a_daa_on_y_alike(tmp_path, capsys):
    """The disagreement the issue names: `plan` planned DAA only from shaper_x."""
    cfg = _daa_config("y")
    path = tmp_path / "daa.json"
    cfg.save(path)
    toml = Path(ringtune.envs.__file__).parent / "data" / "ender3.toml"     # the embedded default
    printer = load_printer(toml)
    clear_cache()
    expect = planned_job(printer, None, cfg).print_time
    assert main(["plan", "--config", str(path), "--printer", str(toml), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["daa_hz"] == RINGING_HZ
    assert res["print_time_s"] == pytest.approx(expect, rel=1e-12)


@pytest.mark.parametrize("name", ["none", "None", "off"])
def test_no_shaper_names_give_no_shaper(name):
    cfg = TuneConfig(shaper_x=name, shaper_y="mzv", freq_x=40.0, freq_y=50.0)
    shapers, centred = shapers_from_config(cfg)
    assert shapers["x"] is None and shapers["y"].name == "mzv" and centred


def _zigzag(tmp_path, feed_mm_s: float, width: float = 2.0, n: int = 40):
    lines = ["G21", "G90", "M82", "G92 E0", f"G1 X10 Y10 F{feed_mm_s * 60:g}"]
    x, e = 10.0, 0.0
    for i in range(n):
        x += width if i % 2 == 0 else -width
        e += 0.1
        lines.append(f"G1 X{x:g} Y{10 + 0.4 * (i + 1):g} E{e:.3f}")
    path = tmp_path / "zigzag.gcode"
    path.write_text("\n".join(lines) + "\n")
    return read_gcode(path)


def test_marlin_frequency_limit_sees_the_machines_max_feedrate(tmp_path):
    """Marlin (firmware.md §2.4) divides a segment's time by the max-feedrate speed factor before
    comparing it with 1/F: 2 mm zigzags asked at 200 mm/s take 10 ms (under 1/60 Hz = 16.7 ms:
    throttled) on a free machine, but 20 ms on one capped at 100 mm/s (over 16.7 ms: left alone)."""
    job = _zigzag(tmp_path, 200.0)
    cfg = TuneConfig(shaper_x="none", shaper_y="none", freq_limit_hz=60.0, freq_limit_method="marlin")
    free = plan_with_config(job, MachineLimits(velocity=500.0), cfg).freq_limit
    capped = plan_with_config(job, MachineLimits(velocity=500.0, max_velocity=(100.0, 100.0, 10.0, 50.0)),
                              cfg).freq_limit
    assert free.source == capped.source == "config" and free.hz == 60.0
    assert free.moves_slowed > 30
    assert capped.moves_slowed == 0


def test_the_jobs_own_m201_f_applies_unless_job_limits_are_ignored(tmp_path):
    _zigzag(tmp_path, 200.0)
    path = tmp_path / "with_m201.gcode"
    path.write_text("M201 F60 S30\n" + (tmp_path / "zigzag.gcode").read_text())
    job = read_gcode(path)
    limits = MachineLimits(accel=20000.0, velocity=500.0, junction="jd")   # Marlin's; fast enough that the limit binds
    own = plan_with_config(job, limits, None)
    assert own.freq_limit.source == "job M201 F" and own.freq_limit.hz == 60.0
    assert own.freq_limit.moves_slowed > 30
    ignored = plan_with_config(job, limits, None, use_job_limits=False)
    assert ignored.freq_limit is None
    assert own.plan.print_time > ignored.plan.print_time
    # Klipper has no M201: under its corner rule the job's M201 F limits nothing
    klipper = plan_with_config(job, MachineLimits(accel=20000.0, velocity=500.0, junction="scv"), None)
    assert klipper.freq_limit is None
