"""Seams: where a visible feature starts or ends next to motion of another class (mm/s, s).

A visible wall begins after a travel hop or an inner wall and ends into a travel. With one
acceleration for the job those moves are planned like the wall; with settings per feature
(``feature_accel``, the corners nobody sees) they are not, and what they do lands on the wall: the
hop's deceleration rings into the wall's first millimetres (the seam a person sees), and a
shaper spreads the next travel's acceleration back over the wall's last ones. The sharpest
corners of a visible class need not be near a seam, so the quality windows hold seams of their own
(:func:`ringtune.shaping.testprints.quality_windows`).
"""

from __future__ import annotations

import numpy as np

from ringtune.shaping.features import feature_class, seen_classes
from ringtune.shaping.geometry_cache import by_geometry

#: moves looked at on the other side of a seam (stopping at the visible class itself)
REACH = 5
#: visible classes in the order their seams get windows (what is seen most first)
SEAM_ORDER = ("outer_wall", "top_surface", "bridge_overhang", "other")


def label_classes(plan) -> np.ndarray:
    """The feature class of each of the job's labels (``other`` alone when it has none)."""
    return np.array([feature_class(n) for n in plan.moves.features] or ["other"])


def _present_classes(mv, names: np.ndarray) -> frozenset[str]:
    """The classes the moves have — their label's (``names``) where they extrude, ``travel``
    where not — read from the labels the moves use, not from a string per move; once per job
    (the moves' ends and labels: every plan of a job has the same)."""
    def compute() -> frozenset[str]:
        out = set(names[np.unique(mv.feature[mv.extruding])].tolist())
        return frozenset(out | {"travel"} if not np.all(mv.extruding) else out)
    return by_geometry("present-classes", (mv.start, mv.end, mv.feature), tuple(names.tolist()), compute)


def job_seen_classes(plan) -> frozenset:
    """The classes of ``plan``'s job a person sees (:func:`ringtune.shaping.features.seen_classes`
    of the classes its moves extrude: ``other`` only where the job labels nothing visible)."""
    mv = getattr(plan, "moves", None)
    if mv is None or not len(mv):
        return seen_classes(())
    return seen_classes(_present_classes(mv, label_classes(plan)))


def _seam_moves(mv, names: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(label, each move's class code in it, a visible run's first moves, their last moves): the
    job's labels and geometry alone."""
    # each move's class as a code (its index in ``label``): integers compare faster than strings
    label = np.unique(np.append(names, "travel"))
    cls = np.where(mv.extruding, np.searchsorted(label, names)[mv.feature], np.searchsorted(label, "travel"))
    visible = np.isin(label, list(seen_classes(_present_classes(mv, names))))[cls]
    change = cls[1:] != cls[:-1]
    return label, cls, np.flatnonzero(visible[1:] & change) + 1, np.flatnonzero(visible[:-1] & change)


def _peak_beside(cls: np.ndarray, v: np.ndarray, idx: np.ndarray, step: int) -> np.ndarray:
    """Per move index in ``idx``: the highest cruise speed (mm/s) of the up to :data:`REACH` moves
    on side ``step`` (−1 before, +1 after) up to the next move of the same class."""
    n = len(cls)
    peak = np.zeros(len(idx))
    going = np.ones(len(idx), bool)
    for k in range(1, REACH + 1):
        j = idx + step * k
        inside = (j >= 0) & (j < n)
        jj = np.clip(j, 0, n - 1)
        going &= inside & (cls[jj] != cls[idx])
        peak = np.where(going, np.maximum(peak, v[jj]), peak)
    return peak


def seam_candidates(plan, span: float) -> dict[str, tuple]:
    """Per side (``seam-in``: a visible run's first move; ``seam-out``: its last; ``other`` only
    in a job that labels nothing visible), arrays
    (t0 of a window of ``span`` s, score, line, class): an entry's window starts 0.2·span before
    the run, so the wall after the seam fills it; an exit's ends 0.2·span after the run. Score: the
    highest cruise speed (mm/s) of the other class's moves beside it, the harder they are driven
    the more they leave on the wall."""
    mv = plan.moves
    names = label_classes(plan)
    empty = (np.zeros(0), np.zeros(0), np.zeros(0, np.int64), np.zeros(0, dtype=names.dtype))
    if len(mv) < 2:
        return {"seam-in": empty, "seam-out": empty}
    label, cls, first, last = by_geometry("seam-moves", (mv.start, mv.end, mv.feature), tuple(names.tolist()),
                                          lambda: _seam_moves(mv, names))
    t_end = mv.t_start + mv.duration
    return {
        "seam-in": (mv.t_start[first] - 0.2 * span, _peak_beside(cls, mv.v_cruise, first, -1),
                    mv.line[first], label[cls[first]]),
        "seam-out": (t_end[last] - 0.8 * span, _peak_beside(cls, mv.v_cruise, last, +1),
                     mv.line[last], label[cls[last]]),
    }
