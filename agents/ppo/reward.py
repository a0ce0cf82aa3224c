"""Training reward relative to a reference configuration on the same printer (a control variate).

The tuning problem is a contextual bandit whose cost spreads far more from printer to printer
(about 0.9–1.7 on the randomised printers, +10 on step loss) than between two nearby
configurations on one printer (a few hundredths). PPO's advantage ``r − V(s)`` then depends on the
critic predicting each printer's cost from its spectrum; until it does, the policy gradient is
mostly that spread, and Adam turns noise into steps of full size (the policy drifts away from a
good start). Subtracting the reward of a fixed reference configuration on the *same* printer
cancels the spread and leaves each printer's optimum where it was, since the reference does not
depend on the action.

The reference costs one more evaluation per printer (none when the reference is the env's starting
configuration, whose metrics the reset has evaluated); showing each printer ``repeats`` times in a
row (the same resonance test, so the same observation) spreads that cost over ``repeats`` steps.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from ringtune.shaping.errors import RingtuneError


def reward_of(env, config) -> float:
    """The reward of ``config`` on ``env``'s current printer (a rejected configuration earns
    ``−step_loss_penalty``, as in :meth:`TuneEnv.step`)."""
    try:
        return float(env.reward(env.evaluate(config)))
    except RingtuneError:
        return -float(env.step_loss_penalty)


class ReferenceRelative(gym.Wrapper):
    """Wraps a :class:`ringtune.envs.env.TuneEnv`: reward = reward(action) − reward(reference).

    Args:
        env: the TuneEnv (randomised).
        reference_action: an action of ``env``'s action space; decoded on each printer (with a
            peak-anchored action: around that printer's resonance peaks). None: the env's starting
            configuration, whose metrics the env observed at reset (no extra evaluation; needs
            ``observe_metrics``).
        repeats: episodes per drawn printer (≥ 1). A ``reset(seed=…)`` always draws a new one.

    ``info["cost"]`` carries the unmodified cost (−reward of the env) and ``info["reference_cost"]``
    the reference's, so curves and monitors can report the true objective.
    """

    def __init__(self, env, reference_action, repeats: int = 1):
        super().__init__(env)
        if int(repeats) < 1:
            raise RingtuneError(f"must be ≥ 1, not {repeats}", "printer_repeats")
        if reference_action is None and not getattr(env.unwrapped, "observe_metrics", False):
            raise RingtuneError("without a reference action the env must observe its starting metrics",
                                "reference_action")
        self.reference_action = None if reference_action is None else np.asarray(reference_action, np.float32)
        self.repeats = int(repeats)
        self._left = 0
        self._first: tuple | None = None
        self._ref = 0.0

    def reset(self, *, seed=None, options=None):
        if seed is not None or options or self._left <= 0:   # a new printer (none is left before the first)
            obs, info = self.env.reset(seed=seed, options=options)
            base = self.env.unwrapped
            if self.reference_action is None:        # the starting configuration, evaluated by the reset
                m = base.start_metrics_
                self._ref = float(base.reward(m)) if m is not None else -float(base.step_loss_penalty)
            else:
                self._ref = reward_of(base, base.decode(self.reference_action))
            self._first = (obs.copy(), dict(info))
            self._left = self.repeats
        self._left -= 1
        obs, info = self._first
        return obs.copy(), {**info, "reference_cost": -self._ref}

    def step(self, action):
        obs, r, terminated, truncated, info = self.env.step(action)
        info = {**info, "cost": -float(r), "reference_cost": -self._ref}
        return obs, float(r) - self._ref, terminated, truncated, info
