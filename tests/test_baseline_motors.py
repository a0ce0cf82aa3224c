"""Klipper's pick over a bound: the rule sets max_accel by its own smoothing target alone, so on a
printer with weak motors its pick at max_accel loses steps or runs over the reserve, and with a
shaper that smooths much it can round corners past the path-error bound. tune (and simulate) then
judge the pick at the highest acceleration found within the bounds and say so; a pick within them
stays as it is."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from ringtune.agents.tune.baselines import LOWER_STEP, LOWER_TRIES, Baselines, baselines_for
from ringtune.agents.tune.study import DEFAULT_EVALUATOR, StudySettings, resolve_evaluator
from ringtune.agents.tune.versus import baseline_evaluations
from ringtune.envs.printer import load_printer, printer_from_dict
from ringtune.envs.random_printer import random_printer_dict
from ringtune.shaping.config import TuneConfig


def _metrics(accel: float, load_of, path_error_of) -> SimpleNamespace:
    """Figures alike for every acceleration but the motor load (``load_of(accel)``), the path error
    (``path_error_of(accel)``, mm) and print time."""
    load = load_of(accel)
    return SimpleNamespace(print_time_s=1000.0 + 1e6 / accel, step_loss=load > 1.0, path_error_mm=path_error_of(accel),
                           overshoot_mm=0.01, ringing_mm=0.005, peak_accel=accel, motor_load=load,
                           ripple_mm=0.02, ripple_p90_mm=0.018, corner_in_mm=0.03, corner_out_mm=0.01,
                           extrusion_over_pct=5.0, extrusion_under_pct=8.0, e_lag_mm=0.5, show_through_mm=0.01)


def _baselines(pick_accel: float, load_of, path_error_of=lambda a: 0.03):
    calls = []

    def evaluator(configs, printer, job, **_kw):
        calls.append([c.accel for c in configs])
        return [_metrics(c.accel, load_of, path_error_of) for c in configs]

    configs = Baselines()
    configs.add("klipper", TuneConfig(shaper_x="mzv", freq_x=60.0, shaper_y="mzv", freq_y=50.0, accel=pick_accel),
                "Klipper's rule", "measurement")
    configs.add("none", TuneConfig(shaper_x="none", shaper_y="none", freq_x=0.0, freq_y=0.0, accel=3000.0),
                "no shaping", "no shaping")
    notes: list[str] = []
    settings = StudySettings(storage="", motor_reserve=0.2)
    out = baselines_for(load_printer(None), "klipper", settings, evaluator, "ripple_mm", note=notes.append,
                        configs=configs)
    return out, calls, notes


def _highest(load_of, allowed: float = 0.8) -> float:
    """The highest acceleration on the grid whose load is within ``allowed`` (brute force)."""
    return max(a for a in range(int(LOWER_STEP), 40000, int(LOWER_STEP)) if load_of(float(a)) <= allowed)


@pytest.mark.parametrize("load_of", [lambda a: a / 6100.0,                 # force ∝ acceleration
                                     lambda a: 0.15 + a / 9000.0],         # and a part that does not grow
                         ids=["proportional", "affine"])
def test_a_pick_the_motors_cannot_follow_is_judged_at_the_highest_acceleration_they_can(load_of):
    out, calls, notes = _baselines(21300.0, load_of)
    k = out.points["klipper"]
    assert k.feasible and k.config.accel == _highest(load_of)
    assert out.configs["klipper"] is k.config and k.config.shaper_x == "mzv" and k.config.freq_x == 60.0
    assert len(calls) <= 1 + LOWER_TRIES                # the baselines, then the tries
    assert out.labels["klipper"] == f"Klipper's rule at {k.config.accel:.0f} mm/s² (within the bounds)"
    assert len(out.notes) == 1 and "max_accel 21300 mm/s²" in out.notes[0] and "loses steps" in out.notes[0]
    assert f"judged at {k.config.accel:.0f} mm/s²" in out.notes[0] and "has motor load" in out.notes[0] and notes and notes[0].endswith(out.notes[0][:-1])
    assert out.points["none"].config.accel == 3000.0     # the others as they were


def test_a_pick_that_rounds_corners_past_the_bound_is_judged_where_it_keeps_it():
    """Motors strong enough; the path error grows with the acceleration (0.1 mm bound)."""
    def path_error(a):
        return 0.02 + a / 60000.0

    out, calls, _notes = _baselines(7800.0, lambda a: a / 30000.0, path_error)
    k = out.points["klipper"]
    highest = max(a for a in range(100, 7800, 100) if path_error(a) <= 0.1)
    assert k.feasible and k.config.accel == highest == 4800
    assert "has path error 150.0 µm (100.0 µm allowed)" in out.notes[0] and "loses steps" not in out.notes[0]
    assert "judged at 4800 mm/s², the highest found within the bounds (motor load 16%, path error 100.0 µm)" \
        in out.notes[0]


def test_a_path_error_that_barely_falls_with_the_acceleration_is_bracketed_to_the_grids_highest():
    """The path error of Klipper's ZV pick for Marlin on the built-in part, as simulated (µm at
    7800, 7300, 7000, 6500, 6000, 5800 mm/s²; linear between): it falls 9 µm over 2000 mm/s², so a
    line through two tries overshoots; the tries bracket the bound and land on the grid's highest."""
    table = np.array([[5800, 96.4], [6000, 98.0], [6500, 100.9], [7000, 102.4], [7300, 102.8], [7800, 105.8]])

    def path_error(a):
        return float(np.interp(a, table[:, 0], table[:, 1])) / 1000.0

    out, calls, _notes = _baselines(7800.0, lambda a: a / 13300.0, path_error)
    highest = max(a for a in range(5800, 7800, 100) if path_error(a) <= 0.1)
    assert out.points["klipper"].config.accel == highest == 6300
    assert len(calls) <= 1 + LOWER_TRIES


def test_a_pick_the_motors_can_follow_stays_as_it_is():
    out, calls, notes = _baselines(4000.0, lambda a: a / 6100.0)
    assert out.points["klipper"].config.accel == 4000.0 and len(calls) == 1
    assert out.labels["klipper"] == "Klipper's rule" and not out.notes and not notes


def test_where_no_acceleration_relieves_the_motors_the_pick_stays():
    """A job whose own accelerations rule: the load does not move with the pick's acceleration."""
    out, calls, _notes = _baselines(9000.0, lambda a: 0.95)
    assert out.points["klipper"].config.accel == 9000.0 and not out.points["klipper"].feasible
    assert not out.notes and len(calls) <= 1 + LOWER_TRIES


def test_tune_and_simulate_judge_a_weak_motors_pick_at_the_same_acceleration():
    """A random printer whose motors cannot follow Klipper's pick (seed 7: the rule's max_accel
    21300 mm/s² asks them for more than their force on the built-in print): tune's baselines and
    simulate's lower it to one acceleration, where the simulated motors keep the reserve."""
    printer = printer_from_dict(random_printer_dict(np.random.default_rng(7), load_printer(None).to_dict()))
    notes: list[str] = []
    settings = StudySettings(storage="", motor_reserve=0.2, freq_margin=0.05, printer=printer)
    tuned = baselines_for(printer, "klipper", settings, resolve_evaluator(DEFAULT_EVALUATOR), "ripple_mm",
                          note=notes.append)
    bl, judged = baseline_evaluations(printer, "klipper", None, freq_margin=0.05, motor_reserve=0.2,
                                      max_path_error_mm=settings.max_path_error_mm, note=notes.append)
    first = tuned.notes[0]
    assert "max_accel 21300 mm/s²" in first and "has motor load" in first
    accel = tuned.configs["klipper"].accel
    assert LOWER_STEP <= accel < 21300 and bl.configs["klipper"].accel == accel
    m = judged["klipper"][0]
    assert not m.step_loss and m.motor_load <= 0.8 and m.motor_load == pytest.approx(tuned.points["klipper"].metrics["motor_load"])
    assert bl.labels["klipper"] == tuned.labels["klipper"] and f"at {accel:.0f} mm/s²" in bl.labels["klipper"]
    assert sum("judged at" in n for n in notes) == 2
