"""Simulate a printer following a commanded (planned, shaped) motion.

``simulate(printer, motion)`` drives the MuJoCo model of :mod:`ringtune.envs.mujoco_model` with the motion's
x/y acceleration through ``mujoco.rollout`` (one C++ call, no Python loop per step) and returns a
:class:`SimResult`; ``backend="lti"`` gives the exact linear answer from :mod:`ringtune.envs.lti`.
``simulate_batch`` runs many motions (and printers) in one threaded rollout.

Input to the integrator: RK4 holds the control constant over each step, but the motion's
acceleration changes at arbitrary times. Each step's control is the exact mean acceleration over the
step (Δv/h) plus a correction that also restores the first moment of the acceleration in time
(``m_k = h(v_k + v_{k+1})/2 − (p_{k+1} − p_k)``, moved to the neighbouring steps as ±m_k/2h²); a
jump inside a step then costs O((ωh)³) instead of O((ωh)²).

Everything derived (nozzle, head acceleration, motor forces, step loss) is computed exactly from
the state (q, q̇) by the same vectorised post-processing for both backends
(:func:`ringtune.envs.sim_result.post_process`).

Slip model (:mod:`ringtune.envs.rotor`, the default when the motor can carry the described modes):
MuJoCo's rotors feel the stepper's sinusoidal magnet, the LTI backend its linearisation, so below
the holding force both agree and above it only MuJoCo skips steps. ``SimResult.rotor_lag`` then
reports each rotor's lag; ``step_loss`` is flagged by the demanded force exceeding the force at
the motor's speed (as for the rigid motor) or by a rotor lagging one full step (past the torque
peak) — in MuJoCo that is a real, permanent skip.
"""

from __future__ import annotations

import math
import os

import mujoco
import numpy as np
from mujoco import rollout

from ringtune.envs.lti import frequency_response_along, response
from ringtune.envs.modal_system import LinearSystem
from ringtune.envs.mujoco_model import INTEGRATOR, TIMESTEP, build_model, drive_gains, linear_system
from ringtune.envs.printer import load_printer
from ringtune.envs.printer_model import Printer
from ringtune.envs.sim_result import SimResult, post_process
from ringtune.shaping.errors import RingtuneError

BACKENDS = ("mujoco", "lti")


def _kinematics(motion, t0: float, h: float, m: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(p, v, a) of x, y on the grid ``t0 + k·h``, k < m, in O(n + m) without a search.

    After the motion's end the commanded acceleration is zero, so a motion that ends at rest stays
    put and a window cut mid-move continues at its end velocity (no fictitious velocity jump)."""
    times = t0 + np.arange(m) * h
    tb = motion.t
    first = np.clip(np.ceil((tb - t0) / h - 1e-9).astype(np.int64), 0, m)
    idx = np.repeat(np.arange(motion.n_segments), np.diff(first))
    lo, hi = int(first[0]), int(first[0]) + len(idx)
    p = np.empty((m, 2))
    v = np.empty((m, 2))
    a = np.empty((m, 2))
    tau = (times[lo:hi] - tb[idx])[:, None]
    A = motion.a[idx, :2]
    V = motion.v[idx, :2]
    p[lo:hi] = motion.p[idx, :2] + (V + 0.5 * A * tau) * tau
    v[lo:hi] = V + A * tau
    a[lo:hi] = A
    if lo > 0:
        p[:lo] = motion.p[0, :2]
        v[:lo] = 0.0
        a[:lo] = 0.0
    if hi < m:
        pe, ve = motion.end_state()
        dt = (times[hi:] - tb[-1])[:, None]
        p[hi:] = pe[-1, :2] + ve[-1, :2] * dt
        v[hi:] = ve[-1, :2]
        a[hi:] = 0.0
    return p, v, a


def _step_controls(p: np.ndarray, v: np.ndarray, h: float) -> np.ndarray:
    """(nstep, 2) per-step control −a (mm/s²) from grid positions and velocities (nstep+1, 2):
    the exact mean of the acceleration over each step plus the first-moment correction."""
    mean = np.diff(v, axis=0) / h
    m1 = 0.5 * h * (v[:-1] + v[1:]) - np.diff(p, axis=0)          # first-moment residual per step
    corr = np.zeros_like(mean)
    corr[1:] += m1[:-1]
    corr[:-1] -= m1[1:]
    return -(mean + corr / (2.0 * h * h))


def _scale(sysm: LinearSystem) -> np.ndarray:
    """mm per MuJoCo joint unit of each coordinate (rotor hinges are in radians)."""
    return sysm.scale if sysm.scale is not None else np.ones(sysm.n)


def _grid(motion, h: float, tail: float, dec: int = 1) -> int:
    """Steps of ``h`` covering the motion and ``tail``, rounded up to whole output samples
    (multiples of ``dec``) so every backend ends on the same output grid."""
    n = max(1, int(np.ceil((motion.duration + tail) / h - 1e-9)))
    return -(-n // dec) * dec


def _decimation(h: float, rate: float | None) -> int:
    if rate is None:
        return 1
    r = int(round(1.0 / (h * rate)))
    if r < 1 or abs(r * h * rate - 1.0) > 1e-6:
        raise RingtuneError(f"rate {rate:g} Hz must divide the simulation rate {1 / h:g} Hz", "rate")
    return r


def _initial(sysm: LinearSystem, motion, initial: str, nonlinear: bool = False) -> np.ndarray:
    """Initial state [q, q̇]. ``nonlinear`` (MuJoCo slip model): a static rotor sits where its
    sinusoidal magnet gives the linear spring's force, asin(F/F_hold)·λ/2π, and the bodies keep their
    stretch relative to it (when the load exceeds F_hold no rest exists; the linear state is kept)."""
    if initial == "rest":
        return np.zeros(2 * sysm.n)
    if initial == "static":
        a0 = motion.acceleration(np.array([motion.start_time]))[0, :2]
        q = sysm.static_deflection(a0)
        if nonlinear and sysm.rotors:
            shift = np.zeros(sysm.n)
            for r in sysm.rotors:
                ratio = r.stiffness * q[r.index] / r.peak
                if abs(ratio) < 1.0:
                    shift[r.index] = np.arcsin(ratio) * r.scale - q[r.index]
            # the rotors' extra lag carries their bodies (each mode spring keeps its stretch)
            q = q + shift
            for name, coefs, _k, _c in sysm.springs:
                if name.startswith("spring_"):
                    body = sysm.names.index(name[len("spring_"):])
                    q[body] -= sum(c * shift[j] for j, c in coefs.items() if j != body)
        return np.concatenate([q, np.zeros(sysm.n)])
    raise RingtuneError(f"initial must be 'rest' or 'static', not {initial!r}", "initial")


#: accuracy budget of :func:`auto_timestep`: RK4's phase error per cycle grows like (ω·h)⁴ and a
#: mode rings for about 1/ζ cycles, so (ω·h)⁴/ζ bounds the accumulated error. At 1.0, one mode at
#: 150 Hz with ζ = 0.05 and h = 0.5 ms (metric 0.98) stays within 0.35 % RMS of the exact solution.
RK4_ERROR_BUDGET = 1.0


def auto_timestep(printer: Printer) -> float:
    """Integration step (s) for ``printer``: :data:`TIMESTEP` (0.5 ms), divided by the smallest
    integer k that keeps (ω·h)⁴/ζ ≤ :data:`RK4_ERROR_BUDGET` for every mode seen at the nozzle
    (damping floored at 0.005). Integer fractions keep output rates that divide 2 kHz valid.
    The default Ender-3-class printer keeps 0.5 ms; a 150 Hz mode with ζ = 0.01 gets 0.25 ms."""
    k = 1
    for axis in ("x", "y"):
        for mode in printer.effective_modes(axis):
            need = 2 * math.pi * mode.freq * TIMESTEP / (RK4_ERROR_BUDGET * max(mode.damping, 0.005)) ** 0.25
            k = max(k, math.ceil(need - 1e-9))
    return TIMESTEP / k


def simulate(printer: Printer | None, motion, backend: str = "mujoco", rate: float | None = None,
             tail: float = 0.0, timestep: float | None = None, initial: str = "rest") -> SimResult:
    """Simulate ``printer`` (None = embedded default) following ``motion``.

    Args:
        backend: "mujoco" (default) or "lti" (exact linear reference, much faster).
        rate: output sample rate, Hz (must divide 1/timestep; default 2 kHz with the automatic
            timestep, else 1/timestep).
        tail: seconds simulated after the motion ends (commanded acceleration zero: a motion that
            ends at rest rings out in place; a window cut mid-move coasts at its end velocity).
        timestep: integration step, s; None picks it from the printer's modes for MuJoCo
            (:func:`auto_timestep`: 0.5 ms, or an integer fraction of it for lightly damped or
            high modes) and 0.5 ms output sampling for the exact ``lti`` backend.

    Meant for windows of a job (seconds): the MuJoCo backend keeps every state of the rollout in
    memory (about 8·(1 + 2n) bytes per step for n modes).
        initial: "rest" (no deflection at the start) or "static" (settled under the initial
            commanded acceleration, for windows cut out of a longer motion).
    """
    return simulate_batch(printer, [motion], backend=backend, rate=rate, tail=tail,
                          timestep=timestep, initial=initial, nthread=1)[0]


def _batch_printers(printer_or_list, motions: list) -> list[Printer]:
    """One printer per motion: the list given (loaded where a name or path), or one for all."""
    if not isinstance(printer_or_list, (list, tuple)):
        return [load_printer(printer_or_list)] * len(motions)
    printers = [load_printer(p) for p in printer_or_list]
    if len(printers) != len(motions):
        raise RingtuneError(f"{len(printers)} printers for {len(motions)} motions", "simulate_batch")
    return printers


def _batch_timestep(printers: list[Printer], backend: str, timestep: float | None) -> float:
    """The step (s): as given, TIMESTEP for the exact backend (it only sets the output sampling),
    else the finest automatic step of the printers."""
    if timestep is not None:
        h = float(timestep)
    elif backend == "lti":
        h = TIMESTEP
    else:
        h = min(auto_timestep(p) for p in {id(p): p for p in printers}.values())
    if not (h > 0 and np.isfinite(h)):
        raise RingtuneError(f"timestep must be a positive number of seconds, not {timestep!r}", "timestep")
    return h


def _lti_batch(printers, systems, motions, h, dec, tail, initial) -> list[SimResult]:
    """Each motion through the exact linear response (the ``lti`` backend)."""
    out = []
    for p, mo in zip(printers, motions):
        sysm = systems[id(p)]
        t = mo.start_time + np.arange(0, _grid(mo, h, tail, dec) + 1, dec) * h
        q, qd = _lti_response(sysm, mo, t, _initial(sysm, mo, initial))
        out.append(post_process(p, sysm, _kinematics(mo, mo.start_time, h * dec, len(t)), t, q, qd, "lti"))
    return out


def simulate_batch(printer_or_list, motions: list, backend: str = "mujoco", nthread: int | None = None,
                   rate: float | None = None, tail: float = 0.0, timestep: float | None = None,
                   initial: str = "rest") -> list[SimResult]:
    """Simulate many motions in one threaded rollout; ``printer_or_list`` is one printer for all or
    one per motion. Results come back in the order of ``motions``.

    The motions are packed as replicas of one MuJoCo model (up to :data:`MAX_REPLICAS` each),
    which is far cheaper per motion than separate rollouts. ``nthread`` None uses one thread per
    full replica model (up to the CPU count); an explicit ``nthread`` splits the motions over at
    least that many models and threads. Other keywords as :func:`simulate`."""
    if backend not in BACKENDS:
        raise RingtuneError(f"backend must be one of {', '.join(BACKENDS)}, not {backend!r}", "backend")
    motions = list(motions)
    printers = _batch_printers(printer_or_list, motions)
    if not motions:
        return []
    h = _batch_timestep(printers, backend, timestep)
    if not tail >= 0:
        raise RingtuneError(f"tail must be ≥ 0 s, not {tail!r}", "tail")
    # output grid: ``rate``, or 1/TIMESTEP (2 kHz) when the step is automatic, whatever the step
    dec = _decimation(h, rate if rate is not None or timestep is not None else 1.0 / TIMESTEP)
    systems = {id(p): linear_system(p) for p in {id(p): p for p in printers}.values()}
    if backend == "lti":
        return _lti_batch(printers, systems, motions, h, dec, tail, initial)
    return _rollout(printers, systems, motions, h, dec, tail, initial, nthread)


def _lti_response(sysm, motion, t, x0):
    return response(sysm, motion, t, x0)


#: what a rollout's control array gives each step: the generalised forces (the models have no actuators)
_FORCES = int(mujoco.mjtState.mjSTATE_QFRC_APPLIED)
#: most windows packed into one MuJoCo model as independent replicas (amortises per-step cost)
MAX_REPLICAS = 16


def _chunks(n: int, nthread: int) -> list[list[int]]:
    """Split n items into balanced chunks: at least ``nthread`` (if possible), at most MAX_REPLICAS each."""
    k = max(min(nthread, n), -(-n // MAX_REPLICAS))
    size = -(-n // k)
    return [list(range(i, min(i + size, n))) for i in range(0, n, size)]


_DATA_CACHE: dict = {}


def _datas(model, n: int) -> list:
    """n MjData for ``model`` (rollout ignores their contents; reused between calls)."""
    key = id(model)
    got = _DATA_CACHE.get(key)
    if got is None or got[0] is not model or len(got[1]) < n:
        if len(_DATA_CACHE) > 64:
            _DATA_CACHE.clear()
        got = (model, [mujoco.MjData(model) for _ in range(n)])
        _DATA_CACHE[key] = got
    return got[1][:n]


def _pack(group: list[int], chunks, m0, printers, systems, motions, nsteps, h, initial):
    """Initial states and drive forces of one rollout batch (a row per replica model of ``group``)
    and where each motion sits in it: (init, forces, [(batch row, motion, dof offset, kinematics)]).
    The forces are each coordinate's ``qfrc_applied``, :func:`drive_gains` times its control (−a of
    its axis, mm/s²): what the motor actuators would apply, bit for bit."""
    nstate = mujoco.mj_stateSize(m0, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    members = [i for ci in group for i in chunks[ci]]
    init = np.zeros((len(group), nstate))
    ctrl = np.zeros((len(group), max(nsteps[i] for i in members), m0.nv))
    init[:, 0] = min(motions[i].start_time for i in members)
    layout, gains = [], {}
    for b, ci in enumerate(group):
        off = 0
        for i in chunks[ci]:
            sysm, mo, n = systems[id(printers[i])], motions[i], systems[id(printers[i])].n
            x0 = _initial(sysm, mo, initial, nonlinear=True)
            sc = _scale(sysm)
            init[b, 1 + off:1 + off + n] = x0[:n] / sc
            init[b, 1 + m0.nq + off:1 + m0.nq + off + n] = x0[n:] / sc
            kin = _kinematics(mo, mo.start_time, h, nsteps[i] + 1)
            u = _step_controls(kin[0], kin[1], h)                     # (nstep, 2) = −a
            g = gains.get(id(sysm))
            if g is None:
                g = gains[id(sysm)] = drive_gains(sysm)
            ctrl[b, :nsteps[i], off:off + n] = (u @ sysm.B.T if sysm.rotors else u[:, sysm.axis]) * g
            layout.append((b, i, off, kin))
            off += n
    return init, ctrl, layout


def _unpack(layout, init, state, nq, printers, systems, motions, nsteps, h, dec, results) -> None:
    """Each motion's result from a rollout's states, on the output grid (every ``dec``-th step)."""
    for b, i, off, kin in layout:
        sysm, n = systems[id(printers[i])], systems[id(printers[i])].n
        rows = np.arange(0, nsteps[i] + 1, dec)
        t = motions[i].start_time + rows * h
        kin = tuple(k[rows] for k in kin) if dec > 1 else kin
        qs, qds = (_rows(init[b], state[b], len(rows), dec, slice(c, c + n)) for c in (1 + off, 1 + nq + off))
        if sysm.scale is not None:
            qs, qds = qs * sysm.scale, qds * sysm.scale
        results[i] = post_process(printers[i], sysm, kin, t, qs, qds, "mujoco")


def _rows(init_row: np.ndarray, states: np.ndarray, n_rows: int, dec: int, cols: slice) -> np.ndarray:
    """Columns ``cols`` of the states at steps 0, dec, 2·dec, … (``n_rows`` of them; step 0 the
    initial state, step k the rollout's state k − 1), copying only those columns of one replica,
    not the batch row's, through a strided view (twice as fast as gathering the rows by index)."""
    out = np.empty((n_rows, cols.stop - cols.start))
    out[0] = init_row[cols]
    out[1:] = states[dec - 1:dec * (n_rows - 1):dec, cols]
    return out


def _rollout(printers, systems, motions, h, dec, tail, initial, nthread):
    """The motions as replicas of MuJoCo models, rolled out in threads (models of one shape together)."""
    if nthread is None:                 # threads only for full replica models: replicas are cheaper
        nthread = min(os.cpu_count() or 1, -(-len(motions) // MAX_REPLICAS))
    nsteps = [_grid(m, h, tail, dec) for m in motions]
    # sort by length so that chunks pad little; each chunk is one replicated model
    order = sorted(range(len(motions)), key=lambda i: nsteps[i])
    chunks = [[order[j] for j in c] for c in _chunks(len(motions), nthread)]
    models = [build_model([printers[i] for i in c], h, INTEGRATOR, actuators=False) for c in chunks]
    groups: dict = {}
    for ci, m in enumerate(models):
        groups.setdefault((m.nq, m.nv, m.nu, m.ntendon), []).append(ci)
    results: list = [None] * len(motions)
    for cis in groups.values():
        m0 = models[cis[0]]
        init, ctrl, layout = _pack(cis, chunks, m0, printers, systems, motions, nsteps, h, initial)
        nth = max(1, min(nthread, len(cis)))
        # one model per batch row, one MjData per thread (rollout runs a single one unthreaded)
        state, _ = rollout.rollout([models[ci] for ci in cis], _datas(m0, nth), init, ctrl, control_spec=_FORCES)
        _unpack(layout, init, state, m0.nq, printers, systems, motions, nsteps, h, dec, results)
    return results


def resonance_test(printer: Printer | None, axis, rng: np.random.Generator | None = None,
                   accel_per_hz: float = 60.0, freq_start: float = 5.0, freq_end: float = 135.0,
                   sample_rate: float = 3200.0, max_freq: float = 200.0, noise_floor: float = 50.0,
                   dof: float = 6.0, freqs: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """PSD of the head acceleration along ``axis`` as Klipper's ``TEST_RESONANCES`` would record it.

    ``axis`` ``"x"`` or ``"y"`` gives that axis's PSD (``psd_x`` / ``psd_y``); a direction
    ``(dx, dy)`` (``TEST_RESONANCES AXIS=dx,dy``, e.g. ``(1, 1)`` and ``(1, -1)``, the CoreXY belt
    tests) sweeps along the unit vector and gives ``psd_x + psd_y``, Klipper's ``psd_xyz``.

    Excitation model: Klipper sweeps a commanded sinusoidal acceleration of amplitude
    ``accel_per_hz·f`` (mm/s²) from ``freq_start`` to ``freq_end`` at constant rate; a slow sweep
    spends ``1/(f_end − f_start)`` of its time per Hz, so the Welch-averaged PSD of the head
    acceleration is ``(accel_per_hz·f·|T(f)|)² / (2·(f_end − f_start))`` in (mm/s²)²/Hz inside the
    sweep, with ``T`` the exact transmissibility of the linear model (CoreXY coupling included),
    plus a flat sensor ``noise_floor``. Bins are Klipper's: 0.5 s windows rounded up to a power of
    two at ``sample_rate`` (1.5625 Hz at 3200 Hz), up to ``max_freq`` — or ``freqs`` (Hz) when given
    (a measured file's bins).

    With ``rng`` each bin is scattered like a Welch estimate (Gamma with ``dof`` degrees of freedom,
    mean preserved); without it the expected PSD is returned. Returns (freqs, psd)."""
    pr = load_printer(printer)
    direction = _test_direction(axis)
    if freqs is None:
        nfft = 1 << int(np.ceil(np.log2(sample_rate * 0.5)))
        df = sample_rate / nfft
        freqs = np.arange(0, int(max_freq / df) + 1) * df
    freqs = np.asarray(freqs, float)
    sysm = linear_system(pr)
    T = frequency_response_along(sysm, np.maximum(freqs, 1e-3), direction)
    gain = (np.abs(T) ** 2).sum(axis=1) if isinstance(axis, tuple) else np.abs(T[:, "xy".index(axis)]) ** 2
    inside = (freqs >= freq_start) & (freqs <= freq_end)
    psd = np.where(inside, (accel_per_hz * freqs) ** 2 * gain / (2.0 * (freq_end - freq_start)), 0.0)
    psd = psd + noise_floor
    if rng is not None:
        psd = psd * rng.gamma(dof / 2.0, 2.0 / dof, size=psd.shape)
    return freqs, psd


def _test_direction(axis) -> tuple[float, float]:
    """The unit vector of a resonance test's axis: ``"x"``, ``"y"`` or a direction ``(dx, dy)``."""
    if axis in ("x", "y"):
        return (1.0, 0.0) if axis == "x" else (0.0, 1.0)
    if isinstance(axis, tuple) and len(axis) == 2:
        d = np.asarray(axis, float)
        norm = float(np.hypot(*d))
        if np.all(np.isfinite(d)) and norm > 0:
            return float(d[0] / norm), float(d[1] / norm)
    raise RingtuneError(f"axis must be 'x', 'y' or a direction (dx, dy), not {axis!r}", "axis")
