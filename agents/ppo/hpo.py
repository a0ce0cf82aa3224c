"""Optuna tunes PPO's own hyperparameters (``ringtune train --hpo``).

Each trial is a short :func:`ringtune.agents.ppo.training.train` run (``budget`` steps) in its own folder;
its objective is the held-out printers' mean cost at the last evaluation (the evaluation callback's
printers, never trained on). Seeded TPE, sequential, in-memory study; the trials' results go to
``out_dir/hpo.json``.
"""

from __future__ import annotations

import json
from pathlib import Path

import optuna

from ringtune.agents.ppo.training import train
from ringtune.shaping.errors import RingtuneError


def suggest_hyper(trial) -> dict:
    """PPO hyperparameters searched (others keep :data:`ringtune.agents.ppo.training.DEFAULT_HYPER`)."""
    width = trial.suggest_categorical("width", [64, 128, 256])
    return {
        "learning_rate": trial.suggest_float("learning_rate", 1e-4, 3e-3, log=True),
        "n_steps": trial.suggest_categorical("n_steps", [64, 128, 256]),
        "n_epochs": trial.suggest_int("n_epochs", 4, 20),
        "log_std_init": trial.suggest_float("log_std_init", -3.0, -1.0),
        "ent_coef": trial.suggest_float("ent_coef", 1e-5, 1e-2, log=True),
        "net_arch": [width, width],
    }


def tune_hyperparameters(out_dir: str | Path, n_trials: int = 6, budget: int = 2048, n_envs: int = 2,
                         seed: int = 0, env_kwargs: dict | None = None) -> dict:
    """Run the study; returns {"best_params": hyper dict, "best_cost": float, "trials": n, "all": [...]}."""
    if n_trials < 1:
        raise RingtuneError("needs at least one trial", "n_trials")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.create_study(direction="minimize", sampler=optuna.samplers.TPESampler(seed=seed))
    rows = []

    def objective(trial):
        hyper = suggest_hyper(trial)
        res = train(out / f"trial_{trial.number}", budget, n_envs, seed, hyper=hyper, env_kwargs=env_kwargs,
                    eval_freq=budget, checkpoint_freq=budget, progress_bar=False)
        cost = res.eval_mean_cost[-1] if res.eval_mean_cost else float("inf")
        rows.append({"number": trial.number, "hyper": hyper, "cost": cost})
        return cost

    study.optimize(objective, n_trials=n_trials)
    best = suggest_hyper(optuna.trial.FixedTrial(study.best_trial.params))
    result = {"best_params": best, "best_cost": float(study.best_value), "trials": n_trials, "all": rows}
    (out / "hpo.json").write_text(json.dumps(result, indent=2))
    return result
