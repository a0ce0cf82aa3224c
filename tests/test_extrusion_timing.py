"""The extruder under input shaping, per firmware (seed 002), against ΣAᵢTᵢ·v.

A straight line from rest to rest at 100 mm/s (20000 mm/s²: the acceleration ends within 0.25 mm)
on a stiff machine (the nozzle is the shaped X/Y command). The shaped axes lag the planner by their
shaper's centroid ΣAᵢTᵢ (causal) or not at all on average (centred); the extruder follows the
firmware's own rule. Truth: the lag computed here from the shaper's impulses, times the speed;
on cruise the extruder leads the nozzle by exactly that where the firmware leaves E on the
planner's clock behind delayed X/Y, and by nothing where E is shaped or delayed alike or X/Y are
centred; from rest (and to rest) that lead builds up (and falls) within the first (last) mm of
path, so the material there is off by lead/1 mm.
"""

from __future__ import annotations

import numpy as np
import pytest

from ringtune.envs.window_metrics import compute_metrics
from ringtune.shaping.apply import shape_motion
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.e_timing import E_TIMINGS, XY_DELAYS, extruder_command
from ringtune.shaping.features import FEATURE_CLASSES
from ringtune.shaping.firmware import FIRMWARES
from ringtune.shaping.motion import Motion
from ringtune.shaping.shapers import shapers_from_config
from tests.test_seen_measures import StiffSim

V, A, LENGTH = 100.0, 20000.0, 60.0
E_PER_MM = 0.033
RATE = 100_000.0

#: a shaper each firmware has (RepRapFirmware has no ZV)
SHAPER = {"rrf": "zvd", "rrf35": "zvd", "rrf34": "zvd"}


def line() -> Motion:
    """Rest to rest along X, extruding E_PER_MM per mm."""
    td = V / A
    cr = (LENGTH - V * td) / V
    t = np.cumsum([0.0, td, cr, td])
    acc = np.array([[A, 0, 0, A * E_PER_MM], [0, 0, 0, 0], [-A, 0, 0, -A * E_PER_MM]], float)
    return Motion.from_constant_accel(t, acc, p0=[0.0, 0.0, 0.2, 5.0], extruding=np.ones(3, bool))


def judged(firmware: str, timing: str | None = None, cruise_only: bool = False):
    cfg = TuneConfig(firmware=firmware, shaper_x=SHAPER.get(firmware, "zv"), shaper_y=SHAPER.get(firmware, "zv"),
                     freq_x=40.0, freq_y=40.0, damping_x=0.05, damping_y=0.05)
    shapers, centred = shapers_from_config(cfg)
    mo = line()
    shaped = shape_motion(mo, shapers, centred)
    e_cmd = extruder_command(mo, shapers, centred, FIRMWARES[firmware], timing)
    sx = shapers["x"]
    lo, hi = shaped.t[0], shaped.t[-1]
    if cruise_only:   # well inside the cruise, on every clock
        lo, hi = mo.t[1] + 2 * sx.duration, mo.t[2] - 2 * sx.duration
    t = np.arange(lo, hi, 1.0 / RATE)
    sim = StiffSim(t, shaped.position(t)[:, :2], np.zeros((len(t), 2)))
    lag = 0.0 if centred else sx.centroid
    m = compute_metrics(sim, mo, lag=lag, settle=sx.duration - (sx.centre_delay if centred else 0.0),
                        anticipate=sx.centre_delay if centred else 0.0, e_command=e_cmd)
    return m, sx, centred


def expected_lead(firmware: str, timing: str, sx, centred: bool) -> float:
    """mm the extruder leads the nozzle on cruise: v × (the mean delay of the firmware's X/Y − the
    delay of its E). X/Y: centred impulses are delayed by ΣAᵢTᵢ − the centre the firmware removes
    (0 unless it rounds the centre, as FT_MOTION does to whole 1 ms samples); causal ones by ΣAᵢTᵢ;
    FT_MOTION's axis synchronisation delays every shaped axis by its rounded centre on top of the
    centred impulses, ΣAᵢTᵢ on average. E: not at all (neither), by X/Y's (rounded) delay (delayed),
    or as X/Y (shaped)."""
    fw = FIRMWARES[firmware]
    centroid = float(np.dot(sx.amplitudes, sx.times))
    xy = {"centred": centroid - sx.centre_delay, "causal": centroid, "largest": centroid}[fw.xy_delay]
    e = {"neither": 0.0, "shaped": xy,
         "delayed": sx.centre_delay if fw.xy_delay == "largest" else centroid}[timing]
    return V * (xy - e)


def marlin_zv(mo: Motion):
    """Metrics of ``mo`` under Marlin's classic ZV at 40 Hz, no damping (halves 12.5 ms apart, lag
    6.25 ms), on a stiff machine, with Marlin's extruder; and the shaped command's samples."""
    cfg = TuneConfig(firmware="marlin", shaper_x="zv", shaper_y="zv", freq_x=40.0, freq_y=40.0,
                     damping_x=0.0, damping_y=0.0)
    shapers, centred = shapers_from_config(cfg)
    assert float(np.dot(shapers["x"].amplitudes, shapers["x"].times)) == pytest.approx(0.00625)
    shaped = shape_motion(mo, shapers, centred)
    t = np.arange(shaped.t[0], shaped.t[-1], 1.0 / RATE)
    sim = StiffSim(t, shaped.position(t)[:, :2], np.zeros((len(t), 2)))
    e_cmd = extruder_command(mo, shapers, centred, FIRMWARES["marlin"])
    return compute_metrics(sim, mo, lag=0.00625, settle=0.0125, e_command=e_cmd), sim, e_cmd


@pytest.mark.parametrize("firmware", list(FIRMWARES))
def test_cruise_lead_is_the_shaped_axes_lag_times_speed(firmware):
    fw = FIRMWARES[firmware]
    for timing in {fw.e_timing, fw.e_sync_timing} - {""}:
        m, sx, centred = judged(firmware, timing, cruise_only=True)
        lead = expected_lead(firmware, timing, sx, centred)
        assert m.e_lag_mm == pytest.approx(abs(lead), abs=2e-4), timing
        # steady lead: the same material per mm as asked
        assert m.extrusion_over_pct < 0.1 and m.extrusion_under_pct < 0.1


def test_e_timing_of_each_firmware():
    assert {f.e_timing for f in FIRMWARES.values()} <= set(E_TIMINGS)
    assert {f.xy_delay for f in FIRMWARES.values()} <= set(XY_DELAYS)
    assert all(f.e_source for f in FIRMWARES.values())
    assert FIRMWARES["klipper"].e_timing == "neither" and FIRMWARES["klipper"].xy_delay == "centred"
    assert FIRMWARES["rrf"].e_timing == "shaped"
    assert FIRMWARES["marlin"].e_timing == "neither" and FIRMWARES["marlin"].xy_delay == "causal"
    ftm = FIRMWARES["marlin-ftm"]
    assert (ftm.e_timing, ftm.xy_delay, ftm.e_sync_timing) == ("neither", "largest", "delayed")
    assert all(bool(f.e_sync) == bool(f.e_sync_timing) for f in FIRMWARES.values())


@pytest.mark.parametrize("firmware", ["marlin", "marlin-ftm"])
def test_start_and_stop_of_a_line_when_e_leads(firmware):
    """E on the planner's clock, X/Y delayed: the first mm of the line gets lead/1 mm too much
    material, the last mm that much too little."""
    m, sx, centred = judged(firmware)
    lead = expected_lead(firmware, "neither", sx, centred)
    assert lead > 0.4
    assert m.e_lag_mm == pytest.approx(lead, rel=1e-3)
    assert m.extrusion_over_pct == pytest.approx(100 * lead / 1.0, rel=2e-3)
    assert m.extrusion_under_pct == pytest.approx(100 * lead / 1.0, rel=2e-3)
    assert m.features["other"]["extrusion_over_pct"] == pytest.approx(m.extrusion_over_pct)


def test_shaped_extruder_lays_what_is_asked():
    m, _, _ = judged("rrf")
    assert m.e_lag_mm < 1e-6
    assert m.extrusion_over_pct < 1e-4 and m.extrusion_under_pct < 1e-4


def test_extrusion_worked_example_of_the_docstring():
    """Marlin classic ZV at 40 Hz, no damping: halves 12.5 ms apart, lag 6.25 ms, 0.625 mm at
    100 mm/s; 62.5 % too much material over the first mm, too little over the last."""
    mo = line()
    m, sim, e_cmd = marlin_zv(mo)
    assert m.e_lag_mm == pytest.approx(0.625, rel=1e-3)
    assert m.extrusion_over_pct == pytest.approx(62.5, rel=2e-3)
    assert m.extrusion_under_pct == pytest.approx(62.5, rel=2e-3)
    # the same line as sparse infill: nobody sees its material, so the job's figures leave it out
    # and its own stay in features; as solid infill (under a top surface) it counts
    for label, counted in (("infill", False), ("solid_infill", True)):
        cls = np.full(mo.n_segments, FEATURE_CLASSES.index(label))
        lm = compute_metrics(sim, mo, lag=0.00625, settle=0.0125, classes=cls, e_command=e_cmd)
        assert lm.features[label]["extrusion_over_pct"] == pytest.approx(62.5, rel=2e-3)
        assert lm.extrusion_over_pct == (pytest.approx(62.5, rel=2e-3) if counted else 0.0)


def line_changing_rate(factor: float) -> Motion:
    """:func:`line` whose extrusion rate changes by ``factor`` halfway along (two moves, one leg)."""
    td, r1, r2 = V / A, E_PER_MM, factor * E_PER_MM
    x_ramp, half = V * td / 2, LENGTH / 2
    t = np.cumsum([0.0, td, (half - x_ramp) / V, (LENGTH - half - x_ramp) / V, td])
    e1 = 5.0 + x_ramp * r1
    e2 = e1 + (half - x_ramp) * r1
    e3 = e2 + (LENGTH - half - x_ramp) * r2
    p = [[0, 0, 0.2, 5.0], [x_ramp, 0, 0.2, e1], [half, 0, 0.2, e2], [LENGTH - x_ramp, 0, 0.2, e3]]
    v = [[0, 0, 0, 0], [V, 0, 0, V * r1], [V, 0, 0, V * r2], [V, 0, 0, V * r2]]
    a = [[A, 0, 0, A * r1], [0, 0, 0, 0], [0, 0, 0, 0], [-A, 0, 0, -A * r2]]
    return Motion(t, p, v, a, np.ones(4, bool))


def test_a_line_whose_rate_changes_midway_is_judged_in_filament():
    """The extrusion rate quadruples halfway along the line (a slicer's legs differ in filament per
    mm of path). Marlin ZV at 40 Hz puts E 0.625 mm of path ahead of the nozzle: the stretch of 1 mm
    ending at the change gets the new rate over its last 0.625 mm, (4 − 1) × 0.625 = 187.5 % more
    than asked; the shortfall is the stop's, 62.5 % — never beyond 100 % (a lead in mm of path
    read at each end's own rate would make it −187.5 % where the lead drops from 2.5 to 0.625 mm)."""
    m, _, _ = marlin_zv(line_changing_rate(4.0))
    assert m.extrusion_over_pct == pytest.approx(187.5, rel=2e-3)
    assert m.extrusion_under_pct == pytest.approx(62.5, rel=2e-3)


@pytest.mark.parametrize("factor", [4.0, 0.25, 1.3])
def test_the_lead_across_a_change_of_rate_is_the_path_between_nozzle_and_extruder(factor):
    """E runs 6.25 ms ahead of the nozzle at 100 mm/s: 0.625 mm of path wherever the rate changes
    (where the extruder has got to, read along the path at each move's own rate; read at the leg's
    mean rate it was 1.0 mm for a fourfold change)."""
    m, _, _ = marlin_zv(line_changing_rate(factor))
    assert m.e_lag_mm == pytest.approx(0.625, rel=1e-3)


def test_retraction_after_the_line_is_not_material_taken_back():
    """E leading X/Y retracts while the nozzle still finishes the line: the part keeps what was
    laid (the shortfall at the stop is the lead, not the retraction)."""
    mo = line()
    end = mo.end_state()[0][-1]
    retract = Motion(np.array([mo.t[-1], mo.t[-1] + 0.02]), end[None, :], np.array([[0, 0, 0, -40.0]]),
                     np.zeros((1, 4)), np.zeros(1, bool))
    m, _, _ = marlin_zv(Motion.concatenate([mo, retract]))
    assert m.extrusion_under_pct == pytest.approx(62.5, rel=2e-3)


@pytest.mark.parametrize("firmware, shaper", [("marlin", "zv"), ("rrf", "zvd"), ("klipper", "zv")])
def test_plan_trajectory_writes_the_extruder_as_the_firmware_commands_it(tmp_path, capsys, firmware, shaper):
    """From the CSV alone: on the cruise of a long line, the e column leads the material the path
    holds at the written x by ΣAᵢTᵢ·v where the firmware leaves E behind delayed X/Y (Marlin), and
    not at all where E is shaped with X/Y (RepRapFirmware) or X/Y are centred (Klipper)."""
    import json

    from ringtune.agents.cli.main import main

    job = tmp_path / "line.gcode"
    job.write_text("G90\nM83\nG1 X10 Y10 F6000\nG1 X110 Y10 E3.3 F6000\n")
    cfg = tmp_path / "c.json"
    cfg.write_text(json.dumps({"firmware": firmware, "shaper_x": shaper, "shaper_y": shaper,
                               "freq_x": 40, "freq_y": 40, "damping_x": 0.05, "damping_y": 0.05}))
    traj = tmp_path / "t.csv"
    assert main(["plan", str(job), "--config", str(cfg), "--trajectory", str(traj), "--rate", "2000"]) == 0
    capsys.readouterr()
    t, x, _, _, e = np.loadtxt(traj, delimiter=",", skiprows=1, usecols=range(5)).T
    cruise = (x > 40) & (x < 80)                     # well away from the ends, at 100 mm/s
    asked = 0.033 * (x[cruise] - 10.0)               # filament the path holds up to x (E from 0)
    lead = (e[cruise] - asked) / 0.033
    shapers, centred = shapers_from_config(TuneConfig.load(cfg))
    lag = float(np.dot(shapers["x"].amplitudes, shapers["x"].times))
    want = V * lag if firmware == "marlin" else 0.0
    np.testing.assert_allclose(lead, want, atol=2e-3)


def test_shaped_extruder_follows_the_shaped_path_with_two_shapers():
    """Kalico's enabled_extruders (its E synchronisation) with a different shaper on X and Y, on a
    30° line: the filament follows the nozzle's progress along the line, the projection of the
    shaped X/Y, u_x²·X-shaped + u_y²·Y-shaped; on a stiff machine the extruder never leaves the
    nozzle."""
    cfg = TuneConfig(firmware="kalico", shaper_x="zv", shaper_y="mzv", freq_x=40.0, freq_y=55.0,
                     damping_x=0.05, damping_y=0.05)
    shapers, centred = shapers_from_config(cfg)
    u = np.array([np.cos(np.radians(30)), np.sin(np.radians(30))])
    td = V / A
    cr = (LENGTH - V * td) / V
    t = np.cumsum([0.0, td, cr, td])
    acc = np.array([[A * u[0], A * u[1], 0, A * E_PER_MM], [0, 0, 0, 0], [-A * u[0], -A * u[1], 0, -A * E_PER_MM]])
    mo = Motion.from_constant_accel(t, acc, p0=[0.0, 0.0, 0.2, 5.0], extruding=np.ones(3, bool))
    shaped = shape_motion(mo, shapers, centred)
    ts = np.arange(shaped.t[0], shaped.t[-1], 1.0 / RATE)
    sim = StiffSim(ts, shaped.position(ts)[:, :2], np.zeros((len(ts), 2)))
    lag = max(s.duration for s in shapers.values())
    common = dict(settle=lag, anticipate=lag)       # straight spans well clear of the start and stop
    fw = FIRMWARES["kalico"]
    synced = compute_metrics(sim, mo, e_command=extruder_command(mo, shapers, centred, fw, "shaped"), **common)
    plain = compute_metrics(sim, mo, e_command=extruder_command(mo, shapers, centred, fw), **common)
    assert synced.e_lag_mm < 1e-6
    # what remains is the nozzle's detour off the line while the two axes' shapers disagree (about
    # 37 µm across over a fraction of a mm: a path that much longer than the line)
    assert synced.extrusion_over_pct < 1.0 and synced.extrusion_under_pct < 1.0
    # unshaped, the extruder keeps the planner's time while the axes start and stop on their own
    # shapers' (centred) clocks: the material at the start and stop is off by far more
    assert plain.extrusion_over_pct > 5 * synced.extrusion_over_pct


def test_no_stretch_is_short_of_more_material_than_it_asks(data_dir):
    """Cura's cut plate: its first wall after the cut carries 1200 mm of filament over 160 mm of path
    (7.5 mm per mm, against 0.03–0.1 elsewhere). Unshaped, the nozzle lags that rate change and
    every shortfall stays a shortfall of what was asked: at most 100 %, in every class (read in mm
    of path at each end's own rate, this read 301 %); and a run's last stretch, which the nozzle's
    travel carries past the path's end, is not divided by nothing (the built-in print)."""
    from ringtune.envs.evaluate import evaluate
    none = TuneConfig(shaper_x="none", shaper_y="none", accel=3000.0)
    m = evaluate(none, None, data_dir / "gcode/fastlb_cura_um2/platte_klein_cut.gcode")
    assert 0 < m.extrusion_under_pct <= 100.0
    assert all(f["extrusion_under_pct"] <= 100.0 for f in m.features.values())
    pick = evaluate(TuneConfig(shaper_x="ei", shaper_y="mzv", freq_x=51.4, freq_y=46.6, accel=4800.0))
    assert 0 < pick.extrusion_over_pct < 100.0 and 0 < pick.extrusion_under_pct < 100.0
