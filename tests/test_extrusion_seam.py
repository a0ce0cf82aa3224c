"""Material at a wall's start reached by a travel, and a wall a window cuts, against exact truth.

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
