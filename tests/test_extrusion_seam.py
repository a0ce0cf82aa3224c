"""Material at a wall's start reached by a travel, a wall a window cuts, and a change of rate after
many cut corners, against exact truth.

A wall that starts where a travel stops (a seam): a centred shaper starts the nozzle turning before
the wall's time, so the nozzle's motion before the extruder starts is the end of the travel, not
wall. Truth for a reversal (travel along +X decelerating to rest at x0 at a, wall back along −X
accelerating at a from rest) under an undamped centred ZV (impulses ½, ½ at ±Δ/2) on a stiff
machine: while both impulses see the same parabola x0 − a·σ²/2, the nozzle is at
x0 − a(τ² + Δ²/4)/2 at τ after the wall's time: it turns δ = a·Δ²/8 short of x0 and then gains
exactly what the planner gains, aτ²/2, which is what the extruder (on the planner's clock) pushes;
once the planner cruises the shaped command is the planner's, so the nozzle has gained δ less than
the extruder has pushed. Over the stretch of 1 mm from where the nozzle turns: δ / 1 mm too much,
and never too little (the material for the δ the nozzle never reaches is laid on the next mm).
"""

from __future__ import annotations

import numpy as np
import pytest

from ringtune.envs.window_metrics import compute_metrics
from ringtune.shaping.apply import shape_motion
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.e_timing import extruder_command
from ringtune.shaping.features import FEATURE_CLASSES
from ringtune.shaping.firmware import FIRMWARES
from ringtune.shaping.motion import Motion
from ringtune.shaping.shapers import shapers_from_config
from tests.test_seen_measures import StiffSim

A, V, F = 5000.0, 50.0, 40.0      # mm/s², mm/s (ramps of V²/2A = 0.25 mm), Hz
WALL, E_PER_MM, RATE = 20.0, 0.033, 100_000.0


def reversal_seam() -> Motion:
    """20 ms at rest, a travel of 0.5 mm along +X (accelerate, decelerate to rest at x = 0.5), then
    a wall of WALL mm back along −X from rest to rest, extruding E_PER_MM per mm."""
    td = V / A
    cruise = (WALL - V * td) / V
    t = np.cumsum([0.0, 0.02, td, td, td, cruise, td])
    ax = [0.0, A, -A, -A, 0.0, A]
    acc = np.array([[a, 0, 0, 0] for a in ax], float)
    acc[3:, 3] = np.array(ax[3:]) * -E_PER_MM          # E rises as X falls along the wall
    extruding = np.array([False, False, False, True, True, True])
    return Motion.from_constant_accel(t, acc, p0=[0.0, 0.0, 0.2, 5.0], extruding=extruding)


def klipper_zv_metrics(mo: Motion, t_hi: float | None = None):
    """Metrics of ``mo`` under Klipper's ZV at F Hz, no damping (centred), stiff machine; samples
    up to ``t_hi`` s (default: all of the shaped motion)."""
    cfg = TuneConfig(firmware="klipper", shaper_x="zv", shaper_y="zv", freq_x=F, freq_y=F,
                     damping_x=0.0, damping_y=0.0)
    shapers, centred = shapers_from_config(cfg)
    sx = shapers["x"]
    assert centred and sx.duration == pytest.approx(0.5 / F)
    shaped = shape_motion(mo, shapers, centred)
    t = np.arange(shaped.t[0], shaped.t[-1] if t_hi is None else t_hi, 1.0 / RATE)
    sim = StiffSim(t, shaped.position(t)[:, :2], np.zeros((len(t), 2)))
    e_cmd = extruder_command(mo, shapers, centred, FIRMWARES["klipper"])
    return compute_metrics(sim, mo, settle=sx.duration - sx.centre_delay, anticipate=sx.centre_delay,
                           e_command=e_cmd)


def test_a_travel_ending_at_the_walls_start_is_not_wall_the_nozzle_failed_to_fill():
    """δ = a·Δ²/8 = 0.098 mm too much over the first mm and nothing short (it read 16.4 % short
    and 16.4 % too much: the travel's last 2δ before the wall's time counted as wall)."""
    delta = A * (0.5 / F) ** 2 / 8.0
    m = klipper_zv_metrics(reversal_seam())
    assert m.extrusion_over_pct == pytest.approx(100.0 * delta, rel=1e-2)
    assert m.extrusion_under_pct < 0.05


def test_a_wall_the_window_cuts_within_its_first_mm_has_no_stretch_to_judge():
    """Samples ending 0.4 mm into the wall: the run goes on beyond them, so no stretch of 1 mm is
    whole; its first 0.4 mm is not a short run of its own (read as one, it was 30.7 % short)."""
    mo = reversal_seam()
    t_wall = mo.t[3]
    tau = np.sqrt(2 * 0.25 / A) + 0.15 / V          # 0.25 mm of ramp, 0.15 mm of cruise
    m = klipper_zv_metrics(mo, t_hi=t_wall + tau)
    assert m.extrusion_over_pct == 0.0 and m.extrusion_under_pct == 0.0
    whole = klipper_zv_metrics(mo)
    assert whole.extrusion_over_pct > 5.0          # the same start, judged whole, is judged


def meander_then_wall() -> tuple[Motion, np.ndarray]:
    """From rest up Y, a meander of 20 right-angle corners at 100 mm/s (legs of 2 mm along ±Y, 1 mm
    along +X), 2 mm more along +X, a 28 mm wall along +X whose rate quadruples after 15 mm, 2 mm
    more, to rest. Returns the motion and each segment's class (the wall outer_wall, the rest
    infill: at the stop the extruder on the planner's clock runs a·Δ²/8 ahead of the centred
    command, which is not the wall's to judge here)."""
    v = 100.0
    ramp_t = v / 20000.0
    legs = [((0.0, 1.0), 2.0 - v * ramp_t / 2)]
    for k in range(10):
        legs += [((1.0, 0.0), 1.0), ((0.0, -1.0 if k % 2 == 0 else 1.0), 2.0)]
    legs += [((1.0, 0.0), 2.0), ((1.0, 0.0), 15.0), ((1.0, 0.0), 13.0), ((1.0, 0.0), 2.0 - v * ramp_t / 2)]
    rates = [E_PER_MM] * (len(legs) - 2) + [4 * E_PER_MM] * 2
    cls = ["infill"] * (len(legs) - 3) + ["outer_wall", "outer_wall", "infill"]
    t, p, vel = [0.0, ramp_t], [[0.0, 0.0, 0.2, 5.0]], [[0.0, 0.0, 0.0, 0.0]]
    acc = [[0.0, 20000.0, 0.0, 20000 * E_PER_MM]]
    pos = np.array([0.0, v * ramp_t / 2, 0.2, 5.0 + v * ramp_t / 2 * E_PER_MM])
    for (dx, dy), length in legs:
        rate = rates[len(p) - 1]
        p.append(pos.tolist())
        vel.append([v * dx, v * dy, 0.0, v * rate])
        acc.append([0.0, 0.0, 0.0, 0.0])
        pos = pos + np.array([dx * length, dy * length, 0.0, length * rate])
        t.append(t[-1] + length / v)
    p.append(pos.tolist())
    vel.append([v, 0.0, 0.0, v * rates[-1]])
    acc.append([-20000.0, 0.0, 0.0, -20000.0 * rates[-1]])
    t.append(t[-1] + ramp_t)
    classes = [FEATURE_CLASSES.index(c) for c in ["infill", *cls, "infill"]]
    mo = Motion(np.array(t), np.array(p), np.array(vel), np.array(acc), np.ones(len(p), bool))
    return mo, np.array(classes)


def test_corners_cut_earlier_in_a_run_do_not_move_a_later_change_of_rate():
    """On a straight wall the centred shaper puts the nozzle where the planner is and E follows the
    planner: every stretch of the wall gets what it asks, across its fourfold change of rate too.
    The 20 corners before it, each cut short, saved the nozzle path; counted on from there, the
    change of rate landed 8.7 mm early (it read 300 % too much on the wall)."""
    mo, classes = meander_then_wall()
    cfg = TuneConfig(firmware="klipper", shaper_x="zv", shaper_y="zv", freq_x=F, freq_y=F,
                     damping_x=0.0, damping_y=0.0)
    shapers, centred = shapers_from_config(cfg)
    sx = shapers["x"]
    shaped = shape_motion(mo, shapers, centred)
    t = np.arange(shaped.t[0], shaped.t[-1], 1.0 / RATE)
    sim = StiffSim(t, shaped.position(t)[:, :2], np.zeros((len(t), 2)))
    m = compute_metrics(sim, mo, settle=sx.duration - sx.centre_delay, anticipate=sx.centre_delay,
                        classes=classes, e_command=extruder_command(mo, shapers, centred, FIRMWARES["klipper"]))
    wall = m.features["outer_wall"]
    assert wall["extrusion_over_pct"] < 0.5 and wall["extrusion_under_pct"] < 0.5
    assert m.features["infill"]["extrusion_over_pct"] > 2.0          # the corners themselves are judged


@pytest.mark.parametrize("phase", [0.0, 0.3, 0.7])
def test_a_blob_on_a_fast_wall_reads_its_own_share_of_one_mm(phase):
    """A straight wall at 150 mm/s, the nozzle on it, the extruder pushing ε = 10 % of a
    millimetre's filament more over 1 ms: every stretch of exactly 1 mm holding the blob lays
    10 % too much. At 2 kHz the samples are 0.075 mm apart; a stretch that ran to the first
    sample past 1 mm was 1.05 mm long here and read 9.52 %. Its end is now placed between the two
    samples about it."""
    v, e_mm, t0, tau = 150.0, 0.033, 0.06, 0.001
    eps, t_end = 0.1 * e_mm, WALL / v
    path = Motion(np.array([0.0, t_end]), np.array([[0.0, 0.0, 0.2, 0.0]]), np.array([[v, 0.0, 0.0, v * e_mm]]),
                  np.zeros((1, 4)), np.array([True]))
    e_cmd = Motion(np.array([0.0, t0, t0 + tau, t_end + 0.01]),
                   np.array([[0.0], [e_mm * v * t0], [e_mm * v * (t0 + tau) + eps]]),
                   np.array([[e_mm * v], [e_mm * v + eps / tau], [e_mm * v]]), np.zeros((3, 1)), np.ones(3, bool))
    t = np.arange(phase / 2000.0, t_end, 1 / 2000.0)
    sim = StiffSim(t, path.position(t)[:, :2], np.zeros((len(t), 2)))
    m = compute_metrics(sim, path, e_command=e_cmd, classes=np.array([FEATURE_CLASSES.index("outer_wall")]))
    assert m.extrusion_over_pct == pytest.approx(10.0, rel=1e-3)
