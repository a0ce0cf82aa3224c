"""What ``ringtune motor`` reports: a stepper's force at the belt against speed, from its
datasheet constants (the built-in table's, or given), the driver's run current and voltage and the
belt travel per revolution — loaded exactly as a printer description's ``[motor]`` table is, so
what is assumed is said the same way (:attr:`MotorModel.assumed`).

Units: N, mm/s, mm/s², A RMS, V, mm, kg.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ringtune.envs.motors import lookup_motor
from ringtune.envs.printer import printer_from_dict
from ringtune.envs.stepper import StepperDrive
from ringtune.shaping.errors import RingtuneError

#: belt speeds of the force table, mm/s
SPEEDS = (0.0, 100.0, 200.0, 300.0, 500.0)


@dataclass
class MotorReport:
    """The motor's force table (``result``: the command's JSON keys but ``plot``), its drive, and
    the remarks for the person at the terminal (``notes``)."""

    result: dict
    drive: StepperDrive
    notes: list[str]


def motor_report(name: str, constants: dict | None = None, run_current: float | None = None,
                 voltage: float | None = None, rotation_distance: float | None = None,
                 mass: float | None = None) -> MotorReport:
    """The force at the belt of motor ``name`` (``constants``: datasheet constants given, by their
    ``[motor]`` keys, over the table's) at :data:`SPEEDS`; with ``mass`` (kg) the acceleration
    F(v)/mass too. An error names the ``[motor]`` key at fault (``run_current``)."""
    ref = lookup_motor(name)
    table = {"name": ref.name if ref is not None else name.strip(), **(constants or {})}
    for key, v in (("run_current", run_current), ("voltage", voltage), ("rotation_distance", rotation_distance)):
        if v is not None:
            table[key] = v
    mo = _motor_model(table)
    drive = mo.stepper
    forces = drive.force(np.array(SPEEDS))
    c = drive.motor
    result = {
        "motor": table["name"],
        "constants": {"holding_torque_nm": c.holding_torque, "rated_current_a": c.rated_current,
                      "resistance_ohm": c.resistance, "inductance_h": c.inductance,
                      "steps_per_revolution": c.steps_per_revolution},
        "run_current_a": drive.run_current, "voltage_v": drive.voltage,
        "rotation_distance_mm": drive.rotation_distance, "assumed": list(mo.assumed),
        "force_n": [[s, float(f)] for s, f in zip(SPEEDS, forces)],
        "corner_speed_mm_s": drive.corner_speed,
        "half_force_speed_mm_s": drive.half_force_speed,
    }
    if mass is not None:
        result["mass_kg"] = mass
        result["accel_mm_s2"] = [[s, float(f) / mass * 1e3] for s, f in zip(SPEEDS, forces)]
    return MotorReport(result, drive, _notes(mo, known=ref is not None))


def _motor_model(table: dict):
    """The MotorModel of a ``[motor]`` table, loaded as a printer description's is."""
    try:
        return printer_from_dict({"motor": table, "x": {"modes": [{"freq": 50.0}]},
                                  "y": {"modes": [{"freq": 50.0}]}}).motor
    except RingtuneError as exc:                      # name the key, not the description's path to it
        raise RingtuneError(exc.bare, exc.where.rsplit(".", 1)[-1]) from None


def _notes(mo, known: bool) -> list[str]:
    """What was assumed (a table motor's step count goes without saying), and a run current above
    the rated one."""
    notes = [f"note: {n}" for n in mo.assumed if not (known and n.startswith("steps_per_revolution"))]
    drive = mo.stepper
    if drive.run_current > drive.motor.rated_current:
        notes.append(f"note: run_current {drive.run_current:g} A is above the motor's rated {drive.motor.rated_current:g} A: "
                     "the force is credited only up to the rated current (the iron saturates), and the motor "
                     "runs hotter than its datasheet allows")
    return notes
