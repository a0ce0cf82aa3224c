"""The study's sampler: Optuna's multi-objective TPE, reproducible per trial, its trials split once
per trial.

- **Reproducible.** The random state is reseeded from (seed, trial number) before every trial, so a
  trial's point does not depend on how many trials other workers ran first.
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

import numpy as np
import optuna
from optuna.samplers._tpe import sampler as _tpe


def make_sampler(seed: int | None, n_startup_trials: int = 10) -> optuna.samplers.TPESampler:
    """Multi-objective TPE whose random state depends only on (seed, trial number)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
        return ReseedingTPESampler(seed, n_startup_trials=n_startup_trials, multivariate=True, group=True)


class ReseedingTPESampler(optuna.samplers.TPESampler):
    """TPE reseeded before each trial, splitting the trials once per trial (module docstring)."""

    def __init__(self, seed, **kw):
        super().__init__(seed=seed, **kw)
        self._base_seed = seed

    def before_trial(self, study, trial):
        if self._base_seed is not None:
            s = int(np.random.SeedSequence([int(self._base_seed), int(trial.number)]).generate_state(1)[0])
            self._rng.rng.seed(s)
            self._random_sampler._rng.rng.seed(s ^ 0x5EED)
        super().before_trial(study, trial)

    def sample_relative(self, study, trial, search_space):
        with split_once():
            return super().sample_relative(study, trial, search_space)


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
