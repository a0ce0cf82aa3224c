"""The motors' bound on acceleration, rigid machine: the acceleration at which the weakest motor
needs all its force (or keeps a reserve) at a head speed, in the worst direction; the top of the
acceleration search (:func:`accel_ceiling`), and the notes ``tune`` prints about it. Units: mm/s²,
mm/s, N."""

from __future__ import annotations

import math
from typing import Any

import numpy as np


def motor_accel_limit(printer: Any, speed: float, n_dir: int = 181, reserve: float = 0.0) -> tuple[float, str]:
    """(mm/s², motor name): the acceleration at which the weakest motor would need all its force
    while the head moves at ``speed`` (mm/s) in the worst direction, rigid machine.

    Moving along the unit vector u at acceleration a, the axes need the forces m_ax·a·u_ax (moving
    masses, kg, print on the bed included); the motors (``Printer.drive_motors``: drive vectors
    D_k, belt speed per unit head speed) share them by the least-squares inverse P of the drive,
    as the simulation does: motor k gives a·Σ_ax P_ax,k·m_ax·u_ax at the belt, plus its rotor's
    reflected mass m_r·a·(D_k·u) and its friction, at belt speed speed·|D_k·u|, where it has
    ``max_force(speed·|D_k·u|)``. The result is the smallest a over directions (``n_dir`` from 0
    to 180°; diagonals load one CoreXY motor most) and motors at which demand meets force; on pure
    axis moves it equals ``Printer.motor_accel_limit``. ``reserve``: the fraction of the force kept
    free (demand, friction included, meets (1 − reserve)·max_force)."""
    th = np.linspace(0.0, np.pi, n_dir)
    u = np.stack([np.cos(th), np.sin(th)], axis=1)                      # (n, 2)
    motors = printer.drive_motors()
    D = np.array([d for _n, _m, d in motors], float).T                  # (2, k)
    P = np.linalg.pinv(D.T)                                             # (2, k)
    mass = np.array([printer.moving_mass("x"), printer.moving_mass("y")])
    best, who = np.inf, ""
    for k, (name, mo, _d) in enumerate(motors):
        proj = u @ D[:, k]                                              # motor mm per head mm
        per_accel = np.abs(u @ (P[:, k] * mass) + mo.rotor_mass * proj) * 1e-3   # N per mm/s²
        avail = (1.0 - reserve) * np.asarray(mo.max_force(speed * np.abs(proj)), float) - mo.friction
        with np.errstate(divide="ignore", invalid="ignore"):
            a = np.where(per_accel > 1e-12, np.maximum(avail, 0.0) / per_accel, np.inf)
        i = int(np.argmin(a))
        if a[i] < best:
            names = dict(_MOTOR_NAMES, b="B motor (stepper_z)") if printer.kinematics == "corexz" else _MOTOR_NAMES
            best, who = float(a[i]), names.get(name, f"{name} motor")
    return best, who


_MOTOR_NAMES = {"x": "X motor", "y": "Y motor", "a": "A motor (stepper_x)", "b": "B motor (stepper_y)"}


def accel_ceiling(printer: Any, speed: float | None = None) -> tuple[float, str]:
    """(mm/s², basis): the top of the acceleration search — :func:`motor_accel_limit` at ``speed``
    (default the printer's velocity limit).

    The firmware's limits do not cap it: the tuned value is what the user will set as the
    printer's ``max_accel`` (so today's ``limits.accel`` is no bound), and a per-axis cap
    (``limits.max_accel``: Kalico's ``max_x_accel``/``max_y_accel``, Marlin's ``M201 X/Y``) is
    applied by the planner to the moves along that axis, as each trial carries it
    (:func:`trial_axis_caps`); the summary says which caps bind
    (:mod:`ringtune.agents.tune.binding`)."""
    what = "the job's top speed"
    if speed is None:
        what, speed = "the printer's velocity limit", printer.limits.velocity
    v = float(speed)
    a, who = motor_accel_limit(printer, v)
    return a, f"the {who} would need all its force at {v:.0f} mm/s ({what})"


def top_speed_load_note(printer: Any, accel: float, reserve: float) -> str:
    """With no job given (the built-in print stands in for prints that may run at the printer's
    velocity limit): the share of the weakest motor's force the acceleration asks for at that
    speed, rigid machine (:func:`motor_accel_limit`), and whether that keeps the reserve."""
    v = float(printer.limits.velocity)
    limit, who = motor_accel_limit(printer, v)
    load = float(accel) / limit if limit > 0 else math.inf
    kept = ("within the reserve" if load <= 1.0 - reserve else
            f"BEYOND the {reserve * 100:.0f} % reserve: a print that fast at this acceleration may skip steps")
    return (f"At the printer's velocity limit {v:.0f} mm/s (no job given; the built-in print runs slower) "
            f"{accel:.0f} mm/s² asks the {who} for {load * 100:.0f} % of its force there (rigid machine): {kept}.")


#: how the note names one defaulted axis motor where it is not "X motor" / "Y motor": (kinematics, axis) -> name
_ONE_DEFAULT_MOTOR = {("corexz", "x"): "A and B motors (stepper_x, stepper_z)"}


def defaults_note(printer: Any) -> str:
    """One sentence when the motor bound rests on defaults (``Printer.defaulted``: a motor with
    neither a name, datasheet constants nor ``force``; an axis with no ``mass``), else "" (also
    for ``printer`` None)."""
    d = set(getattr(printer, "defaulted", ()))
    motors, masses = ([ax for ax in "xy" if f"{ax}.{kind}" in d] for kind in ("motor", "mass"))
    parts = []
    if motors:
        what = ("motor" if len(motors) == 2 else
                _ONE_DEFAULT_MOTOR.get((printer.kinematics, motors[0]), f"{motors[0].upper()} motor"))
        parts.append(f"the default {what} ({printer.motor_for(motors[0]).force:g} N)")
    if masses:
        kg = ", ".join(f"{ax.upper()} {getattr(printer, ax).mass:g} kg" for ax in masses)
        parts.append(f"default mass{'es' if len(masses) == 2 else ''} ({kg})")
    if not parts:
        return ""
    them = "them" if len(motors) + len(masses) > 1 else "it"
    return (f"The motor bound comes from {' and '.join(parts)}: give {them} (see ringtune identify "
            "--motor/--mass, or ringtune printer from-klipper).")
