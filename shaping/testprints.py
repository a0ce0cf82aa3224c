"""Built-in test print and the quality-relevant windows of any planned job (mm, mm/s, s, Hz).

:func:`builtin_test_gcode` writes a short job (about four seconds of motion) that shows what input
shaping and the frequency limit are about:

1. a ringing-tower layer: one square perimeter, 90° corners at 100 mm/s;
2. nophead's zigzag infill: one continuous extrusion path whose zigzag strokes narrow so that the
   direction-change frequency, at the commanded 80 mm/s, sweeps 10, 15, 20, 30, 40, 55, 80 Hz
   (four cycles each);
3. a circle (G2 arc, radius 8 mm) at 80 mm/s.

:func:`quality_windows` picks, from any plan, the stretches physics should score: the sharpest
corners taken at speed and the highest-frequency zigzags, so a long print is judged on a fraction of
its length.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ringtune.shaping.freqlimit import CYCLES
from ringtune.shaping.gcode import read_gcode
from ringtune.shaping.job import Job

ZIGZAG_FREQS = (10.0, 15.0, 20.0, 30.0, 40.0, 55.0, 80.0)    # Hz at the commanded speed
ZIGZAG_SPEED = 80.0          # mm/s
ZIGZAG_STEP = 0.25           # mm advance per stroke along X
ZIGZAG_CYCLES = 4
E_PER_MM = 0.033             # 0.45 x 0.2 mm line, 1.75 mm filament


@dataclass(frozen=True)
class Window:
    """A stretch of a planned job worth simulating: [t0, t1] s, ``kind`` ``corner`` | ``zigzag``,
    ``score`` (corner: velocity change across it, mm/s; zigzag: direction-change frequency, Hz),
    ``line``: the G-code line at its centre."""

    t0: float
    t1: float
    kind: str
    score: float
    line: int = 0


def zigzag_stroke_width(freq: float, speed: float = ZIGZAG_SPEED, step: float = ZIGZAG_STEP) -> float:
    """Stroke width (mm across) whose zigzag at ``speed`` changes direction at ``freq`` cycles/s:
    one cycle is two strokes of path length ``speed/(2·freq)``."""
    stroke = speed / (2.0 * freq)
    return math.sqrt(max(stroke * stroke - step * step, 0.0))


def builtin_test_gcode() -> str:
    """G-code text of the built-in test print (absolute XYZ, relative E)."""
    out = ["; ringtune built-in test print", "G90", "M83", "G92 E0", "G1 Z0.2 F600"]

    def ext(x0, y0, x1, y1):
        return E_PER_MM * math.hypot(x1 - x0, y1 - y0)

    # 1. ringing-tower layer: square perimeter, sharp corners at speed
    out += ["G1 X20 Y20 F9000", ";TYPE:External perimeter", "G1 F6000"]
    pts = [(45, 20), (45, 45), (20, 45), (20, 20)]
    x, y = 20.0, 20.0
    for px, py in pts:
        out.append(f"G1 X{px} Y{py} E{ext(x, y, px, py):.5f}")
        x, y = px, py
    # 2. zigzag infill sweeping direction-change frequency
    x0, yc = 60.0, 35.0
    out += ["G1 E-0.8 F2400", f"G1 X{x0:.3f} Y{yc:.3f} F9000", "G1 E0.8 F2400",
            ";TYPE:Internal infill", f"G1 F{ZIGZAG_SPEED * 60:.0f}"]
    x, y = x0, yc
    up = True
    for f in ZIGZAG_FREQS:
        w = zigzag_stroke_width(f)
        for _ in range(2 * ZIGZAG_CYCLES):
            nx, ny = x + ZIGZAG_STEP, yc + (w / 2 if up else -w / 2)
            out.append(f"G1 X{nx:.4f} Y{ny:.4f} E{ext(x, y, nx, ny):.5f}")
            x, y, up = nx, ny, not up
    # 3. circle
    cx, cy, r = 100.0, 35.0, 8.0
    out += ["G1 E-0.8 F2400", f"G1 X{cx + r:.3f} Y{cy:.3f} F9000", "G1 E0.8 F2400",
            ";TYPE:Perimeter", "G1 F4800",
            f"G2 X{cx + r:.3f} Y{cy:.3f} I{-r:.3f} J0 E{E_PER_MM * 2 * math.pi * r:.5f}",
            "G1 E-0.8 F2400", "G1 Z1.2 F600"]
    return "\n".join(out) + "\n"


def builtin_test_print() -> Job:
    """The built-in test print, parsed (see :func:`builtin_test_gcode`)."""
    job = read_gcode(builtin_test_gcode())
    job.source = "<builtin test print>"
    return job


# -- windows ------------------------------------------------------------------------------------
def _corner_candidates(plan, tau: float = 0.02):
    """Junctions inside extrusion: time, xy velocity change over ±tau (mm/s), line."""
    mv = plan.moves
    n = len(mv)
    if n < 2:
        return np.zeros(0), np.zeros(0), np.zeros(0, np.int64)
    ext = mv.extruding
    both = ext[1:] & ext[:-1]
    d_prev = (mv.end[:-1] - mv.start[:-1])[:, :2]
    d_next = (mv.end[1:] - mv.start[1:])[:, :2]
    dot = np.einsum("ij,ij->i", d_prev, d_next)
    norm = np.linalg.norm(d_prev, axis=1) * np.linalg.norm(d_next, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        cos = np.where(norm > 0, dot / norm, 1.0)
    idx = np.flatnonzero(both & (cos < math.cos(math.radians(30))))
    tj = mv.t_start[idx + 1]
    vb = plan.motion.velocity(tj - tau)[:, :2]
    va = plan.motion.velocity(tj + tau)[:, :2]
    score = np.linalg.norm(va - vb, axis=1)
    return tj, score, mv.line[idx + 1]


def direction_change_frequencies(plan):
    """Local direction-change frequency (Hz) in planned time while extruding: for every run of
    2·3 reversals of X or Y inside one extrusion path, 3 cycles / their duration.

    Returns (t_centre, freq, line) arrays."""
    mv = plan.moves
    n = len(mv)
    ts, fs, ls = [], [], []
    if n < 2:
        return np.zeros(0), np.zeros(0), np.zeros(0, np.int64)
    ext = mv.extruding
    connected = np.all(mv.start[1:] == mv.end[:-1], axis=1)
    k = 2 * CYCLES
    for axis in (0, 1):
        s = np.sign(mv.end[:, axis] - mv.start[:, axis])
        sel = np.flatnonzero((s != 0) & ext)
        if len(sel) <= k:
            continue
        # a reversal at move j: previous moving move on this axis had the opposite sign, same path
        prev, cur = sel[:-1], sel[1:]
        same_path = _same_path(ext, connected, prev, cur)
        rev = cur[(s[cur] != s[prev]) & same_path]
        if len(rev) <= k:
            continue
        t_rev = mv.t_start[rev]
        span = t_rev[k:] - t_rev[:-k]
        # all k reversals must lie in one path: no non-extruding move between the first and last
        good = _same_path(ext, connected, rev[:-k], rev[k:]) & (span > 0)
        with np.errstate(divide="ignore"):
            f = CYCLES / span
        ts.append(0.5 * (t_rev[k:] + t_rev[:-k])[good])
        fs.append(f[good])
        ls.append(mv.line[rev[:-k]][good])
    if not ts:
        return np.zeros(0), np.zeros(0), np.zeros(0, np.int64)
    return np.concatenate(ts), np.concatenate(fs), np.concatenate(ls)


def _same_path(ext, connected, a, b) -> np.ndarray:
    """For index pairs a ≤ b: all moves a..b extruding and connected."""
    bad = np.concatenate(([0], np.cumsum(~ext)))
    gap = np.concatenate(([0], np.cumsum(~connected)))
    return (bad[b + 1] - bad[a] == 0) & (gap[b] - gap[a] == 0)


def quality_windows(plan, max_windows: int = 8, span: float = 0.25) -> list[Window]:
    """Up to ``max_windows`` non-overlapping windows of ``span`` s each, half the sharpest corners
    (largest velocity change while extruding, window starting just before the corner so the
    ringing after it is inside) and half the highest-frequency zigzags; a kind with too few
    candidates leaves its places to the other. Sorted by start time."""
    duration = plan.motion.end_time
    span = min(span, duration)
    tc, sc, lc = _corner_candidates(plan)
    tz, fz, lz = direction_change_frequencies(plan)
    # candidates best first; each kind is consumed lazily from its own cursor
    cands = {
        "corner": (tc - 0.2 * span, sc, lc, np.argsort(-sc, kind="stable")),
        "zigzag": (tz - 0.5 * span, fz, lz, np.argsort(-fz, kind="stable")),
    }
    cursor = {"corner": 0, "zigzag": 0}
    chosen: list[Window] = []
    lo_t, hi_t = plan.motion.start_time, duration - span

    def take(kind: str, quota: int) -> int:
        t0s, scores, lines, order = cands[kind]
        got = 0
        k = cursor[kind]
        while got < quota and k < len(order):
            i = order[k]
            k += 1
            t0 = float(min(max(t0s[i], lo_t), hi_t))
            if all(t0 + span <= w.t0 or t0 >= w.t1 for w in chosen):
                chosen.append(Window(t0, t0 + span, kind, float(scores[i]), int(lines[i])))
                got += 1
        cursor[kind] = k
        return got

    half = max_windows // 2
    got_c = take("corner", max_windows - half)
    got_z = take("zigzag", half + (max_windows - half - got_c))
    if got_c + got_z < max_windows:
        take("corner", max_windows - got_c - got_z)
    return sorted(chosen, key=lambda w: w.t0)


def relocate_windows(plan, reference: list[Window], span: float = 0.25) -> list[Window]:
    """The windows ``reference`` chose (on another plan of the same job: other acceleration or
    frequency limit), placed on ``plan``: the same G-code lines, the same corners and zigzags,
    at the times ``plan`` reaches them, scored on ``plan``.

    Why: choosing windows afresh for every configuration lets the set of simulated corners change
    when the acceleration crosses a threshold (many corners of a test print score almost alike),
    and the cost then jumps by ~10 % between neighbouring accelerations; comparing configurations
    on the same corners keeps the objective smooth. A line ``plan`` lacks as a candidate takes the
    candidate of that kind on the nearest line."""
    duration = plan.motion.end_time
    span = min(span, duration)
    lo_t, hi_t = plan.motion.start_time, duration - span
    tc, sc, lc = _corner_candidates(plan)
    tz, fz, lz = direction_change_frequencies(plan)
    cands = {"corner": (tc - 0.2 * span, sc, lc), "zigzag": (tz - 0.5 * span, fz, lz)}
    out = []
    for w in reference:
        t0s, scores, lines = cands.get(w.kind, cands["corner"])
        if len(lines) == 0:
            t0s, scores, lines = cands["zigzag" if w.kind == "corner" else "corner"]
        if len(lines) == 0:
            return quality_windows(plan, max_windows=len(reference), span=span)
        i = int(np.argmin(np.abs(np.asarray(lines, np.int64) - int(w.line))))
        t0 = float(min(max(t0s[i], lo_t), hi_t))
        out.append(Window(t0, t0 + span, w.kind, float(scores[i]), int(lines[i])))
    return sorted(out, key=lambda w: w.t0)
