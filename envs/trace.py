"""The simulated nozzle path of a job, as a CSV anyone can plot (``ringtune simulate --trace``).

Columns (one row per output sample, 2 kHz by default):

- ``t`` s since the job's first move;
- ``x_cmd, y_cmd, z`` the planned (G-code) path, mm, before input shaping;
- ``extruding`` 1 while the move deposits material, else 0;
- ``x_shaped, y_shaped`` the command after the config's input shaper (what the motors follow), mm;
  ``simulate`` applies the job's own shaper commands from where they stand;
- ``x_nozzle, y_nozzle`` the simulated nozzle relative to the print (bed frame), mm;
- ``window`` 0 for a whole-job trace; else the quality window's number (1, 2, ...).

A job whose motion lasts up to :data:`WHOLE_JOB_MAX_S` is simulated whole, from rest, with the
same printer, shapers and backend as the metrics; a longer one is traced over the quality windows
the metrics judged (said on stderr by the command).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ringtune.envs.planned_job import planned_job, resolve_printer
from ringtune.envs.sim import simulate
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.job_shapers import shape_timeline, shaper_timeline

#: longest motion (s) traced whole; longer jobs are traced over their quality windows
WHOLE_JOB_MAX_S = 600.0
COLUMNS = ("t", "x_cmd", "y_cmd", "z", "extruding", "x_shaped", "y_shaped", "x_nozzle", "y_nozzle", "window")


def _rows(path_motion, sim, window: int) -> np.ndarray:
    t = np.asarray(sim.t)
    cmd = path_motion.position(t)
    seg = path_motion.segment_index(t)
    inside = (t >= path_motion.start_time) & (t <= path_motion.end_time)
    ext = path_motion.extruding[seg] & inside
    return np.column_stack([t, cmd[:, 0], cmd[:, 1], cmd[:, 2], ext.astype(float),
                            sim.commanded[:, 0], sim.commanded[:, 1], sim.nozzle[:, 0], sim.nozzle[:, 1],
                            np.full(len(t), float(window))])


def trace_job(config: TuneConfig, printer, job=None, backend: str = "mujoco",
              job_shapers: bool = False) -> np.ndarray:
    """(m, len(COLUMNS)) rows of the whole job simulated from rest (see module doc); with
    ``job_shapers`` the job's own shaper commands apply where they stand."""
    printer = resolve_printer(printer)
    plan = planned_job(printer, job, config).plan
    motion = plan.motion
    timeline = shaper_timeline(plan.events, config) if job_shapers else [(-math.inf, config)]
    shaped = shape_timeline(motion, timeline)
    sim = simulate(printer, shaped, backend=backend, initial="rest")
    return _rows(motion, sim, 0)


def trace_windows(evaluation) -> np.ndarray:
    """Rows of the quality windows an :class:`ringtune.envs.evaluate.Evaluation` simulated."""
    parts = [_rows(run.path, sim, k) for k, (run, sim) in enumerate(zip(evaluation.runs, evaluation.sims), 1)]
    return np.concatenate(parts) if parts else np.zeros((0, len(COLUMNS)))


def write_trace(path: str | Path, rows: np.ndarray) -> None:
    """Write ``rows`` as CSV with the :data:`COLUMNS` header (mm and s to 1 µm / 1 µs)."""
    fmt = ["%.6f"] + ["%.5f"] * 3 + ["%d"] + ["%.5f"] * 4 + ["%d"]
    np.savetxt(path, rows, fmt=fmt, delimiter=",", header=",".join(COLUMNS), comments="")


def read_trace(path: str | Path) -> dict[str, np.ndarray]:
    """A trace CSV back as {column: array}."""
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return {c: data[:, i] for i, c in enumerate(COLUMNS)}
