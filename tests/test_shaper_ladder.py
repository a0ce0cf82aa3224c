"""Each shaper of Klipper's rule at the highest acceleration the judgement allows: checked with an
evaluator whose verdicts are known in advance (ripple proportional to acceleration, a factor per
shaper; a motor bound above a set acceleration for one shaper), on the real search space of the
default printer."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from ringtune.agents.tune.pareto import point_from_metrics
from ringtune.agents.tune.shaper_ladder import DAMPINGS, FREQ_SCALES, RUNGS, climb, rule_shapings, rungs
from ringtune.agents.tune.space import default_space
from ringtune.agents.tune.stop import Bounds
from ringtune.envs.printer import load_printer
from ringtune.shaping.config import TuneConfig

#: µm of ripple at the start's 5000 mm/s² per shaper; it grows in proportion to the acceleration
RIPPLE_AT_START = {"ei": 60.0, "zvd": 40.0, "mzv": 100.0, "2hump_ei": 20.0}
OVERLOAD_ABOVE = 7000.0       # mm/s²: 2hump_ei asks a motor more than the reserve above this
BOUNDS = Bounds(max_path_error_mm=0.1, max_motor_load=0.8, max_show_through_mm=0.2)
FREQS = {"x": {"ei": 55.0, "zvd": 50.0, "mzv": 52.0, "2hump_ei": 66.0},
         "y": {"ei": 44.0, "zvd": 40.0, "mzv": 41.0, "2hump_ei": 53.0}}


def _metrics(cfg: TuneConfig):
    """Known verdicts: print time falls with acceleration; ripple is the shaper's factor times the
    acceleration (the worse axis); 2hump_ei overloads a motor above OVERLOAD_ABOVE."""
    a = float(cfg.accel)
    ripple = max(RIPPLE_AT_START[cfg.shaper_x], RIPPLE_AT_START[cfg.shaper_y]) * a / 5000.0 / 1000.0
    load = 0.9 if "2hump_ei" in (cfg.shaper_x, cfg.shaper_y) and a > OVERLOAD_ABOVE else 0.5
    return SimpleNamespace(print_time_s=1000.0 + 1e6 / a, step_loss=False, path_error_mm=0.05, overshoot_mm=0.03,
                           ringing_mm=0.01, peak_accel=a, motor_load=load, ripple_mm=ripple, ripple_p90_mm=ripple,
                           corner_in_mm=0.04, corner_out_mm=0.02, extrusion_over_pct=10.0,
                           extrusion_under_pct=8.0, e_lag_mm=0.05, show_through_mm=0.0)


def _fits(names=tuple(RIPPLE_AT_START)):
    rows = {ax: [SimpleNamespace(name=n, freq=FREQS[ax][n]) for n in names] for ax in "xy"}
    return {ax: SimpleNamespace(shapers=rows[ax], best=rows[ax][0]) for ax in "xy"}


@pytest.fixture(scope="module")
def space():
    return default_space(load_printer(None), "klipper")


def _point(cfg):
    return point_from_metrics(cfg, _metrics(cfg), max_path_error_mm=0.1, max_motor_load=0.8, max_show_through_mm=0.2)


def _climb(space, fits, **kw):
    start = _point(TuneConfig(shaper_x="ei", freq_x=55.0, shaper_y="ei", freq_y=44.0, accel=5000.0))
    calls = []

    def evaluate(configs):
        calls.append(len(configs))
        return [_metrics(c) for c in configs]

    return start, climb(start, {"klipper": start}, evaluate, space, BOUNDS, fits, **kw), calls


def _text(name, k=1.0, z=0.1):
    fx, fy = (round(FREQS[ax][name] * k, 1) for ax in "xy")
    return f"X {name} @ {fx:.1f} Hz S {z:g}, Y {name} @ {fy:.1f} Hz S {z:g}"


def _variants(name, value):
    """Each shaping of ``name`` the ladder tries -> ``value``; ei's at the start's own frequencies
    and damping is the start itself, left out."""
    return {_text(name, k, z): value for k in FREQ_SCALES for z in DAMPINGS
            if (name, k, z) != ("ei", 1.0, 0.1)}


V = len(FREQ_SCALES) * len(DAMPINGS)     # shapings per shaper


def test_each_shaper_climbs_as_high_as_the_judgement_allows(space):
    start, ladder, calls = _climb(space, _fits())
    # by hand: the start ripples 60 µm; a rung passes while the shaper's ripple stays within the
    # resolution (5 %, at least 1 µm) of it. zvd: 40·r ≤ 63 → r ≤ 1.575 → 1.5 (7500);
    # 2hump_ei: 20·r passes every rung, the motor bound stops it above 7000 → 1.35 (6750, on the
    # 100 mm/s² step 6800); mzv: 100·1.1 = 110 µm and ei: 60·1.1 = 66 µm fail the first rung.
    # Then the gap above the fastest: zvd failed at 8500, so 2/3 and 1/3 of the way from 7500, 8200
    # (65.6 µm: fails) and 7800 (62.4 µm: passes); 2hump_ei's gap (6800–7500) lies below 7500.
    # Frequency and damping do not matter to this evaluator: each shaper's shapings are alike.
    assert dict(ladder.tried) == {**_variants("zvd", 7800.0), **_variants("mzv", None),
                                  **_variants("2hump_ei", 6800.0), **_variants("ei", None)}
    assert ladder.offered == len(ladder.tried) == 4 * V - 1
    assert ladder.moved
    cfg = ladder.point.config
    # every zvd shaping reaches 7500 at the same print time and ripple: the first in the table's order
    assert (cfg.shaper_x, cfg.freq_x, cfg.shaper_y, cfg.freq_y, cfg.damping_x, cfg.accel) == \
        ("zvd", 50.0, "zvd", 40.0, 0.1, 7800.0)
    assert ladder.point.print_time_s < start.print_time_s
    # one batch per rung, of the shapings still climbing: all at 5500; mzv's and ei's out, zvd's
    # and 2hump_ei's at 6000, 6800 and 7500; 2hump_ei's out, zvd's at 8500, where they fail; then
    # zvd's gap, two accelerations each
    assert calls == [4 * V - 1, 2 * V, 2 * V, 2 * V, V, 2 * V] and ladder.evaluations == sum(calls)
    assert f"the fastest, {_text('zvd')} at 7800 mm/s²" in ladder.sentence()


def test_the_budget_cuts_the_shapings_in_the_tables_order(space):
    start, ladder, calls = _climb(space, _fits(), max_evaluations=V + 5)
    # the first V + 5 shapings: ei's V − 1, then 6 of zvd's, all judged at 5500; the budget spent there
    assert calls == [V + 5]
    assert dict(ladder.tried) == {**_variants("ei", None), **dict(list(_variants("zvd", 5500.0).items())[:6])}
    assert ladder.point.config.accel == 5500.0 and ladder.evaluations == V + 5
    assert f"{V + 5} of {4 * V - 1} within the budget" in ladder.sentence()


def test_with_a_screen_the_budget_counts_what_is_judged(space):
    calls = []

    def exact(configs):
        calls.append(len(configs))
        return [_metrics(c) for c in configs]

    start, ladder, judged = _climb(space, _fits(), max_evaluations=V + 5, screen=exact)
    # every shaping is screened at 5500; of those passing (zvd's and 2hump_ei's, in the table's
    # order) the first V + 5 are judged, and the budget is spent
    assert calls == [4 * V - 1] and judged == [V + 5] and ladder.evaluations == V + 5
    assert dict(ladder.tried) == {**_variants("ei", None), **_variants("zvd", 5500.0), **_variants("mzv", None),
                                  **dict((k, 5500.0 if i < 5 else None)
                                         for i, k in enumerate(_variants("2hump_ei", None)))}
    # at 5500 the 2hump_ei shapings ripple least (22 against zvd's 44 µm): the first of them is chosen
    cfg = ladder.point.config
    assert (cfg.shaper_x, cfg.freq_x, cfg.damping_x, cfg.accel) == ("2hump_ei", 66.0, 0.1, 5500.0)


def test_nothing_faster_at_the_baselines_quality_leaves_the_choice(space):
    start, ladder, calls = _climb(space, _fits(("ei", "mzv")))
    assert not ladder.moved and ladder.point is start
    # ei's other shapings pass no rung (the same ripple at a higher acceleration: 66 > 63 µm)
    assert dict(ladder.tried) == {**_variants("mzv", None), **_variants("ei", None)}
    assert calls == [2 * V - 1]
    assert "none faster than the choice (none passed the first rung, 5500 mm/s²)" in ladder.sentence()


def test_the_rules_frequencies_and_dampings_per_shaper_and_axis(space):
    start = TuneConfig(shaper_x="ei", freq_x=55.0, shaper_y="ei", freq_y=44.0, accel=5000.0)
    got = rule_shapings(start, _fits(), space)
    # the start's own shaping is left out (the rule's pick, the first row, is the start's)
    assert {(c.shaper_x, c.freq_x, c.shaper_y, c.freq_y, c.damping_x) for c in got} == \
        {(n, round(FREQS["x"][n] * k, 1), n, round(FREQS["y"][n] * k, 1), z)
         for n in ("zvd", "mzv", "2hump_ei", "ei") for k in FREQ_SCALES for z in DAMPINGS} - {("ei", 55.0, "ei", 44.0, 0.1)}
    assert all(c.accel == 5000.0 and c.damping_x == c.damping_y for c in got)
    # the rule's table order: ei's first
    assert [c.shaper_x for c in got[:V - 1]] == ["ei"] * (V - 1)


def test_one_shaper_for_all_axes_tries_each_axis_frequency():
    rrf = default_space(load_printer(None), "rrf")
    start = TuneConfig(firmware="rrf", shaper_x="mzv", freq_x=45.0, shaper_y="mzv", freq_y=45.0, accel=5000.0)
    got = {(c.shaper_x, c.freq_x, c.shaper_y, c.freq_y, c.damping_x)
           for c in rule_shapings(start, _fits(("zvd", "mzv")), rrf)}
    assert got == {(n, f, n, f, z) for n in ("zvd", "mzv") for ax in "xy" for z in DAMPINGS
                   for f in (round(FREQS[ax][n] * k, 1) for k in FREQ_SCALES)}


def test_rungs_are_above_the_choice_and_inside_the_range(space):
    top = space.accel[1]
    assert rungs(5000.0, space) == [round(5000 * r / space.accel_step) * space.accel_step for r in RUNGS]
    high = rungs(0.8 * top, space)
    assert high and all(0.8 * top < a <= top for a in high) and len(high) < len(RUNGS)
    assert rungs(top, space) == []


def test_screening_on_the_exact_model_changes_nothing_but_the_cost(space):
    """The worst of the printer and its twins is no better than the exact model on any measure: a
    shaping the screen fails, the judgement fails too. Here the judged ripple is the exact one
    × 1.2 (the twins ring more); the baseline is judged."""
    calls: list = []

    def judged(configs):
        calls.append(("judged", len(configs)))
        out = []
        for c in configs:
            m = _metrics(c)
            m.ripple_mm *= 1.2
            m.ripple_p90_mm *= 1.2
            out.append(m)
        return out

    def exact(configs):
        calls.append(("exact", len(configs)))
        return [_metrics(c) for c in configs]

    start_cfg = TuneConfig(shaper_x="ei", freq_x=55.0, shaper_y="ei", freq_y=44.0, accel=5000.0)
    start = point_from_metrics(start_cfg, judged([start_cfg])[0], max_path_error_mm=0.1, max_motor_load=0.8,
                               max_show_through_mm=0.2)
    results = []
    for screen in (None, exact):
        calls.clear()
        ladder = climb(start, {"klipper": start}, judged, space, BOUNDS, _fits(), screen=screen)
        results.append((ladder, sum(n for kind, n in calls if kind == "judged"), calls))
    (plain, plain_judged, _), (screened, screened_judged, calls) = results
    assert screened.tried == plain.tried and screened.point.config == plain.point.config
    # mzv's and ei's shapings fail the first rung on the exact model and are never judged
    # by hand (the judged baseline ripples 72 µm, 75.6 with the resolution): mzv's shapings fail
    # 5500 on the exact model too (110 µm) and 2hump_ei's 7500 (the motor bound), so neither is
    # judged there; ei's pass the screen at 5500 (66 µm) and fail the judgement (79.2 µm)
    assert screened_judged == plain_judged - 2 * V and screened.evaluations == screened_judged
    assert screened.screened == sum(n for kind, n in calls if kind == "exact") > 0
    assert "screened on the exact model first" in screened.sentence()


def test_the_exact_model_is_no_worse_than_the_judged_worst_case():
    """The screen's premise on the real evaluator: each measure on the exact model is at most the
    worst of the printer and its ±5 % twins (tune's judgement), and print time is the same."""
    from ringtune.envs.evaluate import evaluate_many
    printer = load_printer(None)
    cfgs = [TuneConfig(shaper_x="mzv", freq_x=50.0, shaper_y="ei", freq_y=44.0, accel=7000.0),
            TuneConfig(shaper_x="zv", freq_x=60.0, shaper_y="zv", freq_y=47.0, accel=4000.0)]
    for ex, worst in zip(evaluate_many(cfgs, printer, None, freq_margin=0.0),
                         evaluate_many(cfgs, printer, None, freq_margin=0.05)):
        assert ex.print_time_s == worst.print_time_s
        a, b = ex.to_dict(), worst.to_dict()
        for key in ("ripple_mm", "ripple_p90_mm", "corner_in_mm", "corner_out_mm", "extrusion_over_pct",
                    "extrusion_under_pct", "path_error_mm", "motor_load", "show_through_mm"):
            assert a[key] <= b[key] + 1e-12, key
        assert ex.features and set(ex.features) == set(worst.features)
        for cls, measures in ex.features.items():
            for key, value in measures.items():
                assert value <= worst.features[cls][key] + 1e-12, (cls, key)


def test_a_smoother_is_tried_at_one_damping():
    """Kalico's smoothers take no damping ratio: one shaping per frequency, not one per damping."""
    kalico = default_space(load_printer(None), "kalico")
    start = TuneConfig(firmware="kalico", shaper_x="ei", freq_x=55.0, shaper_y="ei", freq_y=44.0, accel=5000.0)
    rows = {ax: [SimpleNamespace(name="smooth_mzv", freq=f)] for ax, f in (("x", 50.0), ("y", 40.0))}
    fits = {ax: SimpleNamespace(shapers=rows[ax], best=rows[ax][0]) for ax in "xy"}
    got = rule_shapings(start, fits, kalico)
    assert [(c.shaper_x, c.freq_x, c.freq_y) for c in got] == \
        [("smooth_mzv", round(50.0 * k, 1), round(40.0 * k, 1)) for k in FREQ_SCALES]


def test_the_rules_pick_of_two_shapers_is_tried_like_the_others(space):
    rows = {ax: [SimpleNamespace(name=n, freq=FREQS[ax][n]) for n in ("ei", "mzv")] for ax in "xy"}
    fits = {"x": SimpleNamespace(shapers=rows["x"], best=rows["x"][0]),     # X ei, Y mzv
            "y": SimpleNamespace(shapers=rows["y"], best=rows["y"][1])}
    start = TuneConfig(shaper_x="zv", freq_x=50.0, shaper_y="zv", freq_y=40.0, accel=5000.0)
    got = [(c.shaper_x, c.freq_x, c.shaper_y, c.freq_y, c.damping_x) for c in rule_shapings(start, fits, space)]
    pick = [("ei", round(55.0 * k, 1), "mzv", round(41.0 * k, 1), z) for k in FREQ_SCALES for z in DAMPINGS]
    assert got[-len(pick):] == pick and len(got) == 3 * len(pick)


@pytest.mark.parametrize("job", [None, "part"])
def test_judging_what_the_screen_passed_simulates_only_the_twins_for_the_same_figures(job):
    """evaluate_twins (the screen's exact-model figures reused, the ±5 % twins simulated) gives
    exactly evaluate_many's judgement, per feature class too: the built-in print and the part, a
    single acceleration and a per-feature configuration."""
    from ringtune.envs.evaluate import evaluate_many, evaluate_twins
    printer = load_printer(None)
    cfgs = [TuneConfig(shaper_x="mzv", freq_x=53.1, shaper_y="mzv", freq_y=42.7, damping_x=0.2, damping_y=0.2,
                       accel=6300.0),
            TuneConfig(shaper_x="ei", freq_x=51.4, shaper_y="mzv", freq_y=46.6, accel=4800.0,
                       feature_accel={"infill": 9000.0, "travel": 8000.0})]
    exact = evaluate_many(cfgs, printer, job, freq_margin=0.0)
    for a, b in zip(evaluate_twins(cfgs, exact, printer, job, freq_margin=0.05),
                    evaluate_many(cfgs, printer, job, freq_margin=0.05)):
        assert a.to_dict() == b.to_dict() and a.features == b.features


def test_the_wider_check_refuses_the_fastest_and_takes_the_next_that_holds(space):
    """Wider printers (agents/tune/wider.py) that find every zvd shaping above 7500 mm/s² worse: the
    ladder takes the fastest passing point at or below it (zvd at 7500, by hand from the test above),
    and says how many faster ones it refused; with no point holding, the choice stays."""
    asked = []

    def wider(cfg):
        asked.append((cfg.shaper_x, cfg.accel))
        return "worse" if cfg.shaper_x == "zvd" and cfg.accel > 7500 else None

    start, ladder, _ = _climb(space, _fits(), wider=wider)
    assert (ladder.point.config.shaper_x, ladder.point.config.accel) == ("zvd", 7500.0)
    assert ladder.held_off == V and asked[:V] == [("zvd", 7800.0)] * V and asked[V] == ("zvd", 7500.0)
    assert f"{V} faster ones refused: worse on a printer further off the model" in ladder.sentence()
    start, ladder, _ = _climb(space, _fits(), wider=lambda cfg: "worse")
    assert ladder.point is start and not ladder.moved and ladder.to_dict()["held_off"] > 0


def test_a_rung_that_buys_under_the_least_saving_leaves_the_choice(space):
    """The evaluator above with print time 1000 s + 1e3/a (the job's speeds bound it): zvd's and
    2hump_ei's shapings keep the quality up to 7800 and 6800 mm/s² as before, but the fastest saves
    1e3/5000 − 1e3/7800 ≈ 0.07 s, under MIN_STEP_SAVING (0.05 % of 1000.2 s): the choice stays."""
    from ringtune.agents.tune.stop import MIN_STEP_SAVING

    def metrics(cfg):
        return SimpleNamespace(**{**vars(_metrics(cfg)), "print_time_s": 1000.0 + 1e3 / float(cfg.accel)})

    start_cfg = TuneConfig(shaper_x="ei", freq_x=55.0, shaper_y="ei", freq_y=44.0, accel=5000.0)
    start = point_from_metrics(start_cfg, metrics(start_cfg), max_path_error_mm=0.1, max_motor_load=0.8,
                               max_show_through_mm=0.2)
    assert 1e3 / 5000.0 - 1e3 / 7800.0 < MIN_STEP_SAVING * start.print_time_s
    ladder = climb(start, {"klipper": start}, lambda cs: [metrics(c) for c in cs], space, BOUNDS, _fits())
    assert not ladder.moved and ladder.point is start
