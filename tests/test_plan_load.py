"""The motors' load over every move of a job (``envs/plan_load.py``), against Newton's law worked by
hand for one move, against the direction scan of ``motor_bound.motor_accel_limit``, and in what
``tune`` judges: a job whose fastest travel no quality window holds."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ringtune.agents.tune.motor_bound import motor_accel_limit
from ringtune.envs.evaluate import evaluate_many
from ringtune.envs.plan_load import plan_load, segment_loads
from ringtune.envs.printer import load_printer, printer_from_dict
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.motion import Motion


def trapezoid(direction, accel: float, top: float, cruise_s: float = 0.2) -> Motion:
    """One straight move along ``direction`` (unit, xy): accelerate at ``accel`` (mm/s²) to ``top``
    (mm/s), cruise ``cruise_s``, decelerate to rest."""
    u = np.asarray(direction, float) / np.linalg.norm(direction)
    ta = top / accel
    t = np.array([0.0, ta, ta + cruise_s, 2 * ta + cruise_s])
    v = np.zeros((3, 4))
    a = np.zeros((3, 4))
    v[1, :2] = v[2, :2] = top * u
    a[0, :2], a[2, :2] = accel * u, -accel * u
    p = np.zeros((3, 4))
    p[1, :2] = 0.5 * accel * ta ** 2 * u
    p[2, :2] = p[1, :2] + top * cruise_s * u
    return Motion(t, p, v, a, move=np.zeros(3, int))


def corexy():
    return printer_from_dict({
        "kinematics": "corexy", "print_mass": 0.0,
        "motor": {"name": "ldo-42sth48-2504ac", "run_current": 1.2, "voltage": 24, "rotation_distance": 40},
        "x": {"mass": 0.4, "modes": [{"freq": 60.0, "damping": 0.1}]},
        "y": {"mass": 0.8, "modes": [{"freq": 45.0, "damping": 0.1}]}})


def test_a_cartesian_y_move_loads_the_y_motor_as_newton_says():
    p = load_printer(None)
    mo = p.motor_for("y")
    accel, top = 6000.0, 150.0
    got = plan_load(p, trapezoid((0, 1), accel, top))
    by_hand = ((p.moving_mass("y") + mo.rotor_mass) * accel * 1e-3 + mo.friction) / float(mo.max_force(top))
    assert got.motor == "y" and got.load == pytest.approx(by_hand, rel=1e-12)
    # the cruise asks only friction; at rest before the move, nothing
    seg = segment_loads(p, trapezoid((0, 1), accel, top))
    assert seg[1] == pytest.approx(mo.friction / float(mo.max_force(top)), rel=1e-12)


def test_a_corexy_diagonal_turns_one_motor_at_root_two_the_speed():
    """Along (1, 1)/√2 only motor A turns, at √2 × the head speed; it carries half of each axis's
    force (the drive's inverse: A = (F_x + F_y)/2) plus its rotor's share; B carries
    (F_x − F_y)/2 and its friction, at rest."""
    p = corexy()
    mo = p.motor_for("x")
    accel, top = 5000.0, 200.0
    ax = ay = accel / math.sqrt(2)
    f_a = (0.5 * p.moving_mass("x") * ax + 0.5 * p.moving_mass("y") * ay + mo.rotor_mass * (ax + ay)) * 1e-3
    load_a = (f_a + mo.friction) / float(mo.max_force(math.sqrt(2) * top))
    f_b = abs(0.5 * p.moving_mass("x") * ax - 0.5 * p.moving_mass("y") * ay) * 1e-3
    load_b = (f_b + mo.friction) / float(mo.max_force(0.0))
    got = plan_load(p, trapezoid((1, 1), accel, top))
    assert got.motor == "a" and got.load == pytest.approx(max(load_a, load_b), rel=1e-12)
    assert load_a > load_b


@pytest.mark.parametrize("kind", ["cartesian", "corexy"])
def test_at_the_direction_scans_bound_the_worst_move_keeps_exactly_the_reserve(kind):
    """``motor_accel_limit`` scans directions for the acceleration at which the weakest motor keeps
    the reserve at a speed; a move in each scanned direction reaching that speed at that
    acceleration loads its motor at most 1 − reserve, and the worst direction exactly so."""
    p = load_printer(None) if kind == "cartesian" else corexy()
    top, reserve = 180.0, 0.2
    accel, _who = motor_accel_limit(p, top, reserve=reserve)
    loads = [plan_load(p, trapezoid((math.cos(th), math.sin(th)), accel, top)).load
             for th in np.linspace(0.0, math.pi, 181)]
    assert max(loads) == pytest.approx(1.0 - reserve, rel=1e-9)


def test_the_judged_motor_load_holds_the_fastest_travel_no_window_holds():
    """A square wall printed slowly, then one long fast travel along Y: the quality windows hold the
    wall's corners, not the travel; the judged motor load is the travel's, as Newton gives it for
    the bed's mass at the travel's speed, and it is over the reserve where the windows' is not."""
    p = load_printer(None)
    travel = 250.0
    wall = "\n".join(f"G1 X{x} Y{y} E{e} F1800" for x, y, e in
                     ((120, 100, 1), (120, 120, 2), (100, 120, 3), (100, 100, 4)))
    job = f"G28\nG90\nM82\nG1 X100 Y100 F6000\n;TYPE:External perimeter\n{wall}\n;TYPE:Travel\nG0 X100 Y10 F{travel * 60:.0f}\n"
    accel = 12000.0
    m = evaluate_many([TuneConfig(accel=accel)], p, job)[0]
    mo = p.motor_for("y")
    by_hand = ((p.moving_mass("y") + mo.rotor_mass) * accel * 1e-3 + mo.friction) / float(mo.max_force(travel))
    windows = max(w["motor_load"] for w in m.details["windows"])
    assert m.details["plan_load"]["motor"] == "y"
    assert m.motor_load == pytest.approx(by_hand, rel=1e-9)
    assert windows < 0.8 < m.motor_load
