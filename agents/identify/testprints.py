"""Calibration prints in a firmware's own dialect: the ringing tower (bands of shaper frequency, or
shaping off to measure ripples) and the acceleration ladder (``ringtune testprint``).

Geometry and comments come from :mod:`ringtune.shaping.calibration_prints`; every shaper line is
what ``ringtune export`` writes for that firmware (:func:`ringtune.hardware.dialects.export_config`).
Units: mm, mm/s, mm/s², Hz.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ringtune.hardware.dialects import export_config
from ringtune.hardware.firmware_check import check_available
from ringtune.shaping import calibration_prints as cp
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.firmware import Firmware
from ringtune.shaping.shapers import default_damping

#: shapers the tower prefers, narrowest band first: the band with the least ringing then pins the
#: frequency closest (ZV removes 90 % within ±6 %, MZV within ±10 %: firmware.md / seed 000 table)
TOWER_SHAPERS = ("zv", "mzv", "zvd", "ei")


def shaper_lines(firmware: str, shaper: str, freq: float, damping: float) -> list[str]:
    """What ``ringtune export --firmware FIRMWARE`` writes for ``shaper`` at ``freq`` Hz on both
    axes (``shaper`` "none": shaping off)."""
    freq_set = freq if shaper != "none" else 0.0
    cfg = TuneConfig(firmware=firmware, shaper_x=shaper, shaper_y=shaper, freq_x=freq_set, freq_y=freq_set,
                     damping_x=damping, damping_y=damping)
    try:
        return export_config(cfg, firmware, accel=False).lines
    except RingtuneError as exc:
        raise RingtuneError(f"{exc.bare} (band at {freq:g} Hz)", "--bands") from None


def tower_shaper(firmware: str, shaper: str | None) -> str:
    """The tower's shaper: ``shaper`` if the firmware has it, else the narrowest it has."""
    if shaper:
        return check_available(shaper, firmware, "--shaper")
    return next(s for s in TOWER_SHAPERS if s in Firmware.named(firmware).shapers)


@dataclass
class TowerPlan:
    """A ringing tower ready to write: its bands, the G-code text and what to tell the user."""

    bands: list[cp.Band]
    gcode: str
    measure: list[str]
    notes: list[str] = field(default_factory=list)


def ringing_tower(firmware: str, *, speed: float, accel: float, bands: tuple[float, float, int] | None,
                  band_height: float, height: float, shaper: str | None, damping: float | None,
                  geometry: cp.TowerGeometry, ext: cp.Extrusion, hotend: float, bed: float,
                  printer_name: str) -> TowerPlan:
    """The ringing tower for ``firmware``: ``bands`` = (F0, F1, N) or None for shaping off."""
    notes = []
    record = Firmware.named(firmware, "--firmware")
    if bands is None:
        name, zeta = "none", 0.0
        n_layers = max(3, int(round(height / ext.layer)))
        specs = [(1, 0.0, n_layers * ext.layer, 0.0)]
    else:
        name = tower_shaper(firmware, shaper)
        if damping is None:
            damping = default_damping(record.flavor)
            notes.append(f"shaper damping {damping:g}: {record.title}'s default (--damping to change)")
        zeta = damping
        specs = cp.tower_bands(bands[0], bands[1], int(bands[2]), band_height, ext.layer)
    out_bands = [cp.Band(k, z0, z1, f, f, name, zeta, shaper_lines(firmware, name, f, zeta))
                 for k, z0, z1, f in specs]
    g, v = geometry, speed
    measure = _what_to_measure(g, v, bands is not None)
    header = [f"ringtune testprint ringing for {record.title} ({printer_name})",
              f"single-wall square tower {g.side:g} mm, front-left corner at X{g.x0:g} Y{g.y0:g}, printed "
              f"counter-clockwise at {v:g} mm/s with {accel:.0f} mm/s² acceleration",
              f"layers {ext.layer:g} mm, line {ext.line_width:.3g} mm wide, {ext.filament:g} mm filament, "
              f"nozzle {hotend:.0f} °C, bed {bed:.0f} °C (start: heat, G28)",
              "", *measure]
    end = (["the shaper of the last band stays active until the firmware restarts or you send your own "
            "settings (ringtune export)"] if bands is not None else
           ["shaping stays off until the firmware restarts or you send your own settings (ringtune export)"])
    accel_set = cp.accel_lines(firmware, accel)
    end.append(f"the acceleration set at the start ({'; '.join(accel_set)}) stays too: "
               + ("restart Klipper or set your own" if Firmware.named(firmware).family == "klipper" else
                  "M501 reloads the saved settings" if firmware in ("marlin", "marlin-ftm", "prusa") else
                  "restart or run config.g again"))
    start = cp.start_lines(hotend, bed, accel_set)
    text = cp.ringing_tower(out_bands, g, ext, header=header, start=start, end_note=end)
    return TowerPlan(out_bands, text, measure, notes)


def _what_to_measure(g: cp.TowerGeometry, v: float, banded: bool) -> list[str]:
    xr, yt = g.x0 + g.side, g.y0 + g.side
    faces = [f"X ringing is on the walls along Y: the right wall (X{xr:g}, printed towards +Y from the "
             f"front-right corner) and the left wall (X{g.x0:g}, towards -Y from the back-left corner).",
             f"Y ringing is on the walls along X: the back wall (Y{yt:g}, printed towards -X from the "
             f"back-right corner) and the front wall (Y{g.y0:g}, towards +X from the front-left corner)."]
    if banded:
        return ["what to look for:", *faces,
                "Per axis, find the band whose walls show the least ringing (band 1 is the lowest), then:",
                "  ringtune identify --tower-band X=<band>,Y=<band> --tower <this file> -o printer.toml"]
    return ["what to measure (calipers, or a photo with a scale):", *faces,
            "On a wall, skip the first two ripples after the corner where it starts (the head was still",
            "accelerating there: they lie closer together). From the crest of the third ripple measure to",
            "the crest N ripples further on and divide by N: that is the ripple spacing S (mm).",
            "Optional damping: the depth of a ripple divided by the depth of the next one, R (> 1).",
            f"  ringtune identify --ripples X=<Sx>,Y=<Sy> --speed {v:g} [--decay X=<Rx>,Y=<Ry>] -o printer.toml",
            f"(frequency = {v:g} mm/s / S: 2 mm apart is {v / 2:g} Hz.)"]


# -- the acceleration ladder ---------------------------------------------------------------------------
@dataclass
class LadderPlan:
    accels: list[float]
    gcode: str
    table: list[str]
    notes: list[str] = field(default_factory=list)


def ladder_accels(start: float, tuned: float, rungs: int) -> tuple[list[float], list[str]]:
    """Accelerations of the ladder: ``rungs`` evenly spaced from ``start`` to ``tuned`` (both
    included), then 110 % and 120 % of ``tuned``; and notes."""
    notes = []
    if not (math.isfinite(tuned) and tuned > 0):
        raise RingtuneError(f"the tuned acceleration must be a positive number, not {tuned!r}", "--config")
    if rungs < 2 or rungs > 20:
        raise RingtuneError(f"must be 2 to 20, not {rungs}", "--rungs")
    if start >= tuned:
        notes.append(f"the tuned acceleration {tuned:.0f} mm/s² is not above the starting one "
                     f"({start:.0f}); the ladder starts at half the tuned value")
        start = tuned / 2
    step = (tuned - start) / (rungs - 1)
    accels = [start + k * step for k in range(rungs)] + [1.1 * tuned, 1.2 * tuned]
    return [float(round(a)) for a in accels], notes


def accel_ladder(firmware: str, config: TuneConfig, *, start_accel: float, rungs: int,
                 geometry: cp.LadderGeometry, ext: cp.Extrusion, hotend: float, bed: float,
                 printer_name: str) -> LadderPlan:
    tuned = float(config.accel)
    accels, notes = ladder_accels(start_accel, tuned, rungs)
    g = geometry
    record = Firmware.named(firmware, "--firmware")
    exp = export_config(config, firmware, accel=False)     # the shaper; the ladder sets the acceleration
    table = [f"{'rung':>4}  {'accel mm/s²':>11}  {'of tuned':>8}"]
    table += [f"{k:>4}  {a:>11.0f}  {a / tuned * 100:>7.0f}%" for k, a in enumerate(accels, 1)]
    look = ["Rung 0 draws the reference dashes; rung K draws dash K further out, after its fast moves.",
            f"Dashes along Y (going +Y from X{g.cx:g} Y{g.cy:g}) must stay on one line in X; dashes along X",
            "(going +X from the same point) on one line in Y. A dash out of line means the motors skipped",
            "steps on that rung or an earlier one: the first such dash names the rung (table above).",
            "Also listen: grinding or a loud knock at a rung is the same warning.",
            f"Print with the tuned acceleration ({tuned:.0f} mm/s²) only if every dash up to rung "
            f"{len(accels)} ({accels[-1]:.0f} mm/s², 120 %) is in line."]
    header = [f"ringtune testprint accel for {record.title} ({printer_name})",
              f"checks the tuned acceleration {tuned:.0f} mm/s² and 20 % beyond, from {accels[0]:.0f} mm/s²",
              f"fast moves at {g.speed:g} mm/s, {g.reach:g} mm each way from the reference point "
              f"X{g.cx:g} Y{g.cy:g} (X, Y, both diagonals), {g.reps}× per rung, {g.hop:g} mm above the bed",
              f"acceleration set with {cp.accel_syntax(firmware)}; the tuned shaper is on (as ringtune export "
              "writes it) because prints will run with it",
              "", "ladder table:", *table, "", "what to look for:", *look]
    restore = cp.accel_lines(firmware, start_accel, axis_maxima=False)
    end = ["the last lines set the starting acceleration again: " + "; ".join(restore)]
    fw = Firmware.named(firmware)
    if fw.family == "klipper" and fw.axis_accel_set:
        end.append("the raised X_ACCEL/Y_ACCEL caps stay until RESET_VELOCITY_LIMIT or a restart")
    elif fw.family != "klipper":
        end.append("the raised M201 axis maxima stay until reset: M501 (Marlin, Prusa) or restart (RRF)")
    if firmware in ("marlin", "marlin-ftm", "prusa"):
        end.append("a Marlin built with LIMITED_MAX_ACCEL_EDITING caps M201: check with M503 that the "
                   "top rung's M201 was taken")
    start = cp.start_lines(hotend, bed, [])
    text = cp.accel_ladder(accels, firmware, g, ext, header=header, start=start, safe_accel=start_accel,
                           shaper_lines=exp.lines, restore=restore, end_note=end)
    return LadderPlan(accels, text, table + [""] + look, notes)
