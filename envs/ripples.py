"""Vibration modes from what a person measures on a printed part, without an accelerometer.

Ripples (seed 000, RepRapFirmware's M593 notes): a wall printed at a constant speed ``V`` (mm/s)
right after a sharp corner carries the ringing of the axis that just stopped, frozen into the
plastic. Adjacent ripple peaks lie ``s = V / f_d`` mm apart, where ``f_d`` is the frequency at
which the mode rings freely — its *damped* frequency ``f_d = f·√(1 − ζ²)``. The first peaks after
the corner are closer together (the head is still accelerating along the wall) and are skipped.

Damping from the heights of successive ripples (the logarithmic decrement): a free decay falls by
``R = h_k / h_{k+1} = exp(δ)`` per period, ``δ = 2πζ/√(1 − ζ²)``, so ``ζ = δ / √(4π² + δ²)``.

A ringing tower (bands printed at different shaper frequencies): the band with the least ringing
is printed with the shaper frequency closest to the mode; its frequency is the estimate, good to
half the band step.

Units: mm, mm/s, Hz; damping ratios are dimensionless.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ringtune.shaping.errors import RingtuneError


@dataclass(frozen=True)
class RippleMode:
    """One axis's mode from a ripple measurement.

    freq: natural frequency, Hz; damped_freq: the ringing frequency ``V/spacing``, Hz;
    damping: ratio; spacing: mm between adjacent ripple peaks; speed: wall speed, mm/s;
    damping_from: where the damping came from (e.g. ``"decay ratio 1.9"``, ``"klipper default"``).
    """

    axis: str
    freq: float
    damped_freq: float
    damping: float
    spacing: float
    speed: float
    damping_from: str


#: damping ratio assumed when none is measured: the median of the dominant modes' damping that
#: ``ringtune identify`` fits to the ten axes of real Klipper resonance tests in
#: ``tests/data/accel/klipper_psd`` (Ender 3, Switchwire, Voron 0.1, Voron 2.4, CR-10S Pro, one
#: unnamed printer; they span 0.04-0.23). A physical property of printers, not any firmware's shaper
#: setting (Klipper builds shapers at 0.1, Marlin at 0.15: those choose a shaper, they measure nothing).
TYPICAL_DAMPING = 0.12
TYPICAL_DAMPING_SOURCE = ("the median damping of the dominant modes fitted to ten real Klipper resonance "
                          "tests (tests/data/accel/klipper_psd: 0.04-0.23)")


#: the largest damping ripples are read for: twice the highest of the real tests (0.23) would still
#: leave a ripple 1/7 of the one before; beyond it the ripples are gone after one or two
MAX_RIPPLE_DAMPING = 0.3
#: ringing frequencies a ripple spacing can be (Hz): Klipper's resonance sweep starts at 5 Hz, and
#: no printer frame rings above 300 Hz with a ripple one could count (the real tests peak at 130 Hz)
RIPPLE_FREQ_RANGE = (5.0, 300.0)


def damping_from_ratio(ratio: float, where: str = "ratio") -> float:
    """Damping ratio from the ratio ``R`` of a ripple's height over the next one's (> 1: ringing
    decays), by the logarithmic decrement ``δ = ln R``, ``ζ = δ/√(4π² + δ²)``. Ripples that grow
    (``R < 1``) are not a free decay: refused."""
    if not (isinstance(ratio, (int, float)) and math.isfinite(ratio) and ratio > 0):
        raise RingtuneError(f"a ratio of ripple heights must be a positive number, not {ratio!r}", where)
    if ratio < 1.0:
        raise RingtuneError(f"ripples that grow (each {ratio:g} of the next one's height) are not a decay: "
                            "something pumps the resonance (a zigzag, a fan), or the heights are in the wrong "
                            "order — give a ripple's height over the NEXT one's, e.g. 1.6", where)
    delta = math.log(ratio)
    if delta < 1e-6:
        raise RingtuneError("successive ripples of equal height show no decay: the damping cannot be "
                            "read from them (measure the first and a later ripple)", where)
    zeta = delta / math.sqrt(4.0 * math.pi ** 2 + delta ** 2)
    if zeta > MAX_RIPPLE_DAMPING:
        raise RingtuneError(f"a ripple {ratio:g} times the next one's height means damping {zeta:.2f}, beyond "
                            f"{MAX_RIPPLE_DAMPING:g} (real printers: 0.04-0.23): ripples that die that fast leave "
                            "none to measure; give one ripple's height over the very next one's "
                            f"(at most {ratio_from_damping(MAX_RIPPLE_DAMPING):.1f})", where)
    return zeta


def ratio_from_damping(damping: float) -> float:
    """Height ratio of a ripple to the next one for damping ratio ``damping`` (< 1)."""
    return math.exp(2.0 * math.pi * damping / math.sqrt(1.0 - damping ** 2))


def mode_from_ripples(axis: str, spacing: float, speed: float, damping: float,
                      damping_from: str, where: str = "ripples") -> RippleMode:
    """The mode behind ripples ``spacing`` mm apart on a wall printed at ``speed`` mm/s:
    ringing frequency ``V/s``, natural frequency ``V/(s·√(1 − ζ²))``."""
    for name, v in (("spacing", spacing), ("speed", speed)):
        if not (math.isfinite(v) and v > 0):
            raise RingtuneError(f"{name} must be a positive number, not {v:g}", where)
    if not 0 <= damping < 1:
        raise RingtuneError(f"damping ratio must be in [0, 1), not {damping:g}", where)
    fd = speed / spacing
    lo, hi = RIPPLE_FREQ_RANGE
    if not lo <= fd <= hi:
        raise RingtuneError(f"{speed:g} mm/s over {spacing:g} mm is {fd:.3g} Hz: not a printer resonance "
                            f"(expected {lo:g}-{hi:g} Hz); is the spacing in mm, between adjacent ripples, and the "
                            "speed the wall's, in mm/s?", where)
    return RippleMode(axis, fd / math.sqrt(1.0 - damping ** 2), fd, damping, spacing, speed, damping_from)


def parse_axis_values(text: str, option: str, positive: bool = True) -> dict[str, float]:
    """``"X=2.4,Y=2.9"`` -> ``{"x": 2.4, "y": 2.9}`` (one axis is enough; errors name ``option``)."""
    out: dict[str, float] = {}
    for part in str(text).split(","):
        key, sep, value = part.partition("=")
        ax = key.strip().lower()
        if not sep or ax not in ("x", "y"):
            raise RingtuneError(f"expected AXIS=VALUE pairs like X=2.4,Y=2.9, not {part.strip()!r}", option)
        if ax in out:
            raise RingtuneError(f"axis {ax.upper()} given twice", option)
        try:
            v = float(value)
        except ValueError:
            raise RingtuneError(f"{ax.upper()}={value.strip()!r} is not a number", option) from None
        if not math.isfinite(v) or (positive and v <= 0):
            raise RingtuneError(f"{ax.upper()}={value.strip()} must be a positive number", option)
        out[ax] = v
    return out


def tower_frequency(bands: list[tuple[float, float, float]], number: int, axis: str,
                    where: str = "--tower-band") -> tuple[float, float]:
    """(frequency, half the step to the neighbouring bands) of band ``number`` (1 = lowest) for
    ``axis``, from ``bands`` = [(z_bottom mm, z_top mm, {axis: Hz})...] as the tower's table has
    them."""
    if not 1 <= number <= len(bands):
        raise RingtuneError(f"band {number} of axis {axis.upper()}: the tower has bands 1 to {len(bands)}",
                            where)
    freqs = [b[2][axis] for b in bands]
    f = freqs[number - 1]
    if f <= 0:
        raise RingtuneError(f"band {number} was printed with shaping off on {axis.upper()}: it says nothing "
                            "about the frequency", where)
    steps = [abs(b - a) for a, b in zip(freqs, freqs[1:]) if a > 0 and b > 0]
    return f, (min(steps) / 2.0 if steps else math.nan)
