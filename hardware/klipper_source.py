"""A Klipper configuration as sections to read facts from (:class:`Source`: from ``printer.cfg`` or
from Moonraker), and Klipper's defaults for what is read from it.

Sections are matched case-insensitively; each value read says where it came from (``file:line``,
else the file or URL with the section and option), and each Klipper default taken is a note.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ringtune.hardware.firmware_facts import to_number

#: Klipper's defaults for what is taken from its configuration (toolhead.py, stepper.py,
#: extras/input_shaper.py)
KLIPPER_DEFAULTS = {"square_corner_velocity": 5.0, "minimum_cruise_ratio": 0.5, "full_steps_per_rotation": 200,
            "shaper_type": "mzv", "damping_ratio": 0.1,
            # [firmware_retraction] (klippy/extras/firmware_retraction.py)
            "retract_length": 0.0, "retract_speed": 20.0, "unretract_extra_length": 0.0, "unretract_speed": 10.0,
            "arc_resolution": 1.0}        # [gcode_arcs] resolution (klippy/extras/gcode_arcs.py)


@dataclass
class Source:
    """Sections to read facts from, and how to say where a value came from."""

    sections: dict
    label: str                                   # file or URL
    origin: dict = field(default_factory=dict)   # (section, option) -> "file:line"
    given: set | None = None                     # (section lower, option) the user wrote; None = all
    notes: list = field(default_factory=list)
    unread: list = field(default_factory=list)   # files Klipper reads that could not be read here

    def name(self, section: str) -> str | None:
        """The section's name as written (sections are matched case-insensitively)."""
        for key in self.sections:
            if key.lower() == section.lower():
                return key
        return None

    def get(self, section: str, option: str):
        real = self.name(section)
        return None if real is None else self.sections[real].get(option)

    def where(self, section: str, option: str) -> str:
        real = self.name(section) or section
        return self.origin.get((real, option)) or f"{self.label}: [{real}] {option}"

    def given_by_user(self, section: str, option: str) -> bool:
        if self.get(section, option) is None:
            return False
        return self.given is None or (section.lower(), option) in self.given

    def number(self, section: str, option: str, default=None, integer=False, unit=""):
        """The option as a number; Klipper's ``default`` (with a note) when the user did not set it."""
        v = self.get(section, option)
        if v is None and default is None:
            return None
        value = default if v is None else to_number(v, self.where(section, option), integer)
        if not self.given_by_user(section, option) and default is not None:
            self.notes.append(f"[{self.name(section) or section}] {option} not set: Klipper's default "
                              f"{value:g}{unit} is used")
        return value
