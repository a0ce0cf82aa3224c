"""Stepper force against speed (envs/stepper.py), the built-in motor table, and ``ringtune motor``.

Acceptance 1 of issue 13: one motor's force at three speeds against an independent computation
written here; force never rises with speed; a higher voltage never lowers it; (old form: see
test_printer_motors.py and the existing physics tests)."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from ringtune.agents.cli import main as cli
from ringtune.envs.motors import MOTOR_TABLE, lookup_motor
from ringtune.envs.stepper import StepperDrive

REFERENCE = Path(__file__).parent / "data" / "reference" / "motors.md"


def pullout_force_by_search(R, L, T_h, I_r, steps, run_rms, V, rotation_distance, speed_mm_s):
    """Independent of the module: the phase as a circuit driven by a voltage phasor u·e^{jδ}
    (|u| ≤ V), back-EMF from Klipper autotune's constant ke = T_h/(2·I_r) (V·s/rad RMS, so
    √2·ke·ω peak), torque from the power balance of two phases, T = 2·½·Re(E·conj(I))/ω, the
    chopper's peak current √2·run_rms as a bound; the best load angle found by brute force."""
    r = rotation_distance * 1e-3 / (2 * math.pi)
    w = speed_mm_s * 1e-3 / r
    ke = T_h / (2 * I_r)
    if w == 0:
        return math.sqrt(2) * ke * min(math.sqrt(2) * run_rms, V / R) / r
    E = math.sqrt(2) * ke * w
    Z = R + 1j * (steps / 4) * w * L
    u = np.linspace(0.0, V, 801)[:, None]
    d = np.linspace(-math.pi, math.pi, 4001)[None, :]
    current = (u * np.exp(1j * d) - E) / Z
    ok = np.abs(current) <= math.sqrt(2) * run_rms
    power = np.where(ok, E * current.real, -np.inf)            # two phases × ½·E·Re(I)
    return float(np.max(power)) / w / r


def test_force_at_three_speeds_matches_an_independent_computation():
    """ldo-42sth40-1684ac (1.65 Ω, 3.6 mH, 0.45 N·m at 1.68 A) at 1.2 A RMS from 12 V on a 40 mm
    rotation distance: one speed in the flat part, one just past the corner, one far down."""
    m = MOTOR_TABLE["ldo-42sth40-1684ac"]
    drive = StepperDrive(m, 1.2, 12.0, 40.0)
    speeds = (100.0, 300.0, 900.0)
    got = drive.force(np.array(speeds))
    want = [pullout_force_by_search(1.65, 0.0036, 0.45, 1.68, 200, 1.2, 12.0, 40.0, s) for s in speeds]
    np.testing.assert_allclose(got, want, rtol=0.02)
    f0 = drive.standstill_force
    # the three speeds lie in the three parts of the curve
    assert got[0] == pytest.approx(f0) and 0.5 * f0 < got[1] < 0.999 * f0 and got[2] < 0.5 * f0


def test_standstill_force_and_the_autotune_back_emf_constant():
    m = MOTOR_TABLE["ldo-42sth48-2504ac"]
    d = StepperDrive(m, 2.5, 24.0, 40.0)
    r = 40e-3 / (2 * math.pi)
    # run current (RMS) equal to the rated current gives the holding torque
    assert d.standstill_force == pytest.approx(0.55 / r)
    assert d.back_emf_rms == pytest.approx(0.55 / (2 * 2.5))
    # above the rated current no more torque is credited (saturation, conservative)
    assert StepperDrive(m, 4.0, 24.0, 40.0).standstill_force == pytest.approx(d.standstill_force)
    # half the current, half the force
    assert StepperDrive(m, 1.25, 24.0, 40.0).standstill_force == pytest.approx(d.standstill_force / 2)


def test_high_speed_force_falls_like_one_over_speed():
    """Far past the corner the inductance dominates: F·v tends to a constant
    (K·V/(p·L)/r · r … i.e. the power the voltage can push through the reactance)."""
    d = StepperDrive(MOTOR_TABLE["ldo-42sth48-2504ac"], 1.77, 24.0, 40.0)
    v = np.array([20000.0, 40000.0])
    fv = d.force(v) * v
    assert fv[1] == pytest.approx(fv[0], rel=0.02)


@given(st.sampled_from(sorted(MOTOR_TABLE)), st.floats(0.2, 1.5), st.floats(5.0, 60.0),
       st.floats(1.0, 3.0), st.floats(16.0, 80.0))
@settings(max_examples=200, deadline=None, derandomize=True)
def test_force_never_rises_with_speed_and_more_voltage_never_lowers_it(name, frac, volt, more, rd):
    m = MOTOR_TABLE[name]
    lo = StepperDrive(m, frac * m.rated_current, volt, rd)
    hi = StepperDrive(m, frac * m.rated_current, volt * more, rd)
    v = np.linspace(0.0, 5000.0, 2001)
    f_lo, f_hi = lo.force(v), hi.force(v)
    assert np.all(np.isfinite(f_lo)) and np.all(f_lo >= 0.0)
    assert np.all(np.diff(f_lo) <= 1e-9 * f_lo[0])
    assert np.all(f_hi >= f_lo - 1e-9 * f_lo[0])


def test_every_motor_of_the_reference_is_in_the_table_with_its_constants():
    rows = [line for line in REFERENCE.read_text().splitlines()
            if re.match(r"^\| [^ ]+ \| [\d.]+ \|", line)]
    assert len(rows) == 203
    for line in rows:
        name, R, L, T, I, n = [c.strip() for c in line.strip("|").split("|")]
        m = lookup_motor(name)
        assert m is not None, name
        assert (m.resistance, m.inductance, m.holding_torque, m.rated_current, m.steps_per_revolution) == \
            (float(R), float(L), float(T), float(I), int(n)), name
    assert len(MOTOR_TABLE) == len(rows)


# -- ringtune motor ---------------------------------------------------------------------------------
def _run(argv, capsys):
    try:
        rc = cli.main(argv)
    except SystemExit as exc:
        rc = exc.code
    return rc, capsys.readouterr()


def test_motor_command_json(capsys, tmp_path):
    rc, cap = _run(["motor", "ldo-42sth40-1684ac", "--run-current", "1.2", "--voltage", "12",
                    "--rotation-distance", "40", "--mass", "0.8", "--json", "--plot", str(tmp_path / "f.png")],
                   capsys)
    assert rc == 0, cap.err
    r = json.loads(cap.out)
    assert [s for s, _ in r["force_n"]] == [0, 100, 200, 300, 500]
    want = [pullout_force_by_search(1.65, 0.0036, 0.45, 1.68, 200, 1.2, 12.0, 40.0, s) for s in (0, 300, 500)]
    got = dict(r["force_n"])
    np.testing.assert_allclose([got[0], got[300], got[500]], want, rtol=0.02)
    # the half-force speed is where the independent computation gives half the standstill force
    half = pullout_force_by_search(1.65, 0.0036, 0.45, 1.68, 200, 1.2, 12.0, 40.0, r["half_force_speed_mm_s"])
    assert half == pytest.approx(got[0] / 2, rel=0.02)
    assert [a for _, a in r["accel_mm_s2"]] == pytest.approx([f / 0.8 * 1e3 for _, f in r["force_n"]])
    assert r["assumed"] == [] and cap.err == ""
    assert (tmp_path / "f.png").stat().st_size > 10000


def test_motor_command_says_its_defaults_and_refuses_unknown_names(capsys):
    rc, cap = _run(["motor", "LDO-42STH48-2504AC"], capsys)
    assert rc == 0
    for word in ("run_current = 1.77 A", "voltage = 24 V", "rotation_distance = 40 mm"):
        assert word in cap.err
    assert "half of it at" in cap.out
    rc, cap = _run(["motor", "ldo-42sth48-2504"], capsys)
    lines = cap.err.strip().splitlines()
    assert rc == 2 and len(lines) == 1 and "ldo-42sth48-2504ac" in lines[0] and cap.out == ""
    rc, cap = _run(["motor", "ldo-42sth48-2504ac", "--voltage", "0"], capsys)
    assert rc == 2 and "--voltage" in cap.err


@pytest.mark.parametrize("name, frac, volt", [("ldo-42sth48-2504ac", 0.7, 24.0), ("wantai-42byghm810", 0.5, 12.0),
                                              ("omc-14hs10-0404s", 1.0, 24.0), ("ldo-42sth40-1684ac", 1.3, 24.0)])
def test_corner_speed_is_where_the_flat_part_ends(name, frac, volt):
    m = MOTOR_TABLE[name]
    d = StepperDrive(m, frac * m.rated_current, volt, 40.0)
    vc = d.corner_speed
    assert 0 < vc < math.inf
    f0 = d.standstill_force
    assert float(d.force(0.999 * vc)) == pytest.approx(f0, rel=1e-9)
    assert float(d.force(1.01 * vc)) < f0 * (1 - 1e-6)


def test_motor_command_takes_the_constants_of_a_motor_the_table_lacks(capsys, tmp_path):
    # the V0 of tests/data/klipper_config defines its motor inline ([motor_constants
    # fysetc-35hsh7402-24b-400a] in v0/config/autotune.cfg): the command must take those constants
    name = "fysetc-35hsh7402-24b-400a"
    assert lookup_motor(name) is None
    rc, cap = _run(["motor", name, "--run-current", "0.7"], capsys)
    assert rc == 2 and cap.out == "" and len(cap.err.strip().splitlines()) == 1
    for flag in ("--holding-torque", "--rated-current", "--resistance", "--inductance"):
        assert flag in cap.err
    rc, cap = _run(["motor", name, "--holding-torque", "0.42", "--rated-current", "1.5", "--resistance", "2.8",
                    "--inductance", "0.0055", "--run-current", "0.7", "--voltage", "24",
                    "--rotation-distance", "40", "--json"], capsys)
    assert rc == 0, cap.err
    r = json.loads(cap.out)
    assert r["motor"] == name and r["constants"]["holding_torque_nm"] == 0.42
    got = dict(r["force_n"])
    want = [pullout_force_by_search(2.8, 0.0055, 0.42, 1.5, 200, 0.7, 24.0, 40.0, s) for s in (0, 500)]
    np.testing.assert_allclose([got[0], got[500]], want, rtol=0.02)
    assert "steps_per_revolution = 200" in cap.err          # the one constant not given is said
    rc, cap = _run(["motor", name, "--holding-torque", "-1", "--rated-current", "1.5", "--resistance", "2.8",
                    "--inductance", "0.0055"], capsys)
    assert rc == 2 and "--holding-torque" in cap.err


def test_motor_command_refuses_a_plot_folder_and_says_a_current_above_the_rating(capsys, tmp_path):
    rc, cap = _run(["motor", "ldo-42sth40-1684ac", "--plot", str(tmp_path)], capsys)
    assert rc == 2 and "--plot" in cap.err and "directory" in cap.err
    assert not Path(str(tmp_path) + ".png").exists()
    rc, cap = _run(["motor", "ldo-42sth40-1684ac", "--run-current", "2.0", "--voltage", "24",
                    "--rotation-distance", "40"], capsys)
    assert rc == 0 and "above the motor's rated 1.68 A" in cap.err
    rc, cap = _run(["motor", "ldo-42sth40-1684ac", "--run-current", "0.9", "--voltage", "24",
                    "--rotation-distance", "40"], capsys)
    assert rc == 0 and cap.err == ""
