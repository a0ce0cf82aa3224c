"""The ``limit`` post-processor: rewrite a G-code file so its feedrates respect a direction-change
frequency limit, changing only the F words it must; and (``--accel``) scale a sliced file's own
acceleration commands to a tuned acceleration, keeping the ratios between features
(:func:`rewrite_accel_bytes`).

A move line whose planned speed differs from the speed the output file would command there gets
an F word (its own F replaced, or one added before any comment/checksum). The first move after a
slowed stretch gets the original F back the same way. Every other byte of the input is kept; one
header comment at the top records what was done. A checksummed line (``N.. *cs``) that is changed
gets its XOR checksum recomputed.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.freqlimit import apply_freq_limit, resolve_min_speed_factor
from ringtune.shaping.gcode import checksum, read_gcode
from ringtune.shaping.gcode_file import read_gcode_bytes

_MOVE = re.compile(rb"^\s*(?:[Nn]\s*-?\d+\s*)?[Gg]0*[0-3](?![0-9.])")
_F_WORD = re.compile(rb"([Ff])\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)")


@dataclass
class LimitResult:
    lines_changed: int
    moves_slowed: int
    f_words_changed: int
    f_words_added: int
    header: str
    min_speed_factor: float          # the floor actually used (fraction of the requested speed)


def _fmt(f_mm_min: float) -> bytes:
    s = f"{f_mm_min:.1f}"
    if "." in s:
        s = s.rstrip("0").rstrip(".")
    return s.encode()


def _split_code(line: bytes) -> tuple[bytes, bytes, bytes]:
    """(code, checksum part '*nn' or b'', rest: comment and line end)."""
    body = line.rstrip(b"\r\n")
    end = line[len(body):]
    semi = body.find(b";")
    code, comment = (body, b"") if semi < 0 else (body[:semi], body[semi:])
    star = code.rfind(b"*")
    cs = b""
    if star >= 0 and code[star + 1:].strip().isdigit():
        code, cs = code[:star], code[star:]
    return code, cs, comment + end


def _line_end(lines: list[bytes]) -> bytes:
    """The file's line ending (its first line's): CR LF or LF."""
    return b"\r\n" if lines and lines[0].endswith(b"\r\n") else b"\n"


def _with_checksum(code: bytes, cs: bytes) -> bytes:
    if not cs:
        return code
    body = code.rstrip()
    return body + b"*" + str(checksum(body)).encode()


def limit_gcode_bytes(data: bytes, limit_hz: float, method: str = "sections",
                      min_speed_factor: float | None = None,
                      source: str = "<gcode>") -> tuple[bytes, LimitResult]:
    """Apply the frequency limit (Hz) to G-code bytes; returns the new bytes and what changed.
    ``min_speed_factor`` None: the method's default (``freqlimit.resolve_min_speed_factor``)."""
    job = read_gcode(data, source=source)        # same line numbering as data.splitlines()
    min_speed_factor = resolve_min_speed_factor(job, method, min_speed_factor)
    limited = apply_freq_limit(job, limit_hz, method, min_speed_factor)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(job.feed > 0, limited.feed / job.feed, 1.0)
    # one ratio per source line (arcs give several moves per line: the slowest wins)
    line_ratio: dict[int, float] = {}
    for ln, r in zip(job.line.tolist(), ratio.tolist()):
        line_ratio[ln] = min(r, line_ratio.get(ln, 1.0))
    lines = data.splitlines(keepends=True)
    nl = _line_end(lines)
    out = []
    modal_in = modal_out = 1500.0      # F (mm/min) the input / output file commands here (F1500 default)
    changed = added = replaced = 0
    for ln, line in enumerate(lines, 1):
        if not _MOVE.match(line):
            out.append(line)
            continue
        code, cs, tail = _split_code(line)
        m = _F_WORD.search(code, _MOVE.match(code).end())      # the move word is before any comment or checksum
        if m:                              # the pattern matches numbers only
            modal_in = float(m.group(2))
        r = line_ratio.get(ln, 1.0)
        target = modal_in if r >= 1.0 else float(_fmt(modal_in * r))
        if m:
            if target == modal_in:
                modal_out = modal_in
                out.append(line)
                continue
            new_code = code[:m.start(2)] + _fmt(target) + code[m.end(2):]
            replaced += 1
        else:
            if target == modal_out or ln not in line_ratio:
                out.append(line)
                continue
            stripped = code.rstrip()
            new_code = stripped + b" F" + _fmt(target) + code[len(stripped):]
            added += 1
        out.append(_with_checksum(new_code, cs) + tail)
        modal_out = target
        changed += 1
    slowed = int(np.sum(ratio < 1.0 - 1e-12))
    header = (f"; ringtune limit: method={method} freq_limit={limit_hz:g} Hz "
              f"min_speed_factor={min_speed_factor:g}; slowed {slowed} of {job.n_moves} moves; "
              f"changed F on {changed} lines ({replaced} replaced, {added} added); "
              f"nothing else differs from the input")
    result = LimitResult(changed, slowed, replaced, added, header, min_speed_factor)
    return header.encode() + nl + b"".join(out), result


def limit_file(src: str | Path, dst: str | Path | None, limit_hz: float, method: str = "sections",
               min_speed_factor: float | None = None) -> tuple[bytes, LimitResult]:
    """Read ``src``, apply the limit, write ``dst`` (if given); returns (bytes, result)."""
    src = Path(src)
    data = read_gcode_bytes(src)
    out, result = limit_gcode_bytes(data, limit_hz, method, min_speed_factor, source=str(src))
    if dst is not None:
        Path(dst).write_bytes(out)
    return out, result


# -- acceleration rewrite (ringtune limit --accel) ------------------------------------------------

#: the acceleration commands a sliced file carries: Marlin/RRF/Prusa M204 (P print, S print and
#: travel, T travel; R is the extruder's retraction and stays), M201 X/Y (per-axis maxima that cap
#: M204), Klipper SET_VELOCITY_LIMIT ACCEL= (Klipper also reads M204 S / P+T)
_ACCEL_LINE = re.compile(rb"^(\s*(?:[Nn]\s*-?\d+\s*)?)(M204|M201|SET_VELOCITY_LIMIT)(?![0-9A-Za-z_])", re.I)
_LETTER_WORD = re.compile(rb"(?<![A-Za-z_])([A-Za-z])\s*([-+]?(?:\d+\.?\d*|\.\d+))")
_KLIPPER_ACCEL = re.compile(rb"(?i)(?<![A-Za-z_])(ACCEL(?:_TO_DECEL)?)\s*=\s*([-+]?(?:\d+\.?\d*|\.\d+))")
_SCALED = {b"M204": (b"P", b"S", b"T"), b"M201": (b"X", b"Y")}
_PRINTING = {b"M204": (b"P", b"S"), b"SET_VELOCITY_LIMIT": (b"ACCEL",)}


@dataclass
class AccelResult:
    lines_changed: int
    reference: float | None          # mm/s²: the file's highest printing acceleration (None: none set)
    factor: float                    # every acceleration value scaled by this
    header: str
    notes: list[str]


def _accel_words(code: bytes, word: bytes):
    """(match, letter) of the acceleration values on one command line, as the firmware reads them."""
    start = _ACCEL_LINE.match(code).end()
    if word == b"SET_VELOCITY_LIMIT":
        return [(m, m.group(1).upper()) for m in _KLIPPER_ACCEL.finditer(code, start)]
    return [(m, m.group(1).upper()) for m in _LETTER_WORD.finditer(code, start)
            if m.group(1).upper() in _SCALED[word]]


def _printing_accels(lines: list[bytes]) -> list[float]:
    """Every printing acceleration the file sets (M204 P/S, SET_VELOCITY_LIMIT ACCEL), mm/s² (the
    patterns match numbers only)."""
    printing = []
    for line in lines:
        code = _split_code(line)[0]
        m = _ACCEL_LINE.match(code)
        if not m:
            continue
        word = m.group(2).upper()
        printing += [float(w.group(2)) for w, letter in _accel_words(code, word) if letter in _PRINTING.get(word, ())]
    return printing


def _scaled_line(line: bytes, factor: float) -> bytes | None:
    """``line`` with every acceleration of its command scaled by ``factor`` (new checksum), or None
    when it has none or none changes."""
    code, cs, tail = _split_code(line)
    m = _ACCEL_LINE.match(code)
    if not m:
        return None
    new, pos = b"", 0
    for w, _ in _accel_words(code, m.group(2).upper()):
        new += code[pos:w.start(2)] + _fmt(float(w.group(2)) * factor)
        pos = w.end(2)
    new += code[pos:]
    return None if new == code else _with_checksum(new, cs) + tail


def rewrite_accel_bytes(data: bytes, accel: float, source: str = "<gcode>") -> tuple[bytes, AccelResult]:
    """Scale every acceleration command of a sliced file so its highest printing acceleration
    (M204 P/S, SET_VELOCITY_LIMIT ACCEL) becomes ``accel`` mm/s², keeping the ratios between
    features (and M204 T, M201 X/Y in the same ratio, so the caps do not undo it). Only those
    numbers change; a header comment says what was done; checksummed lines get a new checksum."""
    if not (accel > 0 and np.isfinite(accel)):
        raise RingtuneError(f"must be an acceleration > 0 mm/s², not {accel!r}", "--accel")
    lines = data.splitlines(keepends=True)
    nl = _line_end(lines)
    printing = _printing_accels(lines)
    notes: list[str] = []
    if max(printing, default=0.0) <= 0:
        header = (f"; ringtune limit --accel {accel:g}: the file sets no printing acceleration (no M204 P/S, "
                  "no SET_VELOCITY_LIMIT ACCEL), so nothing was changed: the printer's own acceleration applies")
        notes.append("the file sets no printing acceleration: set the printer's (ringtune push / export)")
        return header.encode() + nl + data, AccelResult(0, None, 1.0, header, notes)
    reference = max(printing)
    factor = accel / reference
    scaled = [_scaled_line(line, factor) for line in lines]
    changed = sum(s is not None for s in scaled)
    out = [s or line for line, s in zip(lines, scaled)]
    if len(set(printing)) > 1:
        notes.append(f"{len(set(printing))} printing accelerations in the file (features): all scaled by "
                     f"{factor:.4g}, so their ratios stay")
    header = (f"; ringtune limit --accel {accel:g}: the file's highest printing acceleration {reference:g} mm/s² "
              f"becomes {accel:g}; every acceleration command (M204 P/S/T, M201 X/Y, SET_VELOCITY_LIMIT ACCEL/ACCEL_TO_DECEL) "
              f"scaled by {factor:.4g}; changed {changed} lines; nothing else differs from the input")
    return header.encode() + nl + b"".join(out), AccelResult(changed, reference, factor, header, notes)
