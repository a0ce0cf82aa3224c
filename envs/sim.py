"""Simulate a printer following a commanded (planned, shaped) motion.

``simulate(printer, motion)`` drives the MuJoCo model of :mod:`ringtune.envs.model` with the motion's
x/y acceleration through ``mujoco.rollout`` (one C++ call, no Python loop per step) and returns a
:class:`SimResult`; ``backend="lti"`` gives the exact linear answer from :mod:`ringtune.envs.lti`.
``simulate_batch`` runs many motions (and printers) in one threaded rollout.

Input to the integrator: RK4 holds the control constant over each step, but the motion's
acceleration changes at arbitrary times. Each step's control is the exact mean acceleration over the
step (Δv/h) plus a correction that also restores the first moment of the acceleration in time
(``m_k = h(v_k + v_{k+1})/2 − (p_{k+1} − p_k)``, moved to the neighbouring steps as ±m_k/2h²); a
jump inside a step then costs O((ωh)³) instead of O((ωh)²).

Everything derived (nozzle, head acceleration, motor forces, step loss) is computed exactly from
the state (q, q̇) by the same vectorised post-processing for both backends.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ringtune.envs.model import INTEGRATOR, TIMESTEP, LinearSystem, build_model, linear_system
from ringtune.envs.printer import Printer, load_printer
from ringtune.shaping.errors import RingtuneError

BACKENDS = ("mujoco", "lti")


@dataclass
class SimResult:
    """One simulated run, sampled uniformly.

    Attributes:
        t: (m,) s.
        commanded: (m, 2) commanded (shaped) x, y, mm.
        nozzle: (m, 2) simulated nozzle relative to the print (bed frame), mm.
        head_accel: (m, 2) absolute acceleration of the head (x) and bed (y, cartesian), mm/s².
        motor_force: (m, k) force each motor must give at the belt, N (cartesian: X, Y; CoreXY: A, B).
        motor_force_max: (m, k) force each motor can give at its current speed, N.
        step_loss: whether the demanded force ever exceeded what the motor has.
        accel_sensor: (m, 3) what an accelerometer on the toolhead reads, mm/s² (x, y, z; z = 0).
        step_loss_time: first time (s) of step loss, or None.
        backend: "mujoco" or "lti".
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

    @property
    def deviation(self) -> np.ndarray:
        """(m, 2) nozzle minus commanded, mm."""
        return self.nozzle - self.commanded

    @property
    def force_ratio(self) -> float:
        """Largest demanded/available motor force (> 1 means step loss)."""
        return float(np.max(np.abs(self.motor_force) / self.motor_force_max))


def _kinematics(motion, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(p, v, a) of x, y at sorted times ``t`` ≥ start; after the motion's end the commanded
    acceleration is zero, so a motion that ends at rest stays put and a window cut mid-move
    continues at its end velocity (no fictitious velocity jump)."""
    te = motion.end_time
    tc = np.minimum(t, te)
    p = motion.position(tc)[:, :2]
    v = motion.velocity(tc)[:, :2]
    a = motion.acceleration(tc)[:, :2]
    after = t >= te
    if after.any():
        p[after] += v[after] * (t[after] - te)[:, None]
        a[after] = 0.0
    return p, v, a


def _step_controls(motion, t0: float, h: float, nstep: int) -> np.ndarray:
    """(nstep, 2) per-step control −a (mm/s²) with mean and first moment of the true input."""
    p, v, _ = _kinematics(motion, t0 + np.arange(nstep + 1) * h)
    mean = np.diff(v, axis=0) / h
    m1 = 0.5 * h * (v[:-1] + v[1:]) - np.diff(p, axis=0)          # first-moment residual per step
    corr = np.zeros_like(mean)
    corr[1:] += m1[:-1]
    corr[:-1] -= m1[1:]
    return -(mean + corr / (2.0 * h * h))


def _post(printer: Printer, sysm: LinearSystem, motion, t: np.ndarray, q: np.ndarray,
          qd: np.ndarray, backend: str) -> SimResult:
    """Everything derived from the state samples (exact for the linear mechanics)."""
    p, v, a = _kinematics(motion, t)
    qdd = sysm.qacc(q, qd, a)
    onehot = np.zeros((sysm.n, 2))
    onehot[np.arange(sysm.n), sysm.axis] = 1.0
    dev = q @ (onehot * sysm.share[:, None])
    head = a + qdd @ (onehot * sysm.share[:, None])
    # force through the belts on each axis: Σ m_i (a_cmd + q̈_i), kg·mm/s² -> N
    f_axis = (qdd + a[:, sysm.axis]) @ (onehot * sysm.mass[:, None]) * 1e-3
    mo = printer.motor
    if printer.kinematics == "corexy":
        f_belt = np.stack([(f_axis[:, 0] + f_axis[:, 1]) / 2, (f_axis[:, 0] - f_axis[:, 1]) / 2], axis=1)
        vm = np.stack([v[:, 0] + v[:, 1], v[:, 0] - v[:, 1]], axis=1)
        am = np.stack([a[:, 0] + a[:, 1], a[:, 0] - a[:, 1]], axis=1)
    else:
        f_belt, vm, am = f_axis, v, a
    force = f_belt + mo.rotor_mass * am * 1e-3 + mo.friction * np.sign(vm)
    fmax = mo.max_force(vm)
    over = np.abs(force) > fmax
    hit = np.flatnonzero(over.any(axis=1))
    sensor = np.zeros((len(t), 3))
    sensor[:, :2] = head
    return SimResult(t=t, commanded=p, nozzle=p + dev, head_accel=head, motor_force=force,
                     motor_force_max=fmax, step_loss=bool(len(hit)), accel_sensor=sensor,
                     step_loss_time=float(t[hit[0]]) if len(hit) else None, backend=backend)


def _grid(motion, h: float, tail: float) -> int:
    return max(1, int(np.ceil((motion.duration + tail) / h - 1e-9)))


def _decimation(h: float, rate: float | None) -> int:
    if rate is None:
        return 1
    r = int(round(1.0 / (h * rate)))
    if r < 1 or abs(r * h * rate - 1.0) > 1e-6:
        raise RingtuneError(f"rate {rate:g} Hz must divide the simulation rate {1 / h:g} Hz", "rate")
    return r


def _initial(sysm: LinearSystem, motion, initial: str) -> np.ndarray:
    if initial == "rest":
        return np.zeros(2 * sysm.n)
    if initial == "static":
        a0 = motion.acceleration(np.array([motion.start_time]))[0, :2]
        return np.concatenate([sysm.static_deflection(a0), np.zeros(sysm.n)])
    raise RingtuneError(f"initial must be 'rest' or 'static', not {initial!r}", "initial")


def simulate(printer: Printer | None, motion, backend: str = "mujoco", rate: float | None = None,
             tail: float = 0.0, timestep: float = TIMESTEP, initial: str = "rest") -> SimResult:
    """Simulate ``printer`` (None = embedded default) following ``motion``.

    Args:
        backend: "mujoco" (default) or "lti" (exact linear reference, much faster).
        rate: output sample rate, Hz (default 1/timestep; must divide it).
        tail: seconds simulated after the motion ends (the machine keeps ringing at rest).
        timestep: integration step, s (RK4).
        initial: "rest" (no deflection at the start) or "static" (settled under the initial
            commanded acceleration, for windows cut out of a longer motion).
    """
    return simulate_batch(printer, [motion], backend=backend, rate=rate, tail=tail,
                          timestep=timestep, initial=initial, nthread=1)[0]


def simulate_batch(printer_or_list, motions: list, backend: str = "mujoco", nthread: int | None = None,
                   rate: float | None = None, tail: float = 0.0, timestep: float = TIMESTEP,
                   initial: str = "rest") -> list[SimResult]:
    """Simulate many motions in one threaded rollout; ``printer_or_list`` is one printer for all or
    one per motion. Results come back in the order of ``motions``."""
    if backend not in BACKENDS:
        raise RingtuneError(f"backend must be one of {', '.join(BACKENDS)}, not {backend!r}", "--backend")
    motions = list(motions)
    if isinstance(printer_or_list, (list, tuple)):
        printers = [load_printer(p) if not isinstance(p, Printer) else p for p in printer_or_list]
        if len(printers) != len(motions):
            raise RingtuneError(f"{len(printers)} printers for {len(motions)} motions", "simulate_batch")
    else:
        pr = printer_or_list if isinstance(printer_or_list, Printer) else load_printer(printer_or_list)
        printers = [pr] * len(motions)
    if not motions:
        return []
    h = float(timestep)
    dec = _decimation(h, rate)
    systems = {}
    for p in printers:
        if id(p) not in systems:
            systems[id(p)] = linear_system(p)
    if backend == "lti":
        out = []
        for p, mo in zip(printers, motions):
            sysm = systems[id(p)]
            nstep = _grid(mo, h, tail)
            t = mo.start_time + np.arange(0, nstep + 1, dec) * h
            q, qd = lti_response(sysm, mo, t, _initial(sysm, mo, initial))
            out.append(_post(p, sysm, mo, t, q, qd, "lti"))
        return out
    return _rollout(printers, systems, motions, h, dec, tail, initial, nthread)


def lti_response(sysm, motion, t, x0):
    from ringtune.envs.lti import response

    return response(sysm, motion, t, x0)


def _rollout(printers, systems, motions, h, dec, tail, initial, nthread):
    import mujoco
    from mujoco import rollout

    models = [build_model(p, h, INTEGRATOR) for p in printers]
    # group homogeneous models (same sizes) so each group is one rollout call
    groups: dict = {}
    for i, m in enumerate(models):
        groups.setdefault((m.nq, m.nv, m.nu, m.ntendon), []).append(i)
    results: list = [None] * len(motions)
    if nthread is None:
        nthread = min(len(motions), os.cpu_count() or 1)
    for idx in groups.values():
        nsteps = [_grid(motions[i], h, tail) for i in idx]
        nmax = max(nsteps)
        m0 = models[idx[0]]
        nq = m0.nq
        nstate = mujoco.mj_stateSize(m0, mujoco.mjtState.mjSTATE_FULLPHYSICS)
        init = np.zeros((len(idx), nstate))
        ctrl = np.zeros((len(idx), nmax, m0.nu))
        for b, i in enumerate(idx):
            mo = motions[i]
            sysm = systems[id(printers[i])]
            init[b, 0] = mo.start_time
            x0 = _initial(sysm, mo, initial)
            init[b, 1:1 + nq] = x0[:nq]
            init[b, 1 + nq:1 + 2 * nq] = x0[nq:]
            ctrl[b, :nsteps[b]] = _step_controls(mo, mo.start_time, h, nsteps[b])
        nth = max(1, min(nthread, len(idx)))
        datas = [mujoco.MjData(m0) for _ in range(nth)]
        mlist = [models[i] for i in idx] if len(idx) > 1 else m0
        state, _ = rollout.rollout(mlist, datas if nth > 1 else datas[0], init, ctrl)
        for b, i in enumerate(idx):
            st = np.concatenate([init[b][None], state[b, :nsteps[b]]])[::dec]
            mo = motions[i]
            t = mo.start_time + np.arange(0, nsteps[b] + 1, dec) * h
            q = st[:, 1:1 + nq]
            qd = st[:, 1 + nq:1 + 2 * nq]
            results[i] = _post(printers[i], systems[id(printers[i])], mo, t, q, qd, "mujoco")
    return results


def resonance_test(printer: Printer | None, axis: str, rng: np.random.Generator | None = None,
                   accel_per_hz: float = 60.0, freq_start: float = 5.0, freq_end: float = 135.0,
                   sample_rate: float = 3200.0, max_freq: float = 200.0, noise_floor: float = 50.0,
                   dof: float = 6.0) -> tuple[np.ndarray, np.ndarray]:
    """PSD of the head acceleration along ``axis`` as Klipper's ``TEST_RESONANCES`` would record it.

    Excitation model: Klipper sweeps a commanded sinusoidal acceleration of amplitude
    ``accel_per_hz·f`` (mm/s²) from ``freq_start`` to ``freq_end`` at constant rate; a slow sweep
    spends ``1/(f_end − f_start)`` of its time per Hz, so the Welch-averaged PSD of the head
    acceleration is ``(accel_per_hz·f·|T(f)|)² / (2·(f_end − f_start))`` in (mm/s²)²/Hz inside the
    sweep, with ``T`` the exact transmissibility of the linear model (CoreXY coupling included),
    plus a flat sensor ``noise_floor``. Bins are Klipper's: 0.5 s windows rounded up to a power of
    two at ``sample_rate`` (1.5625 Hz at 3200 Hz), up to ``max_freq``.

    With ``rng`` each bin is scattered like a Welch estimate (Gamma with ``dof`` degrees of freedom,
    mean preserved); without it the expected PSD is returned. Returns (freqs, psd)."""
    from ringtune.envs.lti import frequency_response

    pr = printer if isinstance(printer, Printer) else load_printer(printer)
    if axis not in ("x", "y"):
        raise RingtuneError(f"axis must be 'x' or 'y', not {axis!r}", "axis")
    nfft = 1 << int(np.ceil(np.log2(sample_rate * 0.5)))
    df = sample_rate / nfft
    freqs = np.arange(0, int(max_freq / df) + 1) * df
    sysm = linear_system(pr)
    T = frequency_response(sysm, np.maximum(freqs, 1e-3), 0 if axis == "x" else 1)
    inside = (freqs >= freq_start) & (freqs <= freq_end)
    psd = np.where(inside, (accel_per_hz * freqs * np.abs(T)) ** 2 / (2.0 * (freq_end - freq_start)), 0.0)
    psd = psd + noise_floor
    if rng is not None:
        psd = psd * rng.gamma(dof / 2.0, 2.0 / dof, size=psd.shape)
    return freqs, psd
