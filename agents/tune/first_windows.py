"""A big batch screened on a few quality windows first: what fails there fails on the whole job.

The screen (:func:`ringtune.agents.tune.stop.screen_failures`) judges each configuration on the
exact model over every quality window of the job. In a big batch most fail (the shaper ladder's 66
shapings at a rung, all of them on the part), and each failure shows in one or two windows. Every
figure of the job but the ripple's 90th percentiles is the worst window's, and a figure's verdict
is monotone in it (worse than a baseline's where it exceeds it by more than the resolution, which
grows more slowly than the figure). So a configuration that breaks a bound, is worse than a
baseline on such a figure, or is no faster, on some of the windows, does so on the whole job:

1. the batch's first :data:`PROBES` configurations are screened on every window; the windows where
   more probes fail on that window alone rank first, then those where one comes nearest to failing
   (on the part, two probes fail in the windows that hold 55 and 42 of 63 failures; on the built-in
   print in one window, and the nearest of the others holds 45 of 52);
2. the rest are screened on the :data:`FIRST` first-ranked windows; what fails there is rejected
   with that failure (its figures those windows', lower bounds of the job's, never judged or shown);
3. the others are screened on every window, as without this step.

The verdicts are the screen's on every window (a test checks them against it). A batch smaller
than :data:`MIN_BATCH`, or a screen that cannot take a subset of windows (``on_windows``), is
screened on every window at once; so is the rest of a batch whose probes both pass (the shaper
ladder's later batches on the built-in print pass whole, and the first windows would be screened
for nothing).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Callable, Sequence

from ringtune.agents.tune.pareto import JUDGED_KEYS, Point, point_from_metrics
from ringtune.agents.tune.stop import Bounds, Failure, as_exact_variant, evaluated, failure, screen_failures
from ringtune.envs.metrics import Metrics
from ringtune.shaping.config import TuneConfig

#: configurations screened on every window first, whose failures rank the windows (one per core)
PROBES = 2
#: windows the rest of the batch is screened on first
FIRST = 2
#: smallest batch screened in stages (in a smaller one the probes, screened on every window, are over a quarter)
MIN_BATCH = 8
#: the figures that are not the worst window's (more windows can lower them)
NOT_WORST = "ripple_p90_mm"


def staged_failures(configs: Sequence[TuneConfig], screen: Callable[[Sequence[TuneConfig]], list],
                    bases: dict[str, Point], faster_than: Point, bounds: Bounds, res) -> list[Failure | None]:
    """:func:`ringtune.agents.tune.stop.screen_failures`' verdicts (per config, why it fails on the
    exact model, or None), found in stages (module docstring). ``screen.on_windows(configs,
    windows)``: the screen on those windows only (indices into each config's shaped windows)."""
    configs = list(configs)
    on_windows = getattr(screen, "on_windows", None)
    if on_windows is None or len(configs) < MIN_BATCH:
        return _verdicts(configs, screen(configs), bases, faster_than, bounds, res)
    probed = screen(configs[:PROBES])
    out = _verdicts(configs[:PROBES], probed, bases, faster_than, bounds, res)
    rest = configs[PROBES:]
    if all(f is None for f in out):     # both pass: where a batch passes whole, the first windows save nothing
        return out + _verdicts(rest, screen(rest), bases, faster_than, bounds, res)
    first = sorted(ranked_windows(configs[:PROBES], probed, bases, bounds, res)[:FIRST])
    early = [fails_anyway(p, bases, faster_than, bounds, res) for p in evaluated(
        rest, lambda cs: on_windows(cs, first), bounds, "")]
    todo = [c for c, f in zip(rest, early) if f is None]
    full = iter(_verdicts(todo, screen(todo), bases, faster_than, bounds, res) if todo else [])
    return out + [f if f is not None else next(full) for f in early]


def fails_anyway(p: Point, bases: dict[str, Point], faster_than: Point, bounds: Bounds, res) -> Failure | None:
    """Why ``p``, screened on some of the job's windows, fails on the whole job, or None: its
    failure (:func:`ringtune.agents.tune.stop.failure` on the exact model) over the figures that are
    the worst window's (the ripple's 90th percentiles left out)."""
    return failure(as_exact_variant(_worst_window_figures(p)), bases, faster_than, bounds, res)


def ranked_windows(configs: Sequence[TuneConfig], metrics: Sequence[Metrics], bases: dict[str, Point],
                   bounds: Bounds, res) -> list[int]:
    """Every window (index) of configurations screened on every window (``metrics``), those where
    more of them fail on that window alone first (:func:`nearness` above 1), then those where one
    comes nearest to failing."""
    score: dict[int, tuple[int, float]] = {}
    for cfg, m in zip(configs, metrics):
        for i, d in enumerate(m.details.get("windows", [])):
            near = nearness(_window_point(cfg, d, m.print_time_s, bounds), bases, bounds, res)
            n, top = score.get(i, (0, 0.0))
            score[i] = (n + (near > 1.0), max(top, near))
    return sorted(score, key=lambda i: (-score[i][0], -score[i][1], i))


def nearness(p: Point, bases: dict[str, Point], bounds: Bounds, res) -> float:
    """How near ``p`` is to failing on a worst-window figure: the largest ratio of one to where it
    would fail (a bound; a baseline's figure, over its printer variants or on the exact model, plus
    the resolution); above 1 exactly where :func:`fails_anyway` finds a bound or a measure,
    infinite where it loses steps."""
    if p.step_loss:
        return math.inf
    out = [float(p.metrics.get(k, 0.0)) / b for k, b in (("path_error_mm", bounds.max_path_error_mm),
                                                        ("motor_load", bounds.max_motor_load),
                                                        ("show_through_mm", bounds.max_show_through_mm)) if b > 0]
    for base in bases.values():
        exact = dict(base.variants).get((1.0, 1.0), {})
        for k in JUDGED_KEYS:
            mine = p.value(k)
            if mine is None or k.endswith(NOT_WORST):
                continue
            for theirs in (base.value(k), exact.get(k)):
                if theirs is not None:
                    out.append(mine / max(theirs + res.tolerance(k, mine, theirs), 1e-12))
    return max(out, default=0.0)


def _verdicts(configs, metrics, bases, faster_than, bounds, res) -> list[Failure | None]:
    """:func:`ringtune.agents.tune.stop.screen_failures` of configurations already screened (``metrics``)."""
    return screen_failures(configs, lambda _cs: metrics, bases, faster_than, bounds, res)


def _window_point(cfg: TuneConfig, window: dict, print_time_s: float, bounds: Bounds) -> Point:
    """The point of one window's measures (``Metrics.to_dict`` with details), as a job's."""
    fields = {k: v for k, v in window.items() if k in {f.name for f in dataclasses.fields(Metrics)}}
    m = Metrics(**{**fields, "print_time_s": print_time_s, "details": {}})
    return point_from_metrics(cfg, m, max_path_error_mm=bounds.max_path_error_mm,
                              max_motor_load=bounds.max_motor_load, max_show_through_mm=bounds.max_show_through_mm)


def _worst_window_figures(p: Point) -> Point:
    """``p`` without the figures that are not the worst window's (:data:`NOT_WORST`)."""
    return dataclasses.replace(p, metrics={k: v for k, v in p.metrics.items() if not k.endswith(NOT_WORST)},
                               variants=tuple((v, {k: x for k, x in figs.items() if not k.endswith(NOT_WORST)})
                                              for v, figs in p.variants))
