"""Benchmark: ``ringtune tune --trials 200`` on the default printer — time and convergence.

Targets (DESIGN.md, issue 21): the whole command ≤ 30 s on 2 cores; the choice's print time and
every visible measure against Klipper's pick (the same simulation); its best objective within 1 % of
a dense grid's (``--grid``). "Objective" is the scalar the user's ``--weight`` W picks by, J = print_time_s + W ·
overshoot_mm (W in s/mm; printed for two W), best feasible point of each (no step loss, path error
within the study's bound, 0.1 mm by default); the hypervolume ratio of the two fronts is printed as
well. The grid spans the same space (agents.tune.grid.grid_params: every shaper on each axis × F levels
per axis, S levels, acceleration levels over the whole range, frequency limit off; the study may
also use a frequency limit, which only slows the print on this job).

Run: ``python benchmarks/bench_tune.py [--trials 200] [--workers 2] [--grid-freqs 5] [--grid-accels 6]``

``--gcode JOB`` (issue 22: real jobs are fast to tune): ``tune --gcode JOB`` with the same trials
and workers after the built-in print's run, its wall time against the target (≤ 30 s on 2 cores)
and its ratio to the built-in print's, measured in the same run; no grid.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path



def run_tune(args, prefix: str, *extra: str):
    """(the ``--json`` result, wall time s, output folder) of ``ringtune tune`` with the benchmark's trials and
    workers (and ``extra`` options) in a fresh folder; (None, wall, folder) after printing its error."""
    out = Path(tempfile.mkdtemp(prefix=prefix))
    cmd = [sys.executable, "-m", "ringtune.agents.cli.main", "tune", *extra, "--trials", str(args.trials),
           "--workers", str(args.workers), "--out", str(out), "--json"]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        print(proc.stderr[-2000:])
        return None, wall, out
    return json.loads(proc.stdout), wall, out

def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--trials", type=int, default=200)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--grid-freqs", type=int, default=5, help="F levels per axis and shaper")
    ap.add_argument("--grid-dampings", default="0.1", help="S levels of the grid (comma list)")
    ap.add_argument("--grid-accels", type=int, default=6, help="acceleration levels spread evenly over the "
                    "whole range (default 6)")
    ap.add_argument("--weights", default="20,100", help="W values, s/mm")
    ap.add_argument("--skip-grid", action="store_true", help="(the default) no grid comparison")
    ap.add_argument("--grid", action="store_true", help="also run the dense grid (slow: tens of minutes)")
    ap.add_argument("--gcode", default=None, help="also tune this sliced job and print the ratio to the built-in print")
    args = ap.parse_args()

    from ringtune.agents.tune.grid import hypervolume, run_grid
    from ringtune.agents.tune.grid import grid_params
    from ringtune.agents.tune.space import SearchSpace
    from ringtune.agents.tune.pareto import pareto_front, scalar_objective
    from ringtune.agents.tune.study import StudySettings, open_study
    from ringtune.agents.tune.study_results import study_points
    from ringtune.envs.printer import load_printer

    res, wall, out = run_tune(args, "bench-tune-")
    if res is None:
        return 1
    cpu = _children_cpu()
    print(f"ringtune tune --trials {args.trials} --workers {args.workers}: {wall:.1f} s wall on "
          f"{os.cpu_count()} cores (target ≤ 30 s): {'PASS' if wall <= 30 else 'FAIL'}; "
          f"load average {os.getloadavg()[0]:.1f} at the end (other work shares the cores); CPU time of the "
          f"command and its workers {cpu:.1f} s (÷ {os.cpu_count()} = {cpu / os.cpu_count():.1f} s: the wall time on idle cores if "
          "both stayed busy)")
    print(f"  {_steps(res)}")
    vs = res.get("versus", {}).get("klipper")
    if vs:
        print(f"  chosen ({res['chosen']['chosen_by']}) against Klipper's pick, same simulation: "
              + "; ".join(f"{k} {v['value']:.4g} vs {v['baseline']:.4g} {v['verdict']}" for k, v in vs.items()))
    if res.get("stop"):
        print(f"  {res['stop']['sentence']}")
    dk = res.get("dominates_klipper")
    if dk:
        print(f"  front point dominating Klipper's rule: {dk['faster_s']:.3f} s faster ({dk['faster_pct']:.1f} %), "
              f"{dk['better_mm'] * 1000:.1f} µm less {res['quality'].removesuffix('_mm').replace('_', ' ')} "
              f"({dk['better_pct']:.1f} %), no visible measure worse")
    else:
        print("  no front point dominates Klipper's rule")
    if args.gcode:
        return _job_run(args, wall)
    if args.skip_grid or not args.grid:
        return 0

    printer = load_printer(None)
    settings = StudySettings(storage=res["storage"] if res["storage"].startswith(("journal:", "sqlite", "postgres"))
                             else f"journal:{out / 'study.journal'}", study_name=res["study"])
    study = open_study(StudySettings(**{**settings.to_dict(), **_stored(settings)}))
    space = SearchSpace.from_dict(study.user_attrs["settings"]["space"])
    pts = study_points(study, space)
    import numpy as np

    top = [float(a) for a in np.linspace(space.accel[0], space.accel[1], args.grid_accels)]
    zs = tuple(float(z) for z in args.grid_dampings.split(","))
    params = grid_params(space, n_freq=args.grid_freqs, dampings=zs, accels=tuple(top))
    t1 = time.perf_counter()
    margin = float(study.user_attrs["settings"].get("freq_margin", 0.0))
    grid = run_grid(space, printer=printer, params=params, batch=128, freq_margin=margin)
    tg = time.perf_counter() - t1
    print(f"dense grid: {len(grid)} points in {tg:.0f} s ({1000 * tg / len(grid):.0f} ms/point); accelerations "
          f"{top}, {args.grid_freqs} F per axis and shaper, S {zs}; resonances ±{100 * margin:g} % (damping ×0.75) as in the study")
    ok = True
    for w in (float(x) for x in args.weights.split(",")):
        bs = min((p for p in pts if p.feasible), key=lambda p: scalar_objective(p, w))
        bg = min((p for p in grid if p.feasible), key=lambda p: scalar_objective(p, w))
        js, jg = scalar_objective(bs, w), scalar_objective(bg, w)
        gap = 100.0 * (js - jg) / jg
        ok &= gap <= 1.0
        print(f"  W = {w:g} s/mm: study best J = {js:.4f} s, grid best J = {jg:.4f} s, study − grid = {gap:+.2f} % "
              f"(target ≤ +1 %): {'PASS' if gap <= 1.0 else 'FAIL'}")
    fs, fg = pareto_front(pts), pareto_front(grid)
    ref = (max(p.print_time_s for p in fs + fg) * 1.05, max(p.quality_mm for p in fs + fg) * 1.05)
    print(f"  hypervolume study/grid = {hypervolume(fs, ref) / hypervolume(fg, ref):.3f} "
          f"(fronts of {len(fs)} and {len(fg)} points; study {len(pts)} evaluations, grid {len(grid)})")
    print("convergence:", "PASS" if ok else "FAIL")
    return 0


def _job_run(args, builtin_wall: float) -> int:
    """``tune --gcode JOB``: wall time, its target and its ratio to the built-in print's run."""
    from ringtune.envs.planned_job import planned_job
    from ringtune.envs.printer import load_printer

    planned = planned_job(load_printer(None), args.gcode, None).print_time
    before = _children_cpu()
    res, wall, _ = run_tune(args, "bench-tune-job-", "--gcode", args.gcode)
    if res is None:
        return 1
    cpu, cores = _children_cpu() - before, os.cpu_count() or 1
    pf = res.get("per_feature") or {}
    print(f"ringtune tune --gcode {args.gcode} ({planned / 60:.1f} min planned on the default printer) "
          f"--trials {args.trials} --workers {args.workers}: {wall:.1f} s wall (target ≤ 30 s): "
          f"{'PASS' if wall <= 30 else 'FAIL'}; {wall / builtin_wall:.2f}× the built-in print's {builtin_wall:.1f} s "
          f"in this run; CPU time of the command and its workers {cpu:.1f} s (÷ {cores} = {cpu / cores:.1f} s: the "
          f"wall time if every core stayed busy; the rest, {wall - cpu / cores:.1f} s, is a core waiting); "
          f"per feature: {pf.get('accel') or 'off'}")
    print(f"  {_steps(res)}")
    return 0


def _steps(res: dict) -> str:
    """Each step's wall-clock seconds, as tune measured them (``timings_s`` of its ``--json``)."""
    laps = res.get("timings_s") or {}
    parts = laps.get("refine_parts") or {}
    top = ", ".join(f"{k.removesuffix('_s')} {v:.1f}" for k, v in laps.items() if k != "refine_parts")
    inner = ", ".join(f"{k.removesuffix('_s')} {v:.1f}" for k, v in parts.items())
    return f"steps (s, tune's own clock, of its {res.get('elapsed_s', float('nan')):.1f} s): {top}" + (
        f"; after the study: {inner}" if inner else "")


def _children_cpu() -> float:
    """CPU seconds (user + system) of this process's finished children so far."""
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def _stored(settings) -> dict:
    """The study's own settings (so open_study accepts it)."""
    import optuna

    from ringtune.agents.tune.storage import make_storage

    st = optuna.load_study(study_name=settings.study_name, storage=make_storage(settings.storage))
    s = dict(st.user_attrs["settings"])
    s.pop("enqueue", None)
    return s


if __name__ == "__main__":
    sys.exit(main())
