"""The stepper motor of a printer description as data: the force it gives at the belt against belt
speed, its rotor and its electrical cycle, in the old form (force, corner speed) or from the
datasheet (the stepper physics of :mod:`ringtune.envs.stepper`), and its ``[motor]`` table written
back. Reading and validating a ``[motor]`` table is :mod:`ringtune.envs.printer_motor`.

Units: N, N/m, kg, kg·m², mm, mm/s, A, V, Ω, H, N·m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ringtune.envs.motors import MotorConstants, lookup_motor
from ringtune.envs.printer_defaults import DEFAULTS
from ringtune.envs.stepper import (DEFAULT_ROTATION_DISTANCE, DEFAULT_VOLTAGE, StepperDrive,
    default_run_current)


#: MotorModel fields that are a motor's datasheet constants (from ``name`` or given explicitly)
MOTOR_CONSTANT_KEYS = ("holding_torque", "rated_current", "resistance", "inductance", "steps_per_revolution")
#: MotorModel fields of the drive and mechanics of a datasheet motor (optional; defaults assumed aloud)
MOTOR_DRIVE_KEYS = ("run_current", "voltage", "rotation_distance", "rotor_inertia")


@dataclass
class MotorModel:
    """Stepper seen at the belt: the force (N) it can give against belt speed (mm/s), its rotor.

    Two forms. Old form: ``force`` up to ``corner_speed``, then ``force·corner_speed/speed``.
    Datasheet form (``holding_torque``, ``rated_current``, ``resistance``, ``inductance`` all set,
    e.g. from ``name`` in :data:`ringtune.envs.motors.MOTOR_TABLE`): the stepper physics of
    :mod:`ringtune.envs.stepper` with ``run_current`` (A RMS), ``voltage`` (V) and
    ``rotation_distance`` (mm/rev); then ``force`` (the holding force at the run current, the rotor's
    magnetic spring), ``corner_speed``, ``steps_per_mm`` (when ``rotation_distance`` is given) and
    ``rotor_mass`` (when ``rotor_inertia``, kg·m², is given: J/r²) are *derived* on construction.
    Drive values left ``None`` take the defaults of :mod:`ringtune.envs.stepper`, listed in
    ``assumed`` (one sentence each, for stderr and TOML comments)."""

    force: float = DEFAULTS["motor_force"]
    corner_speed: float = DEFAULTS["corner_speed"]
    rotor_mass: float = DEFAULTS["rotor_mass"]
    friction: float = DEFAULTS["friction"]
    steps_per_mm: float | None = DEFAULTS["steps_per_mm"]     # None (datasheet form): from rotation_distance
    microsteps: float = DEFAULTS["microsteps"]
    rotor_damping: float = DEFAULTS["rotor_damping"]
    slip: bool | None = None
    name: str | None = None
    holding_torque: float | None = None
    rated_current: float | None = None
    resistance: float | None = None
    inductance: float | None = None
    steps_per_revolution: int | None = None
    run_current: float | None = None
    voltage: float | None = None
    rotation_distance: float | None = None
    rotor_inertia: float | None = None
    assumed: tuple = field(default=(), compare=False, repr=False)
    _stepper: Any = field(default=None, init=False, compare=False, repr=False)

    def __post_init__(self) -> None:
        if not self.has_datasheet:
            self._stepper = None
            if self.steps_per_mm is None:
                self.steps_per_mm = DEFAULTS["steps_per_mm"]
            return
        n = int(self.steps_per_revolution or 200)
        run, volt, rd, notes = self._drive_or_assumed(n)
        self.steps_per_mm = n * self.microsteps / rd
        consts = MotorConstants(self.name or "custom", self.resistance, self.inductance,
                                self.holding_torque, self.rated_current, n)
        drive = StepperDrive(consts, float(run), float(volt), float(rd))
        self._stepper = drive
        self.force = drive.standstill_force
        self.corner_speed = drive.corner_speed
        if self.rotor_inertia is not None:
            self.rotor_mass = self.rotor_inertia / drive.radius ** 2
        self.assumed = tuple(notes)

    def _drive_or_assumed(self, n: int) -> tuple[float, float, float, list[str]]:
        """(run current A RMS, voltage V, rotation distance mm, what was assumed) of a datasheet motor
        with ``n`` steps per revolution: as given, else the typical value, said."""
        notes = []
        if self.steps_per_revolution is None:
            notes.append("steps_per_revolution = 200 (not given: a 1.8° motor assumed)")
        run = self.run_current
        if run is None:
            run = default_run_current(self.rated_current)
            notes.append(f"run_current = {run:.3g} A RMS (not given: rated_current/√2, the sine's "
                         "peak at the rated current)")
        volt = self.voltage
        if volt is None:
            volt = DEFAULT_VOLTAGE
            notes.append(f"voltage = {volt:g} V (not given: a 24 V supply assumed)")
        rd = self.rotation_distance
        if rd is None and self.steps_per_mm is None:
            rd = DEFAULT_ROTATION_DISTANCE
            notes.append(f"rotation_distance = {rd:g} mm (not given: a GT2 belt on a 20-tooth pulley assumed)")
        elif rd is None:
            rd = n * self.microsteps / self.steps_per_mm
            notes.append(f"rotation_distance = {rd:.4g} mm (not given: from steps_per_mm = "
                         f"{self.steps_per_mm:g}, {self.microsteps:g} microsteps, {n} steps/rev)")
        return run, volt, rd, notes

    @property
    def has_datasheet(self) -> bool:
        """True when the four datasheet constants are set (the stepper physics is used)."""
        return None not in (self.holding_torque, self.rated_current, self.resistance, self.inductance)

    @property
    def stepper(self):
        """The :class:`ringtune.envs.stepper.StepperDrive` (datasheet form) or ``None``."""
        return self._stepper

    @property
    def electrical_cycle(self) -> float:
        """mm of belt per electrical cycle (4 full steps): the period of the torque–angle curve."""
        return 4.0 * self.microsteps / self.steps_per_mm

    @property
    def full_step(self) -> float:
        """mm of belt per full step."""
        return self.microsteps / self.steps_per_mm

    @property
    def magnetic_stiffness(self) -> float:
        """N/m at the belt of the rotor on its magnetic spring: ``force·2π/λ`` (small-angle slope of
        ``force·sin(2π e/λ)``)."""
        return self.force * 2.0 * math.pi / (self.electrical_cycle * 1e-3)

    def max_force(self, speed: np.ndarray | float) -> np.ndarray:
        """Largest force (N) the motor can give at belt speed ``speed`` (mm/s): the stepper curve
        (datasheet form) or ``force`` up to ``corner_speed``, then ``force·corner_speed/|speed|``."""
        if self._stepper is not None:
            return self._stepper.force(speed)
        s = np.abs(np.asarray(speed, dtype=float))
        return self.force * np.minimum(1.0, self.corner_speed / np.maximum(s, 1e-12))

    def to_dict(self) -> dict:
        """The ``[motor]`` table: only what was given (derived and assumed values are left out, so
        that reading it back gives the same motor; a named motor's constants only where they differ
        from the built-in table)."""
        d = self._datasheet_dict() if self.has_datasheet else self._old_form_dict()
        if self.slip is not None:
            d["slip"] = self.slip
        return d

    def _given(self, keys) -> dict:
        """{key: value} of ``keys`` that are set (not None), in order."""
        return {k: getattr(self, k) for k in keys if getattr(self, k) is not None}

    def _old_form_dict(self) -> dict:
        """:meth:`to_dict` of a motor given by force and corner speed."""
        d: dict[str, Any] = {"force": self.force, "corner_speed": self.corner_speed,
                             "rotor_mass": self.rotor_mass, "friction": self.friction,
                             "steps_per_mm": self.steps_per_mm}
        if self.microsteps != DEFAULTS["microsteps"] or self.rotor_damping != DEFAULTS["rotor_damping"]:
            d.update(microsteps=self.microsteps, rotor_damping=self.rotor_damping)
        return {**d, **self._given(("name",)), **self._given(MOTOR_DRIVE_KEYS)}

    def _datasheet_dict(self) -> dict:
        """:meth:`to_dict` of a motor from its name and/or datasheet constants (a named motor's
        constants only where they differ from the built-in table)."""
        ref = lookup_motor(self.name) if self.name else None
        d = {**self._given(("name",)),
             **{k: v for k, v in self._given(MOTOR_CONSTANT_KEYS).items() if ref is None or getattr(ref, k) != v},
             **self._given(MOTOR_DRIVE_KEYS)}
        if self.rotation_distance is None:
            d["steps_per_mm"] = self.steps_per_mm
        if self.rotor_inertia is None:
            d["rotor_mass"] = self.rotor_mass
        d.update(friction=self.friction, microsteps=self.microsteps, rotor_damping=self.rotor_damping)
        return d
