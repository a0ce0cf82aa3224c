"""Points, Pareto fronts and the choice of one point (shared by the study, the grid and reports)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError


@dataclass
class Point:
    """One evaluated configuration (a trial, a grid point or a baseline)."""

    config: TuneConfig
    print_time_s: float
    quality_mm: float
    step_loss: bool = False
    metrics: dict = field(default_factory=dict)
    label: str = ""
    number: int | None = None

    def dominates(self, other: "Point") -> bool:
        return (self.print_time_s <= other.print_time_s and self.quality_mm <= other.quality_mm
                and (self.print_time_s < other.print_time_s or self.quality_mm < other.quality_mm))


def pareto_front(points: Sequence[Point]) -> list[Point]:
    """The feasible non-dominated points, sorted by print time."""
    feas = sorted((p for p in points if not p.step_loss), key=lambda p: (p.print_time_s, p.quality_mm))
    front: list[Point] = []
    best_q = np.inf
    for p in feas:
        if p.quality_mm < best_q:
            front.append(p)
            best_q = p.quality_mm
    return front


#: mm: quality differences smaller than this are not worth print time when choosing the knee
KNEE_QUALITY_SCALE = 0.01


def choose(front: Sequence[Point], weight: float | None = None) -> Point:
    """The point to use: minimising ``print_time_s + weight·quality_mm`` (weight in s/mm), or else
    the knee — the front point closest to the ideal corner after scaling print time by the front's
    range and quality by its range but at least :data:`KNEE_QUALITY_SCALE` (10 µm; so that a front
    whose points all lie within a few micrometres is not bought with seconds)."""
    if not front:
        raise RingtuneError("no feasible configuration was found (every trial lost steps); "
                            "lower the acceleration range or run more trials", "tune")
    if weight is not None:
        return min(front, key=lambda p: p.print_time_s + weight * p.quality_mm)
    t = np.array([p.print_time_s for p in front])
    q = np.array([p.quality_mm for p in front])
    tn = (t - t.min()) / max(t.max() - t.min(), 1e-12)
    qn = (q - q.min()) / max(q.max() - q.min(), KNEE_QUALITY_SCALE)
    return front[int(np.argmin(np.hypot(tn, qn)))]


def scalar_objective(p: Point, weight: float) -> float:
    """``print_time_s + weight·quality_mm`` (s), the single number convergence checks compare."""
    return p.print_time_s + weight * p.quality_mm
