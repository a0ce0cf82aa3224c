"""What the machine does: printer description, MuJoCo model, simulation, exact linear reference,
metrics, gymnasium environments and identification from accelerometer data."""

import gymnasium

ENV_IDS = ("ringtune/Tune-v0", "ringtune/TuneFixed-v0")


def _register_envs() -> None:
    """Register the gymnasium environments (one-shot episodes: no ``max_episode_steps``)."""
    if ENV_IDS[0] not in gymnasium.registry:
        gymnasium.register(ENV_IDS[0], entry_point="ringtune.envs.env:TuneEnv", kwargs={"randomize": True})
    if ENV_IDS[1] not in gymnasium.registry:
        gymnasium.register(ENV_IDS[1], entry_point="ringtune.envs.env:TuneEnv", kwargs={"randomize": False})


_register_envs()
