"""The reference-relative training reward (agents/ppo/reward.py): same printer, same optimum,
the printer's own cost level removed."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from ringtune.agents.ppo import policy as ppo
from ringtune.agents.ppo.reward import ReferenceRelative, reward_of
from ringtune.agents.tune.study import StudySettings
from ringtune.envs.env import TuneEnv
from ringtune.envs.evaluate import evaluate_many
from ringtune.envs.variants import DEFAULT_FREQ_MARGIN

from test_ppo_train import SQUARE_JOB

KW = ppo.resolve_env_kwargs({"job": SQUARE_JOB})


def _wrapped(repeats=2):
    return ReferenceRelative(TuneEnv(randomize=True, **KW), ppo.prior_action(KW), repeats)


def test_reference_action_earns_zero_and_rewards_are_differences_of_true_costs():
    env = _wrapped(repeats=3)
    env.reset(seed=11)
    ref = ppo.prior_action(KW)
    _, r0, term, _, info = env.step(ref)
    assert term and r0 == 0.0 and info["cost"] == pytest.approx(info["reference_cost"])
    other = ref.copy()
    other[-1] = -1.0            # the lowest acceleration: slower, so a different cost
    env.reset()
    _, r1, _, _, info1 = env.step(other)
    # the wrapper's reward is exactly the difference of the plain env's costs on that printer
    base = env.unwrapped
    assert r1 == pytest.approx(reward_of(base, base.decode(other)) - reward_of(base, base.decode(ref)), abs=1e-12)
    assert r1 == pytest.approx(info1["reference_cost"] - info1["cost"], abs=1e-12)
    assert r1 != 0.0


def test_each_printer_is_shown_repeats_times_then_a_new_one():
    env = _wrapped(repeats=2)
    o1, _ = env.reset(seed=5)
    p1 = env.unwrapped.printer.to_dict()
    env.step(env.action_space.sample())
    o2, _ = env.reset()
    assert np.array_equal(o1, o2) and env.unwrapped.printer.to_dict() == p1
    env.step(env.action_space.sample())
    o3, _ = env.reset()
    assert env.unwrapped.printer.to_dict() != p1 and not np.array_equal(o1, o3)
    # a seeded reset always draws (and reproduces) the printer of that seed
    o4, _ = env.reset(seed=5)
    assert np.array_equal(o1, o4)


def test_rejects_zero_repeats():
    from ringtune.shaping.errors import RingtuneError

    with pytest.raises(RingtuneError, match="printer_repeats"):
        _wrapped(repeats=0)


@pytest.mark.slow
def test_sb3_checker_passes_on_the_wrapped_training_env():
    from stable_baselines3.common.env_checker import check_env

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(_wrapped(), warn=True)


def test_training_env_observes_the_prior_and_its_evaluation_is_the_reference():
    """The training env starts from PRIOR and observes its metrics; without a reference action the
    wrapper takes the reference reward from that reset evaluation (two evaluations per printer: the
    baseline the cost judges against, and the prior; not three), and it is the same number an
    independent evaluation of that configuration gives."""
    assert KW["observe_metrics"] and np.array_equal(np.float32(KW["start_action"]), ppo.prior_action(KW))
    env = ReferenceRelative(TuneEnv(randomize=True, **KW), None, 2)
    base = env.unwrapped
    calls = []
    plain = base.evaluate
    base.evaluate = lambda c: calls.append(c) or plain(c)
    obs, info = env.reset(seed=21)
    assert len(calls) == 2 and calls[0].to_dict() == info["baseline_config"]
    start = calls[1]      # PRIOR: MZV on the peaks, S 0.075, at the starting acceleration
    assert (start.shaper_x, start.shaper_y, start.accel) == ("mzv", "mzv", base.spec_.accel_start)
    assert start.freq_x == pytest.approx(info["peaks_hz"][0]) and start.damping_x == pytest.approx(0.075)
    # the observation's metrics part is the prior's metrics on this printer, not zeros
    n = base.spec_.size
    metrics_part = obs[2 * base.n_bins + n: 2 * base.n_bins + n + 7]
    assert np.allclose(metrics_part, base._metrics_vector(base.start_metrics_)) and metrics_part[1:4].max() > 0
    fresh = TuneEnv(printer=base.printer, **{**KW, "observe_metrics": False, "accel_anchor": "absolute"})
    fresh.reset(seed=0)
    fresh.observe_start(peaks=base.peaks_)      # the same resonance peaks: the same baseline
    assert info["reference_cost"] == pytest.approx(-fresh.reward(fresh.evaluate(start)), rel=1e-9)
    env.reset()                # the same printer again: no evaluation
    assert len(calls) == 2


def test_training_judges_as_tune_judges_on_the_printer_and_its_twins():
    """The policy's environment (training, held-out printers, recommend) judges every answer as
    tune does: the worst of the printer and its resonances ±5 % with damping ×0.75. Trained on the
    printer alone, a policy learned answers the twins punish (README, PPO)."""
    assert KW["freq_margin"] == DEFAULT_FREQ_MARGIN == StudySettings(storage="journal:unused").freq_margin
    env = TuneEnv(randomize=True, **KW)
    env.reset(seed=21)

    def judged(cfg, margin):
        return evaluate_many([cfg], env.printer, env.job, backend=KW["backend"], freq_margin=margin)[0]

    assert env.start_metrics_.to_dict() == judged(env.config, DEFAULT_FREQ_MARGIN).to_dict()
    action = ppo.prior_action(KW)
    cfg = env.decode(action)
    twins, alone = judged(cfg, DEFAULT_FREQ_MARGIN), judged(cfg, 0.0)
    _, reward, *_ = env.step(action)
    assert reward == pytest.approx(-env.cost(twins), abs=1e-12)
    assert env.cost(twins) > env.cost(alone)        # the twins count: this answer rings more on one of them
