"""Acceptance 2: a seconds-long seeded PPO run measurably beats a random policy (and its own
untrained start) on a simplified setting: one fixed printer with a 90 Hz mode on both axes, one
shaper family (ZV), one shared setting for both axes, a small job with four sharp corners, and
ringing/overshoot weighted up so that the shaper frequency matters. The best frequency is near the
printer's mode; the untrained policy's answer (action 0) is 47 Hz."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from ringtune.envs.actions import decode_action  # noqa: E402
from ringtune.envs.env import TuneEnv  # noqa: E402
from ringtune.envs.printer import load_printer, printer_from_dict  # noqa: E402

SQUARE_JOB = "G21\nG90\nM83\nG1 X20 Y20 F12000\n" + "".join(
    "G1 X60 Y20 E1 F12000\nG1 X60 Y60 E1\nG1 X20 Y60 E1\nG1 X20 Y20 E1\n" for _ in range(2))


def _env():
    base = load_printer(None).to_dict()
    d = {**base, "name": "stiff-90Hz",
         "x": {**base["x"], "modes": [{"freq": 90.0, "damping": 0.05}]},
         "y": {**base["y"], "modes": [{"freq": 90.0, "damping": 0.05}]}}
    env = TuneEnv(printer=printer_from_dict(d, "test printer"), job=SQUARE_JOB, shapers=("zv",),
                  per_axis=False, backend="lti", observe_metrics=False,
                  weights={"worse": 20.0})
    env.reset(seed=0)
    return env


def _cost(env, action) -> float:
    env.reset(seed=1)
    return -env.step(np.asarray(action, np.float32))[1]


@pytest.mark.slow
def test_short_ppo_run_beats_random_policy_and_its_start():
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.logger import Logger
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    torch.set_num_threads(1)
    venv = VecNormalize(DummyVecEnv([_env]), norm_obs=False, norm_reward=True, gamma=0.0)
    model = PPO("MlpPolicy", venv, n_steps=32, batch_size=32, n_epochs=10, learning_rate=3e-3, gamma=0.0,
                gae_lambda=1.0, seed=0, device="cpu", policy_kwargs={"net_arch": [32, 32], "log_std_init": -0.5})
    model.set_logger(Logger(None, []))     # no SB3-<date> folder left in the temporary directory
    env = _env()
    obs, _ = env.reset(seed=1)
    start = model.predict(obs, deterministic=True)[0]
    model.learn(128)
    trained = model.predict(obs, deterministic=True)[0]

    rng = np.random.default_rng(0)
    random_costs = [_cost(env, rng.uniform(-1, 1, 4)) for _ in range(16)]
    c_start, c_trained = _cost(env, start), _cost(env, trained)
    print(f"start {c_start:.3f}  trained {c_trained:.3f}  random mean {np.mean(random_costs):.3f}")
    assert c_trained < np.mean(random_costs) - 0.1
    assert c_trained < c_start - 0.3
    # it learned to move the ZV frequency up toward the 90 Hz mode
    assert decode_action(trained, env.spec_).freq_x > decode_action(start, env.spec_).freq_x + 10
