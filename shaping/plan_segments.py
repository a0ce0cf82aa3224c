"""A plan's motion as a recipe: the segments' times always, their states only where asked (s, mm, mm/s, mm/s²).

The planner gives every move four segments (dwell, accelerate, cruise, decelerate) and keeps those
that last. Segment ``j`` of move ``m`` and kind ``k`` (flat index ``4·m + k``) starts at
``start[m] + u[m]·dist0[m, k]`` with velocity ``u[m]·speed0[m, k]`` and acceleration
``u[m]·acc[m, k]`` (``u``: the move's unit vector over x, y, z, e). The boundaries ``t`` are one
running sum over the whole job; the states are element-wise products, so the rows of any span,
computed alone, are bit for bit the rows of the whole :class:`~ringtune.shaping.motion.Motion`.

A tuning trial needs the whole job's time but only a few windows of its motion and the XY velocity
and acceleration of every segment (the motors' load): building the full (segments × 4) position,
velocity and acceleration arrays for a 40-minute job (some 180 000 segments) cost as much as the
rest of planning it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ringtune.shaping.motion import Motion, locate, span_rows


@dataclass(frozen=True)
class XYKinematics:
    """Velocity (mm/s) at each segment's start and its acceleration (mm/s²), x and y columns,
    with the boundaries ``t`` (s) and each segment's move (−1: a dwell)."""

    t: np.ndarray
    v: np.ndarray
    a: np.ndarray
    move: np.ndarray


@dataclass(frozen=True)
class PlanSegments:
    """The recipe of a plan's segments (module docstring); ``t``: (n+1,) boundaries, s."""

    t: np.ndarray
    kept: np.ndarray          # (n,) flat index 4·move + kind of each segment
    extruding: np.ndarray     # (n,) bool, as Motion.extruding
    start: np.ndarray         # (moves, 4) mm
    u: np.ndarray             # (moves, 4) unit vector of each move
    dist0: np.ndarray         # (moves, 4) mm along the move at each kind's start
    speed0: np.ndarray        # (moves, 4) mm/s at each kind's start
    acc: np.ndarray           # (moves, 4) mm/s² of each kind

    @classmethod
    def of(cls, t, kept, start, u, dist0, speed0, acc, extruding_moves) -> "PlanSegments":
        """The recipe from the planner's per-move arrays; ``extruding_moves``: (moves,) bool."""
        move_idx = kept >> 2
        moving = (kept & 3) != 0
        u_e = np.take(u[:, 3], move_idx)
        ext = (extruding_moves[move_idx] & moving
               & (np.abs(u_e * np.take(speed0, kept)) + np.abs(u_e * np.take(acc, kept)) > 0))
        return cls(t, kept, ext, start, u, dist0, speed0, acc)

    @property
    def n_segments(self) -> int:
        return len(self.kept)

    @property
    def move(self) -> np.ndarray:
        """(n,) the move of each segment, −1 for a dwell."""
        return self._move(slice(None))

    def _move(self, sel) -> np.ndarray:
        kept = self.kept[sel]
        return np.where((kept & 3) != 0, kept >> 2, -1)

    def _rows(self, sel, columns: int = 4, position: bool = True) -> tuple[np.ndarray | None, np.ndarray, np.ndarray]:
        """(p, v, a) of the segments ``sel`` (a slice or index array), their first ``columns``
        axes (x, y, z, e); p None without ``position``."""
        kept = self.kept[sel]
        move = kept >> 2
        u, start = (self.u, self.start) if columns >= 4 else (self.u[:, :columns], self.start[:, :columns])
        u_seg = np.take(u, move, axis=0)
        v, a = u_seg * np.take(self.speed0, kept)[:, None], u_seg * np.take(self.acc, kept)[:, None]
        if not position:
            return None, v, a
        return np.take(start, move, axis=0) + u_seg * np.take(self.dist0, kept)[:, None], v, a

    def motion(self) -> Motion:
        """The whole motion."""
        p, v, a = self._rows(slice(None))
        return Motion(self.t, p, v, a, self.extruding, self.move)

    def window(self, t_start: float, t_end: float) -> Motion:
        """``self.motion().window(t_start, t_end)``, building only its segments."""
        lo, hi, i0, i1 = span_rows(self.t, t_start, t_end)
        p, v, a = self._rows(slice(i0, i1))
        part = Motion(self.t[i0:i1 + 1], p, v, a, self.extruding[i0:i1], self._move(slice(i0, i1)))
        return part.window(lo, hi)

    def velocity(self, times: np.ndarray) -> np.ndarray:
        """``self.motion().velocity(times)``, (len(times), 4) mm/s, from the segments there only."""
        idx, tau, inside = locate(self.t, times)
        _p, v, a = self._rows(idx, position=False)
        return (v + a * tau[:, None]) * inside[:, None]

    def xy_kinematics(self) -> XYKinematics:
        """The x/y velocity and acceleration of every segment (what the motors' load reads)."""
        _p, v, a = self._rows(slice(None), columns=2, position=False)
        return XYKinematics(self.t, v, a, self.move)

    @property
    def nbytes(self) -> int:
        return sum(getattr(self, f).nbytes for f in self.__dataclass_fields__)
