"""What a job's geometry alone decides is computed once per geometry (shaping/geometry_cache.py):
the same result for the same arrays, a new one for other arrays, read-only results; and the copies
of a job the planner makes for each setting share the arrays, so the frequency limit's wavelengths
and the windows' corners are computed once per job, with the same values as computed afresh."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ringtune.envs.planned_job import resolve_job
from ringtune.envs.printer import load_printer
from ringtune.shaping import freqlimit, geometry_cache, seams, testprints
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.config_plan import plan_with_config


def test_the_same_arrays_get_the_same_result_and_other_arrays_their_own():
    calls = []
    a, b = np.arange(5.0), np.arange(5.0)

    def compute(x):
        calls.append(1)
        return (x * 2.0, (x + 1.0,))

    first = geometry_cache.by_geometry("t", (a,), (), lambda: compute(a))
    again = geometry_cache.by_geometry("t", (a,), (), lambda: compute(a))
    other = geometry_cache.by_geometry("t", (b,), (), lambda: compute(b))
    assert first is again and other is not first and len(calls) == 2
    assert geometry_cache.by_geometry("t", (a,), ("other argument",), lambda: compute(a)) is not first
    with pytest.raises(ValueError):
        first[0][0] = 1.0                      # read-only, nested arrays too
    with pytest.raises(ValueError):
        first[1][0][0] = 1.0


def test_past_its_limit_the_oldest_geometry_is_dropped_and_computed_again():
    geometry_cache._CACHE.clear()
    xs = [np.full(3, float(k)) for k in range(geometry_cache.MAX_ENTRIES + 1)]
    calls = []

    def total(x):
        calls.append(1)
        return float(x.sum())

    assert [geometry_cache.by_geometry("e", (x,), (), lambda x=x: total(x)) for x in xs] == \
        [3.0 * k for k in range(len(xs))]
    assert geometry_cache.by_geometry("e", (xs[-1],), (), lambda: total(xs[-1])) == 3.0 * (len(xs) - 1)
    assert len(calls) == len(xs)                                   # the newest kept
    assert geometry_cache.by_geometry("e", (xs[0],), (), lambda: total(xs[0])) == 0.0
    assert len(calls) == len(xs) + 1                               # the oldest computed again


@pytest.fixture(scope="module")
def part():
    return resolve_job("part")[1]


def test_the_planners_copies_of_a_job_share_one_computation_with_the_values_computed_afresh(part, monkeypatch):
    limits = load_printer(None).limits
    counted = {"wavelengths": 0, "corners": 0, "reversals": 0, "seams": 0}
    for name, mod, fn in (("wavelengths", freqlimit, "_path_wavelengths"), ("corners", testprints, "_corner_moves"),
                          ("reversals", testprints, "_reversals"), ("seams", seams, "_seam_moves")):
        orig = getattr(mod, fn)

        def wrapped(*a, _orig=orig, _name=name, **k):
            counted[_name] += 1
            return _orig(*a, **k)
        monkeypatch.setattr(mod, fn, wrapped)
    geometry_cache._CACHE.clear()
    plans = []
    for accel, hz in ((5000.0, 40.0), (7000.0, 40.0), (9000.0, 55.0)):
        cfg = TuneConfig(firmware="klipper", accel=accel, freq_limit_hz=hz, freq_limit_method="sections",
                         feature_accel={"infill": 2 * accel})
        plans.append(plan_with_config(part, limits, cfg).plan)
        testprints._candidates(plans[-1], 0.25)
        seams.seam_candidates(plans[-1], 0.25)
    # three settings, three copies of the job: one computation of each
    assert counted == {"wavelengths": 1, "corners": 1, "reversals": 1, "seams": 1}
    # the cached values are those computed afresh, on a copy with new arrays
    fresh = dataclasses.replace(part, start=part.start.copy(), end=part.end.copy(), feature=part.feature.copy(),
                                stop_before=part.stop_before.copy())
    assert np.array_equal(freqlimit.path_wavelengths(fresh, "sections"), freqlimit.path_wavelengths(part, "sections"))
    assert counted["wavelengths"] == 2
    moves = dataclasses.replace(plans[0].moves, start=plans[0].moves.start.copy(), end=plans[0].moves.end.copy())
    names = seams.label_classes(plans[0])
    afresh = seams._seam_moves(moves, names)
    cached = geometry_cache.by_geometry("seam-moves", (plans[0].moves.start, plans[0].moves.end, plans[0].moves.feature),
                                        tuple(names.tolist()), lambda: None)
    assert all(np.array_equal(a, b) for a, b in zip(afresh, cached)) and len(afresh[2]) > 100
    assert np.array_equal(testprints._corner_moves(moves), geometry_cache.by_geometry(
        "corners", (plans[0].moves.start, plans[0].moves.end), (), lambda: None))
