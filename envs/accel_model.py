"""The acceleration one simulation suggests: scale a configuration's metrics with acceleration.

On the linear printer every deviation of the nozzle from its path is proportional to the commanded
acceleration (the planner's velocity profile changes too, so this is a first-order model), and so
is the force the motors must give. One evaluation of a configuration at acceleration ``a0`` then
predicts its cost at any other acceleration ``a``:

    cost(a) ≈ w_time · T(a)/T0 + (w_path·path_error + w_over·overshoot + w_ring·ringing) · a/a0

with the print time ``T(a)`` exact from the planner, and its motor load as ``load0 · a/a0``. The
anchor is the ``a`` that minimises this cost among those whose predicted load stays at or below
``load_cap`` (default 0.7: a 30 % force reserve for what the linear scaling misses: the
force's fall with speed, resonant overshoot of the belts). It is what an engineer reads off one
test print ("it rings this much and uses this much of its motor at 4000; how hard can I drive it?"),
and it is the physical anchor around which the PPO policy decides the acceleration
(``ActionSpec.accel_anchor = "model"``).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ringtune.envs.evaluate import planned_job
from ringtune.envs.metrics import Metrics
from ringtune.shaping.config import TuneConfig

#: fraction of the motor's force the anchor may plan to use
LOAD_CAP = 0.7


def model_accel(printer, job, config: TuneConfig, metrics: Metrics, weights: dict, baseline_s: float,
                accel_range: tuple[float, float], load_cap: float = LOAD_CAP, n: int = 33) -> float:
    """mm/s²: the acceleration within ``accel_range`` (``n`` log-spaced candidates) that minimises
    the first-order cost model above, given ``metrics`` of ``config`` on ``printer`` for ``job``
    (``weights`` as the env's reward: keys time, path_error, overshoot, ringing; ``baseline_s`` the
    print time T0 the time ratio divides by). ``config.accel`` None means the printer's own."""
    a0 = float(config.accel or printer.limits.accel)
    lo, hi = accel_range
    grid = np.geomspace(lo, hi, n)
    times = np.array([planned_job(printer, job, dataclasses.replace(config, accel=float(a))).print_time
                      for a in grid])
    quality = (weights["path_error"] * metrics.path_error_mm + weights["overshoot"] * metrics.overshoot_mm
               + weights["ringing"] * metrics.ringing_mm)
    cost = weights["time"] * times / baseline_s + quality * grid / a0
    if metrics.motor_load > 0:
        allowed = grid <= load_cap * a0 / metrics.motor_load
        allowed[0] = True              # the lowest candidate is always allowed
        cost = np.where(allowed, cost, np.inf)
    return float(grid[int(np.argmin(cost))])
