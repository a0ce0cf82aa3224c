"""Evaluate a tuning configuration on a job: the one call ``tune`` (Optuna) and the PPO env use.

Print time comes from the planner over the whole job (no physics); quality comes from physics on
the job's quality windows (sharpest corners, fastest zigzags, seams), each simulated with enough
lead-in for the shaper and the machine to settle:

1. :func:`ringtune.envs.planned_job.planned_job`: the job planned under the configuration, with
   its quality windows (cached);
2. :func:`ringtune.envs.windows.window_runs`: each window shaped with the config's shapers;
3. all windows of all configs (and of the printer's variants) go to one ``simulate_batch`` call;
4. :func:`ringtune.envs.windows.metrics_of`: the job's metrics, the worst window's.
"""

from __future__ import annotations

import dataclasses
from collections import OrderedDict
from typing import Sequence

from ringtune.envs.metrics import Metrics, worst_case
from ringtune.envs.plan_load import plan_load
from ringtune.envs.planned_job import PlannedJob, planned_job, require_windows, resolve_printer
from ringtune.envs.sim import auto_timestep, simulate_batch
from ringtune.envs.variants import variant_factors
from ringtune.envs.window_dedup import WindowMemo, moved
from ringtune.envs.windows import (SETTLE_MIN, WindowRun, auto_settle, corner_tail, metrics_of, window_metrics,
                                   window_runs)
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.motion import Motion


def with_plan_load(metrics: Metrics, printer, pj: PlannedJob) -> Metrics:
    """``metrics`` with the motors' load over every move of the job (rigid machine,
    :func:`ringtune.envs.plan_load.plan_load`, once per plan; the printer's variants share its
    masses and motors) taken into ``motor_load`` beside the simulated windows' (the larger counts;
    above 1 a motor loses steps: ``step_loss``). ``details["plan_load"]``: the plan's figure, the
    motor, the time (s) and the G-code line of the move."""
    key = repr((printer.moving_mass("x"), printer.moving_mass("y"), printer.drive_motors()))
    cached = getattr(pj, "_plan_load", None)
    if cached is None or cached[0] != key:
        cached = (key, plan_load(printer, pj.plan.xy_kinematics()))
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
                  freq_margin: float = 0.0, job_accel: str | None = None,
                  memo: WindowMemo | None = None, windows: Sequence[int] | None = None) -> list[Metrics]:
    """:func:`evaluate` for many configs, all their windows simulated in one ``simulate_batch``.

    ``freq_margin`` > 0 (a fraction, e.g. 0.05): each config is also judged on the printer with
    every resonance ``freq_margin`` lower and higher and its damping ratios × ``TWIN_DAMPING``
    (:func:`variant_factors`), and the worst quality counts
    (:func:`ringtune.envs.metrics.worst_case`), so that a shaper tuned to the edge of its band on
    the exact model is not preferred to one that survives the drift of a real printer or a damping
    ratio fitted high. ``memo``: windows measured before are not simulated again
    (:class:`ringtune.envs.window_dedup.WindowMemo`). ``windows``: only these of each config's
    shaped quality windows (indices, in the job's order, those it has; None: all), the figures the
    worst of those (a screen that rejects on a few windows what the whole job rejects)."""
    return [m for m, _ in evaluate_judged(configs, printer, job, backend, settle=settle, nthread=nthread,
                                          freq_margin=freq_margin, job_accel=job_accel, memo=memo, windows=windows)]


def evaluate_judged(configs: Sequence[TuneConfig], printer=None, job=None, backend: str = "mujoco", *,
                    settle: float | None = None, nthread: int | None = None,
                    freq_margin: float = 0.0, job_accel: str | None = None,
                    job_shapers: bool = False, memo: WindowMemo | None = None, windows: Sequence[int] | None = None
                    ) -> list[tuple[Metrics, list["Evaluation"]]]:
    """:func:`evaluate_many`'s figures with what they came from: per config, (the judged metrics,
    its :class:`Evaluation` on each printer variant of :func:`variant_factors`). ``tune`` and
    ``simulate`` both judge through here, so their figures for one configuration are the same.
    ``job_shapers``: the job's own shaper commands apply (:func:`window_runs`; ``simulate``), else
    the configuration's shapers rule the whole job (``tune``: the shaper being tuned); ``windows``:
    as :func:`evaluate_many`."""
    if not 0 <= freq_margin < 1:
        raise RingtuneError(f"must be in [0, 1), not {freq_margin}", "freq_margin")
    printer = resolve_printer(printer)
    if settle is None:
        settle = auto_settle(printer)
    factors = variant_factors(freq_margin)
    runs = evaluate_variants(configs, [v.of(printer) for v in factors], job, backend, settle=settle, nthread=nthread,
                             job_accel=job_accel, job_shapers=job_shapers, memo=memo, windows=windows)
    per_config = [list(evs) for evs in zip(*runs)]        # per config, its Evaluation per variant
    return [(evs[0].metrics if len(evs) == 1 else worst_case((e.metrics for e in evs), factors), evs)
            for evs in per_config]


def evaluate_twins(configs: Sequence[TuneConfig], exact: Sequence[Metrics], printer=None, job=None,
                   backend: str = "mujoco", *, freq_margin: float, job_accel: str | None = None,
                   nthread: int | None = None, memo: WindowMemo | None = None) -> list[Metrics]:
    """:func:`evaluate_many` with ``freq_margin`` for configurations whose figures on the exact model
    (``exact``: :func:`evaluate_many` with no margin, same printer, job and backend) are known: only
    the detuned twins are simulated, and the worst of the three counts, as :func:`evaluate_judged`
    takes it (a screen on the exact model that passes costs no second simulation of it)."""
    printer = resolve_printer(printer)
    factors = variant_factors(freq_margin)
    twins = [v.of(printer) for v in factors if not v.exact]
    runs = evaluate_variants(configs, twins, job, backend, settle=auto_settle(printer), nthread=nthread,
                             job_accel=job_accel, memo=memo)
    return [worst_case([m, *(e.metrics for e in evs)], factors) for m, evs in zip(exact, zip(*runs))]


@dataclasses.dataclass
class Evaluation:
    """Everything one evaluation produced (for plots and reports)."""

    config: TuneConfig
    metrics: Metrics
    planned: PlannedJob
    runs: list[WindowRun]
    sims: list | None         # SimResult per run (None: measured through a WindowMemo)


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
                      job_shapers: bool = False, memo: WindowMemo | None = None,
                      windows: Sequence[int] | None = None) -> list[list[Evaluation]]:
    """:func:`evaluate_detailed` of ``configs`` on each of ``printers`` (variants of one printer
    with the same limits: its resonances detuned), per printer a list per config. Each config's
    job is planned and its windows shaped once (only the corner tail depends on the variant), and
    the windows of all variants whose integration step is the same go to one ``simulate_batch``
    (as many replicas, threads over the cores): the same figures as one call per variant, for
    less than the cost of one call per variant. With ``memo`` only the windows it does not know are
    simulated (each distinct one once) and then remembered; the evaluations then carry no
    simulations (``sims`` None), only their figures. ``windows``: as :func:`evaluate_many`."""
    printers = [resolve_printer(p) for p in printers]
    prepared = []
    for cfg in configs:
        pj = require_windows(planned_job(printers[0], job, cfg, job_accel=job_accel), job)
        runs = shaped_windows(pj, cfg, settle, corner_tail(printers[0]), job_shapers)
        prepared.append((cfg, pj, runs if windows is None else [runs[i] for i in windows if i < len(runs)]))
    per_printer = []
    for p in printers:
        tail = corner_tail(p)
        per_printer.append([(cfg, pj, runs if tail == corner_tail(printers[0]) else
                             [dataclasses.replace(r, corner_tail=tail) for r in runs]) for cfg, pj, runs in prepared])
    if memo is not None:
        return _remembered(printers, per_printer, backend, nthread, memo)
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


def _remembered(printers: list, per_printer: list, backend: str, nthread: int | None, memo: WindowMemo
                ) -> list[list[Evaluation]]:
    """:func:`evaluate_variants`' evaluations with ``memo``: each window's measures remembered,
    else simulated (each distinct window of the call once) and remembered."""
    keys = [[[memo.key(p, backend, r) for r in runs] for _c, _pj, runs in pp] for p, pp in zip(printers, per_printer)]
    found: dict = {}
    todo: list[list] = [[] for _ in printers]
    for k, pp in enumerate(per_printer):
        for (_c, _pj, runs), ks in zip(pp, keys[k]):
            for run, key in zip(runs, ks):
                if key not in found:
                    got = memo.get(key, run)
                    found[key] = (got, run) if got is not None else None
                    if got is None:
                        todo[k].append((key, run))
    sims = _simulate_grouped(printers, [[r.shaped for _k, r in t] for t in todo], backend, nthread)
    for t, psims in zip(todo, sims):
        for (key, run), sim in zip(t, psims):
            found[key] = (window_metrics(run, sim), run)
            memo.put(key, run, found[key][0])
    out = []
    for k, pp in enumerate(per_printer):
        evs = []
        for (cfg, pj, runs), ks in zip(pp, keys[k]):
            parts = [moved(*found[key], run) for run, key in zip(runs, ks)]
            evs.append(Evaluation(cfg, with_plan_load(Metrics.worst(parts, print_time_s=pj.print_time), printers[0], pj),
                                  pj, runs, None))
        out.append(evs)
    return out


#: the windows last shaped, by plan and configuration (the study shapes a trial's windows for the
#: printer as modelled, then again for its twins: the same windows)
_SHAPED: "OrderedDict[tuple, tuple]" = OrderedDict()
_SHAPED_MAX = 8


def shaped_windows(pj: PlannedJob, cfg: TuneConfig, settle: float, tail: float, job_shapers: bool) -> list[WindowRun]:
    """:func:`ringtune.envs.windows.window_runs` of ``pj`` under ``cfg``, shaped once for a few
    calls in a row (the corner tail, which only the metrics read, set per call)."""
    key = (id(pj), cfg.key(), settle, job_shapers)
    hit = _SHAPED.get(key)
    if hit is None or hit[0] is not pj:
        hit = (pj, window_runs(pj, cfg, settle, tail, job_shapers))
        _SHAPED[key] = hit
        while len(_SHAPED) > _SHAPED_MAX:
            _SHAPED.popitem(last=False)
    _SHAPED.move_to_end(key)
    return [r if r.corner_tail == tail else dataclasses.replace(r, corner_tail=tail) for r in hit[1]]


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
