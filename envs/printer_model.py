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

from ringtune.shaping.errors import RingtuneError

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


@dataclass
class MotorModel:
    """Stepper seen at the belt: force (N) it can give falls with speed above ``corner_speed``."""

    force: float = DEFAULTS["motor_force"]
    corner_speed: float = DEFAULTS["corner_speed"]
    rotor_mass: float = DEFAULTS["rotor_mass"]
    friction: float = DEFAULTS["friction"]
    steps_per_mm: float = DEFAULTS["steps_per_mm"]
    microsteps: float = DEFAULTS["microsteps"]
    rotor_damping: float = DEFAULTS["rotor_damping"]
    slip: bool | None = None

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
        """Largest force (N) the motor can give at belt speed ``speed`` (mm/s):
        ``force`` up to ``corner_speed``, then ``force·corner_speed/|speed|``."""
        s = np.abs(np.asarray(speed, dtype=float))
        return self.force * np.minimum(1.0, self.corner_speed / np.maximum(s, 1e-12))


@dataclass
class Printer:
    """A validated printer description (TOML form: :mod:`ringtune.envs.printer`)."""

    name: str = "printer"
    kinematics: str = "cartesian"
    limits_dict: dict = field(default_factory=dict)
    x: AxisModel = field(default_factory=lambda: AxisModel(DEFAULTS["mass_x"], [Mode(50.0, 0.07)]))
    y: AxisModel = field(default_factory=lambda: AxisModel(DEFAULTS["mass_y"], [Mode(40.0, 0.07)]))
    motor: MotorModel = field(default_factory=MotorModel)
    print_mass: float = DEFAULTS["print_mass"]
    belt_stiffness: float | None = None
    belt_mismatch: float = DEFAULTS["belt_mismatch"]
    description: str = ""

    # -- derived physics --------------------------------------------------------------------------
    def axis(self, name: str) -> AxisModel:
        if name not in ("x", "y"):
            raise RingtuneError(f"axis must be 'x' or 'y', not {name!r}")
        return self.x if name == "x" else self.y

    def moving_mass(self, axis: str) -> float:
        """kg moving on ``axis`` during printing (the Y bed of a bed slinger carries the print)."""
        m = self.axis(axis).mass
        if axis == "y" and self.kinematics == "cartesian":
            m += self.print_mass
        return m

    def effective_modes(self, axis: str) -> list[Mode]:
        """The modes actually simulated: on a cartesian bed slinger the print mass lowers every Y
        mode's frequency by sqrt(m/(m+print)) at unchanged stiffness and damping coefficient
        (so the damping ratio falls by the same factor)."""
        ax = self.axis(axis)
        r = ax.mass / self.moving_mass(axis)
        if r == 1.0:
            return [replace(m) for m in ax.modes]
        s = math.sqrt(r)
        return [replace(m, freq=m.freq * s, damping=m.damping * s) for m in ax.modes]

    def detuned(self, factor: float) -> "Printer":
        """The same machine with every resonance moved by ``factor`` (each mode's frequency ×
        factor, so every stiffness × factor²; masses, damping ratios and the motor unchanged): what
        drift in a real printer looks like (print mass on the bed, toolhead position, an
        identification off by a few per cent)."""
        if not factor > 0:
            raise RingtuneError(f"detuning factor must be > 0, not {factor}")
        axes = {a: AxisModel(getattr(self, a).mass, [replace(m, freq=m.freq * factor) for m in getattr(self, a).modes])
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
        from ringtune.shaping.planner import MachineLimits  # lazy: planner is a sibling package

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
        for ax in ("x", "y"):
            a = self.axis(ax)
            modes = []
            for m in a.modes:
                md = {"freq": m.freq, "damping": m.damping, "share": m.share}
                if m.mass_share is not None:
                    md["mass_share"] = m.mass_share
                modes.append(md)
            d[ax] = {"mass": a.mass, "modes": modes}
        mo = self.motor
        d["motor"] = {"force": mo.force, "corner_speed": mo.corner_speed, "rotor_mass": mo.rotor_mass,
                      "friction": mo.friction, "steps_per_mm": mo.steps_per_mm}
        if mo.microsteps != DEFAULTS["microsteps"] or mo.rotor_damping != DEFAULTS["rotor_damping"]:
            d["motor"].update(microsteps=mo.microsteps, rotor_damping=mo.rotor_damping)
        if mo.slip is not None:
            d["motor"]["slip"] = mo.slip
        if self.kinematics == "corexy":
            belts: dict[str, Any] = {"mismatch": self.belt_mismatch}
            if self.belt_stiffness is not None:
                belts["stiffness"] = self.belt_stiffness
            d["belts"] = belts
        return d

    def to_toml(self) -> str:
        """TOML text that :func:`ringtune.envs.printer.load_printer` reads back to an equal printer."""
        d = self.to_dict()
        lines = [f"name = {_toml_value(d['name'])}", f"kinematics = {_toml_value(d['kinematics'])}"]
        if "description" in d:
            lines.append(f"description = {_toml_value(d['description'])}")
        lines.append(f"print_mass = {_toml_value(d['print_mass'])}")
        for table in ("limits", "x", "y", "motor", "belts"):
            if table not in d:
                continue
            lines.append("")
            lines.append(f"[{table}]")
            for k, v in d[table].items():
                if k == "modes":
                    inner = ", ".join("{ " + ", ".join(f"{mk} = {_toml_value(mv)}" for mk, mv in m.items())
                                      + " }" for m in v)
                    lines.append(f"modes = [{inner}]")
                else:
                    lines.append(f"{k} = {_toml_value(v)}")
        return "\n".join(lines) + "\n"


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(float(v)) if isinstance(v, float) else str(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {v!r} to TOML")
