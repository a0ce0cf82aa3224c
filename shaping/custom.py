"""RepRapFirmware custom shapers (``M593 P"custom" H… T…``) in both firmware semantics.

- RRF 3.6 (``semantics="3.6"``): ``H`` = individual amplitudes of every impulse except the last
  (at most 4); the last gets ``1 − ΣH``, so ΣH must be < 1. ``T`` = cumulative delays (s) of
  impulses 2..n from the first, strictly increasing; default ``T_i = i·t_d/2``.
- RRF 3.4/3.5 (``semantics="3.5"``): ``H`` = cumulative amplitudes of the extra impulses, each
  larger than the one before and below 1 (the last cumulative amplitude is 1.0); ``T`` = durations
  (s) between successive impulses, each > 0; default ``t_d/2`` each.

``t_d`` is the damped period ``1/(f·sqrt(1−ζ²))``. Returns (amplitudes summing to 1, times from 0).
With ``step_clocks`` (RRF 3.6 as it runs) the delays become whole 750 kHz step clocks as the
firmware stores them: ``lrintf(T·rate)``, or ``(P·i)/2`` with the integer damped period P.
"""

from __future__ import annotations

import math

import numpy as np

from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.shaper_formulas import RRF_STEP_CLOCK, rrf_clocks, rrf_period_clocks

MAX_EXTRA_IMPULSES = 4
SEMANTICS = ("3.6", "3.5")


def _as_list(values, what: str, where: str) -> list[float] | None:
    if values is None:
        return None
    if isinstance(values, (int, float, np.floating)) and not isinstance(values, bool):
        values = [values]
    try:
        out = [float(v) for v in values]
    except (TypeError, ValueError):
        raise RingtuneError(f"{what} must be numbers separated by ':', not {values!r}", where) from None
    if not all(math.isfinite(v) for v in out):
        raise RingtuneError(f"{what} values must be finite: {out}", where)
    return out


def rrf_custom(h, t, freq: float, damping: float, semantics: str = "3.6",
               where: str = "M593", step_clocks: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Amplitudes and times (s) of an RRF custom shaper from its ``H`` and ``T`` lists (``freq``
    Hz, ``damping`` ratio); ``step_clocks`` quantises 3.6 delays as the firmware does."""
    if semantics not in SEMANTICS:
        raise RingtuneError(f"semantics must be one of {SEMANTICS}, not {semantics!r}", where)
    hs = _as_list(h, "H", f"{where} H")
    ts = _as_list(t, "T", f"{where} T")
    _check_counts(hs, ts, where)
    half = 0.5 / (freq * math.sqrt(1.0 - damping * damping))
    if semantics == "3.6":
        return _rrf36(hs, ts, half, freq, damping, step_clocks, where)
    return _rrf35(hs, ts, half, where)


def _check_counts(hs: list, ts: list | None, where: str) -> None:
    """H given, at most :data:`MAX_EXTRA_IMPULSES` values, T (if given) as many."""
    if not hs:
        raise RingtuneError('P"custom" needs H (amplitudes of the impulses except the last)', f"{where} H")
    if len(hs) > MAX_EXTRA_IMPULSES:
        raise RingtuneError(f"at most {MAX_EXTRA_IMPULSES} values allowed, got {len(hs)}", f"{where} H")
    if ts is not None and len(ts) != len(hs):
        raise RingtuneError(f"T needs as many values as H ({len(hs)}), got {len(ts)}", f"{where} T")


def _rrf36(hs: list, ts: list | None, half: float, freq: float, damping: float, step_clocks: bool,
           where: str) -> tuple[np.ndarray, np.ndarray]:
    """3.6: H the amplitudes of all impulses but the last, T their delays after the first (default
    multiples of half the damped period); ``step_clocks``: delays in whole step clocks."""
    n = len(hs)
    if any(v < 0 for v in hs):
        raise RingtuneError(f"amplitudes must not be negative: {hs}", f"{where} H")
    if sum(hs) >= 1.0:
        raise RingtuneError(f"amplitudes must sum to less than 1 (the last impulse gets 1 − ΣH); "
                            f"ΣH = {sum(hs):g}", f"{where} H")
    amps = np.array(hs + [1.0 - sum(hs)])
    delays = np.arange(1, n + 1) * half if ts is None else np.array(ts)
    if ts is not None and (delays[0] <= 0 or np.any(np.diff(delays) <= 0)):
        raise RingtuneError(f"delays must be > 0 and strictly increasing: {ts}", f"{where} T")
    if step_clocks:
        delays = _step_clock_delays(ts, delays, freq, damping, n, where)
    return amps, np.concatenate([[0.0], delays])


def _step_clock_delays(ts, delays: np.ndarray, freq: float, damping: float, n: int, where: str) -> np.ndarray:
    """The delays (s) as RRF 3.6 runs them, in whole step clocks; refused when two coincide."""
    if ts is None:
        P = rrf_period_clocks(freq, damping)
        clocks = np.array([(P * i) // 2 for i in range(1, n + 1)])
    else:
        clocks = rrf_clocks(delays)
    if np.any(np.diff(np.concatenate([[0], clocks])) <= 0):
        raise RingtuneError(f"delays closer than one step clock: {ts}", f"{where} T")
    return clocks / RRF_STEP_CLOCK


def _rrf35(hs: list, ts: list | None, half: float, where: str) -> tuple[np.ndarray, np.ndarray]:
    """3.4 / 3.5: H cumulative amplitudes, T the durations between impulses (default half the
    damped period)."""
    cum = np.array(hs)
    if cum[0] <= 0 or np.any(np.diff(cum) <= 0) or cum[-1] >= 1.0:
        raise RingtuneError(f"cumulative amplitudes must increase strictly and stay below 1: {hs}",
                            f"{where} H")
    amps = np.diff(np.concatenate([[0.0], cum, [1.0]]))
    durations = np.full(len(hs), half) if ts is None else np.array(ts)
    if np.any(durations <= 0):
        raise RingtuneError(f"durations must be > 0: {ts}", f"{where} T")
    return amps, np.concatenate([[0.0], np.cumsum(durations)])
