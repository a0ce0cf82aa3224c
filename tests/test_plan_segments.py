"""A plan's motion built where asked (shaping/plan_segments.py): every span, velocity and x/y row it
gives is bit for bit what the whole motion gives, the whole motion is continuous, and judging a
configuration on a real sliced job never builds the whole motion."""

from __future__ import annotations

import numpy as np
import pytest

from ringtune.envs.evaluate import evaluate_many
from ringtune.envs.planned_job import _nbytes, clear_cache, planned_job
from ringtune.envs.printer import load_printer
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.planner import plan
from ringtune.shaping.plan_segments import PlanSegments

PART = "part"


@pytest.fixture(scope="module")
def part_plan():
    """The built-in sliced part planned at the default printer's limits, the whole motion not built."""
    return planned_job(load_printer(None), PART, TuneConfig(accel=5000.0), job_accel="replace").plan


def test_the_whole_motion_is_continuous(part_plan):
    """Each segment ends where the next starts, and inside a move at the speed it starts the
    next with, from the recipe alone."""
    m = part_plan.segments.motion()
    p_end, v_end = m.end_state()
    assert np.allclose(p_end[:-1], m.p[1:], atol=1e-9)
    same_move = (m.move[1:] == m.move[:-1]) & (m.move[1:] >= 0)
    assert same_move.sum() > 1000
    assert np.allclose(v_end[:-1][same_move], m.v[1:][same_move], atol=1e-7)
    assert m.t[0] == 0.0 and part_plan.end_time == m.t[-1] <= part_plan.print_time


def test_spans_velocities_and_xy_rows_are_the_whole_motions(part_plan):
    seg = part_plan.segments
    whole = seg.motion()
    rng = np.random.default_rng(7)
    for t0 in rng.uniform(whole.t[0] - 1.0, whole.t[-1], 25):
        t1 = t0 + rng.uniform(0.01, 2.0)
        if min(t1, whole.t[-1]) <= max(t0, whole.t[0]):
            continue
        got, want = seg.window(t0, t1), whole.window(t0, t1)
        for name in ("t", "p", "v", "a", "extruding", "move"):
            assert np.array_equal(getattr(got, name), getattr(want, name)), name
    times = np.concatenate([rng.uniform(whole.t[0] - 1.0, whole.t[-1] + 1.0, 500), whole.t[:50]])
    assert np.array_equal(seg.velocity(times), whole.velocity(times))
    xy = seg.xy_kinematics()
    assert np.array_equal(xy.v, whole.v[:, :2]) and np.array_equal(xy.a, whole.a[:, :2])
    assert np.array_equal(xy.move, whole.move) and np.array_equal(xy.t, whole.t)


def test_a_plan_answers_alike_before_and_after_its_motion_is_built():
    job = "G28\nG90\nM83\nG1 X10 Y0 F6000\nG1 X10 Y10 E1\nG4 P100\nG1 X0 Y10 E1\nG1 X0 Y0 E1\n"
    before, after = plan(job), plan(job)
    motion = after.motion                      # built
    times = np.linspace(-0.1, motion.t[-1] + 0.1, 97)
    assert np.array_equal(before.velocity(times), after.velocity(times))
    w0, w1 = before.motion_window(0.05, 0.3), after.motion_window(0.05, 0.3)
    assert np.array_equal(w0.p, w1.p) and np.array_equal(w0.t, w1.t)
    assert np.array_equal(before.xy_kinematics().a, after.xy_kinematics().a)
    # a dwell is a segment of its own, of no move, at rest
    dwell = np.flatnonzero(motion.move == -1)
    assert len(dwell) == 1 and np.diff(motion.t)[dwell[0]] == pytest.approx(0.1)
    assert not motion.v[dwell].any() and not motion.a[dwell].any()
    assert after.nbytes > before.nbytes       # the built motion counts in what the plan holds


def test_judging_a_sliced_job_builds_only_its_windows(monkeypatch):
    """evaluate_many on the built-in part: the print time and windows come from the recipe; the
    plan cache's size accounting does not build the motion either."""
    built = []
    whole = PlanSegments.motion
    monkeypatch.setattr(PlanSegments, "motion", lambda self: built.append(1) or whole(self))
    clear_cache()
    m = evaluate_many([TuneConfig(accel=4321.0)], None, PART, "lti", job_accel="replace")[0]
    pj = planned_job(load_printer(None), PART, TuneConfig(accel=4321.0), job_accel="replace")
    assert _nbytes(pj) > 0 and m.print_time_s == pytest.approx(pj.print_time)
    assert built == []
    assert pj.plan.motion.t[-1] <= pj.print_time and built == [1]
