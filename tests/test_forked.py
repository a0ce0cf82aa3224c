"""envs.forked.split_map: a batch split over forked processes gives what one call gives, in order;
a child's error is raised in the parent; the real evaluator's figures do not depend on the split."""

from __future__ import annotations

import os
import signal

import pytest

from ringtune.envs.evaluate import evaluate_many
from ringtune.envs.forked import CAN_FORK, split_map
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError

pytestmark = pytest.mark.skipif(not CAN_FORK, reason="splitting forks (Linux)")


def test_parts_come_back_in_order_and_are_computed_in_other_processes():
    def square(part):
        return [(x * x, os.getpid()) for x in part]

    out = split_map(square, range(11), parts=3)
    assert [v for v, _ in out] == [x * x for x in range(11)]
    pids = {p for _, p in out}
    assert len(pids) == 3 and os.getpid() in pids          # two children, the last part here
    assert split_map(square, [5], parts=4) == [(25, os.getpid())]   # one item: no child
    assert split_map(square, [], parts=2) == []


def test_a_childs_error_is_raised_here():
    def fails_on_two(part):
        if 2 in part:
            raise ValueError("two is not allowed")
        return list(part)

    with pytest.raises(ValueError, match="two is not allowed"):
        split_map(fails_on_two, [1, 2, 3, 4], parts=2)


def test_a_child_that_dies_is_an_error_not_a_hang():
    def dies_in_child(part):
        if 0 in part:
            os.kill(os.getpid(), signal.SIGKILL)
        return list(part)

    with pytest.raises(RingtuneError, match="ended without a result"):
        split_map(dies_in_child, [0, 1, 2, 3], parts=2)


def test_the_real_evaluators_figures_do_not_depend_on_the_split():
    configs = [TuneConfig(shaper_x="mzv", shaper_y="ei", freq_x=50.0, freq_y=45.0, accel=5000.0),
               TuneConfig(shaper_x="zv", shaper_y="zv", freq_x=48.0, freq_y=44.0, accel=3000.0),
               TuneConfig(shaper_x="ei", shaper_y="mzv", freq_x=60.0, freq_y=47.0, damping_x=0.2, accel=6000.0)]
    whole = evaluate_many(configs, freq_margin=0.05)
    split = split_map(lambda part: evaluate_many(part, freq_margin=0.05), configs, parts=2)
    assert [m.to_dict(details=True) for m in split] == [m.to_dict(details=True) for m in whole]
