"""The printer description as data: vibration modes, axes, the stepper motor and the printer.

Besides the fields, the types carry the physics derived from them (moving mass with the print on
the bed, the modes actually simulated, CoreXY belt stiffnesses, the motor's force–speed curve and
electrical cycle) and write themselves back as TOML. Reading and validating a TOML description,
its documented form and the embedded printers are :mod:`ringtune.envs.printer`.

Units: kg, N, N/m (= kg/s²), mm, mm/s, Hz.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ringtune.envs.motors import MotorConstants, lookup_motor
from ringtune.envs.stepper import (DEFAULT_ROTATION_DISTANCE, DEFAULT_VOLTAGE, StepperDrive,
    default_run_current)
from ringtune.envs.toml_writer import toml_value, write_table
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.planner import MachineLimits

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


@dataclass
class Mode:
    """One vibration mode of an axis: the nozzle deviation carries ``share`` of a base-excited
    oscillator at ``freq`` (Hz) with damping ratio ``damping``; ``mass_share`` is its fraction of
    the moving mass (modal effective mass; ``None`` = ``share``)."""

    freq: float
    damping: float
    share: float = 1.0
    mass_share: float | None = None

    @property
    def omega(self) -> float:
        """Natural angular frequency, rad/s."""
        return 2.0 * math.pi * self.freq

    @property
    def mass_fraction(self) -> float:
        return self.share if self.mass_share is None else self.mass_share


@dataclass
class AxisModel:
    """An axis: its moving mass (kg) and modes (measured with an empty bed)."""

    mass: float
    modes: list[Mode]


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


@dataclass
class Printer:
    """A validated printer description (TOML form: :mod:`ringtune.envs.printer`)."""

    name: str = "printer"
    kinematics: str = "cartesian"
    limits_dict: dict = field(default_factory=dict)
    x: AxisModel = field(default_factory=lambda: AxisModel(DEFAULTS["mass_x"], [Mode(50.0, 0.07)]))
    y: AxisModel = field(default_factory=lambda: AxisModel(DEFAULTS["mass_y"], [Mode(40.0, 0.07)]))
    motor: MotorModel = field(default_factory=MotorModel)
    x_motor: MotorModel | None = None
    y_motor: MotorModel | None = None
    print_mass: float = DEFAULTS["print_mass"]
    belt_stiffness: float | None = None
    belt_mismatch: float = DEFAULTS["belt_mismatch"]
    description: str = ""
    current: dict = field(default_factory=dict)
    measurement: dict = field(default_factory=dict)
    #: what the loaded description left to :data:`DEFAULTS` ("x.mass", "y.mass"; "x.motor",
    #: "y.motor": that axis's motor has neither a name, datasheet constants nor ``force``); set by
    #: :func:`ringtune.envs.printer.printer_from_dict`, empty for a Printer built in Python
    defaulted: tuple = field(default=(), compare=False, repr=False)

    # -- motors -----------------------------------------------------------------------------------
    def motor_for(self, axis: str) -> MotorModel:
        """The motor of ``[x.motor]`` / ``[y.motor]`` (``[motor]`` when the axis has none). On CoreXY
        ``x`` is motor A (stepper_x), ``y`` motor B (stepper_y); on CoreXZ ``x`` is the pair A, B
        that drives X (stepper_x and stepper_z), ``y`` the bed's own motor (stepper_y)."""
        if axis not in ("x", "y"):
            raise RingtuneError(f"axis must be 'x' or 'y', not {axis!r}")
        own = self.x_motor if axis == "x" else self.y_motor
        return self.motor if own is None else own

    def drive_motors(self) -> list[tuple[str, MotorModel, tuple[float, float]]]:
        """Every motor that moves the head in the XY plane: (name, model, drive) with ``drive`` the
        motor's belt speed per unit (x, y) speed. Cartesian: X (1, 0), Y (0, 1). CoreXY: A (1, 1),
        B (1, −1). CoreXZ (Z still while a layer prints, so A = x + z and B = x − z both turn with
        x): A (1, 0), B (1, 0), Y (0, 1)."""
        mx, my = self.motor_for("x"), self.motor_for("y")
        if self.kinematics == "corexy":
            return [("a", mx, (1.0, 1.0)), ("b", my, (1.0, -1.0))]
        if self.kinematics == "corexz":
            return [("a", mx, (1.0, 0.0)), ("b", mx, (1.0, 0.0)), ("y", my, (0.0, 1.0))]
        return [("x", mx, (1.0, 0.0)), ("y", my, (0.0, 1.0))]

    def motor_accel_limit(self, axis: str, speed: np.ndarray | float = 0.0) -> np.ndarray:
        """mm/s²: the largest steady acceleration of a pure ``axis`` move passing ``speed`` (mm/s)
        that every motor driving it can give (rigid masses; the modes' transient overshoot and any
        reserve are the caller's). Motor k must give its share of the axis force (the least-squares
        inverse P of the drive D, as in the simulation) plus its rotor's inertia and friction:
        ``a_max = min_k (F_k(|D_k|·v) − friction_k) / |P_k·m_axis + m_r,k·D_k|``."""
        e = 0 if axis == "x" else 1
        if axis not in ("x", "y"):
            raise RingtuneError(f"axis must be 'x' or 'y', not {axis!r}")
        motors = self.drive_motors()
        D = np.array([d for _n, _m, d in motors], float).T            # (2, k)
        P = np.linalg.pinv(D.T)                                         # (2, k)
        m = self.moving_mass(axis)
        v = np.abs(np.asarray(speed, dtype=float))
        out = np.full(v.shape, np.inf)
        for k, (_n, mo, _d) in enumerate(motors):
            if D[e, k] == 0.0:
                continue
            per_accel = abs(P[e, k] * m + mo.rotor_mass * D[e, k])      # kg
            spare = np.maximum(mo.max_force(abs(D[e, k]) * v) - mo.friction, 0.0)
            out = np.minimum(out, spare / per_accel * 1e3)
        return out

    # -- derived physics --------------------------------------------------------------------------
    def axis(self, name: str) -> AxisModel:
        if name not in ("x", "y"):
            raise RingtuneError(f"axis must be 'x' or 'y', not {name!r}")
        return self.x if name == "x" else self.y

    def moving_mass(self, axis: str) -> float:
        """kg moving on ``axis`` during printing (the Y bed of a bed slinger carries the print:
        cartesian and CoreXZ)."""
        m = self.axis(axis).mass
        if axis == "y" and self.kinematics in ("cartesian", "corexz"):
            m += self.print_mass
        return m

    def effective_modes(self, axis: str) -> list[Mode]:
        """The modes actually simulated: on a bed slinger (cartesian, CoreXZ) the print mass lowers every Y
        mode's frequency by sqrt(m/(m+print)) at unchanged stiffness and damping coefficient
        (so the damping ratio falls by the same factor)."""
        ax = self.axis(axis)
        r = ax.mass / self.moving_mass(axis)
        if r == 1.0:
            return [replace(m) for m in ax.modes]
        s = math.sqrt(r)
        return [replace(m, freq=m.freq * s, damping=m.damping * s) for m in ax.modes]

    def detuned(self, factor: float, damping: float = 1.0) -> "Printer":
        """The same machine with every resonance moved by ``factor`` (each mode's frequency ×
        factor, so every stiffness × factor²; masses and the motor unchanged) and every mode's
        damping ratio × ``damping``: what drift in a real printer looks like (print mass on the
        bed, toolhead position, an identification off by a few per cent in frequency and more in
        damping)."""
        if not factor > 0:
            raise RingtuneError(f"detuning factor must be > 0, not {factor}")
        if not damping > 0:
            raise RingtuneError(f"damping factor must be > 0, not {damping}")
        axes = {a: AxisModel(getattr(self, a).mass, [replace(m, freq=m.freq * factor, damping=m.damping * damping)
                                                     for m in getattr(self, a).modes])
                for a in ("x", "y")}
        k = None if self.belt_stiffness is None else self.belt_stiffness * factor ** 2
        return replace(self, **axes, belt_stiffness=k)

    def belt_stiffnesses(self) -> tuple[float, float]:
        """(k_A, k_B) in N/m of the CoreXY belts as seen at the head. Default mean stiffness: half of
        the smaller primary-mode axis stiffness (share·mass·ω²), so that matched belts give exactly
        the measured primary frequencies with a non-negative residual (frame) stiffness."""
        k = self.belt_stiffness
        if k is None:
            k = 0.5 * min(self.primary_stiffness("x"), self.primary_stiffness("y"))
        return k * (1.0 + self.belt_mismatch / 2.0), k * (1.0 - self.belt_mismatch / 2.0)

    def primary_stiffness(self, axis: str) -> float:
        """N/m of the first mode of ``axis``: modal mass × ω²."""
        m = self.effective_modes(axis)[0]
        return m.mass_fraction * self.moving_mass(axis) * m.omega ** 2

    def machine_limits(self):
        """The firmware limits as :class:`ringtune.shaping.planner.MachineLimits`."""
        kw = dict(self.limits_dict)
        for key in ("jerk", "max_accel", "max_velocity"):
            if key in kw and kw[key] is not None:
                kw[key] = tuple(kw[key])
        return MachineLimits(**kw)

    @property
    def limits(self):
        return self.machine_limits()

    # -- serialisation ----------------------------------------------------------------------------
    def to_dict(self) -> dict:
        d: dict[str, Any] = {"name": self.name, "kinematics": self.kinematics}
        if self.description:
            d["description"] = self.description
        d["print_mass"] = self.print_mass
        d["limits"] = dict(self.limits_dict)
        motor = self.motor.to_dict()
        for ax in ("x", "y"):
            a, own = self.axis(ax), getattr(self, f"{ax}_motor")
            d[ax] = {"mass": a.mass, "modes": [_mode_dict(m) for m in a.modes],
                     **({} if own is None else {"motor": self._own_motor_dict(own, motor)})}
        d["motor"] = motor
        if self.kinematics == "corexy":
            d["belts"] = {"mismatch": self.belt_mismatch, **({} if self.belt_stiffness is None
                                                              else {"stiffness": self.belt_stiffness})}
        d.update({k: dict(v) for k, v in (("current", self.current), ("measurement", self.measurement)) if v})
        return d

    def _own_motor_dict(self, own: MotorModel, base: dict) -> dict:
        """An axis's ``[x.motor]`` table: whole when it names another motor or form, else only what
        differs from ``[motor]``."""
        od = own.to_dict()
        if od.get("name") != base.get("name") or own.has_datasheet != self.motor.has_datasheet:
            return od
        return {k: v for k, v in od.items() if base.get(k, _MISSING) != v}

    def to_toml(self) -> str:
        """TOML text that :func:`ringtune.envs.printer.load_printer` reads back to an equal printer.
        What a datasheet motor assumes (run current, voltage, …) is written as a comment."""
        d = self.to_dict()
        lines = [f"name = {toml_value(d['name'])}", f"kinematics = {toml_value(d['kinematics'])}"]
        if "description" in d:
            lines.append(f"description = {toml_value(d['description'])}")
        lines.append(f"print_mass = {toml_value(d['print_mass'])}")
        notes = {"motor": self.motor.assumed}
        for ax in ("x", "y"):
            own = getattr(self, f"{ax}_motor")
            if own is not None:
                notes[f"{ax}.motor"] = own.assumed
        for table in ("limits", "x", "y", "motor", "belts", "current", "measurement"):
            if table in d:
                write_table(lines, table, d[table], notes)
        return "\n".join(lines) + "\n"


_MISSING = object()


def _mode_dict(m: Mode) -> dict:
    """A mode's TOML table: freq, damping, share and, when given, mass_share."""
    md = {"freq": m.freq, "damping": m.damping, "share": m.share}
    if m.mass_share is not None:
        md["mass_share"] = m.mass_share
    return md


def unmeasured_note(printer) -> str | None:
    """The note that a description's modes are the defaults `printer from-…` wrote (its
    ``[measurement] source = "none"``): every figure then rests on another printer's resonances."""
    if (getattr(printer, "measurement", None) or {}).get("source") != "none":
        return None
    return (f"note: {printer.name}: its modes were not measured ([measurement] source = \"none\", as "
            "`ringtune printer from-…` writes them): they are the embedded Ender-3-class printer's, and "
            "every figure here rests on them; run `ringtune identify` on your resonance files (or "
            "--ripples / --tower-band) to measure yours")
