"""Raw accelerometer captures: :class:`RawAccel` (time s, acceleration per axis mm/s²) and the
parsers of its two formats, which the readers of :mod:`ringtune.hardware.accel` call on a detected
file (see ``shared/reference/firmware.md`` §1.4, §3.4):

- Klipper raw accelerometer CSV ``#time,accel_x,accel_y,accel_z`` (s, mm/s²).
- RepRapFirmware ``M956`` CSV ``Sample,X,Y,Z`` (only the captured axes; values in g) ending with the
  trailer ``Rate <Hz>, overflows <n>``; time = sample / rate; converted to mm/s².

Every malformed file raises :class:`RingtuneError` naming the file and line.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ringtune.hardware.accel_lines import finite_floats, first_content, is_float
from ringtune.shaping.errors import RingtuneError

#: standard gravity in mm/s² (Klipper's FREEFALL_ACCEL)
G_MM_S2 = 9.80665 * 1000.0

_M956_TRAILER = re.compile(r"^\s*Rate\s+([0-9.]+)\s*,\s*overflows\s+(\d+)\s*$", re.IGNORECASE)


@dataclass
class RawAccel:
    """A raw accelerometer capture: time (s) and acceleration per axis (mm/s²).

    Axes that were not captured (M956 with only some axes) are None.
    ``rate`` is the sample rate the file states (M956 trailer) or N / (t_last − t_first).
    """

    t: np.ndarray
    ax: np.ndarray | None
    ay: np.ndarray | None
    az: np.ndarray | None
    source: str = ""
    rate: float = 0.0
    overflows: int = 0
    fmt: str = "klipper-raw"

    def axis(self, axis: str) -> np.ndarray:
        arr = getattr(self, f"a{axis}", None)
        if arr is None:
            raise RingtuneError(f"axis {axis.upper()} was not captured", self.source or None)
        return arr


# -- Klipper raw accelerometer CSV ---------------------------------------------------------------

def _bad_raw_line(path: Path, body: list[tuple[int, str]]) -> RingtuneError:
    """The error naming the first line of a raw capture that is not four finite numbers (the slow
    path, taken only when the fast reader failed)."""
    for i, ln in body:
        parts = ln.split(",")
        if len(parts) != 4:
            return RingtuneError(f"expected 4 values (time,accel_x,accel_y,accel_z), found {len(parts)}",
                                 f"{path}:{i + 1}")
        bad = next((p for p in parts if not is_float(p) or not math.isfinite(float(p))), None)
        if bad is not None:
            return RingtuneError(f"not a finite number: {bad.strip()[:30]!r}", f"{path}:{i + 1}")
    return RingtuneError("unreadable raw accelerometer data", str(path))  # pragma: no cover


def parse_klipper_raw(path: Path, lines: list[str]) -> RawAccel:
    body = [(i, ln) for i, ln in enumerate(lines) if ln.strip() and not ln.lstrip().startswith("#")]
    if len(body) < 2:
        raise RingtuneError("fewer than two samples", str(path))
    try:
        data = np.loadtxt([ln for _, ln in body], delimiter=",", dtype=float, ndmin=2)
        ok = data.shape[1] == 4 and np.isfinite(data).all()
    except ValueError:
        ok = False
    if not ok:
        raise _bad_raw_line(path, body)
    t = data[:, 0]
    dt = np.diff(t)
    if (dt <= 0).any():
        k = int(np.argmax(dt <= 0)) + 1
        raise RingtuneError("time must increase", f"{path}:{body[k][0] + 1}")
    rate = (len(t)) / (t[-1] - t[0])
    return RawAccel(t, data[:, 1].copy(), data[:, 2].copy(), data[:, 3].copy(), str(path), rate, 0,
                    "klipper-raw")


# -- RRF M956 ------------------------------------------------------------------------------------

def _m956_axes(line: str, where: str) -> list[str]:
    """The axes of an M956 header: 'Sample' then some of X, Y, Z, each once."""
    header = [h.strip().upper() for h in line.split(",")]
    axes = header[1:]
    distinct_xyz = set(axes) <= {"X", "Y", "Z"} and len(set(axes)) == len(axes)
    if header[0] != "SAMPLE" or not axes or not distinct_xyz:
        raise RingtuneError(f"M956 header must be 'Sample' then some of X,Y,Z, not {line.strip()!r}", where)
    return axes


def _m956_row(s: str, axes: list[str], rows: list, where: str) -> list[float]:
    """One sample row (index, then a value per axis), refused when it does not follow the last."""
    if s.lower().startswith("failed"):
        raise RingtuneError(f"the capture failed on the printer: {s!r}", where)
    parts = s.split(",")
    if len(parts) != len(axes) + 1:
        raise RingtuneError(f"expected {len(axes) + 1} values (Sample,{','.join(axes)}), found {len(parts)}", where)
    vals = finite_floats(parts, where)
    if rows and vals[0] != rows[-1][0] + 1:
        raise RingtuneError(f"sample index {vals[0]:g} does not follow {rows[-1][0]:g}", where)
    return vals


def _m956_trailer(m: re.Match, where: str) -> tuple[float, int]:
    """(sample rate Hz, overflows) of the 'Rate N, overflows M' trailer."""
    rate = float(m.group(1))
    if not rate > 0:
        raise RingtuneError("sample rate must be > 0", where)
    return rate, int(m.group(2))


def parse_m956(path: Path, lines: list[str]) -> RawAccel:
    hi = first_content(lines)
    axes = _m956_axes(lines[hi], f"{path}:{hi + 1}")
    rows = []
    trailer = None
    for i in range(hi + 1, len(lines)):
        s = lines[i].strip()
        where = f"{path}:{i + 1}"
        if not s:
            continue
        if trailer is not None:
            raise RingtuneError("data after the 'Rate N, overflows M' trailer", where)
        m = _M956_TRAILER.match(s)
        if m:
            trailer = _m956_trailer(m, where)
        else:
            rows.append(_m956_row(s, axes, rows, where))
    if trailer is None:
        raise RingtuneError("missing the 'Rate <Hz>, overflows <n>' trailer line (truncated capture?)",
                            f"{path}:{len(lines)}")
    if len(rows) < 2:
        raise RingtuneError("fewer than two samples", str(path))
    rate, overflows = trailer
    data = np.asarray(rows, dtype=float)
    t = data[:, 0] / rate
    acc = {ax: data[:, 1 + j] * G_MM_S2 for j, ax in enumerate(axes)}
    return RawAccel(t, acc.get("X"), acc.get("Y"), acc.get("Z"), str(path), rate, overflows, "m956")
