"""Evaluate a tuning configuration on a job: the one call ``tune`` (Optuna) and the PPO env use.

Print time comes from the planner over the whole job (no physics); quality comes from physics on
the job's quality windows (sharpest corners, fastest zigzags), each simulated with enough lead-in
for the shaper and the machine to settle:

1. job (G-code path, G-code text, a parsed ``Job``, or None for the built-in test print)
   → :func:`ringtune.shaping.config_plan.plan_with_config` with the printer's limits (the config's
   acceleration per the job-acceleration mode ``job_accel``, its frequency limit, DAA) → print
   time, s;
2. ``quality_windows`` of that plan; each window ``[t0, t1]`` is cut from the unshaped motion with
   margins, shaped with the config's shapers (centred or causal per the firmware flavour), and cut
   again to ``[t0 − lead, t1 + tail]`` where the shaped command is exact
   (``lead = shaper duration + settle``, ``tail = shaper duration``; ``settle`` defaults to
   :func:`auto_settle` of the printer);
3. all windows of all configs go to one ``simulate_batch`` call;
4. :func:`ringtune.envs.metrics.compute_metrics` on the samples inside each ``[t0, t1]``
   (unshaped clock); the job's metrics are the worst window's (:meth:`Metrics.worst`).

Parsed jobs and plans (with their windows) are cached per (job, limits, frequency limit), so
repeated evaluations of configurations that only change the shaper skip parsing and planning.
Everything is deterministic.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections import OrderedDict
from pathlib import Path
from types import SimpleNamespace
from typing import Any, Sequence

import numpy as np

from ringtune.envs.metrics import CORNER_TAIL, Metrics, compute_metrics, worst_case
from ringtune.envs.plan_load import plan_load
from ringtune.envs.printer import load_printer
from ringtune.envs.sim import auto_timestep, simulate_batch
from ringtune.envs.variants import variant_factors
from ringtune.shaping import gcode, testprints
from ringtune.shaping.apply import shape_motion
from ringtune.shaping.builtin_jobs import job_path
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.config_plan import JOB_ACCEL_SETTINGS, job_accel_mode, plan_with_config
from ringtune.shaping.e_timing import extruder_command
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.features import FEATURE_CLASSES, class_indices
from ringtune.shaping.firmware import FIRMWARES
from ringtune.shaping.job import SETTING_KEYS
from ringtune.shaping.job_shapers import config_at, shaper_timeline
from ringtune.shaping.motion import Motion
from ringtune.shaping.shapers import shapers_from_config

#: bounds (s) of the simulated history before each window beyond the shaper's duration; within
#: them it is SETTLE_TAUS decay time constants 1/(ζω) of the printer's slowest-decaying mode, so
#: vibration left by earlier motion is simulated, not cut off
SETTLE_MIN, SETTLE_MAX, SETTLE_TAUS = 0.05, 0.3, 3.0
#: quality windows per job and their span, s
MAX_WINDOWS = 8
WINDOW_SPAN = 0.25
#: bounds (s) of the part of a corner after the shaped command has turned (see corner_tail)
CORNER_TAIL_MIN, CORNER_TAIL_MAX = 0.005, 0.03

_JOBS: "OrderedDict[Any, Any]" = OrderedDict()
_PLANS: "OrderedDict[Any, Any]" = OrderedDict()
_CACHE_SIZE = 64
#: job settings the window choice leaves out (the printer's own limits rule there)
REFERENCE_FREE = (*JOB_ACCEL_SETTINGS, "square_corner_velocity", "junction_deviation", "jerk_x", "jerk_y",
                  "min_cruise_ratio", "accel_to_decel")


@dataclasses.dataclass
class PlannedJob:
    """A planned job and its quality windows (cached)."""

    plan: Any                 # shaping.planner.Plan
    windows: list             # [Window(t0, t1, kind, score)]

    @property
    def print_time(self) -> float:
        return float(self.plan.print_time)

    @property
    def motion(self) -> Motion:
        return self.plan.motion


def _remember(cache: OrderedDict, key, value):
    cache[key] = value
    cache.move_to_end(key)
    while len(cache) > _CACHE_SIZE:
        cache.popitem(last=False)
    return value


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


def resolve_job(job):
    """(cache key, parsed Job) from a path, G-code text, a Job, the name of a built-in job
    (:data:`ringtune.shaping.builtin_jobs.BUILTIN_JOBS`), or None (built-in test print)."""
    job = job_path(job)
    if job is None:
        key = ("builtin",)
    elif isinstance(job, (str, os.PathLike)):
        p = Path(job)
        if isinstance(job, str) and "\n" in job:
            key = ("text", hash(job))
        elif p.is_file():
            st = p.stat()
            key = ("file", str(p.resolve()), st.st_mtime_ns, st.st_size)
        else:
            raise RingtuneError("no such G-code file", str(job))
    else:
        return ("object", id(job)), job
    if key in _JOBS:
        _JOBS.move_to_end(key)
        return key, _JOBS[key]
    parsed = testprints.builtin_test_print() if job is None else gcode.read_gcode(job)
    return key, _remember(_JOBS, key, parsed)


def job_accel_commands(job) -> dict[str, float]:
    """The acceleration commands a parsed job sets itself: {setting: largest value it sets}
    (mm/s²; keys of :data:`ringtune.shaping.config_plan.JOB_ACCEL_SETTINGS`; empty when it sets none)."""
    out = {}
    for k in JOB_ACCEL_SETTINGS:
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
    jkey, parsed = resolve_job(job)
    limits = printer.limits
    settings = _plan_settings(config)
    fl, accel, daa, caps, feature = settings
    if accel is None:
        mode = "replace"       # nothing to replace with: the job's and the machine's limits as they are
    key = (jkey, repr(limits), fl, accel, daa, max_windows, span, mode, caps, feature)
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


# -- shaping the windows -------------------------------------------------------------------------
@dataclasses.dataclass
class WindowRun:
    """One quality window prepared for simulation."""

    t0: float                 # quality window on the unshaped clock, s
    t1: float
    shaped: Motion            # shaped command over [t0 - lead, t1 + tail]
    path: Motion              # unshaped command over the same span (geometry for the metrics)
    lag: float                # s, see compute_metrics
    settle: float             # s, see compute_metrics
    anticipate: float = 0.0   # s, see compute_metrics
    classes: np.ndarray | None = None      # feature class index per segment of ``path``
    e_command: Motion | None = None        # the firmware's extruder on the shaped clock
    e_synced: Motion | None = None         # ... with its E synchronisation on (None: no such option)
    corner_tail: float = CORNER_TAIL       # s, see compute_metrics


def auto_settle(printer) -> float:
    """s of history simulated before each window: SETTLE_TAUS time constants 1/(ζω) of the
    printer's slowest-decaying mode, clipped to [SETTLE_MIN, SETTLE_MAX]."""
    rates = [m.damping * m.omega for ax in ("x", "y") for m in printer.effective_modes(ax)]
    tau = 1.0 / max(min(rates), 1e-9) if rates else 0.0
    return float(min(max(SETTLE_TAUS * tau, SETTLE_MIN), SETTLE_MAX))


def corner_tail(printer) -> float:
    """s after a shaped corner that still belong to it: half the period of the printer's lowest
    mode (its first swing), clipped to [CORNER_TAIL_MIN, CORNER_TAIL_MAX]."""
    freqs = [m.omega / (2.0 * np.pi) for ax in ("x", "y") for m in printer.effective_modes(ax)]
    if not freqs:
        return CORNER_TAIL
    return float(min(max(0.5 / min(freqs), CORNER_TAIL_MIN), CORNER_TAIL_MAX))


def segment_classes(pj: PlannedJob, motion: Motion) -> np.ndarray:
    """(motion.n_segments,) feature class index of each segment of a window of ``pj``'s motion:
    the class of its G-code move's label (``other`` outside any move or without a move table)."""
    out = np.full(motion.n_segments, FEATURE_CLASSES.index("other"), np.int64)
    moves = getattr(pj.plan, "moves", None)
    if moves is None or not len(moves.feature):
        return out
    by_move = class_indices(moves.features)[moves.feature]
    known = motion.move >= 0
    out[known] = by_move[motion.move[known]]
    return out


def _extruder(raw: Motion, shapers, centred: bool, config: TuneConfig):
    """The firmware's extruder command for ``raw``, and with its E synchronisation on (or None)."""
    fw = FIRMWARES[config.firmware]
    e_cmd = extruder_command(raw, shapers, centred, fw)
    synced = extruder_command(raw, shapers, centred, fw, fw.e_sync_timing) if fw.e_sync_timing else None
    return e_cmd, synced


def shaper_timing(shapers, centred: bool) -> tuple[float, float, float, float]:
    """(duration, lag, after, before) of the active shapers, s: the longest impulse train; the
    causal shaped command's delay (0 when centred); after a corner (unshaped time) when the shaped
    command runs straight again (the last impulse has passed); how long before a corner it starts
    turning (centred shapers only)."""
    active = [s for s in shapers.values() if s is not None]
    duration = max((s.duration for s in active), default=0.0)
    if not centred:        # a causal command runs straight once its longest train has passed
        return duration, max((s.centroid for s in active), default=0.0), duration, 0.0
    return (duration, 0.0, max((s.duration - s.centre_delay for s in active), default=0.0),
            max((s.centre_delay for s in active), default=0.0))


def window_runs(pj: PlannedJob, config: TuneConfig, settle: float = SETTLE_MIN,
                tail: float = CORNER_TAIL, job_shapers: bool = False) -> list[WindowRun]:
    """Shape each quality window of ``pj`` with the config's shapers (``settle`` s of extra
    history before each, beyond the shaper's duration); ``tail``: see :func:`corner_tail`.
    ``job_shapers``: the job's own shaper commands apply from where they stand
    (:func:`ringtune.shaping.job_shapers.shaper_timeline`); each window is shaped with the
    shapers in force at its start (``simulate``; ``tune`` judges the configuration's own)."""
    timeline = shaper_timeline(pj.plan.events, config) if job_shapers else [(-math.inf, config)]
    motion = pj.motion
    runs = []
    for w in pj.windows:
        cfg = config_at(timeline, w.t0)
        shapers, centred = shapers_from_config(cfg)
        active = any(s is not None for s in shapers.values())
        duration, lag, after, before = shaper_timing(shapers, centred)
        a, b = w.t0 - duration - settle, w.t1 + duration
        lo, hi = max(a - duration, motion.start_time), min(b + duration, motion.end_time)
        if hi - lo <= 1e-9:
            continue
        raw = motion.window(lo, hi)
        shaped = shape_motion(raw, shapers, centred) if active else raw
        a, b = max(a, shaped.start_time), min(b, shaped.end_time)
        path = motion.window(max(a, lo), min(b, hi))
        e_cmd, synced = _extruder(raw, shapers, centred, cfg)
        runs.append(WindowRun(w.t0, w.t1, shaped.window(a, b), path, lag, after, before,
                              segment_classes(pj, path), e_cmd, synced, tail))
    return runs


def _trimmed(sim, t_lo: float, t_hi: float):
    """The samples of ``sim`` with t in [t_lo, t_hi] (a shallow copy with sliced arrays)."""
    t = np.asarray(sim.t)
    keep = (t >= t_lo) & (t <= t_hi)
    fields = {}
    for f in ("t", "commanded", "nozzle", "head_accel", "motor_force", "motor_force_max", "accel_sensor"):
        v = getattr(sim, f, None)
        if v is not None and np.ndim(v) >= 1 and len(v) == len(t):
            fields[f] = np.asarray(v)[keep]
    return SimpleNamespace(step_loss=bool(getattr(sim, "step_loss", False)), **fields)


def metrics_of(runs: list[WindowRun], sims: list, print_time: float) -> Metrics:
    """Job metrics from the simulated windows: the worst window's values."""
    parts = []
    for run, sim in zip(runs, sims):
        part = compute_metrics(_trimmed(sim, run.t0 + run.lag, run.t1 + run.lag), run.path,
                               lag=run.lag, settle=run.settle, anticipate=run.anticipate,
                               classes=run.classes, e_command=run.e_command,
                               e_command_synced=run.e_synced, corner_tail=run.corner_tail)
        parts.append(part)
    return Metrics.worst(parts, print_time_s=print_time)


def with_plan_load(metrics: Metrics, printer, pj: PlannedJob) -> Metrics:
    """``metrics`` with the motors' load over every move of the job (rigid machine,
    :func:`ringtune.envs.plan_load.plan_load`, once per plan; the printer's variants share its
    masses and motors) taken into ``motor_load`` beside the simulated windows' (the larger counts;
    above 1 a motor loses steps: ``step_loss``). ``details["plan_load"]``: the plan's figure, the
    motor, the time (s) and the G-code line of the move."""
    key = repr((printer.moving_mass("x"), printer.moving_mass("y"), printer.drive_motors()))
    cached = getattr(pj, "_plan_load", None)
    if cached is None or cached[0] != key:
        cached = (key, plan_load(printer, pj.plan.motion))
        pj._plan_load = cached  # type: ignore[attr-defined]
    load = cached[1]
    moves = pj.plan.moves
    line = int(moves.line[load.move]) if 0 <= load.move < len(moves) else None
    metrics.details["plan_load"] = {"load": load.load, "motor": load.motor, "t_s": load.t, "line": line}
    metrics.motor_load = max(metrics.motor_load, load.load)
    metrics.step_loss = metrics.step_loss or load.load > 1.0
    return metrics


# -- the public calls -------------------------------------------------------------------------------
def evaluate(config: TuneConfig, printer=None, job=None, backend: str = "mujoco", *,
             settle: float | None = None, nthread: int | None = None, job_accel: str | None = None) -> Metrics:
    """Print time (whole job) and quality (physics on the quality windows) of ``config``.

    Args:
        config: the tuning configuration.
        printer: a ``Printer``, a printer TOML path, or None for the embedded default.
        job: a G-code path, G-code text, a parsed Job, or None for the built-in test print.
        backend: ``"mujoco"`` (default) or ``"lti"`` (exact linear screening).
        settle: s of simulated lead-in beyond the shaper's duration (None: :func:`auto_settle`).
        nthread: simulation threads (default: up to one per window and core).
        job_accel: ``replace`` or ``respect`` (:func:`ringtune.shaping.config_plan.job_accel_mode`;
            default the config's own, else ``replace``).
    """
    return evaluate_many([config], printer, job, backend, settle=settle, nthread=nthread, job_accel=job_accel)[0]


def evaluate_many(configs: Sequence[TuneConfig], printer=None, job=None, backend: str = "mujoco", *,
                  settle: float | None = None, nthread: int | None = None,
                  freq_margin: float = 0.0, job_accel: str | None = None) -> list[Metrics]:
    """:func:`evaluate` for many configs, all their windows simulated in one ``simulate_batch``.

    ``freq_margin`` > 0 (a fraction, e.g. 0.05): each config is also judged on the printer with
    every resonance ``freq_margin`` lower and higher and its damping ratios × ``TWIN_DAMPING``
    (:func:`variant_factors`), and the worst quality counts
    (:func:`ringtune.envs.metrics.worst_case`), so that a shaper tuned to the edge of its band on
    the exact model is not preferred to one that survives the drift of a real printer or a damping
    ratio fitted high."""
    return [m for m, _ in evaluate_judged(configs, printer, job, backend, settle=settle, nthread=nthread,
                                          freq_margin=freq_margin, job_accel=job_accel)]


def evaluate_judged(configs: Sequence[TuneConfig], printer=None, job=None, backend: str = "mujoco", *,
                    settle: float | None = None, nthread: int | None = None,
                    freq_margin: float = 0.0, job_accel: str | None = None,
                    job_shapers: bool = False) -> list[tuple[Metrics, list["Evaluation"]]]:
    """:func:`evaluate_many`'s figures with what they came from: per config, (the judged metrics,
    its :class:`Evaluation` on each printer variant of :func:`variant_factors`). ``tune`` and
    ``simulate`` both judge through here, so their figures for one configuration are the same.
    ``job_shapers``: the job's own shaper commands apply (:func:`window_runs`; ``simulate``), else
    the configuration's shapers rule the whole job (``tune``: the shaper being tuned)."""
    if not 0 <= freq_margin < 1:
        raise RingtuneError(f"must be in [0, 1), not {freq_margin}", "freq_margin")
    printer = resolve_printer(printer)
    if settle is None:
        settle = auto_settle(printer)
    variants = [v.of(printer) for v in variant_factors(freq_margin)]
    runs = evaluate_variants(configs, variants, job, backend, settle=settle, nthread=nthread, job_accel=job_accel,
                             job_shapers=job_shapers)
    per_config = [list(evs) for evs in zip(*runs)]        # per config, its Evaluation per variant
    return [(evs[0].metrics if len(evs) == 1 else worst_case(e.metrics for e in evs), evs)
            for evs in per_config]


def evaluate_twins(configs: Sequence[TuneConfig], exact: Sequence[Metrics], printer=None, job=None,
                   backend: str = "mujoco", *, freq_margin: float, job_accel: str | None = None) -> list[Metrics]:
    """:func:`evaluate_many` with ``freq_margin`` for configurations whose figures on the exact model
    (``exact``: :func:`evaluate_many` with no margin, same printer, job and backend) are known: only
    the detuned twins are simulated, and the worst of the three counts, as :func:`evaluate_judged`
    takes it (a screen on the exact model that passes costs no second simulation of it)."""
    printer = resolve_printer(printer)
    twins = [v.of(printer) for v in variant_factors(freq_margin) if not v.exact]
    runs = evaluate_variants(configs, twins, job, backend, settle=auto_settle(printer), job_accel=job_accel)
    return [worst_case([m, *(e.metrics for e in evs)]) for m, evs in zip(exact, zip(*runs))]


@dataclasses.dataclass
class Evaluation:
    """Everything one evaluation produced (for plots and reports)."""

    config: TuneConfig
    metrics: Metrics
    planned: PlannedJob
    runs: list[WindowRun]
    sims: list                # SimResult per run


def evaluate_detailed(configs: Sequence[TuneConfig], printer=None, job=None, backend: str = "mujoco", *,
                      settle: float | None = None, nthread: int | None = None,
                      job_accel: str | None = None, job_shapers: bool = False) -> list[Evaluation]:
    """Like :func:`evaluate_many`, keeping the plans, shaped windows and simulation results."""
    printer = resolve_printer(printer)
    if settle is None:
        settle = auto_settle(printer)
    return evaluate_variants(configs, [printer], job, backend, settle=settle, nthread=nthread, job_accel=job_accel,
                             job_shapers=job_shapers)[0]


def evaluate_variants(configs: Sequence[TuneConfig], printers: Sequence, job=None, backend: str = "mujoco", *,
                      settle: float = SETTLE_MIN, nthread: int | None = None, job_accel: str | None = None,
                      job_shapers: bool = False) -> list[list[Evaluation]]:
    """:func:`evaluate_detailed` of ``configs`` on each of ``printers`` (variants of one printer
    with the same limits: its resonances detuned), per printer a list per config. Each config's
    job is planned and its windows shaped once (only the corner tail depends on the variant), and
    the windows of all variants whose integration step is the same go to one ``simulate_batch``
    (as many replicas, threads over the cores): the same figures as one call per variant, for
    less than the cost of one call per variant."""
    printers = [resolve_printer(p) for p in printers]
    prepared = []
    for cfg in configs:
        pj = planned_job(printers[0], job, cfg, job_accel=job_accel)
        prepared.append((cfg, pj, window_runs(pj, cfg, settle, corner_tail(printers[0]), job_shapers)))
    per_printer = []
    for p in printers:
        tail = corner_tail(p)
        per_printer.append([(cfg, pj, runs if tail == corner_tail(printers[0]) else
                             [dataclasses.replace(r, corner_tail=tail) for r in runs]) for cfg, pj, runs in prepared])
    sims = _simulate_grouped(printers, [[r.shaped for _c, _p, runs in pp for r in runs] for pp in per_printer],
                             backend, nthread)
    out = []
    for pp, psims in zip(per_printer, sims):
        evs, i = [], 0
        for cfg, pj, runs in pp:
            part = psims[i:i + len(runs)]
            metrics = with_plan_load(metrics_of(runs, part, pj.print_time), printers[0], pj)
            evs.append(Evaluation(cfg, metrics, pj, runs, part))
            i += len(runs)
        out.append(evs)
    return out


def _simulate_grouped(printers: list, motions: list[list[Motion]], backend: str, nthread: int | None) -> list[list]:
    """``simulate_batch`` of each printer's motions, one call per group of printers sharing an
    integration step (a batch integrates all its printers with the smallest step, so only
    printers of one step are batched together: every result is what a call of its own gives)."""
    groups: dict = {}
    for k, p in enumerate(printers):
        groups.setdefault(auto_timestep(p) if backend == "mujoco" else 0.0, []).append(k)
    out: list = [[] for _ in printers]
    for ks in groups.values():
        flat_p = [printers[k] for k in ks for _ in motions[k]]
        flat_m = [m for k in ks for m in motions[k]]
        sims = simulate_batch(flat_p, flat_m, backend=backend, nthread=nthread, initial="static") if flat_m else []
        i = 0
        for k in ks:
            out[k] = sims[i:i + len(motions[k])]
            i += len(motions[k])
    return out
