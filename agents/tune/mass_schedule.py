"""Schedules by printed mass: a bed slinger's Y shaper frequency (and, where quality needs it, the
acceleration) per band of layers, following the Y mode down as the print's mass grows on the bed.

Per layer the mass on the bed halfway through it (the job's extruded filament, its diameter and
density stated), the model's dominant Y mode at that mass (:mod:`ringtune.envs.bed_load`). A band
runs while the mode stays within ``step`` (a fraction, 2 % by default) of the mode where the band
started; its frequency is the tuned ``freq_y`` moved with the mode, ``freq_y·f(m)/f(0)`` at the
band's middle mass m (the tuned frequency keeps its place among the modes; a config that targets the
mode gets the mode). A lower shaper frequency smooths corners more at the same acceleration (the
visible corners round off): with ``band_accel="auto"`` a band whose shaper would smooth more than
:data:`SMOOTHING_TOLERANCE` beyond the tuned one (Klipper's smoothing estimate,
:func:`ringtune.shaping.analysis.smoothing`) gets the acceleration at which it smooths as the tuned
one does — and since that estimate leaves out the nozzle's own lag on the heavier bed,
:func:`ringtune.agents.tune.mass_check.schedule_job` simulates the last band's corners and holds
every band to the largest share of the tuned smoothing
(:data:`ringtune.agents.tune.mass_check.SMOOTHING_TARGETS`) at which they round no more than the
fixed frequency's; ``"keep"`` leaves the acceleration alone. The words: :mod:`ringtune.agents.tune.mass_report`.

What a fixed frequency costs (the job's last band simulated at the tuned and at the schedule's
frequency) is measured in :mod:`ringtune.agents.tune.mass_check`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ringtune.agents.tune.pareto import DEFAULT_RESOLUTION
from ringtune.agents.tune.space import freq_floor
from ringtune.envs.bed_load import dominant_y_mode, is_bed_slinger
from ringtune.envs.planned_job import job_accel_commands, resolve_job, resolve_printer
from ringtune.envs.printer_model import Printer
from ringtune.hardware.dialects import shaper_commands
from ringtune.shaping.analysis import max_accel, residual_vibration, smoothing
from ringtune.shaping.builtin_jobs import job_path
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.config_plan import for_firmware
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.firmware import FIRMWARES
from ringtune.shaping.gcode import read_gcode
from ringtune.shaping.gcode_file import read_gcode_bytes
from ringtune.shaping.job_shapers import overriding
from ringtune.shaping.layer_commands import PRUSA_WEIGHT_ADJUST, TAG, prusa_weight_frequency, schedule_inserts
from ringtune.shaping.layers import FILAMENT_DENSITY_G_CM3, FILAMENT_DIAMETER_MM, Layer, job_layers
from ringtune.shaping.rewrite import rewrite_job, shapers_to_replace
from ringtune.shaping.slicer import slicer_filament
from ringtune.shaping.shapers import get_shaper

#: a new band starts when the Y mode has moved this fraction from where the band started
BAND_STEP = 0.02
#: a band's shaper may smooth this fraction more than the tuned one before its acceleration is
#: lowered: the relative resolution at which tune calls two distances the same
SMOOTHING_TOLERANCE = DEFAULT_RESOLUTION.distance_rel
#: how a band's acceleration is chosen
BAND_ACCEL = ("auto", "keep")


@dataclass
class Band:
    """Layers ``first_layer``..``last_layer`` (from ``z_mm``), ``mass_kg`` of print on the bed at
    the band's middle, the model's dominant Y mode there (``mode_hz``), the chosen ``freq_y`` (Hz),
    ``accel`` (mm/s², None = unchanged), ``grams`` on the bed in all (with the printer's own
    print_mass), what Prusa's linear rule sets from ``M74 W`` with the schedule's ``M593 A M``
    (``prusa_hz``) and with its defaults (``prusa_default_hz``), and the firmware lines inserted
    where the band begins."""

    first_layer: int
    last_layer: int
    z_mm: float
    mass_kg: float
    mode_hz: float
    freq_y: float
    accel: float | None
    grams: float
    commands: list[str] = field(default_factory=list)
    prusa_hz: float = float("nan")
    prusa_default_hz: float = float("nan")

    def to_dict(self) -> dict:
        return {"first_layer": self.first_layer, "last_layer": self.last_layer, "z_mm": self.z_mm,
                "mass_g": self.mass_kg * 1e3, "mode_hz": self.mode_hz, "freq_y": self.freq_y,
                "accel": self.accel, "prusa_rule_hz": self.prusa_hz, "prusa_default_rule_hz": self.prusa_default_hz,
                "commands": self.commands}


@dataclass
class MassSchedule:
    """The schedule of one job on one printer: bands, layers, filament, the config it starts from."""

    config: TuneConfig
    bands: list[Band]
    layers: list[Layer]
    diameter_mm: float
    density_g_cm3: float
    #: where each filament figure came from: "given", "the job's" (its slicer's header) or "default"
    filament_source: dict[str, str]
    empty_mode_hz: float
    step: float
    final_mode_hz: float
    notes: list[str] = field(default_factory=list)
    ripple: dict | None = None

    @property
    def needed(self) -> bool:
        """Whether the mode moves more than the band step over the job (more than one band)."""
        return len(self.bands) > 1

    @property
    def total_kg(self) -> float:
        last = self.layers[-1]
        return last.mass_before + last.mass

    def y_schedule(self) -> list[dict[str, float]] | None:
        """The TuneConfig ``y_schedule`` entries (None: one band, the tuned frequency holds)."""
        if not self.needed:
            return None
        return [{"z_mm": b.z_mm, "freq_y": b.freq_y, **({"accel": b.accel} if b.accel else {}),
                 "mass_g": round(b.grams, 3)} for b in self.bands]

    def scheduled_config(self) -> TuneConfig:
        return replace(self.config, y_schedule=self.y_schedule(), extra=dict(self.config.extra))

    def inserts(self) -> dict[int, list[str]]:
        """{layer index: lines} where each band begins (:func:`schedule_inserts` of the scheduled
        config: what any tool reading its ``y_schedule`` writes)."""
        return schedule_inserts([la.z for la in self.layers], self.scheduled_config())

    def to_dict(self) -> dict:
        return {"firmware": self.config.firmware, "filament_diameter_mm": self.diameter_mm,
                "filament_density_g_cm3": self.density_g_cm3, "filament_source": dict(self.filament_source),
                "print_mass_g": self.total_kg * 1e3,
                "layers": len(self.layers), "empty_mode_hz": self.empty_mode_hz,
                "final_mode_hz": self.final_mode_hz, "scheduled": self.needed,
                "tuned_freq_y": self.config.freq_y, "band_step": self.step,
                "bands": [b.to_dict() for b in self.bands], "y_schedule": self.y_schedule(),
                "last_band": self.ripple, "notes": list(self.notes)}


def _band_ranges(modes: np.ndarray, step: float) -> list[tuple[int, int]]:
    """(first, last) layer of each band: a band ends before the layer whose mode has moved more
    than ``step`` from the band's first layer's."""
    out, a = [], 0
    for j in range(1, len(modes)):
        if abs(modes[j] / modes[a] - 1.0) > step:
            out.append((a, j - 1))
            a = j
    out.append((a, len(modes) - 1))
    return out


def accel_at_band_frequency(config: TuneConfig, printer: Printer, freq_y: float, factor: float = 1.0) -> float | None:
    """mm/s² at which Y's shaper at ``freq_y`` smooths ``factor`` × as much as the tuned one at the
    tuned acceleration (Klipper's smoothing estimate, rounded down to 10; on a firmware with one
    shaper, as the smoother of the tuned X and Y), or None when at the tuned acceleration it smooths
    no more than :data:`SMOOTHING_TOLERANCE` beyond that."""
    accel = config.accel or printer.limits.accel
    scv = printer.limits.square_corner_velocity
    name, f0, z = config.axis("y")
    band = get_shaper(name, freq_y, z, config.flavor)
    target = smoothing(get_shaper(name, f0, z, config.flavor), accel, scv)
    if FIRMWARES[config.firmware].one_shaper:      # the band's shaper is X's too: keep X's smoothing
        nx, fx, zx = config.axis("x")
        target = min(target, smoothing(get_shaper(nx, fx, zx, config.flavor), accel, scv))
    target *= factor
    if smoothing(band, accel, scv) <= target * (1.0 + SMOOTHING_TOLERANCE):
        return None
    return float(min(accel, np.floor(max_accel(band, scv, target) / 10.0) * 10.0))


def _x_cost(config: TuneConfig, printer: Printer, freq: float) -> tuple[float, float]:
    """(tuned, at ``freq``): X's residual vibration (share-weighted, % of unshaped) when the one
    shaper of RepRapFirmware runs at ``freq`` instead of the tuned frequency."""
    name, fx, z = config.axis("x")
    modes = printer.effective_modes("x")
    w = np.array([abs(m.share) for m in modes])
    fm = np.array([m.freq for m in modes])
    zm = [m.damping for m in modes]

    def rv(f: float) -> float:
        sh = get_shaper(name, f, z, config.flavor)
        return float(sum(wi * residual_vibration(sh, [fi], zi)[0] for wi, fi, zi in zip(w, fm, zm)) / w.sum() * 100)
    return rv(fx), rv(freq)


def filament(job, diameter_mm: float | None = None, density_g_cm3: float | None = None
             ) -> tuple[float, float, dict[str, str]]:
    """(diameter mm, density g/cm³, where each came from): as given, else what the job's slicer wrote
    into it (:func:`ringtune.shaping.slicer.slicer_filament`), else 1.75 mm of PLA."""
    own = slicer_filament(job) if isinstance(job, (str, Path)) and "\n" not in str(job) else {}
    out, source = [], {}
    for key, given, default in (("diameter_mm", diameter_mm, FILAMENT_DIAMETER_MM),
                                ("density_g_cm3", density_g_cm3, FILAMENT_DENSITY_G_CM3)):
        v, where = ((given, "given") if given is not None else (own[key], "the job's") if key in own
                    else (default, "default"))
        out.append(float(v))
        source[key] = where
    return out[0], out[1], source


def mass_schedule(config: TuneConfig, printer=None, job=None, *, diameter_mm: float | None = None,
                  density_g_cm3: float | None = None, step: float = BAND_STEP,
                  band_accel: str = "auto", smoothing_factor: float = 1.0,
                  min_freq: float | None = None) -> MassSchedule:
    """The Y schedule of ``job`` (path, text, Job, a built-in job's name; None: the built-in print)
    on ``printer``, starting from ``config`` (tuned with the printer's own ``print_mass`` on the
    bed); the filament as given, else the job's own, else PLA (:func:`filament`);
    ``smoothing_factor``: the bands' accelerations hold their smoothing to this fraction of the
    tuned one (``band_accel="auto"``); ``min_freq``: the build's lowest shaper frequency, Hz (None:
    the firmware's stock build, :func:`ringtune.agents.tune.space.freq_floor`)."""
    printer, job = resolve_printer(printer), job_path(job)
    _refuse(config, printer, step, band_accel)
    _, parsed = resolve_job(job, for_firmware(printer.limits, config))
    diameter_mm, density_g_cm3, source = filament(job, diameter_mm, density_g_cm3)
    layers = job_layers(parsed, diameter_mm, density_g_cm3)
    f_empty = dominant_y_mode(printer).freq
    modes = np.array([dominant_y_mode(printer, la.mass_during).freq for la in layers])
    lowest = freq_floor(config.firmware, min_freq)
    smoothing = smoothing_factor if band_accel == "auto" else None
    bands, clamped = [], []
    for a, b in _band_ranges(modes, step):
        band, held = _band(config, printer, layers, a, b, f_empty, lowest, smoothing)
        bands.append(band)
        if held:
            clamped.append(a)
    notes = [_clamp_note(config, clamped, lowest, min_freq)] if clamped else []
    sched = MassSchedule(config, bands, layers, diameter_mm, density_g_cm3, source, f_empty, step, float(modes[-1]),
                         notes)
    inserts = sched.inserts()
    for b in bands:
        b.commands = inserts.get(b.first_layer, [])
    _prusa_rule(config, bands)
    if not sched.needed:
        return sched
    notes.extend(_firmware_notes(config, printer, bands))
    own = overriding(parsed, config)
    if own:
        notes.append(f"the job sets its own input shaper (line {own[0].line}: {own[0].text or own[0].command}"
                     f"{f', and {len(own) - 1} more' if len(own) > 1 else ''}), which would move the printer off "
                     "the tuned one while it prints: the job written (-o) has the tuned shaper's command in place "
                     "of each (an earlier schedule's band lines aside), so its bands move the tuned shaper")
    if any(b.accel for b in bands) and job_accel_commands(parsed, for_firmware(printer.limits, config)):
        notes.append("the job sets its own accelerations (M204 / SET_VELOCITY_LIMIT): a band's acceleration "
                     "holds only until the job's next one; rewrite them (`ringtune rewrite`, `limit --accel`) "
                     "or run `--band-accel keep`")
    return sched


def _refuse(config: TuneConfig, printer: Printer, step: float, band_accel: str) -> None:
    """Refuse what has no schedule: a bed that does not carry Y, an unshaped Y, a bad step or mode."""
    if not is_bed_slinger(printer):
        raise RingtuneError(f"a {printer.kinematics} printer's bed does not move with Y: its Y modes do "
                            "not depend on the print's mass (no schedule)", "--printer")
    if not 0.001 <= step <= 0.5:
        raise RingtuneError(f"band step must be within 0.1-50 %, not {step * 100:g} %", "--band-step")
    if band_accel not in BAND_ACCEL:
        raise RingtuneError(f"must be one of {', '.join(BAND_ACCEL)}, not {band_accel!r}", "band_accel")
    if config.shaper_y == "none":
        raise RingtuneError("Y is not shaped (shaper_y none): there is no frequency to schedule", "config: shaper_y")


def _band(config: TuneConfig, printer: Printer, layers: list, a: int, b: int, f_empty: float, lowest: float,
          smoothing: float | None) -> tuple[Band, bool]:
    """Layers ``a``..``b`` as one band, and whether it is held at ``lowest``: the tuned Y frequency
    scaled by the band's mode over the empty bed's, Hz (not below ``lowest``); its acceleration when
    ``smoothing`` (a factor) is given."""
    mass = 0.5 * (layers[a].mass_during + layers[b].mass_during)
    mode = dominant_y_mode(printer, mass).freq
    scaled = config.freq_y * mode / f_empty
    freq = round(max(scaled, lowest), 2)
    accel = None if smoothing is None else accel_at_band_frequency(config, printer, freq, smoothing)
    return Band(a, b, layers[a].z, mass, mode, freq, accel, (printer.print_mass + mass) * 1e3), scaled < lowest


def _clamp_note(config: TuneConfig, clamped: list[int], lowest: float, min_freq: float | None) -> str:
    """The note on bands held at the firmware's lowest shaper frequency ``lowest``, Hz."""
    fw = FIRMWARES[config.firmware]
    build = (" (a stock build's SHAPING_MIN_FREQ; yours: --shaping-min-freq)"
             if min_freq is None and fw.build_min_freq else "")
    return (f"{len(clamped)} band(s) (from layer {clamped[0]}) fall below {fw.title}'s {lowest:g} Hz{build}"
            f" and run at {lowest:g} Hz")


def _firmware_notes(config: TuneConfig, printer: Printer, bands: list[Band]) -> list[str]:
    fam = FIRMWARES[config.firmware].family
    last = bands[-1]
    if fam == "prusa":
        d, m = PRUSA_WEIGHT_ADJUST
        gap = max(abs(b.prusa_hz - b.freq_y) for b in bands)
        return [f"Prusa moves Y itself from M74 W (grams on the bed) by its linear rule f = F + A·min(W/M, 1) "
                f"(M74.cpp); the schedule sets A and M once (M593 A M) so that its line meets the model's "
                f"curve at 0 g and at the last band ({last.grams:.0f} g), {gap:.2f} Hz from it at most "
                f"over the bands; with its defaults A = {d:g} Hz, M = {m:g} g (input_shaper_config.hpp) it "
                f"would set {last.prusa_default_hz:.1f} Hz there, where the model's mode says {last.freq_y:.1f} Hz"]
    if fam == "rrf":
        before, after = _x_cost(config, printer, last.freq_y)
        return [f"RepRapFirmware has one shaper for all axes: moving it to {last.freq_y:.1f} Hz for Y moves "
                f"X's too; X's residual vibration (share-weighted over its modes, % of unshaped) goes from "
                f"{before:.1f} % to {after:.1f} % on the last band"]
    return []


def _prusa_rule(config: TuneConfig, bands: list[Band]) -> None:
    """Each band's Prusa frequencies: by the rule with the schedule's ``M593 A M`` and with its
    defaults."""
    last = bands[-1]
    delta, limit = last.freq_y - config.freq_y, last.grams
    for b in bands:
        b.prusa_default_hz = prusa_weight_frequency(config.freq_y, b.grams)
        b.prusa_hz = prusa_weight_frequency(config.freq_y, b.grams, delta, limit) if delta < 0 else config.freq_y


def scheduled_lines(schedule: MassSchedule, path: str | Path) -> list[str]:
    """The job file's lines with each band's commands (tagged :data:`TAG`) inserted where the band's
    first layer begins (:func:`ringtune.shaping.rewrite.rewrite_job`); every other line as it was,
    but a shaper command of the job's own that would move the printer off the configuration's
    shaper, which gets the configuration's shaper command in its place (as ``ringtune rewrite``
    does: the bands move the tuned shaper, as the schedule judged them)."""
    text = read_gcode_bytes(path).decode("utf-8", "replace")
    lines = text.splitlines(keepends=True)
    job = read_gcode(text, source=str(path))
    inserts = {k: [f"{c} {TAG}" for c in cmds] for k, cmds in schedule.inserts().items()}
    replaced = {ev.line: shaper_commands(schedule.config) for ev in shapers_to_replace(lines, job, schedule.config)}
    return rewrite_job(lines, schedule.config.firmware, None, layer_inserts=inserts, parsed=job, replaced=replaced)
