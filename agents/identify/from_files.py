"""``ringtune identify`` with an accelerometer: the printer from the user's files — modes fitted to
the resonance files, masses by the added-mass method or as weighed, motors, limits and kinematics
from the firmware configuration — as a printer description (TOML) that loads.

:func:`identify_from_files` is the whole path; what is still a default, and the doubts about the
files, come back as sentences for the command to say.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from ringtune.agents.identify.accelerometer import Measurement, klipper_record, read_measurement
from ringtune.agents.identify.belts import BeltComparison, belts_into_description
from ringtune.agents.identify.description import AddedMass, Description, build_description, description_toml, printer_name
from ringtune.agents.identify.model_check import pick_warnings
from ringtune.envs.printer import printer_from_dict
from ringtune.hardware.klipper_config import printer_facts_from_klipper
from ringtune.hardware.marlin_config import printer_facts_from_marlin
from ringtune.hardware.rrf_config import printer_facts_from_rrf
from ringtune.shaping.errors import RingtuneError

#: the firmware configurations identify reads: parameter -> reader
FACT_READERS = {"klipper_config": printer_facts_from_klipper, "marlin": printer_facts_from_marlin,
                "rrf": printer_facts_from_rrf}
#: square-corner velocity Klipper's rule assumes without a configuration, mm/s
DEFAULT_SCV = 5.0


def _silent(_message: str) -> None:
    """A ``note`` that says nothing."""


@dataclass
class Identified:
    """What identify made of the files: the fits (``measurement``; the ``--added-mass`` files'
    in ``loaded_fits``), the added-mass results per axis, Klipper's pick from the files (with the
    square-corner velocity it assumed, mm/s), the description and its TOML, and the doubts about
    the files (``warnings``)."""

    measurement: Measurement
    loaded_fits: list
    added: dict[str, AddedMass]
    klipper: dict
    scv: float
    description: Description
    toml: str
    warnings: list[str] = field(default_factory=list)
    belts: BeltComparison | None = None     # with belt tests: the two belts compared


def identify_from_files(files: list, *, configs: dict | None = None, axis: str | None = None, max_modes: int = 3,
                        fmin: float = 5.0, fmax: float = 135.0, damping: str = "fit", kinematics: str | None = None,
                        base=None, masses: dict | None = None, motors: dict | None = None,
                        added_mass: dict | None = None, loaded_files: list = (), name: str | None = None,
                        facts=None, belts: list | None = None, note=_silent) -> Identified:
    """The printer from the accelerometer ``files`` and, in ``configs`` ({``klipper_config`` |
    ``marlin`` | ``rrf``: path}), its firmware configuration; ``masses`` ({axis: kg}), ``motors``
    ({axis or "all": {name, run_current, voltage}}), ``added_mass`` ({axis or "all": kg}) with the
    ``loaded_files`` measured with it. Fit bounds ``fmin``/``fmax`` Hz, at most ``max_modes`` per
    axis. ``facts``: the configuration's FirmwareFacts already read (e.g. through Moonraker);
    ``belts``: a CoreXY's two diagonal resonance tests (``[belts] mismatch``). The name, when not
    given, from the configuration's or the files' folder (said through ``note``)."""
    read, config_path = read_facts(configs or {})
    facts = facts if facts is not None else read
    kw = dict(axis=axis, max_modes=max_modes, fmin=fmin, fmax=fmax, damping=damping)
    meas = read_measurement(files, **kw)
    warnings = list(meas.warnings)
    loaded, added = None, {}
    if loaded_files:
        loaded = read_measurement(loaded_files, **kw)
        warnings += loaded.warnings
        added = added_masses(meas, loaded, added_mass or {}, warnings)
    scv = DEFAULT_SCV if facts is None else float(
        facts.description.get("limits", {}).get("square_corner_velocity", DEFAULT_SCV))
    klipper = klipper_record(meas.psds, scv)
    if name is None:
        name, whence = printer_name(config_path, files)
        note(f"note: name {name!r}, from {whence} (give --name to choose another)")
    desc = build_description(meas.by_axis(), name=name, kinematics=kinematics, base=base, masses=masses,
                             added=added, facts=facts, motors=motors,
                             measurement=_measurement(meas, loaded, added, klipper))
    header = ["Printer description written by `ringtune identify` from "
              + ", ".join(Path(f).name for f in [*files, *loaded_files])]
    compared = _checked(desc, header, belts, (klipper, meas, warnings))
    return Identified(meas, loaded.fits if loaded else [], added, klipper, scv, desc,
                      description_toml(desc, header), warnings, compared)


def read_facts(configs: dict) -> tuple:
    """(FirmwareFacts, its path) of the configuration given in ``configs`` ({``klipper_config`` |
    ``marlin`` | ``rrf``: path or None}), else (None, None)."""
    for key, path in configs.items():
        if path:
            return FACT_READERS[key](path), path
    return None, None


def added_masses(meas: Measurement, loaded: Measurement, dm: dict, warnings: list[str]) -> dict[str, AddedMass]:
    """{axis: AddedMass} from the tests without and with ``dm`` ({axis or "all": kg}); a doubt
    about an uncertain estimate is appended to ``warnings``."""
    added = {ax: _added_mass(ax, meas, loaded, dm) for ax in loaded.by_axis()}
    for ax, a in added.items():
        if not a.mass_error <= 0.05 * a.mass:
            warnings.append(f"{ax.upper()}: the added-mass estimate {a.mass:.3f} kg is uncertain by "
                            f"±{a.mass_error:.3f} kg (one standard error from the spectra's scatter): "
                            "repeat both tests and give every file (repeats are fitted together), or add more mass (the error falls as the frequencies "
                            "move further apart)")
    unused = [ax.upper() for ax in dm if ax != "all" and ax not in added]
    if unused:
        raise RingtuneError(f"no loaded file of {', '.join(unused)}", "added_mass")
    return added


def _added_mass(ax: str, meas: Measurement, loaded: Measurement, dm: dict) -> AddedMass:
    """Axis ``ax`` by the added-mass method: every base fit of it (best first) against the loaded ones."""
    fits = meas.by_axis()
    if ax not in fits:
        raise RingtuneError(f"the loaded test measured {ax.upper()} but the base files did not", "added_mass")
    mass = dm.get(ax, dm.get("all"))
    if mass is None:
        raise RingtuneError(f"no added mass given for {ax.upper()}", "added_mass")
    repeats = [f for f in meas.fits if f.axis == ax and f is not fits[ax]]     # best fit first
    return AddedMass.from_fits([fits[ax], *repeats], [f for f in loaded.fits if f.axis == ax], mass)


def _measurement(meas: Measurement, loaded: Measurement | None, added: dict, klipper: dict) -> dict:
    """The description's ``[measurement]``: the files (name, SHA-256, axis, kind), the added-mass
    files with their mass, and Klipper's pick from them."""
    out = {"source": "accelerometer",
           "files": [{k: f[k] for k in ("name", "sha256", "axis", "kind") if k in f} for f in meas.files]}
    if added:
        out["added_mass_files"] = [{k: f[k] for k in ("name", "sha256", "axis")}
                                   | {"added_mass_kg": added[f["axis"]].dm}
                                   for f in loaded.files if f["axis"] in added]
    if klipper:
        out["klipper"] = klipper
    return out


def _checked(desc: Description, header: list[str], belts: list | None, pick: tuple) -> BeltComparison | None:
    """Load the description (it must: checked before anything is written), write the belt
    comparison into it (``belts``: the two diagonal tests), warn where the model does not give
    back the files' Klipper pick (``pick``: the pick, the measurement, the warnings to add to) and
    add to its defaults what a named motor's drive still assumes; the belt comparison, or None."""
    printer = _loaded(desc, header)
    compared = None
    if belts:
        compared = belts_into_description(desc, printer, belts)
        printer = _loaded(desc, header)
    klipper, meas, warnings = pick
    for w in pick_warnings(printer, klipper, meas.psds, meas.by_axis()):   # does the model give back the pick?
        warnings.append(w)
        desc.comment("measurement", w)
    for ax in ("x", "y"):
        for sentence in printer.motor_for(ax).assumed:
            said = f"motor: {sentence}"
            if said not in desc.defaults:
                desc.defaults.append(said)
    return compared


def _loaded(desc: Description, header: list[str]):
    """The Printer the description loads as."""
    return printer_from_dict(tomllib.loads(description_toml(desc, header)), "the identified printer")
