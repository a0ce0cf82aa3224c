"""Which firmware wrote a configuration text, and the lines of a report as a host saved them.

:func:`refuse_other_dialect` lets each reader (Klipper ``printer.cfg``, Marlin ``M503``,
RepRapFirmware ``config.g``) refuse, in one line naming the right reader, a file another firmware
wrote: the same G-code letters mean other units there (RRF's ``M203`` is mm/min, Marlin's mm/s;
RRF's ``M593 P"zvd"`` names a shaper, Marlin's ``M593`` is always ZV). Each firmware is told by
what only it writes:

- Klipper: ``[printer]``, ``[stepper_x]``, ``[mcu]``… section headers (``firmware.md`` §1);
- RepRapFirmware: ``M584`` (drive mapping), ``M569`` (driver setup), ``M950`` (ports), ``M669``
  (kinematics), ``M308`` (sensors), ``M563`` (tools), quoted string parameters (``P"zvd"``);
- Marlin: the ``echo:`` lines of a report and its ``M145``/``M851``/``M420``/``M413``/``M900`` lines.

:func:`console_line` strips what host programs add to a saved console (OctoPrint's ``Recv:`` /
``Send:``, Pronterface's ``>>>``/``SENDING:``, Repetier's and serial logs' timestamps) and tells the
lines the host sent (which are not the firmware's answer).
"""

from __future__ import annotations

import re

from ringtune.shaping.errors import RingtuneError

_KLIPPER = re.compile(r"^[ \t]*\[(printer|stepper_[a-z]|mcu|extruder|input_shaper|include\s[^\]]*)\]", re.M | re.I)
_RRF = re.compile(r"^[ \t]*(?:N\d+[ \t]+)?M(584|569|950|669|308|563|671)\b|^[ \t]*M\d+\b[^;\n]*[ \t][A-Z]\"", re.M)
_MARLIN = re.compile(r"^[ \t]*(?:echo:[ \t]*)?M(145|851|420|413|900)\b|^[^\n;#]*\becho:[ \t]*(?:;|M\d)", re.M | re.I)

#: reader of each firmware's configuration, as the user calls it
READERS = {"klipper": "Klipper's printer.cfg (`printer from-klipper`, identify --klipper-config)",
           "marlin": "Marlin's M503 report (`printer from-marlin`, identify --marlin)",
           "rrf": "RepRapFirmware's config.g (`printer from-rrf`, identify --rrf)"}
_NAMES = {"klipper": "a Klipper configuration", "marlin": "a Marlin M503 report",
          "rrf": "a RepRapFirmware configuration"}

_TIMESTAMP = re.compile(r"^\s*\[?(?:\d{4}-\d{2}-\d{2}[ T])?\d{1,2}:\d{2}:\d{2}(?:[.,]\d+)?\]?\s*(?:[-:|]\s*)?")
_SENT = re.compile(r"^(?:send:|sent:|sending:|>>>|>\s)", re.I)
_RECEIVED = re.compile(r"^(?:recv:|received:|read:|<<<|<\s)\s*", re.I)


def sniff_dialect(text: str) -> tuple[str, int] | None:
    """``(firmware, line number)`` of the first line only one firmware writes, else None."""
    hits = []
    for name, pattern in (("klipper", _KLIPPER), ("rrf", _RRF), ("marlin", _MARLIN)):
        m = pattern.search(text)
        if m:
            hits.append((m.start(), name))
    if not hits:
        return None
    start, name = min(hits)
    return name, text.count("\n", 0, start) + 1


def refuse_other_dialect(text: str, path: str, expected: str) -> None:
    """Refuse ``text`` when it is another firmware's configuration than ``expected``."""
    found = sniff_dialect(text)
    if found is None or found[0] == expected:
        return
    name, line = found
    shown = text.splitlines()[line - 1].split(";")[0].strip()[:40]
    raise RingtuneError(f"this is {_NAMES[name]}, not {_NAMES[expected]} (line {line}: {shown!r}); read it as "
                        f"{READERS[name]}", path)


def console_line(raw: str) -> str | None:
    """The firmware's words on one line of a saved console: timestamps and host tags removed;
    None for a line the host sent (``Send: M503``)."""
    line = _TIMESTAMP.sub("", raw.strip(), count=1)
    if _SENT.match(line):
        return None
    return _RECEIVED.sub("", line, count=1)
