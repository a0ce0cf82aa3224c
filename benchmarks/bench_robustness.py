"""Benchmark: a chosen configuration against Klipper's pick on printers beyond the ones it was judged on.

``tune`` judges each configuration on the printer as modelled and on two twins (every resonance
±5 %, every damping ratio ×0.75) and requires no visible measure worse on any of them. A real
printer, or another judge's physics, may sit further off. This simulates the choice (``--config``,
e.g. tune's best.json) and Klipper's pick from the printer's files on a grid of printers — every
mode's frequency × 0.85 … 1.15 and damping ratio × 0.5 … 1.5 — each on its own (no margin), and
counts, per visible measure (:data:`ringtune.agents.tune.versus.SHOWN`: the job's and the outer
wall's own), the printers on which the choice is worse than the pick at the reports' resolution
(1 µm or 5 %; 1 percentage point or 5 % of extrusion). On the three printers tune judged on (×1,
and ×0.95 and ×1.05 with damping ×0.75) a choice tune made has none; the others show how far the
guarantee carries beyond them.

Where Klipper's pick at its max_accel breaks a bound (step loss, the motor reserve, the path
error), tune judges it at the highest acceleration found within them; so does this benchmark, with
the reserve and bound best.json records (``--pick-accel`` sets another acceleration), since the
three judged printers are held to that pick, not to one tune rules out.

Run: ``python benchmarks/bench_robustness.py --config out/best.json [--gcode part] [--printer P] [--pick-accel A]``
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time

from ringtune.agents.cli.simulate_config import freq_margin, max_path_error, motor_reserve
from ringtune.agents.tune.baselines import baseline_configs
from ringtune.agents.tune.pareto import DEFAULT_RESOLUTION, metrics_dict, shown, verdict, words
from ringtune.agents.tune.versus import SHOWN, baseline_evaluations
from ringtune.envs.evaluate import evaluate_many
from ringtune.envs.planned_job import resolve_printer
from ringtune.envs.windows import auto_settle
from ringtune.shaping.builtin_jobs import job_path
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.config_plan import job_accel_mode

FREQS = (0.85, 0.9, 0.95, 1.0, 1.05, 1.1, 1.15)
DAMPINGS = (0.5, 0.75, 1.0, 1.5)
#: the printers tune judges on by default: the model and its twins (frequency, damping factors)
JUDGED = {(1.0, 1.0), (0.95, 0.75), (1.05, 0.75)}


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--config", required=True, help="the configuration to test (tune's best.json)")
    ap.add_argument("--gcode", default=None, help="job (default: the built-in test print; 'part': the built-in part)")
    ap.add_argument("--printer", default=None)
    ap.add_argument("--pick-accel", type=float, default=None,
                    help="mm/s²: Klipper's pick at this acceleration (default: as tune judged it — where at its "
                    "max_accel it breaks a bound, within the bounds best.json records)")
    args = ap.parse_args()
    t0 = time.perf_counter()
    printer = resolve_printer(args.printer)
    job = job_path(args.gcode) if args.gcode else None
    chosen = TuneConfig.from_dict(json.load(open(args.config)))
    if args.pick_accel:
        pick = dataclasses.replace(baseline_configs(printer, chosen.firmware).configs["klipper"], accel=args.pick_accel)
    else:       # as tune judged it: within the bounds best.json records
        pick = baseline_evaluations(printer, chosen.firmware, job, freq_margin=freq_margin(None, chosen),
                                    job_accel=job_accel_mode(chosen), motor_reserve=motor_reserve(chosen),
                                    max_path_error_mm=max_path_error(chosen), note=print)[0].configs["klipper"]
    keys = [k for k in SHOWN if k != "print_time_s"]
    settle = auto_settle(printer)
    worse: dict[str, list[str]] = {k: [] for k in keys}
    inside_worse = 0
    print(f"printer {printer.name}, job {args.gcode or 'built-in test print'}; the choice ({args.config}) against "
          f"Klipper's pick ({pick.shaper_x} @ {pick.freq_x:g} Hz / {pick.shaper_y} @ {pick.freq_y:g} Hz, "
          f"{pick.accel:g} mm/s²), each printer simulated on its own with the lead-in of the printer as modelled")
    for f in FREQS:
        for d in DAMPINGS:
            p = printer if (f, d) == (1.0, 1.0) else printer.detuned(f, d)
            mine, theirs = (metrics_dict(m) for m in evaluate_many([chosen, pick], p, job, settle=settle))
            inside = (f, d) in JUDGED
            bad = [k for k in keys if k in mine and k in theirs
                   and verdict(k, mine[k], theirs[k], DEFAULT_RESOLUTION) == "worse"]
            for k in bad:
                worse[k].append(f"×{f:g}/ζ×{d:g}: {shown(k, mine[k])} against {shown(k, theirs[k])}")
            inside_worse += bool(bad) and inside
            print(f"  resonances ×{f:<4g} damping ×{d:<4g} {'(judged on)' if inside else '           '} "
                  f"worse on: {', '.join(words(k)[0] for k in bad) or 'nothing'}", flush=True)
    n = len(FREQS) * len(DAMPINGS)
    total = sum(len(v) for v in worse.values())
    print(f"worse than Klipper's pick at the resolution: {total} of {n * len(keys)} (printer, measure) pairs; "
          f"of the {len(JUDGED)} printers tune judged on, with any measure worse: {inside_worse} (expected 0)")
    for k, where in worse.items():
        if where:
            print(f"  {words(k)[0]}: {len(where)} of {n} printers — " + "; ".join(where))
    print(f"({time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
