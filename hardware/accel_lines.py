"""What the accelerometer CSV readers share, line by line: where a file's content begins (its
header line) and a data row's fields as finite floats."""

from __future__ import annotations

import math

from ringtune.shaping.errors import RingtuneError


def first_content(lines: list[str]) -> int:
    """Index of the first line that is neither blank nor a ``#`` comment (``#time`` is Klipper's raw
    header, not a comment); -1 when there is none."""
    for i, line in enumerate(lines):
        s = line.strip().lower()
        if s and (not s.startswith("#") or s.startswith("#time")):
            return i
    return -1


def finite_floats(parts: list[str], where: str) -> list[float]:
    """The comma-separated fields of one data row as finite floats; RingtuneError at ``where``
    names the first field that is not a number, or says a value is not finite."""
    try:
        vals = [float(p) for p in parts]
    except ValueError:
        bad = next(p for p in parts if not is_float(p))
        raise RingtuneError(f"not a number: {bad.strip()[:30]!r}", where) from None
    if not all(math.isfinite(v) for v in vals):
        raise RingtuneError("non-finite value", where)
    return vals


def is_float(s: str) -> bool:
    try:
        float(s)
        return True
    except ValueError:
        return False
