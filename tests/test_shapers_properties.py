"""Property tests (acceptance 8): random valid frequencies and dampings for every shaper of every
firmware flavour."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ringtune.shaping.analysis import lag, max_accel, residual_vibration, smoothing
from ringtune.shaping.apply import shape_motion
from ringtune.shaping.custom import rrf_custom
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.motion import Motion
from ringtune.shaping.shapers import FLAVORS, available_shapers, get_shaper, is_centred, max_damping

PAIRS = [(f, n) for f in FLAVORS for n in available_shapers(f) if n != "custom"]
#: formulas with no time quantisation whose impulses cancel the design mode exactly
EXACT = {("klipper", "zv"), ("klipper", "zvd"), ("klipper", "mzv"), ("klipper-legacy", "zv"),
         ("klipper-legacy", "zvd"), ("klipper-legacy", "mzv"), ("klipper-legacy", "2hump_ei"),
         ("rrf35", "zvd"), ("rrf35", "zvdd"), ("rrf35", "zvddd")}
QUANTISED = {"rrf", "marlin-ftm"}
SETTINGS = settings(max_examples=25, deadline=None, derandomize=True)


def _case(draw_freq, draw_frac, flavor, name):
    z = round(draw_frac * min(max_damping(name, flavor), 0.6), 6)
    return get_shaper(name, draw_freq, z, flavor), z


@pytest.mark.parametrize("flavor,name", PAIRS)
@SETTINGS
@given(freq=st.floats(10.0, 150.0), frac=st.floats(0.0, 1.0), plant=st.floats(0.0, 0.5))
def test_every_shaper_is_a_valid_impulse_train(flavor, name, freq, frac, plant):
    s, z = _case(freq, frac, flavor, name)
    assert s.amplitudes.sum() == pytest.approx(1.0, abs=1e-12)
    assert np.all(s.amplitudes >= -1e-5)
    assert s.times[0] == 0.0 and np.all(np.diff(s.times) > 0)
    assert s.duration <= 2.5 / (freq * np.sqrt(1 - z * z)) + 1e-3
    grid = np.linspace(0.1, 4 * freq, 200)
    r = residual_vibration(s, grid, plant)
    assert np.all((r >= 0) & (r <= 1 + 1e-12))
    if (flavor, name) in EXACT:
        assert residual_vibration(s, [freq], z)[0] < 1e-9
    if name in ("zv", "zvd", "zvdd", "zvddd") or (name == "mzv" and flavor.startswith("klipper")):
        if flavor in ("marlin", "marlin-ftm"):
            return
        # step-clock rounding at most: ω · n · 1/750 kHz (RRF's MZV is reversed: not a ZV shaper)
        assert residual_vibration(s, [freq], z)[0] < 2 * np.pi * freq * s.n_impulses / 750_000 + 1e-9


@pytest.mark.parametrize("flavor,name", [p for p in PAIRS if p[0] not in QUANTISED and p[1] != "none"])
@SETTINGS
@given(freq=st.floats(10.0, 150.0), frac=st.floats(0.0, 1.0), k=st.floats(1.1, 3.0))
def test_times_scale_with_the_period(flavor, name, freq, frac, k):
    s1, z = _case(freq, frac, flavor, name)
    s2 = get_shaper(name, freq * k, z, flavor)
    np.testing.assert_allclose(s2.times * k, s1.times, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(s2.amplitudes, s1.amplitudes, rtol=1e-12)
    assert smoothing(s2) < smoothing(s1)


@pytest.mark.parametrize("flavor,name", PAIRS)
@settings(max_examples=10, deadline=None, derandomize=True)
@given(freq=st.floats(15.0, 120.0), frac=st.floats(0.0, 1.0), seed=st.integers(0, 2**32 - 1))
def test_shaping_keeps_the_end_and_lags_as_predicted(flavor, name, freq, frac, seed):
    s, _ = _case(freq, frac, flavor, name)
    rng = np.random.default_rng(seed)
    n = 12
    t = np.concatenate([[0.0], np.cumsum(rng.uniform(0.005, 0.04, n))])
    a = rng.uniform(-3000, 3000, (n, 4))
    accel_part = Motion.from_constant_accel(t, a)
    v_end = accel_part.end_state()[1][-1]
    cruise = Motion(np.array([t[-1], t[-1] + 0.6]), accel_part.end_position[None, :], v_end[None, :],
                    np.zeros((1, 4)))
    motion = Motion.concatenate([accel_part, cruise])
    centred = is_centred(flavor)
    shaped = shape_motion(motion, {"x": s, "y": s}, centred)
    np.testing.assert_allclose(shaped.end_position, motion.end_position, atol=1e-9)
    probe = np.array([t[-1] + 0.3])           # cruise, the whole (≤ 0.25 s) shaper away from both ends
    measured = motion.position(probe)[0, :2] - shaped.position(probe)[0, :2]
    np.testing.assert_allclose(measured, v_end[:2] * lag(s, centred), atol=1e-9)


@pytest.mark.parametrize("name", ["zv", "mzv", "ei", "2hump_ei", "3hump_ei"])
@SETTINGS
@given(freq=st.floats(10.0, 150.0), frac=st.floats(0.0, 1.0), accel=st.floats(100, 20000), scv=st.floats(0, 20))
def test_smoothing_grows_with_accel_and_max_accel_is_its_boundary(name, freq, frac, accel, scv):
    s, _ = _case(freq, frac, "klipper", name)
    assert smoothing(s, accel * 1.5, scv) > smoothing(s, accel, scv) > 0
    m = max_accel(s, scv)
    if m > 0:
        assert smoothing(s, m, scv) <= 0.12 < smoothing(s, m * 1.001 + 1e-6, scv)


@SETTINGS
@given(h=st.lists(st.floats(0.0, 0.5), min_size=1, max_size=6), gaps=st.lists(st.floats(1e-4, 0.02), min_size=6,
                                                                                max_size=6),
       freq=st.floats(10, 100), z=st.floats(0, 0.5))
def test_custom_rrf36_accepts_exactly_what_the_firmware_accepts(h, gaps, freq, z):
    t = list(np.cumsum(gaps[: len(h)]))
    valid = len(h) <= 4 and sum(h) < 1
    if valid:
        a, times = rrf_custom(h, t, freq, z, "3.6")
        assert a.sum() == pytest.approx(1.0) and a[-1] > 0
        np.testing.assert_allclose(times[1:], t)
    else:
        with pytest.raises(RingtuneError):
            rrf_custom(h, t, freq, z, "3.6")
