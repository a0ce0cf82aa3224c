"""Printer description: what the simulated machine is made of, loaded from TOML and validated.

A description names the kinematics, the firmware limits and, per axis, the vibration modes the
nozzle shows relative to the print. Everything physical has a documented default (see
:data:`DEFAULTS`), so the minimal form of DESIGN.md is enough::

    name = "my-ender3"
    kinematics = "cartesian"        # or "corexy"
    [limits]
    accel = 3000
    [x]
    modes = [{ freq = 51.0, damping = 0.06 }, { freq = 95.0, damping = 0.08, share = 0.2 }]
    [y]
    modes = [{ freq = 46.0, damping = 0.05 }]

Units: kg, N, N/m (= kg/s²), mm, mm/s, Hz. A mode's ``share`` is the fraction of the axis's nozzle
response it carries (an axis's shares sum to 1; modes without one split what is left; the higher
modes of a physical chain may carry a small negative share). ``mass_share`` (optional) is the mode's
fraction of the moving mass (modal effective mass), by default equal to ``share``.

Instead of modes an axis may be given physically:

- ``stiffness = 60000`` (N/m, belt stiffness seen at the moving mass) and ``damping`` (ratio):
  one mode at ``sqrt(stiffness/mass)/2π``;
- ``masses = [0.45, 0.1]`` and ``stiffnesses = [60000, 2.0e5]``: a chain motor–spring–mass–spring–
  mass… whose last mass is the nozzle; its modes, nozzle shares and modal masses come from the
  generalised eigenproblem (``damping`` applies to every mode).

Keys per axis (``[x]``, ``[y]``): ``mass`` (kg moving on that axis; for a cartesian bed slinger the
bed of ``[y]`` *without* the print), ``modes`` | ``stiffness`` | ``masses``+``stiffnesses``,
``damping``. Top level: ``print_mass`` (kg on the bed; on a cartesian printer it moves with Y and
lowers Y's frequencies, modes being measured with an empty bed). ``[motor]``: ``force`` (N at the
belt, pull-out force at low speed), ``corner_speed`` (mm/s above which the force falls as
``force·corner_speed/speed``, the constant-power region of a stepper), ``rotor_mass`` (kg, rotor
inertia reflected to the belt), ``friction`` (N), ``steps_per_mm``, ``microsteps`` (per full step, default 16: one electrical cycle
λ = 4·microsteps/steps_per_mm mm of belt), ``rotor_damping`` (damping ratio of the rotor modes, default 0.1) and ``slip``: unset (default)
simulates each rotor on its sinusoidal magnetic spring, so that an overloaded motor really skips
steps, whenever the motor can carry the described modes (otherwise the motor is rigid and step loss
is only detected); ``true`` insists on it (an error names ``[motor].force`` if the motor is too
weak for the modes); ``false`` keeps the rigid, purely linear motor. See :mod:`ringtune.envs.rotor`.
``[belts]`` (corexy only):
``stiffness`` (N/m of each belt at the head; default: half the stiffer-than-needed axis stiffness,
see :meth:`Printer.belt_stiffnesses`) and ``mismatch`` ((k_A − k_B)/mean, 0 = matched belts).
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from ringtune.shaping.errors import RingtuneError

KINEMATICS = ("cartesian", "corexy")

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

LIMIT_KEYS = ("accel", "velocity", "junction", "square_corner_velocity", "junction_deviation",
              "jerk", "max_accel", "max_velocity", "min_cruise_ratio", "travel_accel")
_TOP_KEYS = {"name", "kinematics", "limits", "x", "y", "motor", "belts", "print_mass", "description"}
_AXIS_KEYS = {"mass", "modes", "stiffness", "masses", "stiffnesses", "damping"}
_MODE_KEYS = {"freq", "damping", "share", "mass_share"}
_MOTOR_KEYS = {"force", "corner_speed", "rotor_mass", "friction", "steps_per_mm", "microsteps",
               "rotor_damping", "slip"}
_BELT_KEYS = {"stiffness", "mismatch"}


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
    """A validated printer description (see the module docstring for the TOML form)."""

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
        """TOML text that :func:`load_printer` reads back to an equal printer."""
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


# -- validation -------------------------------------------------------------------------------------
def _num(d: dict, key: str, where: str, default=None, lo=None, hi=None, lo_open=False):
    if key not in d:
        if default is None:
            raise RingtuneError(f"missing required key {key!r}", where)
        return default
    v = d[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise RingtuneError(f"{key} must be a finite number, got {v!r}", f"{where}.{key}")
    v = float(v)
    if lo is not None and (v < lo or (lo_open and v == lo)):
        raise RingtuneError(f"{key} = {v:g} must be {'>' if lo_open else '≥'} {lo:g}", f"{where}.{key}")
    if hi is not None and v > hi:
        raise RingtuneError(f"{key} = {v:g} must be ≤ {hi:g}", f"{where}.{key}")
    return v


def _bool(d: dict, key: str, where: str, default: bool | None) -> bool | None:
    v = d.get(key, default)
    if v is not None and not isinstance(v, bool):
        raise RingtuneError(f"{key} must be true or false, got {v!r}", f"{where}.{key}")
    return v


def _table(d: dict, key: str, where: str) -> dict:
    v = d.get(key, {})
    if not isinstance(v, dict):
        raise RingtuneError(f"[{key}] must be a table, got {type(v).__name__}", f"{where}: {key}")
    return v


def _unknown(d: dict, allowed: set, where: str) -> None:
    extra = sorted(set(d) - allowed)
    if extra:
        raise RingtuneError(f"unknown key {extra[0]!r} (allowed: {', '.join(sorted(allowed))})", where)


def _modes_from_chain(masses, stiffnesses, damping, where) -> tuple[list[Mode], float]:
    """Modes of a chain motor–k1–m1–k2–m2…, nozzle = last mass: (modes, total mass)."""
    m = np.asarray(masses, float)
    k = np.asarray(stiffnesses, float)
    n = len(m)
    K = np.zeros((n, n))
    for i in range(n):
        K[i, i] += k[i]
        if i + 1 < n:
            K[i, i] += k[i + 1]
            K[i, i + 1] = K[i + 1, i] = -k[i + 1]
    # symmetric form: M^-1/2 K M^-1/2
    s = 1.0 / np.sqrt(m)
    w2, psi = np.linalg.eigh(K * s[:, None] * s[None, :])
    phi = psi * s[:, None]                        # mass-normalised mode shapes (φᵀMφ = 1)
    gamma = phi.T @ m                              # participation factors Γ = φᵀ M 1
    share = phi[-1, :] * gamma                     # nozzle participation, Σ = 1
    mass_share = gamma ** 2 / m.sum()              # effective modal mass fraction, Σ = 1
    if np.any(w2 <= 0):
        raise RingtuneError("masses and stiffnesses give a non-positive mode", where)
    modes = [Mode(float(np.sqrt(w) / (2 * math.pi)), damping, float(sh), float(ms))
             for w, sh, ms in zip(w2, share, mass_share)]
    return modes, float(m.sum())


def _axis_from_dict(d: dict, axis: str, where: str) -> AxisModel:
    w = f"{where}: [{axis}]"
    _unknown(d, _AXIS_KEYS, w)
    mass = _num(d, "mass", w, DEFAULTS[f"mass_{axis}"], lo=0.0, lo_open=True)
    damping = _num(d, "damping", w, DEFAULTS["damping"], lo=0.0, hi=0.95)
    given = [k for k in ("modes", "stiffness", "masses") if k in d]
    if len(given) != 1:
        raise RingtuneError("give exactly one of modes, stiffness, or masses + stiffnesses", w)
    if "modes" in d:
        raw = d["modes"]
        if not isinstance(raw, list) or not raw:
            raise RingtuneError("modes must be a non-empty list of {freq, damping, share}", f"{w}.modes")
        modes: list[Mode] = []
        free = []
        total = 0.0
        for i, md in enumerate(raw):
            mw = f"{w}.modes[{i}]"
            if not isinstance(md, dict):
                raise RingtuneError("each mode must be a table like { freq = 50, damping = 0.06 }", mw)
            _unknown(md, _MODE_KEYS, mw)
            f = _num(md, "freq", mw, lo=0.0, lo_open=True, hi=2000.0)
            z = _num(md, "damping", mw, damping, lo=0.0, hi=0.95)
            if "share" in md:
                # physical chains give higher modes small negative shares (nozzle against carriage)
                sh = _num(md, "share", mw, lo=-2.0, hi=2.0)
                if sh == 0.0:
                    raise RingtuneError("share must not be 0 (drop the mode instead)", f"{mw}.share")
                total += sh
            else:
                sh = float("nan")
                free.append(i)
            ms = _num(md, "mass_share", mw, lo=0.0, hi=1.0) if "mass_share" in md else None
            modes.append(Mode(f, z, sh, ms))
        if (free and total > 1.0 + 1e-6) or (not free and abs(total - 1.0) > 1e-3):
            raise RingtuneError(f"mode shares sum to {total:g}; they must sum to 1 "
                                "(leave one out to let it take what is left)", f"{w}.modes")
        if free:
            rest = 1.0 - total
            if rest <= 1e-9:
                raise RingtuneError("modes without a share get nothing: the given shares already sum to 1",
                                    f"{w}.modes")
            for i in free:
                modes[i].share = rest / len(free)
        return AxisModel(mass, modes)
    if "stiffness" in d:
        k = _num(d, "stiffness", w, lo=0.0, lo_open=True)
        return AxisModel(mass, [Mode(math.sqrt(k / mass) / (2 * math.pi), damping, 1.0)])
    ms, ks = d.get("masses"), d.get("stiffnesses")
    for key, v in (("masses", ms), ("stiffnesses", ks)):
        if not isinstance(v, list) or not v or not all(
                isinstance(x, (int, float)) and not isinstance(x, bool) and x > 0 for x in v):
            raise RingtuneError(f"{key} must be a non-empty list of positive numbers", f"{w}.{key}")
    if len(ms) != len(ks):
        raise RingtuneError(f"masses has {len(ms)} entries but stiffnesses has {len(ks)}", f"{w}.stiffnesses")
    if "mass" in d:
        raise RingtuneError("give either mass or masses, not both", f"{w}.mass")
    modes, total = _modes_from_chain(ms, ks, damping, w)
    return AxisModel(total, modes)


def printer_from_dict(d: dict, where: str = "printer") -> Printer:
    """Validate a parsed TOML mapping and build a :class:`Printer` (errors name the key)."""
    if not isinstance(d, dict):
        raise RingtuneError("a printer description must be a table", where)
    _unknown(d, _TOP_KEYS, where)
    name = d.get("name", "printer")
    if not isinstance(name, str):
        raise RingtuneError("name must be a string", f"{where}: name")
    kin = d.get("kinematics", "cartesian")
    if kin not in KINEMATICS:
        raise RingtuneError(f"kinematics must be one of {', '.join(KINEMATICS)}, not {kin!r}",
                            f"{where}: kinematics")
    limits = _table(d, "limits", where)
    lw = f"{where}: [limits]"
    _unknown(limits, set(LIMIT_KEYS), lw)
    for key in ("accel", "velocity", "square_corner_velocity", "junction_deviation", "travel_accel"):
        if key in limits:
            _num(limits, key, lw, lo=0.0, lo_open=True)
    if "min_cruise_ratio" in limits:
        _num(limits, "min_cruise_ratio", lw, lo=0.0, hi=1.0)
    if "junction" in limits and limits["junction"] not in ("scv", "jd", "jerk"):
        raise RingtuneError(f"junction must be scv, jd or jerk, not {limits['junction']!r}", f"{lw}.junction")
    for key in ("jerk", "max_accel", "max_velocity"):
        if key in limits and not (isinstance(limits[key], list) and all(
                isinstance(x, (int, float)) and not isinstance(x, bool) and x >= 0 for x in limits[key])):
            raise RingtuneError(f"{key} must be a list of non-negative numbers (x, y, z, e)", f"{lw}.{key}")
    x = _axis_from_dict(_table(d, "x", where), "x", where)
    y = _axis_from_dict(_table(d, "y", where), "y", where)
    mo = _table(d, "motor", where)
    mw = f"{where}: [motor]"
    _unknown(mo, _MOTOR_KEYS, mw)
    motor = MotorModel(
        force=_num(mo, "force", mw, DEFAULTS["motor_force"], lo=0.0, lo_open=True),
        corner_speed=_num(mo, "corner_speed", mw, DEFAULTS["corner_speed"], lo=0.0, lo_open=True),
        rotor_mass=_num(mo, "rotor_mass", mw, DEFAULTS["rotor_mass"], lo=0.0),
        friction=_num(mo, "friction", mw, DEFAULTS["friction"], lo=0.0),
        steps_per_mm=_num(mo, "steps_per_mm", mw, DEFAULTS["steps_per_mm"], lo=0.0, lo_open=True),
        microsteps=_num(mo, "microsteps", mw, DEFAULTS["microsteps"], lo=1.0),
        rotor_damping=_num(mo, "rotor_damping", mw, DEFAULTS["rotor_damping"], lo=0.0, hi=2.0),
        slip=_bool(mo, "slip", mw, None),
    )
    print_mass = _num(d, "print_mass", where, DEFAULTS["print_mass"], lo=0.0)
    belts = _table(d, "belts", where)
    bw = f"{where}: [belts]"
    if belts and kin != "corexy":
        raise RingtuneError("[belts] applies only to kinematics = \"corexy\"", bw)
    _unknown(belts, _BELT_KEYS, bw)
    p = Printer(
        name=name, kinematics=kin, limits_dict=dict(limits), x=x, y=y, motor=motor,
        print_mass=print_mass,
        belt_stiffness=_num(belts, "stiffness", bw, lo=0.0, lo_open=True) if "stiffness" in belts else None,
        belt_mismatch=_num(belts, "mismatch", bw, DEFAULTS["belt_mismatch"], lo=-1.9, hi=1.9),
        description=str(d.get("description", "")),
    )
    if kin == "corexy":
        ka, kb = p.belt_stiffnesses()
        for ax in ("x", "y"):
            if ka + kb > p.primary_stiffness(ax) * (1 + 1e-9):
                raise RingtuneError(
                    f"belts (k_A + k_B = {ka + kb:.0f} N/m) are stiffer than the first {ax} mode allows "
                    f"({p.primary_stiffness(ax):.0f} N/m = modal mass × ω²); lower [belts].stiffness",
                    f"{bw}.stiffness")
    return p


def load_printer(path: str | Path | None = None) -> Printer:
    """Read and validate a printer TOML; ``None`` gives the embedded default (Ender-3-class).

    A bare name of an embedded description (``"ender3"``, ``"voron24"``) also works."""
    if path is None:
        path = "ender3"
    if isinstance(path, Printer):
        return path
    p = Path(path)
    if not p.exists() and p.suffix == "" and (resources.files("ringtune.envs.data") / f"{p.name}.toml").is_file():
        text = (resources.files("ringtune.envs.data") / f"{p.name}.toml").read_text()
        where = f"<embedded {p.name}.toml>"
    else:
        try:
            text = p.read_text()
        except OSError as exc:
            raise RingtuneError(f"cannot read printer description: {exc.strerror}", str(path)) from None
        where = str(path)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise RingtuneError(f"not valid TOML: {exc}", where) from None
    return printer_from_dict(data, where)


def embedded_printers() -> tuple[str, ...]:
    """Names accepted by :func:`load_printer` without a path."""
    return tuple(sorted(f.name[:-5] for f in resources.files("ringtune.envs.data").iterdir()
                        if f.name.endswith(".toml")))
