"""What stops the chosen acceleration, measured: step it up with the same judgement until it fails.

From the choice, the acceleration is raised in steps of :data:`STEP_REL` (5 %, at least one
``accel_step`` of the search space; a per-feature configuration's group accelerations in the same
ratio, each up to its own motor bound), each step judged exactly as every trial (the study's
evaluator, frequency margin and bounds) and held to the same baselines as the choice (no visible
measure worse than any of them at the resolution, every bound kept, print time lower than the step
below's by at least :data:`MIN_STEP_SAVING`: a raise that buys nothing is not worth the quality and
motor load it spends). Steps are
evaluated :data:`LADDER` at a time in one ``evaluate_many`` call. Where a step fails, each shaper
frequency is tried :data:`FREQ_REL` (2 %) up and down at that acceleration, and that step and the
current choice without their frequency limit, where they have one (one batch); a variant that
passes becomes the new start. A step that passes becomes the choice ("a faster point with no
worse measure"), where it also holds on printers further off the model than the judged twins
(``wider``: :mod:`ringtune.agents.tune.wider`). The walk ends at the first step that fails with
every frequency variant, and what
failed there is reported with both values — the measure that got worse than the baseline's (the
largest relative excess), or the bound that binds (step loss, the motor reserve, the show-through
or path-error bound) —, or at the top of the range (the motors' force, or the firmware's largest
acceleration), or where print time stops falling by :data:`MIN_STEP_SAVING` (the job's speeds bound
it, not acceleration).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from itertools import accumulate
from typing import Any, Callable, NamedTuple, Sequence

from ringtune.agents.tune.pareto import (DEFAULT_RESOLUTION, JUDGED_KEYS, Point, Resolution, judge,
                                         point_from_metrics, shown, words)
from ringtune.agents.tune.space import SearchSpace, config_from_params, params_from_config
from ringtune.envs.variants import Variant
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.firmware import FIRMWARES

#: fraction by which each step raises the acceleration (at least one ``accel_step``)
STEP_REL = 0.05
#: fraction by which each shaper frequency is moved up and down where a step fails
FREQ_REL = 0.02
#: steps evaluated per batch
LADDER = 4
#: most configurations evaluated by one walk
MAX_EVALUATIONS = 80
#: the least share of the print time a raise after the study must save (the measured stop's steps,
#: the shaper ladder's rungs, the walk where nobody looks): a tenth of the 0.5 % that counts as
#: faster. A raise that buys less spends motor load and quality headroom for nothing
MIN_STEP_SAVING = 0.0005


@dataclass
class Bounds:
    """The study's bounds: path error (mm), motor load (fraction), show-through (mm); 0 = none."""

    max_path_error_mm: float = 0.0
    max_motor_load: float = 0.0
    max_show_through_mm: float = 0.0


@dataclass
class Stop:
    """The walk's end: the (possibly new) choice, what stops it there (``kind``: ``measure``,
    ``bound``, ``ceiling``, ``time`` or ``not searched``; ``key``: the measure or bound; its
    ``value`` at the stopping step against ``base_value``, the baseline's or the bound), the stopping
    step's configuration and acceleration (mm/s²), the evaluations spent, and a sentence."""

    point: Point
    start: Point
    kind: str
    key: str | None = None
    baseline: str | None = None
    value: float | None = None
    base_value: float | None = None
    accel: float | None = None
    config: TuneConfig | None = None
    evaluations: int = 0
    sentence: str = ""
    variant: tuple[float, float] | None = None    # where the measure is worse on one printer variant
    declined: Point | None = None    # where the ladder and the stop ended, not taken (:func:`declined_if_same_time`)

    @property
    def moved(self) -> bool:
        return self.point is not self.start

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "key": self.key, "baseline": self.baseline, "value": self.value,
                "baseline_value": self.base_value,
                "accel": self.accel, "config": self.config.to_dict() if self.config else None,
                "moved": self.moved, "from_accel": self.start.config.accel, "to_accel": self.point.config.accel,
                "evaluations": self.evaluations, "sentence": self.sentence,
                "variant": None if self.variant is None else list(self.variant),
                "declined_accel": None if self.declined is None else self.declined.config.accel,
                "declined_print_time_s": None if self.declined is None else self.declined.print_time_s}


def to_beat(p: Point) -> Point:
    """``p`` with the print time a raise from it must get below: :data:`MIN_STEP_SAVING` less (s)."""
    return dataclasses.replace(p, print_time_s=p.print_time_s * (1.0 - MIN_STEP_SAVING))


def next_accels(accel: float, top: float, step: float, n: int = LADDER) -> list[float]:
    """Up to ``n`` accelerations above ``accel`` (mm/s²), each :data:`STEP_REL` above the last
    (rounded to ``step``, at least one ``step`` higher), none above ``top``."""
    out, a = [], float(accel)
    for _ in range(n):
        nxt = max(round(a * (1 + STEP_REL) / step) * step, a + step)
        if nxt > top + 1e-9:
            break
        out.append(float(nxt))
        a = nxt
    return out


def with_accel(cfg: TuneConfig, accel: float, space: SearchSpace) -> TuneConfig:
    """``cfg`` at ``accel`` mm/s², with the per-axis caps a trial at that acceleration carries; a
    per-feature space's group accelerations raised in the same ratio (each within its range)."""
    params = params_from_config(cfg, space)
    ratio = accel / float(cfg.accel) if cfg.accel else 1.0
    params["accel"] = accel
    for group, lo, hi in space.feature_accel:
        key = f"accel_{group}"
        if key in params:
            params[key] = min(max(params[key] * ratio, lo), hi)
    return config_from_params(params, space) if not space.accel_fixed else dataclasses.replace(cfg, accel=accel)


def freq_variants(cfg: TuneConfig, space: SearchSpace) -> list[TuneConfig]:
    """``cfg`` with each shaped axis's frequency :data:`FREQ_REL` up and down (one frequency for
    all axes where the firmware has one shaper), inside the space's ranges."""
    params = params_from_config(cfg, space)
    ranges = {"freq_x": space.freq_x, "freq_y": space.freq_y} if space.per_axis else {"freq": space.freq_x}
    out = []
    for k, (lo, hi) in ranges.items():
        if k not in params:
            continue
        for sign in (-1, 1):
            f = params[k] * (1 + sign * FREQ_REL)
            if lo <= f <= hi:
                out.append(config_from_params({**params, k: f}, space))
    return out


def without_limit(cfg: TuneConfig) -> list[TuneConfig]:
    """``cfg`` without its frequency limit, where it has one ([] otherwise): a limit the study's
    match carried may only slow zigzags once the acceleration is higher."""
    return [dataclasses.replace(cfg, freq_limit_hz=0.0, extra={})] if cfg.freq_limit_hz > 0 else []


def evaluated(configs: Sequence[TuneConfig], evaluate: Callable[[Sequence[TuneConfig]], list], bounds: Bounds,
              label: str) -> list[Point]:
    """``configs`` judged as every trial: their metrics from ``evaluate``, as points marked against
    the study's ``bounds``."""
    return [point_from_metrics(c, m, label=label, max_path_error_mm=bounds.max_path_error_mm,
                               max_motor_load=bounds.max_motor_load, max_show_through_mm=bounds.max_show_through_mm)
            for c, m in zip(configs, evaluate(configs))]


def passing(configs: Sequence[TuneConfig], evaluate: Callable[[Sequence[TuneConfig]], list],
            screen: Callable[[Sequence[TuneConfig]], list] | None, bases: dict[str, Point], faster_than: Point,
            bounds: Bounds, res: Resolution, label: str, max_judged: int | None = None,
            verdicts: Callable[..., list] | None = None) -> tuple[list[Point | None], int, int]:
    """(per config, its judged point where it passes against ``bases`` and ``faster_than``
    (:func:`failure`), else None; how many were judged; how many screened). ``max_judged``: judge
    at most that many, the first in ``configs``' order (the rest count as not passing).

    ``screen``: the same evaluation on the exact model alone, where ``evaluate`` takes the worst of
    the printer and its detuned twins. What fails on the exact model fails the judgement too (the
    worst case is no better on any measure, the exact model is one of the variants judged
    (:func:`as_exact_variant`), and print time is the same), so only what passes the screen is
    judged: a third of the cost for what fails. ``verdicts``: how the screen's verdicts are found
    (:func:`screen_failures`' signature and result; default that: every config on every window)."""
    out, _why, judged, screened = passing_why(configs, evaluate, screen, bases, faster_than, bounds, res, label,
                                              max_judged, verdicts)
    return out, judged, screened


def screen_failures(configs: Sequence[TuneConfig], screen: Callable[[Sequence[TuneConfig]], list],
                    bases: dict[str, Point], faster_than: Point, bounds: Bounds, res: Resolution
                    ) -> list[Failure | None]:
    """Per config, why it fails on the exact model (``screen``), or None."""
    return [failure(as_exact_variant(p), bases, faster_than, bounds, res)
            for p in evaluated(configs, screen, bounds, "")]


def as_exact_variant(p: Point) -> Point:
    """A point judged on the exact model alone (the screen) as that variant of the judgement
    (frequency and damping factors 1): compared with a baseline's own figures on the exact model as
    well as with its worst, either of which the judgement of the worst case fails too."""
    figs = {k: float(p.metrics[k]) for k in JUDGED_KEYS if k in p.metrics}
    return dataclasses.replace(p, variants=(((1.0, 1.0), figs),))


def passing_why(configs: Sequence[TuneConfig], evaluate: Callable[[Sequence[TuneConfig]], list],
                screen: Callable[[Sequence[TuneConfig]], list] | None, bases: dict[str, Point], faster_than: Point,
                bounds: Bounds, res: Resolution, label: str, max_judged: int | None = None,
                verdicts: Callable[..., list] | None = None
                ) -> tuple[list[Point | None], list[tuple | None], int, int]:
    """:func:`passing`, with why each config failed: per config (:func:`failure`'s tuple, and
    whether it was seen on the exact model alone, by the screen), or None where it passed or was
    left unjudged by ``max_judged``."""
    keep = [True] * len(configs)
    why: list[tuple | None] = [None] * len(configs)
    if screen is not None and configs:
        fails = (verdicts or screen_failures)(list(configs), screen, bases, faster_than, bounds, res)
        keep = [f is None for f in fails]
        why = [None if f is None else (f, True) for f in fails]
    if max_judged is not None:          # the first max_judged of those kept, in order
        keep = [k and n <= max_judged for k, n in zip(keep, accumulate(keep))]
    todo = [c for c, k in zip(configs, keep) if k]
    judged = iter(evaluated(todo, evaluate, bounds, label) if todo else [])
    out: list[Point | None] = [next(judged) if k else None for k in keep]
    for i, p in enumerate(out):
        f = None if p is None else failure(p, bases, faster_than, bounds, res)
        if f is not None:
            out[i], why[i] = None, (f, False)
    return out, why, len(todo), len(configs) if screen is not None else 0


class Failure(NamedTuple):
    """Why a point may not replace another (:func:`failure`): ``kind`` (``bound``, ``measure``,
    ``time``, ``ceiling``, ``budget``), the bound's or measure's ``key``, the baseline's key (a
    measure), the point's ``value`` against ``limit`` (the bound, the baseline's figure, the time
    to beat), and ``variant``: the printer variant (frequency, damping factors) those figures are of
    where the measure is worse there and not over the worst of the variants (None otherwise)."""

    kind: str
    key: str | None
    baseline: str | None
    value: float | None
    limit: float | None
    variant: tuple[float, float] | None = None


def worst_measure(p: Point, bases: dict[str, Point], res: Resolution,
                  excused: Callable[[str, str], bool] = lambda name, key: False,
                  variant: tuple[float, float] | None = None) -> Failure | None:
    """The visible measure (:data:`~ringtune.agents.tune.pareto.JUDGED_KEYS`) of ``p`` worse than a
    baseline's by the largest ratio (over the printer variants, or on one of them:
    :func:`ringtune.agents.tune.pareto.compare_figure`), as a ``measure`` :class:`Failure`; None
    where none is. ``excused(baseline, key)``: a figure not held against that baseline;
    ``variant``: the printer variant ``p`` and ``bases`` were simulated on, where it is one."""
    worse = [(f.mine / max(f.theirs, 1e-12), k, name, f) for name, base in bases.items()
             for k, f in judge(p, base, res, JUDGED_KEYS).figures.items()
             if f.verdict == "worse" and not excused(name, k)]
    if not worse:
        return None
    _ratio, k, name, f = max(worse, key=lambda w: w[:3])
    return Failure("measure", k, name, float(f.mine), float(f.theirs), variant or f.variant)


def failure(p: Point, bases: dict[str, Point], faster_than: Point, bounds: Bounds,
            res: Resolution) -> Failure | None:
    """Why ``p`` may not replace ``faster_than``, or None. A bound first; else the visible measure
    worse than a baseline's by the largest ratio (over the printer variants, or on one of them:
    :func:`ringtune.agents.tune.pareto.compare_figure`)."""
    m = p.metrics
    broken = (("step_loss", p.step_loss, 1.0, 0.0),
              ("motor_load", p.overloaded, m.get("motor_load", 0.0), bounds.max_motor_load),
              ("show_through_mm", p.shows_through, m.get("show_through_mm", 0.0), bounds.max_show_through_mm),
              ("path_error_mm", p.too_rough, m.get("path_error_mm", 0.0), bounds.max_path_error_mm))
    for key, flag, value, limit in broken:
        if flag:
            return Failure("bound", key, None, float(value), float(limit))
    worse = worst_measure(p, bases, res)
    if worse:
        return worse
    if p.print_time_s >= faster_than.print_time_s:
        return Failure("time", "print_time_s", None, p.print_time_s, faster_than.print_time_s)
    return None


def measured_stop(start: Point, bases: dict[str, Point], evaluate: Callable[[Sequence[TuneConfig]], list],
                  space: SearchSpace, bounds: Bounds, *, labels: dict[str, str] | None = None,
                  res: Resolution = DEFAULT_RESOLUTION, max_evaluations: int = MAX_EVALUATIONS,
                  wider: Callable[[TuneConfig], Failure | None] | None = None) -> Stop:
    """Walk the acceleration up from ``start`` (module docstring); ``evaluate(configs) -> metrics``
    judges as the study does; ``bases``: the baselines the choice was held to, by key (``labels``
    names them in the sentence); ``wider(config)``: why a step that passes the judgement fails on
    printers further off the model (:mod:`ringtune.agents.tune.wider`), or None."""
    labels = labels or {}
    wider = wider or (lambda cfg: None)

    def fails(p: Point, than: Point) -> Failure | None:
        return failure(p, bases, to_beat(than), bounds, res) or wider(p.config)

    if space.accel_fixed or start.config.accel is None:
        return Stop(start, start, "not searched", sentence="The acceleration is not searched, so nothing is stepped.")
    fw_top = float(FIRMWARES[space.firmware].accel.hi)
    top = min(space.accel[1], fw_top)
    cur, n = start, 0

    def points(cfgs):
        nonlocal n
        n += len(cfgs)
        return evaluated(cfgs, evaluate, bounds, "stop step")

    while n < max_evaluations:
        accs = next_accels(cur.config.accel, top, space.accel_step)
        if not accs:
            why = (space.accel_basis or "the search range's top") if top < fw_top else \
                f"{FIRMWARES[space.firmware].title}'s largest acceleration"
            return _stop(start, cur, Failure("ceiling", "accel", None, float(cur.config.accel), top), None, n, labels,
                         why)
        failed = None
        for p in points([with_accel(cur.config, a, space) for a in accs]):
            why = fails(p, cur)
            if why:
                failed = (p, why)
                break
            cur = p
        if failed is None:
            continue
        p, why = failed
        tried = freq_variants(p.config, space) + without_limit(p.config) + without_limit(cur.config)
        variants = [v for v in points(tried) if fails(v, cur) is None]
        if variants:
            cur = min(variants, key=lambda v: (v.print_time_s, v.quality_mm))
            continue
        return _stop(start, cur, why, p.config, n, labels)
    return _stop(start, cur, Failure("budget", None, None, None, None), None, n, labels)


def _stop(start: Point, cur: Point, why: Failure, cfg, n: int, labels: dict, basis: str = "") -> Stop:
    acc = None if cfg is None else float(cfg.accel)
    label = labels.get(why.baseline, why.baseline or "")
    return Stop(cur, start, why.kind, why.key, why.baseline, why.value, why.limit, acc, cfg, n,
                _sentence(why, acc, cur, label, basis), why.variant)


def _sentence(why: Failure, acc, cur: Point, base_label: str, basis: str) -> str:
    kind, value, limit = why.kind, why.value, why.limit
    here = f"{cur.config.accel:.0f} mm/s²"
    if kind in ("measure", "bound"):
        what = failure_words(why, base_label)
        return f"What stops it at {here}: {what} at {acc:.0f} mm/s² (the next step, measured)."
    if kind == "time":
        return (f"What stops it at {here}: print time falls by less than {MIN_STEP_SAVING * 100:g} % at {acc:.0f} "
                f"mm/s² ({value:.3f} s against {cur.print_time_s:.3f} s): the job's speeds, not its acceleration, "
                f"bound it.")
    if kind == "ceiling":
        return f"What stops it at {here}: the top of the acceleration range, {limit:.0f} mm/s² ({basis})."
    return f"The measured stop ended at {here} after its budget of evaluations, every step passing."


def failure_words(why: Failure, base_label: str) -> str:
    """What failed, with both values: ``"outer wall ripple 31.0 µm > 29.8 µm of Klipper's rule"``
    (``"… on the printer with its resonances 5 % higher and damping ×0.75"`` where it is worse on
    that variant), ``"motor load 84 % > the reserve's 80 %"``, ``"print time 5.702 s, not the 0.05 %
    faster a step must be (below 5.700 s)"`` (the time to beat is :func:`to_beat`'s; ``base_label``
    names the baseline)."""
    kind, key, value, limit = why.kind, why.key, why.value, why.limit
    if kind == "measure":
        on = "" if why.variant is None else f" on {Variant(*why.variant).words()}"
        return f"{words(key)[0]} {shown(key, value)} > {shown(key, limit)} of {base_label}{on}"
    if kind == "time":
        return (f"print time {value:.3f} s, not the {MIN_STEP_SAVING * 100:g} % faster a step must be "
                f"(below {limit:.3f} s)")
    return {"step_loss": "a motor loses steps",
            "motor_load": f"motor load {value * 100:.0f} % > the reserve's {limit * 100:.0f} %",
            "show_through_mm": f"show-through {shown(key, value)} > the {shown(key, limit)} bound",
            "path_error_mm": f"path error {shown(key, value)} > the {shown(key, limit)} bound"}[key]
