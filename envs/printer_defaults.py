"""The documented defaults of a printer description: every physical value a description may leave
out, those of an Ender-3-class machine (the description's form: :mod:`ringtune.envs.printer`).

Units: kg, N, mm/s; damping ratios and the belt mismatch are plain numbers.
"""

from __future__ import annotations

from typing import Any

#: documented defaults for everything physical (an Ender-3-class machine)
DEFAULTS: dict[str, Any] = {
    "mass_x": 0.55,          # kg: toolhead + carriage (direct drive)
    "mass_y": 1.10,          # kg: bed (cartesian) or gantry + toolhead (corexy)
    "print_mass": 0.0,       # kg on the bed
    "damping": 0.07,         # modal damping ratio when a mode gives none
    "motor_force": 30.0,     # N at the belt, low-speed pull-out force of a 42-34 stepper, 20T pulley
    "corner_speed": 150.0,   # mm/s
    "rotor_mass": 0.13,      # kg: 54 g·cm² rotor on a 6.37 mm pulley radius
    "friction": 1.0,         # N
    "steps_per_mm": 80.0,
    "microsteps": 16,        # microsteps per full step (steps_per_mm counts microsteps)
    "rotor_damping": 0.1,    # damping ratio of the rotor modes (slip model)
    "belt_mismatch": 0.0,
}
