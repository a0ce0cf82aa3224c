"""Opening a G-code file: its bytes or its lines, refused in one line naming the file when it is
missing, a folder, unreadable or not G-code (binary data, a picture, a TOML description...)."""

from __future__ import annotations

from pathlib import Path
from typing import Iterator

from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.gcode_sniff import HEAD, not_gcode

def open_lines(path: Path) -> Iterator[str]:
    """The lines of a text file (line ends ``\\n``, ``\\r\\n`` or ``\\r``; undecodable bytes replaced)."""
    with open(path, "r", encoding="utf-8", errors="replace", newline=None) as fh:
        yield from fh


def refuse_non_gcode(head: bytes, where: str) -> None:
    """One line naming ``where`` when ``head`` (a file's first bytes) is not G-code."""
    why = not_gcode(head)
    if why:
        raise RingtuneError(why, where)


def read_head(path: Path, size: int | None = HEAD) -> bytes:
    """The first ``size`` bytes of the G-code file ``path`` (all of it when None), with one-line
    errors for a missing file, a folder and a file that cannot be read."""
    if path.is_dir():
        raise RingtuneError("is a directory, not a G-code file", str(path))
    if not path.is_file():
        raise RingtuneError("no such G-code file", str(path))
    try:
        with open(path, "rb") as fh:
            return fh.read(size) if size is not None else fh.read()
    except OSError as exc:
        raise RingtuneError(f"cannot read: {exc.strerror or exc}", str(path)) from None


def read_gcode_bytes(path: str | Path) -> bytes:
    """The bytes of the G-code file ``path``, refused in one line (naming the file) when it is
    missing, a folder, unreadable or not G-code (binary data, a PNG, a TOML description...)."""
    path = Path(path)
    data = read_head(path, None)
    refuse_non_gcode(data[:HEAD], str(path))
    return data
