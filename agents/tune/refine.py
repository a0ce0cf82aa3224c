"""After the study: the choice refined with the study's own judgement, in three walks.

0. The study's choice, judged on the model and its twins, is held on the wider printers of
   :mod:`ringtune.agents.tune.wider` too; where it is worse there, the walks start from the next
   fastest point the rule would take that holds there (``runners_up``), else from the first
   baseline it was held to.
1. The shaper ladder (:mod:`ringtune.agents.tune.shaper_ladder`): each shaper of Klipper's rule
   climbs higher accelerations; the fastest that passes, and holds on the wider printers of
   :mod:`ringtune.agents.tune.wider`, replaces the choice.
2. The measured stop (:mod:`ringtune.agents.tune.stop`): the acceleration stepped up 5 % at a time
   (and each shaper frequency 2 % either way where a step fails) until a measure is worse, on the
   judged printers or on the wider ones. Where the ladder and the stop together end less than the
   print-time resolution (0.5 %) faster than the study's choice, neither is taken
   (:func:`declined_if_same_time`).
3. Per feature, the walk where nobody looks (:mod:`ringtune.agents.tune.hidden_raise`), each step
   held on the wider printers too.

The wider check runs where the study judges on twins with its own evaluator.

Each is held to the baselines the choice was held to, with the study's evaluator, frequency margin
and bounds, the walk also to the choice it starts from (it spends no visible quality: the top
surfaces are seen); each appends what it did to the choice's sentence.
"""

from __future__ import annotations

import dataclasses
import time
from typing import Callable, Sequence

from ringtune.agents.tune.baselines import Baselines
from ringtune.agents.tune.hidden_raise import Raise, raise_hidden
from ringtune.agents.tune.choice import BASELINE_NAMES, Choice
from ringtune.agents.tune.laps import Laps
from ringtune.agents.tune.shaper_ladder import Ladder, climb, shaping_text
from ringtune.agents.tune.pareto import DEFAULT_RESOLUTION, Point, Resolution
from ringtune.agents.tune.seam_check import check_seams, seams_of
from ringtune.agents.tune.space import SearchSpace
from ringtune.agents.tune.stop import Bounds, Stop, evaluated, failure_words, measured_stop
from ringtune.agents.tune.study import DEFAULT_EVALUATOR, StudySettings, evaluator_kwargs
from ringtune.agents.tune.wider import held_wider, study_evaluate_on, wider_check
from ringtune.envs.evaluate import evaluate_twins
from ringtune.envs.forked import Helpers
from ringtune.envs.planned_job import resolve_job
from ringtune.envs.window_dedup import WindowMemo
from ringtune.shaping.feature_settings import sets_corner


def refine(choice: Choice, bl: Baselines, evaluator: Callable, settings: StudySettings, printer, space: SearchSpace,
           bounds: Bounds, note: Callable[[str], None] = lambda s: None, runners_up: Sequence[Point] = (),
           laps: Laps | None = None) -> tuple[Choice, Stop | None, Raise | None, Ladder | None]:
    """(the choice, the measured stop or None, the raise where nobody looks or None, the shaper
    ladder or None): a choice held to baselines climbs the ladder and takes the measured stop; then,
    searching per feature, the raise, held to the same baselines and to the choice it starts from
    (or, where the choice is held to none: ``--no-baselines``, ``--pick knee``, to that alone).
    ``evaluator``: the study's (``f(configs, printer, job, **kwargs)``); ``bounds``: the study's;
    ``note``: one progress line as each walk starts and ends (they take a while on a long job);
    ``laps``: given the wall-clock seconds of each step (``wider_check_s``, ``shaper_ladder_s``,
    ``measured_stop_s``, ``walk_s``, ``seam_check_s``; those that ran)."""
    with Helpers() as helpers:        # the cores' helper processes, forked once for every walk
        return _refine(choice, bl, evaluator, settings, printer, space, bounds, note, runners_up, laps, helpers)


def _refine(choice, bl, evaluator, settings, printer, space, bounds, note, runners_up, laps, helpers: Helpers):
    """:func:`refine`, its batches split over ``helpers``."""
    evaluate, exact = _evaluators(evaluator, settings, printer, helpers)
    # the walk's candidates each change one feature's moves: most of their windows are its start's,
    # measured once (WindowMemo); the walk's end is judged afresh, so what is reported is exact
    walk_evaluate, walk_exact = _evaluators(evaluator, settings, printer, helpers, memo=True)
    job_accel = evaluator_kwargs(settings).get("job_accel")

    @helpers.register
    def seams(part):
        return seams_of(part, printer, settings.job, job_accel)

    t0 = time.monotonic()
    lap = (laps or Laps()).lap

    # the wider printers' simulations, shared by the four checks below (each baseline simulated once)
    on = (study_evaluate_on(settings.job, evaluator_kwargs(settings), printer, helpers)
          if exact is not None and settings.evaluator == DEFAULT_EVALUATOR else None)

    def widen(held: dict, start):
        """The wider check against ``held`` from ``start`` (None where the study judges on one printer
        or with an evaluator of its own)."""
        return None if on is None else wider_check({k: b.config for k, b in held.items()}, on,
                                                   start=start and start.config)

    def step(what: str) -> None:
        note(f"ringtune tune: after the study ({time.monotonic() - t0:.0f} s): {what}")

    stop = ladder = None
    if choice.baseline is not None:
        held = choice.held_to or (choice.baseline,)
        bases = {k: bl.points[k] for k in held}
        names = {k: bl.labels.get(k, BASELINE_NAMES.get(k, k)) for k in held}
        start, off = held_wider([choice.point, *runners_up], bases[held[0]], widen(bases, None))
        if off is not None:
            then = (f"{names[held[0]]} itself" if start is bases[held[0]] else
                    f"the next fastest the study tried that holds there ({start.label or 'a trial'}, "
                    f"{start.print_time_s:.3f} s)")
            choice = dataclasses.replace(choice, point=start, sentence=(
                f"{choice.sentence}; but that is worse on a printer further off the model "
                f"({failure_words(off, names.get(off.baseline, off.baseline))}), so the choice starts from {then}"))
        lap("wider_check_s")
        step("climbing the shapers of Klipper's rule's table ...")
        before = choice
        ladder = climb(choice.point, bases, evaluate, space, bounds, bl.fits, max_evaluations=settings.n_trials,
                       screen=exact, wider=widen(bases, choice.point))
        if ladder.moved:
            choice = dataclasses.replace(choice, point=ladder.point, sentence=(
                f"{choice.sentence}; then, climbing the shapers of Klipper's rule's table, "
                f"{shaping_text(ladder.point.config)} at {ladder.point.config.accel:.0f} mm/s², every visible "
                f"measure still no worse"))
        lap("shaper_ladder_s")
        step(f"{ladder.evaluations} judged; the measured stop, stepping the acceleration up ...")
        stop = measured_stop(choice.point, bases, evaluate, space, bounds, labels=names,
                             wider=widen(bases, choice.point))
        lap("measured_stop_s")
        if stop.moved:
            choice = dataclasses.replace(choice, point=stop.point, sentence=(
                f"{choice.sentence}; then stepped up by the measured stop from {stop.start.config.accel:.0f} to "
                f"{stop.point.config.accel:.0f} mm/s², every visible measure still no worse"))
        ladder, stop = declined_if_same_time(before.point, ladder, stop)
        if stop.declined is not None:
            choice = before
    else:
        bases = {"choice": choice.point}
    lift = None
    if space.per_feature:
        # quality is spent only where nobody looks: every visible measure also no worse than the
        # choice's own before the walk (the top surfaces are seen)
        step("the walk where nobody looks, each feature group toward its top ...")
        walk_bases = {**bases, "choice": choice.point}
        lift = raise_hidden(choice.point, walk_bases, walk_evaluate, space, bounds, max_evaluations=settings.n_trials,
                            keep_unset=sets_corner(resolve_job(settings.job)[1]),
                            screen=walk_exact, wider=widen(walk_bases, choice.point))
        if lift.moved and settings.evaluator == DEFAULT_EVALUATOR:
            lift.point = evaluated([lift.point.config], evaluate, bounds, lift.point.label)[0]
        lap("walk_s")
        step(f"done ({lift.evaluations} judged, {lift.screened} screened)")
        if lift.moved:
            held = ("than the baseline's or the choice's own before" if choice.baseline is not None
                    else "than the choice's own")
            choice = dataclasses.replace(choice, point=lift.point, sentence=(
                f"{choice.sentence}; then the features nobody sees raised toward their tops, no visible "
                f"measure worse {held}"))
        if lift.moved and settings.evaluator == DEFAULT_EVALUATOR:
            step("every seam of what a person sees, the walk's end against its start ...")
            lift.seams = check_seams(lift.start, lift.point, walk_bases, evaluate, bounds, printer, settings.job,
                                     job_accel=job_accel, split=lambda configs: helpers.map(seams, configs))
            lap("seam_check_s")
            step(f"done ({lift.seams.seams} seams, {lift.seams.simulated} configurations)")
            if lift.seams.point is not lift.point:
                choice = dataclasses.replace(choice, point=lift.seams.point, sentence=(
                    f"{choice.sentence}; at every seam of what a person sees, "
                    + ("the walk taken back" if lift.seams.point is lift.start
                       else f"{', '.join(lift.seams.taken_back)} taken back")))
    return choice, stop, lift, ladder


def declined_if_same_time(before: Point, ladder: Ladder, stop: Stop, res: Resolution = DEFAULT_RESOLUTION
                          ) -> tuple[Ladder, Stop]:
    """(ladder, stop) as they ended; or, where together they end less than the print-time resolution
    faster than ``before`` (the study's choice they climbed from; 0.5 %: what the summary calls the
    same time), both put back there, with ``declined`` where they ended and the stop's sentence
    saying so: the acceleration everyone sees raised for a saving nobody would notice spends motor
    load and the visible measures' margin (each held only at the resolution) for nothing, as the
    walk where nobody looks declines it (:func:`ringtune.agents.tune.hidden_raise._worth_it`)."""
    end = stop.point
    t0, t1 = before.print_time_s, end.print_time_s
    if end is before or t0 - t1 >= res.tolerance("print_time_s", t0, t1):
        return ladder, stop
    if ladder.moved:
        ladder = dataclasses.replace(ladder, point=ladder.start, declined=ladder.point)
    load = [p.metrics.get("motor_load", 0.0) * 100 for p in (end, before)]
    shaping = ("" if (end.config.axis("x"), end.config.axis("y")) == (before.config.axis("x"), before.config.axis("y"))
               else f", {shaping_text(end.config)}")
    sentence = (f"Not raised: the shaper ladder and the measured stop ended at {end.config.accel:.0f} mm/s²{shaping} "
                f"({t1:.3f} s from {t0:.3f} s), a saving under the {res.time_rel * 100:g} % that counts as faster, "
                f"for motor load {load[0]:.0f} % against {load[1]:.0f} %: kept at {before.config.accel:.0f} mm/s², "
                "as the study chose. " + stop.sentence.replace("What stops it at", "What stopped the climb at", 1))
    stop = dataclasses.replace(stop, point=before, start=before, kind="same time", key="print_time_s", baseline=None,
                               value=t1, base_value=t0, accel=float(end.config.accel), config=end.config,
                               sentence=sentence, variant=None, declined=end)
    return ladder, stop


def _evaluators(evaluator: Callable, settings: StudySettings, printer, helpers: Helpers | None = None,
                memo: bool = False) -> tuple[Callable, Callable | None]:
    """(judge, screen): ``judge(configs)`` as the study judges; ``screen(configs)`` the default
    evaluator on the exact model alone where the judgement is the worst of the printer and its
    detuned twins (else None); with the default evaluator ``screen.on_windows(configs, windows)``
    screens on some of the windows only (:mod:`ringtune.agents.tune.first_windows`). What the
    screen evaluated and is then judged has only its twins simulated
    (:func:`ringtune.envs.evaluate.evaluate_twins`: the same figures). The real
    simulation's batches are split over ``helpers`` (the same figures); an injected evaluator runs
    as given, in this process. ``memo``: the real simulation measures each window it has met
    before (in this process, on the same printer variant) from memory
    (:class:`ringtune.envs.window_dedup.WindowMemo`: a fresh simulation's figures to about 1e-7)."""
    kwargs = evaluator_kwargs(settings)
    if memo and settings.evaluator == DEFAULT_EVALUATOR:
        kwargs["memo"] = WindowMemo()     # each helper fills its own copy
    margin = kwargs.get("freq_margin")
    seen: dict[str, object] = {}
    split = helpers.map if helpers is not None and settings.evaluator == DEFAULT_EVALUATOR else _in_process
    register = helpers.register if helpers is not None else (lambda fn: fn)

    @register
    def twins(part):
        return evaluate_twins([c for c, _ in part], [m for _, m in part], printer, settings.job, kwargs["backend"],
                              freq_margin=margin, job_accel=kwargs["job_accel"], memo=kwargs.get("memo"))

    @register
    def judged(part):
        return evaluator(part, printer, settings.job, **kwargs)

    @register
    def exact(part):
        return evaluator(part, printer, settings.job, **{**kwargs, "freq_margin": 0.0})

    @register
    def exact_on(part, windows):
        return evaluator(part, printer, settings.job, **{**kwargs, "freq_margin": 0.0, "windows": windows})

    def judge(configs):
        configs = list(configs)
        known = [seen.get(c.key()) for c in configs]          # empty without a screen
        if configs and all(m is not None for m in known):
            return split(twins, list(zip(configs, known)))
        return split(judged, configs)

    def screen(configs):
        configs = list(configs)
        out = split(exact, configs)
        seen.update((c.key(), m) for c, m in zip(configs, out))
        return out

    if settings.evaluator == DEFAULT_EVALUATOR:      # a subset of the windows: figures never judged
        screen.on_windows = lambda configs, windows: split(exact_on, list(configs), windows)
    return judge, (screen if margin else None)


def _in_process(fn, items, *args) -> list:
    """``fn(items, *args)`` here (:meth:`ringtune.envs.forked.Helpers.map`'s signature, unsplit)."""
    return list(fn(list(items), *args))
