"""Benchmark: do the quality windows' verdicts hold over the whole job?

``tune`` judges each configuration on the job's quality windows (a few seconds of it). This
simulates all of the job for the choice (``--config``, e.g. tune's best.json) and Klipper's pick as
tune judged it, and prints every visible measure (the job's and the outer wall's own) on the windows
and over the whole job, each with the verdict of the choice against the pick
(:mod:`ringtune.agents.tune.whole_job_check`: the exact linear backend, the printer as modelled, so
what differs is only where is measured). ``ringtune simulate --whole-job`` prints the same table.

Run: ``python benchmarks/bench_whole_job.py --config out/best.json [--gcode part] [--printer P]``
"""

from __future__ import annotations

import argparse
import json
import time

from ringtune.agents.cli.simulate_config import freq_margin, max_path_error, motor_reserve
from ringtune.agents.tune.versus import baseline_evaluations
from ringtune.agents.tune.whole_job_check import whole_job_check
from ringtune.envs.planned_job import resolve_printer
from ringtune.shaping.builtin_jobs import job_path
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.config_plan import job_accel_mode


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--config", required=True, help="the configuration to test (tune's best.json)")
    ap.add_argument("--gcode", default=None, help="job (default: the built-in test print; 'part': the built-in part)")
    ap.add_argument("--printer", default=None)
    args = ap.parse_args()
    t0 = time.perf_counter()
    printer = resolve_printer(args.printer)
    job = job_path(args.gcode) if args.gcode else None
    chosen = TuneConfig.from_dict(json.load(open(args.config)))
    mode = job_accel_mode(chosen)
    pick = baseline_evaluations(printer, chosen.firmware, job, freq_margin=freq_margin(None, chosen),
                                job_accel=mode, motor_reserve=motor_reserve(chosen),
                                max_path_error_mm=max_path_error(chosen), note=print)[0].configs["klipper"]
    print(f"printer {printer.name}, job {args.gcode or 'built-in test print'}; the choice ({args.config}) against "
          f"Klipper's pick ({pick.shaper_x} @ {pick.freq_x:g} Hz / {pick.shaper_y} @ {pick.freq_y:g} Hz, "
          f"{pick.accel:g} mm/s²); the printer as modelled, the exact linear backend")
    check = whole_job_check(chosen, printer, job, pick, job_accel=mode)
    print(f"  {check.where}")
    print(f"  whole job: {check.whole[0]['print_time_s']:.1f} s and {check.whole[1]['print_time_s']:.1f} s "
          f"simulated ({check.seconds:.0f} s)")
    print("\n".join(check.table("choice", "Klipper's pick")))
    print(f"({time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
