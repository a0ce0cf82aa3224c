"""The Y modes of a bed slinger with the print on its bed (Hz, kg).

On a bed slinger (cartesian, CoreXZ: the bed is Y's moving mass) the print rides on the bed: with
the springs unchanged every Y mode falls as 1/√(moving mass), ``f(m) = f₀·√(M/(M + m))`` with M the
bed's moving mass and the print mass the printer already carried when its modes were measured
(:meth:`ringtune.envs.printer_model.Printer.effective_modes`, what the simulation runs on).
"""

from __future__ import annotations

from dataclasses import replace

from ringtune.envs.printer_model import Mode, Printer
from ringtune.shaping.errors import RingtuneError

#: kinematics whose Y axis carries the bed (and the print on it)
BED_SLINGERS = ("cartesian", "corexz")


def is_bed_slinger(printer: Printer) -> bool:
    """True when the print moves with Y (cartesian, CoreXZ)."""
    return printer.kinematics in BED_SLINGERS


def loaded(printer: Printer, load_kg: float) -> Printer:
    """The printer with ``load_kg`` of print added on its bed (to what it already carries)."""
    if not load_kg >= 0:
        raise RingtuneError(f"a print mass must be ≥ 0 kg, not {load_kg}", "print mass")
    return replace(printer, print_mass=printer.print_mass + float(load_kg))


def y_modes(printer: Printer, load_kg: float = 0.0) -> list[Mode]:
    """The Y modes the model simulates with ``load_kg`` more print on the bed."""
    if not is_bed_slinger(printer):
        raise RingtuneError(f"a {printer.kinematics} printer's bed does not move with Y: the print's "
                            "mass leaves its Y modes where they are (no schedule by mass)", "kinematics")
    return loaded(printer, load_kg).effective_modes("y")


def dominant_y_mode(printer: Printer, load_kg: float = 0.0) -> Mode:
    """The Y mode with the largest nozzle share at ``load_kg`` more print (what a Y shaper targets)."""
    return max(y_modes(printer, load_kg), key=lambda m: abs(m.share))
