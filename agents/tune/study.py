"""The Optuna Pareto study behind ``ringtune tune``: print time against what a person sees.

- Objectives (all minimised, :data:`ringtune.agents.tune.pareto.OBJECTIVES`): ``print_time_s``,
  ``ripple_mm`` (the worst visible wall's peak-to-peak ripple; ``settings.quality`` may name
  another figure) and ``corner_mm`` (the larger of visible corners' rounding and overshoot), from
  ``ringtune.envs.evaluate.evaluate_many`` or an injected evaluator ``f(configs, printer, job) ->
  [Metrics]`` (given as ``"module:function"`` so that worker processes can import it). Why these
  three and not every visible measure: see ``OBJECTIVES``; the others are judged in the choice.
  The default evaluator simulates a trial's detuned twins only where they can count
  (:mod:`ringtune.agents.tune.trial_screen`).
- Constraints: step loss (``trial.set_constraint("step_loss", 1.0 | 0.0)``), the path-error
  bound (``"path_error"``: path_error_mm − ``max_path_error_mm``), the motor reserve
  (``"motor_load"``: motor_load − (1 − reserve), judged like quality on the printer and its
  detuned twins) and the hidden features' bound (``"show_through"``: show_through_mm −
  ``max_show_through_mm``: infill or inner walls reaching the outer wall); infeasible trials never
  reach the front. The bounds are applied again when the results are read, so a resumed study may be
  judged with other bounds.
- Storage (:func:`make_storage`): a journal file in the output folder by default
  (``journal:out/study.journal``), or any RDB URL (``sqlite:///study.db``,
  ``postgresql+psycopg2://...``) with Optuna's heartbeat (stale RUNNING trials of dead workers on
  any machine are failed and re-run once). On this host, a RUNNING trial whose worker process is
  gone is failed and re-run at once, whatever the storage.
- Exactly N: a worker only evaluates a trial while ``complete + running-with-a-lower-number < N``;
  otherwise the trial is pruned without evaluation. Rerunning the same command resumes with the
  trials already complete; after Ctrl-C the current trial finishes first (a second Ctrl-C aborts
  it; it is re-run on the next start).
- Reproducibility: the TPE sampler is reseeded from (seed, trial number) before every trial, so a
  seeded single-worker run — interrupted and resumed, or not — reproduces exactly. The N local
  workers of one run (``--workers N``) share the seed, and trial n waits for every trial numbered
  n − 2N or lower (:data:`LAG_PER_WORKER`) and sees those alone, in its sampler
  (:mod:`ringtune.agents.tune.sampler`) and in the judgement of which twins can count: a seeded
  run with N workers reproduces exactly too, whichever worker runs which trial. (Workers of other
  machines sharing an RDB storage are not in step.)
"""

from __future__ import annotations

import dataclasses
import importlib
import json
import os
import signal
import subprocess
import sys
import time
import warnings
from collections import Counter
from dataclasses import asdict, dataclass, field
from typing import Any, Callable

import optuna
from optuna.trial import TrialState

from ringtune.agents.tune import trial_screen
from ringtune.agents.tune.sampler import make_sampler
from ringtune.agents.tune.pareto import (DEFAULT_MAX_PATH_ERROR_MM, DEFAULT_MAX_SHOW_THROUGH_MM,
    DEFAULT_MOTOR_RESERVE, OBJECTIVES, metrics_dict, objective_value, variant_figures, variants_to_json)
from ringtune.agents.tune.space import SearchSpace, config_from_params, default_space, suggest_params
from ringtune.agents.tune.storage import _this_worker, await_finished, make_storage, reap_dead_workers
from ringtune.agents.tune.study_resume import check_resumed
from ringtune.agents.tune.workers import start_workers
from ringtune.envs.printer import load_printer
from ringtune.envs.variants import DEFAULT_FREQ_MARGIN, TWIN_DAMPING
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError

DEFAULT_EVALUATOR = "ringtune.envs.evaluate:evaluate_many"


@dataclass
class StudySettings:
    """Everything a worker process needs to join a study (picklable)."""

    storage: str
    study_name: str = "ringtune"
    n_trials: int = 100
    seed: int | None = 0
    quality: str = "ripple_mm"         # the second objective (a metrics key)
    printer: str | None = None          # TOML path or embedded name; None = default printer
    job: str | None = None              # G-code path; None = built-in test print
    firmware: str = "klipper"
    backend: str = "mujoco"
    evaluator: str = DEFAULT_EVALUATOR
    space: dict | None = None           # SearchSpace.to_dict(); None = default_space(printer, firmware)
    n_startup_trials: int = 10
    enqueue: list = field(default_factory=list)   # parameter dicts to try first (e.g. baselines)
    max_path_error_mm: float = DEFAULT_MAX_PATH_ERROR_MM   # mm; 0 = no bound
    freq_margin: float = DEFAULT_FREQ_MARGIN   # fraction: also judged with resonances ± this (worst counts)
    motor_reserve: float = DEFAULT_MOTOR_RESERVE   # fraction of the motors' force kept free; 0 = no bound
    max_show_through_mm: float = DEFAULT_MAX_SHOW_THROUGH_MM   # mm; 0 = no bound
    job_accel: str = "replace"          # "respect": the job's M201/M204 stand; "replace": config.accel replaces them
    twin_damping: float = TWIN_DAMPING  # the twins' damping factor the study is judged with (recorded, not chosen)
    #: Klipper's pick's judged visible measures on the model itself (trial_screen.base_figures):
    #: a trial worse there and beaten on the model alone is not simulated on the twins; None: no such screen
    screen_against: dict | None = None

    def to_dict(self) -> dict:
        return asdict(self)


def objectives(settings: StudySettings) -> list[str]:
    """The study's objective keys: print time, ``settings.quality`` and the corner deviation."""
    return [OBJECTIVES[0], settings.quality, *OBJECTIVES[2:]]


def resolve_evaluator(spec: str | Callable) -> Callable:
    """``"module:function"`` -> the function (callables pass through)."""
    if callable(spec):
        return spec
    mod, _, name = str(spec).partition(":")
    if not mod or not name:
        raise RingtuneError(f"evaluator must be 'module:function', not {spec!r}", "evaluator")
    try:
        return getattr(importlib.import_module(mod), name)
    except (ImportError, AttributeError) as exc:
        raise RingtuneError(f"cannot import evaluator {spec!r}: {exc}", "evaluator") from None


def load_space(settings: StudySettings, printer: Any = None) -> SearchSpace:
    if settings.space:
        return SearchSpace.from_dict(settings.space)
    if printer is None:
        printer = load_printer(settings.printer)
    return default_space(printer, settings.firmware)


def open_study(settings: StudySettings, seed: int | None = None, lag: int = 1):
    """Create or load the study (same name + storage = the same study, from any process); ``lag``:
    the local workers in step (module docstring)."""
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    storage = make_storage(settings.storage)
    study = optuna.create_study(storage=storage, study_name=settings.study_name,
                                directions=["minimize"] * len(OBJECTIVES), load_if_exists=True,
                                sampler=make_sampler(settings.seed if seed is None else seed,
                                                     settings.n_startup_trials, lag=lag, wait=await_finished))
    if study.user_attrs.get("objectives") is None:
        study.set_user_attr("objectives", objectives(settings))
        study.set_user_attr("settings", {k: v for k, v in settings.to_dict().items() if k != "storage"})
        if settings.space:
            study.set_user_attr("space", settings.space)
    else:
        check_resumed(study, settings, objectives(settings))
    return study


#: trials each of N local workers may run ahead: trial n sees those numbered n − N·LAG_PER_WORKER
#: and lower (module docstring), so a worker whose trial was quick seldom waits for a slow one
LAG_PER_WORKER = 2


def count_states(study) -> dict[str, int]:
    """How many trials the study holds in each state, by the state's name (every state, 0 too)."""
    n = Counter(t.state.name for t in study.get_trials(deepcopy=False))
    return {s.name: n[s.name] for s in TrialState}


# -- one worker ------------------------------------------------------------------------------------

class _Stop:
    requested = False


def _install_sigint(flag: _Stop):
    """First Ctrl-C: finish the current trial, then stop. Second: abort now."""
    def handler(signum, frame):
        if flag.requested:
            signal.signal(signal.SIGINT, signal.default_int_handler)
            raise KeyboardInterrupt
        flag.requested = True

    try:
        return signal.signal(signal.SIGINT, handler)
    except ValueError:  # not the main thread
        return None


def run_worker(settings: StudySettings, worker_index: int = 0, *, printer: Any = None,
               on_trial: Callable[[Any], None] | None = None, stop: _Stop | None = None,
               nthread: int | None = None, lag: int = 1) -> int:
    """Run trials of the study until it has ``n_trials`` complete ones (or Ctrl-C). Returns the
    number this worker completed. ``lag`` > 1: one of several local workers in step, all with the
    study's seed, trial n seeing the trials numbered n − ``lag`` and lower (module docstring);
    otherwise each extra worker uses seed + 1009·index.
    ``nthread``: simulation threads of the default evaluator (None: its own choice; workers sharing
    the cores take their share: the figures do not depend on it)."""
    seed = None if settings.seed is None else settings.seed + (0 if lag > 1 else 1009 * worker_index)
    study = open_study(settings, seed=seed, lag=lag)
    evaluator = resolve_evaluator(settings.evaluator)
    if printer is None and settings.evaluator == DEFAULT_EVALUATOR:
        printer = load_printer(settings.printer)
    space = load_space(settings, printer)
    stop = stop or _Stop()
    previous = _install_sigint(stop)
    done = 0
    N = settings.n_trials

    def objective(trial):
        trial.set_user_attr("worker", _this_worker())
        ahead = 0
        if trial.number >= N - 32:   # earlier trials cannot have N others ahead of them
            others = study.get_trials(deepcopy=False, states=(TrialState.COMPLETE, TrialState.RUNNING))
            ahead = sum(1 for t in others if t.state == TrialState.COMPLETE
                        or (t.state == TrialState.RUNNING and t.number < trial.number))
        if ahead >= N or stop.requested:
            trial.set_user_attr("skipped", True)
            study.stop()
            raise optuna.TrialPruned()
        params = suggest_params(trial, space)
        config = config_from_params(params, space)
        try:
            m, screened = _judge(evaluator, settings, config, printer, nthread, study.sampler.history(study))
        except KeyboardInterrupt:
            trial.set_user_attr("interrupted", True)
            raise
        if screened:
            trial.set_user_attr(trial_screen.SCREENED, screened)
        trial.set_user_attr("metrics", metrics_dict(m))
        if variants := variant_figures(m):
            trial.set_user_attr("variants", variants_to_json(variants))
        trial.set_constraint("step_loss", 1.0 if m.step_loss else 0.0)
        bound = settings.max_path_error_mm
        trial.set_constraint("path_error", float(m.path_error_mm) - bound if bound > 0 else -1.0)
        reserve = settings.motor_reserve
        load = getattr(m, "motor_load", None)
        trial.set_constraint("motor_load", float(load) - (1.0 - reserve) if reserve > 0 and load is not None
                             else -1.0)
        st, bound = getattr(m, "show_through_mm", None), settings.max_show_through_mm
        trial.set_constraint("show_through", float(st) - bound if bound > 0 and st is not None else -1.0)
        return tuple(objective_value(m, k) for k in objectives(settings))

    def callback(st, frozen):
        nonlocal done
        if frozen.state == TrialState.COMPLETE:
            done += 1
            if on_trial:
                on_trial(frozen)
        if stop.requested:
            st.stop()

    try:
        _enqueue_new(study, settings.enqueue)
        while not stop.requested:
            reap_dead_workers(study)
            counts = count_states(study)
            if counts["COMPLETE"] >= N:
                break
            free = N - counts["COMPLETE"] - counts["RUNNING"]
            if free <= 0:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
                    optuna.storages.fail_stale_trials(study)
                time.sleep(0.2)   # others are finishing the last trials (or a stale one awaits its heartbeat)
                continue
            study.optimize(objective, n_trials=free, callbacks=[callback], gc_after_trial=False,
                           catch=(), show_progress_bar=False)
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
    return done


def _enqueue_new(study, enqueue: list[dict]) -> None:
    """Enqueue each parameter set unless a trial (any state but FAIL) already has exactly it."""
    for params in enqueue:
        key = sorted(params.items())
        if not any(t.state != TrialState.FAIL and (sorted(t.params.items()) == key or
                                                   t.system_attrs.get("fixed_params") == dict(params))
                   for t in study.get_trials(deepcopy=False)):
            study.enqueue_trial(params, skip_if_exists=False)


def evaluator_kwargs(settings: StudySettings) -> dict:
    """Keyword arguments for the evaluator: the default one takes the backend and the frequency
    margin; an injected ``f(configs, printer, job)`` takes none."""
    if settings.evaluator != DEFAULT_EVALUATOR:
        return {}
    return {"backend": settings.backend, "freq_margin": settings.freq_margin, "job_accel": settings.job_accel}


def _call_evaluator(evaluator, settings: StudySettings, config: TuneConfig, printer, nthread: int | None = None):
    kwargs = evaluator_kwargs(settings)
    if nthread is not None and settings.evaluator == DEFAULT_EVALUATOR:
        kwargs["nthread"] = nthread
    out = evaluator([config], printer if printer is not None else settings.printer, settings.job, **kwargs)
    return out[0]


def _judge(evaluator, settings: StudySettings, config: TuneConfig, printer, nthread: int | None, study):
    """(metrics, why settled on the model alone or ""): the default evaluator judging on the
    printer and its twins simulates the twins only where they can count
    (:mod:`ringtune.agents.tune.trial_screen`); any other, as given."""
    if settings.evaluator == DEFAULT_EVALUATOR and settings.freq_margin > 0:
        return trial_screen.evaluate_trial(config, printer if printer is not None else settings.printer, settings,
                                           study, nthread)
    return _call_evaluator(evaluator, settings, config, printer, nthread), ""


def _worker_main(argv: list[str]) -> int:
    """``python -m ringtune.agents.tune.study worker INDEX [WORKERS]`` with the settings as JSON on
    stdin (``WORKERS``: how many share the cores and run in step; each then simulates with its
    share of threads)."""
    if len(argv) not in (2, 3) or argv[0] != "worker":
        print("usage: python -m ringtune.agents.tune.study worker INDEX [WORKERS]  (settings JSON on stdin)",
              file=sys.stderr)
        return 2
    settings = StudySettings(**json.loads(sys.stdin.read()))
    return _worker_code(settings, int(argv[1]), None if len(argv) == 2 else max(1, int(argv[2])))


def _worker_code(settings: StudySettings, index: int, workers: int | None, printer: Any = None) -> int:
    """Run worker ``index`` of ``workers`` local ones in step (None: a lone worker, not in step);
    its exit code (130 after Ctrl-C, 2 after an error, said on stderr)."""
    share = None if workers is None else max(1, (os.cpu_count() or 1) // workers)
    try:
        run_worker(settings, index, printer=printer, nthread=share,
                   lag=LAG_PER_WORKER * workers if workers and workers > 1 else 1)
    except KeyboardInterrupt:
        return 130
    except RingtuneError as exc:
        print(f"ringtune worker {index}: error: {exc}", file=sys.stderr)
        return 2
    return 0


# -- the whole study -------------------------------------------------------------------------------

@dataclass
class StudyRun:
    """What a run left in storage."""

    study: Any
    completed_before: int
    completed_now: int
    interrupted: bool


def run_study(settings: StudySettings, workers: int = 1, *, printer: Any = None,
              progress: Callable[[int, int, Any], None] | None = None) -> StudyRun:
    """Run (or resume) the study with ``workers`` local processes; ``progress(done, total, study)``.

    With one worker the trials run in this process; with more, spawned processes share the
    storage and this process only watches (and reports progress).
    """
    if workers < 1:
        raise RingtuneError("must be ≥ 1", "workers")
    study = open_study(settings)
    before = count_states(study)["COMPLETE"]
    if progress:
        progress(before, settings.n_trials, study)
    stop = _Stop()
    interrupted = False
    if workers == 1:
        def on_trial(_):
            if progress:
                progress(count_states(study)["COMPLETE"], settings.n_trials, study)
        run_worker(settings, 0, printer=printer, on_trial=on_trial, stop=stop)
        interrupted = stop.requested
    else:
        interrupted = _run_workers(settings, study, workers, progress, printer)
    after = count_states(study)["COMPLETE"]
    if progress:
        progress(after, settings.n_trials, study)
    return StudyRun(study, before, after - before, interrupted)


def _run_workers(settings: StudySettings, study, workers: int,
                 progress: Callable[[int, int, Any], None] | None, printer: Any = None) -> bool:
    """The study in ``workers`` processes sharing its storage (:mod:`ringtune.agents.tune.workers`:
    forked with ``printer``, or spawned), this one watching and reporting progress; whether Ctrl-C
    stopped it (a worker that fails otherwise is an error)."""
    interrupted = False
    _enqueue_new(study, settings.enqueue)      # once, here: workers racing to enqueue would duplicate
    alone = dataclasses.replace(settings, enqueue=[])
    procs = start_workers(alone.to_dict(), workers, lambda i: _worker_code(alone, i, workers, printer),
                          settings.storage)
    try:
        while any(p.poll() is None for p in procs):
            time.sleep(0.3)
            if progress:
                progress(count_states(study)["COMPLETE"], settings.n_trials, study)
    except KeyboardInterrupt:
        interrupted = True   # the workers got the same Ctrl-C: they finish their trial and stop
        _let_finish(procs, 30)
    codes = [p.wait() for p in procs]
    bad = [] if interrupted else [c for c in codes if c != 0]
    if bad:
        raise RingtuneError(f"{len(bad)} worker process(es) failed (exit codes {bad}); "
                            "rerun to resume", "workers")
    return interrupted


def _let_finish(procs: list, grace_s: float) -> None:
    """Wait up to ``grace_s`` (s) in all for the processes to end; terminate those still running."""
    deadline = time.time() + grace_s
    for p in procs:
        try:
            p.wait(max(0.1, deadline - time.time()))
        except subprocess.TimeoutExpired:
            p.terminate()


if __name__ == "__main__":
    sys.exit(_worker_main(sys.argv[1:]))
