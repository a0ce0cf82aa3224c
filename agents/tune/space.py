"""The tuning search space: what ``tune`` (Optuna), ``grid`` and the reports vary, per firmware.

Parameters (Optuna names):

- ``shaper`` (RepRapFirmware: one shaper for all axes) or ``shaper_x``, ``shaper_y``: the shaper
  types the target firmware offers (``none`` included; RRF ``custom`` excluded);
- ``freq`` (RRF) or ``freq_x``, ``freq_y``: shaper frequency F, Hz, around the printer's modes;
- ``damping``: shaper damping ratio S (one for all axes), within every offered shaper's limit;
- ``freq_limit``: ``off`` or a frequency-limit method (``nophead``, ``sections``, ``marlin``), and
  ``freq_limit_hz`` (Hz, only when on);
- ``accel``: printing acceleration, mm/s², in steps of ``accel_step``.

:func:`config_from_params` turns a parameter dict into a :class:`TuneConfig`; the same function
serves Optuna trials, grid points and stored trials, so they can never disagree.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from ringtune.shaping.config import FREQ_LIMIT_METHODS, TuneConfig
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.firmware import FIRMWARES
from ringtune.shaping.shapers import available_shapers, max_damping


@dataclass(frozen=True)
class SearchSpace:
    """Ranges of one study (units: Hz, mm/s²)."""

    firmware: str
    shapers: tuple[str, ...]
    per_axis: bool
    freq_x: tuple[float, float]
    freq_y: tuple[float, float]
    damping: tuple[float, float]
    freq_limit_methods: tuple[str, ...]
    freq_limit_hz: tuple[float, float]
    accel: tuple[float, float]
    accel_step: float = 100.0
    freq_step: float = 0.1
    min_speed_factor: float = 0.3
    accel_basis: str = ""               # what sets the acceleration range's top (for the summary)

    @property
    def accel_fixed(self) -> bool:
        """The acceleration is not searched (one value: it has no effect, or the user fixed it)."""
        return self.accel[0] == self.accel[1]

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "SearchSpace":
        kw = dict(d)
        for k in ("shapers", "freq_limit_methods"):
            kw[k] = tuple(kw[k])
        for k in ("freq_x", "freq_y", "damping", "freq_limit_hz", "accel"):
            kw[k] = tuple(float(v) for v in kw[k])
        return cls(**kw)


def default_space(printer: Any, firmware: str = "klipper", *, accel: tuple[float, float] | None = None,
                  shapers: tuple[str, ...] | None = None, speed: float | None = None) -> SearchSpace:
    """The default space for ``printer`` on ``firmware``.

    F spans 0.6×–1.8× the axis's lowest/highest mode (clipped to 10–200 Hz); S 0–0.2 (capped
    by the offered shapers' limits); frequency limit 10–80 Hz with every method; acceleration
    from 0.3× the printer's own limit up to :func:`accel_ceiling` at the job's top speed
    ``speed`` (mm/s; default the printer's velocity limit): where the weakest motor would need all
    its force (the firmware's limits are no bound: see there). ``accel`` = (lo, hi) overrides it
    (lo = hi: the acceleration is not searched).
    """
    if firmware not in FIRMWARES:
        raise RingtuneError(f"firmware must be one of {', '.join(FIRMWARES)}, not {firmware!r}", "firmware")
    flavor = FIRMWARES[firmware].flavor
    offered = tuple(n for n in available_shapers(flavor) if n != "custom")
    if shapers:
        bad = [s for s in shapers if s not in offered]
        if bad:
            raise RingtuneError(f"{firmware} does not offer {', '.join(bad)} (offers {', '.join(offered)})",
                                "shapers")
        offered = tuple(shapers)
    zmax = min([0.2] + [max_damping(n, flavor) for n in offered if n != "none"])
    ranges = {}
    for ax in ("x", "y"):
        freqs = [m.freq for m in getattr(printer, ax).modes] or [40.0]
        lo = max(10.0, round(0.6 * min(freqs), 1))
        hi = min(200.0, round(1.8 * max(freqs), 1))
        ranges[ax] = (lo, hi)
    per_axis = not FIRMWARES[firmware].one_shaper
    if not per_axis:
        ranges["x"] = ranges["y"] = (min(ranges["x"][0], ranges["y"][0]), max(ranges["x"][1], ranges["y"][1]))
    if accel is not None:
        acc, basis = accel, "--accel-range"
    else:
        top, basis = accel_ceiling(printer, speed)
        hi = max(100.0, math.floor(top / 100.0) * 100.0)
        lo = min(max(100.0, round(0.3 * float(printer.limits.accel), -2)), max(100.0, round(hi / 3.0, -2)))
        acc = (lo, hi)
    if not (0 < acc[0] <= acc[1]):
        raise RingtuneError(f"acceleration range must be 0 < lo ≤ hi, not {acc}", "accel")
    return SearchSpace(firmware=firmware, shapers=offered, per_axis=per_axis, freq_x=ranges["x"],
                       freq_y=ranges["y"], damping=(0.0, float(zmax)), freq_limit_methods=FREQ_LIMIT_METHODS,
                       freq_limit_hz=(10.0, 80.0), accel=(float(acc[0]), float(acc[1])), accel_basis=basis)


def motor_accel_limit(printer: Any, speed: float, n_dir: int = 181) -> tuple[float, str]:
    """(mm/s², motor name): the acceleration at which the weakest motor would need all its force
    while the head moves at ``speed`` (mm/s) in the worst direction, rigid machine.

    Moving along the unit vector u at acceleration a, the axes need the forces m_ax·a·u_ax (moving
    masses, kg, print on the bed included); the motors (``Printer.drive_motors``: drive vectors
    D_k, belt speed per unit head speed) share them by the least-squares inverse P of the drive,
    as the simulation does: motor k gives a·Σ_ax P_ax,k·m_ax·u_ax at the belt, plus its rotor's
    reflected mass m_r·a·(D_k·u) and its friction, at belt speed speed·|D_k·u|, where it has
    ``max_force(speed·|D_k·u|)``. The result is the smallest a over directions (``n_dir`` from 0
    to 180°; diagonals load one CoreXY motor most) and motors at which demand meets force; on pure
    axis moves it equals ``Printer.motor_accel_limit``."""
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
        avail = np.asarray(mo.max_force(speed * np.abs(proj)), float) - mo.friction
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
    (``limits.max_accel``: Klipper's ``max_x_accel``/``max_y_accel``, Marlin's ``M201 X/Y``) is
    applied by the planner to the moves along that axis, in every trial alike
    (:func:`axis_cap_notes`)."""
    v = float(speed if speed is not None else printer.limits.velocity)
    a, who = motor_accel_limit(printer, v)
    return a, f"the {who} would need all its force at {v:.0f} mm/s (the job's top speed)"


def axis_cap_notes(printer: Any) -> list[str]:
    """One sentence per X/Y cap of the printer's own (``limits.max_accel``), named as its firmware
    writes it: it limits the moves along that axis, not the tuned acceleration."""
    caps = tuple(printer.limits.max_accel or ())[:2]
    fw = str((getattr(printer, "current", None) or {}).get("firmware", "")).lower()
    out = []
    for ax, cap in zip("xy", caps):
        if not cap or cap <= 0:
            continue
        name = (f"max_{ax}_accel" if fw == "klipper" else f"M201 {ax.upper()}" if fw
                else f"[limits] max_accel's {ax.upper()} entry")
        out.append(f"{ax.upper()}'s own cap {name} {cap:.0f} mm/s² applies to {ax.upper()} moves (the planner keeps "
                   f"each move's {ax.upper()} acceleration under it, in every trial and baseline alike); it does not "
                   "cap the tuned acceleration.")
    return out


def defaults_note(printer: Any) -> str:
    """One sentence when the motor bound rests on defaults (``Printer.defaulted``: a motor with
    neither a name, datasheet constants nor ``force``; an axis with no ``mass``), else ""."""
    d = set(getattr(printer, "defaulted", ()) or ())
    motors = [ax for ax in "xy" if f"{ax}.motor" in d]
    masses = [ax for ax in "xy" if f"{ax}.mass" in d]
    if not motors and not masses:
        return ""
    parts = []
    if motors:
        force = printer.motor_for(motors[0]).force
        if len(motors) == 2:
            parts.append(f"the default motor ({force:g} N)")
        else:
            names = dict(_MOTOR_NAMES) if printer.kinematics == "corexy" else {"x": "X motor", "y": "Y motor"}
            if printer.kinematics == "corexz":
                names["x"] = "A and B motors (stepper_x, stepper_z)"
            parts.append(f"the default {names.get(motors[0], motors[0])} ({force:g} N)")
    if masses:
        kg = ", ".join(f"{ax.upper()} {getattr(printer, ax).mass:g} kg" for ax in masses)
        parts.append(f"default mass{'es' if len(masses) == 2 else ''} ({kg})")
    them = "them" if len(motors) + len(masses) > 1 else "it"
    return (f"The motor bound comes from {' and '.join(parts)}: give {them} (see ringtune identify "
            "--motor/--mass, or ringtune printer from-klipper).")


def suggest_params(trial: Any, space: SearchSpace) -> dict[str, Any]:
    """Ask an Optuna trial for one point of ``space`` (returns the parameter dict)."""
    p: dict[str, Any] = {}
    if space.per_axis:
        p["shaper_x"] = trial.suggest_categorical("shaper_x", list(space.shapers))
        p["shaper_y"] = trial.suggest_categorical("shaper_y", list(space.shapers))
        for ax in ("x", "y"):
            if p[f"shaper_{ax}"] != "none":
                lo, hi = getattr(space, f"freq_{ax}")
                p[f"freq_{ax}"] = trial.suggest_float(f"freq_{ax}", lo, hi)
    else:
        p["shaper"] = trial.suggest_categorical("shaper", list(space.shapers))
        if p["shaper"] != "none":
            p["freq"] = trial.suggest_float("freq", *space.freq_x)
    if any(v != "none" for k, v in p.items() if k.startswith("shaper")):
        p["damping"] = trial.suggest_float("damping", *space.damping)
    p["freq_limit"] = trial.suggest_categorical("freq_limit", ["off", *space.freq_limit_methods])
    if p["freq_limit"] != "off":
        p["freq_limit_hz"] = trial.suggest_float("freq_limit_hz", *space.freq_limit_hz)
    if space.accel_fixed:
        p["accel"] = space.accel[0]      # not searched: it has no effect (or was fixed)
    else:
        p["accel"] = trial.suggest_float("accel", *space.accel)
    return p


def _q(value: float, step: float) -> float:
    return round(round(float(value) / step) * step, 6)


def config_from_params(params: dict[str, Any], space: SearchSpace, extra: dict | None = None) -> TuneConfig:
    """The TuneConfig of a parameter dict (from a trial, a grid point or storage).

    Values are rounded to what a user would type and a firmware keeps: F to ``freq_step``
    (0.1 Hz), S to 0.005, the frequency limit to 0.5 Hz, acceleration to ``accel_step``. (Optuna
    samples them continuously: TPE's discrete kernels cost far more per trial.)"""
    if space.per_axis:
        sx, sy = params["shaper_x"], params["shaper_y"]
        fx, fy = params.get("freq_x", 0.0), params.get("freq_y", 0.0)
    else:
        sx = sy = params["shaper"]
        fx = fy = params.get("freq", 0.0)
    fx, fy = _q(fx, space.freq_step), _q(fy, space.freq_step)
    z = _q(params.get("damping", 0.1), 0.005)
    method = params.get("freq_limit", "off")
    return TuneConfig(firmware=space.firmware, shaper_x=sx, shaper_y=sy, freq_x=float(fx), freq_y=float(fy),
                      damping_x=z, damping_y=z,
                      freq_limit_hz=0.0 if method == "off" else _q(params["freq_limit_hz"], 0.5),
                      freq_limit_method="sections" if method == "off" else method,
                      min_speed_factor=space.min_speed_factor,
                      accel=_q(params.get("accel", space.accel[0]) if not space.accel_fixed else space.accel[0],
                               space.accel_step),
                      extra=dict(extra or {}))


def params_from_config(config: TuneConfig, space: SearchSpace) -> dict[str, Any]:
    """Inverse of :func:`config_from_params` (for enqueuing a known configuration)."""
    p: dict[str, Any] = {}
    if space.per_axis:
        for ax in ("x", "y"):
            p[f"shaper_{ax}"] = getattr(config, f"shaper_{ax}")
            if p[f"shaper_{ax}"] != "none":
                p[f"freq_{ax}"] = getattr(config, f"freq_{ax}")
    else:
        p["shaper"] = config.shaper_x
        if config.shaper_x != "none":
            p["freq"] = config.freq_x
    if config.shaper_x != "none" or config.shaper_y != "none":
        p["damping"] = config.damping_x
    p["freq_limit"] = "off" if config.freq_limit_hz <= 0 else config.freq_limit_method
    if config.freq_limit_hz > 0:
        p["freq_limit_hz"] = config.freq_limit_hz
    if not space.accel_fixed:
        p["accel"] = config.accel
    return p


def grid_params(space: SearchSpace, n_freq: int = 9, n_damping: int = 3, n_accel: int = 6,
                freq_limits: tuple[float, ...] = (), shapers: tuple[str, ...] | None = None,
                dampings: tuple[float, ...] | None = None, accels: tuple[float, ...] | None = None) -> list[dict]:
    """A dense Cartesian grid over ``space`` (parameter dicts), for convergence checks.

    Per axis: every shaper × ``n_freq`` frequencies (``none`` once); S on ``n_damping`` levels;
    acceleration on ``n_accel`` levels (multiples of ``accel_step``); the frequency limit off plus
    each method at each of ``freq_limits`` Hz. ``dampings`` / ``accels`` give explicit levels instead.
    """
    shapers = shapers or space.shapers

    def axis_options(lo_hi, key_s, key_f):
        opts = []
        for s in shapers:
            if s == "none":
                opts.append({key_s: "none"})
            else:
                for f in np.linspace(lo_hi[0], lo_hi[1], n_freq):
                    opts.append({key_s: s, key_f: round(float(f), 1)})
        return opts

    if space.per_axis:
        shaping = [{**a, **b} for a in axis_options(space.freq_x, "shaper_x", "freq_x")
                   for b in axis_options(space.freq_y, "shaper_y", "freq_y")]
    else:
        shaping = axis_options(space.freq_x, "shaper", "freq")
    if dampings is None:
        dampings = [round(float(z), 3) for z in np.linspace(space.damping[0], space.damping[1], n_damping)]
    step = space.accel_step
    if accels is None:
        accels = np.linspace(space.accel[0], space.accel[1], n_accel)
    accels = sorted({round(float(a) / step) * step for a in accels})
    limits = [{"freq_limit": "off"}] + [{"freq_limit": m, "freq_limit_hz": float(h)}
                                         for m in space.freq_limit_methods for h in freq_limits]
    out = []
    for sh in shaping:
        any_on = any(v != "none" for k, v in sh.items() if k.startswith("shaper"))
        for z in (dampings if any_on else [None]):
            for lim in limits:
                for a in accels:
                    p = dict(sh)
                    if z is not None:
                        p["damping"] = z
                    p.update(lim)
                    p["accel"] = a
                    out.append(p)
    return out
