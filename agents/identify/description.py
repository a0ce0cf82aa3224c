"""The printer description ``ringtune identify`` writes: measured modes, and everything else from what
the user gave (firmware configuration, motors, masses, kinematics) — or said aloud as a default.

:func:`build_description` assembles the description as a dict in the TOML form of
:mod:`ringtune.envs.printer` plus, per table, the comments that say where each part came from;
:func:`description_toml` writes it. Whatever is still a default is returned in
:attr:`Description.defaults` (one sentence each: what it is and what it decides), printed on stderr
by the command and written at the top of the TOML.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ringtune.envs.added_mass import added_mass, frequency_scale
from ringtune.envs.identify import AxisFit
from ringtune.envs.printer import load_printer
from ringtune.envs.printer_defaults import DEFAULTS
from ringtune.envs.toml_writer import toml_key, toml_value
from ringtune.shaping.errors import RingtuneError

AXES = ("x", "y")
KINEMATICS = ("cartesian", "corexy", "corexz")


@dataclass(frozen=True)
class AddedMass:
    """An axis identified by the added-mass method: ``dm`` kg added moved the dominant mode from
    ``f0`` to ``f1`` Hz; moving mass ``mass`` (kg) and stiffness ``stiffness`` (N/m)."""

    axis: str
    dm: float
    f0: float
    f1: float
    mass: float
    stiffness: float
    mass_error: float = float("nan")     # kg, one standard error from the spectra's scatter

    @classmethod
    def from_fits(cls, base: AxisFit | list[AxisFit], loaded: AxisFit | list[AxisFit], dm: float) -> "AddedMass":
        """From the spectrum fits of the same axis without and with ``dm`` kg (one test each, or
        repeats): the factor by which the added mass moved the whole spectrum
        (:func:`frequency_scale`), applied to the first base fit's dominant mode (largest share) for
        ``f0`` and ``f1``."""
        bases = base if isinstance(base, list) else [base]
        loads = loaded if isinstance(loaded, list) else [loaded]
        axis = bases[0].axis
        if any(f.kind != "psd" for f in bases + loads):
            raise RingtuneError("the added-mass method needs resonance sweeps (TEST_RESONANCES files) "
                                f"of {axis.upper()}, not free-decay captures", "--added-mass")
        f0 = max(bases[0].modes, key=lambda m: m.share).freq
        _same_spectra(bases, loads)
        scale, err = frequency_scale(bases, loads)
        _check_shift(axis, scale, err)
        m, k = added_mass(f0, f0 * scale, dm)
        u = scale ** -2                                  # m = dm/(u − 1): dm/d(ln s) = dm·2u/(u − 1)²
        return cls(axis, dm, f0, f0 * scale, m, k, dm * 2.0 * u / (u - 1.0) ** 2 * err)

    def to_dict(self) -> dict:
        return {"axis": self.axis, "added_mass_kg": self.dm, "f0_hz": self.f0, "f1_hz": self.f1,
                "mass_kg": self.mass, "mass_error_kg": self.mass_error, "stiffness_n_m": self.stiffness}


def _same_spectra(bases: list[AxisFit], loads: list[AxisFit]) -> None:
    """Refuse a loaded test that is one of the unloaded ones (the same file twice, or a copy)."""
    for b in bases:
        for ld in loads:
            if b.y_measured is not None and ld.y_measured is not None and \
                    np.array_equal(b.y_measured, ld.y_measured) and np.array_equal(b.x_measured, ld.x_measured):
                raise RingtuneError(f"axis {b.axis.upper()}: {ld.source} holds the same spectrum as {b.source}: "
                                    "the loaded test must be a new TEST_RESONANCES run with the mass fixed on",
                                    "--added-mass")


#: the resonances must move by more than this many standard errors for the added mass to say anything
SHIFT_RESOLUTION = 3.0


def _check_shift(axis: str, scale: float, err: float) -> None:
    """Refuse a loaded test whose resonances did not move down beyond the measurement's resolution
    (:data:`SHIFT_RESOLUTION` standard errors of ln s): the mass it gives would be noise."""
    shift = -math.log(scale)
    if shift > SHIFT_RESOLUTION * err:
        return
    raise RingtuneError(f"axis {axis.upper()}: with the added mass the resonances moved by {-100 * shift:+.2f} % "
                        f"(± {100 * err:.2f} %, one standard error), not down beyond the measurement's "
                        f"resolution ({SHIFT_RESOLUTION:g} standard errors): the mass did not move with the axis, "
                        "the files are of the same state, or the mass is too small to measure", "--added-mass")


@dataclass
class Description:
    """A printer description in TOML form (``data``), the comments of each table (``comments``,
    key ``""`` for the top), and what is still a default (``defaults``: one sentence each)."""

    data: dict
    comments: dict[str, list[str]] = field(default_factory=dict)
    defaults: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def comment(self, table: str, text: str) -> None:
        self.comments.setdefault(table, []).append(text)


def _round(v: float, digits: int) -> float:
    return float(f"{v:.{digits}g}")


def fitted_modes(fit: AxisFit) -> list[dict]:
    """The modes of a fit as TOML items, largest share first; the last takes what is left so that
    the shares sum to 1 exactly."""
    modes = sorted(fit.modes, key=lambda m: -m.share)
    out = []
    for k, m in enumerate(modes):
        item = {"freq": _round(m.freq, 4), "damping": _round(min(max(m.damping, 0.0), 0.95), 3)}
        if k < len(modes) - 1:
            item["share"] = _round(m.share, 3)
        out.append(item)
    return out


def _base_modes(base) -> tuple[str, dict[str, list[dict]]]:
    p = load_printer(base)
    modes = {}
    for ax in AXES:
        items = [{"freq": _round(m.freq, 4), "damping": _round(m.damping, 3), "share": _round(m.share, 3)}
                 for m in p.axis(ax).modes]
        items[-1].pop("share")
        modes[ax] = items
    return p.name, modes


def _merge(into: dict, new: dict) -> None:
    for k, v in new.items():
        if isinstance(v, dict) and isinstance(into.get(k), dict):
            _merge(into[k], v)
        else:
            into[k] = v


def _has_motor(d: dict, ax: str) -> bool:
    """Does the description name the motor (or give its constants) for ``ax``? (The axis's own
    ``[x.motor]`` when it has one, else ``[motor]``, as :meth:`Printer.motor_for` picks.)"""
    m = d.get(ax, {}).get("motor") or d.get("motor", {})
    return "name" in m or "holding_torque" in m or "force" in m


def build_description(fits: dict[str, AxisFit], *, name: str = "identified", kinematics: str | None = None,
                      base: str | None = None, masses: dict[str, float] | None = None,
                      added: dict[str, AddedMass] | None = None, facts=None,
                      motors: dict[str, dict] | None = None, measurement: dict | None = None) -> Description:
    """The printer description of measured ``fits`` (one per axis) and what the user gave.

    ``masses``: weighed masses by axis (kg); ``added``: added-mass results by axis; ``facts``: a
    firmware configuration's :class:`FirmwareFacts` (``description`` dict in this form, ``notes``,
    ``source``); ``motors``: ``{"all"|"x"|"y": {name, run_current, voltage}}`` from ``--motor``;
    ``measurement``: the ``[measurement]`` table (files and Klipper's recommendation)."""
    desc = Description({"name": name})
    fw, src = (dict(facts.description), Path(facts.source).name) if facts is not None else ({}, None)
    _kinematics(desc, fw.pop("kinematics", None), kinematics, src)
    _configuration(desc, fw, facts)
    _motors(desc, motors or {}, src)
    base_name, base_modes = _base_modes(base)
    added, masses = added or {}, masses or {}
    _default_masses(desc, [_axis(desc, ax, fits.get(ax), (base_name, base_modes[ax]), added.get(ax), masses.get(ax))
                           for ax in AXES])
    if measurement:
        desc.data["measurement"] = measurement
    return desc


def _default_masses(desc: Description, said: list[str | None]) -> None:
    """Say the axes whose mass is still the default (``said``: per axis, the default in words or None)."""
    default_mass = [m for m in said if m]
    if default_mass:
        desc.defaults.append(f"masses: {', '.join(default_mass)} are the defaults (an Ender-3-class machine): "
                             "the motor load and the acceleration headroom come from them (give --mass "
                             "X=KG,Y=KG weighed, or --added-mass KG with a second resonance test)")


def _kinematics(desc: Description, configured: str | None, given: str | None, src: str | None) -> None:
    """``kinematics``: as given (--kinematics), else the configuration's, else cartesian (said)."""
    if given:
        desc.data["kinematics"] = given
        if configured and configured != given:
            desc.notes.append(f"--kinematics {given} replaces {src}'s {configured}")
    elif configured:
        desc.data["kinematics"] = configured
    else:
        desc.data["kinematics"] = "cartesian"
        why = f"no --kinematics, and {src} does not give it" if src else "no --kinematics, no firmware configuration"
        desc.defaults.append(f"kinematics: cartesian is a default ({why}): a CoreXY or CoreXZ is simulated "
                             "with the wrong coupling of its axes and motors")


def _configuration(desc: Description, fw: dict, facts) -> None:
    """Limits, motors and ``[current]`` from the firmware configuration (its axes' modes aside), or
    the default limits (said)."""
    if facts is None:
        desc.defaults.append("limits: the default printer's (accel 3000 mm/s², velocity 300 mm/s, square "
                             "corner velocity 5 mm/s): the print times and the acceleration range of tune come "
                             "from them (give --klipper-config, --marlin or --rrf)")
        return
    d = desc.data
    _merge(d, {k: v for k, v in fw.items() if k not in AXES})
    for ax in AXES:
        if isinstance(fw.get(ax), dict):
            d.setdefault(ax, {}).update({k: v for k, v in fw[ax].items() if k != "modes"})
    desc.comment("", f"limits, motors and the firmware's current shaping from {facts.source}")
    desc.notes += list(facts.notes)


def _motors(desc: Description, motors: dict, src: str | None) -> None:
    """--motor into every motor table (``all``) or an axis's; a motor still unnamed is said."""
    d = desc.data
    for key, spec in motors.items():
        if key == "all":          # every motor table: [motor] and the per-axis ones the configuration has
            targets = [d.setdefault("motor", {})] + [d[ax]["motor"] for ax in AXES if "motor" in d.get(ax, {})]
        else:
            targets = [d.setdefault(key, {}).setdefault("motor", {})]
        for target in targets:
            if "name" in target and target["name"].casefold() != spec["name"].casefold():
                desc.notes.append(f"--motor {spec['name']} replaces {src}'s motor {target['name']}")
            target.update(spec)
    _unnamed_motors(desc)


def _unnamed_motors(desc: Description) -> None:
    """Say which axes still run the default motor."""
    missing = [ax for ax in AXES if not _has_motor(desc.data, ax)]
    if missing:
        which = " and ".join(ax.upper() for ax in missing)
        desc.defaults.append(f"motor ({which}): the default 42-34 stepper ({DEFAULTS['motor_force']:g} N at the "
                             f"belt up to {DEFAULTS['corner_speed']:g} mm/s): the acceleration headroom and the "
                             "motor load come from the default motor (give --motor NAME[:RUN_CURRENT[:VOLTAGE]] "
                             "or a firmware configuration that names it)")


def _axis(desc: Description, ax: str, fit: AxisFit | None, base: tuple[str, list[dict]],
          added: AddedMass | None, weighed: float | None) -> str | None:
    """Axis ``ax``'s table: its fitted modes (else ``base``'s, said) and its mass (weighed, else by
    the added-mass method); the default mass in words when neither gives it."""
    table = desc.data.setdefault(ax, {})
    table["modes"] = _modes(desc, ax, fit, base)
    if added is not None:
        _added_mass(desc, table, added, weighed)
    if weighed is not None:
        table["mass"] = weighed
        desc.comment(ax, f"mass {weighed:g} kg weighed (--mass)")
    # the per-axis tables come last in TOML order: put modes and mass first
    desc.data[ax] = {k: table[k] for k in ("mass", "modes") if k in table} | \
        {k: v for k, v in table.items() if k not in ("mass", "modes")}
    return None if "mass" in table else f"{ax.upper()} {DEFAULTS[f'mass_{ax}']:g} kg"


def _modes(desc: Description, ax: str, fit: AxisFit | None, base: tuple[str, list[dict]]) -> list[dict]:
    """Axis ``ax``'s modes: fitted, else ``base``'s (a default, said); where they came from in its comment."""
    if fit is not None:
        desc.comment(ax, f"modes fitted to {Path(fit.source).name} ({fit.kind}, {fit.method}, r² = {fit.r2:.3f})")
        return fitted_modes(fit)
    base_name, modes = base
    desc.comment(ax, f"not measured: the modes of {base_name}")
    freqs = ", ".join(f"{m['freq']:g} Hz" for m in modes)
    desc.defaults.append(f"{ax.upper()} was not measured: its modes are {base_name}'s ({freqs}); the shaper "
                         f"tuned for {ax.upper()} fits that printer, not yours (measure {ax.upper()} too)")
    return modes


def _added_mass(desc: Description, table: dict, a: AddedMass, weighed: float | None) -> None:
    """The added-mass method's mass, and how it was found, in the axis's table."""
    table["mass"] = _round(a.mass, 4)
    desc.comment(a.axis, f"mass by the added-mass method: {a.dm:g} kg moved the spectrum by ×{a.f1 / a.f0:.4f} "
                         f"(fitted to both spectra), the dominant mode {a.f0:.2f} Hz to {a.f1:.2f} Hz; "
                         f"m = dm/((f0/f1)² − 1) = {a.mass:.3f} ± {a.mass_error:.3f} kg (1 standard error), "
                         f"stiffness k = m·(2π f0)² = {a.stiffness:.4g} N/m")
    if weighed is not None:
        desc.notes.append(f"{a.axis.upper()}: --mass {weighed:g} kg replaces the added-mass "
                          f"estimate {a.mass:.3f} kg")


#: file names that say nothing of the printer (its folder does: ``ender3/printer.cfg``)
_GENERIC_STEMS = {"printer", "config", "configuration", "configuration_adv", "moonraker", "klipper"}


def printer_name(config: str | None, files: list[str]) -> tuple[str, str]:
    """The printer's name when ``--name`` is not given, and whence: the firmware configuration's
    file name stem (its folder's name when the stem is generic, ``ender3/printer.cfg`` ->
    ``ender3``), else the folder of the first accelerometer file, else ``identified``."""
    candidates = []
    if config:
        p = Path(config).resolve()
        if p.stem.casefold() not in _GENERIC_STEMS:
            candidates.append((p.stem, f"the file name of {Path(config).name}"))
        candidates.append((p.parent.name, f"the folder of {Path(config).name}"))
    if files:
        candidates.append((Path(files[0]).resolve().parent.name, f"the folder of {Path(files[0]).name}"))
    for name, whence in candidates:
        if name and name not in ("/", "."):
            return name, whence
    return "identified", "nothing names it"


# -- TOML -------------------------------------------------------------------------------------------

def description_toml(desc: Description, header: list[str] = ()) -> str:
    """TOML text of ``desc``: ``header`` and the defaults as comments at the top, then the top-level
    keys, then each table (sub-tables ``[x.motor]`` after their parent) with its comments."""
    lines = [f"# {h}" for h in header]
    for title, said in (("Still defaults (not known from your files):", desc.defaults),
                        ("Notes (what the configuration does not say, and what was mapped):", desc.notes)):
        if said:
            lines += [f"# {title}"] + [f"#   - {s}" for s in said]
    lines += [f"# {c}" for c in desc.comments.get("", [])]

    def emit(path: str, table: dict) -> None:
        scalars = {k: v for k, v in table.items() if not isinstance(v, dict)}
        subs = {k: v for k, v in table.items() if isinstance(v, dict)}
        if path:
            lines.append("")
            lines.append(f"[{path}]")
            lines.extend(f"# {c}" for c in desc.comments.get(path, []))
        for k, v in scalars.items():
            if isinstance(v, list) and len(v) > 1 and all(isinstance(x, dict) for x in v) and k != "modes":
                lines.append(f"{toml_key(k)} = [")          # one record per line (e.g. the files)
                lines.extend(f"  {toml_value(x)}," for x in v)
                lines.append("]")
            else:
                lines.append(f"{toml_key(k)} = {toml_value(v)}")
        for k, v in subs.items():
            emit(f"{path}.{k}" if path else k, v)

    emit("", desc.data)
    return "\n".join(lines) + "\n"
