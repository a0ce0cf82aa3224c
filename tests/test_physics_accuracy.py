"""Acceptance 1 and 2 of the physics: MuJoCo against the exact solution, residual ringing a/ω²,
and the doubling of head acceleration by an abrupt acceleration change (seeds/002)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ringtune.envs.printer import printer_from_dict
from ringtune.envs.sim import simulate, simulate_batch
from ringtune.shaping.motion import Motion


def one_mode(freq: float, damping: float = 0.05, **extra) -> "Printer":  # noqa: F821
    """One linear mode per axis on a rigid motor ([motor] slip = false): the acceptance is about the
    linear model; the default slip model adds the motor's sinusoidal magnet (test_physics_nonlinear)."""
    d = {"x": {"modes": [{"freq": freq, "damping": damping}]},
         "y": {"modes": [{"freq": 0.8 * freq, "damping": damping}]}, "motor": {"slip": False}}
    d.update(extra)
    return printer_from_dict(d)


def step_response(t, a, freq, z):
    """Closed-form relative deflection q(t), q̇(t) for a commanded acceleration step a at t = 0."""
    w = 2 * math.pi * freq
    wd = w * math.sqrt(1 - z * z)
    e = np.exp(-z * w * t)
    q = -(a / w**2) * (1 - e * (np.cos(wd * t) + z / math.sqrt(1 - z * z) * np.sin(wd * t)))
    qd = -(a / wd) * e * np.sin(wd * t)
    return q, qd


def trapezoids(rng, n=6, scale=(1.0, 0.5)):
    """Random rest-to-rest trapezoid moves with boundaries off any simulation grid."""
    segs, accs = [], []
    for _ in range(n):
        d1, d2 = rng.uniform(0.0031, 0.041), rng.uniform(0.0, 0.05)
        acc = rng.uniform(1000, 6000) * rng.choice([-1, 1])
        segs += [d1, d2, d1, rng.uniform(0.0, 0.03)]
        accs += [acc, 0.0, -acc, 0.0]
    t = np.r_[0.0, np.cumsum(segs)]
    return Motion.from_constant_accel(t, np.array(accs)[:, None] * np.array([scale]))


def rel_rms(x, ref):
    return float(np.sqrt(np.mean((x - ref) ** 2)) / np.sqrt(np.mean(ref**2)))


def test_lti_matches_closed_form_step_response():
    """The oracle itself against the textbook step response, at times between segment boundaries."""
    f, z, a = 63.0, 0.07, 2500.0
    mo = Motion.from_constant_accel(np.array([0.0, 0.3]), np.array([[a, 0.0]]))
    r = simulate(one_mode(f, z), mo, backend="lti", rate=4000, timestep=0.00025)
    q, _ = step_response(r.t, a, f, z)
    np.testing.assert_allclose(r.deviation[:, 0], q, atol=1e-12 + 1e-9 * np.abs(q).max())


@pytest.mark.parametrize("freq", [20.0, 35.0, 60.0, 100.0, 150.0])
def test_mujoco_within_one_percent_of_exact(freq):
    """Acceptance 1: one linear mode 20–150 Hz, nozzle motion within 1 % RMS of the exact solution."""
    rng = np.random.default_rng(int(freq))
    mo = trapezoids(rng)
    p = one_mode(freq, 0.05)
    mj, ex = simulate_batch(p, [mo], tail=0.1)[0], simulate(p, mo, backend="lti", tail=0.1)
    for axis in (0, 1):
        assert rel_rms(mj.deviation[:, axis], ex.deviation[:, axis]) < 0.01
    # nozzle (absolute, relative to the print): error small against the vibration itself
    assert np.sqrt(np.mean((mj.nozzle - ex.nozzle) ** 2)) < 0.01 * np.sqrt(np.mean(ex.deviation**2))
    # and the MuJoCo result follows the closed form of the first step before the second one
    t1 = mo.t[1]
    sel = mj.t < t1
    q, _ = step_response(mj.t[sel], mo.a[0, 0], freq, 0.05)
    assert np.max(np.abs(mj.deviation[sel, 0] - q)) < 0.01 * np.max(np.abs(q)) + 1e-9


@pytest.mark.parametrize("backend", ["mujoco", "lti"])
@pytest.mark.parametrize("freq,z", [(25.0, 0.03), (60.0, 0.1), (120.0, 0.05)])
def test_residual_ringing_after_unshaped_stop(backend, freq, z):
    """Acceptance 2a: after decelerating at a and stopping abruptly, the nozzle rings with amplitude
    a/ω² decaying as exp(−ζωt) (the stop releases the static lag of seeds/002)."""
    a, T = 3000.0, 0.25
    mo = Motion.from_constant_accel(np.array([0.0, T]), np.array([[-a, -0.5 * a]]), v0=[a * T, 0.5 * a * T])
    r = simulate(one_mode(freq, z), mo, backend=backend, tail=0.3, initial="static")
    w = 2 * math.pi * freq
    wd = w * math.sqrt(1 - z * z)
    after = r.t >= T
    tau = r.t[after] - T
    x = r.deviation[after, 0]
    # least-squares fit of a damped cosine with the known mode: amplitude at the stop
    basis = np.exp(-z * w * tau)[:, None] * np.stack([np.cos(wd * tau), np.sin(wd * tau)], axis=1)
    c, *_ = np.linalg.lstsq(basis, x, rcond=None)
    q0 = a / w**2
    assert abs(c[0] - q0) / q0 < 0.03                      # starts from the released lag a/ω²
    amp = math.hypot(*c) * math.sqrt(1 - z * z)            # envelope·√(1−ζ²) = a/ω²
    assert abs(amp - q0) / q0 < 0.03
    # first opposite extreme, half a damped period later: a/ω²·exp(−ζπ/√(1−ζ²))
    k = np.argmin(x[: int(1.5 * math.pi / wd / (r.t[1] - r.t[0]))])
    assert abs(-x[k] - q0 * math.exp(-z * math.pi / math.sqrt(1 - z * z))) / q0 < 0.03


def _accel_step_from_rest(a, v0=0.0, hold=0.2):
    return Motion.from_constant_accel(np.array([0.0, 0.02, 0.02 + hold]), np.array([[0.0, 0.0], [a, 0.0]]),
                                      v0=[v0, 0.0])


@pytest.mark.parametrize("backend", ["mujoco", "lti"])
def test_abrupt_acceleration_change_doubles_head_acceleration(backend):
    """Acceptance 2b: an acceleration step a gives a peak head acceleration a(1 + e^{−ζπ/√(1−ζ²)})
    (≈ 2a for light damping) unshaped, and no overshoot with ZV at the true frequency."""
    from ringtune.shaping.apply import shape_motion
    from ringtune.shaping.shapers import get_shaper

    f, z, a = 40.0, 0.02, 3000.0
    p = one_mode(f, z)
    mo = _accel_step_from_rest(a)
    raw = simulate(p, mo, backend=backend)
    peak = raw.head_accel[:, 0].max()
    expect = a * (1 + math.exp(-z * math.pi / math.sqrt(1 - z * z)))
    assert abs(peak - expect) / expect < 0.01
    assert peak > 1.9 * a
    for centred in (False, True):
        zv = get_shaper("zv", f, z, flavor="klipper")
        shaped = shape_motion(mo, {"x": zv, "y": None}, centred=centred)
        r = simulate(p, shaped, backend=backend)
        # the motion ends moving, so its shaped copies stop at different times: look before that
        held = r.head_accel[r.t < mo.end_time - zv.duration, 0]
        assert held.max() < 1.01 * a
        assert held.max() > 0.99 * a


@pytest.mark.parametrize("freq", [30.0, 110.0])
def test_velocity_jump_is_an_impulse_in_both_backends(freq):
    """A corner taken at junction speed jumps the commanded velocity: both backends ring alike and
    the relative velocity right after the jump is −Δv (momentum)."""
    t = np.array([0.0, 0.0403, 0.1])
    p = np.zeros((2, 4))
    v = np.array([[5.0, 0, 0, 0], [0.0, 5.0, 0, 0]])          # 90° corner at 5 mm/s
    mo = Motion(t, p + np.array([[0, 0, 0, 0], [5.0 * 0.0403, 0, 0, 0]]), v, np.zeros((2, 4)))
    pr = one_mode(freq, 0.05)
    mj, ex = simulate(pr, mo, tail=0.05), simulate(pr, mo, backend="lti", tail=0.05)
    assert rel_rms(mj.deviation, ex.deviation) < 0.01
    w = 2 * math.pi * freq
    wd = w * math.sqrt(1 - 0.05**2)
    # x: free vibration with initial velocity +5 (−Δv) from the jump: amplitude 5/ω_d
    after = ex.t >= t[1]
    assert abs(np.max(np.abs(ex.deviation[after, 0])) / (5.0 / wd) - 1) < 0.1


from hypothesis import example, given, settings, strategies as st  # noqa: E402


@given(freq=st.floats(20.0, 150.0), z=st.floats(0.01, 0.3), seed=st.integers(0, 2**31 - 1))
@example(freq=149.0, z=0.01171875, seed=0)   # 1.08 % at a fixed 0.5 ms step (found by hypothesis)
@example(freq=143.0, z=0.0215, seed=0)
@example(freq=150.0, z=0.01, seed=1)
@settings(max_examples=12, deadline=None)
def test_property_mujoco_tracks_exact_for_any_mode_and_motion(freq, z, seed):
    """Any single mode 20–150 Hz, damping 0.01–0.3, random trapezoid moves: within 1 % RMS.
    Lightly damped high modes ring for many cycles and RK4's phase drift accumulates (1.5 % at
    150 Hz, ζ 0.01 with a fixed 0.5 ms step); the simulator's automatic timestep
    (:func:`ringtune.envs.sim.auto_timestep`) halves the step for them."""
    rng = np.random.default_rng(seed)
    mo = trapezoids(rng, n=3)
    p = one_mode(freq, z)
    mj, ex = simulate(p, mo, tail=0.05), simulate(p, mo, backend="lti", tail=0.05)
    assert rel_rms(mj.deviation, ex.deviation) < 0.01


def test_auto_timestep_keeps_0_5_ms_for_real_printers_and_refines_light_high_modes():
    from ringtune.envs.printer import load_printer
    from ringtune.envs.sim import auto_timestep

    assert auto_timestep(load_printer("ender3")) == 0.0005
    assert auto_timestep(load_printer("voron24")) == 0.0005
    assert auto_timestep(one_mode(150.0, 0.05)) == 0.0005
    assert auto_timestep(one_mode(150.0, 0.01)) == 0.00025
    assert auto_timestep(one_mode(390.0, 0.02)) < 0.0002
