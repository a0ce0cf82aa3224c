"""Accelerometer file readers: Klipper resonance / calibration CSV, Klipper raw CSV, RRF M956 CSV.

Formats (see ``shared/reference/firmware.md`` §1.3, §1.4, §3.4):

- Klipper ``TEST_RESONANCES`` output, header ``freq,psd_x,psd_y,psd_z,psd_xyz``: a PSD of the
  accelerometer signal in (mm/s²)²/Hz, written before frequency normalisation.
- Klipper multi-dataset form, header ``freq,<name1>,<name2>,...`` (names CSV-quoted if needed),
  one ``psd_sum`` column per dataset.
- Klipper ``calibration_data`` CSV / ``calibrate_shaper.py -c``: the above plus a shaper block,
  either ``,shapers:,zv(34.4),mzv(...)`` (rows: an empty column, then one response per shaper) or,
  in older Klipper, the shaper columns ``zv(34.4),...`` straight after ``psd_xyz``. With a shaper block
  the PSD is already normalised to frequencies (:attr:`PSD.normalized`).
- Klipper raw accelerometer CSV ``#time,accel_x,accel_y,accel_z`` (s, mm/s²).
- RepRapFirmware ``M956`` CSV ``Sample,X,Y,Z`` (only the captured axes; values in g) ending with the
  trailer ``Rate <Hz>, overflows <n>``; time = sample / rate; converted to mm/s².

Every malformed file raises :class:`RingtuneError` naming the file and line.
"""

from __future__ import annotations

import csv
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Union

import numpy as np

from ringtune.hardware.psd import PSD, klipper_psd
from ringtune.shaping.errors import RingtuneError

#: standard gravity in mm/s² (Klipper's FREEFALL_ACCEL)
G_MM_S2 = 9.80665 * 1000.0

_SHAPER_COL = re.compile(r"^\s*([A-Za-z_][\w]*(?:\([^()]*\))?)\s*\(\s*([0-9.]+)\s*\)\s*$")
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


AccelData = Union[PSD, list, RawAccel]


# -- detection ---------------------------------------------------------------------------------

def _read_lines(path: str | Path) -> tuple[Path, list[str]]:
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig", errors="replace")
    except FileNotFoundError:
        raise RingtuneError("no such file", str(path)) from None
    except IsADirectoryError:
        raise RingtuneError("is a directory, not an accelerometer CSV", str(path)) from None
    return path, text.splitlines()


def _first_content(lines: list[str]) -> int:
    """Index of the first line that is neither blank nor a ``#`` comment (``#time`` is Klipper's raw
    header, not a comment); -1 when there is none."""
    for i, line in enumerate(lines):
        s = line.strip().lower()
        if s and (not s.startswith("#") or s.startswith("#time")):
            return i
    return -1


def _detect(path: Path, lines: list[str]) -> str:
    i = _first_content(lines)
    if i < 0:
        raise RingtuneError("empty file: no header line", str(path))
    head = lines[i].strip().lower()
    if head.startswith("freq,") or head == "freq":
        return "resonances"
    if head.startswith("sample,"):
        return "m956"
    if head.startswith("#time") or _numeric_row(head, 4):
        return "klipper-raw"
    _refuse_console_paste(path, lines)
    for sep, word in ((";", "semicolons"), ("\t", "tabs")):
        if head.replace(sep, ",").startswith(("freq,", "sample,", "#time,")):
            raise RingtuneError(f"columns separated by {word} (a spreadsheet's re-save?): give the file as "
                                "the firmware wrote it, with commas", f"{path}:{i + 1}")
    raise RingtuneError(
        f"unrecognised header {lines[i].strip()[:60]!r}; expected Klipper 'freq,psd_x,...', "
        "Klipper raw '#time,accel_x,accel_y,accel_z' or RRF M956 'Sample,X,Y,Z'", f"{path}:{i + 1}")


def _refuse_console_paste(path: Path, lines: list[str]) -> None:
    """A console paste of ACCELEROMETER_QUERY (``// adxl345 values (x, y, z): …``): one reading of the
    accelerometer, not a measurement; refused with what to give instead."""
    for n, line in enumerate(lines, 1):
        text = line.lower()
        if "values (x, y, z)" in text or "accelerometer_query" in text:
            raise RingtuneError("an ACCELEROMETER_QUERY console paste: one reading of the accelerometer, not a "
                                "resonance test; run TEST_RESONANCES AXIS=X and AXIS=Y and give the "
                                "resonances_x_*.csv / resonances_y_*.csv files it writes (in /tmp)", f"{path}:{n}")


def _numeric_row(line: str, n: int) -> bool:
    parts = line.split(",")
    if len(parts) != n:
        return False
    try:
        [float(p) for p in parts]
    except ValueError:
        return False
    return True


def read_accel(path: str | Path) -> AccelData:
    """Read any supported accelerometer file; the format is detected from its header.

    Returns a :class:`PSD` (single-dataset resonance/calibration CSV), a ``list[PSD]``
    (multi-dataset CSV) or a :class:`RawAccel` (Klipper raw, RRF M956).
    """
    return _read_as(path, ("resonances", "m956", "klipper-raw"), "")


def _read_as(path: str | Path, accepted: tuple[str, ...], refusal: str) -> AccelData:
    """Detect the format of ``path`` and parse it if it is one of ``accepted``; otherwise raise
    ``refusal`` (``{kind}`` in it becomes the detected format) naming the file."""
    path, lines = _read_lines(path)
    kind = _detect(path, lines)
    if kind not in accepted:
        raise RingtuneError(refusal.format(kind=kind), str(path))
    parse = {"resonances": _parse_resonances, "m956": _parse_m956, "klipper-raw": _parse_klipper_raw}
    return parse[kind](path, lines)


# -- Klipper resonance / calibration CSV -------------------------------------------------------

def read_resonances_csv(path: str | Path) -> PSD | list[PSD]:
    """Klipper ``TEST_RESONANCES`` / ``calibration_data`` CSV -> PSD (multi-dataset -> list[PSD])."""
    return _read_as(path, ("resonances",),
                    "not a Klipper resonance CSV (looks like {kind}); header must start 'freq,'")


def _parse_resonances(path: Path, lines: list[str]) -> PSD | list[PSD]:
    hi, cols, shaper_names, has_gap = _resonance_header(path, lines)
    n_psd = len(cols)
    rows = _resonance_rows(path, lines, hi, n_psd, has_gap, 1 + n_psd + (1 if has_gap else 0) + len(shaper_names))
    data = np.asarray(rows, dtype=float)
    freqs = data[:, 0]
    shapers = {name: data[:, 1 + n_psd + j] for j, name in enumerate(shaper_names)}
    normalized = bool(shaper_names)
    if [c.lower() for c in cols] == ["psd_x", "psd_y", "psd_z", "psd_xyz"]:
        return PSD(freqs, data[:, 1], data[:, 2], data[:, 3], data[:, 4], str(path),
                   axis_from_file_name(path) or "", normalized, shapers)
    return [PSD(freqs, None, None, None, data[:, 1 + j].copy(), str(path), name, normalized, shapers)
            for j, name in enumerate(cols)]


def _resonance_header(path: Path, lines: list[str]) -> tuple[int, list[str], list[str], bool]:
    """(header line index, PSD columns, shaper columns, whether an empty column and ``shapers:``
    separate them) of a Klipper resonance CSV; old Klipper puts ``name(freq)`` shaper columns
    straight after the PSD columns."""
    hi = _first_content(lines)
    header = [h.strip() for h in next(csv.reader([lines[hi].strip()]))]
    where_h = f"{path}:{hi + 1}"
    if header[0].lower() != "freq":
        raise RingtuneError("first header column must be 'freq'", where_h)
    cols = header[1:]
    shaper_names: list[str] = []
    has_gap = "shapers:" in cols
    if has_gap:
        k = cols.index("shapers:")
        shaper_names = list(cols[k + 1:])
        cols = cols[:k]
    else:
        while cols and _SHAPER_COL.match(cols[-1]):
            shaper_names.insert(0, cols.pop())
    if not cols:
        raise RingtuneError("no PSD columns after 'freq'", where_h)
    return hi, cols, shaper_names, has_gap


def _resonance_rows(path: Path, lines: list[str], hi: int, n_psd: int, has_gap: bool, n_expected: int) -> list:
    """The data rows after the header line ``hi`` as finite floats: ``n_expected`` fields each (the
    empty separator column dropped), PSDs ≥ 0, frequencies rising, at least two rows."""
    rows = []
    for i in range(hi + 1, len(lines)):
        s = lines[i].strip()
        if not s or s.startswith("#"):
            continue
        where = f"{path}:{i + 1}"
        vals = _resonance_row(s.split(","), n_psd, has_gap, n_expected, where)
        if rows and vals[0] <= rows[-1][0]:
            raise RingtuneError(f"frequencies must increase ({vals[0]:g} after {rows[-1][0]:g} Hz)", where)
        rows.append(vals)
    if len(rows) < 2:
        raise RingtuneError("fewer than two frequency rows", str(path))
    return rows


def _resonance_row(parts: list[str], n_psd: int, has_gap: bool, n_expected: int, where: str) -> list[float]:
    """One data row's values (the separator column, which must be empty, dropped); PSDs ≥ 0."""
    if len(parts) != n_expected:
        raise RingtuneError(f"expected {n_expected} comma-separated values as the header says, "
                            f"found {len(parts)}", where)
    if has_gap:
        if parts[1 + n_psd].strip():
            raise RingtuneError(f"column {n_psd + 2} before the shaper block must be empty", where)
        del parts[1 + n_psd]
    vals = _finite_floats(parts, where)
    if any(v < 0 for v in vals[1:1 + n_psd]):
        raise RingtuneError("negative power spectral density", where)
    return vals


def _finite_floats(parts: list[str], where: str) -> list[float]:
    """The comma-separated fields of one data row as finite floats; RingtuneError at ``where``
    names the first field that is not a number, or says a value is not finite."""
    try:
        vals = [float(p) for p in parts]
    except ValueError:
        bad = next(p for p in parts if not _is_float(p))
        raise RingtuneError(f"not a number: {bad.strip()[:30]!r}", where) from None
    if not all(math.isfinite(v) for v in vals):
        raise RingtuneError("non-finite value", where)
    return vals


def _is_float(s: str) -> bool:
    try:
        float(s)
        return True
    except ValueError:
        return False


#: Klipper's ``resonances_<axis>_…``, ``calibration_data_<axis>_…``, ``raw_data_<axis>_…`` (firmware.md §1.4)
_KLIPPER_AXIS_NAME = re.compile(r"(?:^|[^a-z])(?:resonances|calibration_data|raw_data)_([xyz])_", re.IGNORECASE)
#: ``<run>-<tool>-<Axis><start>-<end>-<?>-<shaper>.csv``: RRF M956 captures saved by Duet's Input
#: Shaping plugin (a pattern inferred from the names, tests/data/accel/SOURCES.md)
_RRF_AXIS_NAME = re.compile(r"-([XYZ])-?\d+(?:\.\d+)?-\d")


def axis_from_file_name(path: str | Path) -> str | None:
    """The axis (``"x"``, ``"y"``, ``"z"``) an accelerometer file measured, from its name; None if
    the name does not say.

    Klipper names its files ``resonances_<axis>_<name>.csv`` (likewise ``calibration_data_`` and
    ``raw_data_``), lower case; a prefix (``ender3_resonances_x_…``) and upper case are accepted. A
    diagonal test (``resonances_axis=1.000,-1.000_…``) names no single axis: None. RRF M956 captures
    saved by Duet's Input Shaping plugin are named like ``1-T0-X54-161-0-none.csv`` (axis X).
    """
    name = Path(path).name
    m = _KLIPPER_AXIS_NAME.search(name)
    if m:
        return m.group(1).lower()
    m = _RRF_AXIS_NAME.search(name)
    return m.group(1).lower() if m else None


#: Klipper's ``TEST_RESONANCES AXIS=dx,dy`` file names: ``resonances_axis=1.000,-1.000[,0.000]_<name>.csv``
_KLIPPER_DIRECTION_NAME = re.compile(r"axis=(-?\d+(?:\.\d*)?),(-?\d+(?:\.\d*)?)(?:,(-?\d+(?:\.\d*)?))?_",
                                     re.IGNORECASE)


def direction_from_file_name(path: str | Path) -> tuple[float, float] | None:
    """The (dx, dy) direction of a Klipper resonance test along a direction (``TEST_RESONANCES
    AXIS=1,1`` writes ``resonances_axis=1.000,1.000,0.000_<name>.csv``; before 2025 without the z
    part), from the file's name; None for a single-axis test or a name that does not say."""
    m = _KLIPPER_DIRECTION_NAME.search(Path(path).name)
    if not m:
        return None
    dx, dy = float(m.group(1)), float(m.group(2))
    return (dx, dy) if (dx, dy) != (0.0, 0.0) else None


# -- Klipper raw accelerometer CSV ---------------------------------------------------------------

def read_raw_accel(path: str | Path) -> RawAccel:
    """Klipper raw ``#time,accel_x,accel_y,accel_z`` or RRF M956 CSV -> RawAccel (mm/s²)."""
    return _read_as(path, ("m956", "klipper-raw"),
                    "this is a PSD file (header 'freq,...'), not a raw accelerometer capture; "
                    "use read_resonances_csv")


def _bad_raw_line(path: Path, body: list[tuple[int, str]]) -> RingtuneError:
    """The error naming the first line of a raw capture that is not four finite numbers (the slow
    path, taken only when the fast reader failed)."""
    for i, ln in body:
        parts = ln.split(",")
        if len(parts) != 4:
            return RingtuneError(f"expected 4 values (time,accel_x,accel_y,accel_z), found {len(parts)}",
                                 f"{path}:{i + 1}")
        bad = next((p for p in parts if not _is_float(p) or not math.isfinite(float(p))), None)
        if bad is not None:
            return RingtuneError(f"not a finite number: {bad.strip()[:30]!r}", f"{path}:{i + 1}")
    return RingtuneError("unreadable raw accelerometer data", str(path))  # pragma: no cover


def _parse_klipper_raw(path: Path, lines: list[str]) -> RawAccel:
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
    vals = _finite_floats(parts, where)
    if rows and vals[0] != rows[-1][0] + 1:
        raise RingtuneError(f"sample index {vals[0]:g} does not follow {rows[-1][0]:g}", where)
    return vals


def _m956_trailer(m: re.Match, where: str) -> tuple[float, int]:
    """(sample rate Hz, overflows) of the 'Rate N, overflows M' trailer."""
    rate = float(m.group(1))
    if not rate > 0:
        raise RingtuneError("sample rate must be > 0", where)
    return rate, int(m.group(2))


def _parse_m956(path: Path, lines: list[str]) -> RawAccel:
    hi = _first_content(lines)
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


# -- any reader result as spectra ----------------------------------------------------------------

def to_psd(data: AccelData) -> list[PSD]:
    """Any reader result as a list of PSDs (raw captures go through :func:`klipper_psd`)."""
    if isinstance(data, PSD):
        return [data]
    if isinstance(data, RawAccel):
        return [klipper_psd(data)]
    return list(data)
