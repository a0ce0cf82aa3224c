"""A G-code job planned on a printer as its firmware would, for ``ringtune plan`` and ``ringtune
limit``: the limits and junction rule that apply (and why, in words), the print time and where it
goes, and the highest direction-change frequencies, commanded (at the G-code's F: what a frequency
limit acts on) and planned (with accelerations and corners: what the printer does).

Times in s, frequencies in Hz, lengths in mm. Both commands plan through :func:`planning_limits`,
so they report the same planned frequencies.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from ringtune.envs.printer import load_printer
from ringtune.shaping.builtin_jobs import job_path
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.arcs import arc_resolution, arcs_note
from ringtune.shaping.features import feature_class
from ringtune.shaping.extruder_alone import extruder_alone_note
from ringtune.shaping.klipper_refusals import klipper_refusals, klipper_refusals_note
from ringtune.shaping.config_plan import ConfiguredPlan, for_firmware, plan_with_config
from ringtune.shaping.firmware import FIRMWARES
from ringtune.shaping.firmware_retraction import firmware_retraction_note, firmware_retractions, retraction_plan
from ringtune.shaping.flavor_units import FLAVOR_M203_PER_MINUTE, flavor_note
from ringtune.shaping.freqlimit import commanded_frequencies as per_move
from ringtune.shaping.gcode import read_gcode
from ringtune.shaping.gcode_file import read_gcode_bytes
from ringtune.shaping.gcode_post import AccelResult, LimitResult, limit_file, rewrite_accel_bytes
from ringtune.shaping.job import Job
from ringtune.shaping.klipper_commands import macro_calls, macro_note
from ringtune.shaping.klipper_ignores import klipper_ignored, klipper_ignored_note
from ringtune.shaping.slicer import slicer_estimate, slicer_flavor
from ringtune.shaping.testprints import builtin_test_print, direction_change_frequencies

#: slicer G-code flavour -> the rule that firmware plans corners with by default (Marlin 2 ships
#: with junction deviation, CLASSIC_JERK off; legacy Marlin, RepRapFirmware's M566 and Repetier
#: use jerk; Smoothieware junction deviation)
FLAVOR_JUNCTION = {"klipper": "scv", "marlin2": "jd", "marlin": "jerk", "reprapfirmware": "jerk",
                   "reprap": "jerk", "repetier": "jerk", "smoothie": "jd"}
#: what a job's own commands imply, in order: (the setting it sets, the rule, why in words)
JOB_JUNCTION = (
    ("square_corner_velocity", "scv", "the job sets SQUARE_CORNER_VELOCITY (Klipper)"),
    ("junction_deviation", "jd", "the job sets M205 J (Marlin's junction deviation)"),
    ("jerk_x", "jerk", "the job sets a jerk (M205 X/Y: legacy Marlin, and PrusaSlicer's own estimate; "
                       "RepRapFirmware's M566)"),
    ("jerk_y", "jerk", "the job sets a jerk (M205 X/Y: legacy Marlin, and PrusaSlicer's own estimate; "
                       "RepRapFirmware's M566)"),
)
#: a printer's corner setting ([limits]) -> the rule it belongs to, in order
CORNER_JUNCTION = {"square_corner_velocity": "scv", "junction_deviation": "jd", "jerk": "jerk"}


def junction_rule(job: Job, flavor: str | None = None, printer=None, given: dict | None = None,
                  junction: str = "auto", firmware: str | None = None) -> tuple[str, str]:
    """(rule, why in words): ``junction`` if not ``"auto"``; else the printer's ``[limits]
    junction`` (``given``: its limits); else, for a configuration made for Klipper or Kalico
    (``firmware``), scv, their one rule; else what the job's own commands imply; else the
    slicer's flavour (:data:`FLAVOR_JUNCTION`; ``flavor``: the file's,
    :func:`ringtune.shaping.slicer.slicer_flavor`); else the printer's corner setting; else scv."""
    given = given or {}
    if junction != "auto":
        return junction, "--junction"
    if "junction" in given:
        return given["junction"], f"the printer's [limits] junction ({printer})"
    fw = FIRMWARES.get(firmware or "")
    if fw is not None and fw.family == "klipper":
        return "scv", (f"the configuration is for {fw.title}, whose one corner rule is square_corner_velocity "
                       "(a job's M205 and its slicer's flavour do not apply there)")
    for setting, rule, why in JOB_JUNCTION:
        if not math.isnan(job.file_setting(setting)):
            return rule, why
    if any(ev.command == "SET_VELOCITY_LIMIT" for ev in job.events):
        return "scv", "the job uses SET_VELOCITY_LIMIT, which only Klipper and Kalico have"
    if flavor in FLAVOR_JUNCTION:
        return FLAVOR_JUNCTION[flavor], f"the slicer wrote the job for {flavor}"
    for key, rule in CORNER_JUNCTION.items():
        if key in given:
            return rule, f"the printer gives {key} ({printer})"
    return "scv", ("nothing names a rule (no printer rule, no M205 or SET_VELOCITY_LIMIT, no slicer "
                   "flavour): Klipper's, the default; --junction jd|jerk for Marlin")


def planning_limits(job: Job, path=None, printer=None, junction: str = "auto", firmware: str | None = None):
    """(the machine limits the job is planned with, the junction rule, why in words): the limits of
    ``printer`` (TOML or embedded name; None: the embedded default printer, as every command) with the rule of
    :func:`junction_rule` (``firmware``: the configuration's, if any). Where neither the printer
    (its ``[current] firmware``) nor a configuration names the firmware, a job its slicer wrote for
    RepRapFirmware has its M203 speeds read in mm/min, as there (the why says so)."""
    pr = load_printer(printer)
    limits, given = pr.machine_limits(), dict(pr.limits_dict)
    flavor = slicer_flavor(path) if path else None
    junction, why = junction_rule(job, flavor, printer or "the embedded default printer", given, junction, firmware)
    limits = replace(limits, junction=junction)
    if not (firmware or pr.current.get("firmware")):
        limits, why = _flavor_reading(limits, why, flavor)
    if junction != "scv":
        limits = replace(limits, min_cruise_ratio=0.0)
    return limits, junction, why


def _flavor_reading(limits, why: str, flavor: str | None):
    """(limits, why) for a printer whose firmware nothing names: M203 in mm/min for a job sliced
    for RepRapFirmware, said; else as they were."""
    if not FLAVOR_M203_PER_MINUTE.get(str(flavor).lower()):
        return limits, why
    return replace(limits, m203_per_minute=True), why + (
        f"; its M203 speeds read in mm/min, as RepRapFirmware reads them (the slicer wrote it for {flavor} "
        "and nothing names the printer's firmware)")


def planned_frequencies(p, top: int) -> list[dict]:
    """The ``top`` highest planned direction-change frequencies (one per G-code line):
    [{freq_hz, line, t}], three cycles of zigzag while extruding, in planned time."""
    tz, fz, lz = direction_change_frequencies(p)
    out, seen = [], set()
    for i in np.argsort(-fz, kind="stable"):
        if len(out) >= top:
            break
        if int(lz[i]) not in seen:
            seen.add(int(lz[i]))
            out.append({"freq_hz": float(fz[i]), "line": int(lz[i]), "t": float(tz[i])})
    return out


def commanded_frequencies(job: Job, top: int) -> list[dict]:
    """The ``top`` highest direction-change frequencies at the G-code's commanded speeds (one per
    line): [{freq_hz, line}] (``shaping.freqlimit.commanded_frequencies``)."""
    f = per_move(job)
    out = []
    for i in np.argsort(-f, kind="stable")[:max(top, 0)]:
        if f[i] <= 0:
            break
        out.append({"freq_hz": float(f[i]), "line": int(job.line[i])})
    return out


def hms(seconds: float) -> str:
    """``1h 02m 03s`` / ``4m 05s``."""
    s = int(round(seconds))
    h, rem = divmod(s, 3600)
    m, s = divmod(rem, 60)
    return f"{h}h {m:02d}m {s:02d}s" if h else f"{m}m {s:02d}s"


def _highest(freqs: list[dict]) -> float:
    """Hz of the highest of planned or commanded ``freqs`` (ranked, highest first), 0 when none."""
    return freqs[0]["freq_hz"] if freqs else 0.0


@dataclass
class JobPlan:
    """A planned job: what ``ringtune plan`` reports (:meth:`to_dict`: its JSON keys but
    ``trajectory``)."""

    name: str               # the file, or "built-in test print"
    job: Job
    configured: ConfiguredPlan
    junction: str
    why: str                # why that junction rule, in words
    top: list[dict]         # planned frequencies (planned_frequencies)
    top_commanded: list[dict]
    estimate: float | None  # the slicer's own estimate, s
    read_s: float
    plan_s: float

    def to_dict(self) -> dict:
        p = self.configured.plan
        fl = self.configured.freq_limit
        shaper_events = [{"line": e.line, "command": e.command, "time": e.time, "params": e.params}
                         for e in p.events if e.kind == "shaper"]
        kinds: dict[str, int] = {}
        for e in p.events:
            kinds[e.kind] = kinds.get(e.kind, 0) + 1
        ignored = klipper_ignored(self.job, self.configured.limits)
        macros = macro_calls(self.job) if self.configured.limits.reads_like_klipper else {}
        retractions = firmware_retractions(self.job)
        planned = sum(r.e is not None for r in retraction_plan(self.job, self.configured.limits))
        by_feature = p.time_by_feature()
        return {
            "job": self.name, "junction": self.junction, "junction_reason": self.why,
            "limits": dict(asdict(self.configured.limits)),
            "print_time_s": p.print_time, "print_time": hms(p.print_time),
            "moves": len(p.moves), "extruding_moves": int(p.moves.extruding.sum()), "lines": self.job.n_lines,
            "path_length_mm": float(p.moves.length.sum()), "time_by_feature": by_feature,
            "feature_classes": {label: feature_class(label) for label in by_feature},
            "top_frequencies": self.top, "top_commanded_frequencies": self.top_commanded,
            "max_planned_freq_hz": _highest(self.top), "max_commanded_freq_hz": _highest(self.top_commanded),
            "shaper_events": shaper_events, "events": kinds,
            "slicer_estimate_s": self.estimate,
            "vs_slicer": (p.print_time / self.estimate - 1) if self.estimate else None,
            "freq_limit": None if fl is None else asdict(fl), "daa_hz": self.configured.daa_hz,
            "read_s": self.read_s, "plan_s": self.plan_s,
            # under Klipper's rule: the job's limit lines Klipper does not act on ({command: [lines]})
            "ignored_by_firmware": ignored, "ignored_note": klipper_ignored_note(ignored),
            # read as Klipper reads it: the commands that are not Klipper's own ({command: [lines]})
            "macro_calls": macros, "macro_note": macro_note(macros),
            # G10/G11 firmware retractions ({command: [lines]}), how many planned as E-only moves (the
            # others as stops that take no time: their settings are not known)
            "firmware_retraction": retractions, "firmware_retraction_planned": planned,
            "firmware_retraction_note": firmware_retraction_note(self.job, self.configured.limits),
            # G2/G3 arcs: how many, and how they are cut (Klipper's segments, else chords)
            "arcs": self.job.arcs[0], "arcs_note": arcs_note(self.job, self.configured.limits),
            # Klipper: retractions planned without the extruder's own limits (not given), in words
            "extruder_alone_note": extruder_alone_note(self.job, self.configured.limits),
            # Klipper: the moves its extruder refuses (it stops the print at the first)
            "klipper_refusals": (refused := klipper_refusals(self.job, self.configured.limits)),
            "klipper_refusals_note": klipper_refusals_note(refused),
            # a job sliced for another firmware: its limit lines read in other units, or not at all
            "flavor_note": flavor_note(self.job, self.configured.limits, None),
        }


def plan_job(path=None, printer=None, config: TuneConfig | None = None, junction: str = "auto",
             use_job_limits: bool = True, daa_freq: float | None = None, top: int = 5) -> JobPlan:
    """Plan the G-code at ``path`` (a built-in job's name: its file; None: the built-in test print)
    with ``printer``'s limits (TOML or embedded name; None: the embedded default printer), ``config``'s
    frequency limit and acceleration, the junction rule of :func:`junction_rule`, and ``top``
    frequencies of each kind."""
    path = job_path(path)
    t0 = time.perf_counter()
    job = read_gcode(Path(path)) if path else builtin_test_print()
    limits, junction, why = planning_limits(job, path, printer, junction, config.firmware if config else None)
    job = _arcs_as_cut(job, path, limits, config)
    t_read = time.perf_counter() - t0
    t1 = time.perf_counter()
    configured = plan_with_config(job, limits, config, use_job_limits=use_job_limits, daa_freq=daa_freq)
    t_plan = time.perf_counter() - t1
    return JobPlan(path or "built-in test print", job, configured, junction, why,
                   planned_frequencies(configured.plan, top), commanded_frequencies(configured.job, top),
                   slicer_estimate(path) if path else None, t_read, t_plan)


@dataclass
class LimitedJob:
    """A job rewritten by ``ringtune limit``: its bytes, what the frequency limit and the
    acceleration rewrite did (None: not asked), and the highest frequencies before and after."""

    data: bytes
    limited: LimitResult | None
    accel: AccelResult | None
    frequencies: dict       # {commanded_hz: {before, after}, planned_hz: {before, after}, junction, junction_reason}


def limit_job(path, freq_limit: float | None = None, method: str = "sections",
              min_speed_factor: float | None = None, accel: float | None = None, printer=None) -> LimitedJob:
    """The G-code at ``path`` with its zigzags slowed under ``freq_limit`` Hz (``method``) and/or
    its acceleration commands scaled so the highest printing one is ``accel`` mm/s², with the
    highest direction-change frequencies before and after (planned with ``printer``'s limits)."""
    res = acc = None
    if freq_limit is not None:
        data, res = limit_file(path, None, freq_limit, method, min_speed_factor)
    else:
        data = read_gcode_bytes(path)        # refuses a folder, a binary, a TOML...
    if accel is not None:
        data, acc = rewrite_accel_bytes(data, accel, source=path)
    return LimitedJob(data, res, acc, _frequencies(path, data, printer))


def _arcs_as_cut(job: Job, source, limits, config: TuneConfig | None) -> Job:
    """``job`` read again (from ``source``, a path or the G-code) with its arcs cut as the firmware
    reading it with ``limits`` under ``config`` cuts them (:func:`ringtune.shaping.arcs.arc_resolution`);
    itself when it has no arcs or that firmware's are the tolerance's chords."""
    res = arc_resolution(for_firmware(limits, config))
    if not job.arcs[0] or res is None or source is None:
        return job
    return read_gcode(Path(source) if not isinstance(source, bytes) else source, source=job.source,
                      arc_resolution=res)


def _frequencies(path, limited: bytes, printer=None) -> dict:
    """Highest commanded and planned direction-change frequencies of the file and of its limited
    text, through the same functions as ``ringtune plan``."""
    out: dict = {"commanded_hz": {}, "planned_hz": {}}
    for key, job in (("before", read_gcode(path)), ("after", read_gcode(limited, source=str(path)))):
        limits, junction, why = planning_limits(job, path, printer)
        job = _arcs_as_cut(job, path if key == "before" else limited, limits, None)
        configured = plan_with_config(job, limits)
        out["planned_hz"][key] = _highest(planned_frequencies(configured.plan, 1))
        out["commanded_hz"][key] = _highest(commanded_frequencies(configured.job, 1))
    # the output's limit lines Klipper does not act on (a lone M204 P scaled is still ignored there)
    out.update(junction=junction, junction_reason=why,
               ignored_note=klipper_ignored_note(klipper_ignored(job, limits)))
    return out
