"""The study's twins only where they can count: each trial is judged on the printer as modelled
first, and its detuned twins (``freq_margin``) are simulated only when the result could still
matter.

The judged figures are the worst over the printer and its twins
(:func:`ringtune.envs.metrics.worst_case`), so the model's own figures are lower bounds of them. A
trial is settled on the model alone, its twins not simulated, when

- it already breaks a bound there (lost steps, path error, motor reserve, show-through): the worst
  of the three breaks it too; or
- a trial judged on all three and within the bounds beats it there on print time and on every
  visible measure the front is taken over (so it is off the front, whatever its twins), *and* it is
  worse than Klipper's pick on a judged visible measure on the model itself. The default choice
  holds every candidate to Klipper's pick variant by variant
  (:func:`ringtune.agents.tune.pareto.compare_figure`), so such a trial can be neither the choice
  nor a runner-up.

A settled trial keeps the model's figures and says so (user attribute ``screened``); read back it
is ruled out (``Point.screened``, one of :data:`ringtune.agents.tune.pareto.BOUNDS`), so nothing
the study reports as on the front or chooses rests on a lower bound, even when a resumed study is
read with other bounds.
"""

from __future__ import annotations

from collections import Counter
from typing import Any, Sequence

import numpy as np
from optuna.trial import TrialState

from ringtune.agents.tune.pareto import (DEFAULT_RESOLUTION, JUDGED_KEYS, VISIBLE_KEYS, max_motor_load,
                                         point_from_metrics, verdict)
from ringtune.envs.evaluate import evaluate_many, evaluate_twins

#: the user attribute of a trial settled on the model alone, and its values (why)
SCREENED = "screened"
OVER_A_BOUND = "over a bound on the model alone"
BEATEN = "beaten on the model alone"


def settled_counts(points) -> dict[str, int]:
    """How many of ``points`` (a study read back) were settled on the model alone, by why."""
    return dict(Counter(p.screened for p in points if p.screened))


def base_figures(point) -> dict | None:
    """What a trial is held to: Klipper's pick's judged visible measures on the model itself
    (:attr:`Point.variants` at (1, 1)), or None where it is not a usable reference (missing,
    infeasible, or judged on one printer only)."""
    if point is None or not point.feasible:
        return None
    exact = dict(point.variants).get((1.0, 1.0))
    return dict(exact) if exact else None


def front_keys(quality: str) -> tuple[str, ...]:
    """The figures the front is taken over: print time, the study's quality and the other
    visible measures (as ``tune`` takes it)."""
    return tuple(dict.fromkeys(("print_time_s", quality, *VISIBLE_KEYS)))


def worse_than_base(figures: dict, base: dict | None) -> bool:
    """Whether ``figures`` (a point's metrics on the model itself) are worse than the base's on a
    judged measure, at the default resolution."""
    if not base:
        return False
    return any(verdict(k, figures[k], base[k], DEFAULT_RESOLUTION) == "worse"
               for k in JUDGED_KEYS if k in figures and k in base)


def beaten(figures: dict, judged: Sequence[dict], keys: Sequence[str]) -> bool:
    """Whether one of ``judged`` (figure dicts) is no worse on every key and better on one."""
    if not judged or any(figures.get(k) is None for k in keys):
        return False
    mine = np.array([figures[k] for k in keys], float)
    theirs = np.array([[o.get(k, np.inf) for k in keys] for o in judged], float)
    return bool(np.any(np.all(theirs <= mine, axis=1) & np.any(theirs < mine, axis=1)))


def judged_trials(study) -> list[dict]:
    """The figures (``metrics`` attribute, with print time) of the study's complete trials judged
    on the printer and its twins and within every bound they were run with."""
    return [t.user_attrs["metrics"] for t in study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,))
            if _judged_within_bounds(t)]


def _judged_within_bounds(trial) -> bool:
    """A trial judged on all variants (not settled, with figures) that broke none of its bounds."""
    return (SCREENED not in trial.user_attrs and "metrics" in trial.user_attrs
            and not any(v > 0 for k, v in trial.system_attrs.items() if k.startswith("constraints:")))


def evaluate_trial(config, printer, settings, study, nthread: int | None = None) -> tuple[Any, str]:
    """(metrics, why settled or ""): ``config`` judged as the study judges it, its twins simulated
    only where they can count (see the module docstring)."""
    kw = {"job_accel": settings.job_accel}
    exact = evaluate_many([config], printer, settings.job, settings.backend, nthread=nthread, **kw)[0]
    p = point_from_metrics(config, exact, settings.quality, max_path_error_mm=settings.max_path_error_mm,
                           max_motor_load=max_motor_load(settings.motor_reserve),
                           max_show_through_mm=settings.max_show_through_mm)
    if not p.feasible:
        return exact, OVER_A_BOUND
    if worse_than_base(p.metrics, settings.screen_against) and beaten(
            p.metrics, judged_trials(study), front_keys(settings.quality)):
        return exact, BEATEN
    return evaluate_twins([config], [exact], printer, settings.job, settings.backend,
                          freq_margin=settings.freq_margin, nthread=nthread, **kw)[0], ""
