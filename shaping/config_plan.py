"""A job planned under a TuneConfig: the one path from a parsed job to its plan that ``ringtune plan``
and :func:`ringtune.envs.planned_job.planned_job` (every tuning trial) share.

1. the config's acceleration (mm/s²) is the machine's printing and travel acceleration (export
   sends ``M204 P T``; a retract acceleration, Marlin's ``M204 R``, stays), and its per-axis caps (``max_accel_x``/``y``)
   replace the machine's X/Y caps; how it meets the job's own acceleration
   commands is the job-acceleration mode (:data:`JOB_ACCEL_MODES`, argument ``job_accel`` or the
   config's ``extra["job_accel"]``): ``replace`` (default) — it replaces the job's own commands
   (M204, SET_VELOCITY_LIMIT ACCEL and the X/Y caps of M201) at every feature change, as the
   rewritten file does (step 3: a first layer the job slows itself and its retract acceleration
   kept), what re-slicing at that acceleration with the machine limits raised to it gives;
   ``respect`` — the job's commands stand and ``config.accel`` rules wherever the job sets none
   (the print as sliced);
2. the config's frequency limit rewrites the requested feedrates (``shaping.freqlimit``), unless
   the job's header says ``ringtune limit`` already did, with the same settings; without
   one, a job's own Marlin ``M201 F`` (XY_FREQUENCY_LIMIT) does, as Marlin would, unless the job's
   own limits are ignored; Marlin's emulation takes the machine's per-axis maximum feedrates;
3. a per-feature configuration (:attr:`TuneConfig.per_feature`: accelerations per feature class,
   the corner rule, Klipper's minimum_cruise_ratio) becomes the job's own settings move by move
   (:func:`ringtune.shaping.feature_settings.with_feature_settings`), over the job's own
   printing and travel accelerations (and X/Y caps where it sets them) whatever the mode — what
   the job rewriter writes into the file; the job's retract acceleration (M204 R) stays;
4. the planner plans, with RepRapFirmware ≤ 3.3's DAA when the config (or the caller) selects it.

Before all that, each firmware retraction (G10/G11) whose settings are known becomes the E-only move
the firmware makes (:func:`ringtune.shaping.firmware_retraction.with_firmware_retractions`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.feature_settings import FeatureCommands, with_feature_settings
from ringtune.shaping.firmware import job_reading
from ringtune.shaping.firmware_retraction import with_firmware_retractions, without_inserted
from ringtune.shaping.freqlimit import apply_freq_limit
from ringtune.shaping.job import Job
from ringtune.shaping.job_shapers import with_firmware_shaper_stops
from ringtune.shaping.plan_result import Plan
from ringtune.shaping.planner import MachineLimits, plan
from ringtune.shaping.prusa_limits import hardware_limits, job_model

#: how a config's acceleration meets the job's own acceleration commands (module docstring)
JOB_ACCEL_MODES = ("replace", "respect")
#: the job's own accelerations and X/Y acceleration caps (what "replace" overrules)
JOB_ACCEL_SETTINGS = ("accel_print", "accel_travel", "accel_retract", "accel_klipper", "max_accel_x",
                      "max_accel_y", "limited_accel_x", "limited_accel_y")


@dataclass(frozen=True)
class FreqLimitApplied:
    """The frequency limit a plan was made with: Hz, method, how many moves it slowed, and
    ``source`` (``"config"`` or ``"job M201 F"``)."""

    hz: float
    method: str
    moves_slowed: int
    source: str


@dataclass(frozen=True)
class ConfiguredPlan:
    """The plan, the limits it used (the config's acceleration in), the frequency limit applied
    (None: none), the DAA frequency planned with (Hz, None: off) and the job as planned (its
    requested speeds after the frequency limit: what ``plan`` reports commanded frequencies of)."""

    plan: Plan
    limits: MachineLimits
    freq_limit: FreqLimitApplied | None
    daa_hz: float | None
    job: Job | None = None


def job_accel_mode(config: TuneConfig | None, job_accel: str | None = None) -> str:
    """The job-acceleration mode: ``job_accel`` if given, else the config's ``extra["job_accel"]``,
    else ``"replace"``."""
    mode = job_accel or (config.extra.get("job_accel") if config is not None and config.extra else None) \
        or "replace"
    if mode not in JOB_ACCEL_MODES:
        raise RingtuneError(f"must be one of {', '.join(JOB_ACCEL_MODES)}, not {mode!r}", "job_accel")
    return mode


def sets_accel(job: Job) -> bool:
    """Whether the parsed job sets any acceleration of its own (:data:`JOB_ACCEL_SETTINGS`)."""
    return job.sets(JOB_ACCEL_SETTINGS)


def as_read_by(firmware: str | None) -> TuneConfig | None:
    """A configuration that sets nothing: a job planned with it is the job as ``firmware`` reads it
    (None: as the printer's own, ``[current] firmware``, does)."""
    return TuneConfig(firmware=firmware, accel=None) if firmware else None


def with_axis_caps(limits: MachineLimits, config: TuneConfig | None) -> MachineLimits:
    """``limits`` with the X/Y acceleration caps the config runs with (:attr:`TuneConfig.axis_caps`)."""
    caps = (None, None) if config is None else config.axis_caps
    if caps == (None, None):
        return limits
    old = tuple(limits.max_accel) if limits.max_accel is not None else (0.0, 0.0, 0.0, 0.0)
    new = tuple(float(c) if c is not None else o for c, o in zip(caps, old[:2])) + old[2:]
    return replace(limits, max_accel=new)


def _carries(job: Job, config: TuneConfig) -> bool:
    """Whether the job's F words already carry the config's frequency limit (its ``ringtune limit``
    header names the same Hz, method and speed floor): then it is not applied twice."""
    if job.limited is None:
        return False
    hz, method, floor = job.limited
    return (method == config.freq_limit_method and abs(hz - config.freq_limit_hz) <= 1e-5 * hz
            and abs(floor - config.min_speed_factor) <= 1e-5 * max(floor, 1e-9))


def for_firmware(limits: MachineLimits, config: TuneConfig | None, job: Job | None = None) -> MachineLimits:
    """``limits`` as the firmware the configuration is for reads a job: RepRapFirmware its M203
    in mm/min, Marlin and Prusa without RRF's M566, Prusa held to the hardware limits of the model
    ``job`` names (:mod:`ringtune.shaping.prusa_limits`, normal mode) (None: the printer's own,
    ``[current] firmware``)."""
    if config is None:
        return limits
    limits = replace(limits, **job_reading(config.firmware))
    hw = hardware_limits(job_model(job)) if config.firmware == "prusa" and job is not None else None
    return limits if hw is None else replace(limits, hw_max_accel=hw.max_accel, hw_max_velocity=hw.max_velocity,
                                             hw_max_jerk=hw.jerk)


def plan_with_config(job: Job, limits: MachineLimits, config: TuneConfig | None = None, *,
                     use_job_limits: bool = True, daa_freq: float | None = None,
                     job_accel: str | None = None) -> ConfiguredPlan:
    """Plan ``job`` on a machine with ``limits`` under ``config`` (None: as the job is).

    ``use_job_limits``: whether the job's own M201/M203/M204/M205/SET_VELOCITY_LIMIT lines (and its
    M201 F) apply. ``daa_freq`` (Hz) overrides the config's DAA (:attr:`TuneConfig.daa_freq`).
    ``job_accel``: ``replace`` or ``respect`` (:func:`job_accel_mode`).
    """
    mode = job_accel_mode(config, job_accel)
    limits = for_firmware(with_axis_caps(limits, config), config, job)
    job = with_firmware_retractions(job, limits)   # G10/G11 as the E-only moves the firmware makes, where known
    accel = None if config is None or config.accel is None else float(config.accel)
    if accel is not None:     # export sends it as printing and travel acceleration (M204 P T)
        limits = replace(limits, accel=accel, travel_accel=None)
    # over the job's own, as the rewritten file has them: one acceleration replacing the job's own
    # commands is written at every feature change too (the job's slowed first layer and its retract
    # acceleration, M204 R, kept); a job with none of its own takes it as the machine's (the same plan)
    if config is not None and (config.per_feature or (mode == "replace" and accel is not None and sets_accel(job))):
        job = with_feature_settings(job, FeatureCommands.from_config(config, limits))
        accel = None          # the settings are the job's own now, move by move
    if config is not None:      # the firmware is known: it stops where its own shaper commands change the shaping
        job = with_firmware_shaper_stops(job, config)
    job, freq_limit = _freq_limited(job, limits, config, use_job_limits)
    daa = daa_freq if daa_freq is not None else (None if config is None else config.daa_freq)
    # replace: the config's acceleration wins over the job's own commands (a tuning knob);
    # respect: it is the machine's acceleration (limits.accel), the job's commands stand
    planned = plan(job, limits, daa_freq=daa, use_job_limits=use_job_limits,
                   accel=accel if mode == "replace" else None)
    return ConfiguredPlan(planned, limits, freq_limit, daa, without_inserted(job))


def _freq_limited(job: Job, limits: MachineLimits, config: TuneConfig | None,
                  use_job_limits: bool) -> tuple[Job, FreqLimitApplied | None]:
    """``job`` under the direction-change frequency limit that applies, and which one: the config's
    (already carried by a rewritten job, or applied here), else the job's own M201 F, else none."""
    if config is not None and config.freq_limit_hz > 0:
        hz, method = float(config.freq_limit_hz), config.freq_limit_method
        if _carries(job, config):
            return job, FreqLimitApplied(hz, method, 0, "job (ringtune limit)")
        limited = apply_freq_limit(job, hz, method, float(config.min_speed_factor), max_velocity=limits.max_velocity)
        return limited, FreqLimitApplied(hz, method, int(np.sum(limited.feed < job.feed)), "config")
    # Klipper has no M201 F
    if use_job_limits and job.file_setting("freq_limit_hz") > 0 and not limits.reads_like_klipper:
        limited = apply_freq_limit(job, None, "marlin", max_velocity=limits.max_velocity)
        return limited, FreqLimitApplied(job.file_setting("freq_limit_hz"), "marlin",
                                         int(np.sum(limited.feed < job.feed)), "job M201 F")
    return job, None
