"""The walk where nobody looks (issue 22): after the choice, each feature group is raised toward its
motor top (those nobody sees first) and the corners nobody sees toward their range's top, only as
far as the same judgement allows — checked with an evaluator whose verdicts are known in advance,
on the real per-feature space of the built-in part."""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import pytest

from ringtune.agents.tune.baselines import Baselines
from ringtune.agents.tune.choice import Choice
from ringtune.agents.tune.feature_space import feature_space
from ringtune.agents.tune.hidden_raise import FINER, LEVELS, Raise, batch, raise_hidden, unseen_tops
from ringtune.agents.tune.pareto import point_from_metrics
from ringtune.agents.tune.refine import refine
from ringtune.agents.tune.space import config_from_params, default_space, params_from_config
from ringtune.agents.tune.stop import Bounds
from ringtune.agents.tune.study import StudySettings
from ringtune.envs.planned_job import planned_job
from ringtune.envs.printer import load_printer
from ringtune.shaping.config import TuneConfig

RIPPLE_TOP = 10_000.0      # mm/s²: the infill above this makes the (visible) ripple worse
SHOW_PER_CORNER = 0.01     # mm of show-through per mm/s of the hidden corner rule
SOLID_TOP = 12.0           # mm/s: solid infill's corner rule above this over-extrudes it (judged as seen)
BOUNDS = Bounds(max_path_error_mm=0.1, max_motor_load=0.8, max_show_through_mm=0.2)


def _metrics(cfg: TuneConfig, travel_overloads: bool = False):
    """Known verdicts: print time falls with every hidden acceleration, the hidden corner rules and
    a lower minimum_cruise_ratio; the infill above RIPPLE_TOP ripples the walls more; the sparse
    infill's corner rule shows through, solid infill's above SOLID_TOP over-extrudes (its extrusion
    is seen); the travel may overload a motor at any raise."""
    fa = cfg.feature_accel
    corner = cfg.feature_corner.get("infill", 5.0)
    solid = cfg.feature_corner.get("solid_infill", 5.0)
    mcr = cfg.feature_min_cruise_ratio.get("infill", 0.5)
    t = (1000.0 + sum(1e6 / a for a in fa.values()) - corner - 0.5 * solid + 10.0 * mcr)
    return SimpleNamespace(print_time_s=t, step_loss=False, path_error_mm=0.05, overshoot_mm=0.03, ringing_mm=0.01,
                           peak_accel=5000.0, motor_load=0.9 if travel_overloads and fa.get("travel", 0) > 5000 else 0.5,
                           ripple_mm=0.08 if fa.get("infill", 0) > RIPPLE_TOP else 0.05, ripple_p90_mm=0.04,
                           corner_in_mm=0.1, corner_out_mm=0.04, extrusion_over_pct=15.0 if solid > SOLID_TOP else 10.0,
                           extrusion_under_pct=8.0,
                           e_lag_mm=0.05, show_through_mm=SHOW_PER_CORNER * corner)


@pytest.fixture(scope="module")
def space():
    printer = load_printer(None)
    return feature_space(default_space(printer, "klipper"), printer, "part")


def _start(space):
    params = {"shaper_x": "ei", "shaper_y": "mzv", "freq_x": 51.4, "freq_y": 46.6, "damping_x": 0.1,
              "damping_y": 0.1, "freq_limit": "off", "accel": 5000.0, "corner": 5.0, "min_cruise_ratio": 0.5,
              "corner_hidden": 5.0, "min_cruise_ratio_hidden": 0.5, "corner_solid": 5.0, "min_cruise_ratio_solid": 0.5,
              **{f"accel_{g}": 5000.0 for g, _lo, _hi in space.feature_accel}}
    return config_from_params(params, space)


def _walk(space, **kw):
    start_cfg = _start(space)
    start = point_from_metrics(start_cfg, _metrics(start_cfg, **kw), max_path_error_mm=0.1, max_motor_load=0.8,
                               max_show_through_mm=0.2)
    calls = []

    def evaluate(configs):
        calls.append(len(configs))
        return [_metrics(c, **kw) for c in configs]

    return raise_hidden(start, {"klipper": start}, evaluate, space, BOUNDS), calls


def test_each_group_goes_as_high_as_the_judgement_allows(space):
    tops = {g: hi for g, _lo, hi in space.feature_accel}
    lift, calls = _walk(space)
    got = params_from_config(lift.point.config, space)
    # the highest level of the way from 5000 to the top that keeps the ripple (3/4 breaks it), then
    # the highest of the finer steps into the gap above it
    levels = sorted(5000.0 + f * (tops["infill"] - 5000.0) for f in LEVELS)
    kept = max(round(a / 100) * 100 for a in levels if a <= RIPPLE_TOP)
    above = min(round(a / 100) * 100 for a in levels if a > RIPPLE_TOP)
    finer = [round((kept + f * (above - kept)) / 100) * 100 for f in FINER]
    assert got["accel_infill"] == max([kept] + [a for a in finer if a <= RIPPLE_TOP])
    assert got["accel_solid_infill"] == tops["solid_infill"] and got["accel_travel"] == tops["travel"]
    # the inner walls and the top surfaces after them (here nothing they would make worse)
    assert got["accel_hidden_walls"] == tops["hidden_walls"] and got["accel_top_surface"] == tops["top_surface"]
    # the corners nobody sees: the highest level within the show-through bound, then the highest of
    # the finer steps into the gap above it, no cruise smoothing
    within = (lambda c: SHOW_PER_CORNER * c <= BOUNDS.max_show_through_mm)
    corner_levels = [5.0 + f * (space.hidden_corner[1] - 5.0) for f in LEVELS]
    kept_c = max(c for c in corner_levels if within(c))
    above_c = min(c for c in corner_levels if not within(c))
    want = max(round(c * 2) / 2 for c in [kept_c] + [kept_c + f * (above_c - kept_c) for f in FINER] if within(c))
    assert want > round(kept_c * 2) / 2
    assert got["corner_hidden"] == want and got["min_cruise_ratio_hidden"] == 0.0
    # solid infill's corners apart: held by their own extrusion, which does not hold the others'
    assert want > SOLID_TOP >= got["corner_solid"] > 5.0 and got["min_cruise_ratio_solid"] == 0.0
    assert lift.moved and lift.point.print_time_s < lift.start.print_time_s
    # one batch each: the corners nobody sees and their finer steps, solid infill's and theirs,
    # infill (and its finer steps: the only group stopped below its top), solid infill, travel,
    # inner walls, top surfaces, the job's corner rule (it saves no time here: not taken; its
    # finer steps neither)
    assert lift.evaluations == sum(calls) and len(calls) == 12
    assert [k for k, _a, _b in lift.raised] == ["corner_hidden", "min_cruise_ratio_hidden", "corner_solid",
                                                "min_cruise_ratio_solid", "accel_infill", "accel_solid_infill",
                                                "accel_travel", "accel_hidden_walls", "accel_top_surface"]
    assert "infill 5000 → " in lift.sentence() and lift.to_dict()["to_print_time_s"] == lift.point.print_time_s
    for said in (f"their corner rule 5 → {want:g}", "their minimum_cruise_ratio 0.5 → 0,",
                 f"solid infill's corner rule 5 → {got['corner_solid']:g}", "solid infill's minimum_cruise_ratio 0.5 → 0,"):
        assert said in lift.sentence(), said


def test_each_setting_walked_says_what_holds_it_with_the_value_that_failed(space):
    """Held: the lowest value above where a setting stays that the walk tried, and why it failed,
    with both figures — the known evaluator's: the infill's ripple above RIPPLE_TOP against the
    baseline's, the hidden corner rule's show-through against the bound; a group at its top says so."""
    tops = {g: hi for g, _lo, hi in space.feature_accel}
    lift, _calls = _walk(space)
    held = {h.key: h for h in lift.held}
    assert list(held) == ["corner_hidden", "corner_solid", "accel_infill", "accel_solid_infill", "accel_travel",
                          "accel_hidden_walls", "accel_top_surface", "corner"]
    got = params_from_config(lift.point.config, space)
    infill = held["accel_infill"]
    levels = [round((5000.0 + f * (tops["infill"] - 5000.0)) / 100) * 100 for f in LEVELS]
    finer = [round((max(a for a in levels if a <= RIPPLE_TOP) + f * (min(a for a in levels if a > RIPPLE_TOP)
                                                                     - max(a for a in levels if a <= RIPPLE_TOP))) / 100) * 100
             for f in FINER]
    assert infill.value == got["accel_infill"]
    assert infill.tried == min(a for a in levels + finer if a > RIPPLE_TOP)
    assert infill.why[:5] == ("measure", "ripple_mm", "klipper", 0.08, 0.05) and not infill.screened
    assert infill.why.variant is None
    corner = held["corner_hidden"]
    assert corner.value == got["corner_hidden"] and SHOW_PER_CORNER * corner.tried > BOUNDS.max_show_through_mm
    assert corner.why[:3] == ("bound", "show_through_mm", None)
    assert corner.why[3] == pytest.approx(SHOW_PER_CORNER * corner.tried)
    assert corner.why[4] == BOUNDS.max_show_through_mm
    solid = held["corner_solid"]
    assert solid.value == got["corner_solid"] and solid.tried > SOLID_TOP
    assert solid.why[:5] == ("measure", "extrusion_over_pct", "klipper", 15.0, 10.0)
    assert held["accel_travel"].tried is None and held["accel_travel"].value == held["accel_travel"].top == tops["travel"]
    lines = lift.held_lines({"klipper": "Klipper's rule"}, " mm/s")
    assert f"infill at {infill.value:g} mm/s²: at {infill.tried:g}, ripple 80.0 µm > 50.0 µm of Klipper's rule" in lines
    assert f"travel at {tops['travel']:g} mm/s²: the top of its range" in lines
    assert lift.to_dict()["held"][2]["tried"] == infill.tried
    assert f"corner rule of solid infill at {solid.value:g} mm/s: at {solid.tried:g}, over-extrusion" in " ".join(lines)


def test_a_failure_the_screen_saw_is_said_to_be_on_the_model_as_fitted(space):
    """With the screen, what fails on the exact model is never judged: its Held says it was seen there."""
    start_cfg = _start(space)
    start = point_from_metrics(start_cfg, _metrics(start_cfg), max_path_error_mm=0.1, max_motor_load=0.8,
                               max_show_through_mm=0.2)
    lift = raise_hidden(start, {"klipper": start}, lambda cs: [_metrics(c) for c in cs], space, BOUNDS,
                        screen=lambda cs: [_metrics(c) for c in cs])
    infill = next(h for h in lift.held if h.key == "accel_infill")
    assert infill.screened and infill.why[:2] == ("measure", "ripple_mm")
    assert any(line.endswith("(on the model as fitted, against the baseline's worst over the model and its twins)")
               and line.startswith("infill")
               for line in lift.held_lines({}, " mm/s"))


def test_a_raise_that_saves_less_than_the_least_step_is_not_taken(space):
    """Travel that takes almost no time (its raise saves under MIN_STEP_SAVING of the print time)
    stays where it was, more motor load for nothing; Held says the time it needed to beat."""
    from ringtune.agents.tune.stop import MIN_STEP_SAVING

    def metrics(cfg):
        m = _metrics(cfg)
        travel = cfg.feature_accel.get("travel", 5000.0)
        m.print_time_s -= 1e6 / travel * (1 - 1e-4)        # travel's share: 1e-4 of the others'
        return m

    start_cfg = _start(space)
    start = point_from_metrics(start_cfg, metrics(start_cfg), max_path_error_mm=0.1, max_motor_load=0.8,
                               max_show_through_mm=0.2)
    lift = raise_hidden(start, {"klipper": start}, lambda cs: [metrics(c) for c in cs], space, BOUNDS)
    got = params_from_config(lift.point.config, space)
    assert got["accel_travel"] == 5000.0 and got["accel_solid_infill"] > 5000.0
    held = next(h for h in lift.held if h.key == "accel_travel")
    kind, key, _base, value, limit, _variant = held.why
    assert (kind, key) == ("time", "print_time_s") and held.tried is not None
    before = limit / (1 - MIN_STEP_SAVING)       # the choice's time when the travel was walked
    assert value < before and before - value < MIN_STEP_SAVING * before   # faster, by too little


def test_a_walk_that_ends_no_faster_by_the_resolution_is_not_taken(space):
    """Only the travel saves time here, 0.2 % of the print at its top: each step beats
    MIN_STEP_SAVING, but the walk's end is "the same" print time by the summary's resolution
    (0.5 %), so the choice stays where it was (the motor load for nothing); ``declined`` keeps where
    the walk ended and the sentence says both. Where the travel saves 1 %, the walk is taken."""
    def metrics(cfg, share):
        m = _metrics(cfg)
        travel = cfg.feature_accel.get("travel", 5000.0)
        top = dict((f"accel_{g}", hi) for g, _lo, hi in space.feature_accel)["accel_travel"]
        k = share * 1000.0 / (1 / 5000.0 - 1 / top)      # the travel at its top saves `share` of 1000 s
        m.print_time_s = 1000.0 + k / travel - k / 5000.0
        m.motor_load = 0.3 + 0.4 * (travel > 5000.0)
        return m

    for share, taken in ((0.002, False), (0.01, True)):
        start_cfg = _start(space)
        start = point_from_metrics(start_cfg, metrics(start_cfg, share), max_path_error_mm=0.1, max_motor_load=0.8,
                                   max_show_through_mm=0.2)
        lift = raise_hidden(start, {"klipper": start}, lambda cs: [metrics(c, share) for c in cs], space, BOUNDS)
        assert lift.raised and lift.raised[0][0] == "accel_travel"
        assert lift.moved == taken and (lift.point is start) == (not taken)
        end = lift.point if taken else lift.declined
        assert end.print_time_s == pytest.approx(1000.0 * (1 - share), rel=1e-12)
        if not taken:
            assert lift.sentence().startswith("Not raised where nobody looks: the walk (")
            assert "ended at 998.000 s from 1000.000 s, a saving under the 0.5 % that counts as faster, for motor " \
                   "load 70 % against 30 %: kept as it was." in lift.sentence()
            assert lift.to_dict()["declined_print_time_s"] == pytest.approx(998.0)
        else:
            assert lift.declined is None and lift.to_dict()["declined_print_time_s"] is None


def test_a_group_that_breaks_a_bound_at_every_level_stays(space):
    lift, _calls = _walk(space, travel_overloads=True)
    assert params_from_config(lift.point.config, space)["accel_travel"] == 5000.0
    assert "accel_travel" not in {k for k, _a, _b in lift.raised}


def test_the_walk_stops_at_its_budget(space):
    """No step begins once the budget is spent (tune gives the study's trials: a short study, a
    short walk); the sentence says it was cut."""
    start_cfg = _start(space)
    start = point_from_metrics(start_cfg, _metrics(start_cfg), max_path_error_mm=0.1, max_motor_load=0.8,
                               max_show_through_mm=0.2)
    lift = raise_hidden(start, {"klipper": start}, lambda cs: [_metrics(c) for c in cs], space, BOUNDS,
                        max_evaluations=5)
    # the first step, the corners nobody sees (4 levels and the corner as it is, each with and
    # without cruise smoothing, less the start itself) and its finer steps (2, each both ways),
    # starts before the budget is spent; nothing after
    first = len(batch("corner_hidden", params_from_config(start_cfg, space), space)) + 2 * len(FINER)
    assert first == 9 + 4
    assert lift.cut and lift.evaluations == first
    assert [k for k, _a, _b in lift.raised] == ["corner_hidden", "min_cruise_ratio_hidden"]
    assert "budget of 5 evaluations" in lift.sentence() and lift.to_dict()["cut"] is True


def _plain_and_screened(space, evaluate, exact, judged: list):
    """(the walk from :func:`_start` judging every candidate, how many it judged, the same walk
    screened by ``exact`` first); ``judged``: the list ``evaluate`` appends its batch sizes to."""
    start_cfg = _start(space)
    start = point_from_metrics(start_cfg, _metrics(start_cfg), max_path_error_mm=0.1, max_motor_load=0.8,
                               max_show_through_mm=0.2)
    plain = raise_hidden(start, {"klipper": start}, evaluate, space, BOUNDS)
    n_plain = sum(judged)
    judged.clear()
    return plain, n_plain, raise_hidden(start, {"klipper": start}, evaluate, space, BOUNDS, screen=exact)


def test_screening_on_the_exact_model_changes_the_walk_in_nothing_but_its_cost(space):
    """Each batch screened first on an exact model no worse than the judgement (here the same
    figures): the walk ends at the same point, and what fails is never judged."""
    judged, screened = [], []

    def evaluate(configs):
        judged.append(len(configs))
        return [_metrics(c) for c in configs]

    def exact(configs):
        screened.append(len(configs))
        return [_metrics(c) for c in configs]

    plain, n_plain, lift = _plain_and_screened(space, evaluate, exact, judged)
    assert lift.point.config == plain.point.config and lift.raised == plain.raised
    # every candidate screened; judged only what passed: the infill above RIPPLE_TOP, the corners
    # beyond the show-through bound and what saves no time are never judged
    assert lift.screened == sum(screened) == n_plain and lift.evaluations == sum(judged) < n_plain
    assert f"{lift.screened} screened on the exact model first" in lift.sentence()


def test_judging_the_screens_passes_fastest_first_ends_where_judging_all_does(space):
    """The judgement stricter than the screen (the twins ripple more: the infill above 7000 mm/s²
    fails there, above RIPPLE_TOP already on the model): judging what the screen passes fastest
    first, and only as far as the first that passes, ends the walk at the same point with the same
    settings raised and the same reasons for what holds each (tests/test_fastest_first.py counts
    what it leaves unjudged)."""
    judged = []

    def evaluate(configs):
        judged.append(len(configs))
        out = [_metrics(c) for c in configs]
        for c, m in zip(configs, out):
            if c.feature_accel.get("infill", 0) > 7000:
                m.ripple_mm = 0.07
        return out

    def exact(configs):
        return [_metrics(c) for c in configs]

    plain, n_plain, lift = _plain_and_screened(space, evaluate, exact, judged)
    assert lift.point.config == plain.point.config and lift.raised == plain.raised
    assert 5000 < lift.point.config.feature_accel["infill"] <= 7000      # raised, as far as the judgement allows
    assert [(h.key, h.value, h.tried, h.why.key if h.why else None) for h in lift.held] == \
        [(h.key, h.value, h.tried, h.why.key if h.why else None) for h in plain.held]
    assert lift.evaluations == sum(judged) < n_plain


def test_tunes_walk_spends_no_visible_quality_the_choice_had(space):
    """``tune`` (refine) holds the walk to the baselines and to the choice it starts from: with
    Klipper's pick rippling 0.08 mm and the choice 0.05, infill above RIPPLE_TOP (ripple 0.08: no
    worse than the pick, worse than the choice) is not taken — the walk held to the pick alone takes
    it — while the groups that change no visible measure still go to their tops."""
    start_cfg = _start(space)
    start = point_from_metrics(start_cfg, _metrics(start_cfg), max_path_error_mm=0.1, max_motor_load=0.8,
                               max_show_through_mm=0.2)
    pick_m = _metrics(start_cfg)
    pick_m.ripple_mm, pick_m.print_time_s = 0.08, pick_m.print_time_s + 100.0
    pick = point_from_metrics(start_cfg, pick_m, max_path_error_mm=0.1, max_motor_load=0.8, max_show_through_mm=0.2)
    tops = {g: hi for g, _lo, hi in space.feature_accel}

    def metrics(c):
        """The visible walls above the choice's acceleration ripple more than the pick (the
        measured stop keeps it)."""
        m = _metrics(c)
        m.ripple_mm = 0.09 if c.accel > start_cfg.accel else m.ripple_mm
        return m

    alone = raise_hidden(start, {"klipper": pick}, lambda cs: [metrics(c) for c in cs], space, BOUNDS)
    assert params_from_config(alone.point.config, space)["accel_infill"] == tops["infill"] > RIPPLE_TOP

    choice = Choice(start, "fastest-at-baseline-quality", "klipper", "as fast as the pick", ("klipper",))
    bl = Baselines(points={"klipper": pick}, labels={"klipper": "Klipper's pick"})
    settings = StudySettings(storage="", evaluator="tests.fake:evaluate", n_trials=200)
    got, stop, lift, _ladder = refine(choice, bl, lambda cs, printer, job: [metrics(c) for c in cs], settings,
                                      load_printer(None), space, BOUNDS)
    assert not stop.moved
    params = params_from_config(got.point.config, space)
    assert lift.moved and params["accel_infill"] <= RIPPLE_TOP
    assert got.point.metrics["ripple_mm"] == pytest.approx(0.05)
    assert params["accel_travel"] == tops["travel"] and params["accel_solid_infill"] == tops["solid_infill"]
    assert "than the baseline's or the choice's own before" in got.sentence


def test_the_walks_ceiling_puts_every_setting_nobody_sees_at_its_top_and_keeps_what_is_seen(space):
    start = _start(space)
    tops = {g: hi for g, _lo, hi in space.feature_accel}
    ceiling = unseen_tops(start, space)
    # by hand: each group nobody sees at its range's top (inner walls and solid infill too), the top
    # surfaces, the visible walls and the job's corner rule as they were
    assert ceiling.accel == start.accel and ceiling.corner == start.corner
    assert ceiling.min_cruise_ratio == start.min_cruise_ratio
    assert ceiling.feature_accel["top_surface"] == start.feature_accel["top_surface"]
    for cls, group in (("inner_wall", "hidden_walls"), ("infill", "infill"), ("support", "infill"),
                       ("solid_infill", "solid_infill"), ("travel", "travel")):
        assert ceiling.feature_accel[cls] == tops[group], cls
    for cls in ("infill", "support", "travel", "solid_infill"):
        assert ceiling.feature_corner[cls] == space.hidden_corner[1]
        assert ceiling.feature_min_cruise_ratio[cls] == 0.0
    # planned, the part at that ceiling is faster than the start and no faster than with the groups
    # nobody sees at no limit at all
    printer = load_printer(None)
    t_start = planned_job(printer, "part", start).print_time
    t_ceiling = planned_job(printer, "part", ceiling).print_time
    free = dataclasses.replace(ceiling, feature_accel={**ceiling.feature_accel, **dict.fromkeys(
        ("inner_wall", "infill", "support", "solid_infill", "travel"), 1e6)}, max_accel_x=1e6, max_accel_y=1e6)
    assert planned_job(printer, "part", free).print_time < t_ceiling < t_start


def test_the_ceiling_sentence_says_what_share_of_the_room_the_walk_took():
    def point(t):
        return SimpleNamespace(print_time_s=t)
    walk = Raise(point(1000.0), point(1200.0))
    text = walk.ceiling_sentence(950.0)
    assert "950.0 s" in text and "took 200.0 of the 250.0 s" in text and "(1200.0 s)" in text and "(80 %)" in text
    assert "No faster than the walk's start (1200.0 s)" in Raise(point(1200.0), point(1200.0)).ceiling_sentence(1200.0)
    # tops that plan slower than where the walk ended (Kalico's caps: a higher ACCEL lowers the
    # corners' speed where the caps bind) are said to be no ceiling, not a share over 100 %
    for ceiling in (1100.0, 1250.0):
        text = walk.ceiling_sentence(ceiling)
        assert "ended faster than that, at 1000.0 s" in text and "no ceiling" in text and "%" not in text


@pytest.mark.parametrize("junction", ["jerk", "jd"])
def test_the_walks_ceiling_on_a_printer_without_minimum_cruise_ratio(junction):
    """Marlin's and RRF's corner rules have no minimum_cruise_ratio (the space has none): the ceiling
    still puts each corner group's rule at its range's top and every hidden group's acceleration at
    its top, and its sentence does not speak of a ratio the firmware lacks."""
    printer = dataclasses.replace(load_printer(None), limits_dict={**load_printer(None).limits_dict,
                                                                   "junction": junction})
    space = feature_space(default_space(printer, "marlin"), printer, "part")
    assert space.hidden_min_cruise_ratio is None and space.hidden_corner is not None
    params = {"shaper_x": "zv", "shaper_y": "zv", "freq_x": 50.0, "freq_y": 45.0, "damping_x": 0.1,
              "damping_y": 0.1, "freq_limit": "off", "accel": 5000.0,
              **{f"accel_{g}": 5000.0 for g, _lo, _hi in space.feature_accel}}
    start = config_from_params(params, space)
    ceiling = unseen_tops(start, space)
    tops = {g: hi for g, _lo, hi in space.feature_accel}
    for cls, group in (("inner_wall", "hidden_walls"), ("infill", "infill"), ("travel", "travel")):
        assert ceiling.feature_accel[cls] == tops[group], cls
    for cls in ("infill", "support", "travel", "solid_infill"):
        assert ceiling.feature_corner[cls] == space.hidden_corner[1]
    assert not ceiling.feature_min_cruise_ratio
    lift = Raise(point=SimpleNamespace(print_time_s=95.0), start=SimpleNamespace(print_time_s=100.0))
    assert "minimum_cruise_ratio" not in lift.ceiling_sentence(90.0, cruise=False)
    assert "minimum_cruise_ratio 0" in lift.ceiling_sentence(90.0)


@pytest.mark.parametrize("keep_unset", [False, True])
def test_a_job_with_its_own_corner_rule_keeps_it_where_the_walk_changes_nothing(space, keep_unset):
    """The start leaves the corner settings unset (a single-acceleration choice: the job's own M205 /
    SQUARE_CORNER_VELOCITY rule). With ``keep_unset`` (the job sets its own), every candidate of the
    walk's first step (the corners nobody sees) leaves unset what that step does not change: the
    job-wide corner rule and ratio, solid infill's corner rule and ratio; without it, a candidate
    writes the printer's values out (the same plan on a job with no corner commands of its own)."""
    params = params_from_config(_start(space), space)
    start_cfg = dataclasses.replace(config_from_params(params, space), corner=None, min_cruise_ratio=None,
                                    feature_corner={}, feature_min_cruise_ratio={})
    start = point_from_metrics(start_cfg, _metrics(start_cfg), max_path_error_mm=0.1, max_motor_load=0.8,
                               max_show_through_mm=0.2)
    calls = []

    def evaluate(configs):
        calls.append(list(configs))
        return [_metrics(c) for c in configs]

    raise_hidden(start, {"klipper": start}, evaluate, space, BOUNDS, keep_unset=keep_unset)
    first = calls[0]
    assert first and any(c.feature_corner.get("infill", 0.0) > params["corner_hidden"] for c in first)
    for c in first:
        if keep_unset:
            assert c.corner is None and c.min_cruise_ratio is None
            assert "solid_infill" not in c.feature_corner and "solid_infill" not in c.feature_min_cruise_ratio
        else:
            assert c.corner == params["corner"] and c.min_cruise_ratio == params["min_cruise_ratio"]
            assert c.feature_corner["solid_infill"] == params["corner_solid"]
