"""Where along its run the path holds a given filament (the lead's inverse), against np.interp run
by run: several runs apart by travel, each two legs at a corner merged from moves of their own
filament per mm (as a slicer's variable-width walls are)."""

from __future__ import annotations

import numpy as np
import pytest

from ringtune.envs.extrusion import _held_at
from ringtune.envs.path_geometry import path_legs
from ringtune.shaping.motion import Motion


def runs_of_moves(rng: np.random.Generator) -> Motion:
    """Three runs of two legs (three collinear moves each, rates drawn), a travel between runs;
    constant speed 50 mm/s (the geometry is what matters here)."""
    pts, es, ext = [np.array([10.0, 10.0])], [3.0], []
    for run in range(3):
        for direction in (np.array([1.0, 0.0]), np.array([0.0, 1.0])):
            for _ in range(3):
                step = rng.uniform(0.5, 4.0)
                pts.append(pts[-1] + step * direction)
                es.append(es[-1] + step * rng.uniform(0.01, 0.08))
                ext.append(True)
        pts.append(pts[-1] + np.array([5.0, -20.0]))     # travel to the next run
        es.append(es[-1])
        ext.append(False)
    p_xy = np.array(pts)
    length = np.hypot(*np.diff(p_xy, axis=0).T)
    t = np.concatenate([[0.0], np.cumsum(length / 50.0)])
    dt = np.diff(t)[:, None]
    p = np.column_stack([p_xy, np.full(len(p_xy), 0.2), es])
    v = np.diff(p, axis=0) / dt
    return Motion(t, p[:-1], v, np.zeros_like(v), np.array(ext))


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_the_path_holding_the_filament_made_is_the_runs_own_inverse(seed):
    rng = np.random.default_rng(seed)
    legs = path_legs(runs_of_moves(rng))
    first, last = legs.run_ends
    runs = np.flatnonzero(np.bincount(legs.run[legs.extruding]))
    assert len(runs) == 3 and legs.extruding.sum() == 6      # three moves merged into each leg
    run = rng.choice(runs, 400)
    e_lo, e_hi = legs.e_start[first[run]], legs.e_end[last[run]]
    made = e_lo + rng.uniform(0.0, 1.0, len(run)) * (e_hi - e_lo)
    made[:6] = e_lo[:6]                                   # the run's ends too
    made[6:12] = e_hi[6:12]
    held = _held_at(made, run, legs)
    for r in runs:
        k = slice(legs.knot_first[first[r]], legs.knot_last[last[r]] + 1)
        mine = run == r
        assert held[mine] == pytest.approx(np.interp(made[mine], legs.knot_e[k], legs.knot_s[k]), abs=1e-9)
