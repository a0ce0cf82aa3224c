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
- Klipper raw accelerometer CSV ``#time,accel_x,accel_y,accel_z`` and RepRapFirmware ``M956`` CSV
  ``Sample,X,Y,Z``: detected here, parsed into a :class:`RawAccel` (s, mm/s²) by
  :mod:`ringtune.hardware.raw_accel`.

Every malformed file raises :class:`RingtuneError` naming the file and line.
"""

from __future__ import annotations

import csv
import re
from pathlib import Path
from typing import Union

import numpy as np

from ringtune.hardware.accel_lines import finite_floats, first_content
from ringtune.hardware.psd import PSD, klipper_psd
from ringtune.hardware.raw_accel import RawAccel, parse_klipper_raw, parse_m956
from ringtune.shaping.errors import RingtuneError

_SHAPER_COL = re.compile(r"^\s*([A-Za-z_][\w]*(?:\([^()]*\))?)\s*\(\s*([0-9.]+)\s*\)\s*$")

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


def _detect(path: Path, lines: list[str]) -> str:
    i = first_content(lines)
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
    parse = {"resonances": _parse_resonances, "m956": parse_m956, "klipper-raw": parse_klipper_raw}
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
    hi = first_content(lines)
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
    vals = finite_floats(parts, where)
    if any(v < 0 for v in vals[1:1 + n_psd]):
        raise RingtuneError("negative power spectral density", where)
    return vals


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


# -- raw accelerometer captures (Klipper raw, RRF M956) ------------------------------------------

def read_raw_accel(path: str | Path) -> RawAccel:
    """Klipper raw ``#time,accel_x,accel_y,accel_z`` or RRF M956 CSV -> RawAccel (mm/s²)."""
    return _read_as(path, ("m956", "klipper-raw"),
                    "this is a PSD file (header 'freq,...'), not a raw accelerometer capture; "
                    "use read_resonances_csv")


# -- any reader result as spectra ----------------------------------------------------------------

def to_psd(data: AccelData) -> list[PSD]:
    """Any reader result as a list of PSDs (raw captures go through :func:`klipper_psd`)."""
    if isinstance(data, PSD):
        return [data]
    if isinstance(data, RawAccel):
        return [klipper_psd(data)]
    return list(data)
