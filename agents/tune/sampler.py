"""The study's sampler: Optuna's multi-objective TPE, reproducible per trial, its trials split once
per trial.

- **Reproducible.** The random state is reseeded from (seed, trial number) before every trial, so a
  trial's point does not depend on how many trials other workers ran first. With ``lag`` L > 1
  (L local workers sharing the study), trial n waits until every trial numbered n − L or lower has
  finished and then sees those alone (:class:`History`), whichever worker runs it and whatever
  else has finished meanwhile: a seeded study with L workers reproduces exactly too. With L = 1
  (one worker) every earlier trial has finished and nothing changes.
- **Split once.** With ``group=True`` TPE samples each group of parameters that occur together
  apart (the shapers' own parameters, the frequency limit's…), and for each group it splits the
  same finished trials into its better and worse share (non-dominated sorting and hypervolume
  contributions over every objective). That split is a pure function of the trials (their numbers,
  states and values), so it is computed once per trial and reused by every group: the same points,
  a fraction of the sampler's time (tests/test_sampler.py). Optuna's (private) split function is
  wrapped once per process; the wrapper memoises only while a trial of this sampler is being
  sampled in the same thread, and is Optuna's own everywhere else.
"""

from __future__ import annotations

import threading
import warnings
from contextlib import contextmanager
from typing import Any, Callable

import numpy as np
import optuna
from optuna.samplers._tpe import sampler as _tpe


def make_sampler(seed: int | None, n_startup_trials: int = 10, lag: int = 1,
                 wait: Callable[[Any, int], None] | None = None) -> optuna.samplers.TPESampler:
    """Multi-objective TPE whose random state depends only on (seed, trial number), and whose
    history for trial n is the trials numbered n − ``lag`` and lower (``wait(study, n − lag)``
    blocks until they have finished; module docstring)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
        return ReseedingTPESampler(seed, lag=lag, wait=wait, n_startup_trials=n_startup_trials,
                                   multivariate=True, group=True)


class ReseedingTPESampler(optuna.samplers.TPESampler):
    """TPE reseeded before each trial, splitting the trials once per trial, seeing the trials
    ``lag`` and more behind the one it samples (module docstring)."""

    def __init__(self, seed, lag: int = 1, wait: Callable[[Any, int], None] | None = None, **kw):
        super().__init__(seed=seed, **kw)
        self._base_seed = seed
        self._lag = max(1, int(lag))
        self._wait = wait
        self._history = None

    def before_trial(self, study, trial):
        if self._base_seed is not None:
            s = int(np.random.SeedSequence([int(self._base_seed), int(trial.number)]).generate_state(1)[0])
            self._rng.rng.seed(s)
            self._random_sampler._rng.rng.seed(s ^ 0x5EED)
        self._history = None
        if self._lag > 1:
            upto = trial.number - self._lag
            if self._wait is not None:
                self._wait(study, upto)
            self._history = History(study, upto)
        super().before_trial(self.history(study), trial)

    def infer_relative_search_space(self, study, trial):
        return super().infer_relative_search_space(self.history(study), trial)

    def sample_relative(self, study, trial, search_space):
        with split_once():
            return super().sample_relative(self.history(study), trial, search_space)

    def sample_independent(self, study, trial, param_name, param_distribution):
        return super().sample_independent(self.history(study), trial, param_name, param_distribution)

    def after_trial(self, study, trial, state, values):
        self._history = None
        super().after_trial(study, trial, state, values)

    def history(self, study):
        """The study as the trial being sampled sees it (itself where there is no lag); the
        objective's judgement of which twins can count reads the same trials
        (:mod:`ringtune.agents.tune.trial_screen`)."""
        return study if self._history is None else self._history


class History:
    """A study as its trials numbered ``upto`` and lower show it: every trial query answered from
    those alone; everything else the study's own."""

    def __init__(self, study, upto: int):
        self._study = study
        self._upto = int(upto)

    def __getattr__(self, name):
        return getattr(self._study, name)

    def _get_trials(self, deepcopy: bool = True, states=None, use_cache: bool = False):
        return [t for t in self._study._get_trials(deepcopy=deepcopy, states=states, use_cache=use_cache)
                if t.number <= self._upto]

    def get_trials(self, deepcopy: bool = True, states=None):
        return [t for t in self._study.get_trials(deepcopy=deepcopy, states=states) if t.number <= self._upto]

    @property
    def trials(self):
        return self.get_trials()


#: the split memo of the trial being sampled, per thread (None: Optuna's own split)
_active = threading.local()


@contextmanager
def split_once():
    """Within the block (in this thread), Optuna's TPE split of the trials is computed once per
    distinct set of trials (numbers and states) and arguments; elsewhere, Optuna's own. Where this
    Optuna has no such function, nothing changes."""
    if not _install():
        yield
        return
    _active.memo = {}
    try:
        yield
    finally:
        _active.memo = None


def _install() -> bool:
    """Route Optuna's split through :func:`_memoized` (once per process); False where it has none."""
    split = getattr(_tpe, "_split_trials", None)
    if split is None:
        return False
    if not getattr(split, "ringtune_memo", False):
        _tpe._split_trials = _memoized(split)
    return True


def _memoized(split):
    def once(study, trials, *args, **kwargs):
        memo = getattr(_active, "memo", None)
        if memo is None:
            return split(study, trials, *args, **kwargs)
        key = (tuple((t.number, t.state) for t in trials), args, tuple(sorted(kwargs.items())))
        if key not in memo:
            memo[key] = split(study, trials, *args, **kwargs)
        below, above = memo[key]
        return list(below), list(above)

    once.ringtune_memo = True
    return once
