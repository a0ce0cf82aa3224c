"""Print-quality metrics of a simulated print: what a person would see on the part, each measure
defined here and taken on one window by :func:`compute_metrics` (the record they fill,
:class:`~ringtune.envs.metrics.Metrics`, and how windows and printer variants combine:
:mod:`ringtune.envs.metrics`).

Inputs are a simulation result (``SimResult``: sample times ``t`` in s, simulated ``nozzle`` x/y
relative to the print in mm, ``head_accel`` in mm/s², motor forces, ``step_loss``) and the
*unshaped* planned motion of the same time span (:class:`~ringtune.shaping.motion.Motion`), which
is the geometry the slicer asked for, with the feature class of each of its segments
(:mod:`ringtune.shaping.features`) and the extruder as the firmware commands it
(:mod:`ringtune.shaping.e_timing`). Distances are geometric (to the commanded path), so a nozzle
that merely lags along the path costs nothing; only leaving the path does. "Unshaped clock": the
sample's time minus ``lag`` (the causal shaper's centroid; 0 for centred shapers). A sample is
*extruding* when the unshaped path deposits material at that time; its *class* is the feature
class of that path segment. *Visible* classes (outer walls, top surfaces, bridges and overhangs,
unlabelled moves) are judged by ripple, corners and extrusion; *hidden* ones (inner walls, infill,
solid infill, support) by show-through and extrusion. In a job that labels its visible features,
unlabelled extrusion is a purge line: measured per class, but not in the job's figures
(``seen_classes``).

What a person sees (all mm unless stated):

``ripple_mm``
    on every straight wall of a visible class (an extruding leg), over the span where the shaped
    command runs straight along it — from ``settle`` s after the leg starts (the shaper's last
    impulse has passed the corner) to ``anticipate`` s before it ends (the shaper starts turning
    into the next one), both on the unshaped clock, at least ``min_wall`` s long — the
    peak-to-peak of the nozzle's deviation across the wall (perpendicular to the wall's line):
    what calipers and eyes see. ``ripple_mm`` is the worst wall's. *Example*: a wall along Y after
    a corner where X stopped from a deceleration of 5000 mm/s², on one X mode of 40 Hz with
    damping ratio 0.05, no shaper: the nozzle leaves the corner a/ω² = 0.079 mm ahead and swings
    freely about the wall, x(τ) = 0.079·e^(−ζωτ)(cos ω_dτ + ζ/√(1−ζ²)·sin ω_dτ); over 0.1 s of
    wall the peak-to-peak is 0.079·(1 + e^(−ζπ/√(1−ζ²))) = 0.147 mm.
``ripple_p90_mm``
    the 90th percentile (linear interpolation) of the visible walls' ripples.
``corner_in_mm`` / ``corner_out_mm``
    at every corner (the path turns by ≥ ``corner_angle_deg`` between two legs, one extruding),
    over the samples of visible classes from when the shaped command starts turning
    (``anticipate`` s before the corner, unshaped clock) to ``corner_tail`` s after it has finished
    (``settle`` s after the corner; the tail holds the nozzle's first swing), the distance from the
    nearest point of the corner's two legs, inward (cutting the corner: the shaper's smoothing)
    or outward (past the corner, outside the turn: overshoot) by the side of the corner's
    bisector it lies on, never more than the sample's distance to the path (after chords shorter
    than the corner's span the nozzle is already on the next leg); the worst of each, read between
    samples too: inward where the chord between two samples crosses from one leg's side to the
    other's (the distance to the nearer leg has a kink there), and at the instant a wall starts or
    stops extruding (a sample is added there: what a travel leaves on a wall's start). *Example*: a
    90° corner taken at a constant 100 mm/s, Klipper ZV at 50 Hz with no damping (two halves 10 ms
    apart, centred), a stiff machine: the shaped command cuts the corner by v·Δt/4 = 0.25 mm
    (corner_in 0.25 mm, corner_out 0).
``extrusion_over_pct`` / ``extrusion_under_pct``
    seed 002's extruder timing. The firmware pushes filament as its extruder command says
    (running maximum: retracted filament is not taken back from the part); the G-code asks, per mm
    of path, the filament of the path's own moves. The bead lies along the nozzle's own path:
    along each extrusion run it is measured by the length the nozzle travels from where it is
    along the run when the run starts (a travel that brings it there, beside or back over the
    wall's start, is not wall). Over every stretch of ``SPAN_MM`` = 1 mm of it within a run (a
    shorter run the window holds whole: the run), the material laid against the asked is the
    filament pushed over the stretch against the filament per mm the path asks where the nozzle
    is, times the length it moved (so a corner it cuts short gets its filament on a shorter path;
    on a straight line at one rate, 1 + Δlead/length, lead in mm of path; slicers' moves differ in
    rate, each counts at its own); the largest excess and the largest
    shortfall, in %, over the classes whose material a person sees (:data:`EXTRUSION_SEEN`: the
    visible ones, and the inner walls and solid infill that lie against them; they arise at starts,
    stops and corners). Sparse infill and support are nobody's to see: their own figures stay in
    ``features``.
    *Example*: Marlin classic ZV at 40 Hz (no damping: halves 12.5 ms apart, lag ΣAᵢTᵢ = 6.25 ms)
    leaves the extruder 0.625 mm ahead at 100 mm/s; a line started from rest whose acceleration
    ends within its first mm gets 62.5 % too much material there and 62.5 % too little over its
    last mm.
``e_lag_mm``
    the largest |lead| (mm of path, the nozzle's position taken at its nearest point of the path)
    where the shaped command runs straight along a leg (the spans ``ripple_mm`` measures walls
    on): how far the firmware's extruder runs ahead of (or behind) the nozzle. Example above:
    0.625 mm; where E follows X/Y (Klipper, RepRapFirmware), what remains is the nozzle's own lag
    behind the command while accelerating, a/ω² per mode (seed 002).
``show_through_mm``
    what hidden features push into the outer wall (nophead's serrated edge: infill overshooting
    the outline): over samples of hidden classes, the outward excursion past their corners and
    reversals (as ``corner_out_mm``, where infill turns at the walls), and over their straight
    walls (inner walls lie against the outer wall; its side is not known, so either side counts)
    the largest distance from the wall's line; the worst. Whether it shows depends on how much of
    it the overlap the slicer leaves between infill and walls (typically 10–25 % of a line
    width) absorbs: that bound belongs to the judge. *Example*: infill reversing 0.08 mm past its
    turning points: 0.08 mm.
``features``
    ``{class: {key: value}}`` for each feature class with extruding samples in the judged
    windows, keys :data:`FEATURE_KEYS` (``show_through_mm`` 0 for visible classes); the values
    above are the worst over the visible (respectively hidden; for extrusion :data:`EXTRUSION_SEEN`)
    classes.
``extrusion_if_synced``
    where the firmware can synchronise its extruder and does not by default
    (:attr:`ringtune.shaping.firmware.Firmware.e_sync`), ``extrusion_over_pct``,
    ``extrusion_under_pct`` and ``e_lag_mm`` with that option on; empty otherwise.

Diagnostics and constraints:

``path_error_mm``
    max over extruding samples of visible classes (hidden ones are bounded by what shows through,
    ``show_through_mm``) of the distance from the nozzle to the nearest *extruding* leg of
    the commanded path active within ``match_window`` s of the sample (the time restriction keeps
    adjacent parallel infill lines from being mistaken for the line being printed); each class's
    own in ``features``.
``overshoot_mm``
    max over corners (direction change ≥ ``corner_angle_deg``, either side extruding) of the
    outward excursion after the corner: an extruding sample belongs to the latest corner the
    shaped command has started turning into (``anticipate`` s before the corner's time on the
    shaped clock) for up to ``corner_window`` s; if its nearest path point (as for
    ``path_error_mm``) is on the corner's outgoing leg or is the corner itself, it counts with its
    distance from the path when the vector ``e`` from that point to the nozzle points outward,
    ``e · (d_in − d_out) > 0`` (the outer bisector; for a reversal, past the turning point).
``ringing_mm``
    max over straight walls that follow a corner of the RMS, about its mean, of the nozzle's
    perpendicular deviation from the wall's line over the span ``ripple_mm`` uses (a diagnostic:
    the ripple is what is judged); a wall the window's end cuts short counts where at least 0.1 s
    of it is measured (:data:`ringtune.envs.path_measures.RINGING_MIN_SPAN`).
``peak_accel``
    max over all samples of the head's acceleration magnitude ``|(a_x, a_y)|``, mm/s².
``step_loss``
    the simulator's flag, or any sample where ``|motor_force| > motor_force_max``.
``motor_load``
    max over all samples and motors of ``|motor_force| / motor_force_max``: how much of the force a
    motor has at its speed the motion asks of it (above 1 it loses steps). The evaluator
    (:func:`ringtune.envs.evaluate.with_plan_load`) takes in the same fraction over every move of
    the whole planned job, rigid machine (:mod:`ringtune.envs.plan_load`): the larger counts.
``print_time_s``
    not computed here: the planner's print time over the whole job (s), filled in by
    :func:`ringtune.envs.evaluate.evaluate`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ringtune.envs.extrusion import SPAN_MM, extrusion
from ringtune.envs.metrics import EXTRUSION_KEYS, FEATURE_KEYS, SEEN_KEYS, Metrics, p90_from_walls
from ringtune.envs.path_geometry import Legs, legs_of, nearest_leg, path_legs
from ringtune.envs.path_measures import overshoot, path_error, ringing_rms
from ringtune.envs.visible import Walls, corner_deviation, per_class_max, walls
from ringtune.shaping.features import FEATURE_CLASSES, VISIBLE
from ringtune.shaping.motion import Motion

_VISIBLE = np.array([c in VISIBLE for c in FEATURE_CLASSES])
#: classes whose extrusion a person sees: the visible ones, the inner walls (behind the outer wall:
#: what they lay too much pushes it) and solid infill (under the top surface)
EXTRUSION_SEEN = VISIBLE | {"inner_wall", "solid_infill"}
_EXTRUSION_SEEN = np.array([c in EXTRUSION_SEEN for c in FEATURE_CLASSES])
_OTHER = FEATURE_CLASSES.index("other")
_OUTER_WALL = FEATURE_CLASSES.index("outer_wall")
_N = len(FEATURE_CLASSES)
#: s after the shaped command finished turning a corner that still belongs to it, by default
CORNER_TAIL = 0.0125


# -- the measures of one window ----------------------------------------------------------------------
def compute_metrics(sim: Any, path: Motion, *, lag: float = 0.0, settle: float = 0.0,
                    anticipate: float = 0.0,
                    corner_angle_deg: float = 30.0, corner_window: float = 0.06,
                    match_window: float = 0.05, min_wall: float = 0.02,
                    print_time_s: float = float("nan"), classes: np.ndarray | None = None,
                    e_command: Motion | None = None, e_command_synced: Motion | None = None,
                    corner_tail: float = CORNER_TAIL, seen_classes=None) -> Metrics:
    """Quality metrics of one simulated window against its unshaped commanded path.

    Args:
        sim: a ``SimResult`` (or anything with ``t``, ``nozzle``, ``head_accel``, ``step_loss`` and
            optionally ``motor_force``/``motor_force_max``), times on the same clock as ``path``.
        path: the unshaped planned motion of the window.
        lag: s, delay of the shaped command behind the unshaped one (a causal shaper's centroid;
            0 for centred shapers), used to decide which part of the path a sample belongs to.
        settle: s after a corner (unshaped time) at which the shaped command runs straight along
            the next wall again (last impulse time, minus the centroid if centred).
        anticipate: s before a corner (unshaped time) at which a centred shaped command starts
            turning (the centre delay; 0 for causal shapers).
        corner_angle_deg: smallest direction change that counts as a corner, degrees.
        corner_window: s after a corner searched for ``overshoot_mm``.
        match_window: s either side of a leg's time span within which a sample may match it.
        min_wall: s, shortest measured span of a wall whose ripple counts.
        print_time_s: passed through to the result.
        classes: (path.n_segments,) feature class index of each segment of ``path``
            (:data:`ringtune.shaping.features.FEATURE_CLASSES`; None: all ``other``, visible).
        e_command: the firmware's extruder command on the sim's clock (one-column motion,
            :func:`ringtune.shaping.e_timing.extruder_command`); None: no extrusion measures.
        e_command_synced: the same with the firmware's E synchronisation on, or None.
        corner_tail: s after the shaped command finished turning that still belong to the corner.
        seen_classes: the classes the job-level measures are taken over (the job's seen classes,
            :func:`ringtune.shaping.seams.job_seen_classes`: ``other`` is a purge line in a job
            that labels its visible features); None: :data:`VISIBLE`. Per class, all are measured.
    """
    t, nozzle, machine = _machine(sim)
    step = (t[-1] - t[0]) / (len(t) - 1) if len(t) > 1 else 0.0
    tu, nozzle = _with_edges(t - lag, nozzle, path)   # sample times on the unshaped clock
    t = tu + lag
    seg = path.segment_index(tu)
    cls_seg = np.full(path.n_segments, _OTHER) if classes is None else np.asarray(classes, np.int64)
    extruding = (tu >= path.t[0]) & (tu <= path.t[-1]) & path.extruding[seg]
    legs = legs_of(path, classes) if classes is not None else path_legs(path, cls_seg)
    vis = _VISIBLE if seen_classes is None else np.isin(FEATURE_CLASSES, list(seen_classes))
    details: dict[str, Any] = {"seen_classes": [c for c, v in zip(FEATURE_CLASSES, vis) if v]}
    dist, vec, leg = nearest_leg(tu, nozzle, legs, match_window)
    cls = cls_seg[seg[extruding]]
    ex = (tu[extruding], nozzle[extruding], dist[extruding], vec[extruding], leg[extruding])
    w = walls(ex[0], ex[1], legs, settle - lag, anticipate + lag, min_wall)
    seen = vis[cls]             # the bound on the path is what a person sees (hidden ones: show-through)
    old = dict(path_error_mm=path_error(ex[0][seen], ex[1][seen], ex[2][seen], details),
               overshoot_mm=overshoot(*ex, legs, corner_angle_deg, corner_window, anticipate + lag, details),
               ringing_mm=ringing_rms(w, legs, corner_angle_deg, details))
    per_cls = _seen(ex[0], ex[1], ex[2], cls, legs, w, corner_angle_deg, settle - lag,
                    anticipate + lag, corner_tail, step, details)
    # extrusion: every sample near an extruding leg in time (the extruder may start before the
    # nozzle arrives and stop before it finishes)
    made = _made(t, e_command)
    if made is not None:
        per_cls.update(_extruded(made, tu, nozzle, vec, leg, legs, anticipate + lag, settle - lag))
    m = Metrics(print_time_s=print_time_s, details=details, **old, **machine, **_top(per_cls, vis))
    m.features = _features(per_cls, np.unique(cls))
    p90_from_walls(m, details["ripple_walls"], details["seen_classes"])
    synced = _made(t, e_command_synced)
    if synced is not None:
        m.extrusion_if_synced = _top(_extruded(synced, tu, nozzle, vec, leg, legs, anticipate + lag, settle - lag),
                                     vis)
    return m


def _with_edges(tu: np.ndarray, nozzle: np.ndarray, path: Motion) -> tuple[np.ndarray, np.ndarray]:
    """The samples with one more at each instant inside them where ``path`` starts or stops
    extruding (the nozzle there linear between its neighbours: second order in the spacing). What
    the nozzle does as a wall starts or ends counts from that instant: a wall that starts at the end
    of a travel is off the travel's line by what the travel left, and the first sample after it,
    anywhere up to a spacing later, reads less of it as it decays."""
    ext = np.asarray(path.extruding, bool)
    b = np.flatnonzero(ext[1:] != ext[:-1]) + 1
    if len(tu) < 2 or not len(b):
        return tu, nozzle
    edges = np.where(ext[b], path.t[b], np.nextafter(path.t[b], -np.inf))   # an end: still in the segment
    edges = edges[(edges > tu[0]) & (edges < tu[-1])]
    at = np.searchsorted(tu, edges)
    new = tu[at] != edges
    edges, at = edges[new], at[new]
    if not len(edges):
        return tu, nozzle
    pts = nozzle[at - 1] + (nozzle[at] - nozzle[at - 1]) * ((edges - tu[at - 1]) / (tu[at] - tu[at - 1]))[:, None]
    return np.insert(tu, at, edges), np.insert(nozzle, at, pts, axis=0)


def _machine(sim: Any):
    """(t, nozzle x/y, {peak_accel, step_loss, motor_load}) of a simulation result."""
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
    return t, nozzle, {"peak_accel": peak_accel, "step_loss": step_loss, "motor_load": motor_load}


def _seen(tu, pts, dist, cls, legs: Legs, w: Walls, angle: float, settle: float, early: float,
          tail: float, step: float, details: dict) -> dict[str, np.ndarray]:
    """Per class (arrays over FEATURE_CLASSES): ripple, corner in/out, show-through and path error
    of the extruding samples (the ripple's p90 is set from the walls of all windows); ``step``: s
    between the simulation's samples."""
    details["ripple_walls"] = [[FEATURE_CLASSES[c], float(r)] for c, r in zip(w.cls, w.ripple)]
    if len(w.leg):
        k = w.leg[int(np.argmax(w.ripple))]
        details["ripple_at"] = {"t_start": float(legs.t_start[k]), "t_end": float(legs.t_end[k]),
                                "x": float(legs.start[k, 0]), "y": float(legs.start[k, 1]),
                                "feature": FEATURE_CLASSES[legs.cls[k]]}
    near = np.where(np.isfinite(dist), dist, np.inf)     # never further from the corner than from the path
    inward, outward = corner_deviation(tu, pts, legs, angle, early, max(settle, 0.0) + tail, near, step)
    ow = cls == _OUTER_WALL
    if ow.any():     # where the outer wall's worst corner is (the sample's: a chord's cut is at its start)
        details["outer_wall_at"] = {k: _place(tu, pts, np.where(ow, v, -1.0))
                                    for k, v in (("corner_in_mm", inward), ("corner_out_mm", outward))}
    out = per_class_max(outward, cls, _N)
    hidden_reach = np.maximum(out, per_class_max(w.offset, w.cls, _N))
    finite = np.isfinite(dist)
    return {"ripple_mm": per_class_max(w.ripple, w.cls, _N),
            "ripple_p90_mm": np.zeros(_N),          # from the walls of all windows: p90_from_walls
            "corner_in_mm": per_class_max(inward, cls, _N), "corner_out_mm": out,
            "show_through_mm": np.where(_VISIBLE, 0.0, hidden_reach),
            "path_error_mm": per_class_max(dist[finite], cls[finite], _N)}


def _place(tu: np.ndarray, pts: np.ndarray, values: np.ndarray) -> dict[str, float]:
    """{value (mm), t (unshaped clock, s), x, y (mm)} of the largest of ``values``."""
    i = int(np.argmax(values))
    return {"value": float(values[i]), "t": float(tu[i]), "x": float(pts[i, 0]), "y": float(pts[i, 1])}


def _made(t: np.ndarray, e_command: Motion | None) -> np.ndarray | None:
    """The extruder position the firmware has reached by each sample (running maximum), or None."""
    if e_command is None:
        return None
    return np.maximum.accumulate(e_command.position(t)[:, 0]) if len(t) else np.zeros(0)


def _extruded(made, tu, pts, vec, leg, legs: Legs, before: float, after: float) -> dict[str, np.ndarray]:
    """Per class: worst over- and under-extrusion (%) and largest |lead| (mm)."""
    ex = extrusion(made, tu, pts, vec, leg, legs, max(before, 0.0), max(after, 0.0), SPAN_MM)
    return {"extrusion_over_pct": 100.0 * per_class_max(np.maximum(ex.excess, 0.0), ex.excess_cls, _N),
            "extrusion_under_pct": 100.0 * per_class_max(np.maximum(-ex.excess, 0.0), ex.excess_cls, _N),
            "e_lag_mm": per_class_max(np.abs(ex.lead), ex.lead_cls, _N)}


def _top(per_cls: dict[str, np.ndarray], vis: np.ndarray) -> dict[str, float]:
    """The job-level values: seen measures over the seen classes ``vis`` (a mask over
    FEATURE_CLASSES), show-through over hidden ones, extrusion over those and the rest of
    :data:`EXTRUSION_SEEN` (the ripple's p90 is set from the walls, :func:`p90_from_walls`)."""
    out = {}
    extrusion_seen = vis | (_EXTRUSION_SEEN & ~_VISIBLE)
    for k, v in per_cls.items():
        if k in SEEN_KEYS:
            out[k] = float(np.max(v[vis]))
        elif k in EXTRUSION_KEYS:
            out[k] = float(np.max(v[extrusion_seen]))
        elif k == "show_through_mm":
            out[k] = float(np.max(v))
    return out


def _features(per_cls: dict[str, np.ndarray], present: np.ndarray) -> dict[str, dict[str, float]]:
    """``{class: {key: value}}`` for the classes with extruding samples."""
    return {FEATURE_CLASSES[c]: {k: float(per_cls[k][c]) if k in per_cls else 0.0 for k in FEATURE_KEYS}
            for c in present}
