"""A binary G-code (.bgcode) writer for tests, written from the format's specification (libbgcode's
``doc/specifications.md``) and the packing rules of PrusaSlicer's binarizer, independently of
ringtune's reader: file header; file, printer, print and slicer metadata blocks (INI ``key=value``
lines); G-code blocks of at most 64 KiB cut at line ends, MeatPack-packed with whole-line comments
kept and spaces dropped from G lines; Heatshrink (the ``heatshrink2`` package) or Deflate; CRC32
of each block's header, parameters and data.
"""

from __future__ import annotations

import struct
import zlib

import heatshrink2

#: MeatPack's 4-bit code of each packable character in no-spaces mode ("E" takes the space's code)
NO_SPACES_CODES = {c: i for i, c in enumerate("0123456789.E\nGX")}
SIGNAL = b"\xff\xff"
ENABLE, DISABLE, NO_SPACES = 251, 250, 247


def pack_line(line: str) -> bytes:
    """One G-code line (without its line feed) packed in no-spaces mode: a G line loses its spaces
    and inline comment; pairs of characters two to a byte (low nibble first), 0xF where a full
    byte follows (a full first character comes before the packed second)."""
    code = line.split(";", 1)[0].strip()
    if not code:
        return b""
    g = code.find("G")
    if 0 <= g < len(code) - 1 and code[g + 1].isdigit():
        code = code.replace(" ", "").replace("e", "E").replace("x", "X").replace("g", "G")
    text = code + "\n"
    out = bytearray()
    for i in range(0, len(text), 2):
        a, b = text[i], text[i + 1] if i + 1 < len(text) else "\n"
        ca, cb = NO_SPACES_CODES.get(a), NO_SPACES_CODES.get(b)
        out.append((0xF if cb is None else cb) << 4 | (0xF if ca is None else ca))
        out += (a.encode() if ca is None else b"") + (b.encode() if cb is None else b"")
    return bytes(out)


def meatpack(text: str) -> bytes:
    """A G-code block's text MeatPack-packed as PrusaSlicer packs it (comments kept)."""
    out = bytearray(SIGNAL + bytes([ENABLE]) + SIGNAL + bytes([NO_SPACES]))
    packing = True
    for line in text.splitlines():
        if line.startswith(";"):
            if packing:
                out += SIGNAL + bytes([DISABLE])
                packing = False
            out += (line + "\n").encode()
            continue
        packed = pack_line(line)
        if packed and not packing:
            out += SIGNAL + bytes([ENABLE])
            packing = True
        out += packed
    return bytes(out)


def block(kind: int, params: bytes, data: bytes, compression: int = 0) -> bytes:
    """One block with its CRC32: ``compression`` 0 none, 1 Deflate, 3 Heatshrink 12/4."""
    stored = {0: lambda d: d, 1: zlib.compress,
              3: lambda d: heatshrink2.compress(d, window_sz2=12, lookahead_sz2=4)}[compression](data)
    head = struct.pack("<HHI", kind, compression, len(data)) + (struct.pack("<I", len(stored)) if compression else b"")
    body = head + params + stored
    return body + struct.pack("<I", zlib.crc32(body))


def ini(pairs: dict) -> bytes:
    return "".join(f"{k}={v}\n" for k, v in pairs.items()).encode()


def write_bgcode(gcode: str, slicer: dict, printer: dict | None = None, print_meta: dict | None = None,
                 producer: str = "PrusaSlicer 2.8.1", block_bytes: int = 65536) -> bytes:
    """A version-1 binary G-code file holding ``gcode`` (heatshrink 12/4, MeatPack with comments)
    and the metadata given (slicer metadata Deflate-compressed, as PrusaSlicer writes it)."""
    enc = struct.pack("<H", 0)
    out = bytearray(b"GCDE" + struct.pack("<IH", 1, 1))
    out += block(0, enc, ini({"Producer": producer}))
    out += block(3, enc, ini(printer or {"printer_model": "MK4S"}))
    out += block(4, enc, ini(print_meta or {}))
    out += block(2, enc, ini(slicer), compression=1)
    lines, chunk, size = gcode.splitlines(keepends=True), [], 0
    for line in lines + [None]:
        if line is None or (size + len(line) > block_bytes and chunk):
            out += block(1, struct.pack("<H", 2), meatpack("".join(chunk)), compression=3)
            chunk, size = [], 0
        if line is not None:
            chunk.append(line)
            size += len(line)
    return bytes(out)
