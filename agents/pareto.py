"""Points, Pareto fronts and the choice of one point (shared by the study, the grid and reports)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError


#: mm: default bound on the path error of a usable configuration. Path error is the largest
#: distance of the nozzle from the commanded path while extruding, so it holds corner rounding by
#: the shaper's smoothing as well as overshoot and ringing. Without a bound, the quality objective
#: ``overshoot_mm`` is bought by heavy smoothing (corners cut inwards by 0.3-0.4 mm to save a few
#: µm of overshoot); Klipper bounds the same thing with its smoothing target (0.12 mm). 0.1 mm is
#: a quarter of a 0.4 mm extrusion width.
DEFAULT_MAX_PATH_ERROR_MM = 0.1

METRIC_KEYS = ("print_time_s", "path_error_mm", "overshoot_mm", "ringing_mm", "peak_accel", "step_loss")


@dataclass
class Point:
    """One evaluated configuration (a trial, a grid point or a baseline). A point is feasible
    unless it loses steps or its path error is over the bound it was judged with (``too_rough``)."""

    config: TuneConfig
    print_time_s: float
    quality_mm: float
    step_loss: bool = False
    metrics: dict = field(default_factory=dict)
    label: str = ""
    number: int | None = None
    too_rough: bool = False

    @property
    def feasible(self) -> bool:
        return not (self.step_loss or self.too_rough)

    def dominates(self, other: "Point") -> bool:
        return (self.print_time_s <= other.print_time_s and self.quality_mm <= other.quality_mm
                and (self.print_time_s < other.print_time_s or self.quality_mm < other.quality_mm))


def metrics_dict(m) -> dict:
    """The :data:`METRIC_KEYS` of a metrics object as plain floats (``step_loss`` a bool)."""
    return {k: bool(getattr(m, k)) if k == "step_loss" else float(getattr(m, k)) for k in METRIC_KEYS}


def point_from_metrics(config: TuneConfig, m, quality: str, *, label: str = "", number: int | None = None,
                       max_path_error_mm: float = 0.0) -> Point:
    """A :class:`Point` from a metrics object; ``max_path_error_mm`` > 0 bounds the path error (mm)."""
    p = Point(config, float(m.print_time_s), float(getattr(m, quality)), bool(m.step_loss), metrics_dict(m),
              label, number)
    return judge_path_error(p, max_path_error_mm)


def judge_path_error(p: Point, max_path_error_mm: float) -> Point:
    """Mark ``p`` too rough when its path error exceeds ``max_path_error_mm`` (mm; 0 = no bound)."""
    pe = p.metrics.get("path_error_mm")
    p.too_rough = bool(max_path_error_mm > 0 and pe is not None and pe > max_path_error_mm)
    return p


def pareto_front(points: Sequence[Point]) -> list[Point]:
    """The feasible non-dominated points, sorted by print time."""
    feas = sorted((p for p in points if p.feasible), key=lambda p: (p.print_time_s, p.quality_mm))
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
        raise RingtuneError("no feasible configuration was found (every trial lost steps or exceeded "
                            "--max-path-error); lower the acceleration range, raise --max-path-error or "
                            "run more trials", "tune")
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
