"""Math on any shaper: residual vibration, the band of strong reduction, smoothing, the accel
Klipper would recommend, and the lags shaping introduces.

Residual vibration and smoothing follow Klipper's ``shaper_calibrate.py`` definitions
(``reference/firmware.md`` §1.3); lags follow the Marlin author's derivation (``seeds/002``).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq

from ringtune.shaping.shapers import Shaper, Smoother
from ringtune.shaping.smoothers import smoother_smoothing_terms

#: Klipper's find_shaper_max_accel target: largest accel whose smoothing stays <= 0.12 mm
TARGET_SMOOTHING = 0.12
#: mm/s², the acceleration Klipper quotes smoothing at (calibrate_shaper's table)
SMOOTHING_ACCEL = 5000.0


# -- on impulse arrays: one shaper (A, T of shape (n,)) or a stack of shapers (rows, (k, n)) ------

def impulse_residual(amps, times, freqs, damping: float) -> np.ndarray:
    """Fraction (0..1) of a vibration at each ``freqs`` (Hz) of a plant with damping ratio
    ``damping`` that survives the impulse train(s) — Klipper's ``_estimate_shaper``:

    ``|Σ A_i·exp(−ζω(T_n − T_i))·exp(jω_d T_i)| / ΣA`` with ``ω = 2πf``, ``ω_d = ω√(1−ζ²)``.

    ``amps``/``times`` (s) of shape (n,) give shape ``(len(freqs),)``; a stack (k, n) gives (k, len(freqs)).
    """
    a = np.asarray(amps, dtype=float)
    t = np.asarray(times, dtype=float)
    single = a.ndim == 1
    a, t = np.atleast_2d(a), np.atleast_2d(t)
    omega = 2.0 * math.pi * np.atleast_1d(np.asarray(freqs, dtype=float))
    omega_d = omega * math.sqrt(1.0 - damping ** 2)
    # |Σ A_i e^{-ζω(T_n - T_i)} e^{jω_d T_i}| as one complex exponential per pulse
    expo = (-damping * omega)[None, :, None] * (t[:, -1:] - t)[:, None, :] \
        + 1j * omega_d[None, :, None] * t[:, None, :]
    z = (a[:, None, :] * np.exp(expo)).sum(axis=2)
    s, c = z.imag, z.real
    out = np.sqrt(s * s + c * c) / a.sum(axis=1)[:, None]
    return out[0] if single else out


def smoothing_terms(amps, times, scv: float = 5.0):
    """Klipper's smoothing as affine functions of the acceleration ``accel`` (mm/s²):
    90° corner at square-corner velocity ``scv`` (mm/s) ``c90 + k90·accel``, 180° reversal
    ``k180·accel`` (mm). Returns (c90, k90, k180): floats for one shaper, arrays for a stack."""
    a = np.atleast_2d(np.asarray(amps, dtype=float))
    t = np.atleast_2d(np.asarray(times, dtype=float))
    inv_d = 1.0 / a.sum(axis=1)
    ts = (a * t).sum(axis=1) * inv_d
    d = t - ts[:, None]
    late = t >= ts[:, None]
    c90 = math.sqrt(2.0) * inv_d * scv * np.where(late, a * d, 0.0).sum(axis=1)
    k90 = math.sqrt(2.0) * inv_d * 0.5 * np.where(late, a * d * d, 0.0).sum(axis=1)
    k180 = inv_d * 0.5 * (a * d * d).sum(axis=1)
    if np.ndim(amps) == 1:
        return float(c90[0]), float(k90[0]), float(k180[0])
    return c90, k90, k180


def smoothing_from_terms(terms, accel: float = SMOOTHING_ACCEL):
    """Smoothing (mm) at ``accel`` mm/s² from :func:`smoothing_terms`: the worse of the two turns."""
    c90, k90, k180 = terms
    return np.maximum(c90 + k90 * accel, k180 * accel)


def max_accel_from_terms(terms, target: float = TARGET_SMOOTHING):
    """Largest accel (mm/s²) whose smoothing stays ≤ ``target`` mm, from :func:`smoothing_terms`.

    Klipper finds it by bisection to 1e-8 mm/s²; smoothing is affine in the acceleration, so this
    solves it exactly (the same number to 1e-8), the result never smoothing more than ``target``
    (like Klipper's, whose bisection keeps the side that passes). 0 when even a standstill turn at ``scv`` smooths
    more than ``target`` (Klipper HEAD's guard); inf when the shaper never smooths (one impulse).
    """
    c90, k90, k180 = (np.asarray(x, dtype=float) for x in terms)
    with np.errstate(divide="ignore", invalid="ignore"):
        a90 = np.where(k90 > 0, (target - c90) / k90, np.inf)
        a180 = np.where(k180 > 0, target / k180, np.inf)
    out = np.where(c90 > target, 0.0, np.minimum(a90, a180))
    for _ in range(4):   # the closed form may land one rounding step past the target: step back
        with np.errstate(invalid="ignore"):          # inf · 0 for a shaper that never smooths
            over = smoothing_from_terms((c90, k90, k180), out) > target
        if not over.any():
            break
        out = np.where(over, np.nextafter(out, 0.0), out)
    return float(out) if out.ndim == 0 else out


# -- on a Shaper -------------------------------------------------------------------------------------

def residual_vibration(shaper: Shaper, freqs, damping: float | None = None) -> np.ndarray:
    """Fraction (0..1) of a vibration at each ``freqs`` (Hz) of a plant with damping ratio
    ``damping`` (default: the shaper's own) that survives the shaper (:func:`impulse_residual`)."""
    z = shaper.damping if damping is None else float(damping)
    f = np.asarray(freqs, float)
    return impulse_residual(shaper.amplitudes, shaper.times, f.ravel(), z).reshape(f.shape)


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


def shaper_smoothing_terms(shaper: Shaper, scv: float = 5.0):
    """:func:`smoothing_terms` of a shaper; of a continuous smoother, its kernel's exact integrals
    (the impulse sums of its quadrature would cut the 90° integral at a node, not at the centroid)."""
    if isinstance(shaper, Smoother):
        return smoother_smoothing_terms(shaper.coeffs, shaper.smooth_time, shaper.offset, scv)
    return smoothing_terms(shaper.amplitudes, shaper.times, scv)


def smoothing(shaper: Shaper, accel: float = SMOOTHING_ACCEL, scv: float = 5.0) -> float:
    """Klipper's smoothing estimate, mm: the larger of the offsets a 90° corner (at square-corner
    velocity ``scv`` mm/s) and a 180° reversal suffer at acceleration ``accel`` mm/s²."""
    return float(smoothing_from_terms(shaper_smoothing_terms(shaper, scv), accel))


def max_accel(shaper: Shaper, scv: float = 5.0, target: float = TARGET_SMOOTHING) -> float:
    """Largest accel (mm/s², unrounded) with ``smoothing(accel, scv) <= target`` — Klipper's
    ``find_shaper_max_accel`` (Klipper prints it rounded to 100); see :func:`max_accel_from_terms`."""
    return max_accel_from_terms(shaper_smoothing_terms(shaper, scv), target)


def lag(shaper: Shaper, centred: bool = False) -> float:
    """Steady-state time lag of the shaped motion, s: Σ A_i·T_i when causal, 0 when centred
    (exactly: what remains after subtracting the firmware's centring delay)."""
    return shaper.centroid - shaper.centre_delay if centred else shaper.centroid


def acceleration_lag(accel: float, freq: float) -> float:
    """Static deflection of a mode of ``freq`` Hz under constant ``accel`` mm/s²: a/ω², mm."""
    omega = 2 * math.pi * freq
    return accel / (omega * omega)


def summary(shaper: Shaper, centred: bool, accel: float = SMOOTHING_ACCEL, scv: float = 5.0,
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


def responses(shapers: list[Shaper], freqs, plant_dampings) -> list[dict]:
    """What Klipper's shaper graph shows of each shaper: ``residual`` at ``freqs`` (Hz; the maximum
    over the plant damping ratios, as Klipper draws it), ``band90_hz``, ``duration_s``,
    ``smoothing_mm`` and ``max_accel`` (mm/s², None when the shaper never smooths)."""
    rows = []
    for s in shapers:
        ma = max_accel(s)
        rows.append({"name": s.name, "damping": s.damping,
                     "residual": np.max([residual_vibration(s, freqs, z) for z in plant_dampings], axis=0),
                     "band90_hz": list(band(s, 0.9, s.damping)), "duration_s": s.duration,
                     "smoothing_mm": smoothing(s), "max_accel": ma if math.isfinite(ma) else None})
    return rows
