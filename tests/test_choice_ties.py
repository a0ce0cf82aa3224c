"""The default choice among equally fast configurations: where the planner gives several shapings
one print time (a sliced job whose own accelerations rule every move, so only the shapers differ),
the choice is one that no other beats on what a person sees — not the lowest ripple by a margin
under the resolution with worse corners and extrusion."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from ringtune.agents.tune.choice import fastest, pick
from ringtune.agents.tune.pareto import judge_bounds, point_from_metrics
from ringtune.agents.tune.space import default_space, unshaped_modes_note
from ringtune.envs.planned_job import resolve_printer
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError

PLAN_S = 933.3326182627112      # one plan: every shaping of the job gets this time


def _point(label: str, shaper: str, time_s: float, ripple: float, corner_in: float, under: float):
    """A point with the given figures (mm, %); the rest alike for all."""
    cfg = TuneConfig(firmware="klipper", shaper_x=shaper, shaper_y=shaper, freq_x=120.0, freq_y=80.0, accel=25000.0)
    m = SimpleNamespace(print_time_s=time_s, step_loss=False, path_error_mm=corner_in, overshoot_mm=0.015,
                        ringing_mm=0.007, peak_accel=14000.0, motor_load=0.6, ripple_mm=ripple,
                        ripple_p90_mm=0.9 * ripple, corner_in_mm=corner_in, corner_out_mm=0.0146,
                        extrusion_over_pct=6.5, extrusion_under_pct=under, e_lag_mm=0.9, show_through_mm=0.013)
    return point_from_metrics(cfg, m, label=label)


def test_of_equally_fast_shapings_the_one_nothing_beats_is_chosen_not_the_lowest_ripple():
    klipper = _point("klipper", "mzv", PLAN_S, 0.0256, 0.0241, 13.1)
    # the same plan: 0.4 µm more ripple (the same at 1 µm / 5 %), 7 µm less corner rounding and
    # 4.6 points less under-extrusion (better at 1 µm / 5 % and 1 point / 5 %)
    better = _point("ei", "ei", PLAN_S, 0.0260, 0.0170, 8.5)
    choice = pick([klipper, better], {"klipper": klipper})
    assert choice.point is better and "one no other beats on a visible measure" in choice.sentence
    # a hair faster than Klipper's pick (under the resolution): said so, not "faster"
    hair = _point("ei", "ei", PLAN_S - 0.004, 0.0260, 0.0170, 8.5)
    choice = pick([klipper, hair], {"klipper": klipper})
    assert choice.point is hair and "as fast as Klipper's rule at the resolution, better on 2 of" in choice.sentence
    # the lowest ripple alone would have kept Klipper's pick
    assert min([klipper, better], key=lambda p: p.quality_mm) is klipper


def test_a_faster_plan_still_wins_and_a_tie_nothing_beats_keeps_the_lowest_ripple():
    klipper = _point("klipper", "mzv", PLAN_S, 0.0256, 0.0241, 13.1)
    faster = _point("faster", "mzv", PLAN_S - 0.01, 0.0256, 0.0241, 13.1)
    better = _point("ei", "ei", PLAN_S, 0.0260, 0.0170, 8.5)
    assert fastest([klipper, faster, better]) is faster
    # neither beats the other (one ripples less by more than the resolution, the other corners better)
    low_ripple = _point("zv", "zv", PLAN_S, 0.0150, 0.0241, 13.1)
    assert fastest([low_ripple, better]) is low_ripple


def test_the_study_finding_the_baselines_own_shaping_is_said_to_be_the_baseline_itself():
    """The study's own trial of Klipper's shaping (its per-feature settings written out, all at the
    one acceleration) is Klipper's pick found again: the sentence says nothing better was found,
    not that it is "the best on the study's quality objective" of other shapings."""
    klipper = _point("klipper", "mzv", PLAN_S, 0.0256, 0.0241, 13.1)
    other = _point("ei", "ei", PLAN_S, 0.0262, 0.0240, 13.0)
    again = _point("again", "mzv", PLAN_S, 0.0256, 0.0241, 13.1)
    again.config.feature_accel.update({"infill": 25000.0, "travel": 25000.0})
    again.config.corner = 5.0
    choice = pick([other, again], {"klipper": klipper})
    assert choice.point is again and "nothing better than Klipper's rule itself" in choice.sentence
    # another shaping as fast, which nothing beats: the sentence names the tie-break
    other = _point("ei", "ei", PLAN_S, 0.0250, 0.0240, 13.0)
    choice = pick([other, again], {"klipper": klipper})
    assert choice.point is other and "then the best on the study's quality objective" in choice.sentence


def test_when_no_trial_is_feasible_a_feasible_baseline_is_chosen_else_the_error_counts_the_bounds():
    """With every trial over a bound, the default choice fell into an error although Klipper's pick
    (a candidate too) was feasible; and the error did not say which bound ruled the trials out."""
    klipper = _point("klipper", "mzv", PLAN_S, 0.0256, 0.0241, 13.1)
    rough = [judge_bounds(_point(f"trial {i}", "zv", PLAN_S - 10 * i, 0.03, 0.12, 9.0), 0.1, 0.8, 0.05)
             for i in range(1, 4)]
    assert all(p.too_rough and not p.feasible for p in rough)
    choice = pick([], {"klipper": klipper}, candidates=rough)
    assert choice.point is klipper and choice.baseline == "klipper"
    judge_bounds(klipper, 0.02, 0.8, 0.05)                     # now over the bound too
    with pytest.raises(RingtuneError) as err:
        pick([], {"klipper": klipper}, candidates=rough)
    assert "every trial and every baseline" in str(err.value)
    assert "of the 3 trials: 3 with a path error over --max-path-error" in str(err.value)
    with pytest.raises(RingtuneError) as err:
        pick([], {"klipper": klipper}, how="knee", candidates=rough)
    assert "every trial lost steps or broke a bound" in str(err.value)


def test_a_resonance_below_the_firmwares_lowest_shaper_frequency_is_named_when_nothing_is_feasible():
    """A stock Marlin shapes from 40 Hz: a printer ringing at 33 Hz cannot be shaped there, which is
    why nothing was feasible for it — the error now says so."""
    printer = resolve_printer(None)      # X 45.5 / 58.1 Hz, Y 38.9 / 51.3 Hz: within 5 % of 40 Hz a ZV there holds
    assert unshaped_modes_note(printer, default_space(printer, "marlin")) == ""
    low = printer.detuned(0.85, 1.0)     # X 38.7 Hz (within 5 %), Y 33.1 Hz (not)
    assert unshaped_modes_note(low, default_space(low, "klipper")) == ""
    note = unshaped_modes_note(low, default_space(low, "marlin"))
    assert note.startswith("the printer resonates at 33.1 Hz on Y, below the 40 Hz the search shapes from")
    rough = [judge_bounds(_point("trial 1", "zv", PLAN_S, 0.03, 0.12, 9.0), 0.1, 0.8, 0.05)]
    with pytest.raises(RingtuneError) as err:
        pick([], {}, candidates=rough, why_none=note)
    assert str(err.value).endswith("no shaper cancels that ringing")
