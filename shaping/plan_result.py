"""What the planner gives: its moves (:class:`MoveTable`) and the plan (:class:`Plan`: segments
built where asked, print time, events, limits). Units mm, s, mm/s, mm/s²."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ringtune.shaping.motion import Motion
from ringtune.shaping.plan_segments import PlanSegments, XYKinematics


@dataclass
class MoveTable:
    """Per planned move: source line, geometry, speeds (mm/s), accelerations (mm/s²) and times (s)."""

    line: np.ndarray
    start: np.ndarray
    end: np.ndarray
    length: np.ndarray
    feed: np.ndarray          # requested speed
    v_nominal: np.ndarray     # after velocity limits
    v_entry: np.ndarray
    v_cruise: np.ndarray
    v_exit: np.ndarray
    accel: np.ndarray         # acceleration phase
    decel: np.ndarray         # deceleration phase (differs from accel only under DAA)
    t_start: np.ndarray       # when the move starts moving
    duration: np.ndarray
    feature: np.ndarray
    extruding: np.ndarray
    features: list = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.line)


@dataclass
class Plan:
    """A planned job: its segments (built where asked: :class:`PlanSegments`), its moves, its
    time (s), its events and the limits it was planned with."""

    segments: PlanSegments
    moves: MoveTable
    print_time: float
    events: list
    limits: Any = None                  # shaping.planner.MachineLimits
    _motion: Motion | None = field(default=None, repr=False, compare=False)

    @property
    def motion(self) -> Motion:
        """The whole motion (built once, on first use)."""
        if self._motion is None:
            self._motion = self.segments.motion()
        return self._motion

    @property
    def start_time(self) -> float:
        return float(self.segments.t[0])

    @property
    def end_time(self) -> float:
        return float(self.segments.t[-1])

    def motion_window(self, t_start: float, t_end: float) -> Motion:
        """``motion.window(t_start, t_end)`` (s), the same values, building only that span."""
        return self.segments.window(t_start, t_end)

    def velocity(self, times: np.ndarray) -> np.ndarray:
        """``motion.velocity(times)``, (len(times), 4) mm/s, the same values."""
        return self.segments.velocity(times)

    def xy_kinematics(self) -> XYKinematics:
        """The x/y velocity and acceleration of every segment (:meth:`PlanSegments.xy_kinematics`)."""
        return self.segments.xy_kinematics()

    @property
    def nbytes(self) -> int:
        """Bytes of the arrays held (segments, moves, the motion once built)."""
        held = [self.segments.nbytes, *(a.nbytes for a in vars(self.moves).values() if isinstance(a, np.ndarray))]
        if self._motion is not None:
            held += [a.nbytes for a in vars(self._motion).values() if isinstance(a, np.ndarray)]
        return sum(held)

    def time_by_feature(self) -> dict[str, float]:
        """Seconds of motion per slicer feature (dwells are not counted)."""
        out: dict[str, float] = {}
        sums = np.bincount(self.moves.feature, weights=self.moves.duration,
                           minlength=len(self.moves.features))
        for name, s in zip(self.moves.features, sums):
            if s > 0:
                out[name] = float(s)
        return out
