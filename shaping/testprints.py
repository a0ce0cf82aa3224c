"""Built-in test print and the quality-relevant windows of any planned job (mm, mm/s, s, Hz).

:func:`builtin_test_gcode` writes one layer of a modern job in miniature (about eight seconds of
motion on the default printer), labelled as PrusaSlicer labels its features, at the speeds a
current printer prints them:

1. ``Perimeter`` (inner wall, 250 mm/s): a rectangle loop inside the part, long straight sides;
2. ``External perimeter`` (outer wall, 150 mm/s): the part's outline, started mid-wall as slicers
   hide the seam — a 70 mm wall along X and a 40 mm wall along Y after 90° corners (ripples show
   on them), an acute corner (121° turn), an obtuse one (78°), and a curve of short straight
   segments (10° each, as slicers write arcs) into a 35 mm wall along Y;
3. ``Internal infill`` (250 mm/s): nophead's zigzag, one continuous extrusion path whose strokes
   narrow so that the direction-change frequency at the commanded speed sweeps 10, 15, 20, 30, 40,
   55, 80 Hz (four cycles each).

:func:`quality_windows` picks, from any plan, the stretches physics should score, per feature
class: the sharpest corners of what a person sees (each window runs on along the wall after the
corner, so its ripple is inside), the highest-frequency zigzags and the sharpest corners of what
is hidden (what shows through), so a long print is judged on a fraction of its length.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ringtune.shaping.features import VISIBLE
from ringtune.shaping.freqlimit import CYCLES
from ringtune.shaping.gcode import read_gcode
from ringtune.shaping.geometry_cache import by_geometry
from ringtune.shaping.job import Job
from ringtune.shaping.seams import SEAM_ORDER, label_classes, seam_candidates

ZIGZAG_FREQS = (10.0, 15.0, 20.0, 30.0, 40.0, 55.0, 80.0)    # Hz at the commanded speed
ZIGZAG_SPEED = 250.0         # mm/s
ZIGZAG_STEP = 0.45           # mm advance per stroke along X (one line width)
ZIGZAG_CYCLES = 4
OUTER_SPEED = 150.0          # mm/s, outer wall
INNER_SPEED = 250.0          # mm/s, inner wall
TRAVEL_SPEED = 300.0         # mm/s
E_PER_MM = 0.033             # 0.45 x 0.2 mm line, 1.75 mm filament
#: the outline, counter-clockwise from the middle of the wall F → A: A (90° corner), B (70 mm
#: wall, 90° corner), C (40 mm wall, acute corner), D (obtuse corner), E, then a curve of radius
#: CURVE_R about CURVE_C from E's angle to 180° (10° chords) to F, and back down the wall
OUTLINE = ((20.0, 40.0), (20.0, 20.0), (90.0, 20.0), (90.0, 60.0), (65.0, 45.0))
CURVE_C, CURVE_R, CURVE_FROM_DEG, CURVE_TO_DEG, CURVE_STEP_DEG = (35.0, 55.0), 15.0, 45.0, 180.0, 10.0
INNER_LOOP = ((22.0, 22.0), (88.0, 22.0), (88.0, 42.0), (22.0, 42.0))


@dataclass(frozen=True)
class Window:
    """A stretch of a planned job worth simulating: [t0, t1] s, ``kind`` ``corner`` | ``zigzag`` |
    ``seam-in`` | ``seam-out``, ``score`` (corner: velocity change across it, mm/s; zigzag:
    direction-change frequency, Hz; seam: cruise speed of the motion beside it, mm/s),
    ``line``: the G-code line at its centre, ``feature``: the feature class there
    (:data:`ringtune.shaping.features.FEATURE_CLASSES`)."""

    t0: float
    t1: float
    kind: str
    score: float
    line: int = 0
    feature: str = "other"


def zigzag_stroke_width(freq: float, speed: float = ZIGZAG_SPEED, step: float = ZIGZAG_STEP) -> float:
    """Stroke width (mm across) whose zigzag at ``speed`` changes direction at ``freq`` cycles/s:
    one cycle is two strokes of path length ``speed/(2·freq)``."""
    stroke = speed / (2.0 * freq)
    return math.sqrt(max(stroke * stroke - step * step, 0.0))


def _outline() -> list[tuple[float, float]]:
    """The outer wall's points after A: B, C, D, the curve's chords from E to F, and A again."""
    cx, cy = CURVE_C
    angles = np.arange(CURVE_FROM_DEG, CURVE_TO_DEG + 1e-9, CURVE_STEP_DEG)
    curve = [(cx + CURVE_R * math.cos(math.radians(a)), cy + CURVE_R * math.sin(math.radians(a)))
             for a in angles]
    return [*OUTLINE[1:], *curve, OUTLINE[0]]


class _Writer:
    """G-code lines of the test print, tracking the position (absolute XY, relative E)."""

    def __init__(self) -> None:
        self.lines = ["; ringtune built-in test print: one layer of a modern job in miniature",
                      "G90", "M83", "G92 E0", "G1 Z0.2 F600"]
        self.x, self.y = 0.0, 0.0

    def travel(self, x: float, y: float, retract: bool = True) -> None:
        if retract:
            self.lines.append("G1 E-0.8 F2400")
        self.lines.append(f"G1 X{x:.3f} Y{y:.3f} F{TRAVEL_SPEED * 60:.0f}")
        if retract:
            self.lines.append("G1 E0.8 F2400")
        self.x, self.y = x, y

    def feature(self, label: str, speed: float) -> None:
        self.lines += [f";TYPE:{label}", f"G1 F{speed * 60:.0f}"]

    def extrude(self, x: float, y: float) -> None:
        e = E_PER_MM * math.hypot(x - self.x, y - self.y)
        self.lines.append(f"G1 X{x:.4f} Y{y:.4f} E{e:.5f}")
        self.x, self.y = x, y


def builtin_test_gcode() -> str:
    """G-code text of the built-in test print (absolute XYZ, relative E)."""
    g = _Writer()
    g.travel(*INNER_LOOP[0], retract=False)
    g.feature("Perimeter", INNER_SPEED)
    for p in (*INNER_LOOP[1:], INNER_LOOP[0]):
        g.extrude(*p)
    g.travel(*OUTLINE[0])
    g.feature("External perimeter", OUTER_SPEED)
    for p in _outline():
        g.extrude(*p)
    x0, yc = 30.0, 32.0
    g.travel(x0, yc)
    g.feature("Internal infill", ZIGZAG_SPEED)
    up = True
    for f in ZIGZAG_FREQS:
        w = zigzag_stroke_width(f)
        for _ in range(2 * ZIGZAG_CYCLES):
            g.extrude(g.x + ZIGZAG_STEP, yc + (w / 2 if up else -w / 2))
            up = not up
    g.lines += ["G1 E-0.8 F2400", "G1 Z1.2 F600"]
    return "\n".join(g.lines) + "\n"


def builtin_test_print() -> Job:
    """The built-in test print, parsed (see :func:`builtin_test_gcode`)."""
    job = read_gcode(builtin_test_gcode())
    job.source = "<builtin test print>"
    return job


# -- windows ------------------------------------------------------------------------------------
def _corner_candidates(plan, score: bool = True):
    """Junctions inside extrusion: time, xy velocity change (:func:`_corner_scores`; NaN without
    ``score``), line, index of the move after the junction."""
    mv = plan.moves
    n = len(mv)
    if n < 2:
        return np.zeros(0), np.zeros(0), np.zeros(0, np.int64), np.zeros(0, np.int64)
    idx = by_geometry("corners", (mv.start, mv.end), (), lambda: _corner_moves(mv))
    tj = mv.t_start[idx + 1]
    return tj, _corner_scores(plan, tj) if score else np.full(len(tj), np.nan), mv.line[idx + 1], idx + 1


def _corner_scores(plan, tj: np.ndarray, tau: float = 0.02) -> np.ndarray:
    """The xy velocity change (mm/s) over ±``tau`` s around each junction time ``tj`` (s)."""
    vb = plan.velocity(tj - tau)[:, :2]
    va = plan.velocity(tj + tau)[:, :2]
    return np.linalg.norm(va - vb, axis=1)


def _corner_moves(mv) -> np.ndarray:
    """Index of the move before each junction inside extrusion that turns by more than 30°
    (the moves' geometry alone; extruding: E grows while X/Y move)."""
    ext = mv.extruding
    both = ext[1:] & ext[:-1]
    d_prev = (mv.end[:-1] - mv.start[:-1])[:, :2]
    d_next = (mv.end[1:] - mv.start[1:])[:, :2]
    dot = np.einsum("ij,ij->i", d_prev, d_next)
    norm = np.linalg.norm(d_prev, axis=1) * np.linalg.norm(d_next, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        cos = np.where(norm > 0, dot / norm, 1.0)
    return np.flatnonzero(both & (cos < math.cos(math.radians(30))))


def direction_change_frequencies(plan):
    """Local direction-change frequency (Hz) in planned time while extruding: for every run of
    2·3 reversals of X or Y inside one extrusion path, 3 cycles / their duration.

    Returns (t_centre, freq, line) arrays."""
    mv = plan.moves
    n = len(mv)
    ts, fs, ls = [], [], []
    if n < 2:
        return np.zeros(0), np.zeros(0), np.zeros(0, np.int64)
    k = 2 * CYCLES
    for rev, one_path in by_geometry("reversals", (mv.start, mv.end), (), lambda: _reversals(mv)):
        t_rev = mv.t_start[rev]
        span = t_rev[k:] - t_rev[:-k]
        good = one_path & (span > 0)
        with np.errstate(divide="ignore"):
            f = CYCLES / span
        ts.append(0.5 * (t_rev[k:] + t_rev[:-k])[good])
        fs.append(f[good])
        ls.append(mv.line[rev[:-k]][good])
    if not ts:
        return np.zeros(0), np.zeros(0), np.zeros(0, np.int64)
    return np.concatenate(ts), np.concatenate(fs), np.concatenate(ls)


def _reversals(mv) -> tuple:
    """Per axis with more than 2·CYCLES reversals inside extrusion paths: (the moves where X or Y
    reverses within a path, whether the 2·CYCLES reversals from each lie in one path) — the
    moves' geometry alone."""
    ext = mv.extruding
    connected = np.all(mv.start[1:] == mv.end[:-1], axis=1)
    k = 2 * CYCLES
    out = []
    for axis in (0, 1):
        s = np.sign(mv.end[:, axis] - mv.start[:, axis])
        sel = np.flatnonzero((s != 0) & ext)
        if len(sel) <= k:
            continue
        # a reversal at move j: previous moving move on this axis had the opposite sign, same path
        prev, cur = sel[:-1], sel[1:]
        rev = cur[(s[cur] != s[prev]) & _same_path(ext, connected, prev, cur)]
        if len(rev) <= k:
            continue
        # all k reversals must lie in one path: no non-extruding move between the first and last
        out.append((rev, _same_path(ext, connected, rev[:-k], rev[k:])))
    return tuple(out)


def _same_path(ext, connected, a, b) -> np.ndarray:
    """For index pairs a ≤ b: all moves a..b extruding and connected."""
    bad = np.concatenate(([0], np.cumsum(~ext)))
    gap = np.concatenate(([0], np.cumsum(~connected)))
    return (bad[b + 1] - bad[a] == 0) & (gap[b] - gap[a] == 0)


#: shares of the windows per kind, in the order they are filled: corners of visible features
#: (each window runs on along the wall after the corner), zigzags (fastest direction changes,
#: mostly infill) and corners of hidden features; a kind short of candidates leaves its places to
#: the next, then to any kind with candidates left
WINDOW_SHARES = (("seen-corner", 0.5), ("zigzag", 0.25), ("hidden-corner", 0.25))
#: windows on seams, beyond ``max_windows``: a visible class's entry (``seam-in``) and exit
#: (``seam-out``) in :data:`ringtune.shaping.seams.SEAM_ORDER` — the outer wall's, then the top
#: surfaces' — where per-feature settings of the motion beside them land on what is seen
SEAM_WINDOWS = 4


def _candidates(plan, span: float, order: bool = True, corner_scores: bool = True) -> dict:
    """Per window kind: (t0 of the window, score, line, feature class, order best first; None
    without ``order``). Support, skirt and brim (class ``support``: not the part) offer none while
    the part offers any. Without ``corner_scores`` the corners' scores are NaN and ``"corner-times"``
    gives their junction times (seen, hidden), to score the few that are wanted."""
    tc, sc, lc, mc = _corner_candidates(plan, corner_scores)
    tz, fz, lz = direction_change_frequencies(plan)
    mv = plan.moves
    names = label_classes(plan)
    cls_c = names[mv.feature[mc]] if len(mc) else np.zeros(0, str)
    cls_z = names[mv.feature[_last_move_of(mv.line, lz)]] if len(lz) else np.zeros(0, names.dtype)
    seen = np.isin(cls_c, list(VISIBLE))
    part_c, part_z = cls_c != "support", cls_z != "support"
    if not (part_c.any() or part_z.any()):          # nothing but support: judge it rather than nothing
        part_c, part_z = np.ones(len(cls_c), bool), np.ones(len(cls_z), bool)
    out = {}
    for kind, pick, t0, score, line, cls in (
            ("seen-corner", seen & part_c, tc - 0.2 * span, sc, lc, cls_c),
            ("hidden-corner", ~seen & part_c, tc - 0.2 * span, sc, lc, cls_c),
            ("zigzag", part_z, tz - 0.5 * span, fz, lz, cls_z)):
        t0, score, line, cls = t0[pick], score[pick], line[pick], cls[pick]
        out[kind] = (t0, score, line, cls, _best_per_class_first(score, cls) if order else None)
    if not corner_scores:
        out["corner-times"] = (tc[seen & part_c], tc[~seen & part_c])
    return out


def _last_move_of(move_lines: np.ndarray, lines: np.ndarray) -> np.ndarray:
    """Index of the last move on each of ``lines`` (source line numbers that moves have)."""
    move_lines = np.asarray(move_lines, np.int64)
    lines = np.asarray(lines, np.int64)
    if np.all(move_lines[1:] >= move_lines[:-1]):          # a file read in order: a search
        return np.searchsorted(move_lines, lines, side="right") - 1
    last = {int(line): i for i, line in enumerate(move_lines)}
    return np.array([last[int(x)] for x in lines], np.int64)


def _best_per_class_first(score: np.ndarray, cls: np.ndarray) -> np.ndarray:
    """Candidate order: each class's best, then each class's second best, ... (by score within a
    round), so the windows of a kind cover every feature class that has candidates."""
    by_score = np.argsort(-score, kind="stable")
    rank = np.zeros(len(score), np.int64)
    seen: dict = {}
    for i in by_score:
        rank[i] = seen.get(cls[i], 0)
        seen[cls[i]] = rank[i] + 1
    return np.lexsort((-score, rank))


def quality_windows(plan, max_windows: int = 8, span: float = 0.25, seams: int = SEAM_WINDOWS) -> list[Window]:
    """Up to ``max_windows`` non-overlapping windows of ``span`` s each, shared per feature class
    as :data:`WINDOW_SHARES` says: the sharpest corners (largest velocity change while extruding)
    of visible features, window starting just before the corner so the wall after it is inside;
    the highest-frequency zigzags; the sharpest corners of hidden features. Then one more for each
    feature class of the part with corners that none of those holds (its sharpest corner): a
    class no window holds would go unjudged (the inner walls of a sliced part, whose hidden-corner
    places the infills' sharper corners take, abut the outer wall). Then up to ``seams`` on the
    seams of visible classes (:data:`SEAM_WINDOWS`; each the one whose neighbouring motion runs
    fastest). Sorted by start time; ``kind`` is ``corner``, ``zigzag``, ``seam-in`` or
    ``seam-out``, ``feature`` the class there."""
    duration = plan.end_time
    span = min(span, duration)
    cands = _candidates(plan, span)
    cursor = dict.fromkeys(cands, 0)
    chosen: list[Window] = []
    lo_t, hi_t = plan.start_time, duration - span

    def take(kind: str, quota: int) -> int:
        t0s, scores, lines, classes, order = cands[kind]
        got, k = 0, cursor[kind]
        while got < quota and k < len(order):
            i = order[k]
            k += 1
            t0 = float(min(max(t0s[i], lo_t), hi_t))
            if all(t0 + span <= w.t0 or t0 >= w.t1 for w in chosen):
                chosen.append(Window(t0, t0 + span, "zigzag" if kind == "zigzag" else "corner",
                                     float(scores[i]), int(lines[i]), str(classes[i])))
                got += 1
        cursor[kind] = k
        return got

    left = max_windows
    for kind, share in WINDOW_SHARES:
        left -= take(kind, min(left, max(1, round(share * max_windows))))
    for kind, _ in WINDOW_SHARES:      # places a kind could not fill go to the others
        left -= take(kind, left)
    for kind in ("seen-corner", "hidden-corner"):   # a class with corners the shares left out: its sharpest
        t0s, scores, lines, classes, order = cands[kind]
        covered = {w.feature for w in chosen}
        for i in order:
            t0 = float(min(max(t0s[i], lo_t), hi_t))
            if classes[i] not in covered and all(t0 + span <= w.t0 or t0 >= w.t1 for w in chosen):
                chosen.append(Window(t0, t0 + span, "corner", float(scores[i]), int(lines[i]), str(classes[i])))
                covered.add(str(classes[i]))
    sides = seam_candidates(plan, span)
    for cls, side in [(c, k) for c in SEAM_ORDER for k in ("seam-in", "seam-out")]:
        if seams <= 0:
            break
        t0s, scores, lines, classes = sides[side]
        pick = np.flatnonzero(classes == cls)
        for i in pick[np.argsort(-scores[pick], kind="stable")]:
            t0 = float(min(max(t0s[i], lo_t), hi_t))
            if all(t0 + span <= w.t0 or t0 >= w.t1 for w in chosen):
                chosen.append(Window(t0, t0 + span, side, float(scores[i]), int(lines[i]), cls))
                seams -= 1
                break
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
    duration = plan.end_time
    span = min(span, duration)
    lo_t, hi_t = plan.start_time, duration - span
    c = _candidates(plan, span, order=False, corner_scores=False)     # a corner scored where taken
    corners = tuple(np.concatenate([c["seen-corner"][j], c["hidden-corner"][j]]) for j in range(4))
    corner_times = np.concatenate(c["corner-times"])
    cands = {"corner": corners, "zigzag": c["zigzag"][:4], **seam_candidates(plan, span)}
    out = []
    for w in reference:
        kind = w.kind if w.kind in cands else "corner"
        if len(cands[kind][2]) == 0:
            kind = "zigzag" if w.kind == "corner" else "corner"
        t0s, scores, lines, classes = cands[kind]
        if len(lines) == 0:
            return quality_windows(plan, max_windows=len(reference), span=span)
        i = int(np.argmin(np.abs(np.asarray(lines, np.int64) - int(w.line))))
        t0 = float(min(max(t0s[i], lo_t), hi_t))
        score = _corner_scores(plan, corner_times[i:i + 1])[0] if kind == "corner" else scores[i]
        out.append(Window(t0, t0 + span, w.kind, float(score), int(lines[i]), str(classes[i])))
    return sorted(out, key=lambda w: w.t0)
