"""The mass schedule checked on the model: what a fixed frequency costs is measured, not inferred.

The job's last band of layers is simulated with its mass on the bed, once at the tuned frequency
and once at the schedule's (:func:`last_band_ripple`; ripple = the worst visible wall's
peak-to-peak across the wall, mm; corners mm, time s). Klipper's smoothing estimate, which sets the
bands' accelerations (:mod:`ringtune.agents.tune.mass_schedule`), leaves out the nozzle's own lag on
the heavier bed: :func:`measured_smoothing_factor` finds the largest share of the tuned smoothing
(:data:`SMOOTHING_TARGETS`) at which the last band rounds its corners no more than the fixed
frequency's. :func:`schedule_job` is the whole run: the schedule built, measured so, and written
into the job and the config.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from ringtune.agents.tune.mass_schedule import (BAND_STEP, MassSchedule, accel_at_band_frequency, mass_schedule,
                                                scheduled_lines)
from ringtune.agents.tune.pareto import DEFAULT_RESOLUTION
from ringtune.envs.bed_load import loaded
from ringtune.envs.evaluate import evaluate_many
from ringtune.envs.planned_job import resolve_job, resolve_printer
from ringtune.envs.printer_model import Printer
from ringtune.shaping.builtin_jobs import job_path
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.config_plan import for_firmware
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.firmware import FIRMWARES
from ringtune.shaping.layers import job_slice

#: fractions of the tuned smoothing the bands are held to, tried on the last band (largest first):
#: Klipper's estimate leaves out the nozzle's own lag on a softer bed, so the corners are measured
SMOOTHING_TARGETS = (1.0, 0.94, 0.88, 0.82, 0.76, 0.7)


def last_band_ripple(schedule: MassSchedule, printer=None, job=None, backend: str = "mujoco") -> dict:
    """The job's last band of layers simulated with the band's mass on the bed (its middle's):
    ripple (mm, worst visible wall), corners and time at the tuned frequency and at the band's
    (with its acceleration); on Prusa also at what its own rule sets with its defaults."""
    printer = resolve_printer(printer)
    band = schedule.bands[-1]
    first, last = schedule.layers[band.first_layer], schedule.layers[band.last_layer]
    part, heavy = _last_band(schedule, printer, job)
    fixed = replace(schedule.config, y_schedule=None, extra={})
    fw = FIRMWARES[fixed.firmware]
    runs = {"fixed": fixed, "scheduled": _at(fixed, band.freq_y, band.accel, fw.one_shaper)}
    if fw.family == "prusa":     # what the firmware sets from M74 W by its own rule, ours and its defaults
        runs["scheduled"] = _at(fixed, round(band.prusa_hz, 2), band.accel, False)
        runs["prusa_default_rule"] = _at(fixed, round(band.prusa_default_hz, 2), band.accel, False)
    metrics = evaluate_many(list(runs.values()), heavy, part, backend, job_accel="replace")
    out = {"first_layer": band.first_layer, "last_layer": band.last_layer, "z_mm": first.z, "z_top_mm": last.z,
           "mass_g": band.mass_kg * 1e3, "mode_hz": band.mode_hz,
           "measured_against": "the commanded path, simulated on the exact model with the band's mass on the bed"}
    for (key, cfg), m in zip(runs.items(), metrics):
        out[key] = {"freq_y": cfg.freq_y, "freq_x": cfg.freq_x, "accel": cfg.accel, "ripple_mm": m.ripple_mm,
                    "corner_in_mm": m.corner_in_mm, "corner_out_mm": m.corner_out_mm,
                    "print_time_s": m.print_time_s}
    schedule.ripple = out
    return out


def _last_band(schedule: MassSchedule, printer: Printer, job):
    """(the job's moves of the last band, the printer with the band's mass on the bed)."""
    _, parsed = resolve_job(job, for_firmware(printer.limits, schedule.config))     # as the schedule read it
    band = schedule.bands[-1]
    first, last = schedule.layers[band.first_layer], schedule.layers[band.last_layer]
    return job_slice(parsed, first.first_move, last.last_move + 1), loaded(printer, band.mass_kg)


def measured_smoothing_factor(schedule: MassSchedule, printer=None, job=None,
                              backend: str = "mujoco") -> tuple[float, str | None]:
    """The largest of :data:`SMOOTHING_TARGETS` at which the last band, simulated with its mass on
    the bed, rounds and overshoots its visible corners no more than the tuned config does there
    (tune's resolution); (its smallest, a note) when none does."""
    printer = resolve_printer(printer)
    part, heavy = _last_band(schedule, printer, job)
    cfg, band = replace(schedule.config, y_schedule=None, extra={}), schedule.bands[-1]
    one = FIRMWARES[cfg.firmware].one_shaper
    cands = [_at(cfg, band.freq_y, accel_at_band_frequency(cfg, printer, band.freq_y, c), one) for c in SMOOTHING_TARGETS]
    fixed, *got = evaluate_many([cfg] + cands, heavy, part, backend, job_accel="replace")
    res = DEFAULT_RESOLUTION
    for c, m in zip(SMOOTHING_TARGETS, got):
        if all(getattr(m, k) <= getattr(fixed, k) + res.tolerance(k, getattr(m, k), getattr(fixed, k))
               for k in ("corner_in_mm", "corner_out_mm")):
            return c, None
    m = got[-1]
    return SMOOTHING_TARGETS[-1], (f"even at {SMOOTHING_TARGETS[-1] * 100:g} % of the tuned smoothing the last band "
                                   f"rounds corners by {m.corner_in_mm * 1e3:.1f} µm against the fixed frequency's "
                                   f"{fixed.corner_in_mm * 1e3:.1f} µm")


def _at(config: TuneConfig, freq_y: float, accel: float | None, one_shaper: bool) -> TuneConfig:
    """``config`` with Y at ``freq_y`` (and X too on a firmware with one shaper for all axes)."""
    cfg = replace(config, freq_y=freq_y, accel=accel or config.accel)
    return replace(cfg, freq_x=freq_y) if one_shaper else cfg


def schedule_job(config: TuneConfig, printer=None, job=None, *, diameter_mm: float | None = None,
                 density_g_cm3: float | None = None, step: float = BAND_STEP,
                 band_accel: str = "auto", min_freq: float | None = None, output: str | Path | None = None,
                 config_out: str | Path | None = None, backend: str = "mujoco") -> MassSchedule:
    """:func:`mass_schedule` with the last band measured (:func:`last_band_ripple`); writes the job
    with the bands' lines inserted to ``output`` and the config with its ``y_schedule`` to
    ``config_out`` when given (``job`` must then be a file)."""
    job = job_path(job)
    if output is not None and not (isinstance(job, (str, Path)) and Path(job).is_file()):
        raise RingtuneError("writing the scheduled job needs the job as a G-code file", "--gcode")
    kw = dict(diameter_mm=diameter_mm, density_g_cm3=density_g_cm3, step=step, band_accel=band_accel,
              min_freq=min_freq)
    sched = mass_schedule(config, printer, job, **kw)
    if sched.needed:
        if any(b.accel for b in sched.bands):        # band_accel "auto" lowered some (keep: none)
            sched = _smoothing_measured(sched, printer, job, backend, kw)
        last_band_ripple(sched, printer, job, backend)
    if output is not None:
        Path(output).write_text("".join(scheduled_lines(sched, job)), newline="")
    if config_out is not None:
        sched.scheduled_config().save(config_out)
    return sched


def _smoothing_measured(sched: MassSchedule, printer, job, backend: str, kw: dict) -> MassSchedule:
    """``sched`` again with its bands' accelerations at :func:`measured_smoothing_factor` (as it is
    when that factor is 1), noting the factor."""
    factor, note = measured_smoothing_factor(sched, printer, job, backend)
    if factor == 1.0:
        return sched
    sched = mass_schedule(sched.config, printer, job, smoothing_factor=factor, **kw)
    sched.notes.append(f"the bands hold Klipper's smoothing estimate to {factor * 100:g} % of the tuned "
                       "one: there the last band's corners, simulated, are no worse than the fixed "
                       "frequency's (tune's resolution)" if note is None else note)
    return sched
