"""The acceleration one simulation suggests: scale a configuration's metrics with acceleration.

On the linear printer every deviation of the nozzle from its path is proportional to the commanded
acceleration (the planner's velocity profile changes too, so this is a first-order model), and so
is the force the motors must give. One evaluation of a configuration at acceleration ``a0`` then
predicts its metrics at any other acceleration ``a``: the print time ``T(a)`` exact from the
planner, every distance (ripple, corners, show-through, path error, overshoot, ringing) and the
motor load × ``a/a0``, the extruder's timing as it is (it follows the shaper's lag and the speed).
The anchor is the ``a`` that minimises the env's own cost (:mod:`ringtune.envs.judgement`: ``tune``'s
judgement) of those predicted metrics among those whose predicted load stays at or below
``load_cap`` (default 0.7: a 30 % force reserve for what the linear scaling misses: the force's
fall with speed, resonant overshoot of the belts). It is what an engineer reads off one test print
("it rings this much and uses this much of its motor at 4000; how hard can I drive it?"), and it is
the physical anchor around which the PPO policy decides the acceleration
(``ActionSpec.accel_anchor = "model"``).
"""

from __future__ import annotations

import dataclasses
from typing import Callable

import numpy as np

from ringtune.envs.planned_job import planned_job
from ringtune.envs.metrics import Metrics
from ringtune.shaping.config import TuneConfig

#: fraction of the motor's force the anchor may plan to use
LOAD_CAP = 0.7


#: the measures scaled with acceleration (mm)
SCALED = ("ripple_mm", "ripple_p90_mm", "corner_in_mm", "corner_out_mm", "show_through_mm", "path_error_mm",
          "overshoot_mm", "ringing_mm", "motor_load")


def model_accel(printer, job, config: TuneConfig, metrics: Metrics, cost: Callable[[Metrics], float],
                accel_range: tuple[float, float], load_cap: float = LOAD_CAP, n: int = 33) -> float:
    """mm/s²: the acceleration within ``accel_range`` (``n`` log-spaced candidates) that minimises
    ``cost`` (the env's, of a :class:`Metrics`) of the metrics predicted as above from ``metrics``
    of ``config`` on ``printer`` for ``job``. ``config.accel`` None means the printer's own."""
    a0 = float(config.accel or printer.limits.accel)
    lo, hi = accel_range
    grid = np.geomspace(lo, hi, n)
    costs = []
    for a in grid:
        t = planned_job(printer, job, dataclasses.replace(config, accel=float(a))).print_time
        scaled = {k: float(getattr(metrics, k)) * a / a0 for k in SCALED}
        costs.append(cost(dataclasses.replace(metrics, print_time_s=t, step_loss=False, **scaled,
                                              details=_scaled_details(metrics.details, a / a0, t))))
    costs = np.array(costs)
    if metrics.motor_load > 0:
        allowed = grid <= load_cap * a0 / metrics.motor_load
        allowed[0] = True              # the lowest candidate is always allowed
        costs = np.where(allowed, costs, np.inf)
    return float(grid[int(np.argmin(costs))])


def _scaled_details(details: dict, ratio: float, print_time_s: float) -> dict:
    """``details`` with each printer variant's own figures (``details["variants"]`` of a worst-case
    metrics object, which the cost compares variant by variant) predicted as the job's are: the
    :data:`SCALED` measures × ``ratio``, the print time ``print_time_s``; other details dropped."""
    variants = [{**d, "print_time_s": print_time_s, **{k: float(d[k]) * ratio for k in SCALED if k in d}}
                for d in (details or {}).get("variants", ())]
    return {"variants": variants} if variants else {}
