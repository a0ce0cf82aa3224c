"""torch and stable-baselines3, the optional ``rl`` extra: imported here, on first use, and nowhere
else in ringtune.

They take seconds to import and a core install (``pip install ringtune`` without ``[rl]``) lacks
them, so every other command starts without them; what needs them (``train``, ``recommend
--method policy``) calls :func:`rl` and, without the extra, stops with one line saying how to get it.
"""

from __future__ import annotations

import functools
from types import SimpleNamespace

from ringtune.shaping.errors import RingtuneError

#: how to get the extra, as the refusal says it
INSTALL = "pip install 'ringtune[rl]'"


@functools.cache
def rl() -> SimpleNamespace:
    """The names ringtune uses from torch and stable-baselines3 (``torch``, ``PPO``, callbacks,
    ``Monitor``, vector envs), imported on the first call; RingtuneError in one line without the
    ``rl`` extra."""
    try:
        # the one lazy import of the library: the rl extra (optional, seconds to import)
        import torch
        from stable_baselines3 import PPO
        from stable_baselines3.common.callbacks import BaseCallback, CallbackList, CheckpointCallback, EvalCallback
        from stable_baselines3.common.logger import HumanOutputFormat, Logger
        from stable_baselines3.common.monitor import Monitor
        from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecNormalize
    except ImportError as exc:
        raise RingtuneError(f"PPO needs the optional rl extra (torch, stable-baselines3), and {exc.name} is "
                            f"not installed: {INSTALL}") from None
    return SimpleNamespace(torch=torch, PPO=PPO, BaseCallback=BaseCallback, CallbackList=CallbackList,
                           CheckpointCallback=CheckpointCallback, EvalCallback=EvalCallback, Monitor=Monitor,
                           DummyVecEnv=DummyVecEnv, SubprocVecEnv=SubprocVecEnv, VecNormalize=VecNormalize,
                           HumanOutputFormat=HumanOutputFormat, Logger=Logger)
