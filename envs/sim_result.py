"""What a simulation gives back (:class:`SimResult`) and how it is derived from the state samples
(q, q̇) the same way for both backends of :mod:`ringtune.envs.sim` (:func:`post_process`): the
nozzle, the head's acceleration, each motor's demanded and available force (:func:`motor_forces`)
and step loss (rigid motor, or the slip model's rotors of :mod:`ringtune.envs.rotor`).
Units: mm, s, mm/s², N."""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ringtune.envs.modal_system import LinearSystem
from ringtune.envs.printer_model import Printer


@dataclass
class SimResult:
    """One simulated run, sampled uniformly.

    Attributes:
        t: (m,) s.
        commanded: (m, 2) commanded (shaped) x, y, mm.
        nozzle: (m, 2) simulated nozzle relative to the print (bed frame), mm.
        head_accel: (m, 2) absolute acceleration of the head (x) and bed (y, cartesian), mm/s².
        motor_force: (m, k) force each motor must give at the belt, N (cartesian: X, Y; CoreXY: A, B;
            CoreXZ: A, B, Y — :meth:`Printer.drive_motors`).
        motor_force_max: (m, k) force each motor can give at its current speed, N.
        step_loss: whether the demanded force ever exceeded what the motor has.
        accel_sensor: (m, 3) what an accelerometer on the toolhead reads, mm/s² (x, y, z; z = 0).
        step_loss_time: first time (s) of step loss, or None.
        backend: "mujoco" or "lti".
        rotor_lag: (m, k) mm each rotor sits relative to its commanded (electrical) position, with
            ``[motor] slip = true`` (None otherwise); a skipped step shows as a lag that stays
            a whole number of electrical cycles after the load is gone.
    """

    t: np.ndarray
    commanded: np.ndarray
    nozzle: np.ndarray
    head_accel: np.ndarray
    motor_force: np.ndarray
    motor_force_max: np.ndarray
    step_loss: bool
    accel_sensor: np.ndarray
    step_loss_time: float | None = None
    backend: str = "mujoco"
    rotor_lag: np.ndarray | None = None

    @property
    def deviation(self) -> np.ndarray:
        """(m, 2) nozzle minus commanded, mm."""
        return self.nozzle - self.commanded

    @property
    def force_ratio(self) -> float:
        """Largest demanded/available motor force (> 1 means step loss)."""
        return float(np.max(np.abs(self.motor_force) / self.motor_force_max))


def post_process(printer: Printer, sysm: LinearSystem, kin, t: np.ndarray, q: np.ndarray,
          qd: np.ndarray, backend: str) -> SimResult:
    """Everything derived from the state samples (exact for the linear mechanics); ``kin`` is the
    commanded (p, v, a) at ``t``."""
    p, v, a = kin
    if sysm.rotors:
        return _post_slip(printer, sysm, kin, t, q, qd, backend)
    qdd = sysm.qacc(q, qd, a)
    onehot = np.zeros((sysm.n, 2))
    onehot[np.arange(sysm.n), sysm.axis] = 1.0
    dev = q @ (onehot * sysm.share[:, None])
    head = a + qdd @ (onehot * sysm.share[:, None])
    # force through the belts on each axis: Σ m_i (a_cmd + q̈_i), kg·mm/s² -> N
    f_axis = (qdd + a[:, sysm.axis]) @ (onehot * sysm.mass[:, None]) * 1e-3
    force, fmax, _ = motor_forces(printer, f_axis, v, a)
    over = np.abs(force) > fmax
    return _result(t, p, dev, head, force, fmax, over, backend)


def motor_forces(printer: Printer, f_axis: np.ndarray, v: np.ndarray, a: np.ndarray):
    """(force, force_max, motors): per motor of :meth:`Printer.drive_motors` (columns), the force
    (N) it must give at the belt and the force its own curve allows at its belt speed.

    ``f_axis`` (m, 2): N through the belts on X and Y (Newton on the moving masses); ``v``, ``a``
    (m, 2): commanded mm/s, mm/s². The axis forces are shared by the motors with the least-squares
    inverse of the drive (cartesian: X, Y; CoreXY A = (f_x + f_y)/2, B = (f_x − f_y)/2; CoreXZ
    A = B = f_x/2, Y = f_y); each motor adds its rotor's inertia (m_r·a_motor) and friction."""
    motors = printer.drive_motors()
    D = np.array([d for _n, _m, d in motors], float).T                # (2, k)
    f_belt = f_axis @ drive_inverse(D)
    vm, am = v @ D, a @ D
    mr = np.array([mo.rotor_mass for _n, mo, _d in motors])
    fr = np.array([mo.friction for _n, mo, _d in motors])
    force = f_belt + mr * am * 1e-3 + fr * np.sign(vm)
    fmax = np.stack([mo.max_force(vm[:, k]) for k, (_n, mo, _d) in enumerate(motors)], axis=1)
    return force, fmax, motors


@functools.lru_cache(maxsize=64)
def _drive_inverse_of(key: bytes, shape: tuple) -> np.ndarray:
    inv = np.linalg.pinv(np.frombuffer(key).reshape(shape).T)
    inv.flags.writeable = False          # one array handed to every caller
    return inv


def drive_inverse(D: np.ndarray) -> np.ndarray:
    """The least-squares inverse of the drive ``D`` (2, k) as ``np.linalg.pinv(D.T)`` gives it,
    computed once per drive (every window and plan of a study asks it of the same few); read-only."""
    return _drive_inverse_of(np.ascontiguousarray(D).tobytes(), D.shape)


def _result(t, p, dev, head, force, fmax, over, backend, rotor_lag=None) -> SimResult:
    hit = np.flatnonzero(over.any(axis=1))
    sensor = np.zeros((len(t), 3))
    sensor[:, :2] = head
    return SimResult(t=t, commanded=p, nozzle=p + dev, head_accel=head, motor_force=force,
                     motor_force_max=fmax, step_loss=bool(len(hit)), accel_sensor=sensor,
                     step_loss_time=float(t[hit[0]]) if len(hit) else None, backend=backend,
                     rotor_lag=rotor_lag)


def _post_slip(printer: Printer, sysm: LinearSystem, kin, t, q, qd, backend: str) -> SimResult:
    """Post-processing of the slip model (:mod:`ringtune.envs.rotor`): the MuJoCo rotors feel the
    sinusoidal magnetic force, the LTI ones its linearisation.

    ``motor_force`` is what each motor must give for its rotor to follow the command, by the same
    definition as the rigid-motor model (Newton on the moving masses, Σ m_i (a_cmd + q̈_i) per
    axis, split over the CoreXY belts, plus m_r·a_motor and friction), evaluated on the real state.
    ``step_loss``: that force exceeds the force at the motor's speed, or a rotor lags one full step
    or more (past the peak of its torque–angle curve)."""
    p, v, a = kin
    W = sysm.W
    qdd = sysm.qacc(q, qd, a, nonlinear=backend == "mujoco")
    dev = q @ W
    head = a + qdd @ W
    idx = np.array([r.index for r in sysm.rotors])
    nb = idx.min()                                                    # mode bodies come first
    onehot = np.zeros((nb, 2))
    onehot[np.arange(nb), sysm.axis[:nb]] = 1.0
    f_axis = (qdd[:, :nb] + a[:, sysm.axis[:nb]]) @ (onehot * sysm.mass[:nb, None]) * 1e-3
    force, fmax, motors = motor_forces(printer, f_axis, v, a)
    full_step = np.array([mo.full_step for _n, mo, _d in motors])
    lag = q[:, idx]
    over = (np.abs(force) > fmax) | (np.abs(lag) >= full_step)
    return _result(t, p, dev, head, force, fmax, over, backend, rotor_lag=lag)
