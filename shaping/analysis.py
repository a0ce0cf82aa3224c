"""Math on any shaper: residual vibration, the band of strong reduction, smoothing, the accel
Klipper would recommend, and the lags shaping introduces.

Residual vibration and smoothing follow Klipper's ``shaper_calibrate.py`` definitions
(``reference/firmware.md`` §1.3); lags follow the Marlin author's derivation (``seeds/002``).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq

from ringtune.shaping.shapers import Shaper

#: Klipper's find_shaper_max_accel target: largest accel whose smoothing stays <= 0.12 mm
TARGET_SMOOTHING = 0.12


def residual_vibration(shaper: Shaper, freqs, damping: float | None = None) -> np.ndarray:
    """Fraction (0..1) of a vibration at each ``freqs`` (Hz) of a plant with damping ratio
    ``damping`` (default: the shaper's own) that survives the shaper, as Klipper estimates it:

    ``|Σ A_i·exp(−ζω(T_n − T_i))·exp(jω_d T_i)| / ΣA`` with ``ω = 2πf``, ``ω_d = ω√(1−ζ²)``.
    """
    z = shaper.damping if damping is None else float(damping)
    f = np.asarray(freqs, float)
    A, T = shaper.amplitudes, shaper.times
    omega = 2 * math.pi * f[..., None]
    w = A * np.exp(-z * omega * (T[-1] - T))
    phase = omega * math.sqrt(1 - z * z) * T
    s = (w * np.sin(phase)).sum(-1)
    c = (w * np.cos(phase)).sum(-1)
    return np.sqrt(s * s + c * c) / A.sum()


def band(shaper: Shaper, reduction: float = 0.9, damping: float = 0.0,
         f_center: float | None = None) -> tuple[float, float]:
    """(f_lo, f_hi), Hz: the contiguous frequency range around the shaper's design frequency
    (``f_center``, default ``shaper.freq``) where at least ``reduction`` of the vibration is
    removed, for a plant of damping ``damping``. ``(nan, nan)`` if no such range is near."""
    f0 = shaper.freq if f_center is None else float(f_center)
    limit = 1.0 - reduction
    g = lambda f: float(residual_vibration(shaper, [f], damping)[0]) - limit  # noqa: E731
    grid = f0 * np.linspace(0.02, 4.0, 7981)
    vals = residual_vibration(shaper, grid, damping) - limit
    inside = vals <= 0
    if not inside.any():
        return math.nan, math.nan
    start = int(np.argmin(np.abs(grid - f0)))
    if not inside[start]:  # design frequency outside (e.g. a firmware's mis-ordered MZV): nearest dip
        cands = np.flatnonzero(inside)
        start = int(cands[np.argmin(np.abs(grid[cands] - f0))])
    lo = start
    while lo > 0 and inside[lo - 1]:
        lo -= 1
    hi = start
    while hi < len(grid) - 1 and inside[hi + 1]:
        hi += 1
    f_lo = brentq(g, grid[lo - 1], grid[lo], xtol=1e-10) if lo > 0 else grid[0]
    f_hi = brentq(g, grid[hi], grid[hi + 1], xtol=1e-10) if hi < len(grid) - 1 else grid[-1]
    return float(f_lo), float(f_hi)


def smoothing(shaper: Shaper, accel: float = 5000.0, scv: float = 5.0) -> float:
    """Klipper's smoothing estimate, mm: the larger of the offsets a 90° corner (at square-corner
    velocity ``scv`` mm/s) and a 180° reversal suffer at acceleration ``accel`` mm/s²."""
    A, T = shaper.amplitudes, shaper.times
    inv_d = 1.0 / A.sum()
    ts = float(np.dot(A, T)) * inv_d
    h = 0.5 * accel
    dt = T - ts
    ahead = T >= ts
    offset_90 = math.sqrt(2) * inv_d * float(np.sum(A[ahead] * (scv + h * dt[ahead]) * dt[ahead]))
    offset_180 = inv_d * float(np.sum(A * h * dt * dt))
    return max(offset_90, offset_180)


def max_accel(shaper: Shaper, scv: float = 5.0, target: float = TARGET_SMOOTHING) -> float:
    """Largest accel (mm/s², unrounded) with ``smoothing(accel, scv) <= target`` — Klipper's
    ``find_shaper_max_accel`` bisection (Klipper prints it rounded to 100)."""
    ok = lambda a: smoothing(shaper, a, scv) <= target  # noqa: E731
    if not ok(1e-9):
        return 0.0
    left = right = 1.0
    while not ok(left):
        right = left
        left *= 0.5
    if right == left:
        while ok(right):
            right *= 2.0
            if right > 1e12:   # the shaper never smooths (a single impulse): no limit
                return math.inf
    while right - left > 1e-8:
        mid = 0.5 * (left + right)
        if ok(mid):
            left = mid
        else:
            right = mid
    return left


def lag(shaper: Shaper, centred: bool = False) -> float:
    """Steady-state time lag of the shaped motion, s: Σ A_i·T_i when causal, 0 when centred
    (exactly: what remains after subtracting the firmware's centring delay)."""
    return shaper.centroid - shaper.centre_delay if centred else shaper.centroid


def position_lag(shaper: Shaper, speed: float, centred: bool = False) -> float:
    """Steady-state distance the shaped position trails the commanded one at ``speed`` mm/s, mm."""
    return speed * lag(shaper, centred)


def acceleration_lag(accel: float, freq: float) -> float:
    """Static deflection of a mode of ``freq`` Hz under constant ``accel`` mm/s²: a/ω², mm."""
    omega = 2 * math.pi * freq
    return accel / (omega * omega)


def summary(shaper: Shaper, centred: bool, accel: float = 5000.0, scv: float = 5.0,
            plant_damping: float | None = None) -> dict:
    """Everything ``ringtune shaper`` reports, as plain numbers. The band and the residual are for
    a plant of damping ``plant_damping`` (default: the shaper's own, i.e. matched)."""
    zp = shaper.damping if plant_damping is None else plant_damping
    f_lo, f_hi = band(shaper, 0.9, zp)
    return {
        "duration_s": shaper.duration,
        "lag_s": lag(shaper, centred),
        "centroid_s": shaper.centroid,
        "band90_hz": [f_lo, f_hi],
        "band90_pct": [100 * (f_lo / shaper.freq - 1), 100 * (f_hi / shaper.freq - 1)],
        "smoothing_mm": smoothing(shaper, accel, scv),
        "max_accel": max_accel(shaper, scv),
        "residual_at_freq": float(residual_vibration(shaper, [shaper.freq], zp)[0]),
        "plant_damping": zp,
    }
