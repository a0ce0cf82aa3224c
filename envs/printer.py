"""Printer description: what the simulated machine is made of, loaded from TOML and validated.

A description names the kinematics, the firmware limits and, per axis, the vibration modes the
nozzle shows relative to the print. Everything physical has a documented default (see
:data:`DEFAULTS`), so the minimal form of DESIGN.md is enough::

    name = "my-ender3"
    kinematics = "cartesian"        # or "corexy", "corexz"
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

Motors from the datasheet (:mod:`ringtune.envs.stepper`): instead of ``force``/``corner_speed``,
``[motor]`` may name a built-in motor, ``name = "ldo-42sth48-2504ac"`` (every motor of Klipper
autotune's database, :mod:`ringtune.envs.motors`), and/or give its constants ``holding_torque``
(N·m), ``rated_current`` (A), ``resistance`` (Ω), ``inductance`` (H), ``steps_per_revolution``
(explicit constants win over the named motor's); the drive: ``run_current`` (A RMS), ``voltage``
(V), ``rotation_distance`` (mm of belt per revolution; gives ``steps_per_mm``), ``rotor_inertia``
(kg·m², optional). The force then follows from stepper physics; what is not given is assumed and
said (:attr:`MotorModel.assumed`, TOML comments). ``[x.motor]`` / ``[y.motor]`` override ``[motor]``
per axis (a motor named there replaces the base's motor and keeps its drive): cartesian X, Y; CoreXY
A (stepper_x), B (stepper_y); CoreXZ the A/B pair that drives X (stepper_x, stepper_z) and the bed's
Y motor (stepper_y). CoreXZ: Z is still while a layer prints, so X moves turn A and B together, and
Y is a bed slinger's (the print mass moves with it).

``[current]`` (what the printer runs today: ``source``, ``shaper_x``, ``freq_x``, ``damping_x``, the
same for y, ``accel``, ``firmware``) and ``[measurement]`` (``source``, ``origin`` — whose files they
are when not the user's, e.g. an embedded printer's —, ``files = [{ name, sha256, axis }]``,
``[measurement.klipper]``) are kept as read in :attr:`Printer.current` /
:attr:`Printer.measurement` and written back unchanged.

``[belts]`` (corexy only):
``stiffness`` (N/m of each belt at the head; default: half the stiffer-than-needed axis stiffness,
see :meth:`Printer.belt_stiffnesses`) and ``mismatch`` ((k_A − k_B)/mean, 0 = matched belts).

The data types (:class:`Printer`, :class:`AxisModel`, :class:`Mode`) and their derived physics live
in :mod:`ringtune.envs.printer_model`, :class:`MotorModel` in :mod:`ringtune.envs.motor_model`,
:data:`DEFAULTS` in :mod:`ringtune.envs.printer_defaults`;
this module reads and validates descriptions (an axis's modes and moving mass in
:mod:`ringtune.envs.printer_axes`, the ``[motor]`` tables in :mod:`ringtune.envs.printer_motor`,
the checked values in :mod:`ringtune.envs.toml_checks`).
"""

from __future__ import annotations

import math
import tomllib
from importlib import resources
from pathlib import Path

from ringtune.envs.motor_model import MotorModel
from ringtune.envs.printer_axes import axis_from_dict
from ringtune.envs.printer_defaults import DEFAULTS
from ringtune.envs.printer_model import Printer
from ringtune.envs.printer_motor import inherit_motor, is_datasheet, motor_from_dict
from ringtune.envs.toml_checks import flag, number, refuse_unknown, table
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.planner import AXIS_RULES
from ringtune.shaping.textfile import firmware_config_hint, read_text_file

KINEMATICS = ("cartesian", "corexy", "corexz")

#: ``[limits]``: every acceleration the firmware applies (mm/s², mm/s): ``accel`` (printing; Marlin
#: M204 P, RRF M204 P, Klipper max_accel), ``travel_accel`` (M204 T), ``retract_accel`` (Marlin M204
#: R: E-only moves), ``max_accel``/``max_velocity`` (per-axis caps x, y, z, e; 0 = none), ``axis_rule``
#: (how those caps bind: ``per_axis`` or Kalico's ``limited_corexy``), ``scale_xy_accel`` (Kalico),
#: the corner rule, Klipper's ``min_cruise_ratio`` and an old Klipper's ``accel_to_decel`` (mm/s²), and
#: the firmware retraction a ``G10``/``G11`` makes (``retract_length``, ``unretract_extra_length`` mm,
#: ``retract_speed``, ``unretract_speed`` mm/s, ``retract_zlift`` the Z hop mm), Klipper's ``[gcode_arcs]
#: resolution`` (``arc_resolution``, mm) and its extruder's ``extrude_only_accel`` / ``extrude_only_velocity``
#: (``max_extrude_only_*``: retractions; mm/s², mm/s), and what it refuses: ``max_extrude_ratio`` (filament per mm
#: of path: max_extrude_cross_section / the filament's cross-section), ``nozzle_diameter`` and
#: ``extrude_only_distance`` (mm); ``travel_x`` / ``travel_y``: [min, max] mm where the toolhead may go
#: (Klipper's position_min / position_max); see :class:`ringtune.shaping.planner.MachineLimits`
LIMIT_KEYS = ("accel", "velocity", "junction", "square_corner_velocity", "junction_deviation",
              "jerk", "max_accel", "max_velocity", "min_cruise_ratio", "accel_to_decel", "travel_accel",
              "retract_accel", "axis_rule", "scale_xy_accel", "retract_length", "retract_speed",
              "unretract_extra_length", "unretract_speed", "retract_zlift", "arc_resolution", "extrude_only_accel",
              "extrude_only_velocity", "max_extrude_ratio", "nozzle_diameter", "extrude_only_distance", "travel_x",
              "travel_y")
_TOP_KEYS = {"name", "kinematics", "limits", "x", "y", "motor", "belts", "print_mass", "description",
             "current", "measurement"}
_BELT_KEYS = {"stiffness", "mismatch"}


#: keys of the pass-through sections that must be numbers / strings when present
_NUMERIC = {"current": ("freq_x", "freq_y", "damping_x", "damping_y", "accel"),
            "measurement": ()}
_STRINGS = {"current": ("source", "shaper_x", "shaper_y", "firmware"), "measurement": ("source", "origin")}


def _passthrough(d: dict, sec: str, where: str) -> dict:
    """``[current]`` / ``[measurement]``: kept as read (written back unchanged); the keys the tools
    read are type-checked."""
    t = table(d, sec, where)
    w = f"{where}: [{sec}]"
    for k in _NUMERIC[sec]:
        if k in t:
            number(t, k, w, lo=0.0)
    for k in _STRINGS[sec]:
        if k in t and not isinstance(t[k], str):
            raise RingtuneError(f"{k} must be a string, got {t[k]!r}", f"{w}.{k}")
    if sec == "measurement":
        _check_measurement(t, w)
    return dict(t)


def _check_measurement(t: dict, w: str) -> None:
    """``[measurement]``'s ``files`` (a list of tables) and ``[measurement.klipper]`` (a table)."""
    files = t.get("files", [])
    if not isinstance(files, list) or not all(isinstance(f, dict) for f in files):
        raise RingtuneError('files must be a list of tables like { name = "x.csv", sha256 = "…", axis = "x" }',
                            f"{w}.files")
    if "klipper" in t and not isinstance(t["klipper"], dict):
        raise RingtuneError("[measurement.klipper] must be a table", f"{w}.klipper")


def _defaulted(d: dict, base_raw: dict) -> tuple[str, ...]:
    """What the description leaves to DEFAULTS: an axis's moving mass (no ``mass``/``masses``) and an
    axis's motor force (its table over ``[motor]`` has neither a name, datasheet constants nor
    ``force``): ``Printer.defaulted``."""
    tables = {ax: d.get(ax) if isinstance(d.get(ax), dict) else {} for ax in ("x", "y")}
    masses = [f"{ax}.mass" for ax, t in tables.items() if not t.keys() & {"mass", "masses"}]
    return tuple(masses + [f"{ax}.motor" for ax, t in tables.items() if not _has_force(t, base_raw)])


def _has_force(axis_table: dict, base_raw: dict) -> bool:
    """Whether an axis's motor (its own ``motor`` table over ``[motor]``) gives its force: a named
    motor, datasheet constants or ``force``."""
    own = axis_table.get("motor") if isinstance(axis_table.get("motor"), dict) else {}
    mo = inherit_motor(base_raw, own) if own else base_raw
    return is_datasheet(mo) or "force" in mo


#: ``[limits]``' plain numbers and their bounds (as :func:`number` takes them)
_LIMIT_BOUNDS = {**dict.fromkeys(("accel", "velocity", "square_corner_velocity", "junction_deviation", "travel_accel",
                                  "retract_accel", "accel_to_decel", "retract_speed", "unretract_speed",
                                  "arc_resolution", "extrude_only_accel", "extrude_only_velocity",
                                  "max_extrude_ratio", "nozzle_diameter", "extrude_only_distance"),
                                 {"lo": 0.0, "lo_open": True}),
                 "min_cruise_ratio": {"lo": 0.0, "hi": 1.0}, "retract_length": {"lo": 0.0}, "retract_zlift": {"lo": 0.0},
                 "unretract_extra_length": {}}


def _check_limits(limits: dict, lw: str) -> None:
    """Validate ``[limits]`` (errors name the key); the planner's own check runs on top."""
    for key, bounds in _LIMIT_BOUNDS.items():
        if key in limits:
            number(limits, key, lw, **bounds)
    for key, allowed in (("junction", ("scv", "jd", "jerk")), ("axis_rule", AXIS_RULES)):
        if key in limits and limits[key] not in allowed:
            raise RingtuneError(f"{key} must be one of {', '.join(allowed)}, not {limits[key]!r}", f"{lw}.{key}")
    flag(limits, "scale_xy_accel", lw, None)
    speeds = [k for k in ("retract_speed", "unretract_speed") if k not in limits and limits.get("retract_length")]
    if speeds:
        raise RingtuneError("needed with a retract_length above 0 (mm/s)", f"{lw}.{speeds[0]}")
    for key in ("jerk", "max_accel", "max_velocity"):
        if key in limits and not _four_numbers(limits[key]):
            raise RingtuneError(f"{key} must be a list of 4 non-negative numbers (x, y, z, e)", f"{lw}.{key}")
    for key in ("travel_x", "travel_y"):
        if key in limits and not _range(limits[key]):
            raise RingtuneError(f"{key} must be a list [min, max] of two numbers, min below max (mm)", f"{lw}.{key}")


def _range(v) -> bool:
    return (isinstance(v, list) and len(v) == 2 and all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                        and math.isfinite(x) for x in v) and v[0] < v[1])


def _four_numbers(v) -> bool:
    return isinstance(v, list) and len(v) == 4 and all(
        isinstance(x, (int, float)) and not isinstance(x, bool) and x >= 0 for x in v)


def _name_and_kinematics(d: dict, where: str) -> tuple[str, str]:
    """The description's ``name`` (a string) and ``kinematics`` (one of :data:`KINEMATICS`)."""
    name = d.get("name", "printer")
    if not isinstance(name, str):
        raise RingtuneError("name must be a string", f"{where}: name")
    kin = d.get("kinematics", "cartesian")
    if kin not in KINEMATICS:
        raise RingtuneError(f"kinematics must be one of {', '.join(KINEMATICS)}, not {kin!r}",
                            f"{where}: kinematics")
    return name, kin


def _axis_motors(d: dict, base_raw: dict, motor: MotorModel, where: str) -> dict:
    """{axis: motor} of the axes whose ``[x.motor]``/``[y.motor]`` changes the base motor."""
    axis_motors = {}
    for ax in ("x", "y"):
        own = table(table(d, ax, where), "motor", f"{where}: [{ax}]")
        if not own:
            continue
        m = motor_from_dict(inherit_motor(base_raw, own), f"{where}: [{ax}.motor]")
        if m != motor:                       # an axis table that changes nothing is no own motor
            axis_motors[ax] = m
    return axis_motors


def _belts(belts: dict, kin: str, bw: str) -> tuple[float | None, float]:
    """(belt stiffness N/m or None, mismatch) of ``[belts]``, a CoreXY's alone."""
    if belts and kin != "corexy":
        raise RingtuneError("[belts] applies only to kinematics = \"corexy\"", bw)
    refuse_unknown(belts, _BELT_KEYS, bw)
    stiffness = number(belts, "stiffness", bw, lo=0.0, lo_open=True) if "stiffness" in belts else None
    return stiffness, number(belts, "mismatch", bw, DEFAULTS["belt_mismatch"], lo=-1.9, hi=1.9)


def _check_built(p: Printer, where: str, bw: str) -> None:
    """The planner's own check of the limits, and a CoreXY's belts no stiffer than its first modes allow."""
    try:
        p.machine_limits()
    except RingtuneError as exc:          # the planner's own check (e.g. scale_xy_accel without caps)
        raise RingtuneError(exc.bare, f"{where}: [{exc.where}]" if exc.where else where) from None
    if p.kinematics != "corexy":
        return
    ka, kb = p.belt_stiffnesses()
    for ax in ("x", "y"):
        if ka + kb > p.primary_stiffness(ax) * (1 + 1e-9):
            raise RingtuneError(
                f"belts (k_A + k_B = {ka + kb:.0f} N/m) are stiffer than the first {ax} mode allows "
                f"({p.primary_stiffness(ax):.0f} N/m = modal mass × ω²); lower [belts].stiffness",
                f"{bw}.stiffness")


def printer_from_dict(d: dict, where: str = "printer") -> Printer:
    """Validate a parsed TOML mapping and build a :class:`Printer` (errors name the key)."""
    if not isinstance(d, dict):
        raise RingtuneError("a printer description must be a table", where)
    refuse_unknown(d, _TOP_KEYS, where)
    name, kin = _name_and_kinematics(d, where)
    limits = table(d, "limits", where)
    lw = f"{where}: [limits]"
    refuse_unknown(limits, set(LIMIT_KEYS), lw)
    _check_limits(limits, lw)
    x = axis_from_dict(table(d, "x", where), "x", where)
    y = axis_from_dict(table(d, "y", where), "y", where)
    base_raw = table(d, "motor", where)
    motor = motor_from_dict(base_raw, f"{where}: [motor]")
    axis_motors = _axis_motors(d, base_raw, motor, where)
    print_mass = number(d, "print_mass", where, DEFAULTS["print_mass"], lo=0.0)
    belts = table(d, "belts", where)
    bw = f"{where}: [belts]"
    passthrough = {sec: _passthrough(d, sec, where) for sec in ("current", "measurement")}
    belt_stiffness, belt_mismatch = _belts(belts, kin, bw)
    p = Printer(
        name=name, kinematics=kin, limits_dict=dict(limits), x=x, y=y, motor=motor,
        x_motor=axis_motors.get("x"), y_motor=axis_motors.get("y"), print_mass=print_mass,
        current=passthrough["current"], measurement=passthrough["measurement"],
        belt_stiffness=belt_stiffness, belt_mismatch=belt_mismatch,
        description=str(d.get("description", "")),
        defaulted=_defaulted(d, base_raw),
    )
    _check_built(p, where, bw)
    return p


def load_printer(path: str | Path | None = None) -> Printer:
    """Read and validate a printer TOML; ``None`` gives the embedded default (Ender-3-class).

    A bare name of an embedded description (``"ender3"``, ``"voron24"``) also works."""
    if isinstance(path, Printer):
        return path
    text, where = _printer_text(path)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise RingtuneError(f"not valid TOML: {exc}{firmware_config_hint(text)}", where) from None
    return printer_from_dict(data, where)


def _printer_text(path: str | Path | None) -> tuple[str, str]:
    """(TOML text, where to name in errors) of a printer file or of an embedded description."""
    p = Path("ender3" if path is None else path)
    embedded = resources.files("ringtune.envs.data") / f"{p.name}.toml"
    if (path is None or not p.is_file()) and p.suffix == "" and embedded.is_file():
        return embedded.read_text(), f"<embedded {p.name}.toml>"
    if not p.exists() and not p.is_symlink():
        hint = (f" (and not an embedded printer: {', '.join(embedded_printers())})"
                if p.suffix == "" and p.parent == Path(".") else "")
        raise RingtuneError(f"cannot read printer description: no such file{hint}", str(path))
    return read_text_file(p, "printer description (TOML)"), str(path)


def embedded_printers() -> tuple[str, ...]:
    """Names accepted by :func:`load_printer` without a path."""
    return tuple(sorted(f.name[:-5] for f in resources.files("ringtune.envs.data").iterdir()
                        if f.name.endswith(".toml")))
