"""The policy's answer held to its starting answer (``agents/ppo/guard.py``): the lower cost kept, the
policy's on a tie, each judged once by the cost it is given."""

from __future__ import annotations

import numpy as np

from ringtune.agents.ppo.guard import hold_to_start, start_action
from ringtune.agents.ppo.policy import prior_action, resolve_env_kwargs
from ringtune.agents.ppo.refine import PrinterCost


class _Cost:
    """A cost of actions known in advance: the sum of the action's entries, every call recorded."""

    def __init__(self):
        self.calls = []

    def of_action(self, action):
        self.calls.append(np.array(action))
        return float(np.sum(action))


def test_the_start_is_kept_only_where_it_costs_less():
    policy, start = np.array([0.2, 0.1]), np.array([0.0, 0.1])
    cost = _Cost()
    kept, held = hold_to_start(cost, policy, start)
    assert held.kept == "start" and np.array_equal(kept, start)
    assert (held.policy_cost, held.start_cost) == (np.sum(policy), np.sum(start)) and len(cost.calls) == 2
    kept, held = hold_to_start(_Cost(), start, policy)            # the policy's answer is the cheaper
    assert held.kept == "policy" and np.array_equal(kept, start)
    kept, held = hold_to_start(_Cost(), policy, policy[::-1])     # a tie keeps the policy's answer
    assert held.kept == "policy" and np.array_equal(kept, policy)
    assert "starting answer kept" in hold_to_start(_Cost(), policy, start)[1].sentence()


def test_actions_outside_the_box_are_judged_as_the_env_takes_them():
    cost = _Cost()
    hold_to_start(cost, np.array([3.0, -2.0]), np.array([0.5, 0.5]))
    assert np.array_equal(cost.calls[0], [1.0, -1.0])


def test_the_start_is_the_environments_own_starting_answer():
    kw = resolve_env_kwargs()               # observes the metrics of its start: PRIOR's action
    assert np.allclose(start_action(kw), prior_action(kw))
    kw = resolve_env_kwargs({"observe_metrics": False, "accel_anchor": "absolute"})
    assert kw.get("start_action") is None and np.allclose(start_action(kw), prior_action(kw))


def test_the_cost_of_a_configuration_is_simulated_once(monkeypatch):
    """The guard's kept answer is the refinement's first trial: the cost of one configuration, asked
    again, is the same number without a second simulation (a fixed printer judges it the same)."""
    cost = PrinterCost(None, resolve_env_kwargs({"backend": "lti"}), backend="lti")
    calls = []
    real = cost.env.evaluate
    monkeypatch.setattr(cost.env, "evaluate", lambda c: calls.append(c) or real(c))
    start = start_action(resolve_env_kwargs({"backend": "lti"}))
    first, again = cost.of_action(start), cost.of_action(start)
    other = cost.of_action(np.clip(start + 0.3, -1.0, 1.0))
    assert first == again and len(calls) == 2 and cost.n_evaluations == 2 and other != first
