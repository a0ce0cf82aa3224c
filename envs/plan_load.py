"""The motors' load over a whole planned job, rigid machine: on every segment of constant
acceleration of the plan, the force each XY motor is asked for against the force it has at the
fastest belt speed the segment reaches. The simulated quality windows measure the load with the
belts' dynamics but hold only a few corners; a hidden feature's fastest move (a long travel, a
diagonal infill line) is rarely among them, so this is the bound on every move.

Motor k (``Printer.drive_motors``: drive vector D_k, belt speed per unit head speed) shares the
axes' forces m_ax·a_ax by the least-squares inverse P of the drive, as the simulation does, plus
its rotor's reflected mass and its friction: demand_k = |a·(P_k ∘ m) + m_r,k·(a·D_k)|·1e-3 +
friction_k (N; a in mm/s², masses in kg), against
``max_force(|v·D_k|)`` at the larger of the segment's two end speeds (velocity is linear within a
segment, so its belt speed peaks at an end). At the acceleration
:func:`ringtune.agents.tune.motor_bound.motor_accel_limit` returns for a direction and speed, a
move in that direction reaching that speed loads its motor exactly 1 − reserve.

The planned (unshaped) motion is used: an input shaper's output is a weighted mean, with positive
weights, of the planned acceleration over its duration (tens of ms), so it asks no more of a motor
than the plan's largest demand nearby, at speeds within that span's. Units: mm/s², mm/s, N, kg.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ringtune.envs.sim_result import drive_inverse


@dataclass(frozen=True)
class PlanLoad:
    """The largest load over a plan: ``load`` (fraction of the force the motor has at its speed),
    which ``motor`` (drive name: x, y, a, b), at what time ``t`` (s, start of the segment) and on
    which planned move (``move``, index into the plan's moves; −1 none)."""

    load: float
    motor: str
    t: float
    move: int


def segment_loads(printer: Any, motion: Any) -> np.ndarray:
    """(n_segments,) the largest load over the XY motors on each segment of ``motion`` (a
    :class:`ringtune.shaping.motion.Motion`), rigid machine; 0 where no motor moves the head."""
    return _per_motor(printer, motion).max(axis=0, initial=0.0)


def plan_load(printer: Any, motion: Any) -> PlanLoad:
    """The largest :func:`segment_loads` over the whole motion and where it is (``motion``: a
    Motion, or anything with its ``t``, ``v``, ``a`` (x, y first) and ``move``, such as
    :meth:`ringtune.shaping.plan_result.Plan.xy_kinematics`)."""
    per = _per_motor(printer, motion)
    if per.size == 0:
        return PlanLoad(0.0, "", float("nan"), -1)
    k, i = np.unravel_index(int(np.argmax(per)), per.shape)
    name = printer.drive_motors()[k][0]
    move = int(motion.move[i]) if motion.move is not None else -1
    return PlanLoad(float(per[k, i]), name, float(motion.t[i]), move)


def _per_motor(printer: Any, motion: Any) -> np.ndarray:
    """(n_motors, n_segments) load of each XY motor on each segment."""
    motors = printer.drive_motors()
    D = np.array([d for _n, _m, d in motors], float).T                  # (2, k)
    P = drive_inverse(D)                                                # (2, k)
    mass = np.array([printer.moving_mass("x"), printer.moving_mass("y")])
    a = np.asarray(motion.a, float)[:, :2]
    v0 = np.asarray(motion.v, float)[:, :2]
    v1 = v0 + a * np.diff(np.asarray(motion.t, float))[:, None]
    # |x| + |y| of each, summed by hand (numpy's sum along an axis of two is several times slower)
    moving = ((np.abs(v0[:, 0]) + np.abs(v0[:, 1])) + (np.abs(v1[:, 0]) + np.abs(v1[:, 1]))
              + (np.abs(a[:, 0]) + np.abs(a[:, 1]))) > 0
    out = np.zeros((len(motors), len(a)))
    for k, (_name, mo, _d) in enumerate(motors):
        along = a @ D[:, k]
        demand = np.abs(a @ (P[:, k] * mass) + mo.rotor_mass * along) * 1e-3 + mo.friction
        speed = np.maximum(np.abs(v0 @ D[:, k]), np.abs(v1 @ D[:, k]))
        have = np.maximum(np.asarray(mo.max_force(speed), float), 1e-12)
        out[k] = np.where(moving, demand / have, 0.0)
    return out
