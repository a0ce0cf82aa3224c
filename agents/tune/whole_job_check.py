"""Do the quality windows' verdicts hold over the whole job?

``tune`` judges each configuration on the job's quality windows (a few seconds of it). This
measures a configuration, and a baseline beside it (Klipper's pick), on those windows and over all
of the job (:func:`ringtune.envs.whole_job.whole_job_metrics`: the exact linear backend at 5 kHz, in
pieces cut where nothing is printed or, after two spans printed without a pause, inside a straight
line, each after six time constants of the slowest mode), both on the printer as modelled (not its
twins) with the same exact backend, so what differs between the two columns is only where is
measured. Every visible measure, the job's and the outer wall's own,
with the verdict against the baseline at the reports' resolution (1 µm or 5 %; 1 percentage point or
5 % of extrusion). Used by ``ringtune simulate --whole-job`` and ``benchmarks/bench_whole_job.py``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ringtune.agents.tune.pareto import DEFAULT_RESOLUTION, metrics_dict, shown, verdict, words
from ringtune.agents.tune.versus import SHOWN
from ringtune.envs.evaluate import evaluate_many
from ringtune.envs.forked import split_map
from ringtune.envs.planned_job import planned_job, windows_sentence
from ringtune.envs.whole_job import outer_wall_worst, whole_job_metrics
from ringtune.shaping.config import TuneConfig


@dataclass
class WholeJobCheck:
    """A configuration's measures (and a baseline's, or None) on the windows and over the whole job:
    ``windows``/``whole`` are ``[config's, baseline's]`` :func:`metrics_dict`; ``keys`` the visible
    measures both hold; ``where`` the windows in words; ``seconds`` the whole job's simulation;
    ``places`` where the configuration's outer wall has its worst corner over the whole job
    (:data:`PLACED`; with the G-code line of the move there)."""

    keys: list[str]
    windows: list[dict]
    whole: list[dict]
    where: str
    seconds: float
    places: dict = field(default_factory=dict)     # {key: {value, t, x, y, line}}: the configuration's

    def verdicts(self, side: int) -> dict[str, str]:
        """``{key: better|same|worse}`` of the configuration against the baseline on the windows
        (``side`` 0) or over the whole job (1); empty without a baseline."""
        figures = (self.windows, self.whole)[side]
        if len(figures) < 2:
            return {}
        return {k: verdict(k, figures[0][k], figures[1][k], DEFAULT_RESOLUTION) for k in self.keys}

    def differ(self) -> list[str]:
        """The measures whose verdict differs between the windows and the whole job."""
        on_windows, on_whole = self.verdicts(0), self.verdicts(1)
        return [k for k in on_whole if on_windows[k] != on_whole[k]]

    def worse(self) -> list[str]:
        """The measures worse than the baseline's over the whole job."""
        return [k for k, v in self.verdicts(1).items() if v == "worse"]

    def to_dict(self) -> dict[str, Any]:
        on_windows, on_whole = self.verdicts(0), self.verdicts(1)
        return {"where": self.where, "seconds": self.seconds, "baseline": len(self.whole) > 1,
                "measures": {k: {"windows": [d[k] for d in self.windows], "whole": [d[k] for d in self.whole],
                                 **({"verdict_windows": on_windows[k], "verdict_whole": on_whole[k]}
                                    if on_whole else {})} for k in self.keys},
                "differ": self.differ(), "worse": self.worse(), "outer_wall_worst": self.places}

    def table(self, name: str = "this", baseline: str = "the baseline") -> list[str]:
        """The text report: one line per measure (the windows' figures and verdict, then the whole
        job's), then the differing and worse ones in words."""
        w = max(len(words(k)[0]) for k in self.keys) + 2
        rest = ["baseline", "verdict"][:2 * (len(self.whole) - 1)]
        lines = [f"  {'measure':<{w}}" + _row("windows: " + name, rest) + _row("whole: " + name, rest)]
        on = (self.verdicts(0), self.verdicts(1))
        for k in self.keys:
            lines.append(f"  {words(k)[0]:<{w}}" + _cells(k, self.windows, on[0]) + _cells(k, self.whole, on[1]))
        lines += [f"  the outer wall's worst {words(k)[0].replace('outer wall ', '')} over the whole job ({name}): "
                  f"{shown(k, at['value'])} at {at['t']:.2f} s, X {at['x']:.2f} Y {at['y']:.2f} (G-code line {at['line']})"
                  for k, at in self.places.items()]
        return lines + [f"verdicts against {baseline} that differ between the windows and the whole job: "
                        f"{_listed(self.differ(), len(self.keys))}",
                        f"measures worse than {baseline}'s over the whole job: {_listed(self.worse(), len(self.keys))}"
                        ][:2 * (len(self.whole) - 1)]


def _row(first: str, rest: list[str]) -> str:
    return f"{first:>22}" + "".join(f"{c:>10}" for c in rest)


def _cells(key: str, figures: list[dict], verdicts: dict[str, str]) -> str:
    """One side's figures (µm, %) and its verdict where there is one, under :meth:`WholeJobCheck.table`'s heads."""
    first, *rest = [shown(key, d[key]) for d in figures]
    return _row(first, rest + ([verdicts[key]] if verdicts else []))


def _listed(keys: list[str], n: int) -> str:
    return f"{len(keys)} of {n}" + (f" ({', '.join(words(k)[0] for k in keys)})" if keys else "")


def whole_job_check(config: TuneConfig, printer, job, baseline: TuneConfig | None = None,
                    job_accel: str | None = None) -> WholeJobCheck:
    """``config`` (and ``baseline``) on the job's quality windows and over the whole job, the
    printer as modelled, the exact linear backend (module docstring); ``printer``: a ``Printer``;
    ``job``: as :func:`ringtune.envs.evaluate.evaluate` takes it."""
    configs = [c for c in (config, baseline) if c is not None]
    windows = [metrics_dict(m) for m in evaluate_many(configs, printer, job, "lti", job_accel=job_accel)]
    where = windows_sentence(planned_job(printer, job, config, job_accel=job_accel))
    t0 = time.perf_counter()
    measured = split_map(lambda part: [_measured(c, printer, job, job_accel) for c in part], configs)  # a core each
    seconds = time.perf_counter() - t0
    whole = [figures for figures, _ in measured]
    moves = planned_job(printer, job, config, job_accel=job_accel).plan.moves
    places = {k: {**at, "line": int(moves.line[max(np.searchsorted(moves.t_start, at["t"], side="right") - 1, 0)])}
              for k, at in measured[0][1].items() if at is not None}
    return WholeJobCheck(_common_keys(windows + whole), windows, whole, where, seconds, places)


#: the measures whose worst place over the whole job is said (the outer wall's own)
PLACED = ("outer_wall:corner_in_mm", "outer_wall:corner_out_mm")


def _measured(config: TuneConfig, printer, job, job_accel) -> tuple[dict, dict]:
    """(:func:`metrics_dict` of the whole job, {key of :data:`PLACED`: where it is worst or None})."""
    m = whole_job_metrics(config, printer, job, job_accel=job_accel)
    return metrics_dict(m), {k: outer_wall_worst(m, k.split(":")[1]) for k in PLACED}


def _common_keys(figures: list[dict]) -> list[str]:
    """The visible measures (:data:`ringtune.agents.tune.versus.SHOWN` but print time) all ``figures`` hold."""
    return [k for k in SHOWN[1:] if all(k in d for d in figures)]
