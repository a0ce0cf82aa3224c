"""Opening a G-code file: its bytes or its lines, refused in one line naming the file when it is
missing, a folder, unreadable or not G-code (binary data, a picture, a TOML description...).
Prusa's binary G-code (``.bgcode``) is read as the plain G-code it holds (:mod:`ringtune.shaping.bgcode`)."""

from __future__ import annotations

from pathlib import Path
from typing import Iterator

from ringtune.shaping.bgcode import decode_bgcode, is_bgcode
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
    """The bytes of the G-code file ``path`` (a binary G-code file's plain G-code), refused in one
    line (naming the file) when it is missing, a folder, unreadable or not G-code (binary data, a
    PNG, a TOML description...)."""
    path = Path(path)
    data = read_head(path, None)
    if is_bgcode(data):
        data = decode_bgcode(data, str(path))
    refuse_non_gcode(data[:HEAD], str(path))
    return data


def is_binary_gcode(path: str | Path) -> bool:
    """Whether ``path`` is a readable binary G-code file (False for what cannot be read)."""
    try:
        with open(path, "rb") as fh:
            return is_bgcode(fh.read(4))
    except OSError:
        return False


def gcode_text_or_none(path) -> str | None:
    """The text of the G-code file ``path`` (a binary one's plain G-code; undecodable bytes
    replaced), or None when it cannot be read."""
    try:
        return read_gcode_bytes(path).decode("utf-8", "replace")
    except (RingtuneError, TypeError):
        return None


def binary_note(path) -> str | None:
    """Where ``path`` is binary G-code, one sentence saying what a command that writes the job out
    makes of it; None otherwise."""
    if not is_binary_gcode(path):
        return None
    return (f"{path} is binary G-code (.bgcode): read as the plain G-code it holds (the slicer's packer had "
            "dropped comments after commands), and written out as plain G-code, which Prusa printers print too "
            "(name it .gcode)")


def refuse_binary_output(option: str, path) -> None:
    """Refuse an output named ``.bgcode``: ringtune writes plain G-code."""
    if path and str(path).lower().endswith(".bgcode"):
        raise RingtuneError("ringtune writes plain G-code: give the file a .gcode name (Prusa printers print plain "
                            "G-code too)", f"{option} {path}")
