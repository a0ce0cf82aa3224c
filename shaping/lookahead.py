"""Look-ahead building blocks of the planner, vectorised over all moves (mm, s, mm/s, mm/s²).

- :func:`forward_pass` / :func:`backward_pass`: the min-plus recurrences of look-ahead in closed form;
- :func:`junction_limits`: v² allowed between consecutive moves by the firmware's rule (Klipper
  square-corner velocity, Marlin junction deviation, classic jerk as Marlin and PrusaSlicer);
- :func:`klipper_smoothing`: Klipper's minimum_cruise_ratio / accel_to_decel hill caps;
- :func:`daa_adjust`: RepRapFirmware ≤ 3.3 Dynamic Acceleration Adjustment.
"""

from __future__ import annotations

import math

import numpy as np

from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.job import Job

KLIPPER_INSTANT_CORNER_V = 1.0     # mm/s, Klipper [extruder] instantaneous_corner_velocity default


def forward_pass(c: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """w[0] = c[0]; w[i+1] = min(c[i+1], w[i] + delta[i]) for all i, in closed form."""
    s = np.concatenate(([0.0], np.cumsum(delta)))
    return s + np.minimum.accumulate(c - s)


def backward_pass(c: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """u[n] = c[n]; u[i] = min(c[i], u[i+1] + delta[i])."""
    return forward_pass(c[::-1], delta[::-1])[::-1]


def job_value(job: Job, key: str, default, use: bool) -> np.ndarray:
    n = job.n_moves
    base = np.full(n, np.nan if default is None else float(default))
    if not use:
        return base
    v = job.setting(key)
    return np.where(np.isnan(v), base, v)


#: the job's per-axis caps Klipper and Kalico take, by (prefix, axis): they have no M201 or M203
#: (unknown commands), only Kalico's SET_VELOCITY_LIMIT X_ACCEL/Y_ACCEL in limited kinematics
KLIPPER_AXIS_SETTINGS = {("max_accel", "x"): "limited_accel_x", ("max_accel", "y"): "limited_accel_y"}


def axis_caps(job: Job, prefix: str, machine: tuple | None, use: bool, klipper: bool = False,
              unit: float = 1.0, e_alone: np.ndarray | None = None, e_klipper: float | None = None) -> np.ndarray:
    """(n, 4) per-axis caps (inf = none): the machine's, over them the job's own (× ``unit``:
    RepRapFirmware's M203 is in mm/min) — under ``klipper`` only those Klipper and Kalico take
    (:data:`KLIPPER_AXIS_SETTINGS`), and on E its extruder's ``e_klipper``
    (``max_extrude_only_velocity`` / ``_accel``; None: not known) on the moves ``e_alone`` marks alone
    (:func:`ringtune.shaping.extruder_alone.e_capped`, by their E ratio: ``extruder.py``
    ``check_move``); a move extruding forwards over X/Y has no E limit there."""
    cols = []
    for i, ax in enumerate("xyze"):
        default = np.inf if machine is None or machine[i] <= 0 else machine[i]
        key = _cap_setting(prefix, ax, klipper)
        own = job_value(job, key, None, use and key is not None) * unit
        v = np.where(np.isnan(own), default, own)
        cols.append(np.where(v > 0, v, np.inf))       # Marlin: 0 means "no limit" for M201/M203
    if klipper:                                        # Klipper has no M201/M203 E: its extruder's own
        on = np.zeros(job.n_moves, bool) if e_alone is None else e_alone
        cols[3] = np.where(on, e_klipper or np.inf, np.inf)
    return np.stack(cols, axis=1)


def _cap_setting(prefix: str, ax: str, klipper: bool) -> str | None:
    """The job's setting of ``prefix``'s cap on ``ax`` the firmware takes (None: none)."""
    return KLIPPER_AXIS_SETTINGS.get((prefix, ax)) if klipper else f"{prefix}_{ax}"


def move_accels(job: Job, limits, use: bool, delta: np.ndarray, e_only: np.ndarray,
                override: float | None = None) -> np.ndarray:
    """Each move's acceleration before the per-axis caps (mm/s²): Klipper's one acceleration
    (``scv``), else Marlin's/RRF's by role — E-only moves (retract, unretract) at M204 R, extruding
    moves at P, the others (travel) at T (:attr:`MachineLimits.travel_accel`/``retract_accel``,
    None = the printing acceleration); ``override`` (a tuning knob, sent as ``M204 P T``) replaces
    the printing and travel accelerations, not a known retract acceleration (M204 R)."""
    if override is not None:
        if not (math.isfinite(override) and override > 0):
            raise RingtuneError(f"acceleration must be > 0 mm/s², not {override}", "accel")
        keep = marlin_retractions(job, limits, use, e_only)
        if keep is None:
            return np.full(job.n_moves, float(override))
        return np.where(keep, job_value(job, "accel_retract", limits.retract_accel, use), float(override))
    if limits.reads_like_klipper:
        accel = job_value(job, "accel_klipper", limits.accel, use)
    else:
        a_print = job_value(job, "accel_print", limits.accel, use)
        a_travel = job_value(job, "accel_travel", limits.travel_accel or limits.accel, use)
        a_retract = job_value(job, "accel_retract", limits.retract_accel or limits.accel, use)
        accel = np.where(e_only, a_retract, np.where(delta[:, 3] != 0, a_print, a_travel))
    return np.where(accel > 0, accel, limits.accel)


def extruder_alone(accel: np.ndarray, vmax: np.ndarray, feed: np.ndarray, e_only: np.ndarray, a_cap: np.ndarray,
                   v_cap: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(accel, vmax) with Klipper's moves of the extruder alone at their own caps (``a_cap``,
    ``v_cap``: ``max_extrude_only_accel`` / ``_velocity``, inf = not known), not the toolhead's
    acceleration or speed (``toolhead.py``: such a move starts unlimited and only the extruder's
    ``check_move`` limits it); where a cap is not known, the toolhead's as before."""
    return (np.where(e_only & np.isfinite(a_cap), a_cap, accel),
            np.where(e_only & np.isfinite(v_cap), np.minimum(feed, v_cap), vmax))


def marlin_retractions(job: Job, limits, use: bool, e_only: np.ndarray) -> np.ndarray | None:
    """E-only moves that run at Marlin's ``M204 R`` without per-axis caps: where a retract
    acceleration is known (machine or job) under Marlin's junction rules; None under Klipper's."""
    if limits.reads_like_klipper:
        return None
    known = ~np.isnan(job_value(job, "accel_retract", limits.retract_accel, use))
    return e_only & known


def row_min(a: np.ndarray) -> np.ndarray:
    """Each row's minimum of an (n, k) array with few columns, column by column: ``a.min(axis=1)``
    (NaN wins as there), several times faster along so short a row."""
    out = a[:, 0]
    for j in range(1, a.shape[1]):
        out = np.minimum(out, a[:, j])
    return np.array(out, copy=True) if a.shape[1] == 1 else out


def kinematic_accel(accel: np.ndarray, u: np.ndarray, caps: np.ndarray, rule: str = "per_axis",
                    scale_xy: bool = False, skip: np.ndarray | None = None) -> np.ndarray:
    """The acceleration (mm/s²) each move gets under the per-axis ``caps`` ((n, 4), inf = none) by
    the firmware's rule (planner module docstring): ``per_axis`` — ``min(accel, cap_i/|u_i|)``;
    ``limited_corexy`` — ``min(accel, 1/(|u_x|/c_x + |u_y|/c_y))`` on X/Y (Kalico), per axis on
    Z and E. ``scale_xy``: Kalico's ``scale_xy_accel`` — the X/Y bound times ``accel/hypot(c_x,
    c_y)`` (limited_cartesian) or ``accel/max(c_x, c_y)`` (limited_corexy). ``skip``: moves left
    alone (Marlin's retractions)."""
    au = np.abs(u)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(au > 0, caps / au, np.inf)
        if rule == "limited_corexy":
            share = au[:, 0] / caps[:, 0] + au[:, 1] / caps[:, 1]
            xy = np.where(share > 0, 1.0 / share, np.inf)
            norm = np.maximum(caps[:, 0], caps[:, 1])
        else:
            xy = row_min(ratio[:, :2])
            norm = np.hypot(caps[:, 0], caps[:, 1])
    if scale_xy:
        xy = xy * accel / norm
    out = np.minimum(accel, np.minimum(xy, row_min(ratio[:, 2:])))
    return out if skip is None else np.where(skip, accel, out)


def corexy_speed_cap(vmax: np.ndarray, velocity: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Kalico's limited_corexy speed bound: max_velocity is each motor's, so a move in direction
    ``u`` runs at most ``velocity/max(|u_x + u_y|, |u_x − u_y|) = velocity/(|u_x| + |u_y|)``."""
    ab = np.abs(u[:, 0]) + np.abs(u[:, 1])
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(ab > 1e-12, np.minimum(vmax, velocity / ab), vmax)


def scale_by_axes(value: np.ndarray, u: np.ndarray, caps: np.ndarray) -> np.ndarray:
    """Largest ≤ value such that value·|u_a| ≤ cap_a on every axis."""
    au = np.abs(u)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(au > 0, caps / au, np.inf)
    return np.minimum(value, row_min(ratio))


# -- the planner --------------------------------------------------------------------------------


def junction_limits(job, limits, use, u, d, e_only, vmax, accel, amax_axes, toolhead=None):
    """Junction v² limit between move i-1 and i (c[i], c[0] unused) and jerk 'safe' speeds.
    ``toolhead``: Klipper's acceleration before each move's own caps (None: ``accel``): its
    junction deviation is scv²(√2 − 1)/that, and each move bounds the corner by it times the
    move's own acceleration (``Move.calc_junction``), so a capped move (Z) corners slower."""
    n = job.n_moves
    c = np.full(n, np.inf)
    safe = np.zeros(n)
    if n < 2:
        if limits.junction == "jerk":
            safe = jerk_safe_speeds(job, limits, use, u, vmax)
        return c, safe
    up, uc = u[:-1], u[1:]
    if limits.junction == "scv":
        scv = job_value(job, "square_corner_velocity", limits.square_corner_velocity, use)
        nx = np.where(e_only[:, None], 0.0, u[:, :3])
        cos_j = -np.einsum("ij,ij->i", nx[1:], nx[:-1])
        sin_d2 = np.sqrt(np.maximum(0.5 * (1 - cos_j), 0.0))
        cos_d2 = np.sqrt(np.maximum(0.5 * (1 + cos_j), 0.0))
        one_minus = 1 - sin_d2
        ok = (one_minus > 0) & (cos_d2 > 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            r_jd = sin_d2 / one_minus
            k = math.sqrt(2) - 1
            own = scv ** 2 if toolhead is None else scv ** 2 * accel / toolhead
            jd_v2 = r_jd * k * np.minimum(own[1:], own[:-1])
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
        jd = job_value(job, "junction_deviation", limits.junction_deviation, use)[1:]
        # Marlin's unit vectors are over X, Y, Z and E together wherever E moves (planner.cpp: a move with
        # E steps is normalised with its E component; an E-only move is ±E)
        nv = u / np.linalg.norm(u, axis=1)[:, None]
        cos_t = -np.einsum("ij,ij->i", nv[1:], nv[:-1])
        rev = cos_t > 0.999999
        cos_c = np.clip(cos_t, -0.999999, 1.0)
        sin_d2 = np.sqrt(0.5 * (1 - cos_c))
        ju = nv[1:] - nv[:-1]
        norm = np.linalg.norm(ju, axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            ju = ju / np.where(norm > 0, norm, 1.0)[:, None]
        a_j = scale_by_axes(accel[1:], ju, amax_axes[1:])
        lim = a_j * jd * sin_d2 / (1 - sin_d2)
        # Marlin JD_HANDLE_SMALL_SEGMENTS (planner.cpp since 2.0.6, in 2.1.x and Prusa Buddy): on a
        # segment under 1 mm turning by less than 45° from the last, bound the speed as on the
        # circular arc the segments approximate, v² = length · a / turn
        small = (d[1:] < 1.0) & (cos_c < -0.7071067812)
        with np.errstate(divide="ignore", invalid="ignore"):
            arc = d[1:] * a_j / marlin_turn(cos_c)
        lim = np.where(small, np.minimum(lim, arc), lim)
        lim = np.where(rev, 0.05 ** 2, lim)
        c[1:] = lim
    else:
        safe = jerk_safe_speeds(job, limits, use, u, vmax)
        c[1:] = jerk_junction(job, limits, use, u, vmax, safe) ** 2
    return c, safe


#: Marlin's MinMax polynomial for asin(t), t in [0, 1] (W. R. Franklin's; error ±0.033 rad), highest power first
_ASIN_MINIMAX = (84.31466202, -242.7199627, 262.8130562, -131.1123477, 29.66153956, -1.451838349, 0.032843707)


def marlin_turn(cos_c: np.ndarray) -> np.ndarray:
    """The turn between two moves (rad; 0 straight on) as Marlin's JD_HANDLE_SMALL_SEGMENTS takes it
    where it applies (``cos_c`` < 0: Marlin's junction_cos_theta, −cos of the turn): acos(−cos_c) by
    the polynomial, π/2 − asin(−cos_c), which never falls below 0.033 (a straight run stays bounded)."""
    return np.pi / 2 - np.polyval(_ASIN_MINIMAX, -cos_c)


def jerk_setting(limits) -> str:
    """The prefix of the job settings that carry its jerk on this firmware: M205's and M566's
    (``jerk``), or on a firmware without M566 (Marlin, Prusa) M205's alone (``m205_jerk``)."""
    return "jerk" if limits.reads_m566 else "m205_jerk"


def jerk_limits(job, limits, use) -> np.ndarray:
    """(n, 4) classic jerk per move and axis, mm/s: the job's own over the machine's, held to a
    firmware's compiled ceiling where it has one (``limits.hw_max_jerk``)."""
    key = jerk_setting(limits)
    jerk = np.stack([job_value(job, f"{key}_{ax}", limits.jerk[i], use) for i, ax in enumerate("xyze")], axis=1)
    hw = limits.hw_max_jerk
    return jerk if hw is None else np.minimum(jerk, np.asarray(hw, float)[None, :])


def jerk_safe_speeds(job, limits, use, u, vmax) -> np.ndarray:
    """Speed a move may start from / end at rest with (PrusaSlicer's ``safe_feedrate``)."""
    jerk = jerk_limits(job, limits, use)
    axis_v = np.abs(u) * vmax[:, None]
    capped = np.where(axis_v > jerk, jerk, np.inf)
    return np.minimum(vmax, row_min(capped))


def jerk_junction(job, limits, use, u, vmax, safe) -> np.ndarray:
    """Classic-jerk junction speed between move i-1 and i (PrusaSlicer / Marlin rule), (n-1,)."""
    jerk = jerk_limits(job, limits, use)[1:]
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


def segmented_cummin(values: np.ndarray, run_start: np.ndarray) -> np.ndarray:
    """Running minimum that restarts at each run: out[i] = min(values[run_start[i] .. i]).

    Hillis-Steele doubling: log2(longest run) vectorised steps, exact."""
    out = np.asarray(values, float).copy()
    idx = np.arange(len(out))
    k = 1
    longest = int((idx - run_start).max()) + 1 if len(out) else 0
    while k < longest:
        ok = idx - k >= run_start
        shifted = np.concatenate((np.full(k, np.inf), out[:-k]))
        out = np.where(ok, np.minimum(out, shifted), out)
        k *= 2
    return out


def klipper_smoothing(job, limits, use, cj, w, cruise2, accel, d, dv2, v2, toolhead=None):
    """Klipper's minimum_cruise_ratio: cap each accelerate/decelerate hill at the peak reached
    with the smoothed acceleration, then re-run the passes so junctions stay reachable.

    The smoothed acceleration (mm/s²) is the toolhead's acceleration (``toolhead``, before a move's
    own caps; None: ``accel``) × (1 − minimum_cruise_ratio), the job's MINIMUM_CRUISE_RATIO over
    the machine's, and no more than the move's own (Klipper's ``mcr_pseudo_accel``, bounded in
    ``Move.limit_speed``): a current Klipper and Kalico ignore ACCEL_TO_DECEL. On a Klipper from
    before 2024 (``limits.accel_to_decel`` set: its max_accel_to_decel) it is min(accel_to_decel,
    acceleration), the job's ACCEL_TO_DECEL over the machine's, whatever ACCEL becomes; that
    Klipper has no MINIMUM_CRUISE_RATIO."""
    if limits.accel_to_decel is None:
        mcr = job_value(job, "min_cruise_ratio", limits.min_cruise_ratio, use)
        a_s = np.minimum((accel if toolhead is None else toolhead) * (1 - mcr), accel)
    else:
        a_s = np.minimum(job_value(job, "accel_to_decel", limits.accel_to_decel, use), accel)
    if np.all(a_s >= accel):
        return cruise2, w
    ds = 2 * a_s * d
    sm = backward_pass(forward_pass(cj, ds), ds)
    peak = np.minimum(v2, 0.5 * (sm[:-1] + sm[1:] + ds))      # smoothed peak inside each move
    n = len(d)
    idx = np.arange(n)
    # the closed-form passes carry rounding of the order of eps x (running sum of δ)
    tol = 1e-9 * np.maximum(sm[:-1], 1.0) + 1e-12 * float(ds.sum())
    # Klipper's flush, move by move from the end: a move whose smoothed start is limited from
    # behind is "falling" (delayed); a non-falling move sets the hill's peak if its smoothed
    # profile turns down inside it (or a falling run follows it); a purely rising move takes the
    # peak of the next move that set one; falling moves take the peak of the move before them.
    falling = sm[:-1] >= sm[1:] + ds - tol
    next_falling = np.concatenate((falling[1:], [False]))
    peaking = ~falling & ((sm[:-1] + ds > sm[1:] + tol) | next_falling)
    nxt = np.minimum.accumulate(np.where(peaking, idx, n)[::-1])[::-1]
    prv = np.maximum.accumulate(np.where(~falling, idx, -1))
    peak_ext = np.concatenate((peak, [np.inf]))
    hill_peak = np.where(falling, peak_ext[np.where(prv >= 0, prv, n)], peak_ext[nxt])
    cap = np.minimum(cruise2, hill_peak)
    # falling moves do not accelerate: cruise at most the lowest start speed of the run so far
    first = falling & ~np.concatenate(([False], falling[:-1]))
    run_start = np.maximum.accumulate(np.where(first, idx, 0))
    cap = np.where(falling, np.minimum(cap, segmented_cummin(w[:-1], run_start)), cap)
    c2 = cj.copy()
    c2[1:n] = np.minimum(c2[1:n], np.minimum(cap[1:], cap[:-1]))
    c2[0] = min(c2[0], cap[0])
    c2[n] = min(c2[n], cap[-1])
    w2 = backward_pass(forward_pass(np.minimum(c2, w), dv2), dv2)
    return np.minimum(cap, 0.5 * (w2[:-1] + w2[1:] + dv2)), w2


def daa_adjust(freq, min_accel, w, cruise2, accel, d, u):
    """RRF ≤ 3.3 Dynamic Acceleration Adjustment (``DDA::AdjustAcceleration``), per move.

    Only moves with a top speed above both their start and end speed that move mainly in X or Y
    (|u_x| or |u_y| > 0.5). A phase shorter than one ringing period T is stretched to T, one shorter
    than 2T to 2T (acceleration lowered to Δv/T); the acceleration phase is left alone when the
    previous move is still accelerating into this one, the deceleration phase when the next move
    keeps decelerating. If the stretched phases no longer fit, the move becomes accelerate-then-
    decelerate with both phases exactly T (lower top speed), else accelerate-only or decelerate-only
    "as slowly as we can". Nothing changes when an acceleration would fall under ``min_accel``
    (M593 L) or rise above the original. Returns (accel, decel, cruise v²) per move.
    """
    if not (math.isfinite(freq) and freq > 0):
        raise RingtuneError(f"DAA frequency must be > 0 Hz, not {freq}", "daa_freq")
    T = 1.0 / freq
    s, e = np.sqrt(w[:-1]), np.sqrt(w[1:])
    c = np.sqrt(cruise2)
    A = accel
    tol = 1e-9 * np.maximum(c, 1.0)
    accel_only = (c > s + tol) & (c <= e + tol)                 # no deceleration phase
    decel_only = (c <= s + tol) & (c > e + tol)
    prev_accel_only = np.concatenate(([False], accel_only[:-1]))
    next_decel_only = np.concatenate((decel_only[1:], [False]))
    eligible = (np.maximum(np.abs(u[:, 0]), np.abs(u[:, 1])) > 0.5) & (c > s + tol) & (c > e + tol)
    ta0, td0 = (c - s) / A, (c - e) / A
    adj_a = eligible & ~prev_accel_only & (ta0 < 2 * T)
    adj_d = eligible & ~next_decel_only & (td0 < 2 * T)
    pa = np.where(adj_a, (c - s) / np.where(ta0 < T, T, 2 * T), A)
    pd = np.where(adj_d, (c - e) / np.where(td0 < T, T, 2 * T), A)
    fits = (c * c - s * s) / (2 * pa) + (c * c - e * e) / (2 * pd) <= d
    adjust = adj_a | adj_d
    acc, dec, top = A.copy(), A.copy(), c.copy()
    # 1. the stretched phases fit: keep the top speed
    ok1 = adjust & fits & (pa >= min_accel) & (pd >= min_accel)
    acc = np.where(ok1, pa, acc)
    dec = np.where(ok1, pd, dec)
    # 2. accelerate-decelerate, each phase one period
    top2 = d / T - 0.5 * (s + e)
    a2 = (2 * d - (3 * s + e) * T) / (2 * T * T)
    d2 = (2 * d - (s + 3 * e) * T) / (2 * T * T)
    tri = adjust & ~fits & (top2 > s) & (top2 > e)
    ok2 = tri & (a2 >= min_accel) & (d2 >= min_accel) & (a2 <= A) & (d2 <= A)
    acc = np.where(ok2, a2, acc)
    dec = np.where(ok2, d2, dec)
    top = np.where(ok2, top2, top)
    # 3. accelerate-only / decelerate-only, as slowly as the move allows
    with np.errstate(divide="ignore", invalid="ignore"):
        a3 = (e * e - s * s) / (2 * d)
        d3 = (s * s - e * e) / (2 * d)
    up = adjust & ~fits & ~tri & (s < e) & (a3 >= min_accel)
    down = adjust & ~fits & ~tri & (s > e) & (d3 >= min_accel)
    acc = np.where(up, a3, acc)
    top = np.where(up, e, top)
    dec = np.where(down, d3, dec)
    top = np.where(down, s, top)
    return acc, dec, top ** 2
