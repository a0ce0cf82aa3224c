"""Marlin classic step-domain ZV (acceptance 7): each step split into factor1/factor2 echoes with
an integer accumulator agrees with the continuous ZV of the same motion within one microstep."""

from __future__ import annotations

import numpy as np
import pytest

from ringtune.shaping.apply import shape_motion
from ringtune.shaping.marlin_steps import marlin_zv_steps, step_position, steps_from_motion
from ringtune.shaping.motion import Motion
from ringtune.shaping.shaper_formulas import marlin_factors
from ringtune.shaping.shapers import get_shaper

SPM = 80.0  # steps per mm (16 microsteps, GT2 belt, 20-tooth pulley)


def back_and_forth(seed: int, n_moves: int = 25, accel: float = 3000.0) -> Motion:
    """Trapezoid moves in random directions, with pauses: direction reversals included."""
    rng = np.random.default_rng(seed)
    t, a = [0.0], []
    for _ in range(n_moves):
        ta, tc, s = rng.uniform(0.004, 0.03), rng.uniform(0.0, 0.05), rng.choice([-1.0, 1.0])
        for dur, acc in ((ta, s * accel), (tc, 0.0), (ta, -s * accel), (rng.uniform(0.0, 0.02), 0.0)):
            t.append(t[-1] + dur)
            a.append([acc, 0, 0, 0])
    return Motion.from_constant_accel(np.array(t), np.array(a), p0=[0.3, 0, 0, 0])


def reference_isr(times, dirs, freq, damping, hysteresis=0):
    """Straightforward event-by-event model of Marlin's PULSE_PREP_SHAPING (firmware.md §2.1 and
    seeds/002): de += ±factor; step forward at de >= 64+H (de -= 128), back at de <= -(64+H)."""
    f1, f2 = marlin_factors(damping)
    events = sorted([(t, 0, d * f1) for t, d in zip(times, dirs)] +
                    [(t + 0.5 / freq, 1, d * f2) for t, d in zip(times, dirs)])
    de, out_t, out_d = 0, [], []
    for t, _, w in events:
        if w == 0:
            continue
        de += w
        if de >= 64 + hysteresis:
            de -= 128
            out_t.append(t)
            out_d.append(1)
        elif de <= -(64 + hysteresis):
            de += 128
            out_t.append(t)
            out_d.append(-1)
    return np.array(out_t), np.array(out_d)


def test_unshaped_steps_are_exact():
    m = back_and_forth(1)
    st, sd = steps_from_motion(m, "x", SPM)
    times = np.linspace(-0.01, m.t[-1] + 0.01, 100_001)
    u = (m.position(times)[:, 0] - 0.3) * SPM
    assert np.abs(step_position(st, sd, times) - u).max() <= 0.5 + 1e-9
    assert sd.sum() == round((m.end_position[0] - 0.3) * SPM)
    assert np.all(np.diff(st) >= 0)


@pytest.mark.parametrize("hysteresis", [0, 64])
@pytest.mark.parametrize("damping", [0.0, 0.15, 0.4])
def test_vectorised_isr_matches_event_by_event_model(damping, hysteresis):
    st, sd = steps_from_motion(back_and_forth(2, 12), "x", SPM)
    got_t, got_d = marlin_zv_steps(st, sd, 37.0, damping, hysteresis=hysteresis)
    ref_t, ref_d = reference_isr(st, sd, 37.0, damping, hysteresis)
    np.testing.assert_array_equal(got_d, ref_d)
    np.testing.assert_allclose(got_t, ref_t)


@pytest.mark.parametrize("seed,freq,damping", [(3, 35.0, 0.0), (4, 35.0, 0.1), (5, 52.0, 0.15), (6, 23.0, 0.3)])
def test_step_domain_zv_agrees_with_continuous_zv_within_one_microstep(seed, freq, damping):
    """Bound: unshaped steps are within ½ step of the motion, so the weighted echo sum is within ½
    step of the continuous ZV (weights factor/128, delay 1/(2F)); the accumulator adds ≤ ½ more."""
    m = back_and_forth(seed)
    st, sd = steps_from_motion(m, "x", SPM)
    ms, md = marlin_zv_steps(st, sd, freq, damping)
    continuous = shape_motion(m, {"x": get_shaper("zv", freq, damping, "marlin")}, centred=False)
    times = np.linspace(-0.01, m.t[-1] + 0.1, 200_001)
    u = (continuous.position(times)[:, 0] - 0.3) * SPM
    assert np.abs(step_position(ms, md, times) - u).max() <= 1.0 + 1e-9
    assert md.sum() == sd.sum()                                   # every step arrives


def test_tmc_hysteresis_keeps_within_one_and_a_half_steps():
    m = back_and_forth(8)
    st, sd = steps_from_motion(m, "x", SPM)
    ms, md = marlin_zv_steps(st, sd, 40.0, 0.1, hysteresis=64)
    cont = shape_motion(m, {"x": get_shaper("zv", 40.0, 0.1, "marlin")}, centred=False)
    times = np.linspace(0, m.t[-1] + 0.1, 100_001)
    assert np.abs(step_position(ms, md, times) - (cont.position(times)[:, 0] - 0.3) * SPM).max() <= 1.5 + 1e-9


def test_timer_quantised_delay():
    """64:64 weights: the first step goes out at once (de reaches 64), the second main step only
    brings de back to 0, so the second output step is the first echo, one quantised delay later."""
    st = np.array([0.0, 0.001])
    sd = np.array([1, 1])
    t, d = marlin_zv_steps(st, sd, 33.0, 0.0, timer_rate=2e6)
    assert d.tolist() == [1, 1]
    assert t[0] == 0.0
    assert t[1] == pytest.approx(np.floor(1e6 / 33.0) / 2e6, abs=1e-15)   # (STEPPER_TIMER_RATE/2)/F ticks


def test_segment_boundaries_on_half_step_levels_neither_drop_nor_duplicate_steps():
    """1000 segments of exactly half a step each: every boundary sits on a step level (up to
    floating-point rounding of the accumulated positions)."""
    n = 1000
    dt = (0.5 / SPM) / 10.0                     # half a step at 10 mm/s
    t = np.arange(n + 1) * dt
    v = np.full((n, 4), 0.0)
    v[:, 0] = 10.0
    p = np.zeros((n, 4))
    p[:, 0] = np.cumsum(np.full(n, 10.0 * dt)) - 10.0 * dt
    m = Motion(t, p, v, np.zeros((n, 4)))
    st, sd = steps_from_motion(m, "x", SPM)
    assert sd.sum() == n // 2 and np.all(sd == 1)
    probe = np.linspace(0, t[-1], 20_001)
    assert np.abs(step_position(st, sd, probe) - m.position(probe)[:, 0] * SPM).max() <= 0.5 + 1e-6
