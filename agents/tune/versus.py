"""Every visible measure of one configuration against each baseline: values, verdicts, a text table.

Shared by ``tune`` (summary.txt, ``--json``, best.json) and ``simulate``: for each measure of
:data:`ringtune.agents.tune.pareto.VISIBLE_KEYS` (and print time), the configuration's value, the
baseline's, and the verdict from the configuration's side (``better``, ``same`` or ``worse`` at the
:class:`ringtune.agents.tune.pareto.Resolution`). Values in the JSON are in the metrics' own units
(mm, %, s); the text shows µm, % and s.
"""

from __future__ import annotations

from typing import Callable, Mapping

from ringtune.agents.tune.baselines import Baselines, baseline_configs
from ringtune.agents.tune.pareto import (DEFAULT_RESOLUTION, VISIBLE_KEYS, WORDS, Point, Resolution, shown,
                                         verdict)
from ringtune.envs.evaluate import evaluate_judged

#: the figures compared, in the order shown
SHOWN = ("print_time_s",) + VISIBLE_KEYS


def _value(p: Point | Mapping, key: str) -> float | None:
    if isinstance(p, Point):
        return p.value(key)
    v = p.get(key)
    return None if v is None else float(v)


def versus(point: Point | Mapping, base: Point | Mapping, res: Resolution = DEFAULT_RESOLUTION) -> dict:
    """``{key: {value, baseline, verdict}}`` for every figure of :data:`SHOWN` both have (a Point or a
    metrics dict on each side)."""
    out = {}
    for k in SHOWN:
        a, b = _value(point, k), _value(base, k)
        if a is not None and b is not None:
            out[k] = {"value": a, "baseline": b, "verdict": verdict(k, a, b, res)}
    return out


def versus_all(point: Point | Mapping, baselines: Mapping[str, Point | Mapping],
               res: Resolution = DEFAULT_RESOLUTION) -> dict:
    """:func:`versus` against each baseline, by the baselines' keys."""
    return {k: versus(point, b, res) for k, b in baselines.items()}


def table(point: Point | Mapping, baselines: Mapping[str, Point | Mapping], labels: Mapping[str, str],
          res: Resolution = DEFAULT_RESOLUTION, name: str = "chosen") -> list[str]:
    """Text lines: one row per measure, the configuration's value, then each baseline's value and
    the verdict of the configuration against it; a legend naming the baselines and the resolution."""
    keys = [k for k in SHOWN if _value(point, k) is not None]
    cols = list(baselines)
    head = f"  {'measure':<18}{name:>12}" + "".join(f"  {'[' + str(i + 1) + ']':>12} {'':7}"
                                                   for i in range(len(cols)))
    lines = [head]
    for k in keys:
        row = f"  {WORDS.get(k, (k,))[0]:<18}{shown(k, _value(point, k)):>12}"
        for c in cols:
            b = _value(baselines[c], k)
            row += (f"  {shown(k, b):>12} {verdict(k, _value(point, k), b, res):<7}" if b is not None
                    else f"  {'—':>12} {'':7}")
        lines.append(row.rstrip())
    for i, c in enumerate(cols):
        lines.append(f"  [{i + 1}] {labels.get(c, c)}")
    lines.append(f"  (verdicts: {name} against each; {res.describe()}.)")
    return lines


def baseline_evaluations(printer, firmware: str, job=None, *, backend: str = "mujoco", freq_margin: float = 0.0,
                         job_accel: str | None = None, note: Callable[[str], None] = lambda s: None
                         ) -> tuple[Baselines, dict]:
    """Klipper's pick, what the printer runs now (when known) and no shaping, simulated as ``tune``
    judges them (one ``evaluate_judged`` call): (their :class:`Baselines`, {key: (judged Metrics,
    Evaluation per printer variant)})."""
    bl = baseline_configs(printer, firmware, note=note)
    judged = evaluate_judged(list(bl.configs.values()), printer, job, backend, freq_margin=freq_margin,
                             job_accel=job_accel)
    return bl, dict(zip(bl.configs, judged))
