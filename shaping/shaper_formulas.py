"""The shaper formulas: small pure functions ``(freq Hz, damping ratio[, params]) -> (A, T)``
returning amplitudes (sum 1) and impulse times (s, first 0). Sources: ``reference/firmware.md``
§1.1 (Klipper HEAD and legacy), §2.1–2.2 (Marlin classic and FT_MOTION), §3.2 (RepRapFirmware).
Which firmware uses which formula for which name is decided in ``shaping.shapers`` (the registry).
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import Callable

import numpy as np

from ringtune.shaping.errors import RingtuneError

#: Klipper's SHAPER_VIBRATION_REDUCTION = 20 -> EI vibration tolerance 1/20
DEFAULT_V_TOL = 0.05
#: RepRapFirmware step clock on Duet 3 boards, Hz (delays are whole step clocks)
RRF_STEP_CLOCK = 750_000.0
#: Marlin FT_MOTION trajectory sample rate, Hz (impulse times are whole samples)
FTM_FS = 1000.0

# ---------------------------------------------------------------------------------------------
# helpers
def _df(z: float) -> float:
    return math.sqrt(1.0 - z * z)


def _td(f: float, z: float) -> float:
    """Damped period, s."""
    return 1.0 / (f * _df(z))


def _k(z: float) -> float:
    return math.exp(-z * math.pi / _df(z))


def _norm(a, t) -> tuple[np.ndarray, np.ndarray]:
    a = np.asarray(a, float)
    return a / a.sum(), np.asarray(t, float)


def _poly(rows, z: float) -> np.ndarray:
    """Evaluate each row c0 + c1 z + c2 z² + c3 z³."""
    rows = np.asarray(rows, float)
    return rows @ (z ** np.arange(rows.shape[1]))


# ---------------------------------------------------------------------------------------------
# formulas: Klipper HEAD (§1.1)
def zv(f, z):
    k = _k(z)
    return _norm([1.0, k], [0.0, 0.5 * _td(f, z)])


def zvd(f, z):
    k = _k(z)
    td = _td(f, z)
    return _norm([1.0, 2 * k, k * k], [0.0, 0.5 * td, td])


def binomial_zv(order: int):
    """ZV·(D)^order: binomial amplitudes in K at multiples of half the damped period."""
    def shaper(f, z):
        k = _k(z)
        a = [math.comb(order + 1, i) * k ** i for i in range(order + 2)]
        return _norm(a, 0.5 * _td(f, z) * np.arange(order + 2))
    return shaper


@lru_cache(maxsize=256)
def mzv_coeffs(n: int, t: float) -> np.ndarray:
    """Undamped generalised-MZV amplitudes (Klipper ``get_mzv_coeffs``), impulses at i·t/(n-1),
    in damped periods. Read-only (cached)."""
    if n != int(n) or t <= 0:
        raise RingtuneError(f"mzv needs an integer n and t > 0 (got n={n}, t={t:g})")
    if n < 3 or n <= 2 * t + 1 + 1e-7:                 # Klipper's test, with its 1e-7 margin
        raise RingtuneError(f"mzv needs n >= 3 and n > 2t+1 (got n={n}, t={t:g})")
    n = int(n)                    # 5.0 from a parsed name: the cache takes it for 5, the arrays need an int
    tau = t * (n - 2) / (n - 2 * t - 1)
    T = np.arange(n) * t / (n - 1)
    rows = [np.ones(n)]
    for k in range(n - 1):
        w = 2 * math.pi * (1 + k / tau) * T
        rows += [np.cos(w), np.sin(w)]
    M = np.array(rows)
    rhs = np.zeros(len(rows))
    rhs[0] = 1.0
    A = np.linalg.pinv(M) @ rhs
    if np.any(A < -1e-5):
        raise RingtuneError(f"mzv(n={n},t={t:g}) gives a negative-valued shaper")
    A.setflags(write=False)
    return A


def mzv(f, z, n: int = 3, t: float = 0.0, tau: float = 0.0):
    """Klipper HEAD ``get_mzv_shaper``: n impulses over t damped periods; t = 0 and tau = 0 (not
    given) mean the classic t = 0.75; a non-zero tau (projected duration) takes precedence over t."""
    if tau:
        if tau < 0:
            raise RingtuneError(f"mzv needs tau > 0 (got {tau:g})")
        t = tau * (n - 1) / (n + 2 * tau - 2)
    elif not t:
        t = 0.75
    A = mzv_coeffs(n, float(t))
    kp = math.exp(-2 * t * z * math.pi / ((n - 1) * _df(z)))
    A = A * kp ** np.arange(n)
    return _norm(A, np.arange(n) * t / (n - 1) * _td(f, z))


def ei(f, z, v_tol: float = DEFAULT_V_TOL):
    v = v_tol
    a1 = (0.24968 + 0.24961 * v) + ((0.80008 + 1.23328 * v) + (0.49599 + 3.17316 * v) * z) * z
    a3 = (0.25149 + 0.21474 * v) + ((-0.83249 + 1.41498 * v) + (0.85181 - 4.90094 * v) * z) * z
    a2 = 1 - a1 - a3
    t2 = 0.4999 + (((0.46159 + 8.57843 * v) * v)
                   + (((4.26169 - 108.644 * v) * v) + ((1.75601 + 336.989 * v) * v) * z) * z) * z
    td = _td(f, z)
    return _norm([a1, a2, a3], [0.0, t2 * td, td])


EI2_T = [[0, 0, 0, 0], [0.49890, 0.16270, -0.54262, 6.16180],
         [0.99748, 0.18382, -1.58270, 8.17120], [1.49920, -0.09297, -0.28338, 1.85710]]
EI2_A = [[0.16054, 0.76699, 2.26560, -1.22750], [0.33911, 0.45081, -2.58080, 1.73650],
         [0.34089, -0.61533, -0.68765, 0.42261], [0.15997, -0.60246, 1.00280, -0.93145]]
EI3_T = [[0, 0, 0, 0], [0.49974, 0.23834, 0.44559, 12.4720], [0.99849, 0.29808, -2.36460, 23.3990],
         [1.49870, 0.10306, -2.01390, 17.0320], [1.99960, -0.28231, 0.61536, 5.40450]]
EI3_A = [[0.11275, 0.76632, 3.29160, -1.44380], [0.23698, 0.61164, -2.57850, 4.85220],
         [0.30008, -0.19062, -2.14560, 0.13744], [0.23775, -0.73297, 0.46885, -2.08650],
         [0.11244, -0.45439, 0.96382, -1.46000]]


def ei2(f, z):
    """Klipper HEAD 2hump_ei: cubic fits in ζ, times scaled by the undamped period 1/f."""
    return _norm(_poly(EI2_A, z), _poly(EI2_T, z) / f)


def ei3(f, z):
    return _norm(_poly(EI3_A, z), _poly(EI3_T, z) / f)


# -- legacy closed forms (Klipper ≤ v0.13, Prusa Buddy, Marlin FT_MOTION EI family) -----------
def mzv_legacy(f, z):
    td = _td(f, z)
    kp = math.exp(-0.75 * z * math.pi / _df(z))
    a1 = 1 - 1 / math.sqrt(2)
    return _norm([a1, (math.sqrt(2) - 1) * kp, a1 * kp * kp], [0.0, 0.375 * td, 0.75 * td])


def ei_legacy(f, z, v_tol: float = DEFAULT_V_TOL):
    v, k, td = v_tol, _k(z), _td(f, z)
    return _norm([0.25 * (1 + v), 0.5 * (1 - v) * k, 0.25 * (1 + v) * k * k], [0.0, 0.5 * td, td])


def ei2_legacy(f, z, v_tol: float = DEFAULT_V_TOL):
    v2, k, td = v_tol ** 2, _k(z), _td(f, z)
    x = (v2 * (math.sqrt(1 - v2) + 1)) ** (1 / 3)
    a1 = (3 * x * x + 2 * x + 3 * v2) / (16 * x)
    return _norm([a1, (0.5 - a1) * k, (0.5 - a1) * k ** 2, a1 * k ** 3], 0.5 * td * np.arange(4))


def ei3_legacy(f, z, v_tol: float = DEFAULT_V_TOL):
    v, k, td = v_tol, _k(z), _td(f, z)
    a1 = 0.0625 * (1 + 3 * v + 2 * math.sqrt(2 * (v + 1) * v))
    a2 = 0.25 * (1 - v) * k
    a3 = (0.5 * (1 + v) - 2 * a1) * k * k
    return _norm([a1, a2, a3, a2 * k * k, a1 * k ** 4], 0.5 * td * np.arange(5))


def none_shaper(f, z):
    return np.ones(1), np.zeros(1)


# -- RepRapFirmware (§3.2) ----------------------------------------------------------------------
# 3.6 (``quantised=True``): the damped period P is a whole number of step clocks computed in single
# precision, P = lrintf(StepClockRate / (F·sqrt(1 − S²))); ZVD-family delays are integer divisions
# (i·P)/2, MZV's are (3P)/8 and 2·((3P)/8), EI2/EI3's are lrintf(poly(S)·P). The individual
# amplitudes are stored with the last one = 1 − Σ others, and MZV's in reverse order (a3 first).
# 3.4/3.5 (``quantised=False``): P is a float and the durations between impulses are float
# multiples of it (never rounded to clocks); cumulative MZV coefficients [a3, a2+a3]/Σ, i.e. the
# same reversed amplitudes.
def rrf_period_clocks(f: float, z: float) -> int:
    """RRF 3.6 damped period, whole step clocks (float32 arithmetic as the firmware does it)."""
    z32 = np.float32(z)
    df = np.sqrt(np.float32(1.0 - float(z32 * z32)))
    return int(np.rint(np.float32(np.float32(RRF_STEP_CLOCK) / np.float32(np.float32(f) * df))))


def rrf_clocks(seconds) -> np.ndarray:
    """RRF 3.6 conversion of delays given in s (custom ``T``) to step clocks: lrintf(T·rate)."""
    return np.rint(np.asarray(seconds, np.float32) * np.float32(RRF_STEP_CLOCK)).astype(np.int64)


def _rrf_poly_clocks(t_rows, z: float, P: int) -> np.ndarray:
    """lrintf(poly(ζ)·P): ζ is a float, ζ² and ζ³ float products, the polynomial in double."""
    z32 = np.float32(z)
    z2 = np.float32(z32 * z32)
    powers = np.array([1.0, float(z32), float(z2), float(np.float32(z2 * z32))])
    return np.rint((np.asarray(t_rows, float) @ powers * P).astype(np.float32)).astype(np.int64)


def rrf_binomial(order: int, quantised: bool):
    """RRF zvd (order 1), zvdd (2), zvddd (3): binomial amplitudes, delays i·P/2."""
    def shaper(f, z):
        a, t = binomial_zv(order)(f, z)
        if quantised:
            P = rrf_period_clocks(f, z)
            t = np.array([(i * P) // 2 for i in range(order + 2)], float) / RRF_STEP_CLOCK
        return a, t
    return shaper


def rrf_mzv(quantised: bool):
    """RRF mzv: Klipper's legacy MZV amplitudes in the firmware's order [a3, a2, a1]/Σ (a3 at the
    first delay) at 0, 3P/8, 6P/8."""
    def shaper(f, z):
        kp = math.exp(-0.75 * z * math.pi / _df(z))
        a1 = 1 - math.sqrt(2) / 2
        a = np.array([a1 * kp * kp, (math.sqrt(2) - 1) * kp, a1])
        if quantised:
            d1 = (3 * rrf_period_clocks(f, z)) // 8
            t = np.array([0, d1, 2 * d1], float) / RRF_STEP_CLOCK
        else:
            t = np.array([0.0, 0.375, 0.75]) * _td(f, z)
        return a / a.sum(), t
    return shaper


def rrf_ei(a_rows, t_rows, quantised: bool):
    """RRF ei2/ei3: Klipper HEAD's 2/3-hump polynomials, the last amplitude 1 − Σ others, times
    poly(ζ) × the DAMPED period (Klipper HEAD uses the undamped 1/f)."""
    def shaper(f, z):
        a = _poly(a_rows, z)[:-1]
        a = np.append(a, 1.0 - a.sum())
        if quantised:
            t = _rrf_poly_clocks(t_rows, z, rrf_period_clocks(f, z)) / RRF_STEP_CLOCK
        else:
            t = _poly(t_rows, z) * _td(f, z)
        return a, t
    return shaper


# -- Marlin ---------------------------------------------------------------------------------------
def marlin_factors(z: float) -> tuple[int, int]:
    """Marlin classic ZV weights (factor1, factor2) out of 128 (stepper.cpp)."""
    if z <= 0:
        f2 = 64
    elif z >= 1:
        f2 = 0
    else:
        f2 = int(math.floor(64.44056192 - 99.02008832 * z - 7.58095488 * z ** 2 + 43.073216 * z ** 3))
    return 128 - f2, f2


def marlin_zv(f, z):
    """Classic Marlin ZV: fixed-point weights, echo after the UNDAMPED half period 1/(2F)."""
    f1, f2 = marlin_factors(z)
    return np.array([f1, f2], float) / 128.0, np.array([0.0, 0.5 / f])


def ftm_shaper(family: Callable, base: float):
    """Marlin FT_MOTION: legacy amplitudes; N_i = i·LROUND(base/f/df·FS) samples."""
    def shaper(f, z, **params):
        a, _ = family(f, z, **params)
        n1 = math.floor(base / f / _df(z) * FTM_FS + 0.5)
        return a, np.arange(len(a)) * n1 / FTM_FS
    return shaper


def ftm_mzv(f, z):
    k = _k(z)   # Marlin FTM uses exp(-ζπ/df), not Klipper's exp(-0.75ζπ/df)
    return _norm([1.0, math.sqrt(2) * k, k * k], [0.0, 0.375, 0.75])


def ftm_centre(a: np.ndarray, t: np.ndarray) -> float:
    """FTM centring delay: N0 = LROUND(Σ_{i≥1} A_i·N_i) samples."""
    return math.floor(float(np.dot(a, t)) * FTM_FS + 0.5) / FTM_FS
