"""The first quality measures, kept as diagnostics beside what a person sees (definitions in
:mod:`ringtune.envs.window_metrics`: ``path_error_mm``, ``overshoot_mm``, ``ringing_mm``; mm, s).

Each takes the extruding samples of one window on the unshaped clock (``tu``, s), the nozzle's
x/y (``pts``, mm) and their nearest extruding leg (:func:`ringtune.envs.path_geometry.nearest_leg`).
"""

from __future__ import annotations

import numpy as np

from ringtune.envs.path_geometry import Legs
from ringtune.envs.visible import corner_legs

_ROUNDING = 1e-9  # mm: outward excursions below a nanometre are floating-point noise
_EARLY = 0.001  # s: timing slack when assigning samples to the corner being turned
#: s: the shortest measured stretch of a wall cut short by the window's end whose RMS counts as
#: ringing: two and a half periods of a 25 Hz mode (a window gives the wall after the corner it is
#: placed on about 0.2 s)
RINGING_MIN_SPAN = 0.1


def path_error(tu, pts, dist, details: dict) -> float:
    finite = np.isfinite(dist)
    if not finite.any():
        return 0.0
    k = int(np.argmax(np.where(finite, dist, -1.0)))
    details["path_error_at"] = {"t": float(tu[k]), "x": float(pts[k, 0]), "y": float(pts[k, 1])}
    return float(dist[k])


def overshoot(tu, pts, dist, vec, leg, legs: Legs, angle: float, window: float, early: float,
               details: dict) -> float:
    ks = corner_legs(legs, angle)
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


def ringing_rms(walls, legs: Legs, angle: float, details: dict) -> float:
    """Worst RMS (about its mean) of the deviation across a measured wall that follows a corner
    (``walls``: :func:`ringtune.envs.visible.walls`, whose spans start ``settle`` s after the
    corner). A wall the window's end cuts short counts where at least :data:`RINGING_MIN_SPAN` s
    of it is measured: over a shorter stub just after its corner the RMS is the corner's transient,
    and it grows as the stub shrinks, so it would depend on where the window happens to end."""
    after_corner = (legs.turn_deg[walls.leg] >= angle) & (legs.extruding[walls.leg - 1]
                                                         | legs.extruding[walls.leg]) & (walls.leg > 0)
    after_corner &= walls.cut_span >= RINGING_MIN_SPAN
    if not after_corner.any():
        return 0.0
    i = int(np.argmax(np.where(after_corner, walls.rms, -1.0)))
    k = walls.leg[i]
    details["ringing_at"] = {"t_corner": float(legs.t_end[k - 1]), "t_end": float(legs.t_end[k])}
    return float(walls.rms[i])
