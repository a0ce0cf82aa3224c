"""Every input shaper the firmwares use, in one registry, per firmware flavour.

A shaper is a train of impulses: amplitudes ``A`` (sum 1) at times ``T`` (s, first 0, increasing).
Each formula below is a small pure function ``(freq Hz, damping ratio[, params]) -> (A, T)``; the
flavour tables say which formula each firmware uses for each name (sources:
``reference/firmware.md`` §1.1, §2.1, §2.2, §3.2, §4, §6):

========== ==========================================================================================
flavour    shapers (formula family)
========== ==========================================================================================
klipper    zv, mzv (generalised ``mzv(n=…,t=…)``), zvd, ei (``ei(v_tol=…)``), 2hump_ei, 3hump_ei (HEAD)
klipper-   zv, mzv, zvd, ei, 2hump_ei, 3hump_ei — the ≤ v0.13 closed forms (also Prusa Buddy);
legacy     EI types take ``v_tol`` (Prusa's ``R`` = 1/v_tol)
rrf        RRF 3.6: zvd, zvdd, zvddd, mzv, ei2, ei3 (Klipper HEAD polynomials × DAMPED period),
           custom; delays rounded to the 750 kHz step clock; no zv, no ei
rrf35      RRF 3.4/3.5: same set; MZV amplitudes in the firmware's (reversed) order; custom with
           cumulative H and durations T
marlin     classic ZV only: undamped half period 1/(2F), weights factor1:factor2 out of 128
marlin-ftm M493: zv, zvd, zvdd, zvddd, ei, 2hump_ei, 3hump_ei, mzv (own damping K), times quantised
           to 1 ms (FTM_FS = 1000 Hz)
========== ==========================================================================================

Every flavour also has ``none`` (one impulse). Names are case-insensitive; ``ei2``/``2hei`` mean
``2hump_ei`` and ``ei3``/``3hei`` mean ``3hump_ei``. Asking a flavour for a shaper its firmware lacks
raises :class:`RingtuneError` naming the closest shaper it has.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ringtune.shaping.errors import RingtuneError

FLAVORS = ("klipper", "klipper-legacy", "rrf", "rrf35", "marlin", "marlin-ftm")

#: Klipper's SHAPER_VIBRATION_REDUCTION = 20 -> EI vibration tolerance 1/20
DEFAULT_V_TOL = 0.05
#: RepRapFirmware step clock on Duet 3 boards, Hz (delays are whole step clocks)
RRF_STEP_CLOCK = 750_000.0
#: Marlin FT_MOTION trajectory sample rate, Hz (impulse times are whole samples)
FTM_FS = 1000.0

DEFAULT_DAMPING = {
    "klipper": 0.1, "klipper-legacy": 0.1, "rrf": 0.1, "rrf35": 0.1,
    "marlin": 0.15,       # SHAPING_ZETA_X/Y default in Configuration_adv.h
    "marlin-ftm": 0.1,    # FTM_SHAPING_ZETA_X/Y
}
#: Flavours that centre the impulse train on its centroid (no steady-state lag).
CENTRED = {"klipper": True, "klipper-legacy": True, "marlin-ftm": True,
           "rrf": False, "rrf35": False, "marlin": False}


@dataclass(frozen=True)
class Shaper:
    """An impulse train. ``amplitudes`` sum to 1; ``times`` in s, first 0, increasing.

    ``centre`` is the delay (s) a centring firmware subtracts (default the centroid Σ A_i T_i;
    Marlin FT_MOTION rounds it to whole samples).
    """

    name: str
    flavor: str
    freq: float
    damping: float
    amplitudes: np.ndarray
    times: np.ndarray
    centre: float | None = field(default=None, compare=False)

    @property
    def duration(self) -> float:
        """Time from first to last impulse, s."""
        return float(self.times[-1])

    @property
    def centroid(self) -> float:
        """Σ A_i T_i, s: the steady-state lag of causal shaping."""
        return float(np.dot(self.amplitudes, self.times))

    @property
    def centre_delay(self) -> float:
        """Delay removed by centring firmwares, s."""
        return self.centroid if self.centre is None else float(self.centre)

    @property
    def n_impulses(self) -> int:
        return len(self.amplitudes)

    def to_dict(self) -> dict:
        return {"name": self.name, "flavor": self.flavor, "freq": self.freq, "damping": self.damping,
                "amplitudes": self.amplitudes.tolist(), "times": self.times.tolist()}


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


def mzv_coeffs(n: int, t: float) -> np.ndarray:
    """Undamped generalised-MZV amplitudes (Klipper ``get_mzv_coeffs``), impulses at i·t/(n-1)."""
    if n < 3 or not n > 2 * t + 1:
        raise RingtuneError(f"mzv needs n >= 3 and n > 2t+1 (got n={n}, t={t:g})")
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
    return A


def mzv(f, z, n: int = 3, t: float = 0.75, tau: float | None = None):
    if tau is not None:
        t = tau * (n - 1) / (n + 2 * tau - 2)
    n = int(n)
    A = mzv_coeffs(n, t)
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


# -- RepRapFirmware (§3.2): damped period in whole step clocks ---------------------------------
def _rrf_period(f, z) -> float:
    """Damped period P in step clocks (lrintf in 3.6-dev)."""
    return float(np.rint(RRF_STEP_CLOCK / (f * _df(z))))


def _rrf_times(mults, f, z) -> np.ndarray:
    return np.rint(np.asarray(mults, float) * _rrf_period(f, z)) / RRF_STEP_CLOCK


def _rrf_binomial(order: int):
    def shaper(f, z):
        a, _ = binomial_zv(order)(f, z)
        return a, _rrf_times(0.5 * np.arange(order + 2), f, z)
    return shaper


def _rrf_mzv(reversed_order: bool):
    def shaper(f, z):
        kp = math.exp(-0.75 * z * math.pi / _df(z))
        a1 = 1 - math.sqrt(2) / 2
        a = np.array([a1, (math.sqrt(2) - 1) * kp, a1 * kp * kp])
        if reversed_order:  # RRF 3.4/3.5 (and 3.6-dev) store a3 first
            a = a[::-1]
        return a / a.sum(), _rrf_times([0.0, 0.375, 0.75], f, z)
    return shaper


def _rrf_ei(a_rows, t_rows, cumulative_durations: bool):
    def shaper(f, z):
        a = _poly(a_rows, z)[:-1]
        a = np.append(a, 1.0 - a.sum())           # last = 1 − Σ others
        tp = _poly(t_rows, z)
        if cumulative_durations:                   # 3.4/3.5: each interval rounded on its own
            P = _rrf_period(f, z)
            t = np.concatenate([[0.0], np.cumsum(np.rint(np.diff(tp) * P))]) / RRF_STEP_CLOCK
        else:
            t = _rrf_times(tp, f, z)
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


def _ftm(family: Callable, base: float):
    """Marlin FT_MOTION: legacy amplitudes; N_i = i·LROUND(base/f/df·FS) samples."""
    def shaper(f, z, **params):
        a, _ = family(f, z, **params)
        n1 = math.floor(base / f / _df(z) * FTM_FS + 0.5)
        return a, np.arange(len(a)) * n1 / FTM_FS
    return shaper


def ftm_mzv(f, z):
    k = _k(z)   # Marlin FTM uses exp(-ζπ/df), not Klipper's exp(-0.75ζπ/df)
    return _norm([1.0, math.sqrt(2) * k, k * k], [0.0, 0.375, 0.75])


def _ftm_centre(a: np.ndarray, t: np.ndarray) -> float:
    """FTM centring delay: N0 = LROUND(Σ_{i≥1} A_i·N_i) samples."""
    return math.floor(float(np.dot(a, t)) * FTM_FS + 0.5) / FTM_FS


# ---------------------------------------------------------------------------------------------
# THE registry: flavour -> name -> (formula, accepted parameters, max damping)
# (RRF ei2/ei3 use Klipper's cubic fits, valid to ζ 0.3 / 0.2; later RRF sources clamp S there too)
_P_MZV = ("n", "t", "tau")
_P_EI = ("v_tol",)
REGISTRY: dict[str, dict[str, tuple[Callable, tuple[str, ...], float]]] = {
    "klipper": {
        "none": (none_shaper, (), 0.99), "zv": (zv, (), 0.99), "mzv": (mzv, _P_MZV, 0.99),
        "zvd": (zvd, (), 0.99), "ei": (ei, _P_EI, 0.4), "2hump_ei": (ei2, (), 0.3),
        "3hump_ei": (ei3, (), 0.2),
    },
    "klipper-legacy": {
        "none": (none_shaper, (), 0.99), "zv": (zv, (), 0.99), "mzv": (mzv_legacy, (), 0.99),
        "zvd": (zvd, (), 0.99), "ei": (ei_legacy, _P_EI, 0.99), "2hump_ei": (ei2_legacy, _P_EI, 0.99),
        "3hump_ei": (ei3_legacy, _P_EI, 0.99),
    },
    "rrf": {
        "none": (none_shaper, (), 0.99), "zvd": (_rrf_binomial(1), (), 0.99),
        "zvdd": (_rrf_binomial(2), (), 0.99), "zvddd": (_rrf_binomial(3), (), 0.99),
        "mzv": (_rrf_mzv(False), (), 0.99), "2hump_ei": (_rrf_ei(EI2_A, EI2_T, False), (), 0.3),
        "3hump_ei": (_rrf_ei(EI3_A, EI3_T, False), (), 0.2), "custom": (None, ("h", "t"), 0.99),
    },
    "rrf35": {
        "none": (none_shaper, (), 0.99), "zvd": (_rrf_binomial(1), (), 0.99),
        "zvdd": (_rrf_binomial(2), (), 0.99), "zvddd": (_rrf_binomial(3), (), 0.99),
        "mzv": (_rrf_mzv(True), (), 0.99), "2hump_ei": (_rrf_ei(EI2_A, EI2_T, True), (), 0.3),
        "3hump_ei": (_rrf_ei(EI3_A, EI3_T, True), (), 0.2), "custom": (None, ("h", "t"), 0.99),
    },
    "marlin": {"none": (none_shaper, (), 1.0), "zv": (marlin_zv, (), 1.0)},
    "marlin-ftm": {
        "none": (none_shaper, (), 0.99), "zv": (_ftm(zv, 0.5), (), 0.99),
        "zvd": (_ftm(zvd, 0.5), (), 0.99), "zvdd": (_ftm(binomial_zv(2), 0.5), (), 0.99),
        "zvddd": (_ftm(binomial_zv(3), 0.5), (), 0.99), "ei": (_ftm(ei_legacy, 0.5), _P_EI, 0.99),
        "2hump_ei": (_ftm(ei2_legacy, 0.5), _P_EI, 0.99), "3hump_ei": (_ftm(ei3_legacy, 0.5), _P_EI, 0.99),
        "mzv": (_ftm(ftm_mzv, 0.375), (), 0.99),
    },
}

ALIASES = {"ei2": "2hump_ei", "2hei": "2hump_ei", "2humpei": "2hump_ei", "ei3": "3hump_ei",
           "3hei": "3hump_ei", "3humpei": "3hump_ei", "off": "none", "null": "none"}

#: for an unavailable shaper, the others in order of likeness (impulse count, duration, robustness)
_CLOSEST = {
    "zv": ("mzv", "zvd", "ei"), "mzv": ("zv", "zvd", "ei"), "zvd": ("ei", "mzv", "zvdd", "zv"),
    "ei": ("zvd", "2hump_ei", "mzv", "zv"), "zvdd": ("2hump_ei", "zvd", "zvddd", "ei", "zv"),
    "zvddd": ("3hump_ei", "zvdd", "2hump_ei", "zvd", "zv"),
    "2hump_ei": ("zvdd", "3hump_ei", "ei", "zvd", "zv"), "3hump_ei": ("zvddd", "2hump_ei", "ei", "zv"),
    "custom": ("zvd", "mzv", "zv"), "none": (),
}

_PARAM_RE = re.compile(r"^(\w+)\s*\((.*)\)$")


def available_shapers(flavor: str = "klipper") -> tuple[str, ...]:
    """Canonical shaper names the flavour's firmware offers (``none`` included)."""
    return tuple(_flavor_table(flavor))


def is_centred(flavor: str) -> bool:
    """Whether the firmware centres the impulse train (Klipper, Prusa, Marlin FTM) or lags (RRF, Marlin)."""
    _flavor_table(flavor)
    return CENTRED[flavor]


def default_damping(flavor: str) -> float:
    _flavor_table(flavor)
    return DEFAULT_DAMPING[flavor]


def max_damping(name: str, flavor: str = "klipper") -> float:
    """Largest damping ratio the flavour accepts for the shaper (Klipper HEAD max_damping_ratio)."""
    base, _ = parse_name(name)
    return _entry(base, flavor, "shaper")[2]


def canonical_name(name: str) -> str:
    """Lower-case canonical base name (aliases resolved, parameters dropped)."""
    return parse_name(name)[0]


def parse_name(name: str, where: str = "shaper") -> tuple[str, dict]:
    """Split ``"mzv(n=5,t=1.1)"`` into ``("mzv", {"n": 5, "t": 1.1})``; resolve aliases.

    Parameters follow Klipper's syntax: ``name(args)``, args numbers, named or positional (not
    both). ``custom(h=0.4:0.7,t=0.0135:0.0135)`` takes colon-separated lists.
    """
    if not isinstance(name, str) or not name.strip():
        raise RingtuneError("shaper name must be a non-empty string", where)
    text = name.strip().lower()
    params: dict = {}
    m = _PARAM_RE.match(text)
    if m:
        text, args = m.group(1), m.group(2).strip()
        positional = []
        for part in filter(None, (p.strip() for p in args.split(","))):
            key, _, value = part.rpartition("=")
            key = key.strip()
            try:
                if ":" in value:
                    val = [float(x) for x in value.split(":")]
                else:
                    val = int(value) if re.fullmatch(r"\s*\d+\s*", value) else float(value)
            except ValueError:
                raise RingtuneError(f"bad shaper parameter {part!r} in {name!r}", where) from None
            if key:
                params[key] = val
            else:
                positional.append(val)
        if positional and params:
            raise RingtuneError(f"give shaper parameters by name or by position, not both: {name!r}", where)
        if positional:
            params["_positional"] = positional
    elif "(" in text or ")" in text:
        raise RingtuneError(f"cannot parse shaper {name!r}; expected e.g. 'mzv(n=5,t=1.1)'", where)
    text = text.replace("-", "_").replace(" ", "")
    text = ALIASES.get(text, ALIASES.get(text.replace("_", ""), text))
    return text, params


def _flavor_table(flavor: str) -> dict:
    if flavor not in REGISTRY:
        raise RingtuneError(f"unknown shaper flavour {flavor!r}; one of {', '.join(FLAVORS)}", "flavor")
    return REGISTRY[flavor]


def closest_available(name: str, flavor: str) -> str:
    table = _flavor_table(flavor)
    for other in _CLOSEST.get(name, ()):
        if other in table:
            return other
    return next(n for n in table if n != "none")


def _entry(base: str, flavor: str, where: str):
    table = _flavor_table(flavor)
    if base in table:
        return table[base]
    if base not in _CLOSEST:
        known = sorted(set(_CLOSEST) | set(ALIASES))
        raise RingtuneError(f"unknown shaper {base!r}; known: {', '.join(known)}", where)
    near = closest_available(base, flavor)
    raise RingtuneError(f"{flavor} has no {base!r} shaper; the closest it offers is {near!r} "
                        f"(available: {', '.join(table)})", where)


def get_shaper(name: str, freq: float, damping: float | None = None, flavor: str = "klipper", *,
               h=None, t=None, where: str = "shaper") -> Shaper:
    """The shaper ``name`` of firmware ``flavor`` at ``freq`` Hz and damping ratio ``damping``.

    ``damping`` None takes the flavour's default. ``h``/``t`` (or ``custom(h=…,t=…)``) give the
    impulses of an RRF custom shaper in the flavour's own semantics (see ``shaping.custom``).
    """
    base, params = parse_name(name, where)
    func, allowed, zmax = _entry(base, flavor, where)
    z = DEFAULT_DAMPING[flavor] if damping is None else damping
    if isinstance(freq, bool) or not isinstance(freq, (int, float, np.floating)) or not math.isfinite(freq) \
            or freq <= 0:
        raise RingtuneError(f"frequency must be a finite number > 0 Hz, not {freq!r}", where)
    if isinstance(z, bool) or not isinstance(z, (int, float, np.floating)) or not math.isfinite(z) \
            or not 0 <= z <= zmax or z >= 1:
        raise RingtuneError(f"damping ratio of {base!r} ({flavor}) must be in [0, {min(zmax, 0.99):g}], "
                            f"not {z!r}", where)
    freq, z = float(freq), float(z)
    positional = params.pop("_positional", None)
    if positional:
        if len(positional) > len(allowed):
            raise RingtuneError(f"{base!r} takes at most {len(allowed)} parameters "
                                f"({', '.join(allowed) or 'none'}) in {flavor}", where)
        params.update(zip(allowed, positional))
    unknown = set(params) - set(allowed)
    if unknown:
        raise RingtuneError(f"{base!r} in {flavor} takes no parameter {', '.join(sorted(unknown))}"
                            + (f" (accepted: {', '.join(allowed)})" if allowed else ""), where)
    if base == "custom":
        from ringtune.shaping.custom import rrf_custom
        h = params.get("h", h)
        t = params.get("t", t)
        a, times = rrf_custom(h, t, freq, z, semantics="3.6" if flavor == "rrf" else "3.5", where=where)
    else:
        if "v_tol" in params and not 0 < params["v_tol"] < 1:
            raise RingtuneError(f"v_tol must be in (0, 1), not {params['v_tol']}", where)
        try:
            a, times = func(freq, z, **params)
        except RingtuneError as exc:
            raise RingtuneError(exc.bare, where) from None
    a = np.asarray(a, float)
    times = np.asarray(times, float)
    if len(times) > 1 and np.any(np.diff(times) <= 0):
        raise RingtuneError(f"{name!r} at {freq:g} Hz has coinciding impulse times "
                            f"(frequency too high for {flavor}'s time quantisation)", where)
    a.setflags(write=False)
    times.setflags(write=False)
    centre = _ftm_centre(a, times) if flavor == "marlin-ftm" else None
    label = name.strip().lower() if params else base
    return Shaper(label, flavor, freq, z, a, times, centre)
