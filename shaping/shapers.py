"""Every input shaper the firmwares use, in one registry, per firmware flavour.

A shaper is a train of impulses: amplitudes ``A`` (sum 1) at times ``T`` (s, first 0, increasing).
Each formula (in ``shaping.shaper_formulas``) is a small pure function
``(freq Hz, damping ratio[, params]) -> (A, T)``; the flavour tables below say which formula each
firmware uses for each name (sources:
``reference/firmware.md`` §1.1, §2.1, §2.2, §3.2, §4, §6):

========== ==========================================================================================
flavour    shapers (formula family)
========== ==========================================================================================
klipper    zv, mzv (generalised ``mzv(n=…,t=…)``), zvd, ei (``ei(v_tol=…)``), 2hump_ei, 3hump_ei (HEAD)
klipper-   zv, mzv, zvd, ei, 2hump_ei, 3hump_ei — the ≤ v0.13 closed forms (also Prusa Buddy);
legacy     EI types take ``v_tol`` (Prusa's ``R`` = 1/v_tol)
kalico     zv, mzv, zvd, ei, 2hump_ei, 3hump_ei as klipper-legacy (no parameters), and the continuous
           smoothers smooth_zv, smooth_mzv, smooth_ei, smooth_2hump_ei, smooth_zvd_ei, smooth_si
           (:class:`Smoother`, :mod:`ringtune.shaping.smoothers`)
rrf        RRF 3.6: zvd, zvdd, zvddd, mzv, ei2, ei3 (Klipper HEAD polynomials × DAMPED period),
           custom; delays in whole 750 kHz step clocks of an lrintf damped period; MZV amplitudes
           in the firmware's reversed order (a3 first); no zv, no ei
rrf35      RRF 3.4/3.5: same set and MZV order; float (unrounded) durations; custom with
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

from ringtune.shaping.custom import rrf_custom
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.smoothers import KALICO_SMOOTHERS, kernel, quadrature
from ringtune.shaping.shaper_formulas import (EI2_A, EI2_T, EI3_A, EI3_T, binomial_zv, ei, ei2, ei2_legacy,
    ei3, ei3_legacy, ei_legacy, ftm_centre, ftm_mzv, ftm_shaper, marlin_zv, mzv, mzv_legacy, none_shaper,
    rrf_binomial, rrf_ei, rrf_mzv, zv, zvd)

FLAVORS = ("klipper", "klipper-legacy", "kalico", "rrf", "rrf35", "marlin", "marlin-ftm")


DEFAULT_DAMPING = {
    "klipper": 0.1, "klipper-legacy": 0.1, "kalico": 0.1, "rrf": 0.1, "rrf35": 0.1,
    "marlin": 0.15,       # SHAPING_ZETA_X/Y default in Configuration_adv.h
    "marlin-ftm": 0.1,    # FTM_SHAPING_ZETA_X/Y
}
#: most impulses the firmware accepts (Klipper kin_shaper.c: 10 at HEAD, 5 up to v0.13)
MAX_PULSES = {"klipper": 10, "klipper-legacy": 5, "kalico": 25}
#: Flavours that centre the impulse train on its centroid (no steady-state lag).
CENTRED = {"klipper": True, "klipper-legacy": True, "kalico": True, "marlin-ftm": True,
           "rrf": False, "rrf35": False, "marlin": False}


@dataclass(frozen=True, eq=False)
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

    def _key(self) -> tuple:
        return (self.name, self.flavor, self.freq, self.damping, tuple(self.amplitudes.tolist()),
                tuple(self.times.tolist()), self.centre)

    def __eq__(self, other) -> bool:
        return isinstance(other, Shaper) and self._key() == other._key()

    def __hash__(self) -> int:
        return hash(self._key())

    def to_dict(self) -> dict:
        return {"name": self.name, "flavor": self.flavor, "freq": self.freq, "damping": self.damping,
                "amplitudes": self.amplitudes.tolist(), "times": self.times.tolist()}


@dataclass(frozen=True, eq=False)
class Smoother(Shaper):
    """A continuous input smoother (Kalico's ``smooth_*``; :mod:`ringtune.shaping.smoothers`): its
    impulses are the Gauss–Legendre quadrature of the convolution integral. ``coeffs``: ascending
    ``c_k`` of the unit-integral kernel ``w(τ) = Σ c_k τ^k`` (τ in s) on ``[−T_sm/2, T_sm/2]``;
    ``smooth_time``: ``T_sm``, s; ``offset``: ``t_offs = ∫ τ·w``, s (the firmware's centring)."""

    coeffs: tuple[float, ...] = ()
    smooth_time: float = 0.0
    offset: float = 0.0

    @property
    def duration(self) -> float:
        """The kernel's support, s."""
        return float(self.smooth_time)

    def to_dict(self) -> dict:
        return {**super().to_dict(), "kernel_coeffs": list(self.coeffs), "smooth_time": self.smooth_time,
                "offset": self.offset}


def _smoother(name: str, freq: float, damping: float, flavor: str) -> Smoother:
    """Kalico's smoother ``name`` at ``freq`` Hz; ``damping`` is only the plant damping its residual
    is judged at by default (Kalico's kernel ignores it)."""
    w, t_sm, offset = kernel(name, freq)
    amps, times = quadrature(name, t_sm)
    amps.setflags(write=False)
    times.setflags(write=False)
    return Smoother(name, flavor, float(freq), float(damping), amps, times, offset + 0.5 * t_sm,
                    tuple(float(c) for c in w.coef), t_sm, offset)


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
    # Kalico (KalicoCrew/kalico 8b9f661 shaper_defs.py): Klipper's closed forms of before 2025 (the
    # EI family with v_tol fixed at 0.05, no parameters), and its continuous smoothers
    "kalico": {
        "none": (none_shaper, (), 0.99), "zv": (zv, (), 0.99), "mzv": (mzv_legacy, (), 0.99),
        "zvd": (zvd, (), 0.99), "ei": (ei_legacy, (), 0.99), "2hump_ei": (ei2_legacy, (), 0.99),
        "3hump_ei": (ei3_legacy, (), 0.99), **{name: (None, (), 0.99) for name in KALICO_SMOOTHERS},
    },
    "rrf": {
        "none": (none_shaper, (), 0.99), "zvd": (rrf_binomial(1, True), (), 0.99),
        "zvdd": (rrf_binomial(2, True), (), 0.99), "zvddd": (rrf_binomial(3, True), (), 0.99),
        "mzv": (rrf_mzv(True), (), 0.99), "2hump_ei": (rrf_ei(EI2_A, EI2_T, True), (), 0.3),
        "3hump_ei": (rrf_ei(EI3_A, EI3_T, True), (), 0.2), "custom": (None, ("h", "t"), 0.99),
    },
    "rrf35": {
        "none": (none_shaper, (), 0.99), "zvd": (rrf_binomial(1, False), (), 0.99),
        "zvdd": (rrf_binomial(2, False), (), 0.99), "zvddd": (rrf_binomial(3, False), (), 0.99),
        "mzv": (rrf_mzv(False), (), 0.99), "2hump_ei": (rrf_ei(EI2_A, EI2_T, False), (), 0.3),
        "3hump_ei": (rrf_ei(EI3_A, EI3_T, False), (), 0.2), "custom": (None, ("h", "t"), 0.99),
    },
    "marlin": {"none": (none_shaper, (), 1.0), "zv": (marlin_zv, (), 1.0)},
    "marlin-ftm": {
        "none": (none_shaper, (), 0.99), "zv": (ftm_shaper(zv, 0.5), (), 0.99),
        "zvd": (ftm_shaper(zvd, 0.5), (), 0.99), "zvdd": (ftm_shaper(binomial_zv(2), 0.5), (), 0.99),
        "zvddd": (ftm_shaper(binomial_zv(3), 0.5), (), 0.99), "ei": (ftm_shaper(ei_legacy, 0.5), _P_EI, 0.99),
        "2hump_ei": (ftm_shaper(ei2_legacy, 0.5), _P_EI, 0.99), "3hump_ei": (ftm_shaper(ei3_legacy, 0.5), _P_EI, 0.99),
        "mzv": (ftm_shaper(ftm_mzv, 0.375), (), 0.99),
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
    "smooth_zv": ("zv", "mzv"), "smooth_mzv": ("mzv", "zvd", "ei"), "smooth_ei": ("ei", "zvd", "mzv"),
    "smooth_2hump_ei": ("2hump_ei", "zvdd", "ei"), "smooth_zvd_ei": ("zvd", "ei", "2hump_ei"),
    "smooth_si": ("ei", "zvd", "mzv"),
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


def _parameter_value(value: str):
    """A shaper parameter's value: a colon list of numbers, a whole number, or a number."""
    if ":" in value:
        return [float(x) for x in value.split(":")]
    return int(value) if re.fullmatch(r"\s*\d+\s*", value) else float(value)


def _parameter_list(args: str, name: str, where: str) -> dict:
    """``n=5,t=1.1`` -> {"n": 5, "t": 1.1}; positional values under ``"_positional"`` (not both)."""
    params: dict = {}
    positional = []
    for part in filter(None, (p.strip() for p in args.split(","))):
        key, _, value = part.rpartition("=")
        try:
            val = _parameter_value(value)
        except ValueError:
            raise RingtuneError(f"bad shaper parameter {part!r} in {name!r}", where) from None
        if key.strip():
            params[key.strip()] = val
        else:
            positional.append(val)
    if positional and params:
        raise RingtuneError(f"give shaper parameters by name or by position, not both: {name!r}", where)
    return {"_positional": positional} if positional else params


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
        text, params = m.group(1), _parameter_list(m.group(2).strip(), name, where)
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


def _real(v) -> bool:
    return not isinstance(v, bool) and isinstance(v, (int, float, np.integer, np.floating)) and math.isfinite(v)


def _checked_freq_damping(freq, z, zmax: float, what: str, where: str) -> tuple[float, float]:
    """(freq Hz, damping) as floats, or a refusal: F > 0, 0 ≤ S ≤ the shaper's maximum, below 1."""
    if not _real(freq) or freq <= 0:
        raise RingtuneError(f"frequency must be a finite number > 0 Hz, not {freq!r}", where)
    if not _real(z) or not 0 <= z <= zmax or z >= 1:
        raise RingtuneError(f"damping ratio of {what} must be in [0, {min(zmax, 0.99):g}], not {z!r}", where)
    return float(freq), float(z)


def get_shaper(name: str, freq: float, damping: float | None = None, flavor: str = "klipper", *,
               h=None, t=None, where: str = "shaper") -> Shaper:
    """The shaper ``name`` of firmware ``flavor`` at ``freq`` Hz and damping ratio ``damping``.

    ``damping`` None takes the flavour's default. ``h``/``t`` (or ``custom(h=…,t=…)``) give the
    impulses of an RRF custom shaper in the flavour's own semantics (see ``shaping.custom``).
    """
    base, params = parse_name(name, where)
    func, allowed, zmax = _entry(base, flavor, where)
    freq, z = _checked_freq_damping(freq, DEFAULT_DAMPING[flavor] if damping is None else damping, zmax,
                                    f"{base!r} ({flavor})", where)
    params = _parameters(base, params, allowed, flavor, where)
    if base in KALICO_SMOOTHERS:
        return _smoother(base, freq, z, flavor)
    if base == "custom":
        a, times = rrf_custom(params.get("h", h), params.get("t", t), freq, z,
                              semantics="3.6" if flavor == "rrf" else "3.5", where=where, step_clocks=flavor == "rrf")
    else:
        a, times = _formula(func, freq, z, params, where)
    a, times = _checked_impulses(name, flavor, freq, a, times, where)
    centre = ftm_centre(a, times) if flavor == "marlin-ftm" else None
    label = name.strip().lower() if params else base
    return Shaper(label, flavor, freq, z, a, times, centre)


def _parameters(base: str, params: dict, allowed: tuple, flavor: str, where: str) -> dict:
    """The shaper's parameters by name (positional ones in ``allowed``'s order); one it does not
    take is refused."""
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
    return params


def _formula(func, freq: float, z: float, params: dict, where: str):
    """(amplitudes, times) of a formula shaper; its errors named at ``where``."""
    if "v_tol" in params and not 0 < params["v_tol"] < 1:
        raise RingtuneError(f"v_tol must be in (0, 1), not {params['v_tol']}", where)
    try:
        return func(freq, z, **params)
    except RingtuneError as exc:
        raise RingtuneError(exc.bare, where) from None


def _checked_impulses(name: str, flavor: str, freq: float, a, times, where: str):
    """Read-only arrays of the impulses, refused when two coincide (the flavour's time quantisation)
    or there are more than the firmware takes."""
    a = np.asarray(a, float)
    times = np.asarray(times, float)
    if len(times) > 1 and np.any(np.diff(times) <= 0):
        raise RingtuneError(f"{name!r} at {freq:g} Hz has coinciding impulse times "
                            f"(frequency too high for {flavor}'s time quantisation)", where)
    limit = MAX_PULSES.get(flavor)
    if limit and len(a) > limit:
        raise RingtuneError(f"{name!r} has {len(a)} impulses; {flavor} allows at most {limit}", where)
    a.setflags(write=False)
    times.setflags(write=False)
    return a, times


def shapers_from_config(config) -> tuple[dict[str, Shaper | None], bool]:
    """({"x": Shaper | None, "y": …}, centred) for a :class:`~ringtune.shaping.config.TuneConfig`:
    its firmware's flavour, shaper names, frequencies and dampings. ``"none"`` (and its aliases)
    -> None; ``"daa"`` -> None too: RepRapFirmware's DAA acts in the planner, not as a shaper
    (:attr:`TuneConfig.daa_freq`)."""
    flavor = config.flavor
    out: dict[str, Shaper | None] = {}
    for axis in ("x", "y"):
        name, freq, damping = config.axis(axis)
        if canonical_name(name) in ("none", "daa"):
            out[axis] = None
        else:
            out[axis] = get_shaper(name, freq, damping, flavor, where=f"config: shaper_{axis}")
    return out, CENTRED[flavor]
