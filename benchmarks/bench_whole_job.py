"""Benchmark: do the quality windows' verdicts hold over the whole job?

``tune`` judges each configuration on the job's quality windows (a few seconds of it). This
simulates all of the job (:func:`ringtune.envs.whole_job.whole_job_metrics`: the exact linear
backend at 5 kHz, in pieces cut only where nothing is printed, each after six time constants of
the slowest mode) for the choice (``--config``, e.g. tune's best.json) and Klipper's pick as tune
judged it, and prints every visible measure (the job's and the outer wall's own) on the windows
and on the whole job, each with the verdict of the choice against the pick at the reports'
resolution (1 µm or 5 %; 1 percentage point or 5 % of extrusion). Both on the printer as modelled
(not its twins), both with the same exact backend, so what differs is only where is measured.

Run: ``python benchmarks/bench_whole_job.py --config out/best.json [--gcode part] [--printer P]``
"""

from __future__ import annotations

import argparse
import json
import time

from ringtune.agents.cli.simulate_config import freq_margin, max_path_error, motor_reserve
from ringtune.agents.tune.pareto import DEFAULT_RESOLUTION, metrics_dict, shown, verdict, words
from ringtune.agents.tune.versus import SHOWN, baseline_evaluations
from ringtune.envs.evaluate import evaluate_many
from ringtune.envs.planned_job import planned_job, resolve_printer, windows_sentence
from ringtune.envs.whole_job import whole_job_metrics
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
    windows = [metrics_dict(m) for m in evaluate_many([chosen, pick], printer, job, "lti", job_accel=mode)]
    print(f"  windows: {windows_sentence(planned_job(printer, job, chosen, job_accel=mode))}", flush=True)
    t1 = time.perf_counter()
    whole = [metrics_dict(whole_job_metrics(c, printer, job, job_accel=mode)) for c in (chosen, pick)]
    print(f"  whole job: {whole[0]['print_time_s']:.1f} s and {whole[1]['print_time_s']:.1f} s simulated "
          f"({time.perf_counter() - t1:.0f} s)")
    keys = [k for k in SHOWN if k != "print_time_s" and all(k in d for d in (*windows, *whole))]
    w = max(len(words(k)[0]) for k in keys) + 2
    print(f"  {'measure':<{w}}{'windows: choice':>16} {'pick':>10} {'verdict':<8}{'whole: choice':>14} "
          f"{'pick':>10} verdict")
    disagree, worse = [], []
    for k in keys:
        v_win = verdict(k, windows[0][k], windows[1][k], DEFAULT_RESOLUTION)
        v_all = verdict(k, whole[0][k], whole[1][k], DEFAULT_RESOLUTION)
        print(f"  {words(k)[0]:<{w}}{shown(k, windows[0][k]):>16} {shown(k, windows[1][k]):>10} {v_win:<8}"
              f"{shown(k, whole[0][k]):>14} {shown(k, whole[1][k]):>10} {v_all}")
        disagree += [k] if v_win != v_all else []
        worse += [k] if v_all == "worse" else []
    print(f"verdicts that differ between the windows and the whole job: {len(disagree)} of {len(keys)}"
          + (f" ({', '.join(words(k)[0] for k in disagree)})" if disagree else ""))
    print(f"measures worse than Klipper's pick over the whole job: {len(worse)} of {len(keys)}"
          + (f" ({', '.join(words(k)[0] for k in worse)})" if worse else ""))
    print(f"({time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
