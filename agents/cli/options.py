"""The values the commands' options share, as data: what each one means, its unit and the range it
must lie in, applied by argparse when the command line is parsed.

A command declares such an option with ``type=VALUES["accel"]``; a value
out of range is refused before the command runs, in one line naming the option and the range:
``ringtune limit: error: argument --accel: must be an acceleration > 0 mm/s², not '-5'``.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass


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
        """The range in words: ``> 0 Hz``, ``in [0, 1)``, ``1 to 5``."""
        unit = f" {self.unit}" if self.unit else ""
        if self.high is None:
            return f"{'≥' if self.low_closed else '>'} {self.low:g}{unit}"
        if self.low_closed and self.high_closed:
            return f"{self.low:g} to {self.high:g}{unit}"
        return (f"in {'[' if self.low_closed else '('}{self.low:g}, {self.high:g}"
                f"{']' if self.high_closed else ')'}{unit}")

    def holds(self, v: float) -> bool:
        """Whether ``v`` lies in the range."""
        above = self.low is None or (v >= self.low if self.low_closed else v > self.low)
        below = self.high is None or (v <= self.high if self.high_closed else v < self.high)
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
    "accel": Value("an acceleration", "mm/s²", 0.0),
    "speed": Value("a speed", "mm/s", 0.0),
    "scv": Value("a square-corner velocity", "mm/s", 0.0, low_closed=True),
    "smoothing": Value("a smoothing", "mm", 0.05, low_closed=True),
    "mass": Value("a mass", "kg", 0.0, 100.0, high_closed=False),
    "fraction": Value("a fraction", "", 0.0, 1.0),
    "damping_ratio": Value("a damping ratio", "", 0.0, 1.0, low_closed=True, high_closed=False),
    "margin_percent": Value("a percentage", "%", 0.0, 50.0, low_closed=True, high_closed=False),
    "rate": Value("a sample rate", "samples/s", 0.0),
    "seconds": Value("a time", "s", 0.0),
    "count": Value("a whole number", "", 1, integer=True, low_closed=True),
    "top": Value("a whole number", "", 0, integer=True, low_closed=True),
    "modes": Value("a number of modes", "", 1, 5, low_closed=True, integer=True),
    "points": Value("a number of points", "", 10, 100_000, low_closed=True, integer=True),
}
