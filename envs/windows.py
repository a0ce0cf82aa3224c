"""The quality windows of a planned job prepared for simulation and measured (s, mm).

Each window ``[t0, t1]`` is cut from the unshaped motion with margins, shaped with the config's
shapers (centred or causal per the firmware flavour), and cut again to ``[t0 − lead, t1 + tail]``
where the shaped command is exact (``lead = shaper duration + settle``, ``tail = shaper
duration``; ``settle`` defaults to :func:`auto_settle` of the printer); after simulation,
:func:`ringtune.envs.window_metrics.compute_metrics` on the samples inside each ``[t0, t1]``
(unshaped clock), the job's metrics the worst window's (:meth:`Metrics.worst`).
"""

from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace

import numpy as np

from ringtune.envs.metrics import Metrics
from ringtune.envs.planned_job import PlannedJob
from ringtune.envs.window_metrics import CORNER_TAIL, compute_metrics
from ringtune.shaping.apply import shape_motion
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.e_timing import extruder_command
from ringtune.shaping.features import FEATURE_CLASSES, class_indices
from ringtune.shaping.firmware import FIRMWARES
from ringtune.shaping.job_shapers import config_at, shaper_timeline
from ringtune.shaping.motion import Motion
from ringtune.shaping.seams import job_seen_classes
from ringtune.shaping.shapers import shapers_from_config

#: bounds (s) of the simulated history before each window beyond the shaper's duration; within
#: them it is SETTLE_TAUS decay time constants 1/(ζω) of the printer's slowest-decaying mode, so
#: vibration left by earlier motion is simulated, not cut off
SETTLE_MIN, SETTLE_MAX, SETTLE_TAUS = 0.05, 0.3, 3.0
#: bounds (s) of the part of a corner after the shaped command has turned (see corner_tail)
CORNER_TAIL_MIN, CORNER_TAIL_MAX = 0.005, 0.03


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
    seen_classes: frozenset | None = None  # the job's seen classes (None: VISIBLE), see compute_metrics


def slowest_tau(printer) -> float:
    """s: the time constant 1/(ζω) of the printer's slowest-decaying mode (0 without modes)."""
    rates = [m.damping * m.omega for ax in ("x", "y") for m in printer.effective_modes(ax)]
    return float(1.0 / max(min(rates), 1e-9)) if rates else 0.0


def auto_settle(printer) -> float:
    """s of history simulated before each window: SETTLE_TAUS time constants of the printer's
    slowest-decaying mode (:func:`slowest_tau`), clipped to [SETTLE_MIN, SETTLE_MAX]."""
    return float(min(max(SETTLE_TAUS * slowest_tau(printer), SETTLE_MIN), SETTLE_MAX))


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
    plan = pj.plan
    seen = job_seen_classes(pj.plan)
    runs, shaping = [], {}
    for w in pj.windows:
        cfg = config_at(timeline, w.t0)
        if id(cfg) not in shaping:          # the shapers of each configuration in force, built once
            shapers, centred = shapers_from_config(cfg)
            shaping[id(cfg)] = (shapers, centred, any(s is not None for s in shapers.values()),
                                shaper_timing(shapers, centred))
        shapers, centred, active, (duration, lag, after, before) = shaping[id(cfg)]
        a, b = w.t0 - duration - settle, w.t1 + duration
        lo, hi = max(a - duration, plan.start_time), min(b + duration, plan.end_time)
        if hi - lo <= 1e-9:
            continue
        raw = plan.motion_window(lo, hi)
        shaped = shape_motion(raw, shapers, centred) if active else raw
        a, b = max(a, shaped.start_time), min(b, shaped.end_time)
        path = plan.motion_window(max(a, lo), min(b, hi))
        e_cmd, synced = _extruder(raw, shapers, centred, cfg)
        runs.append(WindowRun(w.t0, w.t1, shaped.window(a, b), path, lag, after, before,
                              segment_classes(pj, path), e_cmd, synced, tail, seen))
    return runs


def _trimmed(sim, t_lo: float, t_hi: float):
    """The samples of ``sim`` with t in [t_lo, t_hi] (a shallow copy with sliced arrays; the
    sample times increase, so the samples kept are one run of them)."""
    t = np.asarray(sim.t)
    keep = slice(int(np.searchsorted(t, t_lo, side="left")), int(np.searchsorted(t, t_hi, side="right")))
    fields = {}
    for f in ("t", "commanded", "nozzle", "head_accel", "motor_force", "motor_force_max", "accel_sensor"):
        v = getattr(sim, f, None)
        if v is not None and np.ndim(v) >= 1 and len(v) == len(t):
            fields[f] = np.asarray(v)[keep]
    return SimpleNamespace(step_loss=bool(getattr(sim, "step_loss", False)), **fields)


def window_metrics(run: WindowRun, sim) -> Metrics:
    """One simulated window's metrics (its samples inside [t0, t1] on the unshaped clock)."""
    return compute_metrics(_trimmed(sim, run.t0 + run.lag, run.t1 + run.lag), run.path,
                           lag=run.lag, settle=run.settle, anticipate=run.anticipate,
                           classes=run.classes, e_command=run.e_command,
                           e_command_synced=run.e_synced, corner_tail=run.corner_tail,
                           seen_classes=run.seen_classes)


def metrics_of(runs: list[WindowRun], sims: list, print_time: float) -> Metrics:
    """Job metrics from the simulated windows: the worst window's values."""
    return Metrics.worst([window_metrics(run, sim) for run, sim in zip(runs, sims)], print_time_s=print_time)


