"""``ringtune simulate --trace OUT.csv``: write the simulated nozzle path (see :mod:`ringtune.envs.trace`)."""

from __future__ import annotations

from ringtune.agents.cli.common import check_output_folder
from ringtune.envs import trace
from ringtune.envs.trace import trace_job, trace_windows, write_trace


def write_trace_option(path, evaluation, config, printer, gcode, backend: str, out) -> None:
    """The whole job traced from rest when its motion is short enough, else the quality windows
    ``evaluation`` simulated; says which on stderr."""
    check_output_folder("--trace", path)
    duration = evaluation.planned.motion.duration
    limit = trace.WHOLE_JOB_MAX_S        # read when called (a test may lower it)
    if duration <= limit:
        rows = trace_job(config, printer, gcode, backend, job_shapers=True)
        what = f"the whole job ({duration:.1f} s of motion, from rest)"
    else:
        rows = trace_windows(evaluation)
        what = (f"its {len(evaluation.runs)} quality windows (the job's {duration:.0f} s of motion is longer "
                f"than the {limit:.0f} s traced whole)")
    write_trace(path, rows)
    out.note(f"trace of {what}: {len(rows)} rows to {path}")
