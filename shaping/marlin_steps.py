"""Marlin's classic step-domain ZV input shaping (``INPUT_SHAPING_X/Y``; ``reference/firmware.md``
§2.1, ``seeds/002``).

Marlin does not shape positions; it shapes *step pulses*. Every step the planner's Bresenham
would emit is split in two: weight ``factor1``/128 now and an echo of weight ``factor2``/128 one
undamped half period ``1/(2F)`` later. A per-axis integer accumulator (``delta_error``) collects the
signed weights; whenever it reaches ``+(64 + H)`` a forward step is emitted and 128 subtracted,
at ``−(64 + H)`` a backward step and 128 added (``H`` = 64 for TMC2208/TMC5160 drivers, else 0).

:func:`steps_from_motion` gives the unshaped step times of an axis exactly (the instants its
position crosses half-step levels); :func:`marlin_zv_steps` applies the echo shaping to them.
The result stays within one step of the continuous ZV shaping of the same motion (tested).
"""

from __future__ import annotations

import numpy as np

from ringtune.shaping.motion import AXES, Motion
from ringtune.shaping.shaper_formulas import marlin_factors


def steps_from_motion(motion: Motion, axis: str, steps_per_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """Step times (s) and directions (+1/−1) of ``axis``: steps happen when the position in steps,
    ``u = x·steps_per_mm``, crosses a half-integer, so the step count is ``round(u − u(t0))``
    relative to the start. Exact for piecewise-constant-acceleration motion."""
    col = AXES.index(axis)
    u0 = motion.p[:, col] * steps_per_mm
    v = motion.v[:, col] * steps_per_mm
    a = motion.a[:, col] * steps_per_mm
    d = motion.dt
    t0 = motion.t[:-1]
    # split each segment at its velocity zero so that every piece is monotone
    with np.errstate(divide="ignore", invalid="ignore"):
        tv = np.where(a != 0, -v / a, np.inf)
    split = (tv > 0) & (tv < d)
    first_d = np.where(split, tv, d)
    ps = [t0, t0[split] + tv[split]]
    pu = [u0, u0[split] + v[split] * tv[split] + 0.5 * a[split] * tv[split] ** 2]
    pv = [v, np.zeros(split.sum())]
    pa = [a, a[split]]
    pd = [first_d, d[split] - tv[split]]
    order = np.argsort(np.concatenate(ps), kind="stable")
    ts, us, vs, as_, ds = (np.concatenate(x)[order] for x in (ps, pu, pv, pa, pd))
    ref = u0[0]
    us = us - ref
    ue = us + vs * ds + 0.5 * as_ * ds * ds
    # step count at every piece boundary, computed once so that rounding at a shared boundary can
    # neither drop nor duplicate a step
    bounds = np.append(us, ue[-1])
    nb = np.floor(bounds + 0.5)
    up, ue_n = nb[:-1], nb[1:]
    counts = np.abs(ue_n - up).astype(np.int64)
    direction = np.sign(ue_n - up)
    piece = np.repeat(np.arange(len(ts)), counts)
    # k-th crossing inside the piece: level = up + dir·(k + 1/2)
    k = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    dirs = direction[piece]
    level = up[piece] + dirs * (k + 0.5)
    dist = dirs * (level - us[piece])          # ≥ 0 along the direction of travel
    vv = np.maximum(dirs * vs[piece], 0.0)
    aa = dirs * as_[piece]
    disc = np.maximum(vv * vv + 2 * aa * dist, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        tau = np.where(dist > 0, 2 * dist / (vv + np.sqrt(disc)), 0.0)
    times = ts[piece] + np.minimum(tau, ds[piece])
    order = np.argsort(times, kind="stable")
    return times[order], dirs[order].astype(np.int64)


def marlin_zv_steps(times: np.ndarray, dirs: np.ndarray, freq: float, damping: float,
                    hysteresis: int = 0, timer_rate: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Shaped step times and directions from unshaped ones, as Marlin's stepper ISR emits them.

    ``freq`` Hz, ``damping`` ratio (only sets the factor1:factor2 split); ``hysteresis`` 0 or 64;
    ``timer_rate`` (Hz, e.g. 2e6 on AVR) quantises the echo delay to whole timer ticks as
    ``(STEPPER_TIMER_RATE/2)/F`` does; None keeps it exact. Vectorised within every run of
    same-direction weights (a Python loop runs only once per direction change of the weight stream).
    """
    f1, f2 = marlin_factors(damping)
    delay = 0.5 / freq if timer_rate is None else np.floor(0.5 * timer_rate / freq) / timer_rate
    times = np.asarray(times, float)
    dirs = np.asarray(dirs, np.int64)
    ev_t = np.concatenate([times, times + delay])
    ev_w = np.concatenate([dirs * f1, dirs * f2])
    order = np.argsort(ev_t, kind="stable")         # at equal times the main step comes first
    ev_t, ev_w = ev_t[order], ev_w[order]
    keep = ev_w != 0
    ev_t, ev_w = ev_t[keep], ev_w[keep]
    thr = 64 + hysteresis
    n_total = np.zeros(len(ev_w), np.int64)        # steps emitted after each event (cumulative)
    sign = np.sign(ev_w)
    run_starts = np.flatnonzero(np.concatenate([[True], sign[1:] != sign[:-1]]))
    run_ends = np.append(run_starts[1:], len(ev_w))
    e = 0                                            # delta_error carried between runs
    n = 0
    for r0, r1 in zip(run_starts, run_ends):
        s = sign[r0]
        x = s * (e + np.cumsum(ev_w[r0:r1]))         # accumulator seen along the run direction
        steps = np.maximum(0, np.floor_divide(x - thr, 128) + 1)
        n_total[r0:r1] = n + s * steps
        e = int(s * (x[-1] - 128 * steps[-1]))
        n = int(n_total[r1 - 1])
    change = np.diff(np.concatenate([[0], n_total]))
    emit = change != 0
    return ev_t[emit], change[emit].astype(np.int64)


def step_position(step_times: np.ndarray, step_dirs: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Net step count at the times ``at`` (steps at exactly ``at`` included)."""
    cum = np.concatenate([[0], np.cumsum(step_dirs)])
    return cum[np.searchsorted(step_times, at, side="right")]
