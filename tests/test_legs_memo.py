"""A window is measured on the printer and on each of its variants against one path object: its legs
(envs/path_geometry.legs_of) are made once while that path lives, are those made afresh, and a new
path or class table gets its own."""

from __future__ import annotations

import dataclasses
import gc

import numpy as np

from ringtune.envs import path_geometry
from ringtune.envs.path_geometry import legs_of, nearest_leg, path_legs, vector_from_segment
from ringtune.shaping.motion import Motion


def _square() -> Motion:
    """A 10 mm square at 50 mm/s, constant speed, extruding (p: x, y, z, e)."""
    corners = np.array([[0, 0], [10, 0], [10, 10], [0, 10], [0, 0]], float)
    n = len(corners) - 1
    p = np.zeros((n, 4))
    v = np.zeros((n, 4))
    p[:, :2] = corners[:-1]
    p[:, 3] = np.arange(n) * 0.4
    v[:, :2] = (corners[1:] - corners[:-1]) / 0.2
    v[:, 3] = 2.0
    return Motion(t=np.arange(n + 1) * 0.2, p=p, v=v, a=np.zeros((n, 4)), extruding=np.ones(n, bool),
                  move=np.arange(n))


def _same(a, b) -> bool:
    return all(np.array_equal(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a))


def test_the_same_path_and_classes_get_the_same_legs_as_made_afresh():
    path, classes = _square(), np.array([0, 0, 1, 1])
    legs = legs_of(path, classes)
    assert legs_of(path, classes) is legs
    assert _same(legs, path_legs(path, classes))
    assert list(legs.cls) == [0, 0, 1, 1]
    other = legs_of(path, np.zeros(4, np.int64))          # another class table: its own legs
    assert other is not legs and _same(other, path_legs(path, np.zeros(4, np.int64)))
    copy = dataclasses.replace(path)                       # another path object: its own
    assert legs_of(copy, classes) is not legs


def test_the_legs_go_with_their_path():
    path = _square()
    legs_of(path, np.zeros(4, np.int64))
    key = id(path)
    assert key in path_geometry._LEGS
    del path
    gc.collect()
    assert key not in path_geometry._LEGS


def test_the_nearest_leg_from_the_legs_stored_segments_is_the_pointwise_one():
    legs = legs_of(_square(), np.zeros(4, np.int64))
    rng = np.random.default_rng(0)
    pts = rng.uniform(-2, 12, (200, 2))
    tu = np.linspace(0, 0.8, 200)
    dist, vec, leg = nearest_leg(tu, pts, legs, 0.05)
    for i in range(len(tu)):                               # every leg active within 0.05 s, by hand
        near = [k for k in range(len(legs)) if legs.t_start[k] - 0.05 <= tu[i] <= legs.t_end[k] + 0.05]
        e = [vector_from_segment(pts[i], legs.start[k], legs.end[k]) for k in near]
        d = [float(np.sqrt(x[0] * x[0] + x[1] * x[1])) for x in e]
        j = int(np.argmin(d))
        assert dist[i] == d[j] and leg[i] == near[j] and np.array_equal(vec[i], e[j])
