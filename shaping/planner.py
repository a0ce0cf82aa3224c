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

Per-axis maximum speeds and accelerations scale each move's speed and acceleration (as Marlin
does). Settings the job itself sets (M201/M203/M204/M205/SET_VELOCITY_LIMIT) override the
machine's from the line where they appear (``use_job_limits``).

Look-ahead is exact over the whole job: the forward pass ``w[i+1] = min(c[i+1], w[i] + δ[i])``
(v² at junctions, δ = 2·a·d) is a min-plus recurrence solved in closed form as
``S + minimum.accumulate(c − S)`` with ``S`` the running sum of δ; the backward pass is its mirror.

RepRapFirmware ≤ 3.3's Dynamic Acceleration Adjustment (``daa_freq``) then lowers each move's
acceleration and deceleration so that each phase lasts one ringing period ``1/f`` (two if one is
too short for the limits), never raising acceleration, and leaves a move alone when its phases
cannot fit the move or the acceleration would drop under ``daa_min_accel`` (M593 L, 10 mm/s²).

Simplification: at a forced stop (G4, M400, a shaper change ...) the jerk rule's "safe speed" jump
uses the smaller of the two moves' safe speeds on both sides (exact for the other rules, which
stop at zero).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.gcode import Event, Job
from ringtune.shaping.motion import Motion

JUNCTIONS = ("scv", "jd", "jerk")
KLIPPER_INSTANT_CORNER_V = 1.0     # mm/s, Klipper [extruder] instantaneous_corner_velocity default


@dataclass
class MachineLimits:
    """Motion limits of a machine (mm/s, mm/s², mm).

    accel: printing acceleration; velocity: top speed; junction: ``scv`` | ``jd`` | ``jerk``;
    square_corner_velocity (Klipper), junction_deviation (Marlin), jerk (x, y, z, e classic jerk);
    max_accel / max_velocity: per-axis caps (x, y, z, e) or None; min_cruise_ratio (Klipper only);
    travel_accel / retract_accel: Marlin's M204 T / R (None = accel).
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
    travel_accel: float | None = None
    retract_accel: float | None = None

    def __post_init__(self) -> None:
        self.validate()

    def validate(self, where: str = "limits") -> None:
        if self.junction not in JUNCTIONS:
            raise RingtuneError(f"junction must be one of {', '.join(JUNCTIONS)}, not {self.junction!r}",
                                f"{where}.junction")
        for name in ("accel", "velocity"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise RingtuneError(f"must be a positive number, not {v!r}", f"{where}.{name}")
        for name in ("square_corner_velocity", "junction_deviation"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise RingtuneError(f"must be a number >= 0, not {v!r}", f"{where}.{name}")
        if not 0 <= self.min_cruise_ratio < 1:
            raise RingtuneError("must be in [0, 1)", f"{where}.min_cruise_ratio")
        for name in ("jerk", "max_accel", "max_velocity"):
            v = getattr(self, name)
            if v is None:
                continue
            if len(v) != 4 or not all(math.isfinite(x) and x >= 0 for x in v):
                raise RingtuneError("needs 4 numbers >= 0 (x, y, z, e)", f"{where}.{name}")
        for name in ("travel_accel", "retract_accel"):
            v = getattr(self, name)
            if v is not None and not (math.isfinite(v) and v > 0):
                raise RingtuneError("must be a positive number", f"{where}.{name}")


@dataclass
class MoveTable:
    """Per planned move: source line, geometry, speeds (mm/s), accelerations (mm/s²) and times (s)."""

    line: np.ndarray
    start: np.ndarray
    end: np.ndarray
    length: np.ndarray
    feed: np.ndarray          # requested speed
    v_nominal: np.ndarray     # after velocity limits
    v_entry: np.ndarray
    v_cruise: np.ndarray
    v_exit: np.ndarray
    accel: np.ndarray         # acceleration phase
    decel: np.ndarray         # deceleration phase (differs from accel only under DAA)
    t_start: np.ndarray       # when the move starts moving
    duration: np.ndarray
    feature: np.ndarray
    extruding: np.ndarray
    features: list = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.line)


@dataclass
class Plan:
    motion: Motion
    moves: MoveTable
    print_time: float
    events: list
    limits: MachineLimits | None = None

    def time_by_feature(self) -> dict[str, float]:
        """Seconds of motion per slicer feature (dwells are not counted)."""
        out: dict[str, float] = {}
        sums = np.bincount(self.moves.feature, weights=self.moves.duration,
                           minlength=len(self.moves.features))
        for name, s in zip(self.moves.features, sums):
            if s > 0:
                out[name] = float(s)
        return out


# -- helpers ------------------------------------------------------------------------------------
def forward_pass(c: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """w[0] = c[0]; w[i+1] = min(c[i+1], w[i] + delta[i]) for all i, in closed form."""
    s = np.concatenate(([0.0], np.cumsum(delta)))
    return s + np.minimum.accumulate(c - s)


def backward_pass(c: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """u[n] = c[n]; u[i] = min(c[i], u[i+1] + delta[i])."""
    return forward_pass(c[::-1], delta[::-1])[::-1]


def _job_value(job: Job, key: str, default, use: bool) -> np.ndarray:
    n = job.n_moves
    base = np.full(n, np.nan if default is None else float(default))
    if not use:
        return base
    v = job.setting(key)
    return np.where(np.isnan(v), base, v)


def _axis_caps(job: Job, prefix: str, machine: tuple | None, use: bool) -> np.ndarray:
    """(n, 4) per-axis caps (inf = none)."""
    cols = []
    for i, ax in enumerate("xyze"):
        default = np.inf if machine is None or machine[i] <= 0 else machine[i]
        v = _job_value(job, f"{prefix}_{ax}", default, use)
        cols.append(np.where(v > 0, v, np.inf))       # Marlin: 0 means "no limit" for M201/M203
    return np.stack(cols, axis=1)


def _scale_by_axes(value: np.ndarray, u: np.ndarray, caps: np.ndarray) -> np.ndarray:
    """Largest ≤ value such that value·|u_a| ≤ cap_a on every axis."""
    au = np.abs(u)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(au > 0, caps / au, np.inf)
    return np.minimum(value, ratio.min(axis=1))


# -- the planner --------------------------------------------------------------------------------
def plan(job_or_moves, limits: MachineLimits | None = None, daa_freq: float | None = None,
         use_job_limits: bool = True, daa_min_accel: float = 10.0) -> Plan:
    """Plan a job (a :class:`Job` or G-code text/path) into exact constant-acceleration motion."""
    from ringtune.shaping.gcode import read_gcode

    job = job_or_moves if isinstance(job_or_moves, Job) else read_gcode(job_or_moves)
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
    velocity = _job_value(job, "velocity", limits.velocity, use)
    vmax = np.minimum(job.feed, velocity)
    vmax = _scale_by_axes(vmax, u, _axis_caps(job, "max_vel", limits.max_velocity, use))
    if limits.junction == "scv":
        accel = _job_value(job, "accel_klipper", limits.accel, use)
    else:
        a_print = _job_value(job, "accel_print", limits.accel, use)
        a_travel = _job_value(job, "accel_travel", limits.travel_accel or limits.accel, use)
        a_retract = _job_value(job, "accel_retract", limits.retract_accel or limits.accel, use)
        accel = np.where(e_only, a_retract, np.where(delta[:, 3] != 0, a_print, a_travel))
    accel = np.where(accel > 0, accel, limits.accel)
    amax_axes = _axis_caps(job, "max_accel", limits.max_accel, use)
    accel = _scale_by_axes(accel, u, amax_axes)
    if np.any(~(vmax > 0)) or np.any(~(accel > 0)):
        i = int(np.flatnonzero(~((vmax > 0) & (accel > 0)))[0])
        raise RingtuneError("a move ends up with zero speed or acceleration (check M203/M201)",
                            f"{job.source}:{job.line[i]}")
    v2 = vmax * vmax
    dv2 = 2.0 * accel * d

    # -- junction limits c[0..n] (v² at the start of move i; c[n] = end of the job) --
    c, safe = _junctions(job, limits, use, u, d, e_only, vmax, accel, amax_axes)
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

    w = backward_pass(forward_pass(cj, dv2), dv2)
    cruise2 = np.minimum(v2, 0.5 * (w[:-1] + w[1:] + dv2))

    if limits.junction == "scv":
        cruise2, w = _klipper_smoothing(job, limits, use, cj, w, cruise2, accel, d, dv2, v2)

    # -- DAA --
    decel = accel.copy()
    acc = accel.copy()
    if daa_freq:
        acc, decel, cruise2 = _daa(daa_freq, daa_min_accel, w, cruise2, accel, d)

    return _build(job, limits, w, cruise2, acc, decel, d, u, vmax, extruding)


def _junctions(job, limits, use, u, d, e_only, vmax, accel, amax_axes):
    """Junction v² limit between move i-1 and i (c[i], c[0] unused) and jerk 'safe' speeds."""
    n = job.n_moves
    c = np.full(n, np.inf)
    safe = np.zeros(n)
    if n < 2:
        if limits.junction == "jerk":
            safe = _jerk_safe(job, limits, use, u, vmax)
        return c, safe
    up, uc = u[:-1], u[1:]
    if limits.junction == "scv":
        scv = _job_value(job, "square_corner_velocity", limits.square_corner_velocity, use)
        nx = np.where(e_only[:, None], 0.0, u[:, :3])
        cos_j = -np.einsum("ij,ij->i", nx[1:], nx[:-1])
        sin_d2 = np.sqrt(np.maximum(0.5 * (1 - cos_j), 0.0))
        cos_d2 = np.sqrt(np.maximum(0.5 * (1 + cos_j), 0.0))
        one_minus = 1 - sin_d2
        ok = (one_minus > 0) & (cos_d2 > 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            r_jd = sin_d2 / one_minus
            k = math.sqrt(2) - 1
            jd_v2 = r_jd * k * np.minimum(scv[1:] ** 2, scv[:-1] ** 2)
            q = 0.25 * sin_d2 / cos_d2
            cent = np.minimum(2 * accel[1:] * d[1:], 2 * accel[:-1] * d[:-1]) * q
        lim = np.where(ok, np.minimum(jd_v2, cent), np.inf)
        # extruder: instantaneous corner velocity on the change of extrusion ratio
        diff_r = np.abs(uc[:, 3] - up[:, 3])
        with np.errstate(divide="ignore"):
            ext = np.where(diff_r > 0, (KLIPPER_INSTANT_CORNER_V / diff_r) ** 2, np.inf)
        lim = np.minimum(lim, ext)
        lim = np.where(e_only[1:] | e_only[:-1], 0.0, lim)
        c[1:] = lim
    elif limits.junction == "jd":
        jd = _job_value(job, "junction_deviation", limits.junction_deviation, use)[1:]
        nv = np.where(e_only[:, None], np.array([0, 0, 0, 1.0]) * np.sign(u[:, 3:4]),
                      np.concatenate([u[:, :3], np.zeros((len(u), 1))], axis=1))
        cos_t = -np.einsum("ij,ij->i", nv[1:], nv[:-1])
        rev = cos_t > 0.999999
        cos_c = np.clip(cos_t, -0.999999, 1.0)
        sin_d2 = np.sqrt(0.5 * (1 - cos_c))
        ju = nv[1:] - nv[:-1]
        norm = np.linalg.norm(ju, axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            ju = ju / np.where(norm > 0, norm, 1.0)[:, None]
        a_j = _scale_by_axes(accel[1:], ju, amax_axes[1:])
        lim = a_j * jd * sin_d2 / (1 - sin_d2)
        # Marlin: short segments of a curve (length < 1 mm, angle > 135°) ~ circular arc bound
        theta = np.arccos(np.clip(-cos_c, -1, 1))      # angle between directions (0 = straight)
        junction_theta = np.pi - theta
        small = (d[1:] < 1.0) & (junction_theta > np.radians(135)) & (theta > 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            arc = d[1:] * a_j / theta
        lim = np.where(small, np.minimum(lim, arc), lim)
        lim = np.where(rev, 0.05 ** 2, lim)
        c[1:] = lim
    else:
        safe = _jerk_safe(job, limits, use, u, vmax)
        c[1:] = _jerk_junction(job, limits, use, u, vmax, safe) ** 2
    if limits.junction == "jerk":
        pass
    elif limits.junction != "jerk":
        safe = np.zeros(n)
    return c, safe


def _jerk_limits(job, limits, use) -> np.ndarray:
    return np.stack([_job_value(job, f"jerk_{ax}", limits.jerk[i], use) for i, ax in enumerate("xyze")],
                    axis=1)


def _jerk_safe(job, limits, use, u, vmax) -> np.ndarray:
    """Speed a move may start from / end at rest with (PrusaSlicer's ``safe_feedrate``)."""
    jerk = _jerk_limits(job, limits, use)
    axis_v = np.abs(u) * vmax[:, None]
    capped = np.where(axis_v > jerk, jerk, np.inf)
    return np.minimum(vmax, capped.min(axis=1))


def _jerk_junction(job, limits, use, u, vmax, safe) -> np.ndarray:
    """Classic-jerk junction speed between move i-1 and i (PrusaSlicer / Marlin rule), (n-1,)."""
    jerk = _jerk_limits(job, limits, use)[1:]
    prev_v, cur_v = vmax[:-1], vmax[1:]
    prev_larger = prev_v > cur_v
    with np.errstate(divide="ignore", invalid="ignore"):
        smaller = np.where(prev_larger, cur_v / prev_v, prev_v / cur_v)
    vj = np.where(prev_larger, cur_v, prev_v)
    v_exit_all = u[:-1] * prev_v[:, None]
    v_entry_all = u[1:] * cur_v[:, None]
    v_factor = np.ones(len(vj))
    limited = np.zeros(len(vj), bool)
    for a in range(4):
        v_exit = np.where(prev_larger, v_exit_all[:, a] * smaller, v_exit_all[:, a])
        v_entry = v_entry_all[:, a]
        v_exit = np.where(limited, v_exit * v_factor, v_exit)
        v_entry = np.where(limited, v_entry * v_factor, v_entry)
        coast_down = (v_entry > 0) | (v_exit < 0)
        coast_up = (v_entry < 0) | (v_exit > 0)
        j = np.where(v_exit > v_entry,
                     np.where(coast_down, v_exit - v_entry, np.maximum(v_exit, -v_entry)),
                     np.where(coast_up, v_entry - v_exit, np.maximum(-v_exit, v_entry)))
        over = j > jerk[:, a]
        with np.errstate(divide="ignore", invalid="ignore"):
            v_factor = np.where(over, v_factor * jerk[:, a] / j, v_factor)
        limited |= over
    vj = np.where(limited, vj * v_factor, vj)
    thr = 0.99 * vj
    not_coasting = (safe[:-1] > thr) & (safe[1:] > thr)
    vj = np.where(not_coasting, safe[1:], vj)
    vj = np.where(prev_v > 1e-4, vj, safe[1:])
    return vj


def _klipper_smoothing(job, limits, use, cj, w, cruise2, accel, d, dv2, v2):
    """Klipper's minimum_cruise_ratio: cap each accelerate/decelerate hill at the peak reached
    with the smoothed acceleration, then re-run the passes so junctions stay reachable."""
    mcr = _job_value(job, "min_cruise_ratio", limits.min_cruise_ratio, use)
    atd = _job_value(job, "accel_to_decel", None, use)
    a_s = np.where(np.isnan(atd), accel * (1 - mcr), np.minimum(atd, accel))
    if np.all(a_s >= accel):
        return cruise2, w
    ds = 2 * a_s * d
    sm = backward_pass(forward_pass(cj, ds), ds)
    peak = np.minimum(v2, 0.5 * (sm[:-1] + sm[1:] + ds))      # smoothed peak inside each move
    n = len(d)
    valley = np.zeros(n + 1, bool)
    valley[1:n] = (sm[1:n] < peak[:-1] - 1e-9) & (sm[1:n] < peak[1:] - 1e-9)
    hill = np.cumsum(valley[:n])
    starts = np.flatnonzero(np.concatenate(([True], hill[1:] != hill[:-1])))
    hill_peak = np.maximum.reduceat(peak, starts)[hill - hill[0]] if n else peak
    cap = np.minimum(cruise2, hill_peak)
    c2 = cj.copy()
    c2[1:n] = np.minimum(c2[1:n], np.minimum(cap[1:], cap[:-1]))
    c2[0] = min(c2[0], cap[0])
    c2[n] = min(c2[n], cap[-1])
    w2 = backward_pass(forward_pass(np.minimum(c2, w), dv2), dv2)
    return np.minimum(cap, 0.5 * (w2[:-1] + w2[1:] + dv2)), w2


def _daa(freq, min_accel, w, cruise2, accel, d):
    """RRF ≤ 3.3 Dynamic Acceleration Adjustment: phase times of one (or two) ringing periods."""
    if not (math.isfinite(freq) and freq > 0):
        raise RingtuneError(f"DAA frequency must be > 0 Hz, not {freq}", "daa_freq")
    period = 1.0 / freq
    s, e = np.sqrt(w[:-1]), np.sqrt(w[1:])
    c = np.sqrt(cruise2)

    def phase_time(dv):
        t = dv / accel
        return np.where(dv <= 0, 0.0, np.where(t < period, period, np.where(t < 2 * period, 2 * period, t)))

    # a phase of two periods or more is left as it is; if a retimed phase then no longer fits
    # the move, the top speed is lowered (both phases retimed) or the move is left alone
    ta, td = phase_time(c - s), phase_time(c - e)
    need = 0.5 * (s + c) * ta + 0.5 * (c + e) * td
    with np.errstate(divide="ignore", invalid="ignore"):
        c_fit = np.where(ta + td > 0, (2 * d - s * ta - e * td) / (ta + td), c)
    c_new = np.where(need > d, c_fit, c)
    with np.errstate(divide="ignore", invalid="ignore"):
        acc = np.where(ta > 0, (c_new - s) / ta, accel)
        dec = np.where(td > 0, (c_new - e) / td, accel)
    kept = ((c - s > 0) & (ta == (c - s) / accel)) | ((c - e > 0) & (td == (c - e) / accel))
    ok = (c_new >= np.maximum(s, e) - 1e-9) & (acc >= min_accel) & (dec >= min_accel) \
        & ~(kept & (need > d)) \
        & (acc <= accel * (1 + 1e-9)) & (dec <= accel * (1 + 1e-9))
    acc = np.where(ok & (ta > 0), acc, accel)
    dec = np.where(ok & (td > 0), dec, accel)
    c_out = np.where(ok, np.maximum(c_new, np.maximum(s, e)), c)
    return acc, dec, c_out ** 2


def _build(job, limits, w, cruise2, acc, dec, d, u, vmax, extruding) -> Plan:
    n = job.n_moves
    s = np.sqrt(np.maximum(w[:-1], 0.0))
    e = np.sqrt(np.maximum(w[1:], 0.0))
    c = np.sqrt(np.maximum(cruise2, 0.0))
    c = np.maximum(c, np.maximum(s, e))
    t_acc = (c - s) / acc
    t_dec = (c - e) / dec
    d_acc = 0.5 * (s + c) * t_acc
    d_dec = 0.5 * (c + e) * t_dec
    d_cr = np.maximum(d - d_acc - d_dec, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_cr = np.where(c > 0, d_cr / c, 0.0)
    dwell = job.dwell_before
    # segments per move: dwell, accel, cruise, decel
    dur = np.stack([dwell, t_acc, t_cr, t_dec], axis=1)                 # (n, 4)
    dist0 = np.stack([np.zeros(n), np.zeros(n), d_acc, d_acc + d_cr], axis=1)
    speed0 = np.stack([np.zeros(n), s, c, c], axis=1)
    acc_sg = np.stack([np.zeros(n), acc, np.zeros(n), -dec], axis=1)
    keep = dur > 1e-12
    flat_dur = dur[keep]
    move_idx = np.broadcast_to(np.arange(n)[:, None], (n, 4))[keep]
    moving = np.broadcast_to(np.array([0, 1, 1, 1], bool), (n, 4))[keep]
    t = np.concatenate(([0.0], np.cumsum(flat_dur)))
    p = job.start[move_idx] + u[move_idx] * dist0[keep][:, None]
    v = u[move_idx] * speed0[keep][:, None]
    a = u[move_idx] * acc_sg[keep][:, None]
    ext = extruding[move_idx] & moving & (np.abs(v[:, 3]) + np.abs(a[:, 3]) > 0)
    motion = Motion(t, p, v, a, ext, np.where(moving, move_idx, -1))
    # move start times (after its dwell)
    move_total = dur.sum(axis=1)
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
    return Plan(motion, table, print_time, events, limits)


def limits_from_job(job: Job, base: MachineLimits | None = None, junction: str | None = None) -> MachineLimits:
    """Machine limits taking the first value the job sets for each (its header), over ``base``."""
    base = base or MachineLimits()
    fs = job.file_setting
    kw = {}
    a = fs("accel_klipper") if junction == "scv" else fs("accel_print")
    if a == a:
        kw["accel"] = a
    for key, name in (("accel_travel", "travel_accel"), ("accel_retract", "retract_accel"),
                      ("square_corner_velocity", "square_corner_velocity"),
                      ("junction_deviation", "junction_deviation"), ("velocity", "velocity"),
                      ("min_cruise_ratio", "min_cruise_ratio")):
        v = fs(key)
        if v == v and v > 0 or (v == 0 and key == "min_cruise_ratio"):
            kw[name] = v
    jerk = [fs(f"jerk_{ax}") for ax in "xyze"]
    if any(j == j for j in jerk):
        kw["jerk"] = tuple(j if j == j else b for j, b in zip(jerk, base.jerk))
    if junction:
        kw["junction"] = junction
    return replace(base, **kw)


def guess_junction(job: Job) -> str:
    """The junction rule a job's own commands point to: Klipper's SET_VELOCITY_LIMIT
    SQUARE_CORNER_VELOCITY -> scv, M205 J -> jd, M205 X/Y -> jerk, else scv."""
    fs = job.file_setting
    if fs("square_corner_velocity") == fs("square_corner_velocity"):
        return "scv"
    if fs("junction_deviation") == fs("junction_deviation"):
        return "jd"
    if fs("jerk_x") == fs("jerk_x") or fs("jerk_y") == fs("jerk_y"):
        return "jerk"
    return "scv"
