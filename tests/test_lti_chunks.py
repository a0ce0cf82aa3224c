"""The exact linear response (envs/lti.py) over many chunks: against an independent stepping of the
state space with the matrix exponential, and in memory proportional to the samples asked."""

from __future__ import annotations

import tracemalloc

import numpy as np
from scipy.linalg import expm

from ringtune.envs.lti import response
from ringtune.envs.mujoco_model import linear_system
from ringtune.envs.printer import load_printer
from ringtune.shaping.motion import Motion


def corner_motion() -> Motion:
    """3 s of piecewise-constant acceleration on x and y with two jumps of velocity (corners taken
    at speed), longer than one chunk of the default printer (about 1.2 s)."""
    t = np.array([0.0, 0.31, 0.7333, 1.5, 2.2071, 2.6, 3.0])
    a = np.array([[3000.0, 0.0], [0.0, -2500.0], [-1200.0, 800.0], [0.0, 0.0], [4000.0, 4000.0], [-900.0, 0.0]])
    v = np.zeros((6, 2))
    for i in range(1, 6):
        v[i] = v[i - 1] + a[i - 1] * (t[i] - t[i - 1])
    v[2] += [-80.0, 60.0]                     # a corner at junction speed
    v[4] = [120.0, 0.0]                       # and another
    pad = np.zeros((6, 2))
    return Motion(t, np.hstack([pad, pad]), np.hstack([v, pad]), np.hstack([a, pad]))


def stepped(sysm, motion: Motion, times: np.ndarray, x0: np.ndarray) -> np.ndarray:
    """[q, q̇] at ``times`` by the matrix exponential of the state space augmented with a held
    acceleration, interval by interval, each velocity jump of the command added as G·Δv."""
    A, G = sysm.state_matrices()
    m = A.shape[0]
    aug = np.zeros((m + 2, m + 2))
    aug[:m, :m], aug[:m, m:] = A, G
    cache: dict = {}

    def prop(dt):
        key = round(dt, 15)
        if key not in cache:
            cache[key] = expm(aug * dt)
        return cache[key]

    bounds = motion.t[(motion.t > times[0]) & (motion.t < times[-1])]
    ev = np.union1d(times, bounds)
    _, v_end = motion.end_state()
    jumps = {float(tb): motion.v[k + 1, :2] - v_end[k, :2] for k, tb in enumerate(motion.t[1:-1])}
    x, out = x0.copy(), {}
    out[ev[0]] = x.copy()
    for a, b in zip(ev[:-1], ev[1:]):
        acc = motion.acceleration(np.array([0.5 * (a + b)]))[0, :2]
        x = (prop(b - a) @ np.concatenate([x, acc]))[:m]
        if float(b) in jumps:
            x = x + G @ jumps[float(b)]
        out[b] = x.copy()
    return np.array([out[t] for t in times])


def test_many_chunks_match_the_matrix_exponential_stepped_interval_by_interval():
    sysm = linear_system(load_printer(None))
    motion = corner_motion()
    times = np.arange(0.0, 3.0 + 1e-9, 1.0 / 5000.0)
    x0 = np.concatenate([np.linspace(-0.02, 0.03, sysm.n), np.linspace(1.0, -2.0, sysm.n)])
    q, qd = response(sysm, motion, times, x0)
    want = stepped(sysm, motion, times, x0)
    scale = np.max(np.abs(want), axis=0)
    assert np.max(np.abs(q - want[:, :sysm.n]) / scale[:sysm.n]) < 1e-8
    assert np.max(np.abs(qd - want[:, sysm.n:]) / scale[sysm.n:]) < 1e-8
    # a later start (its state given) continues the same history
    k = 9001
    q2, qd2 = response(sysm, motion, times[k:], np.concatenate([q[k], qd[k]]))
    assert np.allclose(q2, q[k:], rtol=0, atol=1e-9 * scale[:sysm.n].max())


def test_memory_grows_with_the_samples_asked_not_with_the_complex_history():
    """60 s at 5 kHz: the response's peak allocation within three times its own output (the whole
    complex state of every event time, as before, took about eight)."""
    sysm = linear_system(load_printer(None))
    t = np.arange(0.0, 60.0 + 1e-9, 0.25)
    a = np.tile([[2000.0, -1500.0, 0.0, 0.0], [-2000.0, 1500.0, 0.0, 0.0]], (len(t) // 2, 1))[:len(t) - 1]
    motion = Motion.from_constant_accel(t, a)
    times = np.arange(0.0, 60.0, 1.0 / 5000.0)
    tracemalloc.start()
    try:
        q, qd = response(sysm, motion, times)
        _cur, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    out_bytes = len(times) * 2 * sysm.n * 8
    assert q.shape == (len(times), sysm.n) and np.all(np.isfinite(qd))
    assert peak < 3 * out_bytes
