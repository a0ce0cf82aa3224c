"""Acceptance 5 (CoreXY belt coupling), batching, and the MuJoCo model's own accelerometer."""

from __future__ import annotations

import numpy as np
import pytest

from ringtune.envs.mujoco_model import build_model, linear_system
from ringtune.envs.printer import load_printer, printer_from_dict
from ringtune.envs.sim import simulate, simulate_batch
from ringtune.shaping.motion import Motion


def corexy(mismatch=0.0, **kw):
    d = {"kinematics": "corexy", "x": {"mass": 0.5, "modes": [{"freq": 53.0, "damping": 0.05}]},
         "y": {"mass": 1.1, "modes": [{"freq": 42.0, "damping": 0.07}]}, "belts": {"mismatch": mismatch}}
    d.update(kw)
    return printer_from_dict(d)


def pure_x():
    t = np.array([0.0, 0.0213, 0.0613, 0.0826, 0.2])
    return Motion.from_constant_accel(t, np.array([[4000.0, 0], [0, 0], [-4000.0, 0], [0, 0]]))


@pytest.mark.parametrize("backend", ["mujoco", "lti"])
def test_pure_x_move_excites_y_only_with_unequal_belts(backend):
    mo = pure_x()
    matched = simulate(corexy(0.0), mo, backend=backend)
    assert np.max(np.abs(matched.deviation[:, 0])) > 1e-3
    assert np.max(np.abs(matched.deviation[:, 1])) < 1e-12
    # both motors share a pure X move equally
    np.testing.assert_allclose(matched.motor_force[:, 0], matched.motor_force[:, 1], atol=1e-9)
    skew = simulate(corexy(0.2), mo, backend=backend)
    dy = np.max(np.abs(skew.deviation[:, 1]))
    assert dy > 0.05 * np.max(np.abs(skew.deviation[:, 0]))
    # the mirror-image mismatch gives the mirror-image Y response (w -> -w symmetry)
    flip = simulate(corexy(-0.2), mo, backend=backend)
    np.testing.assert_allclose(flip.deviation[:, 1], -skew.deviation[:, 1], atol=1e-9 * dy + 1e-15)


def test_corexy_coupled_mujoco_matches_exact():
    mo = pure_x()
    for mm in (0.0, 0.3):
        p = corexy(mm)
        mj, ex = simulate(p, mo, tail=0.1), simulate(p, mo, backend="lti", tail=0.1)
        err = np.sqrt(np.mean((mj.deviation - ex.deviation) ** 2)) / np.sqrt(np.mean(ex.deviation**2))
        assert err < 0.01


def test_matched_belts_land_on_the_measured_frequencies():
    """Uncoupled (matched belts) CoreXY modes are exactly the described ones."""
    p = load_printer("voron24")
    s = linear_system(p)
    A, _ = s.state_matrices()
    w = np.sort(np.abs(np.linalg.eigvals(A).imag))[::2] / (2 * np.pi)
    expect = np.sort([m.freq * np.sqrt(1 - m.damping**2) for ax in "xy" for m in p.effective_modes(ax)])
    # the slip model (default) adds the two rotor modes above the described ones
    assert len(w) == len(expect) + 2 * (s.rotors != [])
    np.testing.assert_allclose(w[:len(expect)], expect, rtol=1e-9)


def test_batch_equals_single_runs_and_mixes_printers():
    """Windows packed as replicas of one model give the same answer as one-by-one simulation."""
    rng = np.random.default_rng(3)
    motions = []
    for _ in range(5):
        t = np.r_[0.0, np.cumsum(rng.uniform(0.004, 0.03, 8))]
        a = rng.uniform(-3000, 3000, (8, 2))
        a[-1] = 0
        motions.append(Motion.from_constant_accel(t, a))
    printers = [load_printer(None), load_printer("voron24"), corexy(0.1), load_printer(None), corexy()]
    batch = simulate_batch(printers, motions, nthread=2)
    for p, m, b in zip(printers, motions, batch):
        one = simulate(p, m)
        np.testing.assert_allclose(b.nozzle, one.nozzle, atol=1e-12)
        np.testing.assert_allclose(b.motor_force, one.motor_force, atol=1e-9)
        assert b.t.shape == one.t.shape and b.step_loss == one.step_loss


def test_mjcf_accelerometer_reads_the_toolhead_acceleration():
    """The model's accelerometer on the toolhead body reads its acceleration in the commanded frame
    (q̈ of the first X mode), as the linear system predicts."""
    import mujoco

    p = load_printer(None)
    m = build_model(p, accelerometer=True)
    d = mujoco.MjData(m)
    s = linear_system(p)
    rng = np.random.default_rng(0)
    sc = s.scale if s.scale is not None else np.ones(s.n)      # rotor hinges turn in radians
    q, qd = rng.normal(0, 0.01, m.nq), rng.normal(0, 1.0, m.nv)
    d.qpos[:], d.qvel[:] = q / sc, qd / sc
    a_cmd = np.array([2500.0, -1200.0])
    d.ctrl[:] = -(s.B @ a_cmd)
    mujoco.mj_forward(m, d)
    expect = s.qacc(q[None], qd[None], a_cmd[None], nonlinear=True)[0]
    np.testing.assert_allclose(d.qacc * sc, expect, rtol=1e-9, atol=1e-9 * np.abs(expect).max())
    np.testing.assert_allclose(d.sensordata[0], expect[s.names.index("x0")], rtol=1e-9)


def test_accel_sensor_reports_head_acceleration_and_print_mass_slows_y():
    mo = pure_x()
    r = simulate(load_printer(None), mo)
    np.testing.assert_array_equal(r.accel_sensor[:, :2], r.head_accel)
    assert np.all(r.accel_sensor[:, 2] == 0)
    light = load_printer(None)
    heavy = printer_from_dict({**light.to_dict(), "print_mass": 0.3})
    for a, b in zip(light.effective_modes("y"), heavy.effective_modes("y")):
        assert b.freq == pytest.approx(a.freq * np.sqrt(1.1 / 1.4))
    assert heavy.effective_modes("x")[0].freq == light.effective_modes("x")[0].freq
