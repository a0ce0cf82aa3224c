"""Callbacks of :func:`ringtune.agents.ppo.training.train` (stable-baselines3's classes come from
:func:`ringtune.agents.ppo.rl.rl`: the ``rl`` extra is optional)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ringtune.agents.ppo.rl import rl


def curve_callback():
    """Collects the mean training cost of each rollout (the true cost ``info["cost"]`` under a
    reference-relative reward, else −reward as the Monitor saw it); fields ``timesteps``, ``costs``
    and ``reference_costs`` (the reference's mean cost on the same printers, when reported)."""
    class Curve(rl().BaseCallback):
        def __init__(self):
            super().__init__()
            self.timesteps: list[int] = []
            self.costs: list[float] = []
            self.reference_costs: list[float] = []
            self._buf: list[float] = []
            self._ref: list[float] = []

        def _on_step(self) -> bool:
            for info in self.locals.get("infos", []):
                ep = info.get("episode")
                if ep is not None:
                    self._buf.append(float(info["cost"]) if "cost" in info else -float(ep["r"]))
                    if "reference_cost" in info:
                        self._ref.append(float(info["reference_cost"]))
            return True

        def _on_rollout_end(self) -> None:
            if self._buf:
                self.timesteps.append(int(self.num_timesteps))
                self.costs.append(float(np.mean(self._buf)))
                if len(self._ref) == len(self._buf):
                    self.reference_costs.append(float(np.mean(self._ref)))
                self._buf, self._ref = [], []

    return Curve()


def held_out_callback(eval_venv, n_episodes: int, every: int, out: Path, previous_best: float | None = None):
    """``EvalCallback`` on the held-out printers that also evaluates once when training starts
    (so the starting policy competes for best, and a run that only got worse keeps it) and saves
    the training env's normalisation statistics beside each new best model
    (``best/vecnormalize.pkl``: the best model must see observations scaled as it was trained).
    ``previous_best``: mean reward of the best model of the run being resumed."""
    sb3 = rl()
    best_dir = Path(out) / "best"

    class SaveNormalisation(sb3.BaseCallback):
        def _on_step(self) -> bool:
            vn = self.model.get_vec_normalize_env()
            if vn is not None:
                best_dir.mkdir(parents=True, exist_ok=True)
                vn.save(str(best_dir / "vecnormalize.pkl"))
            return True

    class FromStart(sb3.EvalCallback):
        def _on_training_start(self) -> None:
            super()._on_training_start()
            if previous_best is not None:
                self.best_mean_reward = float(previous_best)
            self._on_step()          # n_calls == 0: evaluates now

    return FromStart(eval_venv, n_eval_episodes=n_episodes, eval_freq=every, best_model_save_path=str(best_dir),
                     log_path=str(out), deterministic=True, verbose=0, callback_on_new_best=SaveNormalisation())
