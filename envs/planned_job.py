"""A job planned for a printer under a configuration, with its quality windows (cached).

1. The job (G-code path, G-code text, a parsed ``Job``, a built-in job's name, or None for the
   built-in test print) is parsed once;
2. :func:`ringtune.shaping.config_plan.plan_with_config` plans it with the printer's limits (the
   config's acceleration per the job-acceleration mode ``job_accel``, its frequency limit, DAA,
   per-feature settings) → print time, s;
3. the quality windows (sharpest corners, fastest zigzags, seams) are chosen once per job on the
   plan at the printer's own limits and relocated onto every configuration's plan, so all are
   judged on the same corners.

Parsed jobs and plans are cached per (job, limits, planning settings): configurations that only
change the shaper skip parsing and planning. Everything is deterministic.
"""

from __future__ import annotations

import dataclasses
import os
from collections import OrderedDict
from pathlib import Path
from typing import Any

import numpy as np

from ringtune.envs.printer import load_printer
from ringtune.shaping import gcode, testprints
from ringtune.shaping.arcs import arc_resolution
from ringtune.shaping.builtin_jobs import job_path
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.config_plan import JOB_ACCEL_SETTINGS, for_firmware, job_accel_mode, plan_with_config
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.job import SETTING_KEYS
from ringtune.shaping.lookahead import KLIPPER_AXIS_SETTINGS
from ringtune.shaping.motion import Motion

#: quality windows per job and their span, s
MAX_WINDOWS = 8
WINDOW_SPAN = 0.25

_JOBS: "OrderedDict[Any, Any]" = OrderedDict()
_PLANS: "OrderedDict[Any, Any]" = OrderedDict()
_CACHE_SIZE = 64
#: bytes of planned jobs the cache holds at most besides the newest (a plan of a 1.5-hour job is
#: 65 MB: a count alone let one tune hold 64 of them, 3 GB)
_CACHE_BYTES = 768_000_000
#: job settings the window choice leaves out (the printer's own limits rule there)
REFERENCE_FREE = (*JOB_ACCEL_SETTINGS, "square_corner_velocity", "junction_deviation", "jerk_x", "jerk_y",
                  "m205_jerk_x", "m205_jerk_y", "min_cruise_ratio", "accel_to_decel")


@dataclasses.dataclass
class PlannedJob:
    """A planned job and its quality windows (cached)."""

    plan: Any                 # shaping.plan_result.Plan
    windows: list             # [Window(t0, t1, kind, score)]

    @property
    def print_time(self) -> float:
        return float(self.plan.print_time)

    @property
    def motion(self) -> Motion:
        return self.plan.motion


def _remember(cache: OrderedDict, key, value):
    """Cache ``value`` as the newest; the oldest go beyond :data:`_CACHE_SIZE` entries or
    :data:`_CACHE_BYTES` of arrays."""
    cache[key] = value
    cache.move_to_end(key)
    sizes = {k: _nbytes(v) for k, v in cache.items()}
    total = sum(sizes.values())
    while len(cache) > 1 and (len(cache) > _CACHE_SIZE or total > _CACHE_BYTES):
        old, _ = cache.popitem(last=False)
        total -= sizes[old]
    return value


def _nbytes(value) -> int:
    """Bytes of the arrays of a cached planned job (:attr:`Plan.nbytes`; 0 for a window list)."""
    return int(getattr(getattr(value, "plan", None), "nbytes", 0))


def clear_cache() -> None:
    """Forget cached jobs and plans (e.g. after a G-code file changed in place)."""
    _JOBS.clear()
    _PLANS.clear()


# -- inputs ------------------------------------------------------------------------------------
def resolve_printer(printer):
    """A ``Printer`` from a Printer, a TOML path, or None (the embedded default)."""
    if printer is None or isinstance(printer, (str, os.PathLike)):
        return load_printer(printer)
    return printer


def resolve_job(job, limits=None):
    """(cache key, parsed Job) from a path, G-code text, a Job, the name of a built-in job
    (:data:`ringtune.shaping.builtin_jobs.BUILTIN_JOBS`), or None (built-in test print).

    ``limits``: the printer's (:class:`ringtune.shaping.planner.MachineLimits`): its arcs are cut as
    its firmware cuts them (:func:`ringtune.shaping.arcs.arc_resolution`; None: tolerance chords) —
    what reads a job beside the printer's plan of it passes the same, so their moves match."""
    job = job_path(job)
    res = arc_resolution(limits)
    if job is None:
        key = ("builtin",)
    elif isinstance(job, (str, os.PathLike)):
        p = Path(job)
        if isinstance(job, str) and "\n" in job:
            key = ("text", hash(job), res)
        elif p.is_file():
            st = p.stat()
            key = ("file", str(p.resolve()), st.st_mtime_ns, st.st_size, res)
        else:
            raise RingtuneError("no such G-code file", str(job))
    else:
        return ("object", id(job)), job
    if key in _JOBS:
        _JOBS.move_to_end(key)
        return key, _JOBS[key]
    twin = _arc_free_twin(key)
    if twin is not None:      # a job without arcs reads the same whoever cuts arcs: only its record differs
        return key, _remember(_JOBS, key, dataclasses.replace(twin, arcs=(0, res, ())))
    parsed = testprints.builtin_test_print() if job is None else gcode.read_gcode(job, arc_resolution=res)
    return key, _remember(_JOBS, key, parsed)


def _arc_free_twin(key):
    """The job cached for the same file or text read with another arc resolution (``key`` but its
    last item), where it has no arcs (G2/G3): the moves read are the same, so the file is not read
    again; else None."""
    if key[0] not in ("file", "text"):
        return None
    for other, job in _JOBS.items():
        if other[:-1] == key[:-1] and not job.arcs[0] and not job.arcs[2]:
            return job
    return None


#: the job's acceleration settings Klipper and Kalico take (:func:`job_accel_commands`): M204 S or
#: P and T together, SET_VELOCITY_LIMIT ACCEL, Kalico's X_ACCEL/Y_ACCEL — no M201, no lone M204 P or T
KLIPPER_ACCEL_SETTINGS = ("accel_klipper", *KLIPPER_AXIS_SETTINGS.values())


def job_accel_commands(job, limits) -> dict[str, float]:
    """The acceleration commands a parsed job sets itself that a firmware reading it as ``limits``
    says (:attr:`ringtune.shaping.planner.MachineLimits.reads_like_klipper`) takes: {setting:
    largest value it sets} (mm/s²; keys of :data:`ringtune.shaping.config_plan.JOB_ACCEL_SETTINGS`,
    as Klipper reads a job those of :data:`KLIPPER_ACCEL_SETTINGS`; empty when it sets none)."""
    out = {}
    for k in (KLIPPER_ACCEL_SETTINGS if limits.reads_like_klipper else JOB_ACCEL_SETTINGS):
        col = np.asarray(job.settings_table)[:, SETTING_KEYS.index(k)]
        col = col[~np.isnan(col)]
        if len(col):
            out[k] = float(col.max())
    return out


def _plan_settings(config: TuneConfig | None) -> tuple:
    """What of ``config`` changes the plan: (frequency limit (Hz, method, speed factor), accel,
    DAA frequency, per-axis caps, per-feature settings (accelerations by class, corner, minimum
    cruise ratio) or None)."""
    if config is None:
        return (0.0, "", 0.0), None, None, (None, None), None
    fl = ((float(config.freq_limit_hz), config.freq_limit_method, float(config.min_speed_factor))
          if config.freq_limit_hz > 0 else (0.0, "", 0.0))
    accel = None if config.accel is None else float(config.accel)
    feature = ((tuple(sorted(config.feature_accel.items())), config.corner, config.min_cruise_ratio,
                tuple(sorted(config.feature_corner.items())), tuple(sorted(config.feature_min_cruise_ratio.items())))
               if config.per_feature else None)
    return fl, accel, config.daa_freq, config.axis_caps, feature


def planned_job(printer, job=None, config: TuneConfig | None = None, *,
                max_windows: int = MAX_WINDOWS, span: float = WINDOW_SPAN,
                job_accel: str | None = None) -> PlannedJob:
    """Parse, frequency-limit and plan ``job`` for ``printer`` under ``config`` (cached).

    ``job_accel``: how ``config.accel`` meets the job's own acceleration commands
    (:func:`ringtune.shaping.config_plan.job_accel_mode`). The quality windows are chosen once, on
    the plan at the printer's own limits without frequency limit (the job's own accelerations and
    corner settings left out: :func:`_reference_windows`), and every configuration is judged on
    those same corners and zigzags (:func:`ringtune.shaping.testprints.relocate_windows`)."""
    mode = job_accel_mode(config, job_accel)
    limits = printer.limits
    jkey, parsed = resolve_job(job, for_firmware(limits, config))
    settings = _plan_settings(config)
    fl, accel, daa, caps, feature = settings
    if accel is None:
        mode = "replace"       # nothing to replace with: the job's and the machine's limits as they are
    key = (jkey, repr(for_firmware(limits, config)), fl, accel, daa, max_windows, span, mode, caps, feature)
    if key in _PLANS:
        _PLANS.move_to_end(key)
        return _PLANS[key]
    plan = plan_with_config(parsed, limits, config, job_accel=mode).plan
    # the corners and zigzags the printer's own plan chose, at this plan's times
    windows = testprints.relocate_windows(plan, _reference_windows(jkey, parsed, limits, max_windows, span), span=span)
    pj = PlannedJob(plan, list(windows))
    if key[0][0] == "object":  # keep the job alive so its id is not reused while cached
        pj.source = parsed  # type: ignore[attr-defined]
    return _remember(_PLANS, key, pj)


def windows_sentence(pj: PlannedJob) -> str:
    """Where a planned job's quality measures are taken, in words: how many quality windows, how
    much of the print time they span (s), what they hold; the rest of the job is planned only."""
    kinds = [w.kind.split("-")[0] for w in pj.windows]
    words = (("corner", "sharpest corner"), ("zigzag", "fastest zigzag"), ("seam", "seam"))
    held = ", ".join(f"{n} {word}{'s' if n > 1 else ''}" for k, word in words if (n := kinds.count(k)))
    span = sum(w.t1 - w.t0 for w in pj.windows)
    return (f"measures: the worst over the job's {len(pj.windows)} quality windows, {span:.1f} s of its "
            f"{pj.print_time:.1f} s ({held} of its features, chosen on the printer's own plan), each simulated "
            "with its lead-in; the rest of the job is planned, not simulated")


def require_windows(pj: PlannedJob, job) -> PlannedJob:
    """``pj`` where it has quality windows to judge; else a :class:`RingtuneError` naming the job
    and why (a job that extrudes nothing: a "no extrusion" flavour, a dry run)."""
    if pj.windows:
        return pj
    _key, parsed = resolve_job(job)       # whether it extrudes: the same however its arcs are cut
    why = ("the job extrudes nothing (no move adds filament while X/Y move; a slicer's \"no extrusion\" G-code "
           "flavour writes no E)" if not parsed.extruding.any() else
           "the job has no corner, zigzag or seam of printed lines to judge")
    raise RingtuneError(f"{why}: ringtune judges what a printed part shows, so there is nothing to judge here "
                        "(`ringtune plan` gives its print time)", parsed.source)


def _reference_windows(jkey, parsed, limits, max_windows: int, span: float) -> list:
    """The quality windows of a job, chosen on its plan at the printer's own limits: the job's own
    accelerations, X/Y caps and corner settings left out (:data:`REFERENCE_FREE`), so a job and
    the same job rewritten with per-feature commands (``ringtune rewrite``) are judged on the
    same corners and zigzags (cached)."""
    key = ("windows", jkey, repr(limits), max_windows, span)
    if key not in _PLANS:
        cols = [SETTING_KEYS.index(k) for k in REFERENCE_FREE]
        table = np.array(parsed.settings_table, dtype=float, copy=True)
        table[:, cols] = np.nan
        plan = plan_with_config(dataclasses.replace(parsed, settings_table=table), limits, None).plan
        _remember(_PLANS, key, testprints.quality_windows(plan, max_windows=max_windows, span=span))
    _PLANS.move_to_end(key)
    return _PLANS[key]


