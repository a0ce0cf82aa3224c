"""What a push says besides applied / not applied: which firmware answered, what stays applied after
a failure and how to undo it, and values far outside what the printer is configured for.

- The wrong firmware is recognised from how it refuses a command it does not know
  (``firmware.md`` §5): Klipper ``// Unknown command:"M493"`` (``klippy/gcode.py``), Marlin
  ``echo:Unknown command: "SET_INPUT_SHAPER …"`` (``gcode.cpp`` ``unknown_command_warning``),
  RepRapFirmware ``Error: Unsupported command`` / ``Bad command``.
- Undo: what each firmware family reloads to drop runtime settings — Klipper ``FIRMWARE_RESTART``
  (reloads printer.cfg), Marlin and Prusa ``M501`` (reloads EEPROM), RepRapFirmware
  ``M98 P"config.g"`` (runs config.g again); a power cycle does it on all of them.
- Limits: a shaper frequency outside 10-150 Hz (where printers resonate and shapers are tuned), or
  an acceleration more than :data:`FAR_FACTOR` times the highest the printer is configured for
  (read before sending), is refused unless forced.
"""

from __future__ import annotations

import re

from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.firmware import FIRMWARES

_STYLES = (("klipper", re.compile(r'^Unknown command:"[^"]*"$')),
           ("marlin", re.compile(r'^Unknown command: "[^"]*"$')),
           ("rrf", re.compile(r"^(?:Unsupported command|Bad command)\b|is not supported", re.I)))
#: family -> how a user undoes runtime settings
UNDO = {"klipper": "FIRMWARE_RESTART (reloads printer.cfg)",
        "marlin": "M501 (reloads the settings saved in EEPROM)",
        "marlin-ftm": "M501 (reloads the settings saved in EEPROM)",
        "prusa": "M501 (reloads the settings saved in EEPROM)",
        "rrf": 'M98 P"config.g" (runs config.g again)'}
_NAMES = {"klipper": "Klipper", "marlin": "Marlin", "rrf": "RepRapFirmware"}
_FLAG = {"klipper": "klipper", "marlin": "marlin or marlin-ftm", "rrf": "rrf (or rrf35, rrf34)"}

#: Hz: where printers resonate and shapers are tuned (FT_MOTION and Buddy start at 10 Hz; Klipper's
#: rule tests up to 150 Hz)
FREQ_RANGE = (10.0, 150.0)
#: an acceleration more than this many times the printer's configured maximum is refused unforced
FAR_FACTOR = 2.0


def answering_firmware(errors: list[str]) -> tuple[str, str] | None:
    """``(family, the firmware's words)`` when a refusal has the form only one firmware uses."""
    for text in errors:
        for family, pattern in _STYLES:
            if pattern.search(text.strip()):
                return family, text.strip()
    return None


def wrong_firmware_note(firmware: str, errors: list[str]) -> str | None:
    """A sentence when the printer refuses in another firmware's words than ``firmware``'s."""
    found = answering_firmware(errors)
    family = FIRMWARES[firmware].family
    if found is None or family.startswith(found[0]):
        return None
    who, words = found
    return (f"the printer answers as {_NAMES[who]} ({words!r}), not as {FIRMWARES[firmware].title}: push "
            f"again with --firmware {_FLAG[who]}")


def undo_note(firmware: str, applied: list[str]) -> str | None:
    """What stays in force after a push that did not fully apply, and how to undo it."""
    if not applied:
        return None
    return (f"still in force on the printer: {', '.join(applied)} (until a restart); to undo now: "
            f"{UNDO[FIRMWARES[firmware].family]}, or power-cycle the printer")


def check_frequencies(expected: dict, where: str = "config") -> None:
    """Refuse a shaper frequency outside :data:`FREQ_RANGE` (``expected``: Export.expected)."""
    lo, hi = FREQ_RANGE
    for key, value in expected.items():
        if key.endswith(".freq") and isinstance(value, (int, float)) and value and not lo <= value <= hi:
            raise RingtuneError(f"{key.split('.')[0].upper()} shaper frequency {value:g} Hz is far outside "
                                f"{lo:g}-{hi:g} Hz, where printers resonate: check the config, or --force to "
                                "send it anyway (nothing was sent)", where)


def check_acceleration(meant: float | None, configured: dict, where: str = "config") -> None:
    """Refuse an acceleration over :data:`FAR_FACTOR` × the highest the printer reports
    (``configured``: read-back keys ``accel``, ``travel_accel``, ``max_accel_x``… as floats)."""
    values = [float(v) for v in configured.values() if v]
    if meant is None or not values:
        return
    top = max(values)
    if meant > FAR_FACTOR * top:
        raise RingtuneError(f"acceleration {meant:g} mm/s² is {meant / top:.1f}× the highest the printer is "
                            f"configured for ({top:g} mm/s², read from it before sending): check the config, "
                            "or --force to send it anyway (nothing was sent)", where)
