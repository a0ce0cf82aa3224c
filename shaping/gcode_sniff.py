"""Is a file G-code at all? One clear sentence before the reader trips over a PNG's bytes or a
TOML's ``name = ...`` line (``line number N must be an integer``).

:func:`not_gcode` looks at the first bytes only (signatures of common binary formats, NUL bytes,
invalid UTF-8 and control characters, of which a text file has few) and at the first lines that
are not comments: G-code has G/M/T commands or Klipper-style upper-case macros there; a printer description, a Klipper configuration or a CSV file has none.
"""

from __future__ import annotations

import re

#: how much of a file is looked at, bytes
HEAD = 64 * 1024
#: code lines looked at
LINES = 200

_SIGNATURES = (
    (b"\x89PNG\r\n\x1a\n", "a PNG image"),
    (b"\xff\xd8\xff", "a JPEG image"),
    (b"GIF8", "a GIF image"),
    (b"%PDF", "a PDF document"),
    (b"PK\x03\x04", "a ZIP archive (a .3mf project or a policy?)"),
    (b"\x1f\x8b", "a gzip archive"),
)
_GCODE = re.compile(r"^\s*(?:[Nn]\s*\d+\s*)?(?:[GgMmTt]\s*\d|(?:[A-Z][A-Z0-9]*_[A-Z0-9_]+|[A-Z]{4,})(?:\s|$)"
                    r"|[XYZEFxyzef]\s*-?[\d.])")
_TOML = re.compile(r"^\s*(?:\[\[?[A-Za-z_][\w.\- \"']*\]\]?\s*(?:#.*)?$|[A-Za-z_][\w\-.]*\s*=)")
_CFG = re.compile(r"^\s*(?:\[[A-Za-z_][\w\- ]*\]\s*$|[a-z_][\w]*\s*:)")
_CSV = re.compile(r"^\s*[\w#.\-]+(?:\s*,\s*[\w.\-+]+)+\s*$")


#: control bytes no text file has (not tab, line feed, form feed, carriage return, escape)
_CONTROL = bytes(set(range(32)) - {9, 10, 11, 12, 13, 27}) + b"\x7f"


def _binary(head: bytes, text: str) -> bool:
    """More than 1 % of the bytes (and more than 2) are invalid UTF-8 or control characters: a text
    file in another 8-bit encoding (a stray latin-1 degree sign in a comment) stays G-code."""
    bad = text.count("\ufffd") + len(head) - len(head.translate(None, _CONTROL))
    return bad > max(2.0, 0.01 * len(head))


def _first_code(head: bytes, text: str) -> list[str]:
    """The first :data:`LINES` non-empty command lines of ``text`` (comments stripped; a last line
    cut off by the head's end is left out)."""
    code = []
    for line in text.splitlines()[:-1] if len(head) >= HEAD else text.splitlines():
        s = line.split(";", 1)[0].strip()
        if s:
            code.append(s)
            if len(code) >= LINES:
                break
    return code


_STL = re.compile(r"^\s*(?:solid\b|facet\s+normal\b|outer\s+loop\b|vertex\s|endloop\b|endfacet\b)")
_OBJ = re.compile(r"^\s*(?:v|vn|vt|f|o|g|s|mtllib|usemtl)\s")

#: what a file whose first lines are not G-code looks like instead, tried in order
_KINDS = (("an STL model (slice it first: ringtune reads the sliced job's G-code)", _STL),
          ("an OBJ model (slice it first: ringtune reads the sliced job's G-code)", _OBJ),
          ("a TOML file (a printer description? give it with --printer)", _TOML),
          ("a configuration file (printer.cfg?)", _CFG), ("a CSV table", _CSV))


def not_gcode(head: bytes) -> str | None:
    """Why ``head`` (a file's first bytes) is not G-code, in words, or None if it may be."""
    what = next((what for sig, what in _SIGNATURES if head.startswith(sig)), None)
    if what:
        return f"{what}, not G-code"
    text = head.decode("utf-8", "replace")
    if b"\x00" in head or _binary(head, text):
        return "not a text file (binary data), not G-code"
    code = _first_code(head, text)
    # G-code if the first command is one, or most are (a stray header line is not a verdict)
    # (no code lines at all: nothing contradicts G-code)
    if sum(bool(_GCODE.match(s)) for s in code) >= 0.5 * len(code) or _GCODE.match(code[0]):
        return None
    for what, rx in _KINDS:
        if sum(bool(rx.match(s)) or s.startswith("#") for s in code) >= 0.5 * len(code):
            return f"looks like {what}, not G-code: its first lines are not G-code commands"
    return "does not look like G-code: its first lines are not G-code commands (G0/G1, M…, T…)"
