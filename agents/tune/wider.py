"""The wider check of the walks after the study (the shaper ladder, the measured stop, the walk
where nobody looks): a step is taken only where no visible measure is worse than the baselines' on
printers further off the model than the judged twins.

``tune`` judges every configuration on the model and two twins (resonances ±5 %, damping ×0.75).
The measured stop (:mod:`ringtune.agents.tune.stop`) climbs until a measure reaches the resolution
on one of them, so it ends at that edge, and a short wall's ripple is the sum of the transients of
its two ends, whose phase a small change of acceleration moves: three printers sample few phases.
Found by ``benchmarks/bench_robustness.py`` on a Voron 0 described from its printer.cfg: the stop's
one step (3900 → 4100 mm/s², 0.2 % of the part's print time) left every measure the same on the
judged printers and rippled the outer wall 16.0 µm against Klipper's pick's 13.7 µm on the printer
with resonances 15 % lower and damping ×0.5. Each step that passes the judgement is simulated on
:data:`WIDER` as well, each printer on its own (as ``bench_robustness`` and ``simulate`` do: the
model's lead-in), against the baselines there.
"""

from __future__ import annotations

from typing import Callable, Sequence

from ringtune.agents.tune.pareto import DEFAULT_RESOLUTION, JUDGED_KEYS, Point, Resolution, judge, point_from_metrics
from ringtune.agents.tune.stop import Failure, worst_measure
from ringtune.envs.evaluate import evaluate_variants
from ringtune.envs.forked import Helpers
from ringtune.envs.variants import Variant
from ringtune.envs.windows import auto_settle
from ringtune.shaping.config import TuneConfig

#: the printers beyond the judged ones a step must also hold on: the model and the frequency ends
#: of ``bench_robustness``'s grid (×0.85, ×1.15), at half the damping, where ringing lasts longest
#: (two more, ×0.9 and ×1.1 as fitted, changed no choice on the built-in print or the part and cost
#: 40 % more)
WIDER = (Variant(0.85, 0.5), Variant(1.0, 0.5), Variant(1.15, 0.5))
_START = "\0start"


def wider_check(bases: dict[str, TuneConfig], evaluate_on: Callable[[Sequence[TuneConfig], Sequence[Variant]], list],
                start: TuneConfig | None = None, variants: Sequence[Variant] = WIDER,
                res: Resolution = DEFAULT_RESOLUTION) -> Callable[[TuneConfig], Failure | None]:
    """``check(config)``: the visible measure (:data:`~ringtune.agents.tune.pareto.JUDGED_KEYS`)
    worse than a baseline's (``bases``: configurations by key) on one of ``variants`` of the printer
    — where ``start`` (the configuration the walk climbs from) is already worse than that baseline
    there, only if worse than ``start``'s too: what the choice already was is not the step's to
    answer for — by the largest ratio, as a :class:`~ringtune.agents.tune.stop.Failure` naming that
    variant; None where none is. ``evaluate_on(configs, variants)``: per variant, the configs'
    metrics on that printer alone. The baselines and ``start`` are simulated once, with the first
    check."""
    refs = {**bases, **({} if start is None else {_START: start})}
    # per variant: the bases there, the (baseline, measure) pairs the start is already worse on, the start
    settled: dict[Variant, tuple[dict[str, Point], set, Point | None]] = {}

    def settle(v: Variant, points: list[Point]) -> None:
        there = dict(zip(refs, points))
        before = there.pop(_START, None)
        excuses = set() if before is None else {(name, k) for name, base in there.items()
                                                for k, verdict in judge(before, base, res, JUDGED_KEYS).verdicts.items()
                                                if verdict == "worse"}
        settled[v] = (there, excuses, before)

    def check(config: TuneConfig) -> Failure | None:
        configs = [config] if settled else [config, *refs.values()]
        found = []
        for v, metrics in zip(variants, evaluate_on(configs, variants)):
            mine, *theirs = [point_from_metrics(c, m) for c, m in zip(configs, metrics)]
            if theirs:
                settle(v, theirs)
            there, excuses, before = settled[v]
            why = worst_measure(mine, there, res, variant=(v.freq, v.damping),
                                excused=lambda name, k: (name, k) in excuses and not _worse_than(mine, before, k, res))
            if why is not None:
                found.append(why)
        return max(found, key=lambda f: (f.value / max(f.limit, 1e-12), f.key, f.baseline)) if found else None

    return check


def _worse_than(mine: Point, before: Point, key: str, res: Resolution) -> bool:
    """Whether ``mine``'s figure ``key`` is worse than ``before``'s (True where ``before`` lacks it)."""
    f = judge(mine, before, res, (key,)).figures.get(key)
    return f is None or f.verdict == "worse"


def study_evaluate_on(job, kwargs: dict, printer, helpers: Helpers | None = None
                      ) -> Callable[[Sequence[TuneConfig], Sequence[Variant]], list]:
    """``evaluate_on(configs, variants)`` as the study's default evaluator judges (its backend and
    job-acceleration mode), each variant of ``printer`` alone with the model's lead-in, the variants
    split over the cores (``helpers``, else a fork per call), each part in one batch
    (:func:`ringtune.envs.evaluate.evaluate_variants`: the same figures as one call each).
    What it simulated once (the baselines, a walk's start) it remembers, so the walks that share it
    do not simulate it again."""
    settle = auto_settle(printer)
    known: dict[tuple[str, Variant], object] = {}

    def on_variants(part, todo):
        return [[e.metrics for e in evs] for evs in evaluate_variants(
            todo, [v.of(printer) for v in part], job, kwargs.get("backend", "mujoco"), settle=settle,
            job_accel=kwargs.get("job_accel"))]

    if helpers is not None:
        helpers.register(on_variants)
    else:
        helpers = Helpers()             # nothing registered: a fork per call

    def evaluate_on(configs, variants):
        todo = list({c.key(): c for c in configs if any((c.key(), v) not in known for v in variants)}.values())
        if todo:
            # the variants split over the cores (each variant's figures are what it gets alone)
            runs = helpers.map(on_variants, list(variants), todo)
            for v, metrics in zip(variants, runs):
                known.update(((c.key(), v), m) for c, m in zip(todo, metrics))
        return [[known[(c.key(), v)] for c in configs] for v in variants]

    return evaluate_on


def held_wider(points: Sequence[Point], first: Point, check: Callable[[TuneConfig], Failure | None] | None
               ) -> tuple[Point, Failure | None]:
    """(the point the walks start from, why the study's choice ``points[0]`` was set aside or None):
    the first of ``points`` (the study's choice, then its runners-up, fastest first) that holds on
    the wider printers (``check``), else the first reference baseline ``first`` itself — the study
    judged its points on the model and its twins alone, and a faster shaping that only rides their
    resolution ripples more a little further off. The baseline's own shaping is not asked."""
    if check is None or not points:
        return (points[0] if points else first), None
    off = None
    for p in points:
        if p is first or p.config == first.config:
            return p, off
        why = check(p.config)
        if why is None:
            return p, off
        off = off or why
    return first, off
