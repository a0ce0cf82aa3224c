"""``ringtune recommend --method klipper``: Klipper's calibrate_shaper rule on a resonance test —
measured files, the files a printer description records, what it recorded from them, or the
model's simulated test — as a TuneConfig, with the per-shaper table behind each axis's pick and
where the data came from."""

from __future__ import annotations

from dataclasses import dataclass

from ringtune.agents.identify.accelerometer import recorded_files, resonance_psds
from ringtune.agents.klipper.baseline import klipper_rule_on_simulated_test, recommend_axes
from ringtune.agents.klipper.rule import DEFAULT_DAMPING_RATIO
from ringtune.envs.planned_job import resolve_printer
from ringtune.shaping.config import TuneConfig


def _silent(_message: str) -> None:
    """A ``note`` that says nothing."""


@dataclass
class KlipperPick:
    """Klipper's rule's answer: the TuneConfig, Klipper's per-shaper table per axis
    (``KlipperRecommendation``; empty when only the recorded pick is known) and, per axis, the
    files or description it came from."""

    config: TuneConfig
    fits: dict
    sources: dict[str, list[str]]


def klipper_pick(accel: list | None = None, printer: str | None = None, firmware: str = "klipper",
                 version: str = "head", scv: float = 5.0, max_smoothing: float | None = None, seed: int | None = None,
                 axes: str | None = None, note=_silent) -> KlipperPick:
    """Klipper's rule on the resonance files ``accel`` (axes as :func:`resonance_psds` tells them;
    ``scv`` mm/s), else on ``printer`` (TOML or embedded name, ``"default"`` the embedded printer):
    the files its ``[measurement]`` records when they are all here unchanged, else what it
    recorded from them, else its model's simulated resonance test (its expected spectrum; with ``seed``,
    bins scattered as a measurement's)."""
    if accel:
        psds, sources = resonance_psds(accel, axes, note)
        fits, fields = recommend_axes(psds, firmware, version, scv, max_smoothing=max_smoothing)
    else:
        fits, fields, sources = _from_printer(printer, firmware, version, scv, max_smoothing, seed, note)
    extra = {"method": "klipper", "klipper_version": version, "sources": sources,
             "klipper": {ax: rec.to_dict() for ax, rec in fits.items()}}
    return KlipperPick(TuneConfig(**fields, extra=extra), fits, sources)


def _from_printer(ref, firmware, version, scv, max_smoothing, seed, note):
    """(fits, TuneConfig fields, sources) of Klipper's rule for the printer description ``ref``."""
    printer = resolve_printer(None if ref in (None, "default") else ref)
    recorded = _recorded(printer, ref, note)
    kept = printer.measurement.get("klipper", {})
    if recorded is not None:        # identify recorded the files: their recommendation, not the model's
        psds, sources = resonance_psds([p for p, _ in recorded], ",".join(ax for _, ax in recorded), note)
        fits, fields = recommend_axes(psds, firmware, version, float(kept.get("scv", scv)),
                                      max_smoothing=max_smoothing)
        return fits, fields, sources
    if _kept_answers(kept, firmware, version, max_smoothing):
        return _kept(kept, ref, note)       # the files moved: what identify recorded from them
    if printer.measurement.get("files"):
        note("note: Klipper's rule runs on the model's simulated resonance test instead")
    if printer.measurement.get("source") == "none":
        note(f"note: {printer.name}: its modes were not measured ([measurement] source = \"none\"): Klipper's "
             "rule runs on the simulated test of the embedded Ender-3-class printer's modes; run `ringtune "
             "identify` on your resonance files to measure yours")
    fits, fields = klipper_rule_on_simulated_test(printer, firmware, version, seed, max_smoothing=max_smoothing)
    sources = {ax: [f"printer:{getattr(printer, 'name', 'default')} (simulated resonance test)"]
               for ax in ("x", "y")}
    return fits, fields, sources


def _kept_answers(kept: dict, firmware: str, version: str, max_smoothing) -> bool:
    """Whether the pick a description recorded is the answer asked for (Klipper's, same version,
    no smoothing bound)."""
    return bool(kept) and firmware == "klipper" and version == kept.get("version") and max_smoothing is None


def _kept(kept: dict, ref, note):
    """(no fits, TuneConfig fields, sources) of the pick a description recorded (``[measurement.klipper]``)."""
    note(f"note: the recommendation {ref} recorded from its files ([measurement.klipper]); "
         "without the files there is no per-shaper table")
    fields = {"firmware": "klipper", "accel": kept.get("max_accel")}
    for ax in ("x", "y"):
        fields.update({f"shaper_{ax}": kept.get(f"shaper_{ax}", "none"), f"freq_{ax}": kept.get(f"freq_{ax}", 0.0),
                       f"damping_{ax}": DEFAULT_DAMPING_RATIO})
    sources = {ax: [f"{ref} [measurement.klipper]"] for ax in ("x", "y") if f"shaper_{ax}" in kept}
    return {}, fields, sources


def _recorded(printer, ref, note) -> list[tuple[str, str]] | None:
    """The resonance files ``printer`` records in ``[measurement]`` (written by ``ringtune identify``)
    when they are all still here and unchanged, else None (with a note when some are missing)."""
    if not printer.measurement.get("files"):
        return None
    found, missing = recorded_files(printer.measurement, ref)
    if missing:
        note(f"note: {ref} was identified from {', '.join(missing)}, not found here (or changed)")
        return None
    if not found:                                 # only free-decay captures: no sweep for the rule
        return None
    note(f"note: Klipper's rule on the resonance files {ref} was identified from")
    return found
