"""Klipper's pick where the motors cannot follow it: the rule sets max_accel by smoothing alone, so
on a printer with weak motors its pick at max_accel loses steps or runs over the reserve. tune then
judges the pick at the highest acceleration where the motors keep their reserve and says so; a pick
the motors can follow stays as it is."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from ringtune.agents.tune.baselines import LOWER_STEP, Baselines, baselines_for
from ringtune.agents.tune.study import DEFAULT_EVALUATOR, StudySettings, resolve_evaluator
from ringtune.agents.tune.versus import baseline_evaluations
from ringtune.envs.printer import load_printer, printer_from_dict
from ringtune.envs.random_printer import random_printer_dict
from ringtune.shaping.config import TuneConfig


def _metrics(accel: float, load_of) -> SimpleNamespace:
    """Figures alike for every acceleration but the motor load (``load_of(accel)``) and print time."""
    load = load_of(accel)
    return SimpleNamespace(print_time_s=1000.0 + 1e6 / accel, step_loss=load > 1.0, path_error_mm=0.03,
                           overshoot_mm=0.01, ringing_mm=0.005, peak_accel=accel, motor_load=load,
                           ripple_mm=0.02, ripple_p90_mm=0.018, corner_in_mm=0.03, corner_out_mm=0.01,
                           extrusion_over_pct=5.0, extrusion_under_pct=8.0, e_lag_mm=0.5, show_through_mm=0.01)


def _baselines(pick_accel: float, load_of):
    calls = []

    def evaluator(configs, printer, job, **_kw):
        calls.append([c.accel for c in configs])
        return [_metrics(c.accel, load_of) for c in configs]

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
    assert len(calls) <= 1 + 4                          # the baselines, then at most four tries
    assert f"at the motors' limit ({k.config.accel:.0f} mm/s²)" in out.labels["klipper"]
    assert len(out.notes) == 1 and "max_accel 21300 mm/s²" in out.notes[0] and "loses steps" in out.notes[0]
    assert f"judged at {k.config.accel:.0f} mm/s²" in out.notes[0] and notes and notes[0].endswith(out.notes[0][:-1])
    assert out.points["none"].config.accel == 3000.0     # the others as they were


def test_a_pick_the_motors_can_follow_stays_as_it_is():
    out, calls, notes = _baselines(4000.0, lambda a: a / 6100.0)
    assert out.points["klipper"].config.accel == 4000.0 and len(calls) == 1
    assert out.labels["klipper"] == "Klipper's rule" and not out.notes and not notes


def test_where_no_acceleration_relieves_the_motors_the_pick_stays():
    """A job whose own accelerations rule: the load does not move with the pick's acceleration."""
    out, calls, _notes = _baselines(9000.0, lambda a: 0.95)
    assert out.points["klipper"].config.accel == 9000.0 and not out.points["klipper"].feasible
    assert not out.notes and len(calls) <= 1 + 4


def test_tune_and_simulate_judge_a_weak_motors_pick_at_the_same_acceleration():
    """A random printer whose motors cannot follow Klipper's pick (seed 7: the rule's max_accel
    21300 mm/s² asks them for more than their force on the built-in print): tune's baselines and
    simulate's lower it to one acceleration, where the simulated motors keep the reserve."""
    printer = printer_from_dict(random_printer_dict(np.random.default_rng(7), load_printer(None).to_dict()))
    notes: list[str] = []
    settings = StudySettings(storage="", motor_reserve=0.2, freq_margin=0.05, printer=printer)
    tuned = baselines_for(printer, "klipper", settings, resolve_evaluator(DEFAULT_EVALUATOR), "ripple_mm",
                          note=notes.append)
    bl, judged = baseline_evaluations(printer, "klipper", None, freq_margin=0.05, motor_reserve=0.2, note=notes.append)
    first = tuned.notes[0]
    assert "max_accel 21300 mm/s²" in first and "asks the motors for" in first
    accel = tuned.configs["klipper"].accel
    assert LOWER_STEP <= accel < 21300 and bl.configs["klipper"].accel == accel
    m = judged["klipper"][0]
    assert not m.step_loss and m.motor_load <= 0.8 and m.motor_load == pytest.approx(tuned.points["klipper"].metrics["motor_load"])
    assert bl.labels["klipper"] == tuned.labels["klipper"] and f"({accel:.0f} mm/s²)" in bl.labels["klipper"]
    assert sum("judged at" in n for n in notes) == 2
