"""agents.grid: the dense grid ``tune``'s convergence is checked against (benchmarks/bench_tune.py).

Truth here is counting and hand-computed areas, not the grid's own output."""

from __future__ import annotations

from pathlib import Path

import pytest

from ringtune.agents.tune.grid import hypervolume, run_grid
from ringtune.agents.tune.pareto import Point, pareto_front
from ringtune.agents.tune.grid import grid_params
from ringtune.agents.tune.space import SearchSpace, config_from_params
from ringtune.shaping.config import TuneConfig

TESTS = Path(__file__).resolve().parent

SPACE = SearchSpace(firmware="klipper", shapers=("none", "zv", "mzv"), per_axis=True, freq_x=(30.0, 90.0),
                    freq_y=(25.0, 75.0), damping=(0.0, 0.2), freq_limit_methods=("nophead", "sections", "marlin"),
                    freq_limit_hz=(10.0, 80.0), accel=(1000.0, 7000.0))


def _pt(t, q):
    return Point(TuneConfig(), t, q)


def test_hypervolume_of_a_hand_computed_staircase():
    # ref (4, 4): (1, 3) adds 3 × 1, (2, 1) adds 2 × 2 -> 7 s·mm; a dominated point adds nothing
    assert hypervolume([_pt(1, 3), _pt(2, 1)], (4, 4)) == pytest.approx(7.0)
    assert hypervolume([_pt(1, 3), _pt(2, 1), _pt(3, 2)], (4, 4)) == pytest.approx(7.0)
    assert hypervolume([_pt(5, 1)], (4, 4)) == 0.0                     # beyond the reference point
    assert hypervolume([], (4, 4)) == 0.0


def test_grid_params_count_and_every_point_inside_the_space():
    n_freq, dampings, accels, limits = 3, (0.05, 0.1), (2000.0, 5000.0, 7000.0), (20.0,)
    params = grid_params(SPACE, n_freq=n_freq, dampings=dampings, accels=accels, freq_limits=limits)
    per_axis = 1 + 2 * n_freq                       # none once, zv and mzv at 3 frequencies each
    shaped = per_axis ** 2 - 1                      # every pair but none/none takes the S levels
    n_limits = 1 + len(SPACE.freq_limit_methods) * len(limits)
    assert len(params) == (shaped * len(dampings) + 1) * n_limits * len(accels)
    configs = [config_from_params(p, SPACE) for p in params]
    keys = {tuple(sorted(c.to_dict().items())) for c in configs}
    assert len(keys) == len(params)                 # no point twice
    for c in configs:
        for ax in ("x", "y"):
            name, f, _ = c.axis(ax)
            lo, hi = getattr(SPACE, f"freq_{ax}")
            assert name in SPACE.shapers and (name == "none" or lo <= f <= hi)
        assert c.accel in accels and c.damping_x in (*dampings, 0.1)
    # the frequency levels are the ends and the middle of each axis's range
    assert sorted({c.freq_x for c in configs if c.shaper_x == "zv"}) == [30.0, 60.0, 90.0]


def test_run_grid_evaluates_every_point_with_the_study_evaluator(monkeypatch):
    monkeypatch.syspath_prepend(str(TESTS))
    import study_objective

    params = grid_params(SPACE, n_freq=2, dampings=(0.1,), accels=(3000.0, 6500.0))
    pts = run_grid(SPACE, params=params, evaluator="study_objective:evaluate", batch=7)
    assert len(pts) == len(params) and [p.number for p in pts] == list(range(len(params)))
    direct = study_objective.evaluate([config_from_params(p, SPACE) for p in params])
    for p, m in zip(pts, direct):
        assert (p.print_time_s, p.quality_mm, p.step_loss) == (m.print_time_s, m.overshoot_mm, m.step_loss)
    # 6500 mm/s² loses steps in that evaluator: no such point reaches the front
    front = pareto_front(pts)
    assert front and all(p.config.accel == 3000.0 for p in front)
    assert any(p.step_loss for p in pts)
