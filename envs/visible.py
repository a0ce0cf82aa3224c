"""Ripple on walls, corner rounding and overshoot, and what hidden features push through to the
outer wall: the geometric measures of :mod:`ringtune.envs.window_metrics` (definitions there;
mm, s).

Every function takes the extruding samples of one simulated window on the unshaped clock (``tu``,
s, sorted) with the nozzle's x/y (``pts``, mm) and the commanded path's legs
(:class:`ringtune.envs.path_geometry.Legs`), and works on all walls or corners at once.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ringtune.envs.path_geometry import EPS_LEN, Legs, vector_from_segment

_SIDE = 1e-9  # mm: smaller projections on the corner's bisector are neither inward nor outward


@dataclass
class Walls:
    """The measured straight walls of a window: leg index, peak-to-peak of the nozzle's deviation
    across the wall (mm), largest distance from the wall's line (mm), RMS of the deviation about
    its mean (mm), feature class index, and how long a stretch of the wall the samples cover where
    the window's end cuts it short (s; ``inf`` where the wall ends inside the window)."""

    leg: np.ndarray
    ripple: np.ndarray
    offset: np.ndarray
    rms: np.ndarray
    cls: np.ndarray
    cut_span: np.ndarray


def wall_spans(legs: Legs, settle: float, early_end: float, min_wall: float):
    """(legs, t0, t1): extruding legs and the span (unshaped clock, s) on which the shaped command
    runs straight along each: from ``settle`` s after the leg starts to ``early_end`` s before it
    ends; spans shorter than ``min_wall`` s are dropped."""
    ks = np.flatnonzero(legs.extruding)
    t0 = legs.t_start[ks] + max(settle, 0.0)
    t1 = legs.t_end[ks] - max(early_end, 0.0)
    keep = t1 - t0 >= min_wall
    return ks[keep], t0[keep], t1[keep]


def walls(tu, pts, legs: Legs, settle: float, early_end: float, min_wall: float) -> Walls:
    """Ripple (peak-to-peak across the wall) and offset of every measured wall, vectorised with
    ``reduceat`` over the samples of all walls."""
    ks, t0, t1 = wall_spans(legs, settle, early_end, min_wall)
    i0 = np.searchsorted(tu, t0, side="left")
    i1 = np.searchsorted(tu, t1, side="right")
    ok = i1 - i0 >= 3
    ks, i0, i1 = ks[ok], i0[ok], i1[ok]
    if len(ks) == 0:
        z = np.zeros(0)
        return Walls(ks, z, z, z, ks, z)
    counts = i1 - i0
    first = np.cumsum(counts) - counts
    wall_of = np.repeat(np.arange(len(ks)), counts)
    idx = np.arange(counts.sum()) - np.repeat(first, counts) + np.repeat(i0, counts)
    d = legs.direction[ks]
    normal = np.stack([-d[:, 1], d[:, 0]], axis=1)
    dev = np.einsum("ij,ij->i", pts[idx] - legs.start[ks][wall_of], normal[wall_of])
    hi = np.maximum.reduceat(dev, first)
    lo = np.minimum.reduceat(dev, first)
    mean = np.add.reduceat(dev, first) / counts
    var = np.maximum(np.add.reduceat(dev * dev, first) / counts - mean * mean, 0.0)
    ended = t1[ok] <= tu[-1]
    cut_span = np.where(ended, np.inf, tu[i1 - 1] - tu[i0])
    return Walls(ks, hi - lo, np.maximum(np.abs(hi), np.abs(lo)), np.sqrt(var), legs.cls[ks], cut_span)


def corner_legs(legs: Legs, angle: float) -> np.ndarray:
    """Indices k of legs that start with a corner (leg k−1 → leg k turns by ≥ ``angle`` degrees),
    at least one side extruding (found once per legs and angle)."""
    found = legs.__dict__.setdefault("_corner_legs", {})
    if angle not in found:
        k = np.flatnonzero(legs.turn_deg >= angle)
        found[angle] = k[legs.extruding[k] | legs.extruding[k - 1]]
    return found[angle]


def corner_deviation(tu, pts, legs: Legs, angle: float, before: float, after: float, near=None,
                     step: float = 0.0):
    """Per sample: (inward, outward) distance (mm) from the corner being turned, 0 where the
    sample is on the other side or belongs to no corner. ``near``: each sample's distance to the
    nearest leg of the window (mm, inf where none); given, both are capped by it (after chords
    shorter than the corner's span a sample on the next leg would be measured from legs it has
    left) and the inward cut between samples ``step`` s apart is added (:func:`_chord_cut`).

    A sample belongs to the latest corner whose span ``[tc − before, tc + after]`` (unshaped clock,
    tc the corner's time) it lies in; its deviation is the vector ``e`` from the nearest point of the
    corner's two legs, outward when ``e · (d_in − d_out) > 0`` (past the corner, outside the turn)
    and inward when < 0 (cutting the corner)."""
    n = len(tu)
    ks = corner_legs(legs, angle)
    if n == 0 or len(ks) == 0:
        return np.zeros(n), np.zeros(n)
    tc = legs.t_end[ks - 1]
    j = np.searchsorted(tc - before, tu, side="right") - 1
    ok = j >= 0
    j = np.maximum(j, 0)
    ok &= tu <= tc[j] + after
    k = ks[j]
    e_in = vector_from_segment(pts, legs.start[k - 1], legs.end[k - 1])
    e_out = vector_from_segment(pts, legs.start[k], legs.end[k])
    d_in = np.einsum("ij,ij->i", e_in, e_in)
    d_out = np.einsum("ij,ij->i", e_out, e_out)
    e = np.where((d_in < d_out)[:, None], e_in, e_out)
    dist = np.sqrt(np.minimum(d_in, d_out))
    d = legs.direction
    b = d[k - 1] - d[k]
    b = b / np.maximum(np.hypot(b[:, 0], b[:, 1]), EPS_LEN)[:, None]
    side = np.einsum("ij,ij->i", e, b)
    inward = np.where(ok & (side < -_SIDE), dist, 0.0)
    outward = np.where(ok & (side > _SIDE), dist, 0.0)
    if near is None:
        return inward, outward
    own = inward <= near                  # the corner's legs are the nearest: its cut is the sample's
    inward, outward = np.minimum(inward, near), np.minimum(outward, near)
    cut = _chord_cut(tu, pts, legs, j, k, np.where(own, inward, 0.0), d_in < d_out, step)
    return np.maximum(inward, cut), outward


def _chord_cut(tu, pts, legs: Legs, j, k, inward, on_in, step: float) -> np.ndarray:
    """Per sample i: the inward cut where the chord to sample i+1 crosses from the incoming leg's
    side to the outgoing one's (0 elsewhere). The cut is the largest distance to the *nearer* leg,
    a kink where the two distances are equal, which samples miss by up to half their spacing (5 %
    of a corner's rounding at 2 kHz); on the chord both distances are linear, so their crossing is
    exact for it (the chord's error is second order in the spacing). Only where both ends of the
    chord cut the same corner, at most ``step`` s (the sampling's) apart, and the crossing's feet
    lie on both legs."""
    out = np.zeros(len(tu))
    i = np.flatnonzero((inward[:-1] > 0) & (inward[1:] > 0) & (on_in[:-1] != on_in[1:]))
    i = i[(j[i] == j[i + 1]) & (tu[i + 1] - tu[i] <= 1.5 * step)]
    if not len(i):
        return out
    kk = k[i]
    vertex, d_in, d_out = legs.end[kk - 1], legs.direction[kk - 1], legs.direction[kk]
    p0, p1 = pts[i] - vertex, pts[i + 1] - vertex
    cross = lambda p, d: np.abs(p[:, 0] * d[:, 1] - p[:, 1] * d[:, 0])   # noqa: E731  distance to the line
    a0, a1, b0, b1 = cross(p0, d_in), cross(p1, d_in), cross(p0, d_out), cross(p1, d_out)
    den = (a0 - b0) - (a1 - b1)
    s = np.clip(np.divide(a0 - b0, den, out=np.zeros_like(den), where=np.abs(den) > 0), 0.0, 1.0)
    at = p0 + s[:, None] * (p1 - p0)
    feet = (np.einsum("ij,ij->i", at, d_in) <= 0) & (np.einsum("ij,ij->i", at, d_out) >= 0)
    out[i] = np.where(feet, a0 + s * (a1 - a0), 0.0)
    return out


def per_class_max(values: np.ndarray, cls: np.ndarray, n_classes: int) -> np.ndarray:
    """(n_classes,) largest value per class index (0 where a class has none)."""
    out = np.zeros(n_classes)
    if len(values):
        np.maximum.at(out, cls, values)
    return out


def p90(values: np.ndarray) -> float:
    """90th percentile with linear interpolation between order statistics (numpy's default
    ``percentile``), 0 for no values; written out because ``np.percentile`` costs ~0.5 ms a call."""
    n = len(values)
    if n == 0:
        return 0.0
    v = np.sort(values)
    pos = 0.9 * (n - 1)
    lo = int(pos)
    hi = min(lo + 1, n - 1)
    return float(v[lo] + (pos - lo) * (v[hi] - v[lo]))
