"""The evaluation pipeline's windowing, shaping, lag and settle on a rigid printer (nozzle = command).

On a perfectly rigid machine the only quality loss is the shaper's own corner smoothing, which cuts
corners inward: no overshoot, and no ringing once the shaped command runs straight along the wall.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from ringtune.envs.planned_job import PlannedJob
from ringtune.envs.windows import metrics_of, window_runs
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.motion import Motion

RATE = 20_000.0


def trapezoid_square() -> tuple[Motion, float]:
    """+x 20 mm then +y 20 mm, each accelerating at 3000 mm/s² to 100 mm/s and stopping; returns
    (motion, time of the corner)."""
    acc, v = 3000.0, 100.0
    ta = v / acc
    tc = (20.0 - v * ta) / v  # cruise time
    t = np.cumsum([0.0, ta, tc, ta, ta, tc, ta])
    a = np.array([[acc, 0], [0, 0], [-acc, 0], [0, acc], [0, 0], [0, -acc]], float)
    a4 = np.zeros((6, 4))
    a4[:, :2] = a
    m = Motion.from_constant_accel(t, a4, extruding=np.ones(6, bool))
    assert np.allclose(m.end_position[:2], [20.0, 20.0])
    return m, float(t[3])


def rigid_sims(runs):
    sims = []
    for r in runs:
        tt, pos = r.shaped.sample(RATE)
        _, acc = r.shaped.sample(RATE, what="acceleration")
        sims.append(SimpleNamespace(t=tt, commanded=pos[:, :2], nozzle=pos[:, :2],
                                    head_accel=acc[:, :2], step_loss=False))
    return sims


def motion_plan(motion):
    """A stand-in for a planned job's plan made of one motion (what window_runs reads of it)."""
    return SimpleNamespace(motion=motion, print_time=motion.duration, start_time=motion.start_time,
                           end_time=motion.end_time, motion_window=motion.window)


def run(config: TuneConfig, settle_override=None):
    motion, tc = trapezoid_square()
    pj = PlannedJob(motion_plan(motion),
                    [SimpleNamespace(t0=tc - 0.1, t1=tc + 0.15, kind="corner")])
    runs = window_runs(pj, config, settle=0.02)
    if settle_override is not None:
        for r in runs:
            r.settle = settle_override(r.settle)
    return metrics_of(runs, rigid_sims(runs), pj.print_time), runs


def test_no_shaping_on_a_rigid_printer_is_perfect():
    m, runs = run(TuneConfig(shaper_x="none", shaper_y="none"))
    assert m.path_error_mm < 1e-9 and m.overshoot_mm == 0.0 and m.ringing_mm < 1e-9
    assert m.peak_accel == pytest.approx(3000.0)
    assert m.print_time_s == pytest.approx(trapezoid_square()[0].duration)


@pytest.mark.parametrize("firmware,shaper", [("klipper", "mzv"), ("klipper", "ei"), ("rrf", "zvd"),
                                             ("marlin", "zv")])
def test_shaping_cuts_the_corner_inward_and_leaves_no_ringing(firmware, shaper):
    cfg = TuneConfig(firmware=firmware, shaper_x=shaper, shaper_y=shaper, freq_x=35.0, freq_y=30.0,
                     damping_x=0.1, damping_y=0.1)
    m, runs = run(cfg)
    assert m.path_error_mm > 1e-3          # the smoothing is seen...
    assert m.overshoot_mm == 0.0           # ...but never outward on a rigid printer
    assert m.ringing_mm < 1e-9             # the wall is straight once the shaper has turned
    # a wall window starting before the shaper finished turning sees the smoothing as ringing
    m_early, _ = run(cfg, settle_override=lambda s: s - 0.01)
    assert m_early.ringing_mm > 1e-4
    # the lag is the centroid for causal firmwares and zero for centred ones
    r = runs[0]
    assert (r.lag > 0) == (firmware in ("rrf", "marlin"))
    # the shaped window has the lead-in: shaper duration + settle before the quality window
    assert r.shaped.start_time <= r.t0 - 0.02 + 1e-9


def zigzag(n_legs: int = 6) -> Motion:
    """Legs of 40 ms (10 ms accelerating at 2000 mm/s², 20 ms cruising, 10 ms stopping) turning
    90° each time: +x, +y, −x, +y, ..."""
    dirs = [(1, 0), (0, 1), (-1, 0), (0, 1)]
    t, a = [0.0], []
    for k in range(n_legs):
        d = np.array(dirs[k % 4], float) * 2000.0
        for dt, acc in ((0.01, d), (0.02, 0 * d), (0.01, -d)):
            t.append(t[-1] + dt)
            a.append([acc[0], acc[1], 0.0, 0.0])
    return Motion.from_constant_accel(np.array(t), np.array(a), extruding=np.ones(len(a), bool))


@pytest.mark.parametrize("firmware,shaper", [("klipper", "mzv"), ("rrf", "zvd"), ("marlin-ftm", "zv")])
def test_short_walls_are_straight_between_the_shaper_turns(firmware, shaper):
    """Walls shorter than the settling plus the next corner's anticipation still measure zero
    ringing on a rigid printer: the window ends where the shaped command starts the next turn."""
    motion = zigzag()
    pj = PlannedJob(motion_plan(motion),
                    [SimpleNamespace(t0=0.04, t1=0.2, kind="zigzag")])
    cfg = TuneConfig(firmware=firmware, shaper_x=shaper, shaper_y=shaper, freq_x=70.0, freq_y=70.0)
    runs = window_runs(pj, cfg, settle=0.02)
    m = metrics_of(runs, rigid_sims(runs), pj.print_time)
    assert m.ringing_mm < 1e-9 and m.overshoot_mm == 0.0 and m.path_error_mm > 1e-3
    # without the anticipation the next corner's smoothing leaks in (centred shapers only)
    if runs[0].anticipate > 0:
        for r in runs:
            r.anticipate = 0.0
        assert metrics_of(runs, rigid_sims(runs), pj.print_time).ringing_mm > 1e-4
