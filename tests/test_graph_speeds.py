"""Speeds to avoid: on a single-mode printer the predicted band holds the speed at which a straight
wall's ripple, simulated in MuJoCo on the whole G-code job, is largest; the graph shows the JSON's
numbers and OrcaSlicer's keys."""

from __future__ import annotations

import json
import math
import tomllib

import numpy as np
import pytest
from PIL import Image

from ringtune.agents.cli.main import main
from ringtune.agents.tune.speeds import speed_advice, typical_wall
from ringtune.envs.evaluate import evaluate
from ringtune.envs.planned_job import resolve_job
from ringtune.envs.printer import printer_from_dict
from ringtune.shaping.config import TuneConfig

ONE_MODE = """
name = "one-mode"
kinematics = "cartesian"
[limits]
accel = 3000
velocity = 250
square_corner_velocity = 5
[x]
mass = 0.5
modes = [{ freq = 40.0, damping = 0.05 }]
[y]
mass = 0.5
modes = [{ freq = 40.0, damping = 0.05 }]
"""


def tower(speed: float, side: float = 40.0, layers: int = 3) -> str:
    """A square single-wall tower: outer walls of ``side`` mm, 90° corners, at ``speed`` mm/s."""
    f = speed * 60
    lines = ["G90", "M82", "G92 E0", "G0 X100 Y100 Z0.2 F6000", ";TYPE:Outer wall"]
    e = 0.0
    for layer in range(layers):
        lines.append(f"G0 Z{0.2 * (layer + 1):.1f}")
        for x, y in ((100 + side, 100), (100 + side, 100 + side), (100, 100 + side), (100, 100)):
            e += side * 0.04
            lines.append(f"G1 X{x:g} Y{y:g} E{e:.4f} F{f:.0f}")
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="module")
def printer():
    return printer_from_dict(tomllib.loads(ONE_MODE), "one-mode")


def test_the_typical_wall_of_a_square_tower():
    length, corner, n = typical_wall(resolve_job(tower(100))[1])
    assert length == pytest.approx(40.0) and corner == pytest.approx(90.0) and n >= 8


def test_the_predicted_band_holds_the_speed_of_the_largest_simulated_ripple(printer):
    config = TuneConfig(firmware="klipper", shaper_x="none", shaper_y="none", accel=3000)
    speeds = np.arange(14.0, 200.0, 6.0)          # a grid of its own, not the prediction's
    ripple = [evaluate(config, printer, tower(v), backend="mujoco").ripple_mm for v in speeds]
    worst = float(speeds[int(np.argmax(ripple))])
    advice = speed_advice(printer, tower(100), config)
    band = advice.worst
    assert band.lo <= worst <= band.hi, (worst, band)
    # the physics behind it: the corner's braking lasts (v - v_corner)/a; half a damped period rings most
    f_d = 40.0 * math.sqrt(1 - 0.05 ** 2)
    assert band.lo <= 3000 / (2 * f_d) + 5 and band.hi >= 3000 / (2 * f_d)
    assert advice.orcaslicer() == {"resonance_avoidance": "1", "min_resonance_avoidance_speed": f"{band.lo:g}",
                                   "max_resonance_avoidance_speed": f"{band.hi:g}"}


def test_shaping_lowers_the_worst_ripple(printer):
    off = speed_advice(printer, None, TuneConfig(firmware="klipper", shaper_x="none", shaper_y="none", accel=3000),
                       step=10.0)
    on = speed_advice(printer, None, TuneConfig(firmware="klipper", shaper_x="zv", shaper_y="zv", freq_x=44.0,
                                                freq_y=44.0, accel=3000), step=10.0)
    for k in ("x", "y"):
        assert on.ripple[k].max() < 0.3 * off.ripple[k].max()


def test_speed_graph_shows_the_json_numbers(capsys, tmp_path):
    ptoml = tmp_path / "p.toml"
    ptoml.write_text(ONE_MODE)
    job = tmp_path / "tower.gcode"
    job.write_text(tower(100))
    png = tmp_path / "speeds.png"
    assert main(["graph", "speeds", "--printer", str(ptoml), "--gcode", str(job), "--step", "10", "-o", str(png),
                 "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    im = Image.open(png)
    px = np.asarray(im.convert("RGB"), dtype=float)
    assert im.size[0] > 800 and 0.02 < (px.sum(axis=2) < 600).mean() < 0.6
    text = im.text["Description"]
    assert set(d["ripple_mm"]) == {"x", "y"} and len(d["ripple_mm"]["x"]) == len(d["speeds_mm_s"])
    for b in d["bands"]:
        assert (f"{b['direction']}: {b['lo']:g}-{b['hi']:g} mm/s (worst {1000 * b['peak_ripple_mm']:.1f} µm at "
                f"{b['peak_speed']:g} mm/s)") in text
    for k, v in d["orcaslicer"].items():
        assert f"{k} = {v}" in text
    assert d["wall_length_mm"] == pytest.approx(40.0)


def test_speed_graph_of_the_real_ender3_and_its_real_tower(capsys, tmp_path, data_dir):
    """Drawn from the real files in tests/data: the Ender 3 identified from its Klipper resonance
    tests and printer.cfg, and the ringing tower sliced for it. The PNG is drawn and holds the JSON's
    bands and OrcaSlicer keys; each band is the run of the JSON's own curve at ≥ 1/√2 of that
    direction's worst (widened half a step), and the worst band holds the curve's maximum."""
    acc = data_dir / "accel/klipper_psd/bassco_ender3"
    toml = tmp_path / "e3.toml"
    assert main(["identify", *sorted(map(str, acc.glob("*.csv"))), "--klipper-config",
                 str(data_dir / "klipper_config/ender3/printer.cfg"), "-o", str(toml)]) == 0
    capsys.readouterr()
    png = tmp_path / "speeds.png"
    assert main(["graph", "speeds", "--printer", str(toml), "--gcode",
                 str(data_dir / "gcode/bassco_ender3/ringing_tower.gcode"), "-o", str(png), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    im = Image.open(png)
    px = np.asarray(im.convert("RGB"), dtype=float)
    assert im.size[0] > 800 and 0.02 < (px.sum(axis=2) < 600).mean() < 0.6
    text = im.text["Description"]
    speeds = np.array(d["speeds_mm_s"])
    step = float(np.median(np.diff(speeds)))
    assert d["bands"] and {b["direction"] for b in d["bands"]} == {"x", "y"}
    for b in d["bands"]:
        assert (f"{b['direction']}: {b['lo']:g}-{b['hi']:g} mm/s (worst {1000 * b['peak_ripple_mm']:.1f} µm at "
                f"{b['peak_speed']:g} mm/s)") in text
        r = np.array(d["ripple_mm"][b["direction"]])
        inside = (speeds > b["lo"]) & (speeds < b["hi"])
        assert np.all(r[inside] >= d["band_level"] * r.max())
        for edge in (b["lo"] - step / 2, b["hi"] + step / 2):        # the grid speeds just outside
            out = np.isclose(speeds, edge)
            assert np.all(r[out] < d["band_level"] * r.max())
        assert b["peak_ripple_mm"] == pytest.approx(r[inside].max())
        assert b["peak_speed"] == speeds[inside][r[inside].argmax()]
    worst = max(d["bands"], key=lambda b: b["peak_ripple_mm"])
    top = max(d["ripple_mm"].values(), key=max)
    assert worst["peak_ripple_mm"] == pytest.approx(max(top))
    for k, v in d["orcaslicer"].items():
        assert f"{k} = {v}" in text
    assert d["orcaslicer"]["min_resonance_avoidance_speed"] == f"{worst['lo']:g}"


TWO_MODES = ONE_MODE.replace('name = "one-mode"', 'name = "two-modes"').replace(
    "[y]\nmass = 0.5\nmodes = [{ freq = 40.0, damping = 0.05 }]", "[y]\nmass = 0.5\nmodes = [{ freq = 60.0, damping = 0.05 }]")


def test_each_direction_rings_with_the_modes_across_it():
    """X at 40 Hz, Y at 60 Hz: a wall along X ripples across it with Y's mode, a wall along Y with
    X's. Braking (v − v_corner)/a into the corner rings most at half a damped period, so each curve's
    worst speed is about a/(2 f_d) of the crossing axis: 25 mm/s for the wall along X, 37.5 along Y.
    (The entry into the corner runs along the other direction; it was labelled an outer wall too, so
    both curves showed the worse of the two walls, the same curve twice.)"""
    printer = printer_from_dict(tomllib.loads(TWO_MODES), "two-modes")
    assert [m.freq for m in printer.x.modes] == [40.0] and [m.freq for m in printer.y.modes] == [60.0]
    config = TuneConfig(firmware="klipper", shaper_x="none", shaper_y="none", accel=3000)
    advice = speed_advice(printer, tower(100), config, step=2.5)
    for along, across in (("x", 60.0), ("y", 40.0)):
        worst = float(advice.speeds[int(np.argmax(advice.ripple[along]))])
        peak = 3000 / (2 * across * math.sqrt(1 - 0.05 ** 2))
        assert abs(worst - peak) <= 5.0, (along, worst, peak)
    assert not np.allclose(advice.ripple["x"], advice.ripple["y"], rtol=0.05)
