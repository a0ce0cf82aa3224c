"""Fast where nobody looks, measured: each feature group raised from the study's choice toward its top.

The study (:mod:`ringtune.agents.tune.study`) samples what a single-acceleration study samples (the
shapers, the visible walls' acceleration); every other group runs the visible walls' acceleration
there (within its range), and the corner rules are the printer's. From the choice, after the
measured stop (:mod:`ringtune.agents.tune.stop`), the walk first takes the corners nobody sees,
a group at a time (:data:`~ringtune.agents.tune.feature_groups.CORNER_GROUPS`: sparse infill, support and
travel, then solid infill, whose extrusion is judged as seen): their corner rule at :data:`LEVELS`
of the way to its range's top, then :data:`FINER` steps into the gap above the highest level kept, each
with minimum_cruise_ratio at its range's bottom (no cruise smoothing) and as it is. Then each
group's acceleration at those levels of the way from where it is to the top of its range (the
motor reserve at the group's own top speed) and the finer steps, one batch each: those nobody sees
(infill, solid infill, travel), then the inner walls (they abut the outer wall: judged by what they
push into it) and the top surfaces (seen: judged by their own ripple, corners and extrusion); last
the job's corner rule (the visible walls' too), the same way. The walk is greedy, so its order
decides where it ends: on the built-in part, when a figure had only to be no worse over the worst
of the judged printers, the corners nobody sees first ended at 1051.1 s (their corner rule 5 → 21.5
mm/s, then infill and travel raised), the accelerations first at 1067.7 s (the solid infill raised
to 9600 mm/s², after which no corner rule above 7 passed); on the built-in print both ended at
5.607 s. Every candidate is judged exactly as every trial (the study's
evaluator, frequency margin and bounds) and held to the same baselines as the choice and to the
choice it starts from (``tune`` passes both in ``bases``: the walk spends no visible quality, the
top surfaces being seen): every bound kept (step loss, motor reserve, show-through, path error),
no visible measure worse than any of them at the resolution (the job's and each visible class's own,
:data:`~ringtune.agents.tune.pareto.JUDGED_KEYS`), print time lower than the current choice's by
at least :data:`~ringtune.agents.tune.stop.MIN_STEP_SAVING` (a raise that buys nothing is not worth
its motor load). The fastest candidate that passes becomes the choice; where none does, the group
stays where it was. A walk that ends no faster than its start by the print-time resolution (0.5 %:
what the summary calls "the same") is not taken (``declined``): it would spend motor load and
hidden quality for nothing a person would notice.
Where the judgement is the worst of the printer and its detuned twins, each batch is screened on the
exact model first and only what passes is judged (:func:`ringtune.agents.tune.stop.passing`).

Why a walk and not the study: sampling a dozen more dimensions besides the shapers, the study found
slower choices in the same number of trials (issue 22's note: 1110–1167 s against 1057–1120 s on
the built-in part, seeds 1–2); each group's top is a known, cheap direction to try (units: mm/s²,
the corner rule in the junction rule's unit).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Callable, Sequence

from ringtune.agents.tune.pareto import DEFAULT_RESOLUTION, Point, Resolution
from ringtune.agents.tune.feature_groups import ABUTTING_GROUPS, CORNER_GROUPS, CORNER_WORDS, SEEN_GROUPS
from ringtune.agents.tune.space import (SearchSpace, config_from_params,
                                        params_from_config)
from ringtune.agents.tune.fastest_first import judged_fastest_first
from ringtune.agents.tune.stop import MIN_STEP_SAVING, Bounds, Failure, failure_words, to_beat
from ringtune.shaping.config import TuneConfig

#: shares of the way from the current value to the range's top that are tried, fastest first
LEVELS = (1.0, 0.75, 0.5, 0.25)
#: then, for an acceleration, these shares of the way from the highest level kept to the lowest
#: one above it (the ladder's gaps are a quarter of the range)
FINER = (2 / 3, 1 / 3)


@dataclass
class Held:
    """Where one walked setting stays and what holds it there, measured: ``tried``, the lowest value
    above it that the walk tried (None: it stays at its range's top, ``top``), and why that failed
    (:class:`ringtune.agents.tune.stop.Failure`); ``screened``:
    the failure was seen on the exact model alone (the screen), not on the twins' judgement."""

    key: str
    value: float
    top: float
    tried: float | None = None
    why: Failure | None = None
    screened: bool = False

    def words(self, labels: dict[str, str], unit: str) -> str:
        """``"hidden walls at 5900 mm/s²: at 8100, outer wall under-extrusion 29.90 % > 28.20 % of the
        choice before the walk"``; ``labels`` names the baselines, ``unit`` is the value's."""
        group = self.key.removeprefix("corner_")
        name = f"corner rule of {CORNER_WORDS[group][0]}" if group in CORNER_WORDS else _name(self.key)
        head = f"{name} at {self.value:g}{unit}"
        if self.tried is None:
            return f"{head}: " + ("the top of its range" if self.value >= self.top else "nothing above it was tried")
        seen = ""
        if self.screened and self.why.variant is None:
            seen = (" (on the model as fitted, against the baseline's worst over the model and its twins)"
                    if self.why.kind == "measure" else " (on the model as fitted)")
        what = failure_words(self.why, labels.get(self.why.baseline, self.why.baseline or ""))
        return f"{head}: at {self.tried:g}, {what}{seen}"

    def to_dict(self) -> dict[str, Any]:
        why = self.why or Failure(None, None, None, None, None)
        return {"parameter": self.key, "value": self.value, "top": self.top, "tried": self.tried, "kind": why.kind,
                "key": why.key, "baseline": why.baseline, "measured": why.value, "limit": why.limit,
                "variant": None if why.variant is None else list(why.variant), "screened": self.screened}


@dataclass
class Raise:
    """The walk's end: the (possibly new) choice, the start, each raised setting as
    ``(parameter, from, to)``, the evaluations judged and those screened on the exact model first."""

    point: Point
    start: Point
    raised: list = field(default_factory=list)
    evaluations: int = 0
    budget: int | None = None        # the most evaluations it may spend (None: no limit)
    cut: bool = False                # it stopped at its budget before its last step
    screened: int = 0
    held: list = field(default_factory=list)     # Held per setting walked, in the walk's order
    declined: Point | None = None    # where the walk ended when that was not faster by the resolution
    resolution: Resolution = DEFAULT_RESOLUTION    # what counts as faster
    seams: Any = None                # the seam check of its end (:mod:`ringtune.agents.tune.seam_check`)

    @property
    def moved(self) -> bool:
        return self.point is not self.start

    def sentence(self) -> str:
        cut = (f"; it stopped at its budget of {self.budget} evaluations (the study's trials) before its last "
               "step" if self.cut else "")
        spent = f"{self.evaluations} evaluations" + (f", {self.screened} screened on the exact model first"
                                                     if self.screened else "")
        if not self.raised:
            return (f"No feature nobody sees could go faster (by at least {MIN_STEP_SAVING * 100:g} % of the print "
                    f"time) with every visible measure kept ({spent}{cut}).")
        parts = ", ".join(f"{_name(k)} {a:g} → {b:g}" for k, a, b in self.raised)
        if self.declined is not None:
            end, start = self.declined, self.start
            load, load0 = (p.metrics.get("motor_load", 0.0) * 100 for p in (end, start))
            return (f"Not raised where nobody looks: the walk ({spent}{cut}; {parts}) ended at "
                    f"{end.print_time_s:.3f} s from {start.print_time_s:.3f} s, a saving under the "
                    f"{self.resolution.time_rel * 100:g} % that counts as faster, for motor load "
                    f"{load:.0f} % against {load0:.0f} %: kept as it was.")
        return (f"Raised where nobody looks, every visible measure and bound still kept ({spent}{cut}): {parts}; "
                f"{self.start.print_time_s:.1f} s → {self.point.print_time_s:.1f} s.")

    def to_dict(self) -> dict[str, Any]:
        return {"raised": [{"parameter": k, "from": a, "to": b} for k, a, b in self.raised],
                "declined_print_time_s": None if self.declined is None else self.declined.print_time_s,
                "from_print_time_s": self.start.print_time_s, "to_print_time_s": self.point.print_time_s,
                "evaluations": self.evaluations, "screened": self.screened, "budget": self.budget, "cut": self.cut,
                "sentence": self.sentence(), "held": [h.to_dict() for h in self.held],
                "seam_check": None if self.seams is None else self.seams.to_dict()}

    def ceiling_sentence(self, ceiling_s: float, cruise: bool = True) -> str:
        """What the walk took of what it could reach: ``ceiling_s``, the planned print time (s) of
        :func:`unseen_tops` of the choice; ``cruise``: the space has minimum_cruise_ratio (Klipper's)."""
        ratio = ", the corners' minimum_cruise_ratio 0" if cruise else ""
        head = (f"Ceiling of the walk (the planner alone; neither quality nor the simulated motor load judged): every "
                f"setting nobody sees at the top of its range{ratio}, what a person sees as chosen: {ceiling_s:.1f} s.")
        room = self.start.print_time_s - ceiling_s
        if self.point.print_time_s < ceiling_s:     # the walk's own steps were timed: one top plans slower
            return (f"{head} The walk ended faster than that, at {self.point.print_time_s:.1f} s: on this printer "
                    "a setting at the top of its range plans slower than where the walk left it, so the tops "
                    "are no ceiling.")
        if room <= 0:
            return f"{head} No faster than the walk's start ({self.start.print_time_s:.1f} s)."
        took = self.start.print_time_s - self.point.print_time_s
        return (f"{head} The walk took {took:.1f} of the {room:.1f} s between its start "
                f"({self.start.print_time_s:.1f} s) and that ({took / room * 100:.0f} %).")

    def held_lines(self, labels: dict[str, str], corner_unit: str) -> list[str]:
        """One line per setting walked: where it stays and what holds it there (:class:`Held`);
        ``labels`` names the baselines, ``corner_unit`` the corner rule's unit."""
        return [h.words(labels, corner_unit if h.key in CORNERS else " mm/s²") for h in self.held]


def _name(key: str) -> str:
    """``accel_infill`` -> "infill", ``corner_hidden`` -> "their corner rule" (the corners nobody
    sees), ``min_cruise_ratio_solid`` -> "solid infill's minimum_cruise_ratio"."""
    for prefix, setting in (("corner_", "corner rule"), ("min_cruise_ratio_", "minimum_cruise_ratio")):
        group = key.removeprefix(prefix)
        if group in CORNER_WORDS:
            return f"{CORNER_WORDS[group][1]} {setting}"
    return {"corner": "the job's corner rule", "min_cruise_ratio": "the job's minimum_cruise_ratio"}.get(
        key, key.removeprefix("accel_").replace("_", " "))


def steps(params: dict[str, Any], space: SearchSpace) -> list[str]:
    """What the walk raises, in order (module docstring): the corner rules of the corners nobody sees
    (sparse infill and travel, then solid infill), the acceleration parameter of each group nobody
    sees, of the abutting ones, of the seen ones, then the job's corner rule, each where the space
    has it."""
    groups = [g for g, _lo, _hi in space.feature_accel if f"accel_{g}" in params]
    order = [g for g in groups if g not in SEEN_GROUPS + ABUTTING_GROUPS] + \
        [g for g in groups if g in ABUTTING_GROUPS] + [g for g in groups if g in SEEN_GROUPS]
    corners = [k for k, (_m, rng, _r) in CORNERS.items() if getattr(space, rng) is not None and k in params]
    first = [k for k in corners if k != "corner"]
    return first + [f"accel_{g}" for g in order] + [k for k in corners if k not in first]


#: each corner rule parameter with its minimum_cruise_ratio and the space's fields of their ranges:
#: the job's, then one per corner group (:data:`~ringtune.agents.tune.feature_groups.CORNER_GROUPS`)
CORNERS = {"corner": ("min_cruise_ratio", "corner", "min_cruise_ratio"),
           **{f"corner_{g}": (f"min_cruise_ratio_{g}", "hidden_corner", "hidden_min_cruise_ratio")
              for g in CORNER_GROUPS}}


def batch(key: str, params: dict[str, Any], space: SearchSpace) -> list[dict[str, Any]]:
    """The candidates for ``key`` from ``params``: its value at :data:`LEVELS` of the way to its
    range's top; for a corner rule (:data:`CORNERS`) each also with its minimum_cruise_ratio at the
    range's bottom and as it is (the current point itself left out)."""
    if key not in CORNERS:
        return _levels(params, key, _top(key, space))
    return _with_ratios(key, _levels(params, key, _top(key, space)) + [dict(params)], params, space)


def gap(key: str, kept: float, cands: list[dict[str, Any]], params: dict[str, Any], space: SearchSpace) -> list[dict]:
    """The candidates :data:`FINER` of the way from ``kept`` (the highest level of ``cands`` that
    passed, or where ``key`` was) to the lowest level above it (none when none is above); a corner
    rule's each with its minimum_cruise_ratio both ways, as :func:`batch` gives them."""
    step = None if key in CORNERS else space.accel_step     # accelerations: the levels as they ran
    levels = (float(p[key]) if step is None else round(float(p[key]) / step) * step for p in cands)
    above = [v for v in levels if v > kept]
    if not above:
        return []
    out = [dict(params, **{key: kept + f * (min(above) - kept)}) for f in FINER]
    return _with_ratios(key, out, params, space) if key in CORNERS else out


def _with_ratios(key: str, cands: list[dict[str, Any]], params: dict[str, Any], space: SearchSpace) -> list[dict]:
    """Corner-rule candidates each with its minimum_cruise_ratio at its range's bottom and as it is
    (the current point itself left out)."""
    mcr_key, _corner_range, mcr_range = CORNERS[key]
    if getattr(space, mcr_range) is not None and mcr_key in params:
        ratios = sorted({getattr(space, mcr_range)[0], float(params[mcr_key])})
        cands = [dict(p, **{mcr_key: r}) for p in cands for r in ratios]
    return [p for p in cands if p != params]


def _levels(params: dict[str, Any], key: str, top: float) -> list[dict[str, Any]]:
    now = float(params[key])
    return [dict(params, **{key: v}) for v in sorted({now + f * (top - now) for f in LEVELS if top > now}, reverse=True)]


def raise_hidden(start: Point, bases: dict[str, Point], evaluate: Callable[[Sequence[TuneConfig]], list],
                 space: SearchSpace, bounds: Bounds, *, res: Resolution = DEFAULT_RESOLUTION,
                 max_evaluations: int | None = None,
                 screen: Callable[[Sequence[TuneConfig]], list] | None = None,
                 wider: Callable[[TuneConfig], Failure | None] | None = None, keep_unset: bool = False) -> Raise:
    """Walk the features nobody sees up from ``start`` (module docstring); ``evaluate(configs) ->
    metrics`` judges as the study does; ``bases``: the baselines the choice was held to;
    ``max_evaluations``: no step begins once the walk has judged that many (``tune`` gives it the
    study's trials: a short study gets a short walk); ``screen``: the exact model alone, where
    ``evaluate`` judges the worst of the twins; ``wider(config)``: why a step that passes fails on
    printers further off the model (:mod:`ringtune.agents.tune.wider`), or None — asked of the
    passing candidates fastest first, until one holds there too. ``keep_unset``: the job sets its own
    corner rule or minimum_cruise_ratio, so a candidate leaves each corner setting unset (the job's
    own, as at the start) where the start has it unset and the walk has not changed it."""
    if not space.per_feature:
        return Raise(start, start)
    walk = Raise(start, start, budget=max_evaluations, resolution=res)
    params = params_from_config(start.config, space)
    unset = _unset_corners(start.config, params) if keep_unset else {}

    def config_of(p: dict[str, Any]) -> TuneConfig:
        c = config_from_params(p, space, extra=start.config.extra)
        changes: dict[str, Any] = {}
        for key, (value, table, classes) in unset.items():
            if p.get(key) != value:
                continue
            if table is None:
                changes[key] = None
            else:
                changes[table] = {k: v for k, v in changes.get(table, getattr(c, table)).items() if k not in classes}
        return replace(c, **changes) if changes else c

    def judged(candidates: list[dict[str, Any]], key: str) -> tuple[Point | None, list[tuple[dict, tuple, bool]]]:
        """(the fastest of ``candidates`` that passes against the current choice, or None; each
        that failed as (its parameters, why, seen by the screen))."""
        pairs = [(p, c) for p, c in ((p, config_of(p)) for p in candidates) if c != walk.point.config]
        if not pairs:
            return None, []
        # a step must save MIN_STEP_SAVING of the print time: a raise that buys nothing is not taken
        beat = to_beat(walk.point)
        # fastest first: a slower candidate cannot be kept; those above the one kept are judged
        # still, for what holds the setting (:func:`_held`)
        value = [float(p[key]) for p, _c in pairs]
        taken, points, why, judged_n = judged_fastest_first(
            [c for _p, c in pairs], evaluate, screen, bases, beat, bounds, res, "hidden raise",
            accept=(lambda p: wider(p.config)) if wider is not None else (lambda p: None),
            needed=lambda i, t: value[i] > value[t])
        best = None if taken is None else points[taken]
        walk.screened += len(pairs) if screen is not None else 0
        walk.evaluations += judged_n
        fails = [(params_from_config(c, space), *w) for (_p, c), w in zip(pairs, why) if w is not None]
        return best, fails

    for key in steps(params, space):
        if max_evaluations is not None and walk.evaluations >= max_evaluations:
            walk.cut = True
            break
        cands = batch(key, params, space)
        best, fails = judged(cands, key)
        kept = float(params_from_config(best.config, space)[key]) if best else float(params[key])
        finer, more = judged(gap(key, kept, cands, params, space), key)
        best = finer or best
        if best is not None:
            new = params_from_config(best.config, space)
            walk.raised += [(k, params[k], new[k]) for k in (key, CORNERS.get(key, ("",))[0])
                            if k in new and new[k] != params.get(k)]
            walk.point, params = best, new
        walk.held.append(_held(key, params, fails + more, space))
    return _worth_it(walk)


def _worth_it(walk: Raise) -> Raise:
    """``walk`` as it ended, or back at its start (``declined``: where it ended) when that is not
    faster by its print-time resolution: a saving the summary calls "the same" is not worth
    the motor load and hidden quality the raise spends."""
    start, end = walk.start.print_time_s, walk.point.print_time_s
    if walk.moved and start - end < walk.resolution.tolerance("print_time_s", start, end):
        walk.declined, walk.point = walk.point, walk.start
    return walk


def _unset_corners(config: TuneConfig, params: dict[str, Any]) -> dict[str, tuple]:
    """{walk parameter: (its value in ``params``, the config's per-class table or None for the
    job-wide setting, the classes)} of the corner settings ``config`` leaves unset."""
    out: dict[str, tuple] = {k: (params[k], None, ()) for k in ("corner", "min_cruise_ratio")
                             if k in params and getattr(config, k) is None}
    for group, classes in CORNER_GROUPS.items():
        for prefix, table in (("corner", "feature_corner"), ("min_cruise_ratio", "feature_min_cruise_ratio")):
            key = f"{prefix}_{group}"
            if key in params and not set(classes) & set(getattr(config, table)):
                out[key] = (params[key], table, classes)
    return out


def _held(key: str, params: dict[str, Any], fails: list[tuple[dict, tuple, bool]], space: SearchSpace) -> Held:
    """What holds ``key`` where ``params`` has it: the failed candidate (parameters, why, screened)
    with the lowest value of ``key`` above it (for a corner rule, the one with its
    minimum_cruise_ratio as kept where both were tried)."""
    value = float(params[key])
    top = _top(key, space)
    mcr = CORNERS.get(key, ("",))[0]
    above = [(float(p[key]), p.get(mcr) != params.get(mcr), why, scr) for p, why, scr in fails if float(p[key]) > value]
    if not above:
        return Held(key, value, top)
    tried, _other, why, scr = min(above, key=lambda f: (f[0], f[1]))
    return Held(key, value, top, tried, why, scr)


def unseen_tops(config: TuneConfig, space: SearchSpace) -> TuneConfig:
    """``config`` with every setting the walk raises where nobody sees it at the top of its range
    (the acceleration of each group not in :data:`SEEN_GROUPS`, inner walls and solid infill
    included; each corner group's rule, its minimum_cruise_ratio at the range's bottom, 0: no
    cruise smoothing); what a person sees (the visible walls, the top surfaces, the job's corner
    rule) as in ``config``. Planned alone, it is the most the walk could reach if no quality and no
    simulated motor load held it back."""
    params = params_from_config(config, space)
    for key in steps(params, space):
        if key == "corner" or key.removeprefix("accel_") in SEEN_GROUPS:
            continue
        params[key] = _top(key, space)
        mcr_key, _corner_range, mcr_range = CORNERS.get(key, (None, None, None))
        if mcr_range is not None and getattr(space, mcr_range) is not None and mcr_key in params:
            params[mcr_key] = float(getattr(space, mcr_range)[0])     # Klipper's alone (scv)
    # the job's corner rule is seen: as in ``config`` (unset: the job's own)
    return replace(config_from_params(params, space, extra=config.extra), corner=config.corner,
                   min_cruise_ratio=config.min_cruise_ratio)


def _top(key: str, space: SearchSpace) -> float:
    """The top of ``key``'s range."""
    if key in CORNERS:
        return float(getattr(space, CORNERS[key][1])[1])
    return float(dict((f"accel_{g}", hi) for g, _lo, hi in space.feature_accel)[key])
