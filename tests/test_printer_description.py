"""Printer description: TOML loading, validation naming the key, defaults, physical forms."""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from ringtune.envs.printer import embedded_printers, load_printer, printer_from_dict
from ringtune.envs.printer_defaults import DEFAULTS
from ringtune.envs.printer_model import Mode
from ringtune.shaping.errors import RingtuneError


def test_default_is_an_ender3_class_bed_slinger():
    p = load_printer(None)
    assert p.kinematics == "cartesian"
    assert "ender" in p.name.lower()
    assert len(p.x.modes) >= 2 and len(p.y.modes) >= 2
    for ax in (p.x, p.y):
        assert abs(sum(m.share for m in ax.modes) - 1) < 1e-9
        assert all(20 < m.freq < 130 and 0 < m.damping < 0.3 for m in ax.modes)
    assert set(embedded_printers()) >= {"ender3", "voron24"}
    assert load_printer("voron24").kinematics == "corexy"


def test_machine_limits_from_the_description():
    pytest.importorskip("ringtune.shaping.planner")
    lim = load_printer(None).machine_limits()
    assert lim.accel == 3000 and lim.velocity == 300 and lim.square_corner_velocity == 5


def test_minimal_design_md_form_gets_documented_defaults(tmp_path):
    f = tmp_path / "p.toml"
    f.write_text('name = "my-ender3"\nkinematics = "cartesian"\n[limits]\naccel = 3000\nvelocity = 300\n'
                 'square_corner_velocity = 5\n[x]\nmodes = [{ freq = 51.0, damping = 0.06 }, '
                 '{ freq = 95.0, damping = 0.08, share = 0.2 }]\n[y]\nmodes = [{ freq = 46.0, damping = 0.05 }]\n')
    p = load_printer(f)
    assert [m.share for m in p.x.modes] == pytest.approx([0.8, 0.2])
    assert p.y.modes[0].share == 1.0
    assert p.x.mass == DEFAULTS["mass_x"] and p.motor.force == DEFAULTS["motor_force"]
    assert p.print_mass == 0.0


@pytest.mark.parametrize("name", ["ender3", "voron24"])
def test_to_toml_round_trips(name):
    p = load_printer(name)
    assert printer_from_dict(tomllib.loads(p.to_toml())) == p


@given(st.lists(st.tuples(st.floats(15, 200), st.floats(0.0, 0.5), st.floats(0.05, 1.0)),
                min_size=1, max_size=4),
       st.floats(0.0, 2.0), st.sampled_from(["cartesian", "corexy"]))
@settings(max_examples=40, deadline=None)
def test_round_trip_property(modes, print_mass, kin):
    total = sum(s for *_, s in modes)
    x = [{"freq": f, "damping": z, "share": s / total} for f, z, s in modes]
    x[-1].pop("share")                        # the last takes what is left
    d = {"kinematics": kin, "print_mass": print_mass, "x": {"modes": x},
         "y": {"modes": [{"freq": 300.0, "damping": 0.1}]}}
    p = printer_from_dict(d)
    q = printer_from_dict(tomllib.loads(p.to_toml()))
    assert q == p
    assert sum(m.share for m in q.x.modes) == pytest.approx(1.0)


def test_one_mode_from_stiffness():
    p = printer_from_dict({"x": {"mass": 0.5, "stiffness": 50000.0, "damping": 0.04},
                           "y": {"modes": [{"freq": 40}]}})
    assert p.x.modes[0].freq == pytest.approx(math.sqrt(50000 / 0.5) / (2 * math.pi))
    assert p.x.modes[0].damping == 0.04 and p.y.modes[0].damping == DEFAULTS["damping"]


def test_chain_of_masses_and_stiffnesses():
    """Two-mass chain motor–k1–m1–k2–m2 (nozzle m2): frequencies solve
    m1 m2 ω⁴ − (m1 k2 + m2 (k1 + k2)) ω² + k1 k2 = 0; shares give the exact static lag
    (m1 + m2)/k1 + m2/k2 per unit acceleration; modal masses sum to the total."""
    m1, m2, k1, k2 = 0.4, 0.15, 60000.0, 200000.0
    p = printer_from_dict({"x": {"masses": [m1, m2], "stiffnesses": [k1, k2], "damping": 0.05},
                           "y": {"modes": [{"freq": 40}]}})
    w2 = np.sort(np.roots([m1 * m2, -(m1 * k2 + m2 * (k1 + k2)), k1 * k2]).real)
    got = sorted(m.omega**2 for m in p.x.modes)
    np.testing.assert_allclose(got, w2, rtol=1e-9)
    assert p.x.mass == pytest.approx(m1 + m2)
    lag = sum(m.share / m.omega**2 for m in p.x.modes)
    assert lag == pytest.approx((m1 + m2) / k1 + m2 / k2, rel=1e-9)
    assert sum(m.mass_fraction for m in p.x.modes) == pytest.approx(1.0)
    assert sum(m.share for m in p.x.modes) == pytest.approx(1.0)
    # a higher chain mode moves the nozzle against the carriage: negative share, and it round-trips
    assert min(m.share for m in p.x.modes) < 0
    assert printer_from_dict(tomllib.loads(p.to_toml())) == p


@pytest.mark.parametrize("text,key", [
    ('kinematics = "delta"', "kinematics"),
    ('[x]\nmodes = [{ freq = -5 }]', "[x].modes[0].freq"),
    ('[x]\nmodes = [{ damping = 0.1 }]', "[x].modes[0]"),
    ('[x]\nmodes = [{ freq = 40, share = 0.7 }, { freq = 60, share = 0.6 }]', "[x].modes"),
    ('[x]\nmodes = [{ freq = 40, share = 0.7 }]', "[x].modes"),
    ('[x]\nmodes = [{ freq = 40, colour = 1 }]', "[x].modes[0]"),
    ('[y]\nmodes = [{ freq = 40 }]\nmass = "heavy"', "[y].mass"),
    ('[motor]\nforce = 0', "[motor].force"),
    ('[motor]\ntorque = 1', "[motor]"),
    ('[motor]\nslip = "yes"', "[motor].slip"),
    ('[motor]\nmicrosteps = 0', "[motor].microsteps"),
    ('[motor]\nrotor_damping = -0.1', "[motor].rotor_damping"),
    ('[belts]\nmismatch = 0.1', "[belts]"),
    ('kinematics = "corexy"\n[belts]\nstiffness = 1e9', "[belts].stiffness"),
    ('[limits]\naccel = -1', "[limits].accel"),
    ('[limits]\nspeed = 100', "[limits]"),
    ('[limits]\ntravel_x = [235, 0]', "[limits].travel_x"),
    ('[limits]\ntravel_y = [0, 235, 250]', "[limits].travel_y"),
    ('[x]\nmasses = [0.3, 0.1]\nstiffnesses = [1e4]', "[x].stiffnesses"),
    ('[x]\nmodes = []', "[x].modes"),
    ('wheels = 4', "printer.toml"),
    ('[x]\nmodes = [{ freq = 40 }]\nstiffness = 1000', "[x]"),
])
def test_bad_descriptions_name_the_key(tmp_path, text, key):
    base = {"[x]": '[x]\nmodes = [{ freq = 50 }]\n', "[y]": '[y]\nmodes = [{ freq = 40 }]\n'}
    body = text + "\n" + "".join(v for k, v in base.items() if k not in text)
    f = tmp_path / "printer.toml"
    f.write_text(body)
    with pytest.raises(RingtuneError) as exc:
        load_printer(f)
    assert key in str(exc.value)
    assert str(f) in str(exc.value)


def test_unreadable_and_invalid_toml(tmp_path):
    with pytest.raises(RingtuneError, match="cannot read"):
        load_printer(tmp_path / "missing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("name = \n")
    with pytest.raises(RingtuneError, match="not valid TOML"):
        load_printer(bad)


def test_motor_force_falls_with_speed():
    m = load_printer(None).motor
    np.testing.assert_allclose(m.max_force([0, m.corner_speed / 2, m.corner_speed]), m.force)
    assert m.max_force(2 * m.corner_speed) == pytest.approx(m.force / 2)
    assert m.max_force(-4 * m.corner_speed) == pytest.approx(m.force / 4)


def test_mode_properties():
    m = Mode(50.0, 0.1, 0.3)
    assert m.omega == pytest.approx(2 * math.pi * 50) and m.mass_fraction == 0.3


def test_motor_electrical_cycle_and_magnetic_stiffness():
    """λ = 4 full steps of belt; k_m = F·2π/λ (the small-angle slope of F·sin(2π e/λ))."""
    m = printer_from_dict({"motor": {"force": 30.0, "steps_per_mm": 80.0, "microsteps": 16},
                           "x": {"modes": [{"freq": 50}]}, "y": {"modes": [{"freq": 40}]}}).motor
    assert m.full_step == pytest.approx(0.2) and m.electrical_cycle == pytest.approx(0.8)
    assert m.magnetic_stiffness == pytest.approx(30.0 * 2 * math.pi / 0.8e-3)
    assert m.slip is None
    p = printer_from_dict({"motor": {"slip": False, "microsteps": 32},
                           "x": {"modes": [{"freq": 50}]}, "y": {"modes": [{"freq": 40}]}})
    q = printer_from_dict(tomllib.loads(p.to_toml()))
    assert q == p and q.motor.slip is False and q.motor.microsteps == 32


def test_unknown_printer_name_lists_the_embedded_ones_and_a_folder_is_named(tmp_path, monkeypatch):
    with pytest.raises(RingtuneError) as e:
        load_printer("default")
    assert "not an embedded printer: ender3, voron24" in str(e.value)
    with pytest.raises(RingtuneError, match="is a directory"):
        load_printer(tmp_path)
    # the default printer is the embedded one, even beside a folder named like it
    monkeypatch.chdir(tmp_path)
    (tmp_path / "ender3").mkdir()
    assert load_printer(None).name == load_printer("ender3").name == embedded_default_name()


def embedded_default_name() -> str:
    import tomllib
    from importlib import resources

    return tomllib.loads((resources.files("ringtune.envs.data") / "ender3.toml").read_text())["name"]
