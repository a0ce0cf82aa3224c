"""Dense grid search over the tuning space (:mod:`ringtune.agents.tune.space`), for checking the study's convergence.

Every grid point is evaluated with the same evaluator as the study (``envs.evaluate.evaluate_many``
by default, batched so that one ``simulate_batch`` call covers many configurations), and the
results are :class:`~ringtune.agents.tune.study.Point` objects, so the same ``pareto_front`` /
``choose`` / ``scalar_objective`` apply to both.
"""

from __future__ import annotations

from typing import Any, Callable, Sequence

from ringtune.agents.tune.space import SearchSpace, config_from_params, grid_params
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
