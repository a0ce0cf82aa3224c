"""Judging fastest first (agents/tune/fastest_first.py): of the candidates the screen passes, the
judgement sees them in order of print time, a batch at a time, and stops at the first batch with
one that passes; checked on candidates whose verdicts are known in advance."""

from __future__ import annotations

from types import SimpleNamespace

from ringtune.agents.tune.fastest_first import judged_fastest_first
from ringtune.agents.tune.pareto import DEFAULT_RESOLUTION, point_from_metrics
from ringtune.agents.tune.stop import Bounds
from ringtune.shaping.config import TuneConfig

BOUNDS = Bounds(max_path_error_mm=0.1, max_motor_load=0.8, max_show_through_mm=0.2)


def _metrics(t: float, ripple: float):
    return SimpleNamespace(print_time_s=t, step_loss=False, path_error_mm=0.05, overshoot_mm=0.03, ringing_mm=0.01,
                           peak_accel=5000.0, motor_load=0.5, ripple_mm=ripple, ripple_p90_mm=0.04,
                           corner_in_mm=0.1, corner_out_mm=0.04, extrusion_over_pct=10.0, extrusion_under_pct=8.0,
                           e_lag_mm=0.05, show_through_mm=0.05)


def _point(t: float, ripple: float = 0.05):
    cfg = TuneConfig(accel=1000.0 * t)
    return point_from_metrics(cfg, _metrics(t, ripple), max_path_error_mm=0.1, max_motor_load=0.8,
                              max_show_through_mm=0.2)


def _run(times, judged_ripple, screen_ripple=lambda t: 0.05, accept=lambda p: None, needed=lambda i, t: False,
         screened=True):
    """judged_fastest_first over candidates with these print times (whole s; candidate i's config
    has accel 1000·t + i), the judgement's ripple by (print time, i) and the screen's by print
    time; the base ripples 0.05 mm at 100 s."""
    configs = [TuneConfig(accel=1000.0 * t + i) for i, t in enumerate(times)]
    calls = []

    def evaluate(cs):
        calls.append(sorted(c.accel // 1000.0 for c in cs))
        return [_metrics(c.accel // 1000.0, judged_ripple(c.accel // 1000.0, int(c.accel % 1000))) for c in cs]

    def screen(cs):
        return [_metrics(c.accel // 1000.0, screen_ripple(c.accel // 1000.0)) for c in cs]

    base = _point(100.0)
    out = judged_fastest_first(configs, evaluate, screen if screened else None, {"klipper": base}, base, BOUNDS,
                               DEFAULT_RESOLUTION, "t",
                               accept=accept, needed=needed, batch=2)
    return out, calls


def test_the_fastest_that_passes_is_taken_and_slower_ones_are_not_judged():
    # the judgement passes what prints in 30 s or more (the faster ones ripple more on the twins)
    times = [60.0, 10.0, 50.0, 20.0, 40.0, 30.0]
    (taken, points, why, judged), calls = _run(times, lambda t, i: 0.05 if t >= 30 else 0.09)
    assert times[taken] == 30.0 and points[taken].print_time_s == 30.0
    assert calls == [[10.0, 20.0], [30.0, 40.0]] and judged == 4
    assert [w[0].key if w else None for w in why] == [None, "ripple_mm", None, "ripple_mm", None, None]
    assert not any(w[1] for w in why if w)                     # seen by the judgement, not the screen
    assert points[times.index(60.0)] is None and points[times.index(40.0)] is not None


def test_what_the_screen_fails_is_never_judged_and_says_so():
    times = [10.0, 20.0, 30.0]
    (taken, _points, why, judged), calls = _run(times, lambda t, i: 0.05, screen_ripple=lambda t: 0.09 if t < 25 else 0.05)
    assert times[taken] == 30.0 and calls == [[30.0]] and judged == 1
    assert [(w[0].key, w[1]) for w in why[:2]] == [("ripple_mm", True), ("ripple_mm", True)]


def test_candidates_as_fast_as_the_last_of_a_batch_are_judged_with_it_and_ties_go_to_quality():
    # three at 20 s: all judged in the first batch; the one with the lowest ripple is taken
    times = [20.0, 10.0, 20.0, 20.0, 40.0]
    ripple = {0: 0.05, 2: 0.03, 3: 0.04}
    (taken, points, _why, judged), calls = _run(times, lambda t, i: 0.09 if t < 15 else ripple.get(i, 0.05))
    assert calls == [[10.0, 20.0, 20.0, 20.0]] and judged == 4
    assert taken == 2 and points[4] is None              # the lowest ripple of the three; none slower judged


def test_a_passing_candidate_the_caller_refuses_is_recorded_and_the_next_taken():
    times = [10.0, 20.0, 30.0]
    refuse = object()
    (taken, points, why, judged), calls = _run(times, lambda t, i: 0.05,
                                               accept=lambda p: refuse if p.print_time_s == 10.0 else None)
    assert times[taken] == 20.0 and why[0] == (refuse, False) and points[0] is None
    assert calls == [[10.0, 20.0]] and judged == 2


def test_slower_candidates_the_caller_needs_are_judged_after_the_take():
    times = [10.0, 20.0, 30.0, 40.0]
    (taken, points, why, judged), calls = _run(times, lambda t, i: 0.05 if t < 35 else 0.09,
                                               needed=lambda i, t: times[i] > 35.0)
    assert times[taken] == 10.0 and calls == [[10.0, 20.0], [40.0]] and judged == 3
    assert why[3][0].key == "ripple_mm" and points[2] is None and why[2] is None


def test_nothing_passes_every_candidate_judged():
    times = [10.0, 20.0, 30.0]
    (taken, points, why, judged), calls = _run(times, lambda t, i: 0.09)
    assert taken is None and judged == 3 and calls == [[10.0, 20.0], [30.0]]
    assert all(w[0].key == "ripple_mm" for w in why) and points == [None] * 3


def test_with_no_screen_every_candidate_is_judged_at_once_and_the_fastest_passing_taken():
    times = [30.0, 10.0, 20.0]
    (taken, points, why, judged), calls = _run(times, lambda t, i: 0.05 if t >= 20 else 0.09, screened=False)
    assert times[taken] == 20.0 and judged == 3 and calls == [[10.0, 20.0, 30.0]]
    assert why[1][0].key == "ripple_mm" and not why[1][1] and points[0] is not None
