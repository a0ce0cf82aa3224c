"""Shaping motion: the seeds/002 worked example (acceptance 5), final position and lag
(acceptance 6), exactness against direct superposition, and the fast sampled shaper."""

from __future__ import annotations

import numpy as np
import pytest

from ringtune.shaping.analysis import lag
from ringtune.shaping.apply import sample_taps, shape_motion, shape_samples
from ringtune.shaping.motion import Motion
from ringtune.shaping.shapers import FLAVORS, Shaper, available_shapers, get_shaper, is_centred


def constant_velocity(segments, p0=0.0) -> Motion:
    """Motion of constant-velocity segments [(duration s, speed mm/s)] on x; velocity may step."""
    t = np.concatenate([[0.0], np.cumsum([d for d, _ in segments])])
    v = np.array([[s, 0, 0, 0] for _, s in segments], float)
    p = np.zeros_like(v)
    p[:, 0] = p0 + np.concatenate([[0.0], np.cumsum([d * s for d, s in segments])[:-1]])
    return Motion(t, p, v, np.zeros_like(v))


def random_motion(rng, n=120, accel=4000.0) -> Motion:
    t = np.concatenate([[0.0], np.cumsum(rng.uniform(0.002, 0.05, n))])
    a = rng.uniform(-accel, accel, (n, 4))
    return Motion.from_constant_accel(t, a, p0=rng.uniform(-50, 50, 4), v0=rng.uniform(-20, 20, 4))


def direct(motion, shaper, centred, times, col=0):
    shifts = shaper.times - (shaper.centre_delay if centred else 0.0)
    return sum(a * motion.position(times - s)[:, col] for a, s in zip(shaper.amplitudes, shifts))


def test_seed_002_worked_example():
    """0 → 2 mm at 2 mm/s, ZV with a 0.5 s resonant period (f = 2 Hz, undamped): 1 mm/s for
    0.25 s, 2 mm/s for 0.75 s, 1 mm/s for 0.25 s (causal, as Marlin applies it)."""
    move = constant_velocity([(1.0, 2.0)])
    zv = get_shaper("zv", 2.0, 0.0, "klipper")
    assert zv.amplitudes.tolist() == [0.5, 0.5] and zv.times[1] == pytest.approx(0.25)
    s = shape_motion(move, {"x": zv}, centred=False)
    np.testing.assert_allclose(s.t, [0.0, 0.25, 1.0, 1.25])
    np.testing.assert_allclose(s.v[:, 0], [1.0, 2.0, 1.0])
    np.testing.assert_allclose(s.a[:, 0], 0.0)
    np.testing.assert_allclose(s.end_position[0], 2.0)
    # the same with Marlin's own ZV (damping 0 -> factors 64:64, delay 1/(2F))
    m = shape_motion(move, {"x": get_shaper("zv", 2.0, 0.0, "marlin")}, centred=False)
    np.testing.assert_allclose(m.v[:, 0], [1.0, 2.0, 1.0])
    # centred (Klipper): same profile, 0.125 s earlier
    c = shape_motion(move, {"x": zv}, centred=True)
    np.testing.assert_allclose(c.t[[0, -1]], [-0.125, 1.125])
    np.testing.assert_allclose(c.velocity(np.array([-0.1, 0.5, 1.1]))[:, 0], [1.0, 2.0, 1.0])


@pytest.mark.parametrize("flavor", FLAVORS)
def test_final_position_and_steady_state_lag(flavor):
    """After the shaper has settled the shaped motion is the commanded one delayed by Σ A_i T_i
    (causal) or by nothing (centred; Marlin FTM: its 1 ms rounding of the centre)."""
    rng = np.random.default_rng(7)
    speed = 30.0
    move = constant_velocity([(0.4, speed), (0.0001, 0.0)], p0=5.0)
    for name in available_shapers(flavor):
        if name == "custom":
            continue
        shaper = get_shaper(name, rng.uniform(25, 70), 0.1, flavor)
        centred = is_centred(flavor)
        s = shape_motion(move, {"x": shaper, "y": shaper}, centred)
        np.testing.assert_allclose(s.end_position, move.end_position, atol=1e-12)
        t = np.array([0.3])                               # well inside the cruise, after the shaper
        measured = (move.position(t)[0, 0] - s.position(t)[0, 0]) / speed
        assert measured == pytest.approx(lag(shaper, centred), abs=1e-12)
        assert abs(measured - (0.0 if centred else shaper.centroid)) <= (5e-4 if flavor == "marlin-ftm" else 1e-12)


def test_shape_motion_is_exact_superposition():
    rng = np.random.default_rng(3)
    motion = random_motion(rng)
    sx = get_shaper("3hump_ei", 41.0, 0.1)
    sy = get_shaper("mzv(n=5,t=1.1)", 29.0, 0.05)
    for centred in (True, False):
        s = shape_motion(motion, {"x": sx, "y": sy}, centred)
        times = np.linspace(motion.t[0] - 0.1, motion.t[-1] + 0.1, 7001)
        np.testing.assert_allclose(s.position(times)[:, 0], direct(motion, sx, centred, times, 0), atol=1e-9)
        np.testing.assert_allclose(s.position(times)[:, 1], direct(motion, sy, centred, times, 1), atol=1e-9)
        np.testing.assert_allclose(s.position(times)[:, 2:], motion.position(times)[:, 2:], atol=1e-9)
        # within each merged segment the stored (p, v, a) continue exactly
        p_end, v_end = s.end_state()
        inner = slice(0, -1)
        np.testing.assert_allclose(p_end[inner], s.p[1:], atol=1e-9)
        # shaped velocity equals the shaped commanded velocity
        vshift = sx.times - (sx.centroid if centred else 0.0)
        mids = 0.5 * (s.t[:-1] + s.t[1:])
        ref_v = sum(a * motion.velocity(mids - d)[:, 0] for a, d in zip(sx.amplitudes, vshift))
        np.testing.assert_allclose(s.velocity(mids)[:, 0], ref_v, atol=1e-9)


def test_breakpoints_are_the_union_of_shifted_boundaries():
    move = constant_velocity([(0.1, 10.0), (0.2, 20.0)])
    sh = Shaper("t", "t", 10, 0, np.array([0.5, 0.3, 0.2]), np.array([0.0, 0.01, 0.05]))
    s = shape_motion(move, {"x": sh}, centred=False)
    expected = np.unique(np.concatenate([move.t + d for d in sh.times]))
    np.testing.assert_allclose(s.t, expected)


def test_no_shaper_is_identity():
    rng = np.random.default_rng(5)
    m = random_motion(rng, 30)
    s = shape_motion(m, {"x": None, "y": get_shaper("none", 40)}, centred=True)
    times = np.linspace(-0.1, m.t[-1] + 0.1, 999)
    np.testing.assert_allclose(s.position(times), m.position(times), atol=1e-12)


def test_extruding_flags_follow_the_commanded_motion():
    m = constant_velocity([(0.1, 10.0), (0.1, 10.0)])
    m.extruding = np.array([True, False])
    s = shape_motion(m, {"x": get_shaper("zv", 40, 0.1)}, centred=False)
    mids = 0.5 * (s.t[:-1] + s.t[1:])
    np.testing.assert_array_equal(s.extruding, mids < 0.1)


@pytest.mark.parametrize("centred", [True, False])
def test_sampled_shaper_agrees_with_exact_within_interpolation_bound(centred):
    rng = np.random.default_rng(11)
    acc = 4000.0
    motion = random_motion(rng, 200, acc)
    rate = 2000.0
    _, x = motion.sample(rate)
    shaper = get_shaper("ei", 43.3, 0.1)
    y = shape_samples(x[:, :2], rate, shaper, centred, block=1000)
    t_end = (len(x) - 1) / rate + motion.t[0]
    _, exact = shape_motion(motion, {"x": shaper, "y": shaper}, centred).sample(rate, motion.t[0], t_end)
    # edge samples differ only where the exact motion moves before t0 / after t_end
    core = slice(int(0.03 * rate), len(x) - int(0.03 * rate))
    bound = acc / rate ** 2 / 8 * 1.0001
    assert np.abs(y[core] - exact[core, :2]).max() <= bound
    # 1-D input and weights that sum to one
    np.testing.assert_allclose(shape_samples(x[:, 0], rate, shaper, centred), y[:, 0])
    assert sample_taps(shaper, rate, centred)[1].sum() == pytest.approx(1.0)


def test_sampled_shaper_on_integer_delays_is_exact_shift():
    x = np.arange(10.0)
    sh = Shaper("t", "t", 1, 0, np.array([0.5, 0.5]), np.array([0.0, 2.0]))
    y = shape_samples(x, 1.0, sh, centred=False)
    np.testing.assert_allclose(y, 0.5 * x + 0.5 * np.concatenate([[0, 0], x[:-2]]))
