"""One configuration against each baseline: every visible measure with values, verdicts and a text
table, and how it compares in print time and quality (:class:`Comparison`).

Shared by ``tune`` (summary.txt, ``--json``, best.json) and ``simulate``: for each measure of
:data:`ringtune.agents.tune.pareto.VISIBLE_KEYS` (and print time), the configuration's value, the
baseline's, and the verdict from the configuration's side (``better``, ``same`` or ``worse`` at the
:class:`ringtune.agents.tune.pareto.Resolution`). Values in the JSON are in the metrics' own units
(mm, %, s); the text shows µm, % and s. :func:`compare` gives ``tune``'s "chosen vs this" sentence
and :func:`best_dominating` the front point that dominates a baseline.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Callable, Mapping, Sequence

from ringtune.agents.tune.baselines import (LOWERED_BOUNDS, Baselines, baseline_configs, bound_limits, bound_ratio,
                                            lowered_label, lowered_pick)
from ringtune.agents.tune.pareto import (CLASS_KEYS, DEFAULT_RESOLUTION, VISIBLE_KEYS, Point, Resolution,
                                         compare_figure, judge, max_motor_load, shown, words)
from ringtune.envs.evaluate import evaluate_judged
from ringtune.envs.variants import Variant

#: the figures compared, in the order shown: the job's, then the outer wall's own (the surface a
#: person looks at first; every visible class's own is judged, :data:`~ringtune.agents.tune.pareto.JUDGED_KEYS`)
SHOWN = ("print_time_s",) + VISIBLE_KEYS + tuple(k for k in CLASS_KEYS if k.startswith("outer_wall:"))


def versus(point: Point, base: Point, res: Resolution = DEFAULT_RESOLUTION) -> dict:
    """``{key: {value, baseline, verdict}}`` for every figure of :data:`SHOWN` both have
    (:func:`ringtune.agents.tune.pareto.compare_figure`): the values are the worst over the printer
    variants; where the verdict is "worse" on one variant only, ``on`` names it (frequency and
    damping factors) with the two values there (``value_there``, ``baseline_there``)."""
    out = {}
    for k in SHOWN:
        f = compare_figure(point, base, k, res)
        if f is not None:
            out[k] = {"value": point.value(k), "baseline": base.value(k), "verdict": f.verdict}
            if f.variant is not None:
                out[k].update(on=list(f.variant), value_there=f.mine, baseline_there=f.theirs)
    return out


def versus_all(point: Point, baselines: Mapping[str, Point], res: Resolution = DEFAULT_RESOLUTION) -> dict:
    """:func:`versus` against each baseline, by the baselines' keys."""
    return {k: versus(point, b, res) for k, b in baselines.items()}


def table(point: Point, baselines: Mapping[str, Point], labels: Mapping[str, str],
          res: Resolution = DEFAULT_RESOLUTION, name: str = "chosen") -> list[str]:
    """Text lines: one row per measure, the configuration's value, then each baseline's value and
    the verdict of the configuration against it; a legend naming the baselines and the resolution."""
    keys = [k for k in SHOWN if point.value(k) is not None]
    cols = list(baselines)
    w = max([len("measure")] + [len(words(k)[0]) for k in keys]) + 2
    head = f"  {'measure':<{w}}{name:>12}" + "".join(f"  {'[' + str(i + 1) + ']':>12} {'':7}"
                                                   for i in range(len(cols)))
    lines, notes = [head], []
    for k in keys:
        row = f"  {words(k)[0]:<{w}}{shown(k, point.value(k)):>12}"
        for i, c in enumerate(cols):
            f = compare_figure(point, baselines[c], k, res)
            if f is None:
                row += f"  {'—':>12} {'':7}"
                continue
            mark = "*" if f.variant is not None else ""
            row += f"  {shown(k, baselines[c].value(k)):>12} {f.verdict + mark:<7}"
            if f.variant is not None:
                notes.append(f"  * {words(k)[0]} against [{i + 1}]: {shown(k, f.mine)} against {shown(k, f.theirs)} "
                             f"on {Variant(*f.variant).words()}")
        lines.append(row.rstrip())
    for i, c in enumerate(cols):
        lines.append(f"  [{i + 1}] {labels.get(c, c)}")
    lines += notes
    on_twins = any(p.variants for p in (point, *baselines.values()))
    how = (f"values: the worst over the printer and its twins where judged on them; verdicts: {name} against each, "
           "on each of them as well as over the worst (* worse on one of them only)" if on_twins
           else f"verdicts: {name} against each")
    lines.append(f"  ({how}; {res.describe()}.)")
    return lines


#: the words for the study's quality objective in sentences
QUALITY_LABEL = {"overshoot_mm": "overshoot", "path_error_mm": "path error", "ripple_mm": "ripple"}


@dataclass
class Comparison:
    """How ``point`` compares with a baseline (positive = better than the baseline), with the
    verdict per figure at the resolution (``better|same|worse``) and ``dominates`` (nothing worse,
    something better; :func:`ringtune.agents.tune.pareto.judge`)."""

    baseline: str
    faster_s: float
    faster_pct: float
    better_mm: float
    better_pct: float
    dominates: bool
    metrics: dict = field(default_factory=dict)
    path_error_better_mm: float | None = None
    path_error_better_pct: float | None = None

    def sentence(self, quality: str) -> str:
        word = QUALITY_LABEL.get(quality, quality)

        def same(key):
            return ": the same" if self.metrics.get(key) == "same" else ""
        t = (f"{self.faster_s:.3f} s faster ({self.faster_pct:.1f} %{same('print_time_s')})" if self.faster_s >= 0
             else f"{-self.faster_s:.3f} s slower ({-self.faster_pct:.1f} %{same('print_time_s')})")
        parts = [t, _diff(self.better_mm, self.better_pct, word, same(quality))]
        if quality != "path_error_mm" and self.path_error_better_mm is not None:
            parts.append(_diff(self.path_error_better_mm, self.path_error_better_pct, "path error",
                               same("path_error_mm")))
        worse = [_FEASIBLE if k == "feasible" else words(k)[0] for k, v in self.metrics.items() if v == "worse"]
        tail = (" — dominates it" if self.dominates else
                f" — does not dominate it (worse {', '.join(worse)})" if worse else
                " — the same within the resolution")
        return "; ".join(parts) + tail

    def to_dict(self) -> dict:
        return dict(self.__dict__)


_FEASIBLE = "feasibility (it breaks a bound the baseline keeps)"


def _diff(better_mm: float, pct: float | None, word: str, same: str = "") -> str:
    p = f" ({abs(pct):.1f} %{same})" if pct is not None else (f" ({same[2:]})" if same else "")
    return (f"{better_mm * 1000:.1f} µm less {word}{p}" if better_mm >= 0
            else f"{-better_mm * 1000:.1f} µm more {word}{p}")


def compare(point: Point, base: Point, res: Resolution = DEFAULT_RESOLUTION) -> Comparison:
    dt = base.print_time_s - point.print_time_s
    dq = base.quality_mm - point.quality_mm
    j = judge(point, base, res)
    pe_p, pe_b = point.value("path_error_mm"), base.value("path_error_mm")
    dpe = None if pe_p is None or pe_b is None else pe_b - pe_p
    return Comparison(base.label, dt, 100.0 * dt / base.print_time_s if base.print_time_s else 0.0,
                      dq, 100.0 * dq / base.quality_mm if base.quality_mm else 0.0, j.dominates, j.verdicts,
                      dpe, None if dpe is None or not pe_b else 100.0 * dpe / pe_b)


def best_dominating(front: Sequence[Point], base: Point, res: Resolution = DEFAULT_RESOLUTION) -> Point | None:
    """The front point dominating ``base`` at the resolution with the largest summed relative
    gain, or None."""
    dom = [p for p in front if judge(p, base, res).dominates]
    if not dom:
        return None

    def gain(p: Point) -> float:
        return ((base.print_time_s - p.print_time_s) / max(base.print_time_s, 1e-12)
                + (base.quality_mm - p.quality_mm) / max(base.quality_mm, 1e-12))

    return max(dom, key=gain)


def baseline_evaluations(printer, firmware: str, job=None, *, backend: str = "mujoco", freq_margin: float = 0.0,
                         job_accel: str | None = None, note: Callable[[str], None] = lambda s: None,
                         motor_reserve: float = 0.0, max_path_error_mm: float = 0.0) -> tuple[Baselines, dict]:
    """Klipper's pick, what the printer runs now (when known) and no shaping, simulated as ``tune``
    judges them (one ``evaluate_judged`` call): (their :class:`Baselines`, {key: (judged Metrics,
    Evaluation per printer variant)}). Where Klipper's pick loses steps, asks the motors for more
    than ``motor_reserve`` leaves (a fraction; 0: step loss alone) or has more path error than
    ``max_path_error_mm`` (0: no bound), it is judged within the bounds, as ``tune`` judges it
    (:func:`ringtune.agents.tune.baselines.lowered_pick`)."""
    bl = baseline_configs(printer, firmware, note=note)

    def run(configs: list) -> list:
        return evaluate_judged(configs, printer, job, backend, freq_margin=freq_margin, job_accel=job_accel)

    judged = dict(zip(bl.configs, run(list(bl.configs.values()))))
    if "klipper" in judged:
        _klipper_within_bounds(bl, judged, run, bound_limits(max_motor_load(motor_reserve), max_path_error_mm),
                               note)
    return bl, judged


def _klipper_within_bounds(bl: Baselines, judged: dict, run: Callable[[list], list], limits: dict,
                           note: Callable[[str], None]) -> None:
    """Klipper's pick in ``bl`` and ``judged`` at :func:`~ringtune.agents.tune.baselines.lowered_pick`
    where at its max_accel it breaks a bound."""
    def figures(m) -> tuple[dict, bool]:
        return {k: float(getattr(m, k)) for k, _name in LOWERED_BOUNDS}, bool(m.step_loss)

    cfg, runs = bl.configs["klipper"], {}

    def judge_at(a: float) -> tuple[dict, bool, bool]:
        runs[a] = run([dataclasses.replace(cfg, accel=a)])[0]
        values, lost = figures(runs[a][0])
        return values, lost, bound_ratio(values, lost, limits) <= 1.0

    found = lowered_pick(cfg.accel, figures(judged["klipper"][0]), judge_at, limits)
    if found is None:
        return
    lowered, words = found
    note(f"ringtune tune: {words}")
    bl.configs["klipper"], judged["klipper"] = dataclasses.replace(cfg, accel=lowered), runs[lowered]
    bl.labels["klipper"] = lowered_label(bl.labels["klipper"], lowered)
