"""Trapezoidal motion planner with look-ahead over the whole job, vectorised (units mm, s, mm/s, mm/s²).

What a firmware does between a parsed move and the motors, for three junction rules:

- ``scv`` — Klipper: "approximated centripetal velocity" from ``square_corner_velocity`` (junction
  deviation ``scv²(√2−1)/accel``), the centripetal half-move bound, the extruder's instantaneous
  corner velocity (1 mm/s), extrude-only moves come to rest; ``minimum_cruise_ratio`` (or legacy
  ``accel_to_decel``) caps each accelerate-decelerate hill at the peak a "smoothed" acceleration
  ``accel·(1 − ratio)`` reaches.
- ``jd`` — Marlin junction deviation: ``v² = a_j·jd·sin(θ/2)/(1 − sin(θ/2))`` with ``a_j`` the
  acceleration limited by the per-axis maxima along the junction vector, and Marlin's short-segment
  arc bound.
- ``jerk`` — classic jerk, as Marlin 1.1/2.x and PrusaSlicer's time estimator compute it: per-axis
  speed jumps bounded by the jerk limits, "safe" entry/exit speeds from and to rest.

Per-axis maximum speeds and accelerations scale each move's speed and acceleration by the
firmware's own rule (``axis_rule``): ``per_axis`` — each axis's share of the move stays under its
cap, ``a ≤ cap_i/|u_i|`` (Marlin ``M201``/``M203`` in its planner's ``LIMIT_ACCEL``, RepRapFirmware
``M201``, Kalico's limited_cartesian, Klipper's Z caps); ``limited_corexy`` — Kalico's
limited_corexy ``check_move``: the two belts' shares, ``a ≤ 1/max(|u_x/c_x + u_y/c_y|, |u_x/c_x −
u_y/c_y|) = 1/(|u_x|/c_x + |u_y|/c_y)`` and the speed ``v ≤ velocity/(|u_x| + |u_y|)`` (max_velocity
is each motor's); ``scale_xy_accel`` scales those caps by the printing acceleration as Kalico does.
Marlin's retraction (an E-only move) runs at ``M204 R`` without the axis caps (its planner's
retract branch) wherever a retract acceleration is known (the machine's ``retract_accel`` or the
job's M204 R); otherwise (RepRapFirmware, whose M204 has no R) an E-only move runs at the printing
acceleration under the E cap (M201 E). Settings the job itself sets (M201/M203/M204/M205/SET_VELOCITY_LIMIT) override the
machine's from the line where they appear (``use_job_limits``).

Look-ahead is exact over the whole job: the forward pass ``w[i+1] = min(c[i+1], w[i] + δ[i])``
(v² at junctions, δ = 2·a·d) is a min-plus recurrence solved in closed form as
``S + minimum.accumulate(c − S)`` with ``S`` the running sum of δ; the backward pass is its mirror.

RepRapFirmware ≤ 3.3's Dynamic Acceleration Adjustment (``daa_freq``; RRF's
``DDA::AdjustAcceleration``) then lowers each move's acceleration and deceleration so that each
phase lasts one ringing period ``1/f`` (two if one is too short for the limits), never raising
acceleration and never under ``daa_min_accel`` (M593 L, 10 mm/s²); see
:func:`ringtune.shaping.lookahead.daa_adjust`. It works on the whole-job plan at once, where RRF
adjusts each move as it prepares it.

Simplification: at a forced stop (G4, M400, a shaper change ...) the jerk rule's "safe speed" jump
uses the smaller of the two moves' safe speeds on both sides (exact for the other rules, which
stop at zero).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.extruder_alone import e_capped
from ringtune.shaping.firmware_retraction import fold_retractions
from ringtune.shaping.gcode import read_gcode
from ringtune.shaping.job import Job
from ringtune.shaping.klipper_reading import klipper_rests
from ringtune.shaping.lookahead import (axis_caps, backward_pass, corexy_speed_cap, daa_adjust, extruder_alone,
                                        forward_pass, jerk_setting, job_value, junction_limits, kinematic_accel,
                                        klipper_smoothing, marlin_retractions, move_accels, scale_by_axes)
from ringtune.shaping.plan_result import MoveTable, Plan
from ringtune.shaping.plan_segments import PlanSegments

__all__ = ["MachineLimits", "plan", "limits_from_job", "guess_junction", "JUNCTIONS",
           "AXIS_RULES"]

JUNCTIONS = ("scv", "jd", "jerk")
#: how per-axis caps bind (module docstring)
AXIS_RULES = ("per_axis", "limited_corexy")


def reads_like_klipper(klipper_reading: bool | None, junction: str) -> bool:
    """Whether a job's limit commands are read as Klipper reads them: ``klipper_reading`` (the
    firmware's, :func:`ringtune.shaping.firmware.job_reading`), else as the junction rule's firmware
    would (Klipper's ``scv``)."""
    return klipper_reading if klipper_reading is not None else junction == "scv"


@dataclass
class MachineLimits:
    """Motion limits of a machine (mm/s, mm/s², mm).

    accel: printing acceleration; velocity: top speed; junction: ``scv`` | ``jd`` | ``jerk``;
    square_corner_velocity (Klipper), junction_deviation (Marlin), jerk (x, y, z, e classic jerk);
    max_accel / max_velocity: per-axis caps (x, y, z, e) or None (Marlin's and RRF's M201/M203; Klipper
    has none on E); extrude_only_accel / extrude_only_velocity: Klipper's [extruder]
    max_extrude_only_accel / _velocity (None: not known), the only limits of the moves
    :func:`~ringtune.shaping.extruder_alone.e_capped` marks there; max_extrude_ratio,
    nozzle_diameter (mm) and extrude_only_distance (mm): the moves Klipper's extruder refuses
    (:func:`~ringtune.shaping.klipper_refusals.klipper_refusals`; None: not known); min_cruise_ratio (Klipper only);
    accel_to_decel: a Klipper from before 2024 (no minimum_cruise_ratio), its max_accel_to_decel in
    mm/s², kept whatever ACCEL becomes (None: a current Klipper or Kalico, which ignore a job's
    ACCEL_TO_DECEL); m203_per_minute: the firmware reads a job's M203 speeds in mm/min
    (RepRapFirmware; Marlin: mm/s); reads_m566: the firmware has RRF's M566 jerk beside M205
    (Marlin and Prusa have M205 alone);
    travel_accel / retract_accel: Marlin's M204 T / R, RRF's M204 T (None = accel; a firmware reading
    the job by role uses them, Klipper has one acceleration); axis_rule: how the per-axis
    caps bind (:data:`AXIS_RULES`, module docstring); scale_xy_accel: Kalico's ``scale_xy_accel``;
    klipper_reading: whether the firmware reads a job's limit commands as Klipper and Kalico do (one
    acceleration from M204 S, or P and T together, or SET_VELOCITY_LIMIT; no M201/M203), else by
    role as Marlin, Prusa and RepRapFirmware (M204 P printing, T travel, R retract; M201/M203 caps);
    None: as the junction rule implies (Klipper's ``scv``, the others' ``jd``/``jerk``) — the
    firmware, not its corner rule, decides it where both are known (:attr:`reads_like_klipper`);
    retract_length (mm), retract_speed, unretract_extra_length (mm), unretract_speed (mm/s): what a
    ``G10``/``G11`` moves the extruder by (Klipper's ``[firmware_retraction]``, Marlin's M207/M208,
    RRF's M207; :mod:`ringtune.shaping.firmware_retraction`), None: not known (a retraction that
    moves the extruder without its speed is not known either); retract_zlift: the Z hop (mm) at each
    ``G10`` (Marlin's and RRF's M207 Z); arc_resolution: Klipper's ``[gcode_arcs]
    resolution`` (mm; None: its default 1 mm, :func:`ringtune.shaping.arcs.arc_resolution`); arc_firmware:
    whose segments G2/G3 become, ``klipper`` | ``marlin`` | ``rrf`` | ``prusa`` (None: as the reading
    implies, :attr:`arc_rule`); hw_max_accel / hw_max_velocity / hw_max_jerk: a firmware's compiled
    ceilings (x, y, z, e) on the per-axis caps and classic jerk whatever M201/M203/M205 ask
    (Prusa-Firmware-Buddy's HWLIMIT for the job's model, :mod:`ringtune.shaping.prusa_limits`), None: none;
    travel_x / travel_y: where the toolhead may go on X / Y, (min, max) mm (Klipper's ``[stepper_x]``
    position_min / position_max: it refuses a move that ends past them,
    :func:`~ringtune.shaping.klipper_refusals.klipper_refusals`), None: not known.
    """

    accel: float = 3000.0
    velocity: float = 300.0
    junction: str = "scv"
    square_corner_velocity: float = 5.0
    junction_deviation: float = 0.013
    jerk: tuple = (8.0, 8.0, 0.4, 5.0)
    max_accel: tuple | None = None
    max_velocity: tuple | None = None
    min_cruise_ratio: float = 0.5
    accel_to_decel: float | None = None
    m203_per_minute: bool = False
    reads_m566: bool = True
    travel_accel: float | None = None
    retract_accel: float | None = None
    axis_rule: str = "per_axis"
    scale_xy_accel: bool = False
    klipper_reading: bool | None = None
    retract_length: float | None = None
    retract_speed: float | None = None
    unretract_extra_length: float = 0.0
    unretract_speed: float | None = None
    arc_resolution: float | None = None
    arc_firmware: str | None = None
    retract_zlift: float = 0.0
    extrude_only_accel: float | None = None
    extrude_only_velocity: float | None = None
    max_extrude_ratio: float | None = None
    nozzle_diameter: float | None = None
    extrude_only_distance: float | None = None
    hw_max_accel: tuple | None = None
    hw_max_velocity: tuple | None = None
    hw_max_jerk: tuple | None = None
    travel_x: tuple | None = None
    travel_y: tuple | None = None

    @property
    def reads_like_klipper(self) -> bool:
        return reads_like_klipper(self.klipper_reading, self.junction)

    @property
    def arc_rule(self) -> str | None:
        """Whose segments G2/G3 become (:data:`ringtune.shaping.arcs.ARC_RULES`): the firmware's, else
        Klipper's where the job is read as Klipper reads it, RepRapFirmware's where M203 is in mm/min,
        Marlin's under its junction rule, None (not known: tolerance chords) otherwise."""
        if self.arc_firmware is not None:
            return self.arc_firmware
        if self.reads_like_klipper:
            return "klipper"
        return "rrf" if self.m203_per_minute else "marlin" if self.junction == "jd" else None

    def __post_init__(self) -> None:
        self.validate()

    def _validate_axis_rule(self, where: str) -> None:
        if self.axis_rule not in AXIS_RULES:
            raise RingtuneError(f"must be one of {', '.join(AXIS_RULES)}, not {self.axis_rule!r}",
                                f"{where}.axis_rule")
        if self.scale_xy_accel and not (self.max_accel and all(c > 0 for c in self.max_accel[:2])):
            raise RingtuneError("scale_xy_accel needs X and Y caps (max_accel)", f"{where}.scale_xy_accel")

    def validate(self, where: str = "limits") -> None:
        if self.junction not in JUNCTIONS:
            raise RingtuneError(f"junction must be one of {', '.join(JUNCTIONS)}, not {self.junction!r}",
                                f"{where}.junction")
        self._validate_axis_rule(where)
        for names, ok, message in _LIMIT_CHECKS:
            for name in names:
                v = getattr(self, name)
                if not ok(v):
                    raise RingtuneError(message.format(v=v), f"{where}.{name}")


def _positive(v) -> bool:
    return isinstance(v, (int, float)) and math.isfinite(v) and v > 0


def _non_negative(v) -> bool:
    return isinstance(v, (int, float)) and math.isfinite(v) and v >= 0


def _fraction(v) -> bool:
    return 0 <= v < 1


def _four_or_none(v) -> bool:
    """None, or four finite values >= 0 (x, y, z, e)."""
    return v is None or (len(v) == 4 and all(math.isfinite(x) and x >= 0 for x in v))


def _positive_or_none(v) -> bool:
    return v is None or (math.isfinite(v) and v > 0)


#: checks of MachineLimits' fields: (names, test of the value, message; {v} is the value)
_LIMIT_CHECKS = (
    (("accel", "velocity"), _positive, "must be a positive number, not {v!r}"),
    (("square_corner_velocity", "junction_deviation"), _non_negative, "must be a number >= 0, not {v!r}"),
    (("min_cruise_ratio",), _fraction, "must be in [0, 1)"),
    (("jerk", "max_accel", "max_velocity", "hw_max_accel", "hw_max_velocity", "hw_max_jerk"), _four_or_none,
     "needs 4 numbers >= 0 (x, y, z, e)"),
    (("travel_accel", "retract_accel", "accel_to_decel", "retract_speed", "unretract_speed", "arc_resolution",
      "extrude_only_accel", "extrude_only_velocity", "max_extrude_ratio", "nozzle_diameter", "extrude_only_distance"),
     _positive_or_none,
     "must be a positive number"),
    (("travel_x", "travel_y"), lambda v: v is None or (len(v) == 2 and all(math.isfinite(x) for x in v)
                                                      and v[0] < v[1]),
     "needs 2 numbers, min < max (mm)"),
    (("unretract_extra_length",), lambda v: isinstance(v, (int, float)) and math.isfinite(v),
     "must be a number, not {v!r}"),
    (("retract_length",), lambda v: v is None or _non_negative(v), "must be a number >= 0, not {v!r}"),
)


# -- the planner ---------------------------------------------------------------------------------

def _held(caps: np.ndarray, ceiling: tuple | None) -> np.ndarray:
    """(n, 4) per-axis caps held to a firmware's compiled ceilings (x, y, z, e; 0: none), whatever
    M201/M203 ask: Prusa-Firmware-Buddy's HWLIMIT (:mod:`ringtune.shaping.prusa_limits`)."""
    if ceiling is None:
        return caps
    top = np.array([c if c > 0 else np.inf for c in ceiling], float)
    return np.minimum(caps, top[None, :])

def plan(job_or_moves, limits: MachineLimits | None = None, daa_freq: float | None = None,
         use_job_limits: bool = True, daa_min_accel: float = 10.0,
         accel: float | None = None) -> Plan:
    """Plan a job (a :class:`Job` or G-code text/path) into exact constant-acceleration motion.

    ``limits``: the machine (default :class:`MachineLimits`); the job's own M201/M203/M204/M205/
    SET_VELOCITY_LIMIT lines override it from where they appear unless ``use_job_limits=False``.
    ``accel``: one acceleration (mm/s²) for every move, replacing the machine's and the job's
    M204/SET_VELOCITY_LIMIT values (per-axis M201 caps still apply) — a tuning knob.
    ``daa_freq``: RRF ≤ 3.3 DAA at this ringing frequency (Hz), ``daa_min_accel`` its M593 L.
    """
    job = job_or_moves if isinstance(job_or_moves, Job) else read_gcode(job_or_moves)
    accel_override = accel
    limits = limits or MachineLimits()
    limits.validate()
    n = job.n_moves
    if n == 0:
        raise RingtuneError("the job has no moves", job.source)
    use = use_job_limits
    delta = job.end - job.start
    xyz = np.sqrt(np.einsum("ij,ij->i", delta[:, :3], delta[:, :3]))
    e_only = xyz == 0
    d = np.where(e_only, np.abs(delta[:, 3]), xyz)
    u = delta / d[:, None]
    extruding = (delta[:, 3] > 0) & (np.hypot(delta[:, 0], delta[:, 1]) > 0)

    # -- speeds and accelerations per move --
    klipper = limits.reads_like_klipper      # Klipper's and Kalico's reading: the job's M201/M203 do not exist there,
    if klipper:                              # nor rests at commands it does not have, nor G4's S word
        stop, dwell, after = klipper_rests(job)
        job = replace(job, stop_before=stop, dwell_before=dwell, dwell_after=after)
    velocity = job_value(job, "velocity", limits.velocity, use and klipper)   # nor SET_VELOCITY_LIMIT on Marlin/RRF
    vmax = np.minimum(job.feed, velocity)
    e_cap = e_capped(delta)                  # the moves Klipper's extruder limits bind
    vcaps = axis_caps(job, "max_vel", limits.max_velocity, use, klipper, 1 / 60 if limits.m203_per_minute else 1.0,
                      e_cap, limits.extrude_only_velocity)
    vcaps = _held(vcaps, limits.hw_max_velocity)
    vmax = scale_by_axes(vmax, u, vcaps)
    if limits.axis_rule == "limited_corexy":
        vmax = corexy_speed_cap(vmax, velocity, u)
    base = move_accels(job, limits, use, delta, e_only, accel_override)
    amax_axes = _held(axis_caps(job, "max_accel", limits.max_accel, use, klipper, e_alone=e_cap,
                                e_klipper=limits.extrude_only_accel), limits.hw_max_accel)
    accel = kinematic_accel(base, u, amax_axes, limits.axis_rule, limits.scale_xy_accel,
                            skip=marlin_retractions(job, limits, use, e_only))
    if klipper:
        accel, vmax = extruder_alone(accel, vmax, job.feed, e_only, amax_axes[:, 3], vcaps[:, 3])
    if np.any(~(vmax > 0)) or np.any(~(accel > 0)):
        i = int(np.flatnonzero(~((vmax > 0) & (accel > 0)))[0])
        raise RingtuneError("a move ends up with zero speed or acceleration (check M203/M201)",
                            f"{job.source}:{job.line[i]}")
    v2 = vmax * vmax
    dv2 = 2.0 * accel * d

    cj = _junction_v2(job, limits, use, u, d, e_only, vmax, accel, amax_axes, v2, base if klipper else None)

    w = backward_pass(forward_pass(cj, dv2), dv2)
    cruise2 = np.minimum(v2, 0.5 * (w[:-1] + w[1:] + dv2))

    if limits.junction == "scv":
        cruise2, w = klipper_smoothing(job, limits, use, cj, w, cruise2, accel, d, dv2, v2, base)

    # -- DAA --
    decel = accel.copy()
    acc = accel.copy()
    if daa_freq:
        acc, decel, cruise2 = daa_adjust(daa_freq, daa_min_accel, w, cruise2, accel, d, u)
    per_move = (w[:-1], w[1:], cruise2, acc, decel, d, u, vmax, extruding)
    if job.fw_inserted is not None:      # firmware retractions: their E-only moves become the rest they are
        t_acc, t_cr, t_dec = _phases(*_speeds(*per_move[:3]), acc, decel, d)[:3]
        job, per_move = fold_retractions(job, per_move, t_acc + t_cr + t_dec)
    return _build(job, limits, *per_move)


def _junction_v2(job, limits, use, u, d, e_only, vmax, accel, amax_axes, v2, toolhead) -> np.ndarray:
    """Junction limits c[0..n] (v² at the start of move i; c[n] = end of the job): the rule's,
    full stops where the job stops, never above either move's top speed."""
    n = job.n_moves
    c, safe = junction_limits(job, limits, use, u, d, e_only, vmax, accel, amax_axes, toolhead)
    stop = job.stop_before.copy()
    stop[0] = True
    if limits.junction == "jerk":
        c_stop = np.minimum(safe, np.concatenate(([safe[0]], safe[:-1]))) ** 2
    else:
        c_stop = np.zeros(n)
    cj = np.empty(n + 1)
    cj[:n] = np.where(stop, c_stop, c)
    cj[n] = safe[-1] ** 2 if limits.junction == "jerk" else 0.0
    cj[1:n] = np.minimum(cj[1:n], np.minimum(v2[1:], v2[:-1]))
    cj[0] = min(cj[0], v2[0])
    return cj


def _speeds(start2, end2, cruise2) -> tuple:
    """(entry, cruise, exit) speeds, mm/s, from their squares (the cruise at least either end)."""
    s = np.sqrt(np.maximum(start2, 0.0))
    e = np.sqrt(np.maximum(end2, 0.0))
    return s, np.maximum(np.sqrt(np.maximum(cruise2, 0.0)), np.maximum(s, e)), e


def _phases(s, c, e, acc, dec, d) -> tuple:
    """Per move (speeds: :func:`_speeds`): seconds of acceleration, cruise and deceleration, and
    the mm of acceleration and of cruise."""
    t_acc, t_dec = (c - s) / acc, (c - e) / dec
    d_acc = 0.5 * (s + c) * t_acc
    d_cr = np.maximum(d - d_acc - 0.5 * (c + e) * t_dec, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return t_acc, np.where(c > 0, d_cr / c, 0.0), t_dec, d_acc, d_cr


def _build(job, limits, start2, end2, cruise2, acc, dec, d, u, vmax, extruding) -> Plan:
    n = job.n_moves
    s, c, e = _speeds(start2, end2, cruise2)
    t_acc, t_cr, t_dec, d_acc, d_cr = _phases(s, c, e, acc, dec, d)
    dwell = job.dwell_before
    # segments per move: dwell, accel, cruise, decel
    dur = np.stack([dwell, t_acc, t_cr, t_dec], axis=1)                 # (n, 4)
    dist0 = np.stack([np.zeros(n), np.zeros(n), d_acc, d_acc + d_cr], axis=1)
    speed0 = np.stack([np.zeros(n), s, c, c], axis=1)
    acc_sg = np.stack([np.zeros(n), acc, np.zeros(n), -dec], axis=1)
    # the segments that last, in order: flat index 4·move + kind; their states are built where
    # asked (PlanSegments: a trial reads a few windows of a long job)
    kept = np.flatnonzero(dur > 1e-12)
    t = np.concatenate(([0.0], np.cumsum(np.take(dur, kept))))
    segments = PlanSegments.of(t, kept, job.start, u, dist0, speed0, acc_sg, extruding)
    # move start times (after its dwell)
    move_total = ((dur[:, 0] + dur[:, 1]) + dur[:, 2]) + dur[:, 3]      # dur.sum(axis=1), in its order, faster
    t_move0 = np.concatenate(([0.0], np.cumsum(move_total)[:-1])) + dwell
    duration = t_acc + t_cr + t_dec
    print_time = float(t[-1] + job.dwell_after)
    events = []
    for ev in job.events:
        if ev.move < n:
            tt = float(t_move0[ev.move] - dwell[ev.move])
        else:
            tt = float(t[-1])
        events.append(replace(ev, time=tt))
    table = MoveTable(job.line, job.start, job.end, d, job.feed, vmax, s, c, e, acc, dec,
                      t_move0, duration, job.feature, extruding, list(job.features))
    return Plan(segments, table, print_time, events, limits)


#: job header settings that set MachineLimits fields: (job's setting, field, 0 allowed)
_JOB_LIMITS = (("accel_travel", "travel_accel", False), ("accel_retract", "retract_accel", False),
               ("square_corner_velocity", "square_corner_velocity", False),
               ("junction_deviation", "junction_deviation", False), ("velocity", "velocity", False),
               ("min_cruise_ratio", "min_cruise_ratio", True))


def limits_from_job(job: Job, base: MachineLimits | None = None, junction: str | None = None) -> MachineLimits:
    """Machine limits taking the first value the job sets for each (its header), over ``base``."""
    base = base or MachineLimits()
    fs = job.file_setting
    kw = {}
    a = fs("accel_klipper") if junction == "scv" else fs("accel_print")
    if a == a:
        kw["accel"] = a
    for key, name, zero_ok in _JOB_LIMITS:
        v = fs(key)
        if v > 0 or (zero_ok and v == 0):     # NaN (unset) fails both
            kw[name] = v
    jerk = _job_jerk(job, base)
    if jerk:
        kw["jerk"] = jerk
    if junction:
        kw["junction"] = junction
    return replace(base, **kw)


def _job_jerk(job: Job, base: MachineLimits) -> tuple | None:
    """(x, y, z, e) jerk the job's header sets (as ``base``'s firmware reads it), mm/s, ``base``'s
    where it sets none; None if none."""
    jerk = [job.file_setting(f"{jerk_setting(base)}_{ax}") for ax in "xyze"]
    if not any(j == j for j in jerk):
        return None
    return tuple(j if j == j else b for j, b in zip(jerk, base.jerk))


def guess_junction(job: Job) -> str:
    """The junction rule a job's own commands point to: Klipper's SET_VELOCITY_LIMIT
    SQUARE_CORNER_VELOCITY -> scv, M205 J -> jd, M205 X/Y -> jerk, else scv."""
    for key, rule in (("square_corner_velocity", "scv"), ("junction_deviation", "jd"), ("jerk_x", "jerk"),
                      ("jerk_y", "jerk")):
        if job.file_setting(key) == job.file_setting(key):      # set (not NaN)
            return rule
    return "scv"
