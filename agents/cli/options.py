"""The values the commands' options share, as data: what each one means, its unit and the range it
must lie in, applied by argparse when the command line is parsed.

A command declares such an option with ``type=VALUES["accel"]``; a value
out of range is refused before the command runs, in one line naming the option and the range:
``ringtune limit: error: --accel: must be an acceleration > 0 mm/s², not '-5'``.
"""

from __future__ import annotations

import argparse
import math
import operator
from dataclasses import dataclass

from ringtune.envs.motors import lookup_motor, unknown_motor_message
from ringtune.envs.printer_axes import check_moving_mass
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.firmware import FIRMWARES
from ringtune.shaping.shapers import FLAVORS


#: end closed -> whether a value is beyond or at it (``a ≥ b``), else strictly beyond (``a > b``)
_AT_LEAST = {True: operator.ge, False: operator.gt}
#: (low end closed, high end closed) -> a bounded range in words
_RANGE_WORDS = {(True, True): "{:g} to {:g}", (False, False): "between {:g} and {:g}",
                (True, False): "in [{:g}, {:g})", (False, True): "in ({:g}, {:g}]"}


@dataclass(frozen=True)
class Value:
    """A number an option takes: what it is (``"a frequency"``), its unit, and its range
    ``low`` … ``high`` (``None``: unbounded), each end open or closed."""

    meaning: str
    unit: str = ""
    low: float | None = None
    high: float | None = None
    low_closed: bool = False
    high_closed: bool = True
    integer: bool = False

    def range_text(self) -> str:
        """The range in words: ``> 0 Hz``, ``in [0, 1)``, ``1 to 5``, ``between 0 and 100 kg``."""
        unit = f" {self.unit}" if self.unit else ""
        if self.high is None:
            return f"{'≥' if self.low_closed else '>'} {self.low:g}{unit}"
        return _RANGE_WORDS[self.low_closed, self.high_closed].format(self.low, self.high) + unit

    def holds(self, v: float) -> bool:
        """Whether ``v`` lies in the range."""
        above = self.low is None or _AT_LEAST[self.low_closed](v, self.low)
        below = self.high is None or _AT_LEAST[self.high_closed](self.high, v)
        return math.isfinite(v) and above and below

    def __call__(self, text: str) -> float | int:
        """argparse type: the number ``text`` names, refused unless in range."""
        try:
            v = int(text) if self.integer else float(text)
        except ValueError:
            v = math.nan
        if not self.holds(v):
            raise argparse.ArgumentTypeError(f"must be {self.meaning} {self.range_text()}, not {text!r}")
        return v


#: the shared values: name -> meaning, unit and range
VALUES: dict[str, Value] = {
    "freq": Value("a frequency", "Hz", 0.0),
    "hz_from_0": Value("a frequency", "Hz", 0.0, low_closed=True),
    "accel": Value("an acceleration", "mm/s²", 0.0),
    "speed": Value("a speed", "mm/s", 0.0),
    "length": Value("a length", "mm", 0.0),
    "scv": Value("a square-corner velocity", "mm/s", 0.0, low_closed=True),
    "smoothing": Value("a smoothing", "mm", 0.05, low_closed=True),
    "mass": Value("a mass", "kg", 0.0, 100.0, high_closed=False),
    "filament_diameter": Value("a filament diameter", "mm", 0.5, 5.0, low_closed=True),
    "filament_density": Value("a filament density", "g/cm³", 0.5, 5.0, low_closed=True),
    "current": Value("a run current", "A", 0.0),
    "voltage": Value("a voltage", "V", 0.0),
    "fraction": Value("a fraction", "", 0.0, 1.0),
    "damping_ratio": Value("a damping ratio", "", 0.0, 1.0, low_closed=True, high_closed=False),
    "margin_percent": Value("a percentage", "%", 0.0, 50.0, low_closed=True, high_closed=False),
    "rate": Value("a sample rate", "samples/s", 0.0),
    "seconds": Value("a time", "s", 0.0),
    "count": Value("a whole number", "", 1, integer=True, low_closed=True),
    "top": Value("a whole number", "", 0, integer=True, low_closed=True),
    "modes": Value("a number of modes", "", 1, 5, low_closed=True, integer=True),
    "points": Value("a number of points", "", 10, 100_000, low_closed=True, integer=True),
    "baud": Value("a serial speed", "baud", 0, integer=True),
}


class PerAxis:
    """argparse type of a per-axis option, ``X=v,Y=v`` (either or both) -> {"x": v, …}, each ``v``
    read by ``value``; a bare ``v`` -> {"all": v} when ``bare`` allows it (every axis)."""

    def __init__(self, value, what: str, bare: bool = True):
        self.value, self.what, self.bare = value, what, bare

    def __call__(self, text: str) -> dict:
        text = text.strip()
        if "=" not in text:
            if not self.bare:
                raise argparse.ArgumentTypeError(f"give the {self.what} per axis: X=…,Y=…")
            return {"all": self.value(text)}
        out = {}
        for part in text.split(","):
            ax, _, v = part.partition("=")
            ax = ax.strip().lower()
            if ax not in ("x", "y") or not v.strip():
                raise argparse.ArgumentTypeError(f"expected X=…,Y=…, not {part.strip()!r}")
            if ax in out:
                raise argparse.ArgumentTypeError(f"{ax.upper()} given twice")
            out[ax] = self.value(v.strip())
        return out


class ListOf:
    """argparse type of ``A,B,…`` -> [a, b, …], each read by ``value`` (at least one)."""

    def __init__(self, value: Value):
        self.value = value

    def __call__(self, text: str) -> list:
        items = [v.strip() for v in text.split(",") if v.strip()]
        if not items:
            raise argparse.ArgumentTypeError(f"expected values separated by commas, not {text!r}")
        return [self.value(v) for v in items]


def moving_mass(text: str) -> float:
    """argparse type of a mass that moves on an axis, kg (:func:`check_moving_mass`'s range)."""
    kg = VALUES["mass"](text)
    try:
        return check_moving_mass(kg, "")
    except RingtuneError as exc:
        raise argparse.ArgumentTypeError(exc.bare) from None


def motor_spec(text: str) -> dict:
    """argparse type of ``NAME[:RUN_CURRENT[:VOLTAGE]]`` -> {name, run_current (A RMS), voltage (V)};
    the name must be a built-in motor."""
    parts = text.split(":")
    if len(parts) > 3 or not parts[0].strip():
        raise argparse.ArgumentTypeError(f"expected NAME[:RUN_CURRENT[:VOLTAGE]], not {text!r}")
    spec: dict = {"name": parts[0].strip()}
    if lookup_motor(spec["name"]) is None:
        raise argparse.ArgumentTypeError(unknown_motor_message(spec["name"]))
    for key, value, v in zip(("run_current", "voltage"), (VALUES["current"], VALUES["voltage"]), parts[1:]):
        try:
            spec[key] = value(v)
        except argparse.ArgumentTypeError as exc:
            raise argparse.ArgumentTypeError(f"{key}: {exc}") from None
    return spec


def flavor_name(text: str) -> str:
    """argparse type of a shaper flavour: one of :data:`FLAVORS`, or a firmware name (its formulas)."""
    name = text.lower()
    flavor = FIRMWARES[name].flavor if name in FIRMWARES else name
    if flavor not in FLAVORS:
        raise argparse.ArgumentTypeError(f"unknown flavour {text!r}; one of {', '.join(FLAVORS)}, or a firmware "
                                         f"({', '.join(FIRMWARES)})")
    return flavor


def number_list(text: str) -> list[float]:
    """argparse type of ``A,B,…``: the numbers, in order (empty items skipped)."""
    try:
        return [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be numbers separated by commas, not {text!r}") from None
