"""Points, Pareto fronts and comparison at a stated resolution (shared by the study, the grid and
reports; the choice of one point: :mod:`ringtune.agents.tune.choice`).

What is judged is what a person sees on the part (:mod:`ringtune.envs.window_metrics`): on the
visible features, the wall ripple (worst wall and 90th percentile), corner rounding inwards and
overshoot outwards, and over- and under-extrusion (:data:`VISIBLE_KEYS`); step loss, the motor
reserve, the hidden features' show-through and the path error are bounds (a point breaking one is
infeasible).

Comparisons ("better", "same", "worse", "dominates") are made at a resolution (:class:`Resolution`):
differences of distances smaller than 1 µm or 5 % of the larger value, whichever is larger, of
extrusion smaller than 1 percentage point or 5 %, and of print time smaller than 0.5 %, are "the
same" — below what the model resolves or a print shows. A configuration dominates another when no
compared figure is worse and at least one is better.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ringtune.envs.metrics import by_variant
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.features import VISIBLE


#: mm: default bound on the path error of a usable configuration. Path error is the largest
#: distance of the nozzle from the commanded path while extruding, so it holds corner rounding by
#: the shaper's smoothing as well as overshoot and ringing. Without a bound, the quality objective
#: ``overshoot_mm`` is bought by heavy smoothing (corners cut inwards by 0.3-0.4 mm to save a few
#: µm of overshoot); Klipper bounds the same thing with its smoothing target (0.12 mm). 0.1 mm is
#: a quarter of a 0.4 mm extrusion width.
DEFAULT_MAX_PATH_ERROR_MM = 0.1
#: fraction of each motor's force at its speed kept in reserve by default (``--motor-reserve 20``):
#: ``motor_load`` ≤ 1 − reserve, so that modelling error (mass, motor constants, a drifting
#: resonance) does not turn into skipped steps
DEFAULT_MOTOR_RESERVE = 0.2

#: mm: default bound on how far hidden features (infill, inner walls) reach towards the outer wall
#: (``show_through_mm``). Slicers overlap infill and walls by 10–25 % of a line width (0.04–0.1 mm
#: at 0.4 mm), which absorbs an excursion smaller than that; 0.05 mm keeps inside the overlap of a
#: typical profile. Klipper's pick on the default printer reaches 17 µm, no shaping 71 µm.
DEFAULT_MAX_SHOW_THROUGH_MM = 0.05

#: what a person sees, all smaller-is-better: the figures the default choice may not make worse
#: than the baseline's (mm, except extrusion in %)
VISIBLE_KEYS = ("ripple_mm", "ripple_p90_mm", "corner_in_mm", "corner_out_mm", "extrusion_over_pct",
                "extrusion_under_pct")
#: each visible feature class judged on its own as well (the worst over them can hide one getting
#: worse: an outer wall's ripple under a top surface's larger one), and the inner walls, which abut
#: the outer wall, on what they push into it: keys ``"<class>:<measure>"`` of a point's metrics
CLASS_MEASURES = {**{c: ("ripple_mm", "corner_in_mm", "corner_out_mm", "extrusion_over_pct", "extrusion_under_pct")
                     for c in sorted(VISIBLE)}, "inner_wall": ("show_through_mm",)}
CLASS_KEYS = tuple(f"{c}:{k}" for c, keys in CLASS_MEASURES.items() for k in keys)
#: what the choice may make no worse than the baseline's: the job's figures and each class's
JUDGED_KEYS = VISIBLE_KEYS + CLASS_KEYS
METRIC_KEYS = ("print_time_s", "path_error_mm", "overshoot_mm", "ringing_mm", "peak_accel", "step_loss",
               "motor_load") + VISIBLE_KEYS + ("e_lag_mm", "show_through_mm")
#: the study's objectives (all minimised). Three, not all seven figures: TPE's multi-objective
#: sampler spreads its trials over the front, and each objective more thins them; print time is the
#: trade, the worst wall's ripple and the worse corner deviation (``corner_mm``, the larger of
#: rounding and overshoot) are what a person sees first. The 90th percentile of ripple and the
#: extrusion follow them closely (both grow with the same ringing and lag) and are judged in the
#: choice and the front (``also``); the bounds are Optuna constraints.
OBJECTIVES = ("print_time_s", "ripple_mm", "corner_mm")
#: the words for each figure in sentences, and its unit
WORDS = {"print_time_s": ("print time", "s"), "ripple_mm": ("ripple", "µm"), "ripple_p90_mm": ("ripple p90", "µm"),
         "corner_in_mm": ("corner rounding", "µm"), "corner_out_mm": ("corner overshoot", "µm"),
         "extrusion_over_pct": ("over-extrusion", "%"), "extrusion_under_pct": ("under-extrusion", "%"),
         "overshoot_mm": ("overshoot", "µm"), "path_error_mm": ("path error", "µm"),
         "show_through_mm": ("show-through", "µm"), "e_lag_mm": ("extruder lag", "µm"),
         "corner_mm": ("corner deviation", "µm")}


def objective_value(m, key: str) -> float:
    """The study's objective ``key`` of a metrics object (``corner_mm``: the larger of
    ``corner_in_mm`` and ``corner_out_mm``); an injected evaluator's object without the visible
    measures gives its ``overshoot_mm`` for them."""
    if key == "corner_mm":
        return max(objective_value(m, "corner_in_mm"), objective_value(m, "corner_out_mm"))
    v = getattr(m, key, None)
    return float(getattr(m, "overshoot_mm") if v is None else v)


def words(key: str) -> tuple[str, str]:
    """(the words for a figure, its unit); a class's own figure (``"outer_wall:ripple_mm"``) as
    "outer wall ripple"."""
    cls, _, k = key.rpartition(":")
    name, unit = WORDS.get(k, (k, "µm"))
    return (f"{cls.replace('_', ' ')} {name}" if cls else name), unit


def shown(key: str, value: float) -> str:
    """A figure in its unit: µm for mm, % for percentages, s for time."""
    unit = words(key)[1]
    if unit == "µm":
        return f"{value * 1000:.1f} µm"
    return f"{value:.2f} %" if unit == "%" else f"{value:.3f} s"


@dataclass(frozen=True)
class Resolution:
    """Differences below these are "the same": distances (mm) under ``distance_mm`` or
    ``distance_rel`` of the larger of the two values (whichever is larger); print time (s) under
    ``time_rel`` of the larger."""

    distance_mm: float = 0.001
    distance_rel: float = 0.05
    time_rel: float = 0.005
    pct_abs: float = 1.0          # percentage points, for the extrusion figures (%)

    def tolerance(self, key: str, a: float, b: float) -> float:
        big = max(abs(a), abs(b))
        if key == "print_time_s":
            return self.time_rel * big
        if key.endswith("_pct"):
            return max(self.pct_abs, self.distance_rel * big)
        return max(self.distance_mm, self.distance_rel * big)

    def describe(self) -> str:
        return (f"differences under {self.distance_mm * 1000:g} µm or {self.distance_rel * 100:g} % "
                f"(whichever is larger) for distances, under {self.pct_abs:g} percentage point or "
                f"{self.distance_rel * 100:g} % for extrusion and under {self.time_rel * 100:g} % for print time "
                "count as the same")


DEFAULT_RESOLUTION = Resolution()


#: the bounds a point may break, in the order they are reported: (its flag on :class:`Point`, the
#: words); the last is a study trial settled on the model alone (its figures are lower bounds)
BOUNDS = (("step_loss", "loses steps"), ("too_rough", "path error over the bound"),
          ("overloaded", "motor load over the reserve"), ("shows_through", "show-through over the bound"),
          ("screened", "judged on the model alone"))


@dataclass
class Point:
    """One evaluated configuration (a trial, a grid point or a baseline). A point is feasible
    unless it loses steps, its path error is over the bound it was judged with (``too_rough``), its
    motor load is over 1 − the motor reserve (``overloaded``) or its hidden features reach the outer
    wall by more than the show-through bound (``shows_through``), or it is a study trial whose
    figures are the model's alone (``screened``). ``quality_mm`` is the study's
    second objective (the worst wall's ripple, mm; a custom evaluator's own figure)."""

    config: TuneConfig
    print_time_s: float
    quality_mm: float
    step_loss: bool = False
    metrics: dict = field(default_factory=dict)
    label: str = ""
    number: int | None = None
    too_rough: bool = False
    overloaded: bool = False
    shows_through: bool = False
    #: its visible measures on each printer variant it was judged on (:func:`variant_figures`):
    #: ((frequency factor, damping factor), {key: value}) each; () where judged on one printer
    variants: tuple = ()
    #: why a study trial was settled on the printer as modelled, its twins not simulated ("" where
    #: it was judged on all): its figures are lower bounds, so it is ruled out
    #: (:mod:`ringtune.agents.tune.trial_screen`)
    screened: str = ""

    @property
    def feasible(self) -> bool:
        return not any(getattr(self, flag) for flag, _words in BOUNDS)

    def dominates(self, other: "Point") -> bool:
        """Strict Pareto dominance on the two objectives (no resolution; the front's relation)."""
        return (self.print_time_s <= other.print_time_s and self.quality_mm <= other.quality_mm
                and (self.print_time_s < other.print_time_s or self.quality_mm < other.quality_mm))

    def value(self, key: str) -> float | None:
        if key == "print_time_s":
            return self.print_time_s
        if key == "corner_mm" and "corner_in_mm" in self.metrics:
            return max(float(self.metrics["corner_in_mm"]), float(self.metrics.get("corner_out_mm", 0.0)))
        v = self.metrics.get(key)
        return None if v is None else float(v)


@dataclass(frozen=True)
class Figure:
    """How one figure of a point compares with a baseline's: the verdict and the two values it
    comes from, and ``variant``: the printer variant (frequency factor, damping factor) where the
    point is worse on that variant although the worst over the variants is not (None: the values
    are the worst over the variants, or of the one printer)."""

    verdict: str
    mine: float
    theirs: float
    variant: tuple[float, float] | None = None


@dataclass
class Judgement:
    """How ``point`` compares with ``base`` at a resolution: per figure ``better|same|worse``
    (from the point's side), ``feasible`` both ways, and ``dominates`` (nothing worse, something
    better, and the point not ruled out where the base is not); ``figures``: each figure's
    :class:`Figure` (the values behind its verdict)."""

    verdicts: dict
    dominates: bool
    resolution: Resolution
    figures: dict = field(default_factory=dict)


#: (point feasible, base feasible) -> the feasibility verdict from the point's side; else "same"
_FEASIBLE_VERDICT = {(False, True): "worse", (True, False): "better"}


def verdict(key: str, mine: float, theirs: float, res: Resolution = DEFAULT_RESOLUTION) -> str:
    """``better``, ``same`` or ``worse`` for a figure where lower is better."""
    d = float(mine) - float(theirs)
    tol = res.tolerance(key, mine, theirs)
    return "worse" if d > tol else "better" if d < -tol else "same"


def compare_figure(point: Point, base: Point, key: str, res: Resolution = DEFAULT_RESOLUTION) -> Figure | None:
    """How ``point``'s figure ``key`` compares with ``base``'s (None where either lacks it).

    Where both were judged on the same printer variants (the model and its detuned twins), the
    figure is compared on each variant as well as over their worst: a point is worse where it is
    worse on any variant — on a printer whose resonances are 5 % higher its outer wall may ripple
    more than the baseline's there while its worst over the three still matches the baseline's
    worst (which comes from another variant). The variant reported is the one it is worse on by
    the largest ratio."""
    a, b = point.value(key), base.value(key)
    if a is None or b is None:
        return None
    out = Figure(verdict(key, a, b, res), a, b)
    if out.verdict == "worse" or not point.variants or not base.variants:
        return out
    theirs = dict(base.variants)
    worst = None
    for f, figs in point.variants:
        x, y = figs.get(key), theirs.get(f, {}).get(key)
        if x is not None and y is not None and verdict(key, x, y, res) == "worse":
            ratio = x / max(y, 1e-12)
            if worst is None or ratio > worst[0]:
                worst = (ratio, Figure("worse", float(x), float(y), f))
    return out if worst is None else worst[1]


def judge(point: Point, base: Point, res: Resolution = DEFAULT_RESOLUTION,
          keys: Sequence[str] | None = None) -> Judgement:
    """Compare ``point`` with ``base`` on ``keys`` (figures both have; default print time and the
    visible measures, or a custom evaluator's overshoot and path error), each over the printer
    variants both were judged on and on each of them (:func:`compare_figure`), and on feasibility."""
    keys = keys if keys is not None else ("print_time_s",) + quality_keys([point, base])
    figs = {k: f for k in keys if (f := compare_figure(point, base, k, res)) is not None}
    v = {k: f.verdict for k, f in figs.items()}
    v["feasible"] = _FEASIBLE_VERDICT.get((point.feasible, base.feasible), "same")
    vals = list(v.values())
    return Judgement(v, "worse" not in vals and "better" in vals, res, figs)


def variant_figures(m) -> tuple:
    """A worst-case metrics object's visible measures (:data:`JUDGED_KEYS`) on each printer variant
    it was judged on (``details["variants"]`` of :func:`ringtune.envs.metrics.worst_case`, each
    naming its variant): ((frequency factor, damping factor), {key: value}) each; () where it was
    judged on one printer or the variants are not named."""
    out = []
    for variant, d in by_variant(m).items():
        figs = {k: float(d[k]) for k in VISIBLE_KEYS if k in d}
        for cls, values in (d.get("features") or {}).items():
            figs.update({f"{cls}:{k}": float(values[k]) for k in CLASS_MEASURES.get(cls, ()) if k in values})
        out.append((variant, figs))
    return tuple(out)


def variants_to_json(variants: tuple) -> list:
    """:attr:`Point.variants` as JSON (a trial's user attribute): [[freq, damping], {key: value}] each."""
    return [[list(f), dict(figs)] for f, figs in variants]


def variants_from_json(data) -> tuple:
    """:func:`variants_to_json`'s inverse."""
    return tuple((tuple(float(x) for x in f), {k: float(v) for k, v in figs.items()}) for f, figs in (data or ()))


def metrics_dict(m) -> dict:
    """The :data:`METRIC_KEYS` of a metrics object as plain floats (``step_loss`` a bool; a
    figure the object lacks, e.g. ``motor_load`` of a custom evaluator, is left out), and the
    :data:`CLASS_KEYS` of the feature classes its windows hold."""
    out = {}
    for k in METRIC_KEYS:
        if hasattr(m, k):
            out[k] = bool(getattr(m, k)) if k == "step_loss" else float(getattr(m, k))
    for cls, values in (getattr(m, "features", None) or {}).items():
        for k in CLASS_MEASURES.get(cls, ()):
            if k in values:
                out[f"{cls}:{k}"] = float(values[k])
    return out


def point_from_metrics(config: TuneConfig, m, quality: str = "ripple_mm", *, label: str = "",
                       number: int | None = None, max_path_error_mm: float = 0.0, max_motor_load: float = 0.0,
                       max_show_through_mm: float = 0.0) -> Point:
    """A :class:`Point` from a metrics object; ``max_path_error_mm`` > 0 bounds the path error (mm),
    ``max_motor_load`` > 0 the motor load (fraction), ``max_show_through_mm`` > 0 the show-through (mm)."""
    p = Point(config, float(m.print_time_s), objective_value(m, quality), bool(m.step_loss), metrics_dict(m),
              label, number, variants=variant_figures(m))
    return judge_bounds(p, max_path_error_mm, max_motor_load, max_show_through_mm)


def _over(p: Point, key: str, bound: float) -> bool:
    """Whether ``p``'s figure ``key`` exceeds ``bound`` (0 = no bound; a figure ``p`` lacks never does)."""
    value = p.metrics.get(key)
    return bool(bound > 0 and value is not None and value > bound)


def judge_path_error(p: Point, max_path_error_mm: float) -> Point:
    """Mark ``p`` too rough when its path error exceeds ``max_path_error_mm`` (mm; 0 = no bound)."""
    p.too_rough = _over(p, "path_error_mm", max_path_error_mm)
    return p


def max_motor_load(reserve: float) -> float:
    """The highest motor load (fraction of the force the motors have) a reserve allows; 0 = no bound."""
    return 1.0 - reserve if reserve > 0 else 0.0


def judge_bounds(p: Point, max_path_error_mm: float = 0.0, max_motor_load: float = 0.0,
                 max_show_through_mm: float = 0.0) -> Point:
    """Every bound at once (0 = no bound): path error and show-through in mm, motor load as a
    fraction of the force the motor has at its speed."""
    p.shows_through = _over(p, "show_through_mm", max_show_through_mm)
    p.overloaded = _over(p, "motor_load", max_motor_load)
    return judge_path_error(p, max_path_error_mm)


def broken_bounds(p: Point) -> list[str]:
    """The bounds ``p`` breaks, in words (:data:`BOUNDS`; empty when feasible)."""
    return [words for flag, words in BOUNDS if getattr(p, flag)]


def pareto_front(points: Sequence[Point], also: Sequence[str] = ()) -> list[Point]:
    """The feasible non-dominated points, sorted by print time.

    Dominance is over print time and the quality objective, and also over the figures named in
    ``also`` (metrics keys, e.g. ``("path_error_mm",)``: then a point with more overshoot but
    much less path error than a faster one stays on the front, so that "no worse overshoot and
    path error than a baseline" can be found on it)."""
    feas = sorted((p for p in points if p.feasible), key=lambda p: (p.print_time_s, p.quality_mm))
    if not also:
        front: list[Point] = []
        best_q = np.inf
        for p in feas:
            if p.quality_mm < best_q:
                front.append(p)
                best_q = p.quality_mm
        return front
    v = np.array([[p.print_time_s, p.quality_mm] + [float(p.metrics.get(k, np.inf)) for k in also] for p in feas])
    kept: dict = {}     # the non-dominated points by their figures: of identical ones, the first only
    for p, row in zip(feas, v):
        if not np.any(np.all(v <= row, axis=1) & np.any(v < row, axis=1)):
            kept.setdefault((p.print_time_s, p.quality_mm, *(p.metrics.get(k) for k in also)), p)
    return list(kept.values())


def no_worse(p: Point, base: Point, res: Resolution = DEFAULT_RESOLUTION, keys: Sequence[str] = JUDGED_KEYS) -> bool:
    """No figure of ``keys`` (that both have) worse than ``base``'s at the resolution (feasibility aside)."""
    return all(v != "worse" for k, v in judge(p, base, res, keys).verdicts.items() if k != "feasible")


#: each set of measures :func:`quality_keys` gives, in words
QUALITY_WORDS = {JUDGED_KEYS: "visible measure", ("overshoot_mm", "path_error_mm"): "overshoot and path error"}


def quality_keys(points: Sequence[Point]) -> tuple[str, ...]:
    """The visible measures the points have (the job's and each class's: :data:`JUDGED_KEYS`); a
    custom evaluator's without them: its overshoot and path error."""
    if any("ripple_mm" in p.metrics for p in points):
        return JUDGED_KEYS
    return ("overshoot_mm", "path_error_mm")


def scalar_objective(p: Point, weight: float) -> float:
    """``print_time_s + weight·quality_mm`` (s), the single number convergence checks compare."""
    return p.print_time_s + weight * p.quality_mm
