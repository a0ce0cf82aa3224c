"""G2/G3 arcs as the chords a firmware would move along (mm): the centre from I/J offsets or a
radius R, the swept angle, and chords that deviate from the arc by at most a tolerance, Z and E
interpolated along — or the firmware's own segments: Klipper's ``[gcode_arcs]`` cuts an I/J arc into
``floor(travel / resolution)`` equal-angle segments (at least one; travel the arc's length with its
helical rise, ``klippy/extras/gcode_arcs.py``); Marlin 2.1 (``plan_arc``, ``G2_G3.cpp``) into
equal-angle segments of at most ``MAX_ARC_SEGMENT_MM``, at least ``MIN_CIRCLE_SEGMENTS`` to a full
circle (:class:`MarlinArcs`); RepRapFirmware 3.5+ (``GCodes::DoArcMove``) and Prusa Buddy (``plan_arc``,
its ``G2_G3.cpp``, RRF's rule with its own constants) into segments set by the deviation they leave and
the speed (:class:`DeviationArcs`). An unknown firmware's arcs are the tolerance's chords."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ringtune.shaping.errors import RingtuneError


#: Klipper's ``[gcode_arcs] resolution`` default, mm
KLIPPER_ARC_RESOLUTION = 1.0


@dataclass(frozen=True)
class MarlinArcs:
    """Marlin 2.1's arc segments, from its build settings (``Configuration_adv.h`` defaults; mm):
    ``MIN_ARC_SEGMENT_MM``, ``MAX_ARC_SEGMENT_MM``, ``MIN_CIRCLE_SEGMENTS`` (no ``ARC_SEGMENTS_PER_SEC``)."""

    min_mm: float = 0.1
    max_mm: float = 1.0
    circle_segments: int = 72

    def segments(self, radius: float, sweep: float, speed: float = 0.0) -> int:
        """How many equal-angle segments ``plan_arc`` cuts an arc of ``radius`` (mm) sweeping ``sweep``
        (rad) into: the arc's flat length (Z left out) over the longest segment, no fewer than the
        circle's share of ``circle_segments`` (all of them for a full circle), then as near both
        lengths as whole segments come (``speed`` is not used: no ``ARC_SEGMENTS_PER_SEC``)."""
        turn = abs(sweep)
        flat = radius * turn
        least = max(1, math.ceil(self.circle_segments * turn / (2 * math.pi) - 1e-9))
        nominal = max(math.floor(flat / self.max_mm), least)
        if flat / nominal > self.max_mm:
            return math.ceil(flat / self.max_mm)
        if flat / nominal < self.min_mm:
            return max(1, math.floor(flat / self.min_mm))
        return nominal


#: Marlin's default build
MARLIN_ARCS = MarlinArcs()


@dataclass(frozen=True)
class DeviationArcs:
    """Arc segments set by the deviation they leave and the speed, RepRapFirmware's rule: its
    ``MaxArcDeviation`` (mm), ``MinArcSegmentLength``, ``MaxArcSegmentLength`` (mm),
    ``MaxArcSegmentsPerSec`` (3.5+, ``Configuration.h``), or Prusa Buddy's ``MAX_ARC_DEVIATION``,
    ``MIN_ARC_SEGMENT_MM``, ``MAX_ARC_SEGMENT_MM``, ``MIN_ARC_SEGMENTS_PER_SEC`` (its printers'
    ``Configuration_*_adv.h``); firmware: its name in what the user reads; sees_speed_factor: the
    speed that sets the segments includes M220's factor (Buddy's ``plan_arc`` takes the feed rate
    as the job gives it, ``feedrate_mm_s``, and only the planner the scaled one)."""

    deviation: float
    min_mm: float
    max_mm: float
    per_second: float
    firmware: str
    sees_speed_factor: bool = True

    def segments(self, radius: float, sweep: float, feed: float, speed_factor: float = 1.0) -> int:
        """How many equal-angle segments the firmware cuts an arc of ``radius`` (mm) sweeping ``sweep``
        (rad) into at the job's ``feed`` (mm/s) under M220's ``speed_factor``: the length that deviates
        ``deviation`` from the arc, sqrt(8·r·deviation), or what ``per_second`` segments cover at
        the speed if shorter, held within the two lengths; the arc's flat length over it, + 0.8,
        whole (at least one)."""
        speed = feed * speed_factor if self.sees_speed_factor else feed
        length = min(max(min(math.sqrt(8 * radius * self.deviation), speed / self.per_second), self.min_mm), self.max_mm)
        return max(int(radius * abs(sweep) / length + 0.8), 1)


#: RepRapFirmware 3.5's and 3.6's constants; the speed includes M220's factor (LoadExtrusionAndFeedrateFromGCode
#: scales ms.feedRate by speedFactor for a move of the job before DoArcMove cuts it)
RRF_ARCS = DeviationArcs(0.005, 0.02, 1.0, 200.0, "RepRapFirmware 3.5+")
#: Prusa Buddy's, the same in every printer's build (MK4, MK3.5, XL, MINI, CORE One)
PRUSA_ARCS = DeviationArcs(0.02, 0.1, 2.0, 50.0, "Prusa Buddy", sees_speed_factor=False)
#: whose arcs are which (:attr:`ringtune.shaping.planner.MachineLimits.arc_rule`; Klipper's are a length)
ARC_RULES = {"marlin": MARLIN_ARCS, "rrf": RRF_ARCS, "prusa": PRUSA_ARCS}


def arc_resolution(limits) -> float | MarlinArcs | DeviationArcs | None:
    """How a firmware reading a job with ``limits`` (a :class:`ringtune.shaping.planner.MachineLimits`)
    cuts arcs, by :attr:`~ringtune.shaping.planner.MachineLimits.arc_rule`: Klipper's segment length
    ``arc_resolution`` (mm; its default 1 mm unless the printer gives one); RepRapFirmware's
    (:data:`RRF_ARCS`), Marlin's default build (:data:`MARLIN_ARCS`), Prusa Buddy's (:data:`PRUSA_ARCS`);
    None where the firmware is not known (tolerance chords)."""
    rule = None if limits is None else limits.arc_rule
    if rule == "klipper":
        return limits.arc_resolution or KLIPPER_ARC_RESOLUTION
    return ARC_RULES.get(rule)


def arc_chords(clockwise: bool, w: dict[str, float], start: list[float], end: list[float], tol: float,
               where: str, resolution: float | MarlinArcs | DeviationArcs | None = None,
               feed: float = 0.0, speed_factor: float = 1.0) -> list[list[float]]:
    """The chord ends ([x, y, z, e] each, mm) of the arc from ``start`` to ``end`` (the last is
    ``end``): as few chords as keep within ``tol`` mm of the arc, or with ``resolution`` (mm) Klipper's
    segments of an I/J arc, or Marlin's, RRF's or Buddy's segments (:class:`MarlinArcs`,
    :class:`DeviationArcs`, which depend on the job's ``feed``, mm/s, and M220's ``speed_factor``);
    ``w``: the command's words (I J or R)."""
    x0, y0 = start[0], start[1]
    cx, cy = arc_centre(clockwise, w, x0, y0, end[0], end[1], where)
    radius = math.hypot(x0 - cx, y0 - cy)
    if radius <= 0:
        raise RingtuneError("arc has zero radius", where)
    a0 = math.atan2(y0 - cy, x0 - cx)
    sweep = arc_sweep(clockwise, a0, math.atan2(end[1] - cy, end[0] - cx))
    if isinstance(resolution, MarlinArcs):
        n = resolution.segments(radius, sweep)
    elif isinstance(resolution, DeviationArcs):
        n = resolution.segments(radius, sweep, feed, speed_factor)
    elif resolution is not None and "R" not in w:      # Klipper: floor(travel / resolution) segments (it refuses R)
        n = max(1, math.floor(math.hypot(radius * sweep, end[2] - start[2]) / resolution))
    else:
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


def arcs_note(job, limits) -> str | None:
    """How ``job``'s arcs are planned on a firmware reading it with ``limits`` (None: it has none)."""
    n = job.arcs[0]
    if not n:
        return None
    res = arc_resolution(limits)
    if res is None:
        return (f"the job's {n} arcs (G2/G3) are planned as chords within {job.arc_tolerance:g} mm of the arc "
                "(the firmware's own segment lengths are not modelled)")
    if isinstance(res, DeviationArcs):
        speed = "the move's speed" if res.sees_speed_factor else "the job's feed rate (before M220)"
        return (f"the job's {n} arcs (G2/G3) are planned as {res.firmware} cuts them: segments that deviate "
                f"{res.deviation:g} mm from the arc, or that {res.per_second:g} a second cover at {speed} if "
                f"shorter, within {res.min_mm:g}–{res.max_mm:g} mm")
    if isinstance(res, MarlinArcs):
        return (f"the job's {n} arcs (G2/G3) are planned as Marlin 2.1 cuts them with its default build settings: "
                f"segments of at most {res.max_mm:g} mm (MAX_ARC_SEGMENT_MM; MIN_ARC_SEGMENT_MM {res.min_mm:g}), "
                f"at least {res.circle_segments} to a full circle (MIN_CIRCLE_SEGMENTS); a build with other "
                "values cuts them otherwise")
    whose = ("the printer's [gcode_arcs] resolution" if limits.arc_resolution else "Klipper's default resolution; "
             "[limits] arc_resolution gives the printer's, which `ringtune printer from-klipper` reads")
    return (f"the job's {n} arcs (G2/G3) are planned as Klipper's [gcode_arcs] cuts them: segments of {res:g} mm "
            f"({whose})" + _refused_words(job.arcs[2]))


def _refused_words(lines: tuple) -> str:
    """What Klipper does with the arcs on ``lines`` (given by R or in relative mode), or ""."""
    if not lines:
        return ""
    return (f"; Klipper refuses {len(lines)} of them (given by R or in relative mode; the first on line {lines[0]}) "
            "and stops the print there: they are planned as chords")
