"""The policy's answer held to its own starting answer: whichever the environment's cost is lower for.

The policy starts every episode from one answer (:data:`ringtune.agents.ppo.policy.PRIOR`: MZV on
each axis's resonance peak, its damping and the anchor acceleration) and outputs a change to it.
On the 20 unseen printers of ``benchmarks/bench_ppo.py`` (the policy of ``ringtune train`` with its
defaults, 2026-12-06) that change made the answer better on 5 printers by more than 1 % and worse
on 11: its gain is a few large wins. Both answers are therefore judged on the printer's model by the
environment's own cost (:class:`ringtune.agents.ppo.refine.PrinterCost`: ``tune``'s judgement as
one number, the printer and its twins) and the lower kept, the policy's on a tie. It costs one
more simulation than the policy's answer alone, and the answer is never worse on the model than
the one the policy started from.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ringtune.agents.ppo.policy import prior_action
from ringtune.agents.ppo.refine import PrinterCost


@dataclass(frozen=True)
class Guard:
    """What the guard judged: which answer it kept (``"policy"`` or ``"start"``) and the
    environment's cost of each (1.0: the baseline itself; lower is better)."""

    kept: str
    policy_cost: float
    start_cost: float

    def to_dict(self) -> dict:
        return {"kept": self.kept, "policy_cost": self.policy_cost, "start_cost": self.start_cost}

    def sentence(self) -> str:
        kept = "the starting answer kept" if self.kept == "start" else "the policy's kept"
        return (f"guard: the policy's answer costs {self.policy_cost:.4f}, its starting answer (MZV on the peaks) "
                f"{self.start_cost:.4f} on the model: {kept}")


def start_action(env_kwargs: dict) -> np.ndarray:
    """The answer the policy's episodes start from: its environment's ``start_action``, else
    :data:`~ringtune.agents.ppo.policy.PRIOR` as an action of that environment."""
    start = env_kwargs.get("start_action")
    return np.asarray(start if start is not None else prior_action(env_kwargs), float)


def hold_to_start(cost: PrinterCost, action, start) -> tuple[np.ndarray, Guard]:
    """(the action kept, the :class:`Guard`): the policy's ``action`` and its starting answer
    ``start`` (an action of the same environment) each judged by ``cost``; the start kept only
    where it costs less."""
    action = np.clip(np.asarray(action, float).ravel(), -1.0, 1.0)
    start = np.clip(np.asarray(start, float).ravel(), -1.0, 1.0)
    policy_cost, start_cost = cost.of_action(action), cost.of_action(start)
    if start_cost < policy_cost:
        return start, Guard("start", policy_cost, start_cost)
    return action, Guard("policy", policy_cost, start_cost)
