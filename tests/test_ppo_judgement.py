"""The PPO environment's cost is tune's judgement (envs/judgement.py): the same resolution and
constraints as agents/tune, the same verdict "worse" on every measure, the docstring's example."""

from __future__ import annotations

import numpy as np
import pytest

from ringtune.agents.tune.pareto import (DEFAULT_MAX_PATH_ERROR_MM, DEFAULT_MOTOR_RESERVE, DEFAULT_RESOLUTION,
                                         Point, judge)
from ringtune.envs.evaluate import evaluate_many
from ringtune.envs.judgement import DEFAULT_WEIGHTS, JUDGED_KEYS, JUDGEMENT, judged_cost, tolerance, worse_by
from ringtune.envs.metrics import EXTRUSION_KEYS, SEEN_KEYS, Metrics
from ringtune.shaping.config import TuneConfig


def test_defaults_are_tunes():
    assert JUDGEMENT == {"distance_mm": DEFAULT_RESOLUTION.distance_mm, "distance_rel": DEFAULT_RESOLUTION.distance_rel,
                         "pct_abs": DEFAULT_RESOLUTION.pct_abs,
                         "motor_reserve": DEFAULT_MOTOR_RESERVE, "max_path_error_mm": DEFAULT_MAX_PATH_ERROR_MM}
    assert set(SEEN_KEYS) | set(EXTRUSION_KEYS) | {"show_through_mm"} == set(JUDGED_KEYS)
    for a, b in ((0.0, 0.0), (0.004, 0.0045), (0.05, 0.2), (12.0, 3.0)):
        for k in JUDGED_KEYS:
            assert tolerance(k, a, b) == DEFAULT_RESOLUTION.tolerance(k, a, b)


def test_worse_where_tunes_judge_says_worse_on_real_evaluations():
    """On the default printer's built-in print: for each configuration, the measures the cost
    charges are exactly those tune's judge calls worse than the baseline's."""
    cfgs = [TuneConfig(shaper_x="mzv", shaper_y="mzv", freq_x=45.5, freq_y=38.9, accel=3000.0),   # the baseline
            TuneConfig(shaper_x="zv", shaper_y="zv", freq_x=35.0, freq_y=35.0, accel=8000.0),
            TuneConfig(shaper_x="ei", shaper_y="2hump_ei", freq_x=52.0, freq_y=50.0, accel=5000.0)]
    ms = evaluate_many(cfgs, None, None, backend="lti")
    base = ms[0]

    def pt(m):
        return Point(TuneConfig(), m.print_time_s, 0.0, False, {k: getattr(m, k) for k in JUDGED_KEYS})
    seen_worse = 0
    for m in ms:
        verdicts = judge(pt(m), pt(base), DEFAULT_RESOLUTION, keys=JUDGED_KEYS).verdicts
        worse = {k for k, v in verdicts.items() if v == "worse"}
        assert set(worse_by(m, base)) == worse
        seen_worse += len(worse)
    assert seen_worse > 0


def test_the_docstrings_example():
    base = Metrics(print_time_s=10.0, ripple_mm=0.005)
    m = Metrics(print_time_s=9.0, ripple_mm=0.007)
    assert judged_cost(m, base, 10.0, DEFAULT_WEIGHTS, 10.0) == pytest.approx(
        0.9 + 5 * np.log(1 + (0.007 - 0.005 - 0.001) / 0.005))
    assert judged_cost(m, base, 10.0, DEFAULT_WEIGHTS, 10.0) == pytest.approx(1.81, abs=0.002)
    # constraints: lost steps cost the penalty; a motor load of 0.9 is half the 20 % reserve over
    over = Metrics(print_time_s=9.0, ripple_mm=0.005, motor_load=0.9, step_loss=True)
    assert judged_cost(over, base, 10.0, DEFAULT_WEIGHTS, 10.0) == pytest.approx(0.9 + 10.0 + 10.0 * 0.5)


def test_worse_on_a_printer_variant_as_tunes_judge_says():
    """Judged on the printer and its ±5 % twins (the env's ``freq_margin``): the cost charges a
    measure worse on any variant both were judged on, exactly where tune's judge, comparing variant
    by variant, calls it worse — and the excess charged is the largest over the worst and the
    variants."""
    cfgs = [TuneConfig(shaper_x="mzv", shaper_y="mzv", freq_x=45.5, freq_y=38.9, accel=3000.0),   # the baseline
            TuneConfig(shaper_x="mzv", shaper_y="mzv", freq_x=47.0, freq_y=40.0, accel=3600.0),
            TuneConfig(shaper_x="ei", shaper_y="2hump_ei", freq_x=52.0, freq_y=50.0, accel=5000.0),
            TuneConfig(shaper_x="zv", shaper_y="zv", freq_x=42.0, freq_y=36.0, accel=3200.0)]
    ms = evaluate_many(cfgs, None, None, backend="lti", freq_margin=0.05)
    base = ms[0]

    def pt(m):
        variants = tuple((tuple(d["variant"]), {k: float(d[k]) for k in JUDGED_KEYS}) for d in m.details["variants"])
        return Point(TuneConfig(), m.print_time_s, 0.0, False, {k: getattr(m, k) for k in JUDGED_KEYS},
                     variants=variants)
    only_on_a_variant = 0
    for m in ms:
        j = judge(pt(m), pt(base), DEFAULT_RESOLUTION, keys=JUDGED_KEYS)
        worse = {k for k, v in j.verdicts.items() if v == "worse"}
        assert set(worse_by(m, base)) == worse
        for k in worse:
            f = j.figures[k]
            tol = tolerance(k, f.mine, f.theirs)
            assert worse_by(m, base)[k] >= (f.mine - f.theirs - tol) / max(f.theirs, tol) - 1e-12
            only_on_a_variant += f.variant is not None
    assert only_on_a_variant > 0
