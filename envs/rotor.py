"""Slip model: each stepper's rotor on its sinusoidal magnetic spring, the belts and modes behind it.

Why (seeds/002: "if you ask the motor to produce too much force then it slips"): the rigid-motor
model can only *detect* an overload. Here a stepper is what it physically is — a rotor held to the
commanded electrical position by a torque that is periodic in the lag ``e`` (mm of belt):

    F_em(e) = −F_hold · sin(2π e / λ),   λ = one electrical cycle = 4 full steps
              = 4·microsteps/steps_per_mm mm of belt

with F_hold the motor's low-speed force (``[motor].force``, or from the datasheet constants the
holding force at the run current, :mod:`ringtune.envs.stepper`). Near e = 0 it is a spring of stiffness
``k_m = F_hold·2π/λ`` (the linear twin used by the exact reference); it can give no more than
F_hold, reached one full step behind (e = λ/4); past that the force *falls*, the rotor runs away
and, once the load is gone, locks again on a later equilibrium e = −j·λ: j whole electrical cycles
(4j full steps) are lost and never recovered — a skipped step. A force-clamped position servo
(``forcerange``) would not do that: it recovers its position when the load drops, so it cannot
show a ruined print.

MuJoCo form (exact, no callbacks, no extra cost): the rotor is a hinge (angle φ = 2π e/λ) about a
horizontal axis whose body is a pendulum: its centre of mass sits ρ below the axis and the model's
gravity (used for nothing else: every other joint slides horizontally) gives the torque
−m g ρ·sin φ exactly — the stepper's torque–angle curve, with m g ρ = F_hold·λ/2π. (A spatial
tendon of zero rest length on a crank gives the same law but doubles the cost per step.) The
rotor's reflected mass ``rotor_mass`` becomes the hinge inertia m_r·(λ/2π)² (parallel-axis part
included), its fictitious force −m_r·a_motor a motor with gear m_r·λ/2π; ``rotor_damping`` is the
damping ratio of the rotor modes (back-EMF and eddy losses).

Coordinates (all relative to the commanded position, so the mass matrix stays diagonal): the
modal bodies of :func:`ringtune.envs.mujoco_model.linear_system`, then one rotor per motor (cartesian:
X, Y; CoreXY: A, B in belt mm; CoreXZ: A, B both turning with X, and Y), each with its own motor's
F_hold, λ and rotor mass (:meth:`Printer.drive_motors`). Every mode body hangs from its axis's
*motor side* (cartesian x → r_X; CoreXY x → (r_A + r_B)/2, y → (r_A − r_B)/2; CoreXZ x →
(r_A + r_B)/2, y → r_Y) through a spring and damper
realised as a fixed tendon; the CoreXY primary modes are also tied by the two belts
``A = u + w − r_A``, ``B = u − w − r_B`` (stiffness as the rigid-motor model).

Series solve: the rotor spring sits in series with the belts, so the mode springs are re-solved
(Newton on their logarithms, the generalised eigenproblem ``K φ = ω² M φ`` of the linearised system)
until the n lowest undamped frequencies equal the described ones to 1e-10; the rotor
modes lie above (≈ √((k_m + belts)/m_r)). The nozzle weights are then solved (linear least squares,
exact when the axes decouple) so that the nozzle's modal shares are the described ones and the
rotor modes are invisible at the nozzle: the measured response stays the measured response, and
what the motor adds is its force, its lag and, above F_hold, its slip. A description whose
frequencies the motor's magnetic stiffness cannot carry (k_m < (m_r + M)·ω² for a single mode)
raises :class:`RingtuneError` naming ``[motor].force``. Damping is modal,
``C = M Φ diag(2ζ_j ω_j) Φᵀ M`` (described ζ on the described modes, ``rotor_damping`` on the rotor
modes), realised in MuJoCo sparsely: each off-diagonal entry as a two-joint damper tendon (merged
into the spring tendon of the same pair), the rest of the diagonal as joint damping. With exact
frequencies, shares and modal damping the nozzle's linear response *is* the rigid-motor model's (the rotor modes are
invisible at the nozzle); the linear difference is in the motor force and the rotor's lag.

Speed: the rotor modes (246 and 256 Hz for the Ender-3 defaults: k_m = 236 N/mm, m_r = 0.13 kg)
have ω·h ≈ 0.8 at RK4's 0.5 ms, well inside RK4's stability limit 2.83 (numerical damping ≈ 0.2 %
per step on those modes only; being invisible at the nozzle in the linear regime, their integration
error does not reach it). A description whose rotor mode would exceed ω·h = 1.5 at 0.5 ms (a very
light rotor on a strong motor) is refused like an infeasible one. Per step the slip model costs
about 20 % more than the rigid one (6 instead of 4 degrees of freedom for the Ender-3 class).

The holding force is the standstill one: its fall with speed
(:meth:`MotorModel.max_force`) stays a detection criterion (``step_loss``), as does a rotor that
passed one full step of lag.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ringtune.envs.modal_system import LinearSystem
from ringtune.shaping.errors import RingtuneError

#: default MuJoCo step (s), as :data:`ringtune.envs.mujoco_model.TIMESTEP` (not imported: model imports us)
TIMESTEP = 0.0005
#: largest ω·h of the stiffest (rotor) mode accepted at that step: RK4 is stable to 2.83; at 1.5 it
#: damps that mode numerically by ~6 % per step (0.2 % at the Ender-3's 0.8); beyond, the slip
#: model is refused (the rigid motor is used unless ``slip = true``)
MAX_OMEGA_H = 1.5


@dataclass
class Rotor:
    """One motor's rotor stage (model units mm, kg, s; forces kg·mm/s² = mN).

    index: its coordinate; name: "x", "y", "a" or "b"; drive: (2,) commanded-acceleration weights
    of its belt coordinate; cycle: λ (mm); peak: F_hold·1000; stiffness: k_m (kg/s²);
    damping: c_r (kg/s, the diagonal of the modal damping matrix at the rotor); mass: m_r (kg)."""

    index: int
    name: str
    drive: np.ndarray
    cycle: float
    peak: float
    stiffness: float
    damping: float
    mass: float

    @property
    def scale(self) -> float:
        """mm of belt per radian of the electrical angle."""
        return self.cycle / (2.0 * math.pi)


def _modal_coordinates(printer) -> tuple[list, list, list, list, list, list]:
    """(names, axis index, mass kg, nozzle share, damping ratio, ω rad/s) of each described mode."""
    names, axis, mass, share, zeta, omega = [], [], [], [], [], []
    for ai, ax in enumerate(("x", "y")):
        total = printer.moving_mass(ax)
        for j, m in enumerate(printer.effective_modes(ax)):
            names.append(f"{ax}{j}")
            axis.append(ai)
            mass.append(max(m.mass_fraction, 1e-6) * total)
            share.append(m.share)
            zeta.append(m.damping)
            omega.append(m.omega)
    return names, axis, mass, share, zeta, omega


def _rotor_coordinates(printer, names: list, axis: list, mass: list, share: list) -> tuple[list, list]:
    """(rotors, their motors), each rotor appended as one more coordinate to the lists given."""
    corexy = printer.kinematics == "corexy"
    rotors, motor_of = [], []
    for k, (mname, mo, drv) in enumerate(printer.drive_motors()):
        rotors.append(Rotor(len(names), mname, np.array(drv), mo.electrical_cycle, mo.force * 1e3,
                            mo.magnetic_stiffness, 0.0, max(mo.rotor_mass, 1e-4)))
        motor_of.append(mo)
        names.append(f"motor_{mname}")
        axis.append(0 if mname in ("x", "a") or (mname == "b" and not corexy) else 1)
        mass.append(rotors[-1].mass)
        share.append(0.0)
    return rotors, motor_of


def _mode_spring_vectors(rotors: list, axis: np.ndarray, nb: int, n: int) -> tuple[np.ndarray, list]:
    """(base, vecs): the motor side of each axis as weights on the rotor coordinates (the least-squares
    inverse of the drive: cartesian X, Y; CoreXY x = (A + B)/2, y = (A − B)/2; CoreXZ x = (A + B)/2,
    y = Y), and each mode's spring stretch vector (its coordinate minus its axis's motor side)."""
    D = np.stack([r.drive for r in rotors], axis=1)                 # (2, k) belt per unit axis
    base = np.zeros((2, n))
    base[:, nb:] = np.linalg.pinv(D.T)
    vecs = []
    for i in range(nb):
        v = -base[axis[i]].copy()
        v[i] += 1.0
        vecs.append(v)
    return base, vecs


def _rotor_and_belt_stiffness(printer, names: list, rotors: list, n: int) -> tuple[np.ndarray, list]:
    """(K0, belts): the rotors' magnetic stiffness and, on a CoreXY, its two belts (N/m)."""
    belts = []
    K0 = np.zeros((n, n))
    for r in rotors:
        K0[r.index, r.index] += r.stiffness
    if printer.kinematics == "corexy":
        ix, iy = names.index("x0"), names.index("y0")
        ka, kb = printer.belt_stiffnesses()
        for bname, sgn, kk, r in (("belt_a", 1.0, ka, rotors[0]), ("belt_b", -1.0, kb, rotors[1])):
            v = np.zeros(n)
            v[ix], v[iy], v[r.index] = 1.0, sgn, -1.0
            K0 += kk * np.outer(v, v)
            belts.append((bname, v, kk, 0.0))
    return K0, belts


def _check_rk4_step(K: np.ndarray, mass: np.ndarray) -> None:
    """Refuse a rotor mode too stiff for RK4 at :data:`TIMESTEP` (ω·h over :data:`MAX_OMEGA_H`)."""
    w_top = undamped_frequencies(K, mass)[-1]
    if w_top * TIMESTEP > MAX_OMEGA_H:
        raise RingtuneError(
            f"the rotor mode at {w_top / (2 * math.pi):.0f} Hz is too stiff for RK4 at "
            f"{TIMESTEP * 1e3:g} ms (ω·h = {w_top * TIMESTEP:.2f} > {MAX_OMEGA_H:g}); raise "
            "[motor].rotor_mass or set [motor].slip = false", "[motor].rotor_mass")


def slip_system(printer):
    """The printer's linearised slip model as a :class:`~ringtune.envs.modal_system.LinearSystem` (rotors
    included, springs solved so the described frequencies and shares hold exactly)."""
    names, axis, mass, share, zeta, omega = _modal_coordinates(printer)
    nb = len(names)
    rotors, motor_of = _rotor_coordinates(printer, names, axis, mass, share)
    n = len(names)
    mass = np.array(mass, float)
    axis = np.array(axis, int)
    drive = np.zeros((n, 2))
    drive[np.arange(nb), axis[:nb]] = 1.0
    for r in rotors:
        drive[r.index] = r.drive
    base, vecs = _mode_spring_vectors(rotors, axis, nb, n)
    K0, belts = _rotor_and_belt_stiffness(printer, names, rotors, n)
    targets = np.sort(np.array(omega))
    kmode = _solve_springs(K0, vecs, mass, np.array(mass[:nb]) * np.array(omega) ** 2, targets, printer)
    K = K0.copy()
    springs = list(belts)
    for i, (v, k) in enumerate(zip(vecs, kmode)):
        K += k * np.outer(v, v)
        springs.append((f"spring_{names[i]}", v, k, 0.0))
    _check_rk4_step(K, mass)
    C = _modal_damping(K, mass, np.array(omega), np.array(zeta),
                       np.array([m.rotor_damping for m in motor_of]), np.array([r.index for r in rotors]))
    springs, joint_damping = _damper_tendons(C, springs)
    scale = np.ones(n)
    for r in rotors:
        r.damping = float(C[r.index, r.index])
        scale[r.index] = r.scale
    W = _nozzle_weights(K, mass, drive, base, axis[:nb], np.array(share[:nb]), np.array(omega))
    springs = [(nm, {j: float(c) for j, c in enumerate(v) if c != 0.0}, k, c) for nm, v, k, c in springs]
    return LinearSystem(names, axis, mass, np.array(share, float), K, C, np.zeros(n), joint_damping,
                        [], printer.kinematics, drive=drive, nozzle_w=W, scale=scale, rotors=rotors,
                        springs=springs)


def undamped_frequencies(K: np.ndarray, mass: np.ndarray) -> np.ndarray:
    """Sorted undamped angular frequencies (rad/s) of ``K φ = ω² diag(mass) φ``."""
    s = 1.0 / np.sqrt(mass)
    w2 = np.linalg.eigvalsh(K * s[:, None] * s[None, :])
    return np.sqrt(np.maximum(w2, 0.0))


def _solve_springs(K0, vecs, mass, k_init, targets, printer) -> np.ndarray:
    """Mode-spring stiffnesses (kg/s²) whose system's lowest len(targets) undamped frequencies are
    ``targets`` (rad/s, sorted). Newton on log-stiffness with a finite-difference Jacobian."""
    nb = len(vecs)
    outer = [np.outer(v, v) for v in vecs]

    def log_freqs(logk):
        """log of the lowest nb frequencies; non-finite when the stiffness has run away (a mode
        at 0 Hz, or an eigen-solve that fails on ~1e15 kg/s² springs): the description is infeasible."""
        K = K0 + sum(math.exp(x) * o for x, o in zip(logk, outer))
        try:
            f = undamped_frequencies(K, mass)[:nb]
        except np.linalg.LinAlgError:
            return np.full(nb, np.nan)
        with np.errstate(divide="ignore"):
            return np.log(f)

    x = np.log(np.asarray(k_init, float))
    ok = False
    for _ in range(60):
        lf = log_freqs(x)
        res = lf - np.log(targets)
        if not np.all(np.isfinite(res)):
            break
        if np.max(np.abs(res)) < 1e-12:
            ok = True
            break
        step = _newton_step(log_freqs, x, lf, res)
        if step is None:
            break
        x = x + step
        if np.max(x) > 60:
            break
    if not ok:
        raise _motor_too_weak(printer, targets)
    return np.exp(x)


def _newton_step(log_freqs, x: np.ndarray, lf: np.ndarray, res: np.ndarray) -> np.ndarray | None:
    """Newton's step on log-stiffness (finite-difference Jacobian, at most e² per iteration), None
    when the Jacobian is not finite or singular."""
    nb = len(x)
    J = np.empty((nb, nb))
    for j in range(nb):
        dx = np.zeros(nb)
        dx[j] = 1e-6
        J[:, j] = (log_freqs(x + dx) - lf) / 1e-6
    if not np.all(np.isfinite(J)):
        return None
    try:
        step = np.linalg.solve(J, -res)
    except np.linalg.LinAlgError:
        return None
    return step * min(1.0, 2.0 / max(np.max(np.abs(step)), 1e-300))


def _motor_too_weak(printer, targets) -> RingtuneError:
    """The refusal when no spring stiffness gives the described modes: the weakest motor's magnetic
    stiffness cannot carry them in series with the belts."""
    mo = min((m for _n, m, _d in printer.drive_motors()), key=lambda m: m.magnetic_stiffness)
    key = "[motor].run_current" if mo.has_datasheet else "[motor].force"
    return RingtuneError(
        f"the motor's magnetic stiffness ({mo.magnetic_stiffness / 1e3:.0f} N/mm from force "
        f"{mo.force:.3g} N over an electrical cycle of {mo.electrical_cycle:g} mm) cannot carry the "
        f"described modes up to {targets[-1] / (2 * math.pi):.1f} Hz in series with the belts; raise "
        f"{key}, lower the masses, or set [motor].slip = false", key)


def _modal_damping(K, mass, omega, zeta, rotor_zeta, rotor_index) -> np.ndarray:
    """Damping matrix (kg/s) that is exactly modal: ``C = M Φ diag(2ζ_j ω_j) Φᵀ M`` with
    mass-normalised modes Φ of (K, M); each described mode gets its ζ (matched by frequency), each
    rotor mode the ``rotor_zeta`` of the rotor that moves most in it (``rotor_index``: their
    coordinates). With exact frequencies and shares this makes the nozzle's linear response
    identical to the rigid-motor model's."""
    s = 1.0 / np.sqrt(mass)
    w2, psi = np.linalg.eigh(K * s[:, None] * s[None, :])
    phi = psi * s[:, None]
    wfreq = np.sqrt(np.maximum(w2, 0.0))
    rz = np.asarray(rotor_zeta, float)
    z = rz[np.argmax(np.abs(psi[np.asarray(rotor_index)]), axis=0)]
    for w, zz in zip(omega, zeta):
        z[int(np.argmin(np.abs(wfreq - w)))] = zz
    Mphi = mass[:, None] * phi
    C = Mphi @ np.diag(2.0 * z * wfreq) @ Mphi.T
    return 0.5 * (C + C.T)


def _damper_tendons(C: np.ndarray, springs: list) -> tuple[list, np.ndarray]:
    """Realise a full damping matrix sparsely: each off-diagonal C_ij as a two-joint tendon
    e_i + sign(C_ij)·e_j of damping |C_ij| (merged into a spring tendon along the same vector),
    the rest of the diagonal as joint damping (may be negative; only the sum matters).
    Returns (tendons, joint damping)."""
    n = len(C)
    tol = 1e-12 * max(np.abs(C).max(), 1e-300)
    out = [list(t) for t in springs]
    joint = np.diag(C).copy()
    for i in range(n):
        for j in range(i + 1, n):
            c = C[i, j]
            if abs(c) <= tol:
                continue
            v = np.zeros(n)
            v[i], v[j] = 1.0, math.copysign(1.0, c)
            joint[i] -= abs(c)
            joint[j] -= abs(c)
            for t in out:
                if np.array_equal(t[1], v) or np.array_equal(t[1], -v):
                    t[3] += abs(c)
                    break
            else:
                out.append([f"damper_{i}_{j}", v, 0.0, abs(c)])
    return [tuple(t) for t in out], joint


def _nozzle_weights(K, mass, drive, base, axis_b, share, omega) -> np.ndarray:
    """(n, 2) nozzle weights over each axis's mode bodies and its motor side, so that for a
    commanded acceleration along the axis the nozzle's modal shares are the described ones on the
    described modes and zero on every other mode (least squares; exact for decoupled axes)."""
    n = len(mass)
    s = 1.0 / np.sqrt(mass)
    w2, psi = np.linalg.eigh(K * s[:, None] * s[None, :])
    phi = psi * s[:, None]                                  # mass-normalised modes
    wfreq = np.sqrt(np.maximum(w2, 0.0))
    W = np.zeros((n, 2))
    for ax in (0, 1):
        bodies = np.flatnonzero(axis_b == ax)
        gamma = phi.T @ (mass * drive[:, ax])               # participation per mode
        cols = [phi[i] for i in bodies] + [base[ax] @ phi]  # each unknown weight's mode shape
        A = np.stack(cols, axis=1) * gamma[:, None]         # (modes, unknowns): share per unit weight
        target = np.zeros(n)
        for i in bodies:
            target[int(np.argmin(np.abs(wfreq - omega[i])))] += share[i]
        sol, *_ = np.linalg.lstsq(A, target, rcond=None)
        W[bodies, ax] = sol[:-1]
        W[:, ax] += sol[-1] * base[ax]
    return W
