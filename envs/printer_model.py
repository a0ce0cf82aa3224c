"""The printer description as data: vibration modes, axes and the printer.

Besides the fields, the types carry the physics derived from them (moving mass with the print on
the bed, the modes actually simulated, CoreXY belt stiffnesses) and write themselves back as TOML.
The stepper motor (its force–speed curve and electrical cycle) is :mod:`ringtune.envs.motor_model`,
the documented defaults :mod:`ringtune.envs.printer_defaults`. Reading and validating a TOML
description, its documented form and the embedded printers are :mod:`ringtune.envs.printer`.

Units: kg, N, N/m (= kg/s²), mm, mm/s, Hz.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ringtune.envs.motor_model import MotorModel
from ringtune.envs.printer_defaults import DEFAULTS
from ringtune.envs.toml_writer import toml_value, write_table
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.firmware import job_reading
from ringtune.shaping.planner import MachineLimits


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
        """The firmware limits as :class:`ringtune.shaping.planner.MachineLimits`, read as the
        firmware it runs (``[current] firmware``) reads a job: RRF's M203 in mm/min, no M566 on
        Marlin (:func:`ringtune.shaping.firmware.job_reading`)."""
        kw = dict(self.limits_dict)
        for key in ("jerk", "max_accel", "max_velocity", "travel_x", "travel_y"):
            if key in kw and kw[key] is not None:
                kw[key] = tuple(kw[key])
        return MachineLimits(**kw, **job_reading(self.current.get("firmware")))

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
