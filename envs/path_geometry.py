"""The commanded path as straight legs, and where each nozzle sample sits on it (mm, s).

:func:`path_legs` merges the planned motion's segments into straight legs (collinear, touching,
same extruding state and same feature class); :func:`nearest_leg` finds, for each sample of the
simulated nozzle, the nearest extruding leg active around the sample's time — the geometry every
measure of :mod:`ringtune.envs.window_metrics` is taken against.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ringtune.shaping.motion import Motion

EPS_LEN = 1e-6  # mm: shorter x/y segments are pure z/e moves or dwells
_COLLINEAR = math.cos(math.radians(1.0))
_TOUCH = 1e-3  # mm: legs closer than this are joined


@dataclass
class Legs:
    """Straight pieces of the commanded x/y path: consecutive collinear segments merged.

    Arrays are (L, 2) points in mm and (L,) times in s; ``turn_deg[k]`` is the turn angle (deg)
    between leg k−1 and leg k (0 for the first leg or where the legs do not touch); ``cls[k]`` the
    feature class index (:data:`ringtune.shaping.features.FEATURE_CLASSES`) of the leg;
    ``s_start[k]`` the path length (mm) from the path's start to the leg's start; ``knot_s`` and
    ``knot_e`` (non-decreasing path length, mm, and the commanded extruder position there, mm of
    filament) at both ends of every segment the legs were merged from (leg k's: ``knot_first[k]`` to
    ``knot_last[k]``; ``e_start``/``e_end`` its ends): a leg's moves may differ in filament per mm of
    path.
    """

    start: np.ndarray
    end: np.ndarray
    t_start: np.ndarray
    t_end: np.ndarray
    extruding: np.ndarray
    turn_deg: np.ndarray
    cls: np.ndarray
    s_start: np.ndarray
    knot_s: np.ndarray
    knot_e: np.ndarray
    knot_first: np.ndarray
    knot_last: np.ndarray

    @cached_property
    def e_start(self) -> np.ndarray:
        """(L,) extruder position (mm of filament) at each leg's start."""
        return self.knot_e[self.knot_first]

    @cached_property
    def e_end(self) -> np.ndarray:
        """(L,) extruder position (mm of filament) at each leg's end."""
        return self.knot_e[self.knot_last]

    @cached_property
    def direction(self) -> np.ndarray:
        """(L, 2) unit vector of each leg (computed once: the legs are not changed once made)."""
        d = self.end - self.start
        return d / np.maximum(_norm(d), EPS_LEN)[:, None]

    @cached_property
    def length(self) -> np.ndarray:
        """(L,) length of each leg, mm."""
        return _norm(self.end - self.start)

    @cached_property
    def run(self) -> np.ndarray:
        """(L,) index of the extrusion run each leg belongs to (a run: consecutive touching
        extruding legs; non-extruding legs get the run before them)."""
        joined = np.concatenate([[False], _norm(self.start[1:] - self.end[:-1]) < _TOUCH])
        prev_ext = np.concatenate([[False], self.extruding[:-1]])
        new = self.extruding & ~(joined & prev_ext)
        return np.cumsum(new) - 1

    @cached_property
    def run_ends(self) -> tuple[np.ndarray, np.ndarray]:
        """Per extrusion run (index = run id): its first and its last extruding leg."""
        n_runs = int(self.run.max()) + 1 if len(self) else 0
        idx = np.flatnonzero(self.extruding)
        first = np.zeros(n_runs, np.int64)
        last = np.zeros(n_runs, np.int64)
        first[self.run[idx[::-1]]] = idx[::-1]     # the lowest index of each run is written last
        last[self.run[idx]] = idx                  # the highest index of each run is written last
        return first, last

    @cached_property
    def extruding_segments(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(indices, start points, start-to-end vectors, squared lengths floored at EPS_LEN²) of the
        extruding legs, as :func:`vector_from_segment` computes them."""
        ext = np.flatnonzero(self.extruding)
        a = self.start[ext]
        ab = self.end[ext] - a
        return ext, a, ab, _squared_length(ab)

    def __len__(self) -> int:
        return len(self.t_start)


def _norm(v: np.ndarray) -> np.ndarray:
    """Lengths of (n, 2) vectors (hypot: faster than linalg.norm on small arrays)."""
    return np.hypot(v[:, 0], v[:, 1])


def _empty_legs() -> Legs:
    z, e = np.zeros((0, 2)), np.zeros(0)
    return Legs(z, z, e, e, e.astype(bool), e, e.astype(np.int64), e, e, e, e.astype(np.int64), e.astype(np.int64))


def path_legs(path: Motion, classes: np.ndarray | None = None) -> Legs:
    """Merge the motion's segments into straight legs (x/y only; z/e-only segments are skipped).

    ``classes``: (n_segments,) feature class index of each segment (None: all 0); a class change
    starts a new leg."""
    p0 = path.p[:, :2]
    p1 = path.end_state()[0][:, :2]
    seg = p1 - p0
    length = _norm(seg)
    keep = np.flatnonzero(length > EPS_LEN)
    if len(keep) == 0:
        return _empty_legs()
    cls_all = np.zeros(path.n_segments, np.int64) if classes is None else np.asarray(classes, np.int64)
    u = seg[keep] / length[keep, None]
    ext, cls = path.extruding[keep], cls_all[keep]
    same_dir = np.einsum("ij,ij->i", u[1:], u[:-1]) >= _COLLINEAR
    touching = _norm(p0[keep[1:]] - p1[keep[:-1]]) < _TOUCH
    same = same_dir & touching & (ext[1:] == ext[:-1]) & (cls[1:] == cls[:-1])
    first = np.flatnonzero(np.concatenate([[True], ~same]))
    last = np.concatenate([first[1:] - 1, [len(keep) - 1]])
    start, end = p0[keep[first]], p1[keep[last]]
    t_start, t_end = path.t[keep[first]], path.t[keep[last] + 1]
    d = end - start
    leg_len = _norm(d)
    d = d / np.maximum(leg_len, EPS_LEN)[:, None]
    cosang = np.clip(np.einsum("ij,ij->i", d[1:], d[:-1]), -1.0, 1.0)
    joined = _norm(start[1:] - end[:-1]) < _TOUCH
    turn = np.concatenate([[0.0], np.where(joined, np.degrees(np.arccos(cosang)), 0.0)])
    s_start = np.concatenate([[0.0], np.cumsum(leg_len)[:-1]])
    if path.p.shape[1] > 3:
        e0, e1 = path.p[keep, 3], p1_e(path)[keep]
    else:
        e0 = e1 = np.zeros(len(keep))
    leg = np.cumsum(np.concatenate([[True], ~same])) - 1
    along = [s_start[leg] + np.clip(np.einsum("ij,ij->i", p[keep] - start[leg], d[leg]), 0.0, leg_len[leg])
             for p in (p0, p1)]
    knot_s = np.maximum.accumulate(np.column_stack(along).ravel())
    knot_e = np.column_stack([e0, e1]).ravel()
    return Legs(start, end, t_start, t_end, ext[first], turn, cls[first], s_start, knot_s, knot_e,
                2 * first, 2 * last + 1)


#: the legs last made, by path: {id(path): (weak reference to it, its classes, legs)}
_LEGS: dict[int, tuple] = {}


def legs_of(path: Motion, classes: np.ndarray | None = None) -> Legs:
    """:func:`path_legs` of ``path`` and ``classes``, made once while the path lives: a window is
    measured on the printer and on each of its variants against the same path object."""
    key = id(path)
    hit = _LEGS.get(key)
    if hit is not None and hit[0]() is path and hit[1] is classes:
        return hit[2]
    legs = path_legs(path, classes)
    _LEGS[key] = (weakref.ref(path, lambda _ref, k=key: _LEGS.pop(k, None)), classes, legs)
    return legs


def p1_e(path: Motion) -> np.ndarray:
    """Extruder position (mm) at the end of each segment."""
    d = path.dt
    return path.p[:, 3] + path.v[:, 3] * d + 0.5 * path.a[:, 3] * d * d


def vector_from_segment(pts: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Vectors from the nearest point of segment a→b to pts; broadcasts (…, 2)."""
    ab = b - a
    return _vector_from(pts, a, ab, _squared_length(ab))


def _squared_length(ab: np.ndarray) -> np.ndarray:
    """|ab|² of (…, 2) vectors, floored at EPS_LEN² (the two components summed by hand: numpy's sum
    along an axis of two is several times slower)."""
    return np.maximum(ab[..., 0] * ab[..., 0] + ab[..., 1] * ab[..., 1], EPS_LEN ** 2)


def _vector_from(pts: np.ndarray, a: np.ndarray, ab: np.ndarray, denom: np.ndarray) -> np.ndarray:
    """:func:`vector_from_segment` with the segment given by its start ``a``, its vector ``ab`` and
    ``denom``, |ab|² floored at EPS_LEN²."""
    ap = pts - a
    s = np.clip((ap[..., 0] * ab[..., 0] + ap[..., 1] * ab[..., 1]) / denom, 0.0, 1.0)
    return pts - (a + s[..., None] * ab)


def nearest_leg(tu: np.ndarray, pts: np.ndarray, legs: Legs, window: float):
    """Per sample: distance (mm), vector from the nearest path point (mm) and the index of the
    nearest extruding leg active within ``window`` s of the sample's time ``tu`` (inf, nan, −1
    where there is none)."""
    dist = np.full(len(tu), np.inf)
    vec = np.full((len(tu), 2), np.nan)
    leg = np.full(len(tu), -1, dtype=np.int64)
    ext, a, ab, denom = legs.extruding_segments
    if len(tu) == 0 or len(ext) == 0:
        return dist, vec, leg
    lo, hi = legs.t_start[ext] - window, legs.t_end[ext] + window  # both non-decreasing
    # legs active around each sample form a contiguous band [j0, j1] of the time-ordered legs
    j0 = np.searchsorted(hi, tu, side="left")
    j1 = np.searchsorted(lo, tu, side="right") - 1
    width = int(np.max(j1 - j0, initial=-1)) + 1
    if width <= 0:
        return dist, vec, leg
    chunk = max(1, 1_000_000 // width)
    for i in range(0, len(tu), chunk):  # chunks of samples × band, bounded memory
        sl = slice(i, i + chunk)
        idx = j0[sl, None] + np.arange(width)[None, :]
        valid = idx <= j1[sl, None]
        idx = np.minimum(idx, len(ext) - 1)
        e = _vector_from(pts[sl, None, :], np.take(a, idx, axis=0), np.take(ab, idx, axis=0), np.take(denom, idx))
        d = np.where(valid, np.sqrt(np.einsum("ijk,ijk->ij", e, e)), np.inf)
        j = np.argmin(d, axis=1)
        rows = np.arange(len(j))
        dist[sl] = d[rows, j]
        found = np.isfinite(dist[sl])
        vec[sl] = np.where(found[:, None], e[rows, j], np.nan)
        leg[sl] = np.where(found, ext[idx[rows, j]], -1)
    return dist, vec, leg
