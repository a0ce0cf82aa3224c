"""The environment's cost of configurations on one printer, and Optuna over the policy's action space.

Used by ``ringtune recommend --method policy --refine N`` (the policy's recommendation is the first
trial of an N-trial study) and by ``benchmarks/bench_ppo.py`` (Optuna alone, policy + Optuna).
The cost is exactly the environment's: ``−reward`` of :class:`ringtune.envs.env.TuneEnv`
(:func:`ringtune.envs.judgement.judged_cost`: the print-time ratio plus the relative excess of every
visible measure over the baseline's beyond tune's resolution, plus the constraints' penalties; a
configuration the firmware rejects costs the penalty).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import optuna

from ringtune.envs.env import TuneEnv
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError


class PrinterCost:
    """Cost of configurations (or actions) on one fixed printer, as ``TuneEnv`` scores them."""

    def __init__(self, printer=None, env_kwargs: dict | None = None, backend: str = "mujoco", job=None,
                 seed: int = 0, peaks=None):
        """``env_kwargs``: the policy's env arguments (its job, weights, action layout); ``job``
        overrides the job. Peak-anchored actions decode around the peaks of the resonance test
        of ``reset(seed=seed)``, or around ``peaks`` (X, Y) Hz when given (e.g. those the policy saw);
        a model-anchored acceleration around the anchor of the starting configuration on those peaks
        (one evaluation, not counted in ``n_evaluations``)."""
        kw = {k: v for k, v in (env_kwargs or {}).items() if k not in ("backend", "randomize")}
        if job is not None:
            kw["job"] = job
        self.env = TuneEnv(printer=printer, randomize=False, backend=backend, **kw)
        self.env.reset(seed=seed)   # the baseline print time, the peaks, the acceleration anchor
        if peaks is not None:
            self.env.observe_start(peaks=peaks)
        self.n_evaluations = 0
        self._costs: dict = {}       # by configuration: one fixed printer judges it the same every time

    @property
    def spec(self):
        return self.env.spec_

    def of_config(self, config: TuneConfig) -> float:
        """The environment's cost of ``config``, simulated once (the guard's answer, judged again as
        the refinement's first trial, is not simulated twice)."""
        key = config.key()
        if key not in self._costs:
            self.n_evaluations += 1
            try:
                self._costs[key] = -self.env.reward(self.env.evaluate(config))
            except RingtuneError:
                self._costs[key] = float(self.env.step_loss_penalty)
        return self._costs[key]

    def of_action(self, action) -> float:
        return self.of_config(self.env.decode(np.clip(np.asarray(action, float), -1, 1)))


@dataclass
class SearchResult:
    best_action: np.ndarray
    best_config: TuneConfig
    best_cost: float
    costs: list = field(default_factory=list)       # cost of every trial, in order

    @property
    def first_cost(self) -> float:
        return self.costs[0]


def optuna_search(cost: PrinterCost, n_trials: int, seed: int = 0, first_action=None) -> SearchResult:
    """Minimise ``cost`` over the action box [-1, 1]^n with Optuna's TPE (seeded, sequential).

    ``first_action`` (e.g. the policy's) is enqueued as trial 0, so the result is never worse than
    it. ``n_trials`` counts that trial."""
    if n_trials < 1:
        raise RingtuneError("needs at least one trial", "n_trials")
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    n = cost.spec.size
    study = optuna.create_study(direction="minimize", sampler=optuna.samplers.TPESampler(seed=seed))
    if first_action is not None:
        a = np.clip(np.asarray(first_action, float).ravel(), -1.0, 1.0)
        study.enqueue_trial({f"a{i}": float(a[i]) for i in range(n)})
    costs: list[float] = []

    def objective(trial):
        a = np.array([trial.suggest_float(f"a{i}", -1.0, 1.0) for i in range(n)])
        c = cost.of_action(a)
        costs.append(c)
        return c

    study.optimize(objective, n_trials=n_trials)
    best = np.array([study.best_trial.params[f"a{i}"] for i in range(n)])
    return SearchResult(best, cost.env.decode(best), float(study.best_value), costs)
