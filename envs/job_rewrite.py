"""A sliced job rewritten for a tuned configuration (``ringtune rewrite``, ``tune --gcode`` →
``job.gcode``): the frequency limit of ``ringtune limit`` (F words; not where the firmware applies
it itself: :func:`native_limit`) and the per-feature
accelerations and corner rule (:mod:`ringtune.shaping.rewrite`), with the planned time before and
after on the printer, planned as ``tune`` plans (the printer's limits with the configuration's
acceleration sent to it, the job's own commands).
Units: s, mm/s²."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable

import numpy as np

from ringtune.envs.planned_job import resolve_printer
from ringtune.shaping.arcs import arc_resolution
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.config_plan import as_read_by, for_firmware, job_accel_mode, plan_with_config
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.feature_settings import (FeatureCommands, accel_groups, class_corner_words, corner_words,
                                              first_layer_caps)
from ringtune.shaping.firmware import FIRMWARES
from ringtune.shaping.gcode import read_gcode
from ringtune.shaping.gcode_file import read_gcode_bytes
from ringtune.shaping.gcode_post import limit_gcode_bytes
from ringtune.shaping.layer_commands import TAG, schedule_inserts
from ringtune.shaping.layers import job_layers
from ringtune.shaping.job import Job
from ringtune.shaping.job_shapers import overriding
from ringtune.shaping.rewrite import rewrite_job, shapers_to_replace

HEADER = "; ringtune rewrite"


@dataclass
class RewrittenJob:
    """The rewritten bytes; planned times (s) of the job as sliced, of the rewritten file and of
    the configuration on the original (what ``tune`` reported; equal to ``after_s`` up to the F
    words' 0.1 mm/min rounding when a frequency limit is on); lines inserted; the header; what
    was set (resolved for the printer)."""

    data: bytes
    before_s: float
    after_s: float
    config_s: float
    lines_inserted: int
    f_lines_changed: int
    header: str
    commands: FeatureCommands | None     # None: nothing per feature (:func:`feature_commands`)
    junction: str = "scv"                # the printer's junction rule the corner values are in
    first_layer: float | None = None     # mm/s²: the job's own first-layer acceleration kept (first_layer_kept)
    shaper_replaced: tuple = ()          # the job's own shaper commands replaced by the tuned shaper's: (line, text)


def rewrite_gcode_bytes(data: bytes, config: TuneConfig, printer=None, source: str = "<gcode>",
                        layer_inserts: dict[int, list[str]] | None = None, parsed: Job | None = None,
                        shaper_lines: Callable[[TuneConfig], list[str]] | None = None) -> RewrittenJob:
    """``data`` with the configuration's frequency limit, per-feature commands and Y schedule
    (``config.y_schedule`` at layer changes, unless ``layer_inserts`` is given) written in for
    ``config.firmware`` (``printer``: a Printer, TOML path or None for the embedded default; its
    limits plan the times and give the junction rule the corner value is written in). ``parsed``:
    ``data`` already read (:func:`ringtune.shaping.gcode.read_gcode`), which is then not read again
    unless it was read to cut arcs otherwise than that firmware cuts them.
    ``shaper_lines(config)``: the configuration's shaper in its firmware's G-code
    (:func:`ringtune.hardware.dialects.shaper_commands`), asked only where the job has shaper
    commands of its own that would move the printer off it (:func:`overriding`), and written in
    their place; such a job without ``shaper_lines`` is refused, naming the line."""
    printer = resolve_printer(printer)
    limits = for_firmware(printer.limits, config)       # the job read as the configuration's firmware reads it
    arcs = arc_resolution(limits)                        # its arcs as that firmware cuts them
    if parsed is None or parsed.arcs[1] != arcs:
        parsed = read_gcode(data, source=source, arc_resolution=arcs)
    original = parsed
    # as sliced, as that firmware runs it (another firmware's shaper commands make it no stop)
    before = plan_with_config(original, limits, as_read_by(config.firmware)).plan.print_time
    if layer_inserts is None and config.y_schedule:
        sched = schedule_inserts([la.z for la in job_layers(original)], config)
        layer_inserts = {k: [f"{c} {TAG}" for c in v] for k, v in sched.items()}
    config_s = plan_with_config(original, limits, config).plan.print_time
    own = _own_shapers(data, original, config, shaper_lines)        # numbered as in the input
    f_changed = 0
    if config.freq_limit_hz > 0 and not native_limit(config):
        data, res = limit_gcode_bytes(data, float(config.freq_limit_hz), config.freq_limit_method,
                                      float(config.min_speed_factor), source=source)
        f_changed = res.lines_changed
    lines = _lines(data)
    if not lines:
        raise RingtuneError("the job is empty", source)
    fc = feature_commands(config, limits)
    # the limit's header and split moves move the lines down: the same commands, where they now stand
    lined = read_gcode(data, source=source, arc_resolution=arcs) if f_changed else original
    now = shapers_to_replace(lines, lined, config) if own and f_changed else own
    replaced = {ev.line: list(shaper_lines(config)) for ev in now} if own else None
    out = rewrite_job(lines, config.firmware, fc, layer_inserts, parsed=lined, replaced=replaced)
    inserted = len(out) - len(lines) - sum(len(v) - 1 for v in (replaced or {}).values())
    nl = "\r\n" if lines[0].endswith("\r\n") else "\n"
    new = "".join(out).encode("utf-8", errors="surrogateescape")
    # the file as the printer runs it: the configuration's machine settings (its acceleration is the
    # machine's, its retract fallback too; its caps as export sends them), the file's own commands
    # per feature — not the configuration's per-feature tables over them; the limit is in the F words
    rewritten = read_gcode(new, source=source, arc_resolution=arcs)
    after = plan_with_config(rewritten, limits, machine_part(config), job_accel="respect").plan.print_time
    header = (f"{HEADER} for {config.firmware} ({limits.junction}): {inserted} lines inserted "
              + (_set_words(fc) if fc is not None else "(the job's own acceleration commands stand: --job-accel "
                 "respect, nothing per feature)")
              + (f"; {shaper_words([ev.line for ev in own])}" if own else "")
              + f"; planned {before:.1f} s as sliced -> {after:.1f} s; nothing else differs from the input")
    return RewrittenJob(header.encode() + nl.encode() + new, before, after, config_s, inserted, f_changed, header, fc,
                        limits.junction, first_layer_kept(original) if fc is not None else None,
                        tuple((ev.line, ev.text or ev.command) for ev in own))


def _lines(data: bytes) -> list[str]:
    """The job's lines, ending at \n, \r\n or \r, as the G-code reader numbers them (str.splitlines
    would also split at form feeds and other separators a comment may hold)."""
    return [ln.decode("utf-8", errors="surrogateescape") for ln in data.splitlines(keepends=True)]


def _own_shapers(data: bytes, job: Job, config: TuneConfig, shaper_lines: Callable | None) -> list:
    """The shaper commands of ``job`` (read from ``data``) the configuration's shaper replaces
    (:func:`ringtune.shaping.rewrite.shapers_to_replace`); refused without ``shaper_lines`` to put there."""
    own = shapers_to_replace(_lines(data), job, config) if overriding(job, config) else []
    if own and shaper_lines is None:
        ev = own[0]
        raise RingtuneError(f"the job sets its own input shaper ({ev.text or ev.command}), which would replace the "
                            "tuned one while it prints, and no shaper command was given to put in its place",
                            f"{job.source}, line {ev.line}")
    return own


def shaper_words(lines: list[int]) -> str:
    """``the job's own shaper command on line 18 replaced by the tuned shaper's``."""
    where = (f"line {lines[0]}" if len(lines) == 1 else
             f"lines {', '.join(map(str, lines[:5]))}{' …' if len(lines) > 5 else ''}")
    return (f"the job's own shaper command{'s' * (len(lines) > 1)} on {where} replaced by the tuned shaper's "
            "(the tuned shaper then rules the whole job, as tune judged it)")


def feature_commands(config: TuneConfig, limits) -> FeatureCommands | None:
    """What the rewrite sets at each feature change: the configuration's per-feature settings, or
    its one acceleration for every feature; None where the configuration was judged with the job's
    own acceleration commands standing (``job_accel`` ``respect``) and sets nothing per feature:
    then the file keeps them, as tune planned it (the configuration's acceleration is the machine's,
    which export sends, for the moves the job sets none for)."""
    if job_accel_mode(config) == "respect" and not config.per_feature:
        return None
    return FeatureCommands.from_config(config, limits)


def _set_words(fc: FeatureCommands) -> str:
    """``at feature changes (accelerations …, corner …)``: what the header says was set."""
    return (f"at feature changes (accelerations {'; '.join(accel_groups(fc.accel))} mm/s²"
            + "".join(f", {w}" for w in corner_words(fc.corner, fc.min_cruise_ratio)
                      + class_corner_words(fc.class_corner, fc.class_mcr)) + ")")


def first_layer_words(kept: float) -> str:
    """One sentence on the first layer the job slows itself (:func:`first_layer_kept`)."""
    return (f"the job slows its own first layer to {kept:.0f} mm/s² (for adhesion, which is not judged here): the "
            "rewritten job keeps the job's own acceleration there wherever it is lower than the per-feature one")


def first_layer_kept(job: Job) -> float | None:
    """The lowest acceleration the job gives its first layer where it slows that layer itself
    (:func:`ringtune.shaping.feature_settings.first_layer_caps`: kept by the rewrite), mm/s²; None."""
    caps = first_layer_caps(job)
    low = [float(np.nanmin(v)) for v in caps.values() if np.any(~np.isnan(v))]
    return min(low) if low else None


def machine_part(config: TuneConfig) -> TuneConfig:
    """What of ``config`` the printer holds itself (``export`` sends it): shapers, acceleration,
    per-axis caps — without the frequency limit (in the file's F words, or the firmware's own
    where :func:`native_limit`) and the per-feature settings (in the file's commands)."""
    return replace(config.without_per_feature(), freq_limit_hz=config.freq_limit_hz if native_limit(config) else 0.0)


def native_limit(config: TuneConfig) -> bool:
    """Whether the firmware applies the configuration's frequency limit itself (Marlin's
    XY_FREQUENCY_LIMIT, ``M201 F S``, sent by ``export``/``push``): then the job keeps its F words."""
    return config.freq_limit_method == "marlin" and FIRMWARES[config.firmware].freq_limit


def rewrite_file(src, dst, config: TuneConfig, printer=None,
                 layer_inserts: dict[int, list[str]] | None = None, parsed: Job | None = None,
                 shaper_lines: Callable[[TuneConfig], list[str]] | None = None) -> RewrittenJob:
    """:func:`rewrite_gcode_bytes` of the file ``src``, written to ``dst`` (None: not written);
    ``parsed``: the file already read."""
    done = rewrite_gcode_bytes(read_gcode_bytes(src), config, printer, str(src), layer_inserts, parsed,
                               shaper_lines)
    if dst is not None:
        Path(dst).write_bytes(done.data)
    return done
