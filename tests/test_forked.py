"""envs.forked.split_map and Helpers: a batch split over forked processes gives what one call gives,
in order; a child's error is raised in the parent; the real evaluator's figures do not depend on the
split; Helpers' processes are forked once and serve every later batch."""

from __future__ import annotations

import multiprocessing
import os
import signal

import pytest

from ringtune.envs.evaluate import evaluate_many
from ringtune.envs.forked import CAN_FORK, Helpers, in_background, split_map
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
    with Helpers(parts=2) as helpers:
        judged = helpers.register(lambda part, margin: evaluate_many(part, freq_margin=margin))
        for _ in range(2):                     # the second batch on the same helper
            out = helpers.map(judged, configs, 0.05)
            assert [m.to_dict(details=True) for m in out] == [m.to_dict(details=True) for m in whole]


def _pids(part, offset=0):
    return [(x + offset, os.getpid()) for x in part]


def test_helpers_are_forked_once_and_serve_every_batch_in_order():
    with Helpers(parts=3) as helpers:
        helpers.register(_pids)
        first = helpers.map(_pids, range(7), 100)
        assert [v for v, _ in first] == list(range(100, 107))
        pids = {p for _, p in first}
        assert len(pids) == 3 and os.getpid() in pids           # two helpers, the last part here
        again = helpers.map(_pids, range(5))
        assert [v for v, _ in again] == list(range(5))
        assert {p for _, p in again} == pids                     # the same processes, no new fork
        assert helpers.map(_pids, [4]) == [(4, os.getpid())]      # one item: here
        # a function registered after the fork is split by a fork of its own, with the same result
        late = helpers.register(lambda part: [x * 2 for x in part])
        assert helpers.map(late, range(6)) == [x * 2 for x in range(6)]
    for pid in pids - {os.getpid()}:                             # closed: ended and reaped
        with pytest.raises(ProcessLookupError):
            os.kill(pid, 0)


def test_helpers_fork_as_many_as_a_batch_needs():
    before = len(multiprocessing.active_children())
    with Helpers(parts=4) as helpers:
        helpers.register(_pids)
        small = {p for _, p in helpers.map(_pids, range(2))}
        assert len(small) == 2 and len(multiprocessing.active_children()) == before + 1
        large = {p for _, p in helpers.map(_pids, range(8))}
        assert len(large) == 4 and small <= large                  # the first helper serves again
    assert len(multiprocessing.active_children()) == before


def test_a_helpers_error_is_raised_here_and_new_helpers_serve_the_next_batch():
    def fails_on_two(part):
        if 2 in part:
            raise ValueError("two is not allowed")
        return [(x, os.getpid()) for x in part]

    def dies_on_zero(part):
        if 0 in part:
            os.kill(os.getpid(), signal.SIGKILL)
        return list(part)

    with Helpers(parts=2) as helpers:
        helpers.register(fails_on_two)
        helpers.register(dies_on_zero)
        before = {p for _, p in helpers.map(fails_on_two, [5, 6, 7, 8])}
        with pytest.raises(ValueError, match="two is not allowed"):
            helpers.map(fails_on_two, [1, 2, 3, 4])
        after = helpers.map(fails_on_two, [5, 6, 7, 8])
        assert [v for v, _ in after] == [5, 6, 7, 8]
        assert {p for _, p in after} - {os.getpid()} != before - {os.getpid()}    # forked afresh
        with pytest.raises(RingtuneError, match="ended without a result"):
            helpers.map(dies_on_zero, [0, 1, 2, 3])
        assert helpers.map(dies_on_zero, [4, 5, 6]) == [4, 5, 6]


def test_in_background_computes_in_another_process_while_this_one_goes_on(tmp_path):
    import time

    def waits_for_the_parent(path):
        """Sees the file this process writes after starting it (so it was not computed first)."""
        for _ in range(1000):
            if path.exists():
                return os.getpid(), path.read_text()
            time.sleep(0.01)
        return os.getpid(), None

    done = in_background(waits_for_the_parent, tmp_path / "go.txt")
    (tmp_path / "go.txt").write_text("written here")
    pid, text = done()
    assert pid != os.getpid() and text == "written here"

    def fails():
        raise RingtuneError("no such job", "job.gcode")

    with pytest.raises(RingtuneError, match="job.gcode: no such job"):
        in_background(fails)()
