"""The study's sampler (agents/tune/sampler.py): TPE's split of the trials computed once per trial
and reused by every group of parameters gives the very points Optuna's own gives, for a fraction
of the splits; on a multi-objective study with constraints and conditional parameters (groups)."""

from __future__ import annotations

import optuna
import pytest
from optuna.samplers._tpe import sampler as tpe_module

from ringtune.agents.tune.sampler import ReseedingTPESampler, make_sampler, split_once


class _OptunasOwnSplit(ReseedingTPESampler):
    """The same sampler with Optuna's split for every group."""

    def sample_relative(self, study, trial, search_space):
        return optuna.samplers.TPESampler.sample_relative(self, study, trial, search_space)


def _objective(trial):
    kind = trial.suggest_categorical("kind", ["a", "b", "none"])
    x = trial.suggest_float(f"x_{kind}", 0.0, 1.0) if kind != "none" else 0.5
    if kind == "b":
        x += trial.suggest_float("extra_b", 0.0, 0.5)
    y = trial.suggest_float("y", -1.0, 1.0)
    trial.set_user_attr("constraint", [y - 0.8])
    return (x - 0.3) ** 2 + y * y, abs(x - y)


def _run(sampler, n=45):
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.create_study(directions=["minimize", "minimize"], sampler=sampler)
    study.optimize(_objective, n_trials=n)
    return [t.params for t in study.trials]


@pytest.mark.parametrize("seed", [0, 1, 7])
def test_the_points_are_optunas_own_with_the_split_made_once_per_trial(seed, monkeypatch):
    calls = []
    split = tpe_module._split_trials

    def counted(*a, **k):
        calls.append(1)
        return split(*a, **k)

    monkeypatch.setattr(tpe_module, "_split_trials", counted)
    own = _run(_OptunasOwnSplit(seed, n_startup_trials=5, multivariate=True, group=True))
    n_own = len(calls)
    calls.clear()
    once = _run(make_sampler(seed, n_startup_trials=5))
    assert once == own
    # groups share one split: fewer splits than Optuna's own (one per group and trial), at least
    # one per trial sampled by TPE
    assert 40 <= len(calls) < n_own
    # outside a trial's sampling the split is Optuna's own again (the memo is per trial and thread)
    calls.clear()
    study = optuna.create_study(directions=["minimize", "minimize"])
    tpe_module._split_trials(study, [], 0)
    tpe_module._split_trials(study, [], 0)
    assert len(calls) == 2


def test_without_the_split_function_nothing_changes(monkeypatch):
    """An Optuna without the function: the sampler samples as Optuna does and patches nothing."""
    monkeypatch.delattr(tpe_module, "_split_trials")
    with split_once():
        assert not hasattr(tpe_module, "_split_trials")


def test_the_history_a_trial_sees_is_the_trials_lag_behind_it():
    """History(study, k): every trial query answers with the trials numbered k and lower; the rest
    of the study is its own (sampler.py: what a trial of N workers in step may read)."""
    from ringtune.agents.tune.sampler import History

    study = optuna.create_study(directions=["minimize", "minimize"])
    for i in range(6):
        study.add_trial(optuna.trial.create_trial(params={"x": float(i)}, values=[float(i), float(-i)],
                                                  distributions={"x": optuna.distributions.FloatDistribution(0, 9)}))
    seen = History(study, 3)
    assert [t.number for t in seen.get_trials(deepcopy=False)] == [0, 1, 2, 3]
    assert [t.number for t in seen._get_trials(deepcopy=False, states=None, use_cache=False)] == [0, 1, 2, 3]
    assert [t.number for t in seen.trials] == [0, 1, 2, 3]
    assert seen.directions == study.directions
    assert [t.number for t in History(study, -1).get_trials()] == []
