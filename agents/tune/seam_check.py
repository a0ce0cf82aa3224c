"""After the walk where nobody looks: every seam of what a person sees, not only the windows' few.

The walk (:mod:`ringtune.agents.tune.hidden_raise`) judges each step on the job's quality windows,
which hold four seams. Settings per feature land on what is seen at every seam (a travel's
deceleration rings into the wall's first millimetres), and a seam the windows do not hold can be
worse: on the part as CuraEngine slices it, when only the last move of a hop onto the wall took the
wall's settings, travel at 10,800 mm/s² with its corners at 30 mm/s left the outer wall's corner
overshoot at 40.0 µm against 29.8 µm before the walk, at a seam whose first corner comes 0.6 mm in
(the whole job simulated, ``benchmarks/bench_whole_job.py``); this check found it. So the walk's
end is simulated on every seam of a visible class (:func:`ringtune.envs.whole_job.seam_metrics`:
the exact linear model of the printer as modelled) against the walk's start; where a visible
measure is worse at the resolution, the raises that meet the seams are taken back — travel's
acceleration, travel's corner rule, the inner walls' acceleration (they are printed just before
the outer wall): each alone, the fastest first, then all of them, then the whole walk — each judged
again on the seams and as every trial, and the first that holds is the choice.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Callable, Sequence

from ringtune.agents.tune.pareto import DEFAULT_RESOLUTION, Point, Resolution, metrics_dict, shown, verdict, words
from ringtune.agents.tune.stop import Bounds, Failure, evaluated, failure, failure_words
from ringtune.agents.tune.versus import SHOWN
from ringtune.envs.forked import split_map
from ringtune.envs.whole_job import seam_metrics
from ringtune.shaping.config import TuneConfig

#: what is taken back, one more at a time: (words, per-class tables, class)
TAKE_BACK = (("travel's acceleration", ("feature_accel",), "travel"),
             ("travel's corner rule", ("feature_corner", "feature_min_cruise_ratio"), "travel"),
             ("the inner walls' acceleration", ("feature_accel",), "inner_wall"))
#: the outer wall's figures whose worst over every seam is reported beside the quality windows'
SEAM_WORST = ("outer_wall:ripple_mm", "outer_wall:corner_in_mm", "outer_wall:corner_out_mm")


@dataclass
class SeamCheck:
    """The seams' verdict on the walk's end (``failure`` against its start, None: it held), what was
    taken back (words), the choice after it, how many seams and configurations were simulated, and
    ``worst``: per figure of :data:`SEAM_WORST` (mm), its worst over every seam for the walk's end
    and its start (exact model) and over the quality windows for the end (as judged)."""

    start: Point
    point: Point
    seams: int
    failure: Failure | None = None
    taken_back: list = field(default_factory=list)
    simulated: int = 0
    worst: dict = field(default_factory=dict)

    def sentence(self) -> str:
        head = (f"Every seam of what a person sees ({self.seams} windows, the exact linear model of the printer "
                "as modelled) against the choice before the walk")
        if self.failure is None:
            return f"{head}: no visible measure worse.{self._worst_words()}"
        why = failure_words(self.failure, "the choice before the walk")
        if self.point is self.start:
            return f"{head}: {why}, so the walk is taken back ({self.start.print_time_s:.1f} s).{self._worst_words()}"
        return (f"{head}: {why}, so {', '.join(self.taken_back)} back as before the walk, which holds there: "
                f"{self.point.print_time_s:.1f} s.{self._worst_words()}")

    def _worst_words(self) -> str:
        """The outer wall's worst over the seams against the quality windows' (where it was measured)."""
        if not self.worst:
            return ""
        cols = ("walk_end", "walk_start", "windows")
        rows = "; ".join(f"{words(k)[0].removeprefix('outer wall ')} "
                         + " / ".join(shown(k, w[c]).removesuffix(" µm") for c in cols) + " µm"
                         for k, w in self.worst.items())
        return (" The outer wall, worst over those seams at the walk's end / before it, and over the quality "
                f"windows as judged (the figures the choice is compared by): {rows}.")

    def to_dict(self) -> dict[str, Any]:
        return {"seams": self.seams, "held": self.failure is None, "taken_back": list(self.taken_back),
                "failure": None if self.failure is None else self.failure._asdict(),
                "print_time_s": self.point.print_time_s, "simulated": self.simulated,
                "outer_wall_worst_mm": self.worst, "sentence": self.sentence()}


def seam_failure(mine, base, res: Resolution = DEFAULT_RESOLUTION) -> Failure | None:
    """The visible measure (the job's and the outer wall's own, :data:`SHOWN`) of metrics ``mine``
    worse than ``base``'s at the resolution by the largest ratio, or None."""
    m, b = metrics_dict(mine), metrics_dict(base)
    both = m.keys() & b.keys() - {"print_time_s"}
    worse = [(m[k] / max(b[k], 1e-12), k) for k in SHOWN if k in both and verdict(k, m[k], b[k], res) == "worse"]
    if not worse:
        return None
    _ratio, k = max(worse)
    return Failure("measure", k, "choice", m[k], b[k])


def seam_worst(mine, base, end: Point) -> dict[str, dict[str, float]]:
    """Per figure of :data:`SEAM_WORST` present in all three: its worst (mm) over every seam for the
    walk's end (``mine``) and start (``base``), and over the end's quality windows (as judged)."""
    m, b, w = metrics_dict(mine), metrics_dict(base), end.metrics
    return {k: {"walk_end": m[k], "walk_start": b[k], "windows": w[k]} for k in SEAM_WORST
            if k in m and k in b and k in w}


def taken_back(end: TuneConfig, start: TuneConfig) -> list[tuple[str, TuneConfig]]:
    """(words, configuration) of ``end`` with what it changed of :data:`TAKE_BACK` as in ``start``:
    each alone, then all of them together (where more than one changed); last ``start`` itself."""
    out, together, said = [], end, []
    for what, tables, cls in TAKE_BACK:
        changed = {t: _as_in(getattr(end, t), getattr(start, t), cls) for t in tables
                   if getattr(start, t).get(cls) != getattr(end, t).get(cls)}
        if changed:
            out.append((what, replace(end, **changed)))
            together = replace(together, **{t: _as_in(getattr(together, t), getattr(start, t), cls) for t in changed})
            said.append(what)
    if len(said) > 1:
        out.append((", ".join(said), together))
    return out + [("the walk", start)]


def _as_in(now: dict, before: dict, cls: str) -> dict:
    """The per-class table ``now`` with ``cls`` as in ``before`` (absent where it is absent there)."""
    out = dict(now)
    out.pop(cls, None)
    out.update((k, before[k]) for k in before.keys() & {cls})
    return out


def seams_of(configs: Sequence[TuneConfig], printer, job, job_accel: str | None = None) -> list:
    """Each configuration's figures over every seam of ``job`` (:func:`seam_metrics`)."""
    return [seam_metrics(c, printer, job, job_accel=job_accel) for c in configs]


def check_seams(start: Point, end: Point, bases: dict[str, Point], evaluate: Callable[[Sequence[TuneConfig]], list],
                bounds: Bounds, printer, job, *, job_accel: str | None = None,
                res: Resolution = DEFAULT_RESOLUTION, split: Callable | None = None) -> SeamCheck:
    """:class:`SeamCheck` of the walk from ``start`` to ``end`` (module docstring); ``evaluate``,
    ``bases`` and ``bounds`` as the walk judged (a configuration taken back must still pass them
    and be faster than ``start``). The seams of two configurations, then of every step back, are
    simulated at once, split over the cores: by ``split(configs)`` (:func:`seams_of`'s figures, e.g.
    on :class:`ringtune.envs.forked.Helpers`), else by :func:`ringtune.envs.forked.split_map`."""
    def on_seams(configs: list[TuneConfig]) -> list:
        if split is not None:
            return split(configs)
        return split_map(lambda part: seams_of(part, printer, job, job_accel), configs)

    base, mine = on_seams([start.config, end.config])
    seams = len(mine.details.get("windows", ()))         # each seam window's own figures
    check = SeamCheck(start, end, seams, seam_failure(mine, base, res), simulated=2, worst=seam_worst(mine, base, end))
    if check.failure is None:
        return check
    steps = [(words, cfg) for words, cfg in taken_back(end.config, start.config) if cfg != start.config]
    check.simulated += len(steps)
    held = [(m.print_time_s, i) for i, m in enumerate(on_seams([cfg for _w, cfg in steps]))
            if seam_failure(m, base, res) is None]
    # each alone, fastest first, then all together (the last step): the first that also passes as judged
    for _t, i in sorted(held, key=lambda ti: (len(steps) > 1 and ti[1] == len(steps) - 1, ti[0])):
        words, cfg = steps[i]
        p = evaluated([cfg], evaluate, bounds, "seam check")[0]
        if failure(p, bases, start, bounds, res) is None:
            check.point, check.taken_back = p, words.split(", ")
            return check
    check.point = start
    return check
