"""Schedules by printed mass on a bed slinger (issue 22 item 3).

Independent truths: the filament mass of a generated solid block
(:mod:`ringtune.shaping.solid_block`) from the E values it wrote (π d²/4 × length × density), and
of two real sliced jobs from their slicers' own header figures; the Y modes with the print on the
bed by a generalised eigen-solve of the default printer's TOML numbers (stiffness = modal mass × ω²
of the empty bed, masses grown by the print), of the MuJoCo model's own matrices, and √(k/m) for a
one-mode bed; Prusa's weight rule from its firmware source (``M74.cpp``: lerp from F to F + A by
W/M, held beyond M; defaults A = −20 Hz, M = 800 g); the ripple and corners from the MuJoCo model
with the last band's mass on the bed.
"""

from __future__ import annotations

import json
import math
import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import eigh

from ringtune.agents.cli import main as cli
from ringtune.agents.tune.mass_check import schedule_job
from ringtune.agents.tune.mass_schedule import filament, mass_schedule, scheduled_lines
from ringtune.envs.bed_load import dominant_y_mode
from ringtune.envs.printer import load_printer, printer_from_dict
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.gcode import read_gcode
from ringtune.shaping.layer_commands import TAG, band_commands, prusa_weight_frequency
from ringtune.shaping.layers import job_layers
from ringtune.shaping.solid_block import solid_block

ENDER3_TOML = Path(__file__).resolve().parent.parent / "envs" / "data" / "ender3.toml"
AREA = math.pi * 1.75 ** 2 / 4          # mm² of 1.75 mm filament
PLA = 1.24e-6                            # kg/mm³


@pytest.fixture(scope="module")
def block(tmp_path_factory):
    text, e_layers = solid_block()
    path = tmp_path_factory.mktemp("mass") / "block.gcode"
    path.write_text(text)
    return path, e_layers


def _ender3_y_mode(load_kg: float) -> float:
    """The dominant Y mode (Hz) of the default printer's TOML with ``load_kg`` on the bed: eigen-solve
    of K = diag(share·M·ω²) (the springs, fixed) against diag(share·(M + load))."""
    d = tomllib.loads(ENDER3_TOML.read_text())
    m_bed, modes = d["y"]["mass"] + d["print_mass"], d["y"]["modes"]
    share = np.array([m["share"] for m in modes])
    k = np.diag(share * m_bed * (2 * np.pi * np.array([m["freq"] for m in modes])) ** 2)
    w2, _ = eigh(k, np.diag(share * (m_bed + load_kg)))
    order = np.argsort(w2)                            # mode j keeps its share: diagonal system
    return float(np.sqrt(w2[order][int(np.argmax(share))]) / (2 * np.pi))


def test_layers_and_mass_from_the_job_match_the_generator(block):
    path, e_layers = block
    layers = job_layers(read_gcode(path))
    assert len(layers) == len(e_layers) == 300
    assert [la.z for la in layers[:3]] == pytest.approx([0.3, 0.6, 0.9])
    mass = e_layers * AREA * PLA
    np.testing.assert_allclose([la.mass for la in layers], mass, rtol=1e-9)
    np.testing.assert_allclose([la.mass_before for la in layers], np.concatenate([[0], np.cumsum(mass)[:-1]]),
                               rtol=1e-9, atol=1e-12)
    assert 0.39 < mass.sum() < 0.42          # 60×60×90 mm of PLA is 402 g
    # a denser, thicker filament scales the mass by its area and density
    heavier = job_layers(read_gcode(path), 2.85, 1.27)
    assert heavier[-1].mass == pytest.approx(layers[-1].mass * (2.85 / 1.75) ** 2 * 1.27 / 1.24, rel=1e-9)


GCODE = Path(__file__).resolve().parent / "data" / "gcode"


@pytest.mark.parametrize("name, density, slicer_mm, slicer_g", [
    ("ianalexis_ender3_marlin/ringing_tower.gcode", 1.04, 5518.28, 13.80),   # PrusaSlicer 2.9 header
    ("bassco_ender3/ringing_tower.gcode", 1.25, 6043.4, 18.17),              # Simplify3D 4.1 header
])
def test_print_mass_of_real_jobs_matches_their_slicers(name, density, slicer_mm, slicer_g):
    """The slicer's own filament figures, printed in each file; the schedule reads the filament
    the slicer sliced for from the file itself (its density differs from PLA's default here)."""
    layers = job_layers(read_gcode(GCODE / name), 1.75, density)
    grams = (layers[-1].mass_before + layers[-1].mass) * 1e3
    assert grams == pytest.approx(slicer_g, rel=0.005)
    assert grams / (density * AREA * 1e-3) == pytest.approx(slicer_mm, rel=0.005)
    assert filament(GCODE / name) == (1.75, density, {"diameter_mm": "the job's", "density_g_cm3": "the job's"})
    s = mass_schedule(TuneConfig(freq_y=38.9), None, GCODE / name)
    assert s.total_kg * 1e3 == pytest.approx(grams, rel=1e-9)
    assert filament(GCODE / name, density_g_cm3=1.24)[1:] == (1.24, {"diameter_mm": "the job's",
                                                                      "density_g_cm3": "given"})


def test_a_light_job_needs_no_schedule_and_stays_as_it_was(tmp_path):
    """The 18 g vase-mode tower moves the default printer's Y mode by under 1 %: no band, no line."""
    src = GCODE / "bassco_ender3/ringing_tower.gcode"
    out, cfg_out = tmp_path / "t.gcode", tmp_path / "t.json"
    s = schedule_job(TuneConfig(freq_x=45.5, freq_y=38.9), None, src, output=out, config_out=cfg_out)
    assert not s.needed and s.ripple is None and s.y_schedule() is None
    assert 0 < 1 - s.final_mode_hz / s.empty_mode_hz < 0.02
    assert out.read_bytes() == src.read_bytes() and TuneConfig.load(cfg_out).y_schedule is None
    part = mass_schedule(TuneConfig(freq_y=38.9), None, "part")      # the built-in part by name: 10 g
    assert not part.needed and 0.005 < part.total_kg < 0.02
    assert part.filament_source["density_g_cm3"] == "default"         # its header's density is 0: unset


def test_one_mode_bed_falls_as_one_over_root_mass():
    p = printer_from_dict({"kinematics": "cartesian", "x": {"mass": 0.5, "stiffness": 50000.0},
                           "y": {"mass": 1.0, "stiffness": 60000.0, "damping": 0.05}})
    for load in (0.0, 0.25, 0.5, 2.0):
        assert dominant_y_mode(p, load).freq == pytest.approx(math.sqrt(60000.0 / (1.0 + load)) / (2 * math.pi),
                                                              rel=1e-12)


def test_the_simulated_model_has_those_modes():
    """The MuJoCo model's own matrices (the slip model: rotors on their magnetic springs, springs
    re-solved in series), eigen-solved with 0.4 kg on the bed, hold the Y modes the schedule uses
    and those of the TOML eigen-solve; the rotor modes sit far above (> 200 Hz)."""
    from ringtune.envs.bed_load import loaded, y_modes
    from ringtune.envs.mujoco_model import linear_system

    p = load_printer(None)
    sysm = linear_system(loaded(p, 0.4))
    w2, _ = eigh(sysm.K, np.diag(sysm.mass))
    freqs = np.sqrt(w2) / (2 * np.pi)
    for m in y_modes(p, 0.4):
        assert np.min(np.abs(freqs - m.freq)) < 1e-6 * m.freq
    assert dominant_y_mode(p, 0.4).freq == pytest.approx(_ender3_y_mode(0.4), rel=1e-9)
    assert len(sysm.rotors) == 2 and freqs[-2:].min() > 200


def test_each_band_is_within_2_percent_of_the_y_mode_at_its_mass_and_ripple_halves(block):
    """Acceptance: the default printer (Ender-3 class, a bed slinger), a 402 g solid block; the
    config aims Y at the empty bed's dominant mode, as Klipper's rule aims at the peak."""
    path, e_layers = block
    f0 = _ender3_y_mode(0.0)
    cfg = TuneConfig(shaper_x="mzv", freq_x=45.5, shaper_y="mzv", freq_y=round(f0, 2), accel=3000)
    s = schedule_job(cfg, None, path)
    mass = e_layers * AREA * PLA
    during = np.concatenate([[0], np.cumsum(mass)[:-1]]) + mass / 2
    assert len(s.bands) >= 5                          # the mode falls by 15 %: many bands
    assert s.bands[0].first_layer == 0 and s.bands[-1].last_layer == len(mass) - 1
    for b in s.bands:
        band_mass = 0.5 * (during[b.first_layer] + during[b.last_layer])
        assert b.freq_y == pytest.approx(_ender3_y_mode(band_mass), rel=0.02)
        for k in range(b.first_layer, b.last_layer + 1):     # and every layer of it
            assert b.freq_y == pytest.approx(_ender3_y_mode(during[k]), rel=0.02)
    r = s.ripple
    last = s.bands[-1]
    assert (r["first_layer"], r["last_layer"]) == (last.first_layer, last.last_layer)
    assert r["mass_g"] == pytest.approx(0.5 * (during[last.first_layer] + during[-1]) * 1e3, rel=1e-9)
    assert r["scheduled"]["ripple_mm"] <= 0.5 * r["fixed"]["ripple_mm"], r
    assert r["fixed"]["ripple_mm"] > 0.005          # the fixed frequency really rings (> 5 µm)
    # the lowered acceleration keeps the corners as the tuned config rounds them (tune's resolution)
    assert r["scheduled"]["corner_in_mm"] <= max(r["fixed"]["corner_in_mm"] * 1.05, r["fixed"]["corner_in_mm"] + 0.001)


def test_the_schedule_goes_into_the_job_at_layer_changes_and_nothing_else_changes(block, tmp_path):
    path, _ = block
    cfg = TuneConfig(freq_x=45.5, freq_y=38.9)
    out, cfg_out = tmp_path / "s.gcode", tmp_path / "s.json"
    s = schedule_job(cfg, None, path, output=out, config_out=cfg_out, backend="lti")
    before = path.read_text().splitlines()
    after = out.read_text().splitlines()
    assert [ln for ln in after if not ln.endswith(TAG)] == before
    tagged = [i for i, ln in enumerate(after) if ln.endswith(TAG)]
    added = [i for i in tagged if i + 1 not in tagged]          # the last line of each band's group
    assert len(tagged) == sum(len(b.commands) for b in s.bands) and len(added) == len(s.bands)
    for i, b in zip(added, s.bands):      # after the last extrusion below, before the Z change up
        first = i - len(b.commands) + 1
        if b.first_layer == 0:
            assert first == 5 and after[i + 1] == "G1 Z0.30 F600"      # before the first move (line 6)
            continue
        assert "E" in after[first - 1] and "X" in after[first - 1] and "Y" in after[first - 1]
        assert after[i + 1] == "G1 E-0.8 F2400" and after[i + 3] == f"G1 Z{b.z_mm:.2f} F600"
    job = read_gcode(out)
    assert [e.params["SHAPER_FREQ_Y"] for e in job.shaper_events()] == [b.freq_y for b in s.bands]
    accel_lines = [float(ln.split("=")[1].split()[0]) for ln in after if ln.startswith("SET_VELOCITY_LIMIT")]
    assert accel_lines == [b.accel for b in s.bands if b.accel]
    back = TuneConfig.load(cfg_out)
    assert back.y_schedule == s.y_schedule() and back.freq_y == 38.9


def test_firmware_forms_and_prusas_own_rule():
    assert band_commands("marlin", 33.47, 386) == ["M593 Y F33.47"]
    assert band_commands("marlin-ftm", 33.47, 386) == ["M493 Y A33.47"]
    assert band_commands("prusa", 33.47, 386.4, accel=2500) == ["M74 W386", "M204 P2500"]
    assert band_commands("kalico", 33.4, 0, accel=2500) == ["SET_INPUT_SHAPER SHAPER_FREQ_Y=33.4",
                                                           "SET_VELOCITY_LIMIT ACCEL=2500"]
    assert band_commands("rrf", 33.4, 0, shaper="mzv", damping=0.1) == ['M593 P"mzv" F33.4 S0.1']
    job = read_gcode("\n".join(band_commands("marlin", 33.47, 0) + band_commands("rrf", 33.4, 0)) + "\nG1 X1\n")
    assert [e.params["F"] for e in job.shaper_events()] == [33.47, 33.4]
    # M74.cpp: lerp(F, F + A, W/M), F + A beyond M; defaults A = -20 Hz, M = 800 g
    assert prusa_weight_frequency(40.6, 0) == 40.6
    assert prusa_weight_frequency(40.6, 400) == pytest.approx(30.6)
    assert prusa_weight_frequency(40.6, 1200) == pytest.approx(20.6)


def test_prusa_marlin_and_rrf_say_what_their_firmware_does(block):
    path, _ = block
    prusa = mass_schedule(TuneConfig(firmware="prusa", freq_x=45.5, freq_y=38.9), None, path, band_accel="keep")
    first, last = prusa.bands[0], prusa.bands[-1]
    assert first.commands[0] == f"M593 A{last.freq_y - 38.9:.2f} M{last.grams:.0f}"   # A < 0, no axis
    assert all(b.commands[-1] == f"M74 W{b.mass_kg * 1e3:.0f}" for b in prusa.bands)
    assert last.prusa_default_hz == pytest.approx(38.9 - 20 * last.mass_kg * 1e3 / 800, rel=1e-9)
    for b in prusa.bands:            # the firmware's line, set by M593 A M, stays within 2 % of the mode
        line = 38.9 + (last.freq_y - 38.9) * b.grams / last.grams
        assert b.prusa_hz == pytest.approx(line, rel=1e-9) and b.prusa_hz == pytest.approx(b.mode_hz, rel=0.02)
    assert any("linear rule" in n for n in prusa.notes)
    marlin = mass_schedule(TuneConfig(firmware="marlin", shaper_x="zv", shaper_y="zv", freq_x=45.5, freq_y=38.9),
                           None, path)
    assert all(b.freq_y == 40.0 for b in marlin.bands)        # a stock build's SHAPING_MIN_FREQ
    assert any("below" in n for n in marlin.notes)
    built = mass_schedule(TuneConfig(firmware="marlin", shaper_x="zv", shaper_y="zv", freq_x=45.5, freq_y=38.9),
                          None, path, min_freq=20.0)              # a build with SHAPING_MIN_FREQ 20
    assert [b.freq_y for b in built.bands] == pytest.approx([b.mode_hz for b in built.bands], abs=0.006)
    assert built.bands[-1].commands[0] == f"M593 Y F{built.bands[-1].freq_y:g}"
    rrf = mass_schedule(TuneConfig(firmware="rrf", freq_x=38.9, freq_y=38.9), None, path)
    note = next(n for n in rrf.notes if "one shaper" in n)
    before, after = (float(v) for v in note.split("from ")[1].split(" % on")[0].split(" % to "))
    assert after > before                                      # X pays for following Y


def test_band_acceleration_keeps_the_tuned_smoothing_where_the_frequency_falls_too_far(block):
    path, _ = block
    s = mass_schedule(TuneConfig(freq_x=45.5, freq_y=38.9, accel=3000), None, path)
    accels = [b.accel or 3000 for b in s.bands]
    assert s.bands[0].accel is None               # 1 % lower: (38.9/38.5)² = 1.02 ≤ the 5 % tolerance
    assert accels == sorted(accels, reverse=True) and accels[-1] < 3000
    # Klipper's smoothing of MZV grows as 1/f² at a fixed acceleration, and is ~affine in it (scv):
    # the acceleration falls about as f²
    assert accels[-1] / 3000 == pytest.approx((s.bands[-1].freq_y / 38.9) ** 2, rel=0.1)
    keep = mass_schedule(TuneConfig(freq_x=45.5, freq_y=38.9, accel=3000), None, path, band_accel="keep")
    assert all(b.accel is None for b in keep.bands)


def test_refusals_are_one_line(block, tmp_path, capsys):
    path, _ = block
    with pytest.raises(RingtuneError, match="does not move with Y"):
        mass_schedule(TuneConfig(), load_printer("voron24"), path)
    with pytest.raises(RingtuneError, match="extrudes nothing"):
        job_layers(read_gcode("G1 X10 Y10\nG1 X20\n"))
    cfg = tmp_path / "c.json"
    cfg.write_text(json.dumps(TuneConfig(freq_y=38.9).to_dict()))
    assert cli.main(["schedule", str(path), "--config", str(cfg), "--filament-diameter", "17.5"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--filament-diameter" in err and "Traceback" not in err
    with pytest.raises(RingtuneError, match="y_schedule\\[0\\].freq_y"):
        TuneConfig.from_dict({"y_schedule": [{"z_mm": 1.0, "freq_y": "fast"}]})


def test_schedule_command_json(block, tmp_path, capsys):
    path, _ = block
    cfg = tmp_path / "c.json"
    cfg.write_text(json.dumps(TuneConfig(freq_x=45.5, freq_y=38.9).to_dict()))
    assert cli.main(["schedule", str(path), "--config", str(cfg), "--json", "--filament-density", "1.27"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["filament_density_g_cm3"] == 1.27 and d["filament_diameter_mm"] == 1.75
    assert d["filament_source"] == {"diameter_mm": "default", "density_g_cm3": "given"}
    want = [{"z_mm": b["z_mm"], "freq_y": b["freq_y"], **({"accel": b["accel"]} if b["accel"] else {}),
             "mass_g": round(b["mass_g"], 3)} for b in d["bands"]]      # the default printer's bed is empty
    assert d["y_schedule"] == want
    assert d["last_band"]["fixed"]["ripple_mm"] > d["last_band"]["scheduled"]["ripple_mm"]


def test_a_shaper_placed_off_the_mode_keeps_its_place_and_still_halves_the_ripple(block):
    """tune's pick on the default printer (README: Y 3hump_ei @ 77.1 Hz, twice the mode): each band
    keeps the tuned frequency's ratio to the eigen-solved mode, and the last layer rings less."""
    path, e_layers = block
    cfg = TuneConfig(shaper_x="zvd", freq_x=57.6, damping_x=0.01, shaper_y="3hump_ei", freq_y=77.1,
                     damping_y=0.08, accel=4900)
    s = schedule_job(cfg, None, path)
    ratio = 77.1 / _ender3_y_mode(0.0)
    for b in s.bands:
        assert b.freq_y == pytest.approx(ratio * _ender3_y_mode(b.mass_kg), rel=2e-3)
    assert s.ripple["scheduled"]["ripple_mm"] <= 0.5 * s.ripple["fixed"]["ripple_mm"], s.ripple


def test_the_config_alone_writes_the_same_job_for_every_firmware(tmp_path):
    """``y_schedule`` is a real configuration: from the saved config and the job (no printer, no
    physics) the rewriter's layer_inserts give exactly the lines ``schedule -o`` wrote."""
    from ringtune.shaping.layer_commands import schedule_inserts
    from ringtune.shaping.rewrite import rewrite_job

    path = tmp_path / "small.gcode"            # 40 × 40 × 60 mm in 0.6 mm layers: 119 g, 3 bands
    path.write_text(solid_block(size_mm=40.0, height_mm=60.0, layer_mm=0.6)[0])
    layer_z = [la.z for la in job_layers(read_gcode(path))]
    for fw, shaper in (("klipper", "mzv"), ("prusa", "mzv"), ("marlin-ftm", "zv"), ("rrf", "mzv")):
        cfg = TuneConfig(firmware=fw, shaper_x=shaper, shaper_y=shaper, freq_x=38.9, freq_y=38.9, accel=3000)
        cfg_out = tmp_path / f"{fw}.json"
        s = mass_schedule(cfg, None, path)
        written = "".join(scheduled_lines(s, path))            # what `schedule -o` writes
        s.scheduled_config().save(cfg_out)                     # and --config-out
        back = TuneConfig.load(cfg_out)
        inserts = {k: [f"{c} {TAG}" for c in v] for k, v in schedule_inserts(layer_z, back).items()}
        again = rewrite_job(path.read_text().splitlines(keepends=True), fw, None, layer_inserts=inserts)
        assert "".join(again) == written, fw
        assert any(b.accel for b in s.bands) and len(s.bands) >= 3


def test_rewrite_applies_the_configs_schedule_as_schedule_writes_it(tmp_path):
    """A config with a ``y_schedule`` (``schedule --config-out``) given to ``ringtune rewrite``: the
    rewritten job carries each band's lines at the same layer changes as ``schedule -o`` wrote."""
    from ringtune.envs.job_rewrite import rewrite_file

    path = tmp_path / "small.gcode"
    path.write_text(solid_block(size_mm=40.0, height_mm=60.0, layer_mm=0.6)[0])
    cfg = TuneConfig(firmware="klipper", freq_x=38.9, freq_y=38.9, accel=3000)
    s = mass_schedule(cfg, None, path)
    written = [ln for ln in "".join(scheduled_lines(s, path)).splitlines() if ln.endswith(TAG)]
    out = tmp_path / "r.gcode"
    rewrite_file(path, out, s.scheduled_config())
    tagged = [ln for ln in out.read_text().splitlines() if ln.endswith(TAG)]
    assert tagged == written and len(tagged) >= 3
    freqs = [e.params["SHAPER_FREQ_Y"] for e in read_gcode(out).shaper_events()]
    assert freqs == [b.freq_y for b in s.bands]


def test_a_jobs_own_shaper_command_gives_way_to_the_tuned_one_and_the_bands_follow_it(tmp_path):
    """A start G-code's own SET_INPUT_SHAPER would put the printer on its shaper for the whole print
    (the bands move only Y's frequency): ``schedule -o`` writes the tuned shaper's command in its
    place, said in a note; read back as Klipper reads it, the tuned shaper rules up to the first
    band line, and each band moves only Y's frequency from there. Scheduling the written job again
    leaves the earlier schedule's band lines alone."""
    from ringtune.hardware.dialects import shaper_commands
    from ringtune.shaping.config_plan import plan_with_config
    from ringtune.shaping.job_shapers import shaper_timeline

    own = "SET_INPUT_SHAPER SHAPER_TYPE=zv SHAPER_FREQ_X=30 SHAPER_FREQ_Y=30"
    path = tmp_path / "small.gcode"
    path.write_text(own + "\n" + solid_block(size_mm=40.0, height_mm=60.0, layer_mm=0.6)[0])
    cfg = TuneConfig(firmware="klipper", shaper_x="ei", shaper_y="mzv", freq_x=45.5, freq_y=38.9, accel=3000)
    s = mass_schedule(cfg, None, path)
    assert any(n.startswith(f"the job sets its own input shaper (line 1: {own})") for n in s.notes)
    written = "".join(scheduled_lines(s, path))
    assert written.splitlines()[0] == f"{shaper_commands(cfg)[0]} ; ringtune: in place of the job's own {own}"
    job = read_gcode(written, source="written")
    steps = shaper_timeline(plan_with_config(job, load_printer(None).limits, cfg).plan.events, cfg)
    assert steps[0][1] == cfg and len(steps) == len(s.bands) + 1
    for (_t, before), (_t2, after), band in zip(steps, steps[1:], s.bands):
        assert after == replace(before, freq_y=band.freq_y)          # only Y's frequency moves
    again = tmp_path / "again.gcode"
    again.write_text(written)
    rewritten = scheduled_lines(mass_schedule(cfg, None, again), again)
    assert rewritten[0] == written.splitlines(keepends=True)[0]          # the tuned shaper's own: kept
    bands = [ln for ln in written.splitlines(keepends=True) if TAG in ln]     # the bands' and their accelerations
    assert len(bands) == sum(len(b.commands) for b in s.bands) and all(ln in rewritten for ln in bands)
