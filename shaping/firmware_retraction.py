"""Firmware retraction: ``G10`` and ``G11`` (without ``P`` or ``L``) ask the printer to retract and restore
the filament by its own settings — Klipper's ``[firmware_retraction]`` (``SET_RETRACTION``; no
section: an unknown command, nothing moves), Marlin's M207/M208 (FWRETRACT), RepRapFirmware's M207
(``G10`` with ``P`` or ``L`` is RRF's tool offset or temperature, not a retraction). Each is an
E-only move, so the head comes to rest there as at a slicer's own retraction (the reader sets
``stop_before``, :class:`RetractionState`: not at a G10 while retracted, nor a G11 while not). The
length and speeds are the printer's, not in the file, so the planner plans these moves as taking no
time; this counts them and says what that leaves out (s)."""

from __future__ import annotations

#: for the sentence's example: Klipper's default speeds (mm/s) at a 1 mm retraction
EXAMPLE_MM, EXAMPLE_OUT_MM_S, EXAMPLE_BACK_MM_S = 1.0, 20.0, 10.0


def is_firmware_retraction(command: str, words) -> bool:
    """Whether ``command`` with ``words`` (its letters) retracts or restores by the printer's own
    settings: ``G10``/``G11`` without ``P`` or ``L``."""
    return command in ("G10", "G11") and not {"P", "L"} & set(words)


class RetractionState:
    """Whether the filament is retracted by firmware, as the firmwares keep it (Klipper's
    ``firmware_retraction.py`` ``is_retracted``, Marlin's ``retracted[]``, RRF's per tool): a ``G10``
    while retracted, or a ``G11`` while not, moves nothing; Klipper's ``SET_RETRACTION`` clears it."""

    def __init__(self):
        self.retracted = False

    def reset(self) -> None:
        """Klipper's ``SET_RETRACTION``: whatever was retracted is forgotten."""
        self.retracted = False

    def moves(self, command: str, words) -> bool:
        """Whether ``command`` (with ``words``) makes the extruder move: an E-only move, at which
        the head comes to rest. Assumes the printer retracts by a length above 0 (Klipper's
        ``[firmware_retraction]`` defaults to 0, and then nothing moves)."""
        if not is_firmware_retraction(command, words) or self.retracted == (command == "G10"):
            return False
        self.retracted = command == "G10"
        return True


def firmware_retractions(job) -> dict[str, list[int]]:
    """{``"G10"`` / ``"G11"``: the job's line numbers, in order} of its firmware retractions and
    restores that move the extruder (:class:`RetractionState`; a parsed
    :class:`ringtune.shaping.job.Job`); empty when it has none."""
    out: dict[str, list[int]] = {}
    state = RetractionState()
    for ev in job.events:
        if ev.command == "SET_RETRACTION":
            state.reset()
        elif state.moves(ev.command, ev.params):
            out.setdefault(ev.command, []).append(int(ev.line))
    return out


def firmware_retraction_note(found: dict[str, list[int]]) -> str | None:
    """One sentence on what :func:`firmware_retractions` found (None: nothing)."""
    if not found:
        return None
    n = max(len(v) for v in found.values())
    each = EXAMPLE_MM / EXAMPLE_OUT_MM_S + EXAMPLE_MM / EXAMPLE_BACK_MM_S
    parts = ", ".join(f"{cmd} ×{len(lines)} (first on line {lines[0]})" for cmd, lines in sorted(found.items()))
    return (f"the job retracts by firmware — {parts}: the length and speeds are the printer's (Klipper's "
            "[firmware_retraction], Marlin's M207/M208, RRF's M207), not in the file, so these moves are planned "
            "as stops that take no time (the printer assumed to retract: Klipper's retract_length defaults to 0, "
            f"and then the head does not stop); at {EXAMPLE_MM:g} mm out at {EXAMPLE_OUT_MM_S:g} mm/s and back at "
            f"{EXAMPLE_BACK_MM_S:g} mm/s they would add {each:.2f} s each, {n * each:.1f} s in all")
