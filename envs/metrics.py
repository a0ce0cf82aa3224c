"""Print-quality metrics of a simulated print: what a person would see on the part.

Inputs are a simulation result (``SimResult``: sample times ``t`` in s, simulated ``nozzle`` x/y
relative to the print in mm, ``head_accel`` in mm/s², motor forces, ``step_loss``) and the
*unshaped* planned motion of the same time span (:class:`~ringtune.shaping.motion.Motion`), which
is the geometry the slicer asked for. All distances are geometric (nearest point on the commanded
path), so a nozzle that merely lags along the path (shaper delay, servo lag) costs nothing; only
leaving the path does.

Definitions (all mm unless stated; "extruding" = the unshaped path deposits material at the
sample's time minus ``lag``, the shaper's delay):

``path_error_mm``
    max over extruding samples of the distance from the nozzle to the nearest *extruding* leg of
    the commanded path active within ``match_window`` s of the sample (the time restriction keeps
    adjacent parallel infill lines from being mistaken for the line being printed).
``overshoot_mm``
    max over corners (direction change ≥ ``corner_angle_deg``, either side extruding) of the
    outward excursion after the corner: an extruding sample belongs to the latest corner the
    shaped command has started turning into (``anticipate`` s before the corner's time on the
    shaped clock) for up to ``corner_window`` s; if its nearest path point (as for
    ``path_error_mm``) is on the corner's outgoing leg or is the corner itself, it counts with its
    distance from the path when the vector ``e`` from that point to the nozzle points outward,
    ``e · (d_in − d_out) > 0`` (the outer bisector; for a reversal, past the turning point).
    Lateral error on the incoming leg belongs to the corner before it.
``ringing_mm``
    max over straight walls (extruding legs that follow a corner) of the RMS, about its mean, of
    the nozzle's perpendicular deviation from the wall's line, taken while the shaped command
    runs straight along the wall: from ``settle`` s after the corner (when the shaped command has
    finished turning) to ``anticipate`` s before the wall's end (when it starts turning into the
    next one), both on the shaped clock; walls where that span is shorter than ``min_wall`` s are
    skipped (too short to show ringing).
``peak_accel``
    max over all samples of the head's acceleration magnitude ``|(a_x, a_y)|``, mm/s².
``step_loss``
    the simulator's flag, or any sample where ``|motor_force| > motor_force_max``.
``motor_load``
    max over all samples and motors of ``|motor_force| / motor_force_max``: how much of the force a
    motor has at its speed the motion asks of it (above 1 it loses steps).
``print_time_s``
    not computed here: the planner's print time over the whole job (s), filled in by
    :func:`ringtune.envs.evaluate.evaluate`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Iterable

import numpy as np

from ringtune.shaping.motion import Motion

_EPS_LEN = 1e-6  # mm: shorter x/y segments are pure z/e moves or dwells
_COLLINEAR = math.cos(math.radians(1.0))
_ROUNDING = 1e-9  # mm: outward excursions below a nanometre are floating-point noise
_EARLY = 0.001  # s: timing slack when assigning samples to the corner being turned


@dataclass
class Metrics:
    """Print time and quality of one configuration on one job (definitions: module docstring).

    Attributes:
        print_time_s: planned print time of the whole job, s.
        path_error_mm: largest nozzle distance from the extrusion path while extruding, mm.
        overshoot_mm: largest outward excursion past the path after a corner or reversal, mm.
        ringing_mm: worst RMS oscillation across a straight wall after a direction change, mm.
        peak_accel: largest head acceleration magnitude, mm/s².
        step_loss: whether a motor was asked for more force than it has at that speed.
        motor_load: largest fraction of the force a motor has at its speed that it was asked for
            (``max |force| / max_force(speed)``; 1 is the edge of step loss; 0 if not simulated).
        details: diagnostics (per-window values, where the worst error occurred); not part of
            the stable ``to_dict()`` keys unless asked for.
    """

    print_time_s: float = float("nan")
    path_error_mm: float = 0.0
    overshoot_mm: float = 0.0
    ringing_mm: float = 0.0
    peak_accel: float = 0.0
    step_loss: bool = False
    motor_load: float = 0.0
    details: dict[str, Any] = field(default_factory=dict)

    QUALITY_KEYS = ("path_error_mm", "overshoot_mm", "ringing_mm")

    def to_dict(self, details: bool = False) -> dict[str, Any]:
        d = {"print_time_s": float(self.print_time_s), "path_error_mm": float(self.path_error_mm),
             "overshoot_mm": float(self.overshoot_mm), "ringing_mm": float(self.ringing_mm),
             "peak_accel": float(self.peak_accel), "step_loss": bool(self.step_loss),
             "motor_load": float(self.motor_load)}
        if details:
            d["details"] = self.details
        return d

    @staticmethod
    def worst(parts: Iterable["Metrics"], print_time_s: float = float("nan")) -> "Metrics":
        """Combine per-window metrics: max of each quality figure, of peak_accel and of motor_load,
        any step loss."""
        parts = list(parts)
        if not parts:
            return Metrics(print_time_s=print_time_s)
        return Metrics(
            print_time_s=print_time_s,
            path_error_mm=max(p.path_error_mm for p in parts),
            overshoot_mm=max(p.overshoot_mm for p in parts),
            ringing_mm=max(p.ringing_mm for p in parts),
            peak_accel=max(p.peak_accel for p in parts),
            step_loss=any(p.step_loss for p in parts),
            motor_load=max(p.motor_load for p in parts),
            details={"windows": [p.to_dict(details=True) for p in parts]},
        )


# -- path geometry ------------------------------------------------------------------------------
@dataclass
class Legs:
    """Straight pieces of the commanded x/y path: consecutive collinear segments merged.

    Arrays are (L, 2) points in mm and (L,) times in s; ``corner[k]`` is the turn angle (deg)
    between leg k−1 and leg k (0 for the first leg or where the legs do not touch).
    """

    start: np.ndarray
    end: np.ndarray
    t_start: np.ndarray
    t_end: np.ndarray
    extruding: np.ndarray
    turn_deg: np.ndarray

    @property
    def direction(self) -> np.ndarray:
        d = self.end - self.start
        return d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), _EPS_LEN)

    def __len__(self) -> int:
        return len(self.t_start)


def path_legs(path: Motion) -> Legs:
    """Merge the motion's segments into straight legs (x/y only; z/e-only segments are skipped)."""
    p0 = path.p[:, :2]
    p1 = path.end_state()[0][:, :2]
    seg = p1 - p0
    length = np.linalg.norm(seg, axis=1)
    keep = np.flatnonzero(length > _EPS_LEN)
    if len(keep) == 0:
        z = np.zeros((0, 2))
        e = np.zeros(0)
        return Legs(z, z, e, e, e.astype(bool), e)
    u = seg[keep] / length[keep, None]
    ext = path.extruding[keep]
    same_dir = np.einsum("ij,ij->i", u[1:], u[:-1]) >= _COLLINEAR
    touching = np.linalg.norm(p0[keep[1:]] - p1[keep[:-1]], axis=1) < 1e-3
    new = np.concatenate([[True], ~(same_dir & touching & (ext[1:] == ext[:-1]))])
    first = np.flatnonzero(new)
    last = np.concatenate([first[1:] - 1, [len(keep) - 1]])
    start, end = p0[keep[first]], p1[keep[last]]
    t_start, t_end = path.t[keep[first]], path.t[keep[last] + 1]
    d = end - start
    d = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), _EPS_LEN)
    cosang = np.clip(np.einsum("ij,ij->i", d[1:], d[:-1]), -1.0, 1.0)
    joined = np.linalg.norm(start[1:] - end[:-1], axis=1) < 1e-3
    turn = np.concatenate([[0.0], np.where(joined, np.degrees(np.arccos(cosang)), 0.0)])
    return Legs(start, end, t_start, t_end, ext[first], turn)


def _nearest_on_segments(pts: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Vectors from the nearest point of segment a→b to pts; broadcasts (…, 2)."""
    ab = b - a
    denom = np.maximum(np.sum(ab * ab, axis=-1), _EPS_LEN ** 2)
    s = np.clip(np.sum((pts - a) * ab, axis=-1) / denom, 0.0, 1.0)
    return pts - (a + s[..., None] * ab)


# -- the metrics -----------------------------------------------------------------------------------
def worst_case(results: Iterable[Metrics]) -> Metrics:
    """One :class:`Metrics` for a configuration judged on several variants of a printer: the
    first's print time (the planner does not see resonances), the largest of every quality metric,
    of ``peak_accel`` and of ``motor_load``, and step loss if any variant lost steps."""
    results = list(results)
    worst = Metrics(print_time_s=results[0].print_time_s,
                    **{k: max(getattr(m, k) for m in results)
                       for k in (*Metrics.QUALITY_KEYS, "peak_accel", "motor_load")},
                    step_loss=any(m.step_loss for m in results))
    worst.details = {"variants": [m.to_dict() for m in results]}
    return worst


def compute_metrics(sim: Any, path: Motion, *, lag: float = 0.0, settle: float = 0.0,
                    anticipate: float = 0.0,
                    corner_angle_deg: float = 30.0, corner_window: float = 0.06,
                    match_window: float = 0.05, min_wall: float = 0.02,
                    print_time_s: float = float("nan")) -> Metrics:
    """Quality metrics of one simulated window against its unshaped commanded path.

    Args:
        sim: a ``SimResult`` (or anything with ``t``, ``nozzle``, ``head_accel``, ``step_loss`` and
            optionally ``motor_force``/``motor_force_max``), times on the same clock as ``path``.
        path: the unshaped planned motion of the window.
        lag: s, delay of the shaped command behind the unshaped one (a causal shaper's centroid;
            0 for centred shapers), used to decide which part of the path a sample belongs to.
        settle: s after a corner (unshaped time) at which the shaped command runs straight along
            the next wall again (last impulse time, minus the centroid if centred).
        corner_angle_deg: smallest direction change that counts as a corner, degrees.
        corner_window: s either side of a corner searched for overshoot.
        match_window: s either side of a leg's time span within which a sample may match it.
        min_wall: s, shortest measured span of a wall whose ringing counts.
        print_time_s: passed through to the result.
    """
    t = np.asarray(sim.t, float)
    nozzle = np.asarray(sim.nozzle, float)[:, :2]
    accel = np.asarray(sim.head_accel, float)[:, :2]
    peak_accel = float(np.max(np.linalg.norm(accel, axis=1))) if len(accel) else 0.0
    step_loss = bool(getattr(sim, "step_loss", False))
    force = getattr(sim, "motor_force", None)
    fmax = getattr(sim, "motor_force_max", None)
    motor_load = 0.0
    if force is not None and fmax is not None and np.size(force):
        step_loss = step_loss or bool(np.any(np.abs(np.asarray(force)) > np.asarray(fmax)))
        motor_load = float(np.max(np.abs(np.asarray(force)) / np.maximum(np.asarray(fmax), 1e-12)))

    tu = t - lag  # sample times on the unshaped clock
    inside = (tu >= path.t[0]) & (tu <= path.t[-1])
    extruding = inside & path.extruding[path.segment_index(tu)]
    legs = path_legs(path)
    details: dict[str, Any] = {}

    tu, pts = tu[extruding], nozzle[extruding]
    dist, vec, leg = _nearest(tu, pts, legs, match_window)
    path_error = _path_error(tu, pts, dist, details)
    overshoot = _overshoot(tu, pts, dist, vec, leg, legs, corner_angle_deg, corner_window,
                           anticipate + lag, details)
    ringing = _ringing(tu, pts, legs, corner_angle_deg, settle - lag, anticipate + lag, min_wall,
                       details)
    return Metrics(print_time_s, path_error, overshoot, ringing, peak_accel, step_loss, motor_load, details)


def _nearest(tu, pts, legs: Legs, window: float):
    """Per sample: distance (mm), vector from the nearest path point (mm) and the index of the
    nearest extruding leg active within ``window`` s (inf, nan, −1 where there is none)."""
    dist = np.full(len(tu), np.inf)
    vec = np.full((len(tu), 2), np.nan)
    leg = np.full(len(tu), -1, dtype=np.int64)
    ext = np.flatnonzero(legs.extruding)
    if len(tu) == 0 or len(ext) == 0:
        return dist, vec, leg
    a, b = legs.start[ext], legs.end[ext]
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
        e = _nearest_on_segments(pts[sl, None, :], a[idx], b[idx])
        d = np.where(valid, np.sqrt(np.einsum("ijk,ijk->ij", e, e)), np.inf)
        j = np.argmin(d, axis=1)
        rows = np.arange(len(j))
        dist[sl] = d[rows, j]
        found = np.isfinite(dist[sl])
        vec[sl] = np.where(found[:, None], e[rows, j], np.nan)
        leg[sl] = np.where(found, ext[idx[rows, j]], -1)
    return dist, vec, leg


def _path_error(tu, pts, dist, details: dict) -> float:
    finite = np.isfinite(dist)
    if not finite.any():
        return 0.0
    k = int(np.argmax(np.where(finite, dist, -1.0)))
    details["path_error_at"] = {"t": float(tu[k]), "x": float(pts[k, 0]), "y": float(pts[k, 1])}
    return float(dist[k])


def _corners(legs: Legs, angle: float) -> np.ndarray:
    """Indices k of legs that start with a corner (leg k−1 → leg k), at least one extruding."""
    k = np.flatnonzero(legs.turn_deg >= angle)
    return k[legs.extruding[k] | legs.extruding[k - 1]]


def _overshoot(tu, pts, dist, vec, leg, legs: Legs, angle: float, window: float, early: float,
               details: dict) -> float:
    ks = _corners(legs, angle)
    if len(tu) == 0 or len(ks) == 0:
        return 0.0
    tc = legs.t_end[ks - 1]
    # each sample belongs to the latest corner the shaped command has started turning into
    j = np.searchsorted(tc, tu + early + _EARLY, side="right") - 1
    ok = j >= 0
    j = np.maximum(j, 0)
    k = ks[j]
    nearest = pts - np.nan_to_num(vec)
    at_vertex = np.linalg.norm(nearest - legs.end[k - 1], axis=1) < 1e-9
    # ...while it is within the window after it and nearest to its outgoing leg or the vertex
    mine = ok & (tu - tc[j] <= window) & ((leg == k) | ((leg == k - 1) & at_vertex))
    if not mine.any():
        return 0.0
    d = legs.direction
    outward = mine & (np.einsum("ij,ij->i", np.nan_to_num(vec), d[k - 1] - d[k]) > _ROUNDING)
    val = np.where(outward, dist, 0.0)
    i = int(np.argmax(val))
    if val[i] > 0:
        details["overshoot_at"] = {"t": float(tu[i]), "corner_t": float(tc[j[i]]),
                                   "turn_deg": float(legs.turn_deg[k[i]])}
    return float(val[i])


def _ringing(tu, pts, legs: Legs, angle: float, settle: float, early_end: float, min_wall: float,
             details: dict) -> float:
    ks = _corners(legs, angle)
    t0 = legs.t_end[ks - 1] + max(settle, 0.0)
    t1 = legs.t_end[ks] - early_end
    keep = legs.extruding[ks] & (t1 - t0 >= min_wall)
    ks, t0, t1 = ks[keep], t0[keep], t1[keep]
    if len(tu) == 0 or len(ks) == 0:
        return 0.0
    order = np.argsort(tu)
    tu, pts = tu[order], pts[order]
    i0 = np.searchsorted(tu, t0, side="left")
    i1 = np.searchsorted(tu, t1, side="right")
    d = legs.direction
    normal = np.stack([-d[:, 1], d[:, 0]], axis=1)
    worst, where = 0.0, None
    for k, a, b in zip(ks, i0, i1):  # one iteration per wall, vectorised within
        if b - a < 3:
            continue
        dev = (pts[a:b] - legs.start[k]) @ normal[k]
        rms = float(np.sqrt(np.mean((dev - dev.mean()) ** 2)))
        if rms > worst:
            worst, where = rms, {"t_corner": float(legs.t_end[k - 1]), "t_end": float(legs.t_end[k])}
    if where:
        details["ringing_at"] = where
    return worst
