"""``ringtune tune``: the main job — an Optuna Pareto study of print time against quality.

``--json`` keys (stable): out, trials, front_size, quality, max_path_error_mm, freq_margin, chosen {config, print_time_s,
quality_mm, chosen_by}, baselines {klipper|none: {config, print_time_s, quality_mm, step_loss}},
vs_baselines {klipper|none: {baseline, faster_s, faster_pct, better_mm, better_pct, dominates}},
dominates_klipper (null or {config, print_time_s, quality_mm, faster_s, ...}), files {readme,
summary, plot, best, apply, front, trials}, storage, study, completed_now, interrupted, elapsed_s.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

NAME = "tune"
HELP = "find the best print-time / quality trade-offs (Optuna Pareto study) — the main job"
DESCRIPTION = """\
Tune input shaping for a printer and a job: an Optuna multi-objective study over the shaper types
the target firmware offers, the shaper frequency F per axis (one F on RepRapFirmware), the damping
S, the infill frequency limit and its method, and the acceleration. Each trial is simulated; a
configuration that loses steps, or whose nozzle leaves the path by more than --max-path-error
(0.1 mm by default: heavy smoothing cuts corners inwards, which overshoot alone would not see), is
ruled out. Every configuration is judged on the printer and on the printer with all resonances
--freq-margin per cent lower and higher (default 5): the worst quality counts, because a real
printer's frequencies drift, and a shaper at the edge of its band on the exact model does not
survive that. The result is the whole trade-off (Pareto front),
the configuration to use (the knee, or the one minimising print time + W × error with --weight W),
and how it compares with Klipper's own rule and with no shaping on the same printer and job.

With no arguments it tunes the built-in Ender-3-class printer on the built-in test print into
./ringtune-out/ in about a minute; open ringtune-out/README.txt first. Running the same command
again resumes the study (also after Ctrl-C or a crash); --trials N extends it to N trials.

examples:
  ringtune tune
  ringtune tune --printer my-printer.toml --gcode benchy.gcode --firmware rrf --trials 400 --workers 2
  ringtune tune --storage postgresql+psycopg2://user:pw@db-host/ringtune --study ender3 --workers 4
"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--printer", metavar="P", help="printer TOML (default: the embedded Ender-3-class printer)")
    p.add_argument("--gcode", metavar="G", help="G-code job (default: the built-in test print)")
    p.add_argument("--firmware", default="klipper", help="target firmware: klipper (default), rrf, rrf35, "
                   "marlin, marlin-ftm, prusa")
    p.add_argument("--trials", type=int, default=200, help="total complete trials of the study (default 200)")
    p.add_argument("--storage", metavar="URL", help="Optuna storage: journal:PATH (default "
                   "journal:OUT/study.journal), sqlite:///file.db, postgresql+psycopg2://user:pw@host/db")
    p.add_argument("--study", default="ringtune", metavar="NAME", help="study name in the storage (default ringtune)")
    p.add_argument("--workers", type=int, default=1, help="local worker processes (default 1; seeded "
                   "single-worker runs reproduce exactly)")
    p.add_argument("--seed", type=int, default=0, help="sampler seed (default 0)")
    p.add_argument("--out", default="ringtune-out", metavar="DIR", help="output folder (default ringtune-out)")
    p.add_argument("--weight", type=float, default=None, metavar="W",
                   help="choose the point minimising print time + W × error (W in s/mm); default: the knee")
    p.add_argument("--quality", choices=("overshoot", "path_error"), default="overshoot",
                   help="quality objective: overshoot_mm (default) or path_error_mm")
    p.add_argument("--max-path-error", type=float, default=None, metavar="MM",
                   help="rule out configurations whose path error (corner rounding, overshoot and ringing) "
                        "exceeds MM (default 0.1; 0 = no bound)")
    p.add_argument("--freq-margin", type=float, default=None, metavar="PCT",
                   help="also judge every configuration with the printer's resonances PCT %% lower and "
                        "higher; the worst quality counts (default 5; 0 = the exact model only)")
    p.add_argument("--backend", choices=("mujoco", "lti"), default="mujoco", help="physics (default mujoco)")
    p.add_argument("--evaluator", metavar="MODULE:FUNC", default=None,
                   help="advanced: score configs with your own f(configs, printer, job) -> metrics")
    p.add_argument("--no-baselines", action="store_true", help="skip Klipper's rule and no-shaping baselines")


def run(args: argparse.Namespace, out) -> int:
    from ringtune.agents import pareto, report, storage, tune_study
    from ringtune.agents.space import default_space, params_from_config
    from ringtune.envs.evaluate import resolve_printer
    from ringtune.shaping.config import TuneConfig
    from ringtune.shaping.errors import RingtuneError

    t_start = time.time()
    if args.trials < 1:
        raise RingtuneError("must be ≥ 1", "--trials")
    if args.workers < 1:
        raise RingtuneError("must be ≥ 1", "--workers")
    if args.weight is not None and not args.weight >= 0:
        raise RingtuneError("must be ≥ 0 (seconds per mm)", "--weight")
    max_pe = pareto.DEFAULT_MAX_PATH_ERROR_MM if args.max_path_error is None else args.max_path_error
    if not max_pe >= 0:
        raise RingtuneError("must be ≥ 0 (mm; 0 = no bound)", "--max-path-error")
    margin = tune_study.DEFAULT_FREQ_MARGIN if args.freq_margin is None else args.freq_margin / 100.0
    if not 0 <= margin < 0.5:
        raise RingtuneError("must be in [0, 50) per cent", "--freq-margin")
    if args.gcode and not Path(args.gcode).is_file():
        raise RingtuneError("no such G-code file", "--gcode")
    out_dir = Path(args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    printer = resolve_printer(args.printer)
    quality = f"{args.quality}_mm"
    space = default_space(printer, args.firmware)
    storage = args.storage or storage.default_storage(out_dir)
    settings = tune_study.StudySettings(
        storage=storage, study_name=args.study, n_trials=args.trials, seed=args.seed, quality=quality,
        printer=str(Path(args.printer).resolve()) if args.printer and Path(args.printer).exists() else args.printer,
        job=str(Path(args.gcode).resolve()) if args.gcode else None, firmware=args.firmware,
        backend=args.backend, evaluator=args.evaluator or tune_study.DEFAULT_EVALUATOR, space=space.to_dict(),
        max_path_error_mm=max_pe, freq_margin=margin)
    evaluator = tune_study.resolve_evaluator(settings.evaluator)

    baselines: dict[str, pareto.Point] = {}
    if not args.no_baselines:
        baselines, fits = _baselines(printer, args, settings, evaluator, quality, out)
        k = baselines.get("klipper")
        if k is not None:   # start the search from what users do today, and its neighbours
            settings.enqueue = [params_from_config(c, space) for c in _warm_start(k.config, fits, space)]

    bar = _progress_bar(out)
    try:
        run_ = tune_study.run_study(settings, args.workers, printer=printer, progress=bar.update)
    finally:
        bar.close()
    st = run_.study
    points = tune_study.study_points(st, space, quality, max_pe)
    front = pareto.pareto_front(points)
    chosen = pareto.choose(front, args.weight)
    result = report.write_report(
        out_dir, points=points, front=front, chosen=chosen, baselines=baselines, quality=quality,
        printer_name=getattr(printer, "name", "printer"), job_name=Path(args.gcode).name if args.gcode else
        "built-in test print", firmware=args.firmware, n_trials=args.trials, storage=storage,
        study_name=args.study, weight=args.weight, command=_command_line(args), max_path_error_mm=max_pe,
        notes=([f"Quality is the worst of the printer as modelled and with all its resonances {margin * 100:g} % "
                "lower and higher (--freq-margin): what survives a real printer's drift."] if margin else [])
        + ([f"The search was warm-started from Klipper's recommendation and {len(settings.enqueue) - 1} "
            "neighbours of it (robust shapers at Klipper's own frequencies, higher accelerations)."]
           if settings.enqueue else []))
    text = result.pop("summary_text")
    result.update({"freq_margin": margin, "storage": storage, "study": args.study, "completed_now": run_.completed_now,
                   "interrupted": run_.interrupted, "elapsed_s": time.time() - t_start})
    lines = [text.rstrip("\n"), "", f"Results in {out_dir}/ — open {out_dir / 'README.txt'} first."]
    if run_.interrupted:
        lines.append(f"Interrupted after {run_.completed_before + run_.completed_now} complete trials; "
                     "run the same command again to resume.")
    out.emit(result, "\n".join(lines))
    return 130 if run_.interrupted else 0


def _warm_start(kcfg, fits, space) -> list:
    """Klipper's pick at its max_accel and 1.25×, 1.5× it; the robust EI family at Klipper's own
    per-shaper frequencies, at its max_accel, 1.25× it and the top of the range (only points inside
    the space)."""
    import dataclasses

    def at(cfg, factor):
        a = min(space.accel[1], round(kcfg.accel * factor / space.accel_step) * space.accel_step)
        return dataclasses.replace(cfg, accel=float(a), extra={})

    out = [at(kcfg, 1.0), at(kcfg, 1.25), at(kcfg, 1.5)]
    for name in ("ei", "2hump_ei", "3hump_ei"):
        freqs = {}
        for ax in ("x", "y"):
            rec = fits.get(ax) if fits else None
            row = next((f for f in rec.shapers if f.name == name), None) if rec else None
            if row is not None:
                freqs[ax] = round(row.freq, 1)
        if len(freqs) == 2 and name in space.shapers:
            fy = freqs["y"] if space.per_axis else freqs["x"]
            cfg = dataclasses.replace(kcfg, shaper_x=name, shaper_y=name, freq_x=freqs["x"], freq_y=fy, extra={})
            out += [at(cfg, 1.0), at(cfg, 1.25), at(cfg, space.accel[1] / kcfg.accel)]
    seen, unique = set(), []
    for c in out:
        key = (c.shaper_x, c.freq_x, c.shaper_y, c.freq_y, c.accel)
        if key not in seen and _inside(c, space):
            seen.add(key)
            unique.append(c)
    return unique


def _inside(cfg, space) -> bool:
    ok = space.accel[0] <= (cfg.accel or 0) <= space.accel[1]
    for ax in ("x", "y"):
        name, f, _ = cfg.axis(ax)
        lo, hi = getattr(space, f"freq_{ax}")
        ok &= name == "none" or (name in space.shapers and lo <= f <= hi)
    return bool(ok) and (space.per_axis or cfg.shaper_x == cfg.shaper_y)


def _baselines(printer, args, settings, evaluator, quality, out) -> dict:
    """Klipper's rule (on the printer's simulated resonance test, at its suggested max_accel) and
    no shaping (the printer's own acceleration), evaluated like every trial."""
    from ringtune.agents import klipper_baseline, tune_study
    from ringtune.agents.pareto import point_from_metrics
    from ringtune.shaping.config import TuneConfig
    from ringtune.shaping.errors import RingtuneError

    configs, fits = {}, {}
    try:
        fits, fields = klipper_baseline.recommend_for_printer(printer, args.firmware, "head", seed=args.seed)
        if fields.get("accel") is None:
            fields["accel"] = float(printer.limits.accel)
        configs["klipper"] = TuneConfig(**fields, extra={"source": "Klipper's calibrate_shaper rule (HEAD)"})
    except (ImportError, RingtuneError) as exc:
        out.note(f"ringtune tune: Klipper's-rule baseline skipped: {exc}")
    configs["none"] = TuneConfig(firmware=args.firmware, shaper_x="none", shaper_y="none", freq_x=0.0, freq_y=0.0,
                                 accel=float(printer.limits.accel), extra={"source": "no shaping"})
    metrics = evaluator(list(configs.values()), printer, settings.job, **tune_study.evaluator_kwargs(settings))
    points = {key: point_from_metrics(cfg, m, quality, label=key, max_path_error_mm=settings.max_path_error_mm)
              for (key, cfg), m in zip(configs.items(), metrics)}
    return points, fits


class _Bar:
    def __init__(self, out):
        self._bar = None
        self._out = out

    def update(self, done: int, total: int) -> None:
        import sys

        if self._bar is None:
            from tqdm import tqdm

            self._bar = tqdm(total=total, initial=min(done, total), desc="trials", unit="trial",
                             file=sys.stderr, dynamic_ncols=True, disable=None)
        delta = min(done, total) - self._bar.n
        if delta > 0:
            self._bar.update(delta)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()


def _progress_bar(out) -> _Bar:
    return _Bar(out)


def _command_line(args) -> str:
    parts = ["ringtune tune"]
    for opt in ("printer", "gcode", "firmware", "storage", "out"):
        v = getattr(args, opt)
        if v and not (opt == "firmware" and v == "klipper") and not (opt == "out" and v == "ringtune-out"):
            parts.append(f"--{opt} {v}")
    return " ".join(parts)
