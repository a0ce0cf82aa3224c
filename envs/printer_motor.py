"""The ``[motor]`` tables of a printer description: the old form (force, corner speed), a built-in
motor by name, datasheet constants, and the drive (run current, voltage, rotation distance); an
axis's table over ``[motor]``. Units: N, mm/s, kg, A, V, mm, Ω, H, N·m (see :mod:`ringtune.envs.printer`)."""

from __future__ import annotations

from ringtune.envs.motor_model import MOTOR_CONSTANT_KEYS, MOTOR_DRIVE_KEYS, MotorModel
from ringtune.envs.motors import lookup_motor, unknown_motor_message
from ringtune.envs.printer_defaults import DEFAULTS
from ringtune.envs.toml_checks import flag, number, refuse_unknown
from ringtune.shaping.errors import RingtuneError

_OLD_FORM_KEYS = {"force", "corner_speed"}
#: given on an axis, each of these replaces the base's other form of the same thing (the belt per
#: revolution, the rotor)
_OTHER_FORM = {"rotation_distance": "steps_per_mm", "steps_per_mm": "rotation_distance",
               "rotor_inertia": "rotor_mass", "rotor_mass": "rotor_inertia"}
_MOTOR_KEYS = {"force", "corner_speed", "rotor_mass", "friction", "steps_per_mm", "microsteps",
               "rotor_damping", "slip", "name", *MOTOR_CONSTANT_KEYS, *MOTOR_DRIVE_KEYS}


def is_datasheet(raw: dict) -> bool:
    """Whether a motor table names a motor or gives datasheet constants (else the old form)."""
    return "name" in raw or any(k in raw for k in MOTOR_CONSTANT_KEYS)


def inherit_motor(base: dict, own: dict) -> dict:
    """An axis's motor table over ``[motor]``: the axis's keys win; a motor named or described on the
    axis replaces the base's motor (its name, constants and old-form force) but keeps its drive; an
    axis's rotation_distance (rotor_inertia) replaces the base's steps_per_mm (rotor_mass) and vice versa."""
    if is_datasheet(own):
        drop = {"name", *MOTOR_CONSTANT_KEYS, *_OLD_FORM_KEYS, "rotor_inertia"}
    elif own.keys() & _OLD_FORM_KEYS:
        drop = {"name", *MOTOR_CONSTANT_KEYS, "rotor_inertia"}
    else:
        drop = set()
    drop |= {_OTHER_FORM[k] for k in own.keys() & _OTHER_FORM.keys()}
    return {**{k: v for k, v in base.items() if k not in drop}, **own}


def _motor_constants(mo: dict, mw: str) -> dict:
    """The datasheet constants a motor table gives: the named built-in motor's, overridden by the
    table's own (empty: the old form, force and corner_speed)."""
    consts = _named_motor(mo, mw) if mo.get("name") is not None else {}
    consts.update({k: number(mo, k, mw, lo=0.0, lo_open=True) for k in MOTOR_CONSTANT_KEYS[:4] if k in mo})
    if "steps_per_revolution" in mo:
        consts["steps_per_revolution"] = _steps_per_revolution(mo, mw)
    return consts


def _named_motor(mo: dict, mw: str) -> dict:
    """The constants of the built-in motor ``mo`` names ({} for a name the table is not, when the
    table gives the four constants itself)."""
    name = mo["name"]
    if not isinstance(name, str) or not name.strip():
        raise RingtuneError("name must be a motor name (string)", f"{mw}.name")
    ref = lookup_motor(name)
    if ref is None and not all(k in mo for k in MOTOR_CONSTANT_KEYS[:4]):
        raise RingtuneError(unknown_motor_message(name), f"{mw}.name")
    return {k: getattr(ref, k) for k in MOTOR_CONSTANT_KEYS} if ref is not None else {}


def _steps_per_revolution(mo: dict, mw: str) -> int:
    """The table's full steps per revolution: a whole multiple of 4 (200, 400)."""
    n = number(mo, "steps_per_revolution", mw, lo=4.0)
    if n != int(n) or int(n) % 4:
        raise RingtuneError(f"steps_per_revolution = {n:g} must be a whole multiple of 4 (200, 400)",
                            f"{mw}.steps_per_revolution")
    return int(n)


def _check_motor_form(mo: dict, consts: dict, mw: str) -> None:
    """A motor from datasheet constants is given in that form alone: all four constants, no
    force/corner_speed, one of rotor_inertia/rotor_mass (nothing to check for the old form)."""
    if not consts:
        return
    missing = [k for k in MOTOR_CONSTANT_KEYS[:4] if k not in consts]
    if missing:
        raise RingtuneError(f"a motor from datasheet constants needs {', '.join(missing)} too "
                            "(or a built-in motor's name)", f"{mw}.{missing[0]}")
    both = sorted(_OLD_FORM_KEYS & mo.keys())
    if both:
        raise RingtuneError(f"{both[0]} belongs to the old form: give either force/corner_speed or "
                            "the motor (name or datasheet constants), whose force follows from them",
                            f"{mw}.{both[0]}")
    if "rotor_inertia" in mo and "rotor_mass" in mo:
        raise RingtuneError("give either rotor_inertia (kg·m²) or rotor_mass (kg at the belt)", f"{mw}.rotor_mass")


def _steps_per_mm(mo: dict, drive: dict, n_steps: int, microsteps: float, datasheet: bool, mw: str):
    """steps/mm: from rotation_distance (a steps_per_mm beside it must agree), as given, None for a
    datasheet motor without either (it assumes and says a rotation distance), else the default."""
    if "rotation_distance" not in drive:
        if datasheet and "steps_per_mm" not in mo:
            return None
        return number(mo, "steps_per_mm", mw, DEFAULTS["steps_per_mm"], lo=0.0, lo_open=True)
    derived = n_steps * microsteps / drive["rotation_distance"]
    spm = number(mo, "steps_per_mm", mw, derived, lo=0.0, lo_open=True)
    if abs(spm - derived) > 1e-3 * derived:
        raise RingtuneError(
            f"steps_per_mm = {spm:g} disagrees with rotation_distance = {drive['rotation_distance']:g} "
            f"({n_steps} steps/rev × {microsteps:g} microsteps / rotation_distance = {derived:g}); "
            "give one of them", f"{mw}.steps_per_mm")
    return derived


#: the motor table's plain numbers: key -> (default, lowest, highest, lowest excluded)
_MOTOR_NUMBERS = {
    "force": (DEFAULTS["motor_force"], 0.0, None, True),
    "corner_speed": (DEFAULTS["corner_speed"], 0.0, None, True),
    "rotor_mass": (DEFAULTS["rotor_mass"], 0.0, None, False),
    "friction": (DEFAULTS["friction"], 0.0, None, False),
    "rotor_damping": (DEFAULTS["rotor_damping"], 0.0, 2.0, False),
}


def motor_from_dict(mo: dict, mw: str) -> MotorModel:
    """One motor table (``[motor]`` or an axis's, already merged over ``[motor]``)."""
    refuse_unknown(mo, _MOTOR_KEYS, mw)
    consts = _motor_constants(mo, mw)
    _check_motor_form(mo, consts, mw)
    drive = {k: number(mo, k, mw, lo=0.0, lo_open=True) for k in ("run_current", "voltage", "rotation_distance")
             if k in mo}
    if "rotor_inertia" in mo:
        drive["rotor_inertia"] = number(mo, "rotor_inertia", mw, lo=0.0)
    microsteps = number(mo, "microsteps", mw, DEFAULTS["microsteps"], lo=1.0)
    steps_per_mm = _steps_per_mm(mo, drive, consts.get("steps_per_revolution", 200), microsteps, bool(consts), mw)
    if not consts and "rotor_inertia" in drive:
        raise RingtuneError("rotor_inertia needs the motor (name or datasheet constants); give rotor_mass "
                            "(kg at the belt) instead", f"{mw}.rotor_inertia")
    numbers = {k: number(mo, k, mw, default, lo=lo, hi=hi, lo_open=lo_open)
               for k, (default, lo, hi, lo_open) in _MOTOR_NUMBERS.items()}
    name = mo.get("name")
    return MotorModel(**numbers, steps_per_mm=steps_per_mm, microsteps=microsteps,
                      slip=flag(mo, "slip", mw, None), name=name.strip() if isinstance(name, str) else None,
                      **consts, **drive)
