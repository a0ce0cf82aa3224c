"""Material laid along the nozzle's real path against what the G-code asks (seed 002; definitions in
:mod:`ringtune.envs.window_metrics`; mm of path, mm of filament, %).

The firmware commands the extruder on its own clock (:mod:`ringtune.shaping.e_timing`: shaped with
X/Y, delayed by their lag, or neither); the nozzle follows the shaped X/Y command through the
machine's physics. At each sample the G-code asks for the filament the path holds up to the point
of the path nearest the nozzle; the firmware has pushed what its extruder command reached. Their
difference, in mm of path, is how far the extruder runs ahead of the nozzle (``lead``). The bead
lies along the nozzle's own path: over each stretch of it, the material pushed is compared with
what the G-code asks per mm where the nozzle is, times the length it moved.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ringtune.envs.path_geometry import EPS_LEN, Legs

#: mm of the nozzle's path over which laid material is compared with the asked (about two
#: nozzle widths: the bead spreads material over its own width)
SPAN_MM = 1.0


@dataclass
class Extrusion:
    """Per judged sample: the extruder's lead over the nozzle along the path (mm; > 0 ahead) and
    the feature class of its leg; per window of :data:`SPAN_MM`: the relative excess of material
    (fraction; > 0 over-extrusion) and the class where the window starts."""

    lead: np.ndarray
    lead_cls: np.ndarray
    excess: np.ndarray
    excess_cls: np.ndarray


def _empty() -> Extrusion:
    z = np.zeros(0)
    return Extrusion(z, z.astype(np.int64), z, z.astype(np.int64))


def extrusion(e_made: np.ndarray, tu: np.ndarray, pts: np.ndarray, vec: np.ndarray, leg: np.ndarray,
              legs: Legs, before: float = 0.0, after: float = 0.0, span: float = SPAN_MM) -> Extrusion:
    """Lead and excess of material of the samples matched to an extruding leg.

    Args:
        e_made: (n,) extruder position the firmware has commanded at each sample (mm of
            filament, the running maximum: retracted filament is not taken back from the part).
        tu: (n,) sample times on the unshaped clock, s, increasing.
        pts: (n, 2) nozzle x/y, mm; ``vec``/``leg``: from
            :func:`ringtune.envs.path_geometry.nearest_leg` (leg −1: no extruding leg near).
        legs: the commanded path's legs.
        before, after: s the shaped command starts turning before a corner (and its run before
            the planner's) and runs straight again after it (ends its run after the planner's).
        span: mm of the nozzle's path per compared stretch.

    Material is compared over the nozzle's own path (:func:`_nozzle_path`): stretches measured
    by the length the nozzle travels from where it is along the run when the run starts (before,
    only how far along the wall it has come, not the travel that brings it there); over each, the
    filament pushed against the filament per mm the path asks where the nozzle is, times the length
    it moved (:func:`_wanted`), so a corner the nozzle cuts short gets its filament on a shorter
    path, and where the nozzle is on the path is read again wherever it runs straight, so what cut
    corners save does not shift the rest of a long run against the path's own changes of rate. The
    lead is read where the shaped command runs straight along a leg (there the nearest point of the
    path is where the nozzle is along it).
    """
    ok = np.flatnonzero(leg >= 0)
    if len(ok) == 0:
        return _empty()
    first, last = legs.run_ends
    k0, run, t = leg[ok], legs.run[leg[ok]], tu[ok]
    along = np.einsum("ij,ij->i", pts[ok] - vec[ok] - legs.start[k0], legs.direction[k0])
    s_near = legs.s_start[k0] + np.clip(along, 0.0, legs.length[k0])
    straight = (t >= legs.t_start[k0] + after) & (t <= legs.t_end[k0] - before)
    lo_e, hi_e = legs.e_start[first[run]], legs.e_end[last[run]]
    made = np.clip(e_made[ok], lo_e, hi_e)
    lead_near = _held_at(made, run, legs) - _running_max_per_run(s_near, run)
    order = np.argsort(run, kind="stable")                     # grouped by run, in time order
    r, lo, hi = run[order], first[run[order]], last[run[order]]
    active = (t[order] >= legs.t_start[lo] - before) & (t[order] <= legs.t_end[hi] + after)
    started = t[order] >= legs.t_start[lo]
    coord, loc, step = _nozzle_path(s_near[order], pts[ok][order], r, active, started, straight[order],
                                    legs.s_start[lo])
    held, beyond, cls = _wanted(coord, loc, step, r, legs, lo, hi)
    whole = _whole_runs(t[order], r, legs.t_start[first], legs.t_end[last])
    excess, start = _excess(made[order], held, beyond, coord, r, span, whole)
    return Extrusion(lead_near[straight], legs.cls[k0][straight], excess, cls[start])


def _nozzle_path(s_near, pts, r, active, started, straight, s_first):
    """Per sample (grouped by run ``r``, in time order): where the nozzle is along its run, mm.

    Returns ``(coord, loc, step)``. ``coord``, the measure of the stretches: from the run's start on
    (``started``: its first leg's time, unshaped clock) the sample's nearest point of the path
    there, then on by the length the nozzle moves between consecutive active samples (``step``;
    0 elsewhere). Before the start, how far along the run the nozzle is at the latest by the start:
    the least nearest-point position from that sample to the start (a shaped command leaving early
    along the wall has laid that much of it; one still finishing a travel beside or back over the
    wall's start has laid none of it, and its own travel there is not wall); the run's start for
    samples before the run is active. ``loc``, where on the path the nozzle is: as ``coord``, but
    set again to the nearest point wherever the shaped command runs straight along a leg
    (``straight``), so that the length a cut corner saves does not shift the rest of the run along
    the path (non-decreasing within the run)."""
    go = active & started
    sn = s_near - s_first
    pair = np.concatenate([[False], (r[1:] == r[:-1]) & go[1:] & go[:-1]])
    step = np.where(pair, np.concatenate([[0.0], np.hypot(*np.diff(pts, axis=0).T)]), 0.0)
    cum = np.cumsum(step)
    idx = np.arange(len(r))
    anchor = np.full(int(r.max()) + 1, len(r))
    np.minimum.at(anchor, r[go], idx[go])
    a = anchor[r]
    after = idx >= a
    a_c = np.minimum(a, len(r) - 1)
    big = float(np.max(sn, initial=0.0)) + 2.0
    lead_in = np.where(active & (idx <= a), sn, big - 1.0) + r * big             # runs apart
    least_on = np.minimum.accumulate(lead_in[::-1])[::-1] - r * big              # suffix minimum per run
    before = np.where(active, np.minimum(least_on, big - 1.0), 0.0)
    coord = np.where(after, sn[a_c] + cum - cum[a_c], before)
    fix = np.maximum.accumulate(np.where(after & ((idx == a) | (go & straight)), idx, -1))
    fix_c = np.maximum(fix, 0)
    loc = np.where(after & (fix >= a), sn[fix_c] + cum - cum[fix_c], coord)
    loc = np.maximum.accumulate(loc + r * big) - r * big                          # non-decreasing per run
    return s_first + coord, s_first + loc, step


def _wanted(coord, loc, step, r, legs: Legs, lo, hi):
    """Per sample (grouped by run, in time order): the filament the path asks over the nozzle's path
    up to it since its run's first sample, and the filament it would ask where the nozzle has run
    past the run's end (at the last leg's rate: :func:`_excess`'s denominator), mm; and the class
    where the nozzle is. Where the nozzle moves (``step`` > 0), what the path asks per mm where it
    is, times the length moved (a corner cut short asks the shorter path's material); elsewhere
    (before the run starts) what the path holds over the nozzle's progress along it."""
    held_at = _asked(coord, legs, lo, hi)
    rate, cls, past = _rate_at(loc, legs, lo, hi)
    firsts = np.concatenate([[True], r[1:] != r[:-1]])
    progress = np.where(firsts, 0.0, np.diff(held_at, prepend=held_at[0]))
    moving = step > 0
    inc_held = np.where(moving, np.where(past, 0.0, rate * step), progress)
    inc_beyond = np.where(moving & past, _per_mm(legs, hi) * step, 0.0)
    return np.cumsum(inc_held), np.cumsum(inc_beyond), cls


def _per_mm(legs: Legs, k: np.ndarray) -> np.ndarray:
    """Mean filament per mm of path of legs ``k``."""
    return np.maximum(legs.e_end[k] - legs.e_start[k], 1e-12) / np.maximum(legs.length[k], EPS_LEN)


def _rate_at(s, legs: Legs, lo, hi):
    """(filament per mm of path, the class, whether past the run's end) at path position ``s`` of
    each sample's run: each merged move at its own rate; nothing over a non-extruding gap within
    the run."""
    k = _leg_at(legs, s, lo, hi)
    off = s - legs.s_start[k]
    j = np.clip(np.searchsorted(legs.knot_s, s, side="right") - 1, legs.knot_first[k], legs.knot_last[k] - 1)
    ds = legs.knot_s[j + 1] - legs.knot_s[j]
    rate = np.where(ds > EPS_LEN, (legs.knot_e[j + 1] - legs.knot_e[j]) / np.maximum(ds, EPS_LEN), _per_mm(legs, k))
    inside = off <= legs.length[k] + EPS_LEN
    return np.where(inside, np.maximum(rate, 0.0), 0.0), legs.cls[k], (k == hi) & ~inside


def _whole_runs(t: np.ndarray, run: np.ndarray, t_first: np.ndarray, t_last: np.ndarray) -> np.ndarray:
    """Per sample: whether the samples of its run span the run's whole time (its first leg's start
    to its last leg's end), so that a run shorter than a stretch is one, not a window's cut of it."""
    n = int(run.max()) + 1
    lo, hi = np.full(n, np.inf), np.full(n, -np.inf)
    np.minimum.at(lo, run, t)
    np.maximum.at(hi, run, t)
    return (lo[run] <= t_first[run]) & (hi[run] >= t_last[run])


def _asked(s, legs: Legs, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Filament (mm) the path holds up to path position ``s`` of each sample's run (within it):
    along the moves each leg was merged from, each at its own rate (:attr:`Legs.knot_s`)."""
    k = _leg_at(legs, s, lo, hi)
    at = legs.s_start[k] + np.clip(s - legs.s_start[k], 0.0, legs.length[k])
    j = np.clip(np.searchsorted(legs.knot_s, at, side="right") - 1, legs.knot_first[k], legs.knot_last[k] - 1)
    s0, e0 = legs.knot_s[j], legs.knot_e[j]
    frac = np.clip((at - s0) / np.maximum(legs.knot_s[j + 1] - s0, EPS_LEN), 0.0, 1.0)
    return e0 + frac * (legs.knot_e[j + 1] - e0)


def _held_at(made: np.ndarray, run: np.ndarray, legs: Legs) -> np.ndarray:
    """Path position (mm) up to which each sample's run holds the filament ``made`` (within the
    run's, mm): the inverse of the path's filament along the run, each merged move at its own
    filament per mm (:attr:`Legs.knot_s`), so a lead read across a change of rate is the path
    between the nozzle and where the extruder has got to, not a rate's guess at it."""
    first, last = legs.run_ends
    runs, rank = np.unique(run, return_inverse=True)
    lo, hi = legs.knot_first[first[runs]], legs.knot_last[last[runs]]
    count = hi - lo + 1
    begin = np.concatenate([[0], np.cumsum(count)[:-1]])
    own = np.repeat(np.arange(len(runs)), count)
    knot = lo[own] + np.arange(int(count.sum())) - begin[own]      # the runs' knots, run by run
    base = legs.knot_e[lo]
    rel = np.maximum(legs.knot_e[knot] - base[own], 0.0)
    big = 2.0 ** np.ceil(np.log2(float(np.max(rel, initial=0.0)) + 2.0))   # runs apart, each non-decreasing
    key = np.maximum.accumulate(rel + own * big)
    at = np.searchsorted(key, np.maximum(made - base[rank], 0.0) + rank * big, side="right") - 1
    j = knot[np.clip(at, begin[rank], begin[rank] + count[rank] - 2)]
    e0, s0 = legs.knot_e[j], legs.knot_s[j]
    frac = np.clip((made - e0) / np.maximum(legs.knot_e[j + 1] - e0, 1e-12), 0.0, 1.0)
    return s0 + frac * (legs.knot_s[j + 1] - s0)


def _running_max_per_run(s: np.ndarray, run: np.ndarray) -> np.ndarray:
    """Running maximum of ``s`` within each run (samples in time order)."""
    order = np.argsort(run, kind="stable")
    big = float(np.ptp(s)) + 1.0
    key = np.maximum.accumulate(s[order] + run[order] * big) - run[order] * big
    out = np.empty_like(s)
    out[order] = key
    return out


def _leg_at(legs: Legs, s: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Index of the extruding leg of each sample's run that holds path length ``s`` (mm)."""
    idx = np.flatnonzero(legs.extruding)
    j = np.searchsorted(legs.s_start[idx], s, side="right") - 1
    return np.clip(idx[np.maximum(j, 0)], lo, hi)


def _excess(made: np.ndarray, asked: np.ndarray, beyond: np.ndarray, s: np.ndarray, run: np.ndarray,
            span: float, whole: np.ndarray):
    """Relative excess of material over each stretch of ``span`` mm of a run's path (its end placed
    between the two samples about it, linearly: running to the first sample past it made a stretch
    up to a sample's spacing longer, 5 % at 150 mm/s and 2 kHz), and the index of the sample where
    it starts: the filament made over the stretch beyond what its path holds,
    against what it holds (in filament, not in mm of path: a slicer's legs differ in filament per
    mm, a short one by a hundred times, and a lead in mm of path is read at each end's own rate);
    where the nozzle's travel runs past the run's end, that part of the stretch counts at the last
    leg's rate in the denominator (``beyond``), so a stretch the path no longer holds is not
    divided by nothing. A run shorter than ``span`` (but longer than a quarter of it) is one
    stretch where its samples span all of it (``whole``); a run the window cuts has only its full
    stretches. Samples grouped by run, in time order; ``s`` and ``made`` non-decreasing within each
    run."""
    run_o = run
    big = float(np.ptp(s)) + 2.0 * span + 1.0
    key = s + run_o * big                                    # runs apart, each non-decreasing
    last = np.searchsorted(run_o, run_o, side="right") - 1    # last sample of each sample's run
    j = np.searchsorted(key, key + span, side="left")
    i_full = np.flatnonzero(j <= last)
    firsts = np.flatnonzero(np.concatenate([[True], run_o[1:] != run_o[:-1]]))
    has_full = np.zeros(int(run_o.max()) + 1, bool)
    has_full[run_o[i_full]] = True
    short = firsts[~has_full[run_o[firsts]]]
    short = short[(key[last[short]] - key[short] > 0.25 * span) & whole[short]]
    i_all = np.concatenate([i_full, short])
    j_all = np.concatenate([j[i_full], last[short]])
    # a full stretch ends exactly ``span`` on: its end between the two samples about it, linear
    f = np.ones(len(i_all))
    jf, i0 = j[i_full], np.maximum(j[i_full] - 1, i_full)
    ds = s[jf] - s[i0]
    f[:len(i_full)] = np.where(ds > 0, np.clip((s[i_full] + span - s[i0]) / np.where(ds > 0, ds, 1.0), 0.0, 1.0), 1.0)
    i_prev = np.concatenate([i0, last[short]])

    def at_end(v):
        return v[i_prev] + f * (v[j_all] - v[i_prev])
    held = at_end(asked) - asked[i_all]
    want = np.maximum(held + at_end(beyond) - beyond[i_all], 1e-12)
    return (at_end(made) - made[i_all] - held) / want, i_all
