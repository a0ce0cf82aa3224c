"""Dense grid search over the tuning space (:mod:`ringtune.agents.tune.space`), for checking the study's convergence.

Every grid point is evaluated with the same evaluator as the study (``envs.evaluate.evaluate_many``
by default, batched so that one ``simulate_batch`` call covers many configurations), and the
results are :class:`~ringtune.agents.tune.study.Point` objects, so the same ``pareto_front`` /
``choose`` / ``scalar_objective`` apply to both.
"""

from __future__ import annotations

import itertools
from typing import Any, Callable, Sequence

import numpy as np

from ringtune.agents.tune.space import SearchSpace, config_from_params, damping_keys, shaping_axes
from ringtune.agents.tune.pareto import DEFAULT_MAX_PATH_ERROR_MM, Point, point_from_metrics
from ringtune.agents.tune.study import DEFAULT_EVALUATOR, resolve_evaluator


def run_grid(space: SearchSpace, *, printer: Any = None, job: Any = None, quality: str = "overshoot_mm",
             evaluator: str | Callable = DEFAULT_EVALUATOR, backend: str = "mujoco",
             params: Sequence[dict] | None = None, batch: int = 64,
             progress: Callable[[int, int], None] | None = None,
             max_path_error_mm: float = DEFAULT_MAX_PATH_ERROR_MM, freq_margin: float = 0.0,
             **grid_kw) -> list[Point]:
    """Evaluate every point of ``params`` (default :func:`grid_params(space, **grid_kw)`); points
    whose path error exceeds ``max_path_error_mm`` (mm; 0 = no bound) are infeasible, as in the study;
    ``freq_margin``: judged also with the resonances moved by ± this fraction (default evaluator)."""
    fn = resolve_evaluator(evaluator)
    kw = {"backend": backend, "freq_margin": freq_margin} if evaluator == DEFAULT_EVALUATOR else {}
    params = list(params if params is not None else grid_params(space, **grid_kw))
    points: list[Point] = []
    for i in range(0, len(params), batch):
        chunk = params[i:i + batch]
        configs = [config_from_params(p, space) for p in chunk]
        for j, (cfg, m) in enumerate(zip(configs, fn(configs, printer, job, **kw))):
            points.append(point_from_metrics(cfg, m, quality, label=f"grid {i + j}", number=i + j,
                                             max_path_error_mm=max_path_error_mm))
        if progress:
            progress(len(points), len(params))
    return points


def hypervolume(front: Sequence[Point], ref: tuple[float, float]) -> float:
    """Area dominated by ``front`` (sorted by print time) up to the reference point (s·mm)."""
    pts = sorted((p.print_time_s, p.quality_mm) for p in front if p.print_time_s < ref[0] and p.quality_mm < ref[1])
    # staircase: each front point adds (ref_t − t) × (drop in quality below the previous point)
    area = 0.0
    prev_q = ref[1]
    for t, q in pts:
        if q < prev_q:
            area += (ref[0] - t) * (prev_q - q)
            prev_q = q
    return area


def _shaping_points(space: SearchSpace, shapers: tuple[str, ...], n_freq: int) -> list[dict]:
    """The grid's shaping parameters: every combination of the axes' options (:func:`_axis_options`),
    the parametrised families left out (Optuna searches them)."""
    plain = tuple(s for s in shapers if "(" not in s)
    points: list[dict] = [{}]
    for ax, s in shaping_axes(space):
        options = _axis_options(plain, getattr(space, f"freq_{ax}"), s, n_freq)
        points = [{**p, **o} for p in points for o in options]
    return points


def _axis_options(shapers: tuple[str, ...], lo_hi: tuple[float, float], suffix: str, n_freq: int) -> list[dict]:
    """One axis's grid points: each shaper at ``n_freq`` frequencies over ``lo_hi`` Hz (``none`` once)."""
    freqs = [round(float(f), 1) for f in np.linspace(lo_hi[0], lo_hi[1], n_freq)]
    out: list[dict] = []
    for s in shapers:
        out += [{f"shaper{suffix}": s}] if s == "none" else [{f"shaper{suffix}": s, f"freq{suffix}": f} for f in freqs]
    return out


def grid_params(space: SearchSpace, n_freq: int = 9, n_damping: int = 3, n_accel: int = 6,
                freq_limits: tuple[float, ...] = (), shapers: tuple[str, ...] | None = None,
                dampings: tuple[float, ...] | None = None, accels: tuple[float, ...] | None = None) -> list[dict]:
    """A dense Cartesian grid over ``space`` (parameter dicts), for convergence checks.

    Per axis: every shaper × ``n_freq`` frequencies (``none`` once; the parametrised families are
    left to Optuna); S on ``n_damping`` levels (once where no axis is shaped);
    acceleration on ``n_accel`` levels (multiples of ``accel_step``); the frequency limit off plus
    each method at each of ``freq_limits`` Hz. ``dampings`` / ``accels`` give explicit levels instead.
    """
    shaping = _shaping_points(space, shapers or space.shapers, n_freq)
    if dampings is None:
        dampings = [round(float(z), 3) for z in np.linspace(space.damping[0], space.damping[1], n_damping)]
    if accels is None:
        accels = np.linspace(space.accel[0], space.accel[1], n_accel)
    accels = sorted({round(float(a) / space.accel_step) * space.accel_step for a in accels})
    limits = [{"freq_limit": "off"}] + [{"freq_limit": m, "freq_limit_hz": float(h)}
                                         for m in space.freq_limit_methods for h in freq_limits]
    damped = [{**sh, **dict.fromkeys(damping_keys(sh, space), z)}
              for sh in shaping for z in (dampings if _shaped(sh) else [None])]
    return [{**point, **lim, "accel": a} for point, lim, a in itertools.product(damped, limits, accels)]


def _shaped(point: dict[str, Any]) -> bool:
    """Whether a grid point shapes any axis."""
    return any(v != "none" for k, v in point.items() if k.startswith("shaper"))
