"""Judge a batch fastest first: of the candidates that pass the screen, only as many as it takes.

The walk where nobody looks (:mod:`ringtune.agents.tune.hidden_raise`) keeps the fastest candidate
of each batch that passes the judgement (the worst of the printer and its detuned twins). Every
candidate is screened on the exact model first, which gives its print time: the judged one's
(print time comes from the planner, the same on every variant). So the candidates the screen passes
are judged in order of that time, :data:`BATCH` at a time (the cores split a batch), and judging
stops at the first batch with one that passes and is accepted: a slower candidate cannot be kept.
Candidates exactly as fast as the last one judged are judged with it, so ties are broken on the
judged quality as before. What the caller reads of the rest (``needed``: the walk reports the
lowest failed value above the one it keeps) is still judged, in one more batch. The result is the
one judging every candidate gives; the twins of the slower candidates are not simulated.
"""

from __future__ import annotations

import os
from typing import Callable, Sequence

from ringtune.agents.tune.pareto import Point, Resolution
from ringtune.agents.tune.stop import Bounds, as_exact_variant, evaluated, failure
from ringtune.shaping.config import TuneConfig

#: candidates judged together (one per core: the judgement splits a batch over the cores)
BATCH = max(2, os.cpu_count() or 1)


def judged_fastest_first(configs: Sequence[TuneConfig], evaluate: Callable, screen: Callable | None,
                         bases: dict[str, Point],
                         faster_than: Point, bounds: Bounds, res: Resolution, label: str,
                         accept: Callable[[Point], object], needed: Callable[[int, int], bool] = lambda i, t: False,
                         batch: int = BATCH) -> tuple[int | None, list, list, int]:
    """(the index of the fastest candidate that passes and that ``accept(point)`` takes, or None;
    per candidate its judged point where it passed, else None; per candidate why it failed —
    (:class:`~ringtune.agents.tune.stop.Failure`, seen by the screen) — or None where it passed or
    was left unjudged; how many were judged). ``accept`` returns None to take a passing point, or
    why it is not taken (recorded as its failure, not seen by the screen); ``needed(i, t)``:
    candidate i is judged even when slower than candidate t, the one taken."""
    n = len(configs)
    points: list[Point | None] = [None] * n
    why: list = [None] * n
    if screen is None:       # no print time before the judgement: every candidate judged at once
        every = [(0.0, i) for i in range(n)]
        _judge(every, configs, evaluate, bases, faster_than, bounds, res, label, points, why)
        return _take(every, points, why, accept), points, why, n
    todo = _screened(configs, screen, bases, faster_than, bounds, res, why)
    judged, taken = 0, None
    while todo and taken is None:
        part = _next_part(todo, batch)
        todo = todo[len(part):]
        judged += _judge(part, configs, evaluate, bases, faster_than, bounds, res, label, points, why)
        taken = _take(part, points, why, accept)
    rest = [(t, i) for t, i in todo if taken is not None and needed(i, taken)]
    if rest:
        judged += _judge(rest, configs, evaluate, bases, faster_than, bounds, res, label, points, why)
    return taken, points, why, judged


def _screened(configs, screen, bases, faster_than, bounds, res, why: list) -> list[tuple[float, int]]:
    """(print time s, index) of the candidates that pass the screen, fastest first; ``why`` filled
    for those that fail it."""
    out = []
    for i, p in enumerate(evaluated(configs, screen, bounds, "")):
        f = failure(as_exact_variant(p), bases, faster_than, bounds, res)
        if f is None:
            out.append((p.print_time_s, i))
        else:
            why[i] = (f, True)
    return sorted(out)


def _next_part(todo: list[tuple[float, int]], batch: int) -> list[tuple[float, int]]:
    """The first ``batch`` of ``todo`` and every later one exactly as fast as the last of them."""
    k = min(batch, len(todo))
    while k < len(todo) and todo[k][0] == todo[k - 1][0]:
        k += 1
    return todo[:k]


def _judge(part, configs, evaluate, bases, faster_than, bounds, res, label, points: list, why: list) -> int:
    """Judge the candidates of ``part``; fill ``points`` (passed) or ``why`` (failed)."""
    idx = [i for _t, i in part]
    for i, p in zip(idx, evaluated([configs[i] for i in idx], evaluate, bounds, label)):
        f = failure(p, bases, faster_than, bounds, res)
        points[i], why[i] = (p, None) if f is None else (None, (f, False))
    return len(idx)


def _take(part, points: list, why: list, accept) -> int | None:
    """The fastest passing candidate of ``part`` (then the lowest quality figure) that ``accept``
    takes; those it refuses are recorded as failed."""
    for i in sorted((i for _t, i in part if points[i] is not None),
                    key=lambda i: (points[i].print_time_s, points[i].quality_mm)):
        off = accept(points[i])
        if off is None:
            return i
        points[i], why[i] = None, (off, False)
    return None
