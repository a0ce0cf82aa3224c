"""Material laid along the nozzle's real path against what the G-code asks (seed 002; definitions in
:mod:`ringtune.envs.metrics`; mm of path, mm of filament, %).

The firmware commands the extruder on its own clock (:mod:`ringtune.shaping.e_timing`: shaped with
X/Y, delayed by their lag, or neither); the nozzle follows the shaped X/Y command through the
machine's physics. At each sample the G-code asks for the filament the path holds up to the point
of the path nearest the nozzle; the firmware has pushed what its extruder command reached. Their
difference, in mm of path, is how far the extruder runs ahead of the nozzle (``lead``); a change
of lead over a stretch of path is material laid there beyond (or short of) what was asked.
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


def extrusion(e_made: np.ndarray, pts: np.ndarray, vec: np.ndarray, leg: np.ndarray, legs: Legs,
              span: float = SPAN_MM) -> Extrusion:
    """Lead and excess of material of the samples matched to an extruding leg.

    Args:
        e_made: (n,) extruder position the firmware has commanded at each sample (mm of
            filament, the running maximum: retracted filament is not taken back from the part).
        pts: (n, 2) nozzle x/y, mm; ``vec``/``leg``: from
            :func:`ringtune.envs.path_geometry.nearest_leg` (leg −1: no extruding leg near).
        legs: the commanded path's legs.
        span: mm of path per compared stretch.
    """
    ok = leg >= 0
    if not ok.any():
        return _empty()
    k = leg[ok]
    length = np.maximum(legs.length[k], EPS_LEN)
    along = np.clip(np.einsum("ij,ij->i", pts[ok] - vec[ok] - legs.start[k], legs.direction[k]), 0.0, length)
    per_mm = np.maximum(legs.e_end[k] - legs.e_start[k], 0.0) / length
    good = per_mm > 0
    k, along, per_mm = k[good], along[good], per_mm[good]
    if len(k) == 0:
        return _empty()
    run = legs.run[k]
    asked = legs.e_start[k] + per_mm * along
    lo, hi = _run_range(legs, run)
    made = np.clip(e_made[ok][good], lo, hi)
    lead = (made - asked) / per_mm
    s = legs.s_start[k] + along
    excess, start = _excess(lead, s, run, span)
    return Extrusion(lead, legs.cls[k], excess, legs.cls[k][start])


def _run_range(legs: Legs, run: np.ndarray):
    """Extruder positions (mm) where each sample's extrusion run starts and ends."""
    runs = legs.run
    ext = legs.extruding
    n_runs = int(runs.max()) + 1 if len(runs) else 0
    lo = np.full(n_runs, np.inf)
    hi = np.full(n_runs, -np.inf)
    np.minimum.at(lo, runs[ext], legs.e_start[ext])
    np.maximum.at(hi, runs[ext], legs.e_end[ext])
    return lo[run], hi[run]


def _excess(lead: np.ndarray, s: np.ndarray, run: np.ndarray, span: float):
    """Relative excess of material over each stretch of ``span`` mm of a run's path, and the index
    of the sample where it starts: (lead at the end − lead at the start) / path length between.
    A run shorter than ``span`` (but longer than a quarter of it) is one stretch.

    Samples are grouped by run in time order; the path position is made non-decreasing within a run
    (a nozzle swinging back does not lay the same stretch twice)."""
    order = np.argsort(run, kind="stable")
    run_o, lead_o = run[order], lead[order]
    big = float(np.ptp(s)) + 2.0 * span + 1.0
    key = np.maximum.accumulate(s[order] + run_o * big)      # per-run running maximum, runs apart
    last = np.searchsorted(run_o, run_o, side="right") - 1    # last sample of each sample's run
    j = np.searchsorted(key, key + span, side="left")
    i_full = np.flatnonzero(j <= last)
    firsts = np.flatnonzero(np.r_[True, run_o[1:] != run_o[:-1]])
    has_full = np.zeros(int(run_o.max()) + 1, bool)
    has_full[run_o[i_full]] = True
    short = firsts[~has_full[run_o[firsts]]]
    short = short[key[last[short]] - key[short] > 0.25 * span]
    i_all = np.r_[i_full, short]
    j_all = np.r_[j[i_full], last[short]]
    length = np.maximum(key[j_all] - key[i_all], EPS_LEN)
    return (lead_o[j_all] - lead_o[i_all]) / length, order[i_all]
