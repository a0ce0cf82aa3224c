"""G2/G3 arcs as the chords a firmware would move along (mm): the centre from I/J offsets or a
radius R, the swept angle, and chords that deviate from the arc by at most a tolerance, Z and E
interpolated along."""

from __future__ import annotations

import math

from ringtune.shaping.errors import RingtuneError


def arc_chords(clockwise: bool, w: dict[str, float], start: list[float], end: list[float], tol: float,
               where: str) -> list[list[float]]:
    """The chord ends ([x, y, z, e] each, mm) of the arc from ``start`` to ``end`` (the last is
    ``end``): as few chords as keep within ``tol`` mm of the arc; ``w``: the command's words (I J or R)."""
    x0, y0 = start[0], start[1]
    cx, cy = arc_centre(clockwise, w, x0, y0, end[0], end[1], where)
    radius = math.hypot(x0 - cx, y0 - cy)
    if radius <= 0:
        raise RingtuneError("arc has zero radius", where)
    a0 = math.atan2(y0 - cy, x0 - cx)
    sweep = arc_sweep(clockwise, a0, math.atan2(end[1] - cy, end[0] - cx))
    n = 1 if radius <= tol else max(1, math.ceil(abs(sweep) / (2 * math.acos(1 - tol / radius))))
    points = []
    for k in range(1, n):
        f = k / n
        ang = a0 + sweep * f
        points.append([cx + radius * math.cos(ang), cy + radius * math.sin(ang),
                       start[2] + (end[2] - start[2]) * f, start[3] + (end[3] - start[3]) * f])
    return points + [list(end)]


def arc_centre(clockwise: bool, w: dict[str, float], x0: float, y0: float, x1: float, y1: float,
                where: str) -> tuple[float, float]:
    """The centre (mm) of a G2/G3 arc from (x0, y0) to (x1, y1): offsets I/J, or radius R (centre left
    of the chord for CCW with R > 0, right for CW; R < 0 takes the long way)."""
    if "R" in w:
        r = w["R"]
        dx, dy = x1 - x0, y1 - y0
        chord = math.hypot(dx, dy)
        if chord == 0 or abs(r) * 2 < chord - 1e-9:
            raise RingtuneError(f"arc radius R{r:g} cannot join points {chord:.4g} mm apart", where)
        h = math.sqrt(max(r * r - chord * chord / 4, 0.0))
        sign = (-1 if clockwise else 1) * (1 if r > 0 else -1)
        return x0 + dx / 2 - sign * h * dy / chord, y0 + dy / 2 + sign * h * dx / chord
    if "I" in w or "J" in w:
        return x0 + w.get("I", 0.0), y0 + w.get("J", 0.0)
    raise RingtuneError(f"{'G2' if clockwise else 'G3'} needs I/J or R", where)


def arc_sweep(clockwise: bool, a0: float, a1: float) -> float:
    """The angle (rad) swept from ``a0`` to ``a1``: negative clockwise, positive counter-clockwise,
    a full turn when they coincide."""
    sweep = a1 - a0
    if clockwise and sweep >= -1e-12:
        return sweep - 2 * math.pi
    if not clockwise and sweep <= 1e-12:
        return sweep + 2 * math.pi
    return sweep
