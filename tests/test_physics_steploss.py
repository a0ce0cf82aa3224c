"""Acceptance 4: step loss appears exactly when the demanded motor force exceeds the force the
motor has at that speed, and input shaping raises the acceleration at which it first appears
(it removes the doubling of head acceleration that an abrupt acceleration change causes)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from ringtune.envs.printer import printer_from_dict
from ringtune.envs.sim import simulate, simulate_batch
from ringtune.shaping.apply import shape_motion
from ringtune.shaping.motion import Motion
from ringtune.shaping.shapers import get_shaper

F, Z, MASS = 40.0, 0.05, 0.5
MOTOR = {"force": 10.0, "corner_speed": 100.0, "rotor_mass": 0.1, "friction": 0.5}
V0, HOLD = 150.0, 0.08


def _printer():
    return printer_from_dict({"x": {"mass": MASS, "modes": [{"freq": F, "damping": Z}]},
                              "y": {"modes": [{"freq": 30.0, "damping": Z}]}, "motor": MOTOR})


def _motion(a, hold=HOLD):
    """Cruise at V0 (already above the corner speed), then an abrupt acceleration a, held."""
    return Motion.from_constant_accel(np.array([0.0, 0.01, 0.01 + hold]),
                                      np.array([[0.0, 0.0], [a, 0.0]]), v0=[V0, 0.0])


def _analytic_ratio(a, t):
    """Demanded / available force after the step, from the closed-form head acceleration
    a[1 − e^{−ζωt}(cos ω_d t − ζ/√(1−ζ²) sin ω_d t)] — independent of the simulator."""
    w = 2 * math.pi * F
    wd = w * math.sqrt(1 - Z * Z)
    head = a * (1 - np.exp(-Z * w * t) * (np.cos(wd * t) - Z / math.sqrt(1 - Z * Z) * np.sin(wd * t)))
    demand = (MASS * head + MOTOR["rotor_mass"] * a) * 1e-3 + MOTOR["friction"]
    speed = V0 + a * t
    have = MOTOR["force"] * np.minimum(1.0, MOTOR["corner_speed"] / speed)
    return demand / have


TT = np.linspace(0.0, HOLD, 80001)


def _threshold():
    a_star = brentq(lambda a: _analytic_ratio(a, TT).max() - 1.0, 100.0, 50000.0, xtol=1e-6)
    onset = TT[np.argmax(_analytic_ratio(a_star * 1.01, TT) > 1.0)]
    return a_star, onset


@pytest.mark.parametrize("backend", ["mujoco", "lti"])
def test_step_loss_exactly_at_the_motor_limit(backend):
    a_star, onset = _threshold()
    p = _printer()
    below, above = (simulate(p, _motion(a_star * k), backend=backend) for k in (0.99, 1.01))
    assert not below.step_loss and below.force_ratio < 1.0
    assert above.step_loss
    assert abs(above.step_loss_time - (0.01 + onset)) < 1.5e-3
    # the demanded force is the physics, not a fudge: at steady acceleration (ringing settled) it
    # is (moving mass + rotor)·a + friction
    steady = simulate(p, _motion(500.0, hold=0.6), backend=backend, tail=0.0)
    late = (steady.t > 0.6) & (steady.t < 0.6 + 0.009)
    np.testing.assert_allclose(steady.motor_force[late, 0], (MASS + MOTOR["rotor_mass"]) * 0.5 + 0.5, rtol=0.02)
    # the available force falls with speed above the corner speed
    np.testing.assert_allclose(steady.motor_force_max[late, 0],
                               MOTOR["force"] * MOTOR["corner_speed"] / (V0 + 500.0 * (steady.t[late] - 0.01)))


def test_shaping_raises_the_acceleration_where_step_loss_appears():
    """Below the corner speed the motor's force is flat, so the limit is the peak force: unshaped it
    carries the doubled head acceleration, ZV-shaped only the commanded one."""
    motor = {"force": 3.0, "corner_speed": 300.0, "rotor_mass": 0.1, "friction": 0.5}
    p = printer_from_dict({"x": {"mass": MASS, "modes": [{"freq": F, "damping": Z}]},
                           "y": {"modes": [{"freq": 30.0, "damping": Z}]}, "motor": motor})
    v0, hold = 20.0, 0.03
    zv = get_shaper("zv", F, Z, flavor="klipper")
    # analytic thresholds: (M·peak head accel + rotor·a)/1000 + friction = force
    peak = 1 + math.exp(-Z * math.pi / math.sqrt(1 - Z * Z))
    a_raw = (motor["force"] - motor["friction"]) * 1e3 / (MASS * peak + motor["rotor_mass"])
    a_zv = (motor["force"] - motor["friction"]) * 1e3 / (MASS + motor["rotor_mass"])
    accels = a_raw * np.geomspace(0.5, 3.0, 40)
    # shape a motion that has been cruising for a while and cut the window: the shaped command
    # then starts cruising too, as it would in the middle of a job
    longer = [Motion.from_constant_accel(np.array([-0.2, 0.01, 0.01 + hold]),
                                         np.array([[0.0, 0.0], [a, 0.0]]), v0=[v0, 0.0]) for a in accels]
    raw = [m.window(0.0, 0.01 + hold) for m in longer]
    shaped = [shape_motion(m, {"x": zv, "y": None}, centred=False).window(0.0, 0.01 + hold) for m in longer]
    sims = simulate_batch(p, raw + shaped)
    # only the part before the held acceleration ends (the shaped copies stop at different times)
    lost = [bool(np.any(np.abs(s.motor_force[s.t < 0.01 + hold - 0.001, 0])
                        > s.motor_force_max[s.t < 0.01 + hold - 0.001, 0])) for s in sims]
    first_raw = accels[lost[:40].index(True)]
    first_shaped = accels[lost[40:].index(True)]
    step = accels[1] / accels[0]
    assert a_raw <= first_raw <= a_raw * step * 1.01
    assert a_zv <= first_shaped <= a_zv * step * 1.01
    assert first_shaped > 1.5 * first_raw
    # step loss is monotonic in acceleration (no spurious flags)
    for part in (lost[:40], lost[40:]):
        k = part.index(True)
        assert all(part[k:]) and not any(part[:k])
