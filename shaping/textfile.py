"""Reading a user's text file (a configuration, a printer description) with one-line errors for
what is not one: a missing file, a folder, a file that cannot be read, binary data."""

from __future__ import annotations

import re
from pathlib import Path

from ringtune.shaping.errors import RingtuneError


def read_text_file(path, what: str) -> str:
    """The text of ``path`` (``what`` names the kind, e.g. "Klipper configuration"); binary data is a
    NUL byte in the first 64 KiB, or more than 1 % of the bytes not UTF-8 (a stray Latin-1 byte in a
    comment is still text). A leading byte-order mark is dropped."""
    p = Path(path)
    if p.is_dir():
        raise RingtuneError(f"is a directory, not a {what} file", str(path))
    try:
        data = p.read_bytes()
    except FileNotFoundError:
        raise RingtuneError("no such file", str(path)) from None
    except OSError as exc:
        raise RingtuneError(f"cannot read: {exc.strerror or exc}", str(path)) from None
    text = data.decode("utf-8", errors="replace").removeprefix("\ufeff")   # a Windows editor's byte-order mark
    if b"\0" in data[:65536] or text.count("\ufffd") > 0.01 * max(len(text), 1):
        raise RingtuneError(f"not a text file (binary data): not a {what}", str(path))
    return text


#: what only each firmware's configuration has: (pattern, what it is, the command that reads it)
_FIRMWARE_FILES = (
    (re.compile(r"^[ \t]*\[(printer|mcu|stepper_[a-z]|input_shaper|include [^\]]+)\][ \t]*$", re.M),
     "Klipper's printer.cfg", "printer from-klipper"),
    (re.compile(r"^[^\n;]*echo:[ \t]*M(92|201|203|204|205|593)\b", re.M | re.I), "Marlin's M503 report",
     "printer from-marlin"),
    (re.compile(r"^[ \t]*M(584|569|669|950)\b", re.M), "RepRapFirmware's config.g", "printer from-rrf"),
)


def firmware_config_hint(text: str) -> str:
    """For a file that should have been a printer description (TOML) but is a firmware's
    configuration: ``": this is X; make a description from it with `ringtune CMD FILE -o printer.toml`"``,
    else ``""``."""
    for pattern, what, command in _FIRMWARE_FILES:
        if pattern.search(text):
            return f"; this is {what}: make a printer description from it with `ringtune {command} FILE -o printer.toml`"
    return ""
