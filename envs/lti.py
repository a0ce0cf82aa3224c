"""Exact linear reference: the printer's linear mechanics driven by piecewise-constant acceleration.

The commanded motion (:class:`~ringtune.shaping.motion.Motion`) is exactly piecewise-constant in
acceleration, so the response of ``ẋ = A x + G a`` is known in closed form. The state matrix is
diagonalised once (``A = V Λ V⁻¹``, complex); each modal coordinate obeys
``z(t+Δ) = e^{λΔ} z(t) + (e^{λΔ} − 1)/λ · g·a`` across every interval of constant acceleration,
exact for any Δ, so segment boundaries that fall between output samples are honoured exactly.
A jump of the commanded velocity (a corner taken at junction speed) is an impulse of acceleration
and makes the relative velocity jump by −Δv. The recursion over the merged sorted times (segment boundaries ∪ output grid) is evaluated with
cumulative sums, ``z_j = e^{λ t_j} (z_0 + Σ_{i<j} β_i e^{−λ t_{i+1}})``, in chunks short enough that
``e^{−λ t}`` stays far from overflow — no Python loop per sample.

Used by the tests as the oracle for the MuJoCo model and offered as ``backend="lti"`` (fast
screening; it has no belt slip and no nonlinearity, but step loss is detected the same way).
"""

from __future__ import annotations

import numpy as np

from ringtune.envs.modal_system import LinearSystem

#: largest decay exponent |Re λ|·Δt inside one chunk of the cumulative-sum evaluation
_CHUNK_EXPONENT = 200.0


def _diagonalise(sysm: LinearSystem):
    A, G = sysm.state_matrices()
    lam, V = np.linalg.eig(A)
    Vinv = np.linalg.inv(V)
    return lam, V, Vinv @ G


def response(sysm: LinearSystem, motion, times: np.ndarray, x0: np.ndarray | None = None
             ) -> tuple[np.ndarray, np.ndarray]:
    """Exact (q, q̇) at ``times`` (sorted, ≥ motion start), each (m, n), mm and mm/s.

    The commanded acceleration is the motion's (x, y) columns; before ``t[0]`` and after ``t[-1]``
    it is zero. ``x0`` (2n,) is the state [q, q̇] at ``times[0]`` (default rest). Evaluated chunk by
    chunk (module docstring), each chunk's states turned into the output samples it holds at once:
    memory in the samples asked, not in every event time's complex state (a 24-minute piece of a
    job at 5 kHz: 0.9 GB, where the whole complex history took 7.6 GB)."""
    times = np.asarray(times, float)
    n = sysm.n
    lam, V, g = _diagonalise(sysm)
    t0 = times[0]
    bounds = motion.t[(motion.t > t0) & (motion.t < times[-1])]
    ev = np.union1d(times, bounds)                        # sorted event times
    dt = np.diff(ev)
    at, kicks = _velocity_jumps(motion, ev, t0, times[-1], g)
    z = np.zeros(2 * n, complex) if x0 is None else np.linalg.solve(V, np.asarray(x0, complex))
    idx = np.searchsorted(ev, times)                      # each output time's place among the events
    out = np.empty((len(times), 2 * n))
    first = int(np.searchsorted(idx, 0, side="right"))
    out[:first] = (z[None, :] @ V.T).real
    rate = np.max(np.abs(lam.real)) if len(lam) else 0.0
    span = _CHUNK_EXPONENT / max(rate, 1e-12)
    j0 = 0
    while j0 < len(ev) - 1:
        j1 = int(np.searchsorted(ev, ev[j0] + span, side="right")) - 1
        j1 = max(min(j1, len(ev) - 1), j0 + 1)
        # acceleration on each interval [ev[j], ev[j+1]) at its midpoint (exact), as modal input
        u = motion.acceleration(0.5 * (ev[j0:j1] + ev[j0 + 1:j1 + 1]))[:, :2] @ g.T
        jump = np.zeros((j1 - j0, 2 * n), complex)
        lo, hi = np.searchsorted(at, (j0, j1))
        np.add.at(jump, at[lo:hi] - j0, kicks[lo:hi])
        # e^{λΔ} for the few distinct interval lengths (mostly the output step), then running
        # products give e^{λ t} and e^{−λ t} without evaluating a complex exponential per sample
        dd, inv = np.unique(dt[j0:j1], return_inverse=True)
        edu = np.exp(lam[None, :] * dd[:, None])
        ed = edu[inv]
        beta = (ed - 1.0) * (u / lam[None, :]) + jump      # exact input over each interval
        e = np.cumprod(ed, axis=0)                         # e^{λ t_{i+1}}
        einv = np.cumprod((1.0 / edu)[inv], axis=0)        # e^{−λ t_{i+1}}
        zc = e * (z[None, :] + np.cumsum(beta * einv, axis=0))   # states at ev[j0 + 1 .. j1]
        a, b = np.searchsorted(idx, (j0 + 1, j1 + 1))
        out[a:b] = (zc[idx[a:b] - (j0 + 1)] @ V.T).real
        z = zc[-1]
        j0 = j1
    return out[:, :n], out[:, n:]


def _velocity_jumps(motion, ev: np.ndarray, t_lo: float, t_hi: float, g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(interval index, modal kick) of each jump of the command's velocity in (t_lo, t_hi]: a
    corner taken at junction speed, a shaped copy that ends, is an impulse of acceleration, so the
    relative velocity jumps by −Δv, added at the end of the interval it ends; indices ascending."""
    none = (np.zeros(0, np.int64), np.zeros((0, g.shape[0]), complex))
    if motion.n_segments < 2:
        return none
    _, v_end = motion.end_state()
    dv = motion.v[1:, :2] - v_end[:-1, :2]
    tb = motion.t[1:-1]
    sel = (tb > t_lo) & (tb <= t_hi) & np.any(dv != 0.0, axis=1)
    if not sel.any():
        return none
    return np.searchsorted(ev, tb[sel]) - 1, dv[sel] @ g.T


def frequency_response_along(sysm: LinearSystem, freqs: np.ndarray, direction) -> np.ndarray:
    """Complex head acceleration on x and y, (F, 2), per unit of commanded acceleration along the
    unit vector ``direction`` (dx, dy) at ``freqs`` (Hz): ``d + Σ share·q̈`` per axis. A diagonal
    (1, ±1)/√2 is Klipper's ``TEST_RESONANCES AXIS=1,±1``: on a CoreXY it turns one motor only."""
    d = np.asarray(direction, float)
    w = 2j * np.pi * np.asarray(freqs, float)
    force = -sysm.mass * (sysm.B @ d)
    out = np.empty((len(w), 2), complex)
    for i, s in enumerate(w):
        Z = sysm.K + s * sysm.C + (s * s) * np.diag(sysm.mass)
        q = np.linalg.solve(Z, force)
        out[i] = d + (s * s) * (q @ sysm.W)
    return out
