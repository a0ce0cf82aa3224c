"""Every shaper Klipper's rule fits, at the highest acceleration the judgement allows.

Klipper's calibrate_shaper gives each shaper a frequency and a max_accel from its smoothing
formula. This step measures instead. From the choice, each shaper the rule fitted on the model's
simulated resonance test — the same shaper on both axes at the rule's own per-shaper frequencies
times :data:`FREQ_SCALES` (on a firmware with one shaper for all axes, at each axis's frequency in
turn), designed for each damping ratio of :data:`DAMPINGS` (a smoother takes none), and the rule's
own pick the same way — climbs :data:`RUNGS` times the choice's acceleration (rounded to the
space's step, none above the range's top), everything else of the choice kept (frequency limit;
per-feature settings raised in the same ratio). Every shaping still climbing is judged at the next
rung in one batch, exactly as every trial (the study's evaluator, frequency margin and bounds), and
held to the same baselines as the choice (:func:`ringtune.agents.tune.stop.failure`), and faster than
it by at least :data:`~ringtune.agents.tune.stop.MIN_STEP_SAVING` of its print time; a shaping
stops at its first failing rung. Then, in one batch, each shaping whose failing rung lies above the
fastest passing acceleration is tried at :data:`FINER` of the way into that gap (the rungs are 7–15 %
apart: a coarse winner is not the fine one). The fastest configuration that passed replaces the
choice; the measured stop then walks it on in 5 % steps. Where the judgement is the worst of the
printer and its detuned twins, each batch is screened on the exact model first
(:func:`ringtune.agents.tune.stop.passing`), a big one on a few of the job's windows before the
rest (:mod:`ringtune.agents.tune.first_windows`: the same verdicts). At most ``max_evaluations``
configurations are judged (tune: the study's trials), the shapings taken in the rule's table order
where a batch would judge more.

Why: the study samples a dozen dimensions at once and seldom meets the narrow region where a
shorter shaper at a higher acceleration keeps the baseline's quality (on the part, the fastest
single acceleration at Klipper's quality was found by one study in eight). The rule knows each
shaper's frequency; it weighs remaining vibration against smoothing with a formula, and a higher
frequency smooths less (smoothing falls as 1/f²), as does a shaper designed for more damping (its
first impulse is larger), which lets the acceleration rise at the same corner rounding for a little
more remaining vibration. The judgement settles that trade. On the part at 1.1× Klipper's pick's
acceleration, every shaping that keeps the pick's quality is at 1.16–1.24× the rule's frequency,
six of eight designed for damping 0.15–0.2; at the rule's own frequencies the outer wall's corners
round 80–140 % more than the pick's.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

from ringtune.agents.klipper.rule import DEFAULT_DAMPING_RATIO
from ringtune.agents.tune.baselines import inside
from ringtune.agents.tune.first_windows import staged_failures
from ringtune.agents.tune.pareto import DEFAULT_RESOLUTION, Point, Resolution
from ringtune.agents.tune.space import SearchSpace
from ringtune.agents.tune.stop import Bounds, passing, to_beat, with_accel
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.firmware import FIRMWARES
from ringtune.shaping.smoothers import takes_damping

#: accelerations tried, as multiples of the choice's
RUNGS = (1.1, 1.2, 1.35, 1.5, 1.7, 2.0)
#: then, for a shaping whose next rung failed above the fastest one's, these shares of the way from
#: its highest passing rung to the failing one (one batch)
FINER = (2 / 3, 1 / 3)
#: each shaper's frequencies tried, as multiples of the rule's own for it
FREQ_SCALES = (1.0, 1.08, 1.16, 1.24)
#: the damping ratios each shaper is designed for (the rule designs for 0.1)
DAMPINGS = (DEFAULT_DAMPING_RATIO, 0.15, 0.2)
#: most configurations judged by one ladder
MAX_EVALUATIONS = 200


@dataclass
class Ladder:
    """The step's outcome: the (possibly new) choice, where it started, each shaping tried with its
    highest passing acceleration (mm/s², None: no rung passed), the evaluations judged, how many
    shapings the rule's table gave (``offered``; more than were tried when the budget cut it), the
    first rung (mm/s², None: the choice is at the range's top) and the configurations screened on
    the exact model first (0: no screen)."""

    point: Point
    start: Point
    tried: list[tuple[str, float | None]] = field(default_factory=list)
    evaluations: int = 0
    offered: int = 0
    first_rung: float | None = None
    screened: int = 0
    held_off: int = 0        # faster passing points refused by the wider check
    declined: Point | None = None    # its fastest, not taken: with the measured stop, no faster by the resolution

    @property
    def moved(self) -> bool:
        return self.point is not self.start

    def sentence(self) -> str:
        if not self.offered:
            return "No shaper of Klipper's rule was tried (the rule did not run on both axes)."
        if self.first_rung is None:
            return "No shaper of Klipper's rule was tried: the choice is at the top of the acceleration range."
        cut = "" if len(self.tried) == self.offered else f", {len(self.tried)} of {self.offered} within the budget"
        head = (f"Each shaper Klipper's rule fits, and its pick ({self.offered} shapings: the rule's frequency × "
                f"{', '.join(f'{k:g}' for k in FREQ_SCALES)}, designed for damping "
                f"{', '.join(f'{z:g}' for z in DAMPINGS)}{cut}) climbed from {RUNGS[0]:g}× to {RUNGS[-1]:g}× the "
                f"choice's acceleration until a visible measure was worse than the baselines' or a bound broke, then "
                f"into the gaps above the fastest "
                f"({self.evaluations} evaluations" + (f", {self.screened} screened on the exact model first)"
                                                      if self.screened else ")"))
        n = sum(a is not None for _, a in self.tried)
        off = (f"; {self.held_off} faster one{'s' if self.held_off > 1 else ''} refused: worse on a printer "
               "further off the model" if self.held_off else "")
        if self.declined is not None:
            return (f"{head}: the fastest, {shaping_text(self.declined.config)} at {self.declined.config.accel:.0f} "
                    f"mm/s² ({n} shaping{'s' if n > 1 else ''} passed a rung{off}), not taken: with the measured "
                    "stop after it, no faster by the print-time resolution (below).")
        if not self.moved:
            return (f"{head}: none faster than the choice (" + (f"{n} passed a rung, none faster{off})." if n else
                    f"none passed the first rung, {self.first_rung:.0f} mm/s²)."))
        return (f"{head}: the fastest, {shaping_text(self.point.config)} at {self.point.config.accel:.0f} mm/s² "
                f"({n} shaping{'s' if n > 1 else ''} passed a rung{off}).")

    def to_dict(self) -> dict[str, Any]:
        return {"moved": self.moved, "from_accel": self.start.config.accel, "to_accel": self.point.config.accel,
                "config": self.point.config.to_dict(), "evaluations": self.evaluations, "screened": self.screened,
                "offered": self.offered, "held_off": self.held_off,
                "declined_config": None if self.declined is None else self.declined.config.to_dict(),
                "tried": [{"shaping": name, "highest_passing_accel": a} for name, a in self.tried],
                "sentence": self.sentence()}


def shaping_text(cfg: TuneConfig) -> str:
    """``X mzv @ 53.6 Hz S 0.15, Y mzv @ 42.7 Hz S 0.15``, or one axis's words when both are the same."""
    x, y = cfg.axis("x"), cfg.axis("y")
    if x == y:
        return f"{x[0]} @ {x[1]:.1f} Hz S {x[2]:.3g}"
    return f"X {x[0]} @ {x[1]:.1f} Hz S {x[2]:.3g}, Y {y[0]} @ {y[1]:.1f} Hz S {y[2]:.3g}"


def rule_shapings(cfg: TuneConfig, fits: dict, space: SearchSpace) -> list[TuneConfig]:
    """``cfg`` with each shaper the rule fitted on both axes (``fits``: axis -> Klipper's
    recommendation) at its per-shaper frequencies times :data:`FREQ_SCALES`, designed for each of
    :data:`DAMPINGS`, and the rule's pick the same way; only what the space holds, each once, the
    shaping ``cfg`` already has left out, in the rule's table order, the pick last."""
    if not fits or not all(ax in fits for ax in ("x", "y")):
        return []
    rows = {ax: {f.name: f.freq for f in fits[ax].shapers} for ax in ("x", "y")}
    bx, by = fits["x"].best, fits["y"].best          # the rule's pick (two shapers where it picks two)
    stems = [((name, rows["x"][name]), (name, rows["y"][name])) for name in rows["x"] if name in rows["y"]]
    stems.append(((bx.name, bx.freq), (by.name, by.freq)))
    pairs = [((sx, fx * k), (sy, fy * k), z) for (sx, fx), (sy, fy) in stems for k in FREQ_SCALES
             for z in (DAMPINGS if takes_damping(sx) and takes_damping(sy) else DAMPINGS[:1])]
    if not space.per_axis:        # one shaper for all axes: each shaper at each axis's frequency
        pairs = [(a, a, z) for *pair, z in pairs for a in pair if pair[0][0] == pair[1][0]]
    out: dict = {}
    for (sx, fx), (sy, fy), z in pairs:
        c = dataclasses.replace(cfg, shaper_x=sx, freq_x=round(fx, 1), shaper_y=sy, freq_y=round(fy, 1),
                                damping_x=z, damping_y=z)
        key = (c.axis("x"), c.axis("y"))
        if inside(c, space) and key != (cfg.axis("x"), cfg.axis("y")):
            out.setdefault(key, c)
    return list(out.values())


def rungs(accel: float, space: SearchSpace) -> list[float]:
    """:data:`RUNGS` × ``accel`` (mm/s²), rounded to the space's step, above ``accel``, none above
    the range's top or the firmware's largest acceleration, each once."""
    top = min(space.accel[1], float(FIRMWARES[space.firmware].accel.hi))
    out = sorted({round(accel * r / space.accel_step) * space.accel_step for r in RUNGS})
    return [float(a) for a in out if accel < a <= top + 1e-9]


def climb(start: Point, bases: dict[str, Point], evaluate: Callable[[Sequence[TuneConfig]], list],
          space: SearchSpace, bounds: Bounds, fits: dict, *, res: Resolution = DEFAULT_RESOLUTION,
          max_evaluations: int = MAX_EVALUATIONS, screen: Callable[[Sequence[TuneConfig]], list] | None = None,
          wider: Callable[[TuneConfig], Any] | None = None) -> Ladder:
    """The step (module docstring) from ``start``, held to ``bases``; ``evaluate(configs) ->
    metrics`` judges as the study does; ``fits``: Klipper's per-axis recommendations on the model.

    ``screen``: the same evaluation on the exact model alone, where ``evaluate`` takes the worst
    of the printer and its detuned twins. A shaping that fails on the exact model fails the
    judgement too (the worst case is no better on any measure, and print time is the same), so
    each rung is screened first and only what passes is judged (a third of the cost for what
    fails; :func:`ringtune.agents.tune.stop.passing`); ``max_evaluations`` counts the judged ones.
    ``wider(config)``: why a passing point fails on printers further off the model
    (:mod:`ringtune.agents.tune.wider`), or None: the fastest passing point that holds there too
    replaces the choice (asked fastest first); ``held_off`` counts those it refused."""
    if space.accel_fixed or not start.config.accel:
        return Ladder(start, start)
    offered = rule_shapings(start.config, fits, space)
    # without a screen the first rung alone judges every shaping: the budget cuts the table
    shapings = offered if screen is not None else offered[:max(max_evaluations, 0)]
    steps = rungs(float(start.config.accel), space)
    highest: list[float | None] = [None] * len(shapings)
    best, n, screened = start, 0, 0
    passed: list[Point] = []

    def judge(batch: list[tuple[int, float]]) -> list[Point | None]:
        """Each (shaping, acceleration) of ``batch`` judged (screened first), within the budget; the
        highest passing accelerations and the fastest point updated; per item its point or None."""
        nonlocal best, n, screened
        points, judged, screens = passing([with_accel(shapings[i], a, space) for i, a in batch], evaluate, screen,
                                          bases, to_beat(start), bounds, res, "shaper ladder",
                                          max_judged=max_evaluations - n, verdicts=staged_failures)
        n, screened = n + judged, screened + screens
        for (i, a), p in zip(batch, points):
            if p is not None:
                highest[i] = max(highest[i] or 0.0, a)
                passed.append(p)
                if (p.print_time_s, p.quality_mm) < (best.print_time_s, best.quality_mm):
                    best = p
        return points

    climbing, failed_at = list(range(len(shapings))), {}
    for a in steps:
        if screen is None:
            climbing = climbing[:max_evaluations - n]
        if not climbing or n >= max_evaluations:
            break
        points = judge([(i, a) for i in climbing])
        failed_at.update({i: a for i, p in zip(climbing, points) if p is None})
        climbing = [i for i, p in zip(climbing, points) if p is not None]
    if n < max_evaluations:
        judge(_gaps(highest, failed_at, float(best.config.accel), space.accel_step))
    held_off = 0
    if wider is not None:
        best = start
        for p in sorted(passed, key=lambda q: (q.print_time_s, q.quality_mm)):
            if (p.print_time_s, p.quality_mm) >= (start.print_time_s, start.quality_mm):
                break
            if wider(p.config) is None:
                best = p
                break
            held_off += 1
    return Ladder(best, start, [(shaping_text(c), a) for c, a in zip(shapings, highest)], n, len(offered),
                  steps[0] if steps else None, screened, held_off)


def _gaps(highest: list[float | None], failed_at: dict[int, float], best: float, step: float
          ) -> list[tuple[int, float]]:
    """(shaping, acceleration mm/s²) at :data:`FINER` of the way from each shaping's highest passing
    rung to the rung it failed at, on the space's ``step``, where that is above ``best`` (the
    fastest shaping's acceleration: only those can beat it)."""
    out = []
    for i, f in failed_at.items():
        h = highest[i]
        if h is None:
            continue
        for a in sorted({round((h + k * (f - h)) / step) * step for k in FINER}, reverse=True):
            if max(h, best) < a < f:
                out.append((i, float(a)))
    return out
