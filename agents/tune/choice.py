"""The choice of one point of a study: the default "same quality, faster" against the reference
baselines, the knee of the front, or a weight of seconds per mm (``--pick``, ``--weight``), each with
a sentence saying what was chosen and why."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ringtune.agents.tune.pareto import (DEFAULT_RESOLUTION, QUALITY_WORDS, Point, Resolution, broken_bounds, judge,
                                         no_worse, quality_keys)
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError


#: mm: quality differences smaller than this are not worth print time when choosing the knee
KNEE_QUALITY_SCALE = 0.01
#: print times closer than this (relative) are one plan: configurations that differ only in what
#: the planner does not see (the shapers), e.g. every trial of a job whose own accelerations rule
SAME_PLAN_REL = 1e-9
PICKS = ("fastest-at-baseline-quality", "knee", "weight")


@dataclass
class Choice:
    """The chosen point, how (``by``: one of :data:`PICKS`), against which baseline (key or None:
    the one it is at least as fast as), every baseline it is held to (``held_to``: no visible
    measure worse than any of them) and a sentence saying so."""

    point: Point
    by: str
    baseline: str | None
    sentence: str
    held_to: tuple = ()


def _broken_counts(points: Sequence[Point]) -> str:
    """`` (of the N trials: k with …, …)``: how many of ``points`` broke each bound; "" for none."""
    n = Counter(w for p in points for w in broken_bounds(p) if w in _BROKEN_WORDS)
    if not n:
        return ""
    return (f" (of the {len(points)} trials: " + ", ".join(f"{k} with {_BROKEN_WORDS[w]}" for w, k in n.most_common())
            + "; a trial may break several)")


#: each bound a point may break (:func:`broken_bounds`' words) as the error names it, with its option
_BROKEN_WORDS = {"loses steps": "lost steps", "path error over the bound": "a path error over --max-path-error",
                 "motor load over the reserve": "a motor load over what --motor-reserve leaves",
                 "show-through over the bound": "hidden features reaching the outer wall by more than "
                                                "--max-show-through"}


class NoFeasible(RingtuneError):
    """Nothing the choice may take is feasible."""


def _no_front(points: Sequence[Point] = (), baselines_too: bool = True) -> RingtuneError:
    """The error when nothing is feasible, counting what ``points`` (every trial, when known) broke;
    ``baselines_too``: the baselines were candidates as well (the default choice)."""
    who = "every trial and every baseline" if baselines_too else "every trial"
    return NoFeasible(f"no feasible configuration was found: {who} lost steps or broke a bound"
                      f"{_broken_counts(points)}; raise the bound that rules most out, lower the acceleration range "
                      "(--accel-range) or run more trials", "tune")


def knee(front: Sequence[Point], trials: Sequence[Point] = (), baselines_too: bool = False) -> Point:
    """The front point closest to the ideal corner after scaling print time by the front's range
    and quality by its range but at least :data:`KNEE_QUALITY_SCALE` (10 µm; so that a front whose
    points all lie within a few micrometres is not bought with seconds). Where there is none, the
    error counts what ``trials`` broke (``baselines_too``: the baselines were candidates and failed too)."""
    if not front:
        raise _no_front(trials, baselines_too)
    t = np.array([p.print_time_s for p in front])
    q = np.array([p.quality_mm for p in front])
    tn = (t - t.min()) / max(t.max() - t.min(), 1e-12)
    qn = (q - q.min()) / max(q.max() - q.min(), KNEE_QUALITY_SCALE)
    return front[int(np.argmin(np.hypot(tn, qn)))]


def choose(front: Sequence[Point], weight: float | None = None, trials: Sequence[Point] = ()) -> Point:
    """The point minimising ``print_time_s + weight·quality_mm`` (weight in s/mm), or else the knee;
    where there is none, the error counts what ``trials`` broke."""
    if not front:
        raise _no_front(trials, False)
    if weight is not None:
        return min(front, key=lambda p: p.print_time_s + weight * p.quality_mm)
    return knee(front)


def _no_worse_seen(p: Point, base: Point, res: Resolution) -> bool:
    """:func:`no_worse` on the visible measures both have (:func:`ringtune.agents.tune.pareto.quality_keys`)."""
    return no_worse(p, base, res, quality_keys([p, base]))


def at_baseline_quality(front: Sequence[Point], base: Point, res: Resolution = DEFAULT_RESOLUTION) -> list[Point]:
    """Feasible points at least as fast as ``base`` with no visible measure (:data:`VISIBLE_KEYS`)
    worse than its at the resolution ("same" counts as no worse)."""
    keys = quality_keys([base, *front])
    return [p for p in front if p.feasible and p.print_time_s <= base.print_time_s and no_worse(p, base, res, keys)]


def reference_baselines(baselines: dict[str, Point], res: Resolution = DEFAULT_RESOLUTION) -> list[tuple[str, Point]]:
    """The baselines the default choice is held to, best first: the feasible shaped ones (no
    shaping only when there is no other). What the printer runs now comes first where it is known
    and no visible measure of it is worse than Klipper's pick; otherwise Klipper's pick does (the
    choice is then never worse than either where it matches the first)."""
    usable = {k: b for k, b in baselines.items() if b.feasible}
    shaped = {k: b for k, b in usable.items() if k != "none"} or usable
    rank = {"current": 0, "klipper": 1}
    if "current" in shaped and "klipper" in shaped and not _no_worse_seen(shaped["current"], shaped["klipper"], res):
        rank = {"klipper": 0, "current": 1}
    return sorted(shaped.items(), key=lambda kb: rank.get(kb[0], 2))


def pick(front: Sequence[Point], baselines: dict[str, Point], how: str = "fastest-at-baseline-quality",
         weight: float | None = None, res: Resolution = DEFAULT_RESOLUTION,
         candidates: Sequence[Point] | None = None, why_none: str = "") -> Choice:
    """Choose the configuration to use.

    ``fastest-at-baseline-quality`` (default): against the first reference baseline
    (:func:`reference_baselines`) the search can match, the fastest of ``candidates`` (default:
    the front) at least as fast with no visible measure worse at the resolution ("same quality,
    faster"). Pass every point of the study as ``candidates``: the front is over print time and a
    few figures, and a point no worse on every judged one can lie behind a front point that is
    worse on another. The reference baselines are candidates too (the study may not have tried them:
    its acceleration range can start above theirs), so where the study tried nothing as fast at their
    quality the choice is the first baseline itself; the knee of the front only where there is no
    usable baseline, and the sentence says so. ``knee``: :func:`knee`. ``weight``: minimises print
    time + ``weight`` × quality (s/mm). ``why_none``: a likely cause added to the error where
    nothing is feasible."""
    rule = _RULES.get(how)
    if rule is None:
        raise RingtuneError(f"must be one of {', '.join(PICKS)}, not {how!r}", "--pick")
    try:
        return rule([p for p in front if p.feasible], baselines, weight, res, candidates)
    except NoFeasible as exc:
        raise NoFeasible(f"{exc.bare}; {why_none}" if why_none else exc.bare, exc.where) from None


def _by_weight(front, _baselines, weight, _res, candidates) -> Choice:
    if weight is None:
        raise RingtuneError("--pick weight needs --weight W (seconds per mm)", "--pick")
    return Choice(choose(front, weight, candidates or ()), "weight", None, f"minimises print time + {weight:g} s/mm × ripple")


def _by_knee(front, _baselines, _weight, _res, candidates) -> Choice:
    return Choice(knee(front, candidates or ()), "knee", None, "the knee of the front (closest to the ideal corner, time "
                  "scaled by the front's range, ripple by its range but at least 10 µm)")


def _by_baselines(front, baselines, _weight, res, candidates) -> Choice:
    pool = front if candidates is None else [p for p in candidates if p.feasible] or front
    return _fastest_at_baseline_quality(front, baselines, res, pool, candidates or ())


#: each rule of :func:`pick` by its name (:data:`PICKS`)
_RULES = {"fastest-at-baseline-quality": _by_baselines, "knee": _by_knee, "weight": _by_weight}


def _fastest_at_baseline_quality(front: list[Point], baselines: dict[str, Point], res: Resolution,
                                 pool: list[Point], trials: Sequence[Point] = ()) -> Choice:
    """:func:`pick`'s default: the fastest point of ``pool`` and the reference baselines with no
    visible measure worse than the reference baselines, tried together then one at a time; without
    any usable baseline, the knee of ``front``, saying why."""
    by_key = dict(reference_baselines(baselines, res))
    worse = f"no worse {QUALITY_WORDS[quality_keys(front or list(by_key.values()))]}"
    # the baselines are configurations too: where the study tried nothing as fast at their quality
    # (e.g. its acceleration range starts above theirs), the choice starts from the baseline itself,
    # never from a knee that is worse on what a person sees
    pool = [*pool, *(b for b in by_key.values() if all(b is not p for p in pool))]
    tries = _tries(list(by_key))
    for held in tries:
        first, *rest = (by_key[k] for k in held)
        cands = _held_to_all(pool, first, rest, res)
        if cands:
            p = fastest(cands, res)
            own = next((k for k, b in by_key.items() if b is p), None)
            why = _held_why(p, first, held, tries, worse, res) if own is None else _baseline_why(
                p, own, held, tries, worse)
            return Choice(p, "fastest-at-baseline-quality", held[0], why, held)
    why = f"no configuration the study tried is as fast as {_named(by_key, ' or ')} with {worse}" if by_key else \
        "there is no usable baseline to match"
    return Choice(knee(front, trials, baselines_too=True), "knee", None, f"the knee of the front, because {why}")


def runners_up(choice: Choice, pool: Sequence[Point], baselines: dict[str, Point], res: Resolution = DEFAULT_RESOLUTION,
               n: int = 4) -> list[Point]:
    """Up to ``n`` points of ``pool`` the default rule would take after ``choice.point``, fastest
    first: feasible, at least as fast as the first baseline ``choice`` is held to and no visible
    measure worse than any of them; faster than that baseline only (it is the fallback itself).
    Empty for another rule."""
    if choice.by != "fastest-at-baseline-quality" or not choice.held_to:
        return []
    first, *rest = (baselines[k] for k in choice.held_to)
    cands = [p for p in _held_to_all(pool, first, rest, res)
             if p is not choice.point and p.print_time_s < first.print_time_s]
    return sorted(cands, key=lambda p: (p.print_time_s, p.quality_mm))[:n]


def _held_to_all(pool: Sequence[Point], first: Point, rest: Sequence[Point], res: Resolution) -> list[Point]:
    """The feasible points of ``pool`` at least as fast as ``first`` with no visible measure worse
    than ``first``'s or any of ``rest``'s."""
    return [p for p in at_baseline_quality(pool, first, res) if all(_no_worse_seen(p, b, res) for b in rest)]


def fastest(cands: Sequence[Point], res: Resolution = DEFAULT_RESOLUTION) -> Point:
    """The fastest of ``cands``; of those equally fast (one plan, :data:`SAME_PLAN_REL`), one that no
    other beats — better on a visible measure at the resolution and worse on none —, then the lowest
    on the study's quality objective. Why: where the planner gives every shaping one time (a job
    whose own accelerations rule), the fastest is a tie, and the quality objective alone (ripple)
    can prefer, by a margin under the resolution, a shaping that corners or extrudes worse."""
    t = min(p.print_time_s for p in cands)
    tied = [p for p in cands if p.print_time_s <= t + SAME_PLAN_REL * abs(t)]
    keys = quality_keys(tied)
    unbeaten = [p for p in tied if not any(q is not p and judge(q, p, res, keys).dominates for q in tied)]
    return min(unbeaten or tied, key=lambda p: p.quality_mm)


def _same_shaping(a: TuneConfig, b: TuneConfig) -> bool:
    """Whether two configurations shape and limit alike: shapers, frequencies, dampings, the
    frequency limit and the acceleration (their per-feature settings aside)."""
    def shaping(c: TuneConfig) -> tuple:
        limit = (c.freq_limit_hz, c.freq_limit_method, c.min_speed_factor) if c.freq_limit_hz > 0 else 0.0
        return (c.firmware, c.shaper_x, c.shaper_y, c.freq_x, c.freq_y, c.damping_x, c.damping_y, limit, c.accel)
    return shaping(a) == shaping(b)


def _tries(keys: list[str]) -> list[tuple]:
    """The sets of reference baselines (by key, best first) the default choice is held to, in turn:
    every one at once (no chaining: "same as the printer's, which is the same as Klipper's" must not
    end worse than Klipper's), then Klipper's pick alone (or, without it, each other one alone)."""
    together = [tuple(keys)] if len(keys) > 1 else []
    return together + ([("klipper",)] if "klipper" in keys else [(k,) for k in keys])


def _named(keys, joiner: str) -> str:
    """The baselines ``keys`` by their short names, joined."""
    return joiner.join(BASELINE_NAMES.get(k, k) for k in keys)


def _held_why(p: Point, b: Point, held: tuple, tries: list[tuple], worse: str,
              res: Resolution = DEFAULT_RESOLUTION) -> str:
    """Why ``p`` was chosen, held to the baselines ``held`` (``b``: the first's point), saying when
    an earlier try (``tries[0]``) found nothing."""
    lead = "" if held == tries[0] else \
        f"no configuration the study tried is as fast as {_named(tries[0], ' and ')} with {worse} than each; "
    name = _named(held, " and ")
    first = BASELINE_NAMES.get(held[0], held[0])
    if p.print_time_s < b.print_time_s:
        v = judge(p, b, res).verdicts
        if v.get("print_time_s") == "same":       # faster by less than the resolution
            better = sum(x == "better" for k, x in v.items() if k not in ("print_time_s", "feasible"))
            gain = f"better on {better} of its visible measures" if better else "the same quality"
            return (f"{lead}the fastest configuration the study tried with {worse} than {name} "
                    f"(as fast as {first} at the resolution, {gain})")
        return (f"{lead}the fastest configuration the study tried with {worse} than {name} "
                f"(same quality, faster than {first})")
    if not _same_shaping(p.config, b.config):
        return (f"{lead}no configuration the study tried is faster than {first} with {worse} than {name}; of those "
                "as fast, one no other beats on a visible measure, then the best on the study's quality objective "
                "(--quality)")
    return (f"{lead}no configuration the study tried is faster than {first} with {worse} than {name}: the search found "
            f"nothing better than {first} itself at that quality (more --trials may)")


def _baseline_why(p: Point, key: str, held: tuple, tries: list[tuple], worse: str) -> str:
    """Why the baseline ``key`` itself (its point ``p``) was chosen: the study tried nothing as fast
    with ``worse`` than the baselines ``held``."""
    lead = "" if held == tries[0] else \
        f"no configuration the study tried is as fast as {_named(tries[0], ' and ')} with {worse} than each; "
    at = f", at {p.config.accel:.0f} mm/s²" if p.config.accel else ""
    return (f"{lead}no configuration the study tried is as fast as {_named(held, ' and ')} with {worse}: "
            f"{BASELINE_NAMES.get(key, key)} itself{at} (more --trials, or an --accel-range reaching down to it, "
            "may find a faster one)")


#: short names of the baselines in sentences
BASELINE_NAMES = {"klipper": "Klipper's rule", "current": "what the printer runs now", "none": "no shaping"}
