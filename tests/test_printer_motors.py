"""Printer description: motors from datasheet constants ([motor], [x.motor], [y.motor]), CoreXZ, and
the pass-through sections [current] / [measurement] (the contract other tools build to)."""

from __future__ import annotations

import math
import tomllib

import pytest

from ringtune.envs.motors import MOTOR_TABLE, lookup_motor
from ringtune.envs.printer import printer_from_dict
from ringtune.envs.motor_model import MotorModel
from ringtune.envs.printer_defaults import DEFAULTS
from ringtune.shaping.errors import RingtuneError

AXES = {"x": {"mass": 0.7, "modes": [{"freq": 60.0, "damping": 0.06}]},
        "y": {"mass": 1.2, "modes": [{"freq": 40.0, "damping": 0.06}]}}


def _printer(**top):
    d = {"x": dict(AXES["x"]), "y": dict(AXES["y"])}
    for k, v in top.items():
        if k in ("x_motor", "y_motor"):
            d[k[0]]["motor"] = v
        else:
            d[k] = v
    return printer_from_dict(d)


def test_named_motor_takes_the_tables_constants_and_explicit_ones_win():
    p = _printer(motor={"name": "LDO-42STH48-2504AC", "run_current": 1.2, "voltage": 24,
                        "rotation_distance": 40})
    mo = p.motor_for("x")
    ref = MOTOR_TABLE["ldo-42sth48-2504ac"]
    assert (mo.holding_torque, mo.rated_current, mo.resistance, mo.inductance, mo.steps_per_revolution) == \
        (ref.holding_torque, ref.rated_current, ref.resistance, ref.inductance, ref.steps_per_revolution)
    assert p.motor_for("y") is p.motor
    q = _printer(motor={"name": "ldo-42sth48-2504ac", "inductance": 0.003, "run_current": 1.2})
    assert q.motor.inductance == 0.003 and q.motor.resistance == ref.resistance
    # a larger inductance can only lower the force at speed
    assert q.motor.max_force(800.0) < p.motor.max_force(800.0)


def test_standstill_force_is_the_holding_torque_scaled_by_current_over_the_pulley_radius():
    """Independent of the stepper module: T_h·I_run/I_r at the belt, r = rotation_distance/2π."""
    p = _printer(motor={"name": "ldo-42sth40-1684ac", "run_current": 0.9, "rotation_distance": 40})
    r = 40e-3 / (2 * math.pi)
    assert p.motor.force == pytest.approx(0.45 * 0.9 / 1.68 / r, rel=1e-9)
    assert float(p.motor.max_force(0.0)) == pytest.approx(p.motor.force)
    # the rotor's magnetic spring uses the same holding force over λ = 4 full steps = 0.8 mm of belt
    assert p.motor.electrical_cycle == pytest.approx(4 * 40 / 200)
    assert p.motor.magnetic_stiffness == pytest.approx(p.motor.force * 2 * math.pi / 0.8e-3)


def test_per_axis_motors_inherit_the_drive_and_replace_the_motor():
    p = _printer(motor={"name": "ldo-42sth40-1684ac", "voltage": 24, "run_current": 1.0},
                 x_motor={"run_current": 0.8},
                 y_motor={"name": "ldo-42sth48-2504ac"})
    mx, my = p.motor_for("x"), p.motor_for("y")
    assert mx.name == "ldo-42sth40-1684ac" and mx.run_current == 0.8 and mx.voltage == 24
    assert my.name == "ldo-42sth48-2504ac" and my.run_current == 1.0 and my.holding_torque == 0.55
    # an axis in the old form replaces a named base motor
    q = _printer(motor={"name": "ldo-42sth40-1684ac"}, y_motor={"force": 20.0, "corner_speed": 100.0})
    assert not q.motor_for("y").has_datasheet and q.motor_for("y").force == 20.0


def test_old_form_behaves_as_before():
    p = _printer(motor={"force": 25.0, "corner_speed": 120.0})
    mo = p.motor_for("x")
    assert not mo.has_datasheet and mo.stepper is None
    assert mo.max_force([0.0, 60.0, 240.0]).tolist() == pytest.approx([25.0, 25.0, 12.5])
    assert _printer().motor == MotorModel()


def test_rotation_distance_gives_steps_per_mm_and_must_agree_with_it():
    p = _printer(motor={"force": 30.0, "rotation_distance": 32.0, "microsteps": 16})
    assert p.motor.steps_per_mm == pytest.approx(200 * 16 / 32)
    q = _printer(motor={"name": "wantai-42byghm810", "rotation_distance": 40.0, "microsteps": 32})
    assert q.motor.steps_per_mm == pytest.approx(400 * 32 / 40)           # a 0.9° motor
    with pytest.raises(RingtuneError, match=r"\[motor\]\.steps_per_mm"):
        _printer(motor={"name": "wantai-42byghm810", "rotation_distance": 40.0, "steps_per_mm": 80})


def test_rotor_inertia_is_reflected_through_the_pulley():
    p = _printer(motor={"name": "ldo-42sth48-2504ac", "rotor_inertia": 82e-7, "rotation_distance": 40})
    r = 40e-3 / (2 * math.pi)
    assert p.motor.rotor_mass == pytest.approx(82e-7 / r ** 2)


@pytest.mark.parametrize("motor, key", [
    ({"name": "ldo-42sth48-2504"}, "[motor].name"),
    ({"holding_torque": 0.4, "rated_current": 1.5}, "[motor].resistance"),
    ({"name": "ldo-42sth48-2504ac", "force": 30.0}, "[motor].force"),
    ({"name": "ldo-42sth48-2504ac", "run_current": -1}, "[motor].run_current"),
    ({"name": "ldo-42sth48-2504ac", "steps_per_revolution": 201}, "[motor].steps_per_revolution"),
    ({"bogus": 1}, "[motor]"),
])
def test_bad_motor_tables_name_the_key(motor, key):
    with pytest.raises(RingtuneError) as e:
        _printer(motor=motor)
    assert key in str(e.value)


def test_unknown_name_suggests_the_closest_and_accepts_full_constants():
    with pytest.raises(RingtuneError, match="ldo-42sth48-2504ac"):
        _printer(motor={"name": "ldo-42sth48-2504"})
    p = _printer(motor={"name": "my-motor", "holding_torque": 0.4, "rated_current": 1.5,
                        "resistance": 2.0, "inductance": 0.003})
    assert p.motor.name == "my-motor" and p.motor.has_datasheet
    assert lookup_motor("my-motor") is None


def test_assumed_drive_values_are_said():
    p = _printer(motor={"name": "ldo-42sth48-2504ac"})
    text = " ".join(p.motor.assumed)
    assert "run_current" in text and "voltage" in text and "rotation_distance" in text
    assert p.motor.run_current is None                          # not invented in the description
    assert p.motor.stepper.run_current == pytest.approx(2.5 / math.sqrt(2))
    assert "# run_current" in p.to_toml()


def test_round_trip_with_motors_current_and_measurement():
    d = {"name": "sw", "kinematics": "corexz", "print_mass": 0.3, "limits": {"accel": 4000},
         "x": {**AXES["x"], "motor": {"run_current": 0.9}},
         "y": {**AXES["y"], "motor": {"name": "ldo-42sth48-2504ac", "run_current": 1.5,
                                      "rotation_distance": 40}},
         "motor": {"name": "ldo-42sth40-1684ac", "voltage": 24},
         "current": {"source": "printer.cfg", "shaper_x": "mzv", "freq_x": 55.2, "damping_x": 0.1,
                     "shaper_y": "ei", "freq_y": 38.0, "accel": 3000, "firmware": "klipper"},
         "measurement": {"source": "accelerometer",
                         "files": [{"name": "x.csv", "sha256": "ab12", "axis": "x"},
                                   {"name": "y.csv", "sha256": "cd34", "axis": "y"}],
                         "klipper": {"shaper_x": "mzv", "freq_x": 55.0, "shaper_y": "ei", "freq_y": 38.2,
                                     "max_accel": 5000, "version": "v0.12.0"}}}
    p = printer_from_dict(d)
    assert p.current == d["current"] and p.measurement == d["measurement"]
    back = tomllib.loads(p.to_toml())
    assert back["current"] == d["current"] and back["measurement"] == d["measurement"]
    assert printer_from_dict(back) == p
    assert printer_from_dict(back).motor_for("y").max_force(700.0) == pytest.approx(p.motor_for("y").max_force(700.0))


def test_passthrough_sections_are_type_checked():
    with pytest.raises(RingtuneError, match=r"\[current\]\.freq_x"):
        _printer(current={"freq_x": "fast"})
    with pytest.raises(RingtuneError, match=r"\[measurement\]\.files"):
        _printer(measurement={"files": "x.csv"})
    assert _printer().current == {} and _printer().measurement == {}


def test_corexz_is_a_bed_slinger_in_y_and_drives_x_with_two_motors():
    p = printer_from_dict({"kinematics": "corexz", "print_mass": 0.4, **AXES})
    assert p.moving_mass("y") == pytest.approx(1.2 + 0.4) and p.moving_mass("x") == 0.7
    # Y modes lowered by the print at unchanged stiffness: f·sqrt(m/(m + print))
    assert p.effective_modes("y")[0].freq == pytest.approx(40.0 * math.sqrt(1.2 / 1.6))
    assert p.effective_modes("x")[0].freq == 60.0
    names = [(n, d) for n, _m, d in p.drive_motors()]
    assert names == [("a", (1.0, 0.0)), ("b", (1.0, 0.0)), ("y", (0.0, 1.0))]
    with pytest.raises(RingtuneError, match="belts"):
        printer_from_dict({"kinematics": "corexz", "belts": {"mismatch": 0.1}, **AXES})
    assert DEFAULTS["print_mass"] == 0.0


_FORMS = [None, {"force": 22.0, "corner_speed": 90.0}, {"name": "ldo-42sth48-2504ac"},
          {"name": "wantai-42byghm810", "run_current": 1.1, "rotation_distance": 32.0, "microsteps": 32},
          {"holding_torque": 0.4, "rated_current": 1.5, "resistance": 2.0, "inductance": 0.003,
           "voltage": 12.0},
          {"run_current": 0.7}, {"name": "ldo-42sth40-1684ac", "inductance": 0.005, "rotor_inertia": 5.4e-6}]


@pytest.mark.parametrize("base", range(len(_FORMS)))
@pytest.mark.parametrize("kin", ["cartesian", "corexy", "corexz"])
def test_every_combination_of_motor_forms_round_trips(base, kin):
    for xi in range(len(_FORMS)):
        yi = (xi + base + 1) % len(_FORMS)
        d = {"kinematics": kin, "x": dict(AXES["x"]), "y": dict(AXES["y"])}
        if _FORMS[base] is not None:
            d["motor"] = dict(_FORMS[base])
        for ax, i in (("x", xi), ("y", yi)):
            if _FORMS[i] is not None:
                d[ax]["motor"] = dict(_FORMS[i])
        p = printer_from_dict(d)
        q = printer_from_dict(tomllib.loads(p.to_toml()))
        assert q == p, (base, xi, yi)
        for ax in ("x", "y"):
            assert q.motor_for(ax).max_force(900.0) == pytest.approx(p.motor_for(ax).max_force(900.0))
