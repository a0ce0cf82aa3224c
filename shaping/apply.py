"""Apply shapers to motion.

:func:`shape_motion` is exact: the shaped position ``Σ A_i·x(t − s_i)`` of piecewise-quadratic
motion is again piecewise quadratic, with breakpoints at the union of the shifted segment
boundaries. Each shifted copy is evaluated (position, velocity, acceleration) at the start of every
merged segment and the weighted copies are summed — no sampling, no interpolation error.

:func:`shape_samples` shapes an already sampled array (uniform rate) with whole-slice shifts and
linear interpolation for the fractional part of each delay; its error is bounded by
``max|ẍ|·Δt²/8`` per impulse (≈ 3e-4 mm at 10 000 mm/s² and 2 kHz), so prefer shape_motion when
the planned motion is at hand.

Shifts: causal firmwares (RRF, Marlin classic) use ``s_i = T_i`` (the shaped motion lags by
Σ A_i T_i); centring firmwares (Klipper, Prusa, Marlin FT_MOTION) use ``s_i = T_i − centre`` so
the steady-state lag is zero.

A continuous smoother (Kalico's ``smooth_*``, :class:`~ringtune.shaping.shapers.Smoother`) is the
convolution ``∫ w(τ)·x(t + t_offs − τ) dτ``; its impulses are the Gauss–Legendre quadrature of that
integral (:mod:`ringtune.shaping.smoothers`), so :func:`shape_motion` evaluates it exactly
wherever the kernel spans no change of acceleration, and across one replaces the kernel's smooth
ramp of acceleration by a staircase of its nodes (position within a micrometre of the exact
convolution: ``tests/test_kalico_smoothers.py``). Its zero-weight end impulses are skipped.
"""

from __future__ import annotations

import numpy as np

from ringtune.shaping.motion import AXES, Motion
from ringtune.shaping.shapers import Shaper

_NONE = (np.ones(1), np.zeros(1))


def impulse_shifts(shaper: Shaper | None, centred: bool) -> tuple[np.ndarray, np.ndarray]:
    """(amplitudes, shifts s) with shaped x(t) = Σ A_i·x(t − s_i)."""
    if shaper is None:
        return _NONE
    keep = shaper.amplitudes != 0.0            # a smoother's end markers
    shifts = shaper.times[keep] - (shaper.centre_delay if centred else 0.0)
    return shaper.amplitudes[keep], shifts


def _eval_copies(motion: Motion, cols: list[int], starts: np.ndarray, mids: np.ndarray,
                 amps: np.ndarray, shifts: np.ndarray):
    """Σ_i A_i · (p, v, a)(τ − s_i) of the columns ``cols`` at merged segment starts (each merged
    segment is located by its midpoint, so shifted breakpoints never pick the wrong side)."""
    # rest segments before the start and after the end make every lookup a plain gather
    end = motion.end_state()[0][-1:, cols]
    zero = np.zeros((1, len(cols)))
    p_ext = np.concatenate([motion.p[:1, cols], motion.p[:, cols], end])
    v_ext = np.concatenate([zero, motion.v[:, cols], zero])
    a_ext = np.concatenate([zero, motion.a[:, cols], zero])
    t_ext = np.concatenate([motion.t[:1], motion.t])
    P = np.zeros((len(starts), len(cols)))
    V = np.zeros_like(P)
    Acc = np.zeros_like(P)
    for amp, s in zip(amps, shifts):
        j = np.searchsorted(motion.t, mids - s, side="right")      # 0 = before, n + 1 = after
        tau = (starts - s - t_ext[j])[:, None]
        a = a_ext[j]
        v = v_ext[j]
        P += amp * (p_ext[j] + (v + 0.5 * a * tau) * tau)
        V += amp * (v + a * tau)
        Acc += amp * a
    return P, V, Acc


def shape_motion(motion: Motion, shapers: dict[str, Shaper | None], centred: bool,
                 merge_tol: float = 1e-12) -> Motion:
    """Exactly shaped copy of ``motion``.

    ``shapers`` maps axis names (``"x"``, ``"y"``, optionally ``"z"``) to a :class:`Shaper` or None;
    axes not named (and ``e``) pass through unchanged. ``centred`` selects centred (Klipper, Prusa,
    Marlin FT_MOTION) or causal (RRF, Marlin classic) shifts. Breakpoints closer than ``merge_tol``
    seconds are merged. ``extruding``/``move`` of a merged segment come from the unshaped motion at
    the same time. Outside [t[0], t[-1]] the input rests (the Motion convention), so when shaping
    a window cut from a longer job, the result is that of the whole job only from one shaper
    duration after the window's start (and, centred, up to the centre delay before its end).
    The output spans [t[0] + min s_i, t[-1] + max s_i].
    """
    ncol = motion.p.shape[1]
    plan = {}
    all_shifts = [np.zeros(1)]
    for axis, shaper in shapers.items():
        if axis not in AXES[:ncol]:
            raise ValueError(f"unknown axis {axis!r}; expected one of {AXES[:ncol]}")
        amps, shifts = impulse_shifts(shaper, centred)
        plan[AXES.index(axis)] = (amps, shifts)
        all_shifts.append(shifts)
    shifts_all = np.unique(np.concatenate(all_shifts))
    t = np.unique((motion.t[None, :] + shifts_all[:, None]).ravel())
    if len(t) > 1:
        keep = np.concatenate([[True], np.diff(t) > merge_tol * max(1.0, abs(t[-1]))])
        t = t[keep]
    if len(t) < 2:
        return Motion(motion.t.copy(), motion.p.copy(), motion.v.copy(), motion.a.copy(),
                      motion.extruding.copy(), motion.move.copy())
    starts = t[:-1]
    mids = 0.5 * (t[:-1] + t[1:])
    m = len(starts)
    P = np.empty((m, ncol))
    V = np.empty((m, ncol))
    Acc = np.empty((m, ncol))
    groups: dict[tuple, list[int]] = {}
    for col in range(ncol):
        amps, shifts = plan.get(col, _NONE)
        groups.setdefault((tuple(amps), tuple(shifts)), []).append(col)
    for (amps, shifts), cols in groups.items():
        P[:, cols], V[:, cols], Acc[:, cols] = _eval_copies(motion, cols, starts, mids, amps, shifts)
    idx = np.searchsorted(motion.t, mids, side="right") - 1
    inside = (idx >= 0) & (idx < motion.n_segments)
    j = np.clip(idx, 0, motion.n_segments - 1)
    extruding = motion.extruding[j] & inside
    move = np.where(inside, motion.move[j], -1)
    return Motion(t, P, V, Acc, extruding, move)


# ---------------------------------------------------------------------------------------------
def sample_taps(shaper: Shaper | None, rate: float, centred: bool) -> tuple[np.ndarray, np.ndarray]:
    """Integer sample lags L and weights w with shaped x[k] ≈ Σ w_j·x[k − L_j] (linear interp)."""
    amps, shifts = impulse_shifts(shaper, centred)
    d = shifts * rate
    lo = np.floor(d)
    frac = d - lo
    lags = np.concatenate([lo, lo + 1]).astype(np.int64)
    weights = np.concatenate([amps * (1 - frac), amps * frac])
    uniq, inv = np.unique(lags, return_inverse=True)
    w = np.zeros(len(uniq))
    np.add.at(w, inv, weights)
    keep = w != 0
    return uniq[keep], w[keep]


def shape_samples(x: np.ndarray, rate: float, shaper: Shaper | None, centred: bool,
                  block: int = 16384) -> np.ndarray:
    """Shape a uniformly sampled signal ``x`` ((m,) or (m, k), time along axis 0, rate Hz).

    Before the first sample the signal is held at ``x[0]``, after the last at ``x[-1]``. Works in
    cache-sized blocks: each tap is one fused multiply-add over a whole slice.
    """
    x = np.asarray(x, float)
    lags, w = sample_taps(shaper, rate, centred)
    m = x.shape[0]
    front = max(int(lags.max()), 0)
    back = max(-int(lags.min()), 0)
    if front or back:
        xp = np.concatenate([np.repeat(x[:1], front, axis=0), x, np.repeat(x[-1:], back, axis=0)])
    else:
        xp = x
    out = np.empty_like(x)
    tmp = np.empty((min(block, m),) + x.shape[1:])
    for b0 in range(0, m, block):
        b1 = min(b0 + block, m)
        acc = out[b0:b1]
        t = tmp[: b1 - b0]
        base = b0 + front
        np.multiply(xp[base - lags[0]: base - lags[0] + b1 - b0], w[0], out=acc)
        for lag, wj in zip(lags[1:], w[1:]):
            s = base - lag
            np.multiply(xp[s: s + b1 - b0], wj, out=t)
            acc += t
    return out
