"""CoreXZ and per-axis motors in the simulation: X moves are carried by both A and B (Z still), Y by
its own motor on a bed that carries the print; each motor is judged against its own curve."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ringtune.envs.mujoco_model import linear_system
from ringtune.envs.printer import printer_from_dict
from ringtune.envs.rotor import undamped_frequencies
from ringtune.envs.sim import simulate
from ringtune.shaping.motion import Motion

MX, MY, PRINT = 0.6, 1.0, 0.4


def corexz(slip=False, x_motor=None, y_motor=None):
    d = {"kinematics": "corexz", "print_mass": PRINT,
         "motor": {"name": "ldo-42sth40-1684ac", "run_current": 1.0, "voltage": 24,
                   "rotation_distance": 40, "slip": slip},
         "x": {"mass": MX, "modes": [{"freq": 55.0, "damping": 0.08}]},
         "y": {"mass": MY, "modes": [{"freq": 38.0, "damping": 0.08}]}}
    if x_motor:
        d["x"]["motor"] = x_motor
    if y_motor:
        d["y"]["motor"] = y_motor
    return printer_from_dict(d)


def move(axis, accel=3000.0):
    t = np.array([0.0, 0.03, 0.06, 0.09, 0.25])
    a = np.zeros((4, 2))
    a[0, axis], a[2, axis] = accel, -accel
    return Motion.from_constant_accel(t, a)


def short_move(axis, accel, top_speed):
    """Accelerate to ``top_speed`` (mm/s) and back to rest, then rest."""
    dt = top_speed / accel
    t = np.array([0.0, dt, 2 * dt, 2 * dt + 0.05])
    a = np.zeros((3, 2))
    a[0, axis], a[1, axis] = accel, -accel
    return Motion.from_constant_accel(t, a)


def commanded(mo, res):
    """Commanded (v, a) at the samples, and a mask away from the acceleration switches (where the
    sample's acceleration depends on which side of the switch it is taken)."""
    v, a = mo.velocity(res.t)[:, :2], mo.acceleration(res.t)[:, :2]
    far = np.min(np.abs(res.t[:, None] - np.array([0.0, 0.03, 0.06, 0.09])[None, :]), axis=1) > 1e-3
    return v, a, far


def test_an_x_move_loads_a_and_b_equally_and_a_y_move_only_the_y_motor():
    p = corexz()
    mx_, my_ = move(0), move(1)
    sx = simulate(p, mx_, backend="lti")
    v, a, far = commanded(mx_, sx)
    assert sx.motor_force.shape[1] == 3                                  # A, B, Y
    np.testing.assert_allclose(sx.motor_force[:, 0], sx.motor_force[:, 1], atol=1e-12)
    assert np.max(np.abs(sx.motor_force[:, 2])) == 0.0                  # the bed does not move
    # Newton: A + B carry the X mass's acceleration (the head's, one mode of share 1), each adding
    # its own rotor inertia and friction
    mo = p.motor_for("x")
    extra = mo.rotor_mass * a[:, 0] * 1e-3 + mo.friction * np.sign(v[:, 0])
    belts = sx.motor_force[:, 0] + sx.motor_force[:, 1] - 2 * extra
    np.testing.assert_allclose(belts[far], MX * sx.head_accel[far, 0] * 1e-3, atol=1e-6)
    sy = simulate(p, my_, backend="lti")
    v, a, far = commanded(my_, sy)
    assert np.max(np.abs(sy.motor_force[:, :2])) == 0.0
    mo = p.motor_for("y")
    extra = mo.rotor_mass * a[:, 1] * 1e-3 + mo.friction * np.sign(v[:, 1])
    # the bed carries the print
    np.testing.assert_allclose((sy.motor_force[:, 2] - extra)[far],
                               (MY + PRINT) * sy.head_accel[far, 1] * 1e-3, atol=1e-6)


def test_y_modes_are_lowered_by_the_print_and_x_modes_are_not():
    p = corexz()
    s = linear_system(p)
    f = np.sort(undamped_frequencies(s.K, s.mass)) / (2 * math.pi)
    np.testing.assert_allclose(f, sorted([55.0, 38.0 * math.sqrt(MY / (MY + PRINT))]), rtol=1e-9)


def test_each_motor_is_judged_against_its_own_curve():
    p = corexz(x_motor={"run_current": 0.6}, y_motor={"name": "ldo-42sth48-2504ac", "run_current": 1.5})
    mo = move(0, 8000.0)
    res = simulate(p, mo, backend="lti")
    speed = np.abs(mo.velocity(res.t)[:, 0])
    np.testing.assert_allclose(res.motor_force_max[:, 0], p.motor_for("x").max_force(speed))
    np.testing.assert_allclose(res.motor_force_max[:, 2], p.motor_for("y").max_force(0.0))
    assert p.motor_for("y").force > 1.5 * p.motor_for("x").force


def test_two_motors_on_x_carry_what_one_on_y_cannot():
    """The same mass and acceleration: X shares it over A and B, Y's single motor gets all of it
    (well-damped modes, light rotors, no friction: each motor's demand is its share of m·a)."""
    p = printer_from_dict({"kinematics": "corexz",
                           "motor": {"name": "ldo-42sth40-1684ac", "run_current": 0.25, "rotation_distance": 40,
                                     "rotor_mass": 0.005, "friction": 0.0, "slip": False},
                           "x": {"mass": 1.0, "modes": [{"freq": 55.0, "damping": 0.7}]},
                           "y": {"mass": 1.0, "modes": [{"freq": 55.0, "damping": 0.7}]}})
    f1 = p.motor_for("y").force
    accel = 1.3 * f1 / 1.0 * 1e3                     # mm/s²: 1.3× one motor's force on 1 kg
    sx = simulate(p, move(0, accel), backend="lti")
    sy = simulate(p, move(1, accel), backend="lti")
    assert sy.step_loss and not sx.step_loss
    assert sx.force_ratio == pytest.approx(sy.force_ratio / 2, rel=0.02)
    assert sy.force_ratio > 1.3                     # at least the static demand (plus the transient)


@pytest.mark.parametrize("backend", ["mujoco", "lti"])
def test_slip_model_of_corexz_keeps_the_described_modes(backend):
    p = corexz(slip=True)
    s = linear_system(p)
    assert [r.name for r in s.rotors] == ["a", "b", "y"]
    w = np.sort(undamped_frequencies(s.K, s.mass))[:2] / (2 * math.pi)
    np.testing.assert_allclose(w, sorted([55.0, 38.0 * math.sqrt(MY / (MY + PRINT))]), rtol=1e-8)
    rigid = simulate(corexz(slip=False), move(0), backend="lti")
    got = simulate(p, move(0), backend=backend)
    err = np.sqrt(np.mean((got.deviation - rigid.deviation) ** 2)) / np.sqrt(np.mean(rigid.deviation ** 2))
    assert err < 0.02
    assert not got.step_loss


@pytest.mark.parametrize("kin", ["cartesian", "corexy", "corexz"])
def test_motor_accel_limit_is_where_the_simulated_demand_meets_the_force(kin):
    """A pure move at the limit acceleration, below the corner speed: once the step's transient has
    died out, the simulated demand of the busiest motor equals its force (Newton with each
    kinematics' split, rotor inertia and friction); at 80 % of it no step is lost."""
    d = {"kinematics": kin, "print_mass": 0.2,
         "motor": {"name": "ldo-42sth40-1684ac", "run_current": 1.0, "voltage": 48, "rotation_distance": 40,
                   "slip": False},
         "x": {"mass": 3.0, "modes": [{"freq": 150.0, "damping": 0.9}]},
         "y": {"mass": 4.0, "modes": [{"freq": 150.0, "damping": 0.9}]}}
    p = printer_from_dict(d)
    mo = p.motor_for("x")
    for ax, e in (("x", 0), ("y", 1)):
        m = p.moving_mass(ax)
        f0 = float(mo.max_force(0.0)) - mo.friction
        share = 1.0 if kin == "cartesian" or (kin == "corexz" and ax == "y") else 0.5
        assert p.motor_accel_limit(ax) == pytest.approx(f0 / (share * m + mo.rotor_mass) * 1e3)
        a = float(p.motor_accel_limit(ax))
        top = 0.9 * mo.corner_speed
        res = simulate(p, short_move(e, a, top), backend="lti")
        steady = (res.t > 0.5 * top / a) & (res.t < top / a - 1e-3)
        assert steady.sum() >= 5
        ratio = np.max(np.abs(res.motor_force[steady]) / res.motor_force_max[steady], axis=1)
        np.testing.assert_allclose(ratio, 1.0, atol=0.01)
        assert not simulate(p, short_move(e, 0.8 * a, top), backend="lti").step_loss
    assert p.moving_mass("y") == pytest.approx(4.0 + (0.0 if kin == "corexy" else 0.2))
    # faster: less force, less acceleration
    assert p.motor_accel_limit("x", 3 * mo.corner_speed) < p.motor_accel_limit("x", 0.0)


def test_slip_rotors_carry_each_motors_own_datasheet_constants():
    """Rotor A of a CoreXY on a 0.9° motor, B on a 1.8° one: each rotor's magnetic peak is its
    motor's holding force at the run current, T_h·I_run/I_r / r, and its period 4 full steps of belt."""
    p = printer_from_dict({"kinematics": "corexy",
                           "x": {"mass": 0.6, "modes": [{"freq": 55.0, "damping": 0.08}],
                                 "motor": {"name": "ldo-42sth48-2004mah", "run_current": 1.2,
                                           "rotation_distance": 40, "rotor_inertia": 6.8e-6}},
                           "y": {"mass": 1.0, "modes": [{"freq": 45.0, "damping": 0.08}],
                                 "motor": {"name": "ldo-42sth48-2504ac", "run_current": 1.5,
                                           "rotation_distance": 40, "rotor_inertia": 6.8e-6}},
                           "motor": {"slip": True}})
    s = linear_system(p)
    r = 40e-3 / (2 * math.pi)
    a, b = s.rotors
    assert a.peak == pytest.approx(0.44 * 1.2 / 2.0 / r * 1e3)          # mN
    assert b.peak == pytest.approx(0.55 * 1.5 / 2.5 / r * 1e3)
    assert a.cycle == pytest.approx(4 * 40 / 400) and b.cycle == pytest.approx(4 * 40 / 200)
    assert a.mass == pytest.approx(6.8e-6 / r ** 2) == b.mass
