"""The slip model (default, [motor] slip; envs.rotor): the stepper's rotor on its sinusoidal magnetic
spring. Below the holding force MuJoCo is the exact linear twin's (LTI with the same rotor stage);
the series spring solve keeps the described modes; above the holding force the rotor really skips
(falls behind by whole electrical cycles and stays there), which no linear model can show."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ringtune.envs.mujoco_model import build_model, drive_gains, linear_system
from ringtune.envs.printer import load_printer, printer_from_dict
from ringtune.envs.rotor import undamped_frequencies
from ringtune.envs.sim import simulate, simulate_batch
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.motion import Motion

from test_physics_accuracy import rel_rms, trapezoids

#: a weak motor (10 N at the belt): slips at 25 000 mm/s² with 0.3 kg + 0.1 kg rotor
WEAK = {"force": 10.0}
MOTOR = {"force": 80.0, "rotor_mass": 0.2, "friction": 0.0, "steps_per_mm": 80.0, "slip": True}


def slip_printer(freq, damping=0.05, mass=0.3, motor=None, **extra):
    mo = {k: v for k, v in dict(MOTOR, **(motor or {})).items() if v is not None}
    d = {"x": {"mass": mass, "modes": [{"freq": freq, "damping": damping}]},
         "y": {"mass": mass, "modes": [{"freq": 0.8 * freq, "damping": damping}]}, "motor": mo}
    d.update(extra)
    return printer_from_dict(d)


def with_slip(name, **motor):
    d = load_printer(name).to_dict()
    d["motor"].update(slip=True, **motor)
    return printer_from_dict(d)


@pytest.mark.parametrize("freq", [20.0, 60.0, 100.0, 150.0])
def test_below_the_holding_force_mujoco_equals_the_linear_twin(freq):
    """(1) One mode 20–150 Hz behind the rotor stage: MuJoCo (sinusoidal magnet) within 1 % RMS of
    the exact LTI solution with the linearised rotor, while the motor stays below its force."""
    rng = np.random.default_rng(int(freq))
    mo = trapezoids(rng, n=4)
    p = slip_printer(freq)
    mj, ex = simulate_batch(p, [mo], tail=0.1)[0], simulate(p, mo, backend="lti", tail=0.1)
    assert not mj.step_loss and mj.force_ratio < 0.5
    for axis in (0, 1):
        assert rel_rms(mj.deviation[:, axis], ex.deviation[:, axis]) < 0.01
    # the rotor lag carries the rotor's own ringing (ω·h ≈ 0.9 here, invisible at the nozzle):
    # RK4 at 0.5 ms integrates it to ≈ 1 % (0.1 % at 0.25 ms)
    assert rel_rms(mj.rotor_lag, ex.rotor_lag) < 0.02
    assert np.max(np.abs(mj.rotor_lag)) > 1e-3                      # the rotor really moves


@pytest.mark.parametrize("name", ["ender3", "voron24"])
def test_embedded_printers_with_slip_track_the_linear_twin(name):
    p = with_slip(name)
    mo = trapezoids(np.random.default_rng(7), n=4, scale=(1.0, 0.6))
    mj, ex = simulate(p, mo, tail=0.1), simulate(p, mo, backend="lti", tail=0.1)
    assert rel_rms(mj.deviation, ex.deviation) < 0.01
    assert rel_rms(mj.motor_force, ex.motor_force) < 0.01


@pytest.mark.parametrize("name,extra", [("ender3", {}), ("ender3", {"print_mass": 0.4}),
                                        ("voron24", {}), ("voron24", {"belts": {"mismatch": 0.2}})])
def test_series_solve_lands_on_the_described_modes(name, extra):
    """(2) The rotor spring is in series with the belts; the re-solved springs put the lowest
    undamped eigenfrequencies of the linear system exactly on the described ones, and the rotor
    modes lie above them (k_m and the rotor mass)."""
    d = load_printer(name).to_dict()
    d["motor"]["slip"] = True
    for k, v in extra.items():
        d[k] = v
    p = printer_from_dict(d)
    s = linear_system(p)
    w = undamped_frequencies(s.K, s.mass) / (2 * math.pi)
    want = np.sort([m.freq for ax in "xy" for m in p.effective_modes(ax)])
    np.testing.assert_allclose(w[:len(want)], want, rtol=1e-10)
    km, mr = p.motor.magnetic_stiffness, p.motor.rotor_mass
    assert np.all(w[len(want):] > 0.9 * math.sqrt(km / mr) / (2 * math.pi))
    # the state matrix has the same (damped) eigenvalues: what both backends integrate
    A, _ = s.state_matrices()
    lam = np.linalg.eigvals(A)
    wd = np.sort(np.abs(lam.imag))[::2][:len(want)] / (2 * math.pi)
    expect = np.sort([m.freq * math.sqrt(1 - m.damping**2) for ax in "xy" for m in p.effective_modes(ax)])
    if not extra.get("belts"):
        np.testing.assert_allclose(wd, expect, rtol=1e-9)


@pytest.mark.parametrize("name", ["ender3", "voron24"])
def test_described_shares_and_damping_keep_the_measured_response(name):
    """(2) Shares and damping are solved too: the nozzle's linear response with the rotor stage is
    the rigid-motor model's (rotor modes invisible at the nozzle), to rounding."""
    rigid = load_printer(name)
    p = with_slip(name)
    mo = trapezoids(np.random.default_rng(3), n=3, scale=(1.0, -0.7))
    a = simulate(rigid, mo, backend="lti", tail=0.05)
    b = simulate(p, mo, backend="lti", tail=0.05)
    assert rel_rms(b.deviation, a.deviation) < 1e-9
    np.testing.assert_allclose(b.head_accel, a.head_accel, atol=1e-9 * np.abs(a.head_accel).max())
    # but the motor side differs: the rotor lags by about force/k_m
    assert np.max(np.abs(b.rotor_lag)) > 0


def test_a_motor_too_weak_for_the_described_frequency_is_an_error():
    """k_m = F·2π/λ in series cannot carry (m_r + M)·ω² beyond its own stiffness."""
    p = slip_printer(150.0, mass=0.55, motor={"force": 20.0})
    with pytest.raises(RingtuneError, match="magnetic stiffness") as exc:
        linear_system(p)
    assert "[motor].force" in str(exc.value)


def test_a_runaway_series_solve_is_infeasible_not_a_crash():
    """A two-mode Y that a 21.7 N motor cannot carry beside a 116 Hz X: the Newton solve drives a
    spring towards infinite stiffness (a 0 Hz mode, then an eigen-solve that fails). That is the
    same infeasibility as above: unset slip falls back to the rigid motor, slip = true is the
    error naming [motor].force (once a LinAlgError escaped, ~1 in 300 random printers)."""
    d = {"name": "runaway", "kinematics": "cartesian",
         "x": {"mass": 1.018051538030529, "modes": [{"freq": 115.80751028153192, "damping": 0.03254612280415192}]},
         "y": {"mass": 0.6429837977442394,
               "modes": [{"freq": 33.72982936616528, "damping": 0.13426772321570668, "share": 0.7197989243064755},
                         {"freq": 49.44207273017178, "damping": 0.16997520575023453, "share": 0.2802010756935244}]},
         "print_mass": 0.36645595443636503, "motor": {"force": 21.65512049032228}}
    assert linear_system(printer_from_dict(d, "runaway")).rotors == []
    d["motor"]["slip"] = True
    with pytest.raises(RingtuneError, match="magnetic stiffness") as exc:
        linear_system(printer_from_dict(d, "runaway"))
    assert "[motor].force" in str(exc.value)


def _over_then_gentle(a_over, a_back, t_over):
    """Accelerate at a_over for t_over, then come back to rest at the gentle a_back."""
    v = a_over * t_over
    t = np.array([0.0, 0.005, 0.005 + t_over, 0.005 + t_over + v / a_back])
    return Motion.from_constant_accel(t, np.array([[0.0, 0.0], [a_over, 0.0], [-a_back, 0.0]]))


def test_above_the_holding_force_the_rotor_skips_and_never_recovers():
    """(3) Asked for 1.6× the holding force the MuJoCo rotor falls behind by more than one full step,
    keeps whole electrical cycles lost after the load is gone (a skipped step) and the nozzle with
    it; the linear twin stays bounded and returns to the commanded position."""
    p = slip_printer(50.0, motor=WEAK)
    s = linear_system(p)
    m_tot = s.mass[s.axis == 0].sum()                     # x bodies + x rotor (its axis is x)
    a_star = p.motor.force * 1e3 / m_tot
    mo = _over_then_gentle(1.6 * a_star, 0.3 * a_star, 0.03)
    mj = simulate(p, mo, tail=0.3)
    ex = simulate(p, mo, backend="lti", tail=0.3)
    lam, step = p.motor.electrical_cycle, p.motor.full_step
    lag = mj.rotor_lag[:, 0]
    assert np.max(np.abs(lag)) > step
    assert mj.step_loss
    end = lag[-200:]
    cycles = np.round(end / lam)
    assert np.all(cycles == cycles[0]) and cycles[0] != 0          # locked on a later equilibrium
    np.testing.assert_allclose(end, cycles[0] * lam, atol=0.05 * lam)
    assert abs(mj.deviation[-1, 0] - cycles[0] * lam) < 0.05 * lam  # the print is shifted
    assert np.max(np.abs(mj.deviation[:, 0])) > 10 * np.max(np.abs(ex.deviation[:, 0]))
    # linear: bounded by the static lag and back to the command at rest
    assert np.max(np.abs(ex.rotor_lag[:, 0])) < 2.5 * 1.6 * p.motor.force / (p.motor.magnetic_stiffness * 1e-3)
    assert abs(ex.deviation[-1, 0]) < 1e-3 and abs(ex.rotor_lag[-1, 0]) < 1e-3


def _staircase(a_end, duration, steps=80, hold=0.0):
    """Acceleration rising in small stairs from 0 to a_end (quasi-static loading), then held."""
    t = np.r_[np.linspace(0.0, duration, steps + 1), duration + hold] if hold else np.linspace(0.0, duration, steps + 1)
    acc = np.linspace(a_end / steps, a_end, steps)
    if hold:
        acc = np.r_[acc, a_end]
    return Motion.from_constant_accel(t, np.stack([acc, np.zeros_like(acc)], axis=1))


def test_slip_onset_where_the_demanded_force_crosses_the_holding_force():
    """(4) Loading the motor slowly, the MuJoCo rotor slips (passes one full step, the torque peak)
    when the analytic demanded force m_total·a crosses F_hold; held just below it never slips."""
    p = slip_printer(50.0, motor=WEAK)
    s = linear_system(p)
    m_tot = s.mass[s.axis == 0].sum()
    a_star = p.motor.force * 1e3 / m_tot
    dur = 0.4
    r = simulate(p, _staircase(1.3 * a_star, dur), tail=0.0)
    crossing = dur * (1.0 / 1.3)                          # m_tot·a(t) = F_hold on the ramp
    onset = r.t[np.argmax(np.abs(r.rotor_lag[:, 0]) >= p.motor.full_step)]
    assert np.any(np.abs(r.rotor_lag[:, 0]) >= p.motor.full_step)
    assert abs(onset - crossing) < 0.02 * dur
    # the LTI twin's linear magnetic force k_m·lag crosses F_hold at the same time
    ex = simulate(p, _staircase(1.3 * a_star, dur), backend="lti", tail=0.0)
    f_lin = p.motor.magnetic_stiffness * 1e-3 * np.abs(ex.rotor_lag[:, 0])
    assert abs(ex.t[np.argmax(f_lin >= p.motor.force)] - crossing) < 0.02 * dur
    # held at 97 % of the holding force: no slip, the lag stays below a full step
    below = simulate(p, _staircase(0.97 * a_star, 0.3, hold=0.2))
    assert np.max(np.abs(below.rotor_lag[:, 0])) < p.motor.full_step
    above = simulate(p, _staircase(1.03 * a_star, 0.3, hold=0.2))
    assert np.max(np.abs(above.rotor_lag[:, 0])) > p.motor.electrical_cycle


def test_mjcf_magnet_is_the_stepper_torque_angle_curve():
    """The rotor pendulum gives exactly −F_hold·sin(2π e/λ) at the belt, for any lag e (beside the
    linear belt springs the displaced rotor stretches)."""
    import mujoco

    p = slip_printer(50.0, motor=WEAK)
    s = linear_system(p)
    m = build_model(p)
    d = mujoco.MjData(m)
    for r in s.rotors:
        for e in np.linspace(-1.7, 1.7, 23) * r.cycle:
            d.qpos[:] = 0.0
            d.qvel[:] = 0.0
            d.qpos[r.index] = e / r.scale
            mujoco.mj_forward(m, d)
            force = (d.qfrc_passive[r.index] - d.qfrc_bias[r.index]) / r.scale   # kg·mm/s² at the belt
            belts = (s.K[r.index, r.index] - r.stiffness) * e     # the linear springs it stretches
            assert force + belts == pytest.approx(-r.peak * math.sin(2 * math.pi * e / r.cycle),
                                                  abs=1e-6 * r.peak)
        # and its inertia is the reflected rotor mass
        d.qpos[:] = 0.0
        mujoco.mj_forward(m, d)
        unit, Mu = np.zeros(m.nv), np.zeros(m.nv)
        unit[r.index] = 1.0
        mujoco.mj_mulM(m, d, Mu, unit)
        assert Mu[r.index] * r.scale ** -2 == pytest.approx(r.mass, rel=1e-9)
        assert np.count_nonzero(Mu) == 1                          # diagonal mass matrix


@pytest.mark.parametrize("name,slip", [("ender3", None), ("voron24", None), ("ender3", False)])
def test_the_drive_as_generalised_forces_is_the_motors_to_the_bit(name, slip):
    """simulate's models have no actuators: each coordinate is driven by ``qfrc_applied`` =
    drive_gains · control. A rollout of that model is MuJoCo's own actuated model driven by the
    same controls, bit for bit (rotors, CoreXY belts and the rigid motor)."""
    import mujoco
    from mujoco import rollout

    d = load_printer(name).to_dict()
    if slip is not None:
        d["motor"]["slip"] = slip
    p = printer_from_dict(d)
    s = linear_system(p)
    driven, bare = build_model([p, p]), build_model([p, p], actuators=False)
    assert driven.nu == 2 * s.n and bare.nu == 0 and bare.nv == driven.nv
    rng = np.random.default_rng(3)
    nstate = mujoco.mj_stateSize(driven, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    init = np.zeros((1, nstate))
    init[0, 1:1 + driven.nq] = rng.normal(0, 0.01, driven.nq)
    a = rng.normal(0, 3000.0, (1, 400, 2))
    per = -(a @ s.B.T) if s.rotors else -a[..., s.axis]                 # each coordinate's control
    ctrl = np.concatenate([per, per], axis=-1)
    forces = ctrl * np.tile(drive_gains(s), 2)
    want, _ = rollout.rollout(driven, mujoco.MjData(driven), init, ctrl)
    got, _ = rollout.rollout(bare, mujoco.MjData(bare), init, forces,
                             control_spec=int(mujoco.mjtState.mjSTATE_QFRC_APPLIED))
    assert np.abs(want).max() > 0
    np.testing.assert_array_equal(got, want)


def test_slip_model_is_the_default_when_the_motor_can_carry_the_modes():
    """Unset [motor].slip: the embedded printers get rotors; a motor too weak for the described
    modes falls back to the rigid motor (step loss detected only); slip = false forces rigid."""
    for name in ("ender3", "voron24"):
        assert [r.name for r in linear_system(load_printer(name)).rotors] == (
            ["x", "y"] if name == "ender3" else ["a", "b"])
    weak = slip_printer(150.0, mass=0.55, motor={"force": 20.0, "slip": None})
    assert weak.motor.slip is None and linear_system(weak).rotors == []
    assert linear_system(slip_printer(50.0, motor={"slip": False})).rotors == []
    # the unset default round-trips as unset
    import tomllib
    assert printer_from_dict(tomllib.loads(load_printer(None).to_toml())).motor.slip is None


@pytest.mark.parametrize("name", ["ender3", "voron24"])
def test_static_start_is_the_nonlinear_rest(name):
    """initial="static" under a held acceleration: the MuJoCo rotor starts at its sinusoidal
    magnet's equilibrium asin(F/F_hold)·λ/2π (beyond the linear lag), so nothing moves."""
    p = load_printer(name)
    mo = Motion.from_constant_accel(np.array([0.0, 0.1]), np.array([[20000.0, 8000.0]]))
    mj = simulate(p, mo, initial="static")
    ex = simulate(p, mo, initial="static", backend="lti")
    assert np.max(np.ptp(mj.rotor_lag, axis=0)) < 1e-9 and np.max(np.ptp(mj.deviation, axis=0)) < 1e-9
    lin = ex.rotor_lag[0]
    k = p.motor.magnetic_stiffness * 1e-3                       # N/mm
    np.testing.assert_allclose(mj.rotor_lag[0], np.arcsin(k * lin / p.motor.force) / k * p.motor.force,
                               rtol=1e-9)
    assert np.all(np.abs(mj.rotor_lag[0]) > np.abs(lin))


def test_input_shaping_keeps_the_default_printer_from_skipping_steps():
    """seeds/002 in the dynamics: an abrupt acceleration nearly doubles the force through the belts,
    so at 32 000 mm/s² the unshaped X move of the default printer skips whole electrical cycles
    (for good), while the same move ZV/MZV/EI-shaped stays well inside one full step and ends on
    the command. The linear twin predicts the overload (demanded force above F_hold unshaped,
    below it shaped) but cannot show the skip."""
    from ringtune.shaping.apply import shape_motion
    from ringtune.shaping.shapers import get_shaper

    p = load_printer(None)
    a, ta = 32000.0, 0.03
    mo = Motion.from_constant_accel(np.array([0.0, ta, 5 * ta]), np.array([[a, 0.0], [-a / 4, 0.0]]))
    shaped = [shape_motion(mo, {"x": get_shaper(n, f, 0.1), "y": None}, centred=False)
              for n, f in (("zv", 45.5), ("mzv", 50.0), ("ei", 50.0))]
    sims = simulate_batch(p, [mo] + shaped, tail=0.2)
    lin = simulate_batch(p, [mo] + shaped, backend="lti", tail=0.2)
    lam, step = p.motor.electrical_cycle, p.motor.full_step
    raw = sims[0]
    assert raw.rotor_lag[-1, 0] <= -lam + 0.05 * lam                   # lost ≥ one electrical cycle
    assert abs(raw.rotor_lag[-1, 0] / lam - round(raw.rotor_lag[-1, 0] / lam)) < 0.05
    assert abs(raw.deviation[-1, 0] - raw.rotor_lag[-1, 0]) < 0.05 * lam
    assert np.max(np.abs(lin[0].motor_force[:, 0])) > p.motor.force
    assert abs(lin[0].deviation[-1, 0]) < 0.02
    for s, ls in zip(sims[1:], lin[1:]):
        assert np.max(np.abs(s.rotor_lag[:, 0])) < step
        assert abs(s.rotor_lag[-1, 0]) < 1e-3 and abs(s.deviation[-1, 0]) < 0.02
        assert np.max(np.abs(ls.motor_force[:, 0])) < p.motor.force


def test_a_rotor_too_light_for_the_timestep_is_refused_or_rigid():
    """A rotor mode beyond ω·h = 1.5 at 0.5 ms would be integrated badly: slip = true names
    [motor].rotor_mass; unset falls back to the rigid motor."""
    with pytest.raises(RingtuneError, match="too stiff for RK4") as exc:
        linear_system(slip_printer(50.0, motor={"rotor_mass": 0.002}))
    assert "[motor].rotor_mass" in str(exc.value)
    assert linear_system(slip_printer(50.0, motor={"rotor_mass": 0.002, "slip": None})).rotors == []
