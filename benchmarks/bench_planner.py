"""Planner speed on the ianalexis ringing tower (acceptance 7), on one core.

Prints, measured in one run: the cost of merely reading the file (``read_gcode``), planning it under
each junction rule (moves per second, target ≥ 100,000), and a plain Python per-move look-ahead
(forward + backward pass and trapezoid times, the loop a firmware runs) as the baseline.

    /work/venv/bin/python benchmarks/bench_planner.py
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import math  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

TARGET = 100_000
FILE = Path(__file__).resolve().parents[1] / "tests/data/gcode/ianalexis_ender3_marlin/ringing_tower.gcode"


def best_of(fn, repeat=5):
    """Best CPU time of ``repeat`` runs (process time: robust to other jobs on a shared machine;
    numpy is held to one thread above, so this is one core's work)."""
    best = math.inf
    out = None
    for _ in range(repeat):
        t = time.process_time()
        out = fn()
        best = min(best, time.process_time() - t)
    return best, out


def python_loop_plan(job, accel=1500.0):
    """Baseline: a per-move Python look-ahead (junction speeds 0 as with this file's jerk 0)."""
    import numpy as np

    d_all = np.linalg.norm((job.end - job.start)[:, :3], axis=1).tolist()
    feed = job.feed.tolist()
    n = len(d_all)
    v2 = [0.0] * (n + 1)
    for i in range(n):                                   # forward
        v2[i + 1] = min(feed[i] ** 2, v2[i] + 2 * accel * d_all[i], 0.0 if i + 1 == n else feed[i + 1] ** 2)
    for i in range(n - 1, -1, -1):                       # backward
        v2[i] = min(v2[i], v2[i + 1] + 2 * accel * d_all[i])
    total = 0.0
    for i in range(n):                                   # trapezoids
        d = d_all[i] if d_all[i] > 0 else 1e-9
        s, e = math.sqrt(v2[i]), math.sqrt(v2[i + 1])
        c = math.sqrt(min(feed[i] ** 2, (v2[i] + v2[i + 1] + 2 * accel * d) / 2))
        da, dd = (c * c - s * s) / (2 * accel), (c * c - e * e) / (2 * accel)
        total += (c - s) / accel + (c - e) / accel + max(d - da - dd, 0) / c
    return total


def main() -> None:
    from ringtune.shaping.gcode import read_gcode
    from ringtune.shaping.planner import MachineLimits, plan

    if not FILE.is_file():
        print(f"missing {FILE}")
        return
    t_read, job = best_of(lambda: read_gcode(FILE), repeat=3)
    n = job.n_moves
    lines = job.n_lines
    print(f"file: {FILE.name} ({lines} lines, {n} moves)")
    print(f"read_gcode:            {t_read * 1e3:8.1f} ms  ({lines / t_read:,.0f} lines/s, {n / t_read:,.0f} moves/s)")
    ok = True
    for junction in ("jerk", "jd", "scv"):
        lim = MachineLimits(junction=junction, min_cruise_ratio=0.5 if junction == "scv" else 0.0)
        t_plan, p = best_of(lambda: plan(job, lim))
        rate = n / t_plan
        ok &= rate >= TARGET
        print(f"plan ({junction:4s}):           {t_plan * 1e3:8.1f} ms  ({rate:,.0f} moves/s; "
              f"{t_plan / t_read:.2f} x the read cost; print time {p.print_time:.0f} s)")
    t_daa, _ = best_of(lambda: plan(job, MachineLimits(junction="jerk"), daa_freq=40.0))
    print(f"plan (jerk + DAA):     {t_daa * 1e3:8.1f} ms  ({n / t_daa:,.0f} moves/s)")
    t_loop, _ = best_of(lambda: python_loop_plan(job), repeat=3)
    print(f"baseline Python loop:  {t_loop * 1e3:8.1f} ms  ({n / t_loop:,.0f} moves/s; "
          f"forward/backward/trapezoid only, no junction rule)")
    print(f"target >= {TARGET:,} moves/s on one core: {'MET' if ok else 'NOT MET'}")


if __name__ == "__main__":
    main()
