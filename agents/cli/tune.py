"""``ringtune tune``: the main job — an Optuna Pareto study of print time against quality.

``--json`` keys (stable): out, trials, front_size, quality, max_path_error_mm, motor_reserve,
max_show_through_mm, freq_margin, resolution {distance_mm, distance_rel, time_rel, pct_abs},
chosen {config, print_time_s, quality_mm, path_error_mm, overshoot_mm, motor_load, measures (every
metrics figure: ripple_mm, ripple_p90_mm, corner_in_mm, corner_out_mm, extrusion_over_pct,
extrusion_under_pct, e_lag_mm, show_through_mm, ...), chosen_by, against (the baseline it is at least
as fast as), held_to (every baseline it has no visible measure worse than), why, rewrite_jobs (the
`ringtune limit` command every job needs, or null)}, baselines
{klipper|current|none: {config, print_time_s, quality_mm, path_error_mm, overshoot_mm, motor_load,
measures, step_loss, breaks, label, source}}, versus {baseline: {print_time_s|ripple_mm|ripple_p90_mm|
corner_in_mm|corner_out_mm|extrusion_over_pct|extrusion_under_pct: {value, baseline, verdict
better|same|worse}}}, stop (null, or the measured stop: {kind measure|bound|ceiling|time|budget|not
searched, key, baseline (whose value it exceeds, for a measure), value, baseline_value, accel (the step that stops it, mm/s²), config, moved,
from_accel, to_accel, evaluations, sentence}), vs_baselines {key: {baseline, faster_s, faster_pct, better_mm,
better_pct, dominates, metrics {print_time_s|overshoot_mm|path_error_mm|feasible: better|same|worse},
path_error_better_mm, path_error_better_pct}}, dominates_klipper, dominates_current (null or {config,
print_time_s, quality_mm, ...comparison}), accel {range, searched, basis, chosen, stopped_by,
headroom, defaults (what of the motor bound is a default: "x.mass", "y.motor", ...; [] when none),
binding (the firmware limits that hold some moves of the chosen configuration lower: list of {name
(the firmware's own: "M201 X", "max_y_accel", "M204 R"), value (mm/s²), what, moves, time_s,
time_without_s (the planner with that limit removed)})},
job_accel {mode, commands, cap_mm_s2, searched, print_time_as_sliced_s, print_time_replaced_s,
replaced_accel, saved_s}, per_feature (null when not searched, else {accel {visible|hidden_walls|
infill|solid_top|travel: mm/s²}, ranges {group: {top_speed_mm_s, range, basis}}, corner, junction,
min_cruise_ratio, why (why it was searched)}), plot_arrows, files {readme, summary, plot, best, apply,
front, trials, job (with --gcode: the rewritten job)}, storage, study, completed_now, interrupted,
elapsed_s.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import tempfile
import time
from pathlib import Path

from tqdm import tqdm

from ringtune.agents.cli.common import (GCODE_JOB_HELP, firmware_name, gcode_job,
                                       progress_interval, say_unmeasured)
from ringtune.agents.tune import pareto, report, storage, study as tune_study
from ringtune.agents.tune.baselines import baselines_for, inside, warm_start
from ringtune.agents.tune import feature_space
from ringtune.agents.tune.binding import binding_limits, binding_sentences
from ringtune.agents.tune.job import accel_statement, job_accel_facts, job_accel_section
from ringtune.agents.tune.pareto import VISIBLE_KEYS, pareto_front
from ringtune.agents.tune.space import default_space, freq_floor_note, params_from_config, top_speed_load_note
from ringtune.agents.tune.stop import Bounds, measured_stop
from ringtune.agents.tune.study import study_points
from ringtune.envs.evaluate import resolve_printer
from ringtune.envs.job_rewrite import rewrite_file
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.firmware import Firmware
from ringtune.shaping.wall_gap import show_through_bound

NAME = "tune"
DESCRIPTION = """\
Tune input shaping for a printer and a job: an Optuna multi-objective study over the shaper types
the target firmware offers, the shaper frequency F per axis (one F on RepRapFirmware), the damping
S, the infill frequency limit and its method, and the acceleration. Each trial is simulated; a
configuration is ruled out when it loses steps, when its nozzle leaves the path by more than
--max-path-error (0.1 mm by default: heavy smoothing cuts corners inwards, which overshoot alone
would not see), or when it asks a motor for more than 1 − --motor-reserve of the force it has at
its speed (80 %: modelling error must not become skipped steps). Every configuration is judged on
the printer and on the printer with all resonances --freq-margin per cent lower and higher
(default 5): the worst counts, because a real printer's frequencies drift.

The acceleration is searched up to where the weakest motor would need all its force at the job's
top speed (from the printer's motors and moving masses; --accel-range LO,HI overrides). The
firmware's max_accel does not cap it (the tuned value is what you set as max_accel); a per-axis cap
(max_y_accel, M201 Y) still limits that axis's moves, in every trial alike. A job that
sets its own accelerations (M201/M204, SET_VELOCITY_LIMIT) keeps them with --job-accel respect (the
default: the print as sliced; the acceleration is then not searched where it has no effect); with
--job-accel replace the tuned acceleration replaces them (what re-slicing would give), and the
summary gives both print times.

Per feature (--per-feature, default auto: on when the acceleration is searched and the job has
features nobody sees, unless --job-accel respect keeps the job's own accelerations): the visible
walls (outer walls, overhangs, unlabelled moves) take the main acceleration; the hidden walls, the
infill (with support), solid/top infill and travel each get their own, searched up to where the
weakest motor keeps its reserve at that group's own top speed; the corner rule (Klipper's
square_corner_velocity, Marlin's junction deviation or jerk, RRF's M566) and Klipper's
minimum_cruise_ratio are searched too. One shaper configuration serves the whole job. With --gcode,
job.gcode beside best.json is the job with the choice written in (as `ringtune rewrite` writes it).

Baselines: Klipper's rule — the recommendation recorded from your resonance files by `ringtune
identify` when the printer has one, else the rule on the model's simulated resonance test (said so);
what the printer runs now, when the printer description has a [current] section; no shaping.
Objectives: print time, the worst visible wall's ripple and corner deviation (rounding or
overshoot); hidden features reaching the outer wall by more than --max-show-through are ruled out.
The configuration chosen by default is the fastest one with no visible measure (ripple and its
90th percentile, corner rounding and overshoot, over- and under-extrusion) worse than the best
baseline's ("same quality, faster"); where there is none, the knee (--pick
knee|fastest-at-baseline-quality|weight, --weight W). Then its acceleration is stepped up 5 % at a
time with the same judgement until a measure gets worse or a bound binds (the summary names it,
with both values). Differences under 1 µm or 5 % of a distance, 1 point or 5 % of extrusion and
0.5 % of print time count as the same.

With no arguments it tunes the built-in Ender-3-class printer on the built-in test print into
./ringtune-out/ in about a minute; open ringtune-out/README.txt first. Running the same command
again resumes the study (also after Ctrl-C or a crash); --trials N extends it to N trials.
Progress goes to stderr: a bar on a terminal, else a line every 10 s (RINGTUNE_PROGRESS_S=N sets it).

examples:
  ringtune tune
  ringtune tune --printer my-printer.toml --gcode benchy.gcode --firmware rrf --trials 400 --workers 2
  ringtune tune --gcode tower.gcode --job-accel replace      # what re-slicing at a tuned accel gives
  ringtune tune --gcode part.gcode --per-feature on          # writes tuned/job.gcode with the choice in it
  ringtune tune --storage postgresql+psycopg2://user:pw@db-host/ringtune --study ender3 --workers 4
"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--printer", metavar="P", help="printer TOML (default: the embedded Ender-3-class printer)")
    p.add_argument("--gcode", metavar="G", type=gcode_job,
                   help=f"G-code job, {GCODE_JOB_HELP} (default: the built-in test print)")
    p.add_argument("--firmware", type=firmware_name, default="klipper",
                   help="target firmware: klipper (default), kalico, rrf, rrf35, rrf34, "
                   "marlin, marlin-ftm, prusa (any case)")
    p.add_argument("--trials", type=int, default=200, help="total complete trials of the study (default 200)")
    p.add_argument("--storage", metavar="URL", help="Optuna storage: journal:PATH (default "
                   "journal:OUT/study.journal), sqlite:///file.db, postgresql+psycopg2://user:pw@host/db")
    p.add_argument("--study", default="ringtune", metavar="NAME", help="study name in the storage (default ringtune)")
    p.add_argument("--workers", type=int, default=1, help="local worker processes (default 1; seeded "
                   "single-worker runs reproduce exactly)")
    p.add_argument("--seed", type=int, default=0, help="sampler seed (default 0)")
    p.add_argument("--out", default="ringtune-out", metavar="DIR", help="output folder (default ringtune-out)")
    p.add_argument("--pick", choices=("fastest-at-baseline-quality", "knee", "weight"), default=None,
                   help="which front point to choose: the fastest with no worse quality than the best baseline "
                        "(default), the knee, or the one minimising print time + W × error (--weight)")
    p.add_argument("--weight", type=float, default=None, metavar="W",
                   help="with --pick weight (implied): seconds of print time worth 1 mm less error")
    p.add_argument("--quality", choices=("ripple", "overshoot", "path_error"), default="ripple",
                   help="the study's second objective besides print time and corner deviation: ripple_mm "
                        "(default: the worst visible wall's peak-to-peak), overshoot_mm or path_error_mm; the "
                        "choice judges every visible measure whichever it is")
    p.add_argument("--max-show-through", type=float, default=None, metavar="MM",
                   help="rule out configurations whose hidden features (infill, inner walls) reach the outer wall "
                        "by more than MM (default: the job's own gap between infill and outer wall where the job states "
                        "its perimeters, widths and infill overlap (PrusaSlicer family), else 0.05; 0 = no bound)")
    p.add_argument("--max-path-error", type=float, default=None, metavar="MM",
                   help="rule out configurations whose path error (corner rounding, overshoot and ringing) "
                        "exceeds MM (default 0.1; 0 = no bound)")
    p.add_argument("--motor-reserve", type=float, default=None, metavar="PCT",
                   help="rule out configurations that ask a motor for more than 100 − PCT %% of the force it "
                        "has at its speed (default 20; 0 = no bound)")
    p.add_argument("--freq-margin", type=float, default=None, metavar="PCT",
                   help="also judge every configuration with the printer's resonances PCT %% lower and "
                        "higher; the worst counts (default 5; 0 = the exact model only)")
    p.add_argument("--shaping-min-freq", metavar="HZ", type=float, default=None,
                   help="Marlin classic: your build's SHAPING_MIN_FREQ (default: a stock build's 40 Hz, the "
                        "lower of SHAPING_FREQ_X/Y); the search stays above it")
    p.add_argument("--accel-range", metavar="LO,HI", default=None,
                   help="acceleration search range, mm/s² (default: from the printer's motors and masses at the "
                        "job's top speed); LO = HI fixes it")
    p.add_argument("--job-accel", choices=("respect", "replace"), default="respect",
                   help="a job's own M201/M204/SET_VELOCITY_LIMIT accelerations: respect them (default, the "
                        "print as sliced) or replace them by the tuned acceleration (what re-slicing would give)")
    p.add_argument("--per-feature", choices=("auto", "on", "off"), default="auto",
                   help="search an acceleration per feature group (hidden walls, infill, solid/top, travel; the "
                        "visible walls take the main one), the corner rule and minimum_cruise_ratio (default auto: "
                        "when the acceleration is searched and the job has features nobody sees)")
    p.add_argument("--backend", choices=("mujoco", "lti"), default="mujoco", help="physics (default mujoco)")
    p.add_argument("--evaluator", metavar="MODULE:FUNC", default=None,
                   help="advanced: score configs with your own f(configs, printer, job) -> metrics")
    p.add_argument("--no-baselines", action="store_true", help="skip the baselines (Klipper's rule, what the "
                   "printer runs now, no shaping)")


def run(args: argparse.Namespace, out) -> int:
    t_start = time.time()
    firmware, dialect, fw_note = firmware_names(args.firmware)
    if args.trials < 1:
        raise RingtuneError("must be ≥ 1", "--trials")
    if args.workers < 1:
        raise RingtuneError("must be ≥ 1", "--workers")
    how = args.pick or ("weight" if args.weight is not None else "fastest-at-baseline-quality")
    if args.weight is not None and not args.weight >= 0:
        raise RingtuneError("must be ≥ 0 (seconds per mm)", "--weight")
    if how == "weight" and args.weight is None:
        raise RingtuneError("--pick weight needs --weight W (seconds per mm)", "--pick")
    max_pe = pareto.DEFAULT_MAX_PATH_ERROR_MM if args.max_path_error is None else args.max_path_error
    if not max_pe >= 0:
        raise RingtuneError("must be ≥ 0 (mm; 0 = no bound)", "--max-path-error")
    margin = tune_study.DEFAULT_FREQ_MARGIN if args.freq_margin is None else args.freq_margin / 100.0
    if not 0 <= margin < 0.5:
        raise RingtuneError("must be in [0, 50) per cent", "--freq-margin")
    reserve = pareto.DEFAULT_MOTOR_RESERVE if args.motor_reserve is None else args.motor_reserve / 100.0
    if not 0 <= reserve < 1:
        raise RingtuneError("must be in [0, 100) per cent", "--motor-reserve")
    if args.max_show_through is not None and not args.max_show_through >= 0:
        raise RingtuneError("must be ≥ 0 (mm; 0 = no bound)", "--max-show-through")
    max_st, st_source = show_through_bound(args.gcode, args.max_show_through, pareto.DEFAULT_MAX_SHOW_THROUGH_MM)
    accel_range = _accel_range(args.accel_range)
    if args.gcode and not Path(args.gcode).is_file():
        raise RingtuneError("no such G-code file", "--gcode")
    out_dir = Path(args.out)
    _check_out(out_dir)
    if fw_note:
        out.note(f"ringtune tune: {fw_note}")
    printer = resolve_printer(args.printer)
    say_unmeasured(printer, out)
    quality = f"{args.quality}_mm"
    facts = job_accel_facts(printer, args.gcode, args.job_accel)
    # no --gcode: the built-in print stands in for the user's, which may run up to the velocity limit
    min_freq = _shaping_min_freq(args.shaping_min_freq)
    space = default_space(printer, firmware, accel=accel_range, speed=facts.top_speed if args.gcode else None,
                          min_freq=min_freq)
    floor_note = freq_floor_note(firmware, min_freq, space)
    if floor_note:
        out.note(f"ringtune tune: {floor_note}")
    if accel_range is None and args.job_accel == "respect" and facts.commands and not facts.accel_matters(space):
        a = float(printer.limits.accel)
        space = dataclasses.replace(space, accel=(a, a), accel_basis="not searched: the job's own acceleration "
                                    "commands rule every move (--job-accel respect)")
    for line in facts.notes(args.job_accel, space):
        out.note(f"ringtune tune: {line}")
    out.note(f"ringtune tune: {st_source}")
    per_feature, why = feature_space.wanted(args.per_feature, space, printer, args.gcode, bool(facts.commands),
                                            args.job_accel)
    if per_feature:
        space = feature_space.feature_space(space, printer, args.gcode, reserve)

    created = not out_dir.exists()
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        store = args.storage or storage.default_storage(out_dir)
        settings = tune_study.StudySettings(
            storage=store, study_name=args.study, n_trials=args.trials, seed=args.seed, quality=quality,
            printer=str(Path(args.printer).resolve()) if args.printer and Path(args.printer).exists() else args.printer,
            job=str(Path(args.gcode).resolve()) if args.gcode else None, firmware=firmware,
            backend=args.backend, evaluator=args.evaluator or tune_study.DEFAULT_EVALUATOR, space=space.to_dict(),
            max_path_error_mm=max_pe, freq_margin=margin, motor_reserve=reserve, job_accel=args.job_accel,
            max_show_through_mm=max_st)
        evaluator = tune_study.resolve_evaluator(settings.evaluator)

        bl = None
        baselines: dict[str, pareto.Point] = {}
        if not args.no_baselines:
            bl = baselines_for(printer, firmware, settings, evaluator, quality, note=out.note)
            baselines = bl.points
            k = baselines.get("klipper")
            if k is not None:   # start the search from what users do today, and its neighbours
                seen, enq = set(), []
                cur = [baselines["current"].config] if "current" in baselines else []
                for i, c in enumerate(warm_start(k.config, bl.fits, space) + [c for c in cur if inside(c, space)]):
                    p = params_from_config(c, space)   # the rule's pick also with the hidden groups at their tops
                    for q in (p, feature_space.at_ceilings(p, space)) if space.per_feature and i == 0 else (p,):
                        key = tuple(sorted(q.items()))
                        if key not in seen:
                            seen.add(key)
                            enq.append(q)
                settings.enqueue = enq

        bar = Progress(quality, max_pe, reserve, space)
        out.release()                    # the study runs long: its notes and progress go out live
        try:
            run_ = tune_study.run_study(settings, args.workers, printer=printer, progress=bar.update)
        finally:
            bar.close()
    except BaseException:
        if created:
            _remove_if_empty(out_dir)
        raise
    st = run_.study
    points = tune_study.study_points(st, space, quality, max_pe, reserve, max_st)
    front = pareto.pareto_front(points, also=_also(points, quality))
    choice = pareto.pick(front, baselines, how, args.weight)
    stop = None
    if choice.baseline is not None:       # step the acceleration up with the same judgement
        stop = _measured_stop(choice, baselines, bl.labels if bl else {}, evaluator, settings, printer, space,
                              max_pe, reserve, max_st)
        if stop.moved:
            choice = dataclasses.replace(choice, point=stop.point, sentence=(
                f"{choice.sentence}; then stepped up by the measured stop from {stop.start.config.accel:.0f} to "
                f"{stop.point.config.accel:.0f} mm/s², every visible measure still no worse"))
    chosen = choice.point
    bindings = binding_limits(printer, args.gcode, chosen.config, firmware, args.job_accel)
    accel_lines, accel_json = accel_statement(chosen, space, max_pe, reserve, points, printer,
                                              binding_sentences(bindings, chosen.config.accel),
                                              None if stop is None or stop.kind == "not searched"
                                              else (stop.sentence, stop.kind if stop.kind != "measure"
                                                    and stop.kind != "bound" else stop.key))
    accel_json["binding"] = [dataclasses.asdict(b) for b in bindings]
    baseline_binding = {k: binding_limits(printer, args.gcode, b.config, firmware, args.job_accel)
                        for k, b in baselines.items()}
    if not args.gcode and chosen.config.accel:
        accel_lines.append(top_speed_load_note(printer, chosen.config.accel, reserve))
    ja_lines, ja_json = job_accel_section(facts, args.job_accel, printer, args.gcode, chosen.config)
    pf_lines, pf_json = feature_space.feature_section(chosen.config, space) if space.per_feature else ([], None)
    if pf_json is not None:
        pf_json["why"] = why
    ja_json["searched"] = not space.accel_fixed
    notes = [f"The {floor_note}."] if floor_note else []
    notes.append(st_source[0].upper() + st_source[1:] + ".")
    if margin:
        notes.append(f"Every figure is the worst of the printer as modelled and with all its resonances "
                     f"{margin * 100:g} % lower and higher (--freq-margin; `ringtune simulate --freq-margin "
                     f"{margin * 100:g}` gives the same figures).")
    else:
        notes.append("Every figure is on the exact model (--freq-margin 0).")
    n_warm = len(settings.enqueue)
    if n_warm:
        notes.append("The search was warm-started from Klipper's recommendation" + (
            "." if n_warm == 1 else f" and {n_warm - 1} neighbour{'s' if n_warm > 2 else ''} of it (the rule's "
            "pick and robust shapers at its frequencies on the model's simulated test, higher accelerations)."))
    result = report.write_report(
        out_dir, points=points, front=front, choice=choice, baselines=baselines, quality=quality,
        printer_name=getattr(printer, "name", "printer"), job_name=Path(args.gcode).name if args.gcode else
        "built-in test print", firmware=firmware, n_trials=args.trials, storage=store,
        study_name=args.study, command=command_line(args), max_path_error_mm=max_pe, motor_reserve=reserve,
        baseline_labels=bl.labels if bl else None,
        sections=[("ACCELERATION", accel_lines)] + ([("PER FEATURE", pf_lines)] if pf_lines else [])
        + ([("THE JOB'S OWN ACCELERATIONS", ja_lines)] if ja_lines else []),
        notes=notes, export_firmware=dialect, max_show_through_mm=max_st, baseline_binding=baseline_binding,
        best_extra={"job_accel": args.job_accel, "freq_margin": margin, "motor_reserve": reserve,
                    "top_speed_mm_s": facts.top_speed if args.gcode else float(printer.limits.velocity),
                    **({"stop": stop.to_dict()} if stop else {})})
    text = result.pop("summary_text")
    result["per_feature"] = pf_json
    if args.gcode:     # the job with the choice written in, beside best.json
        try:
            done = rewrite_file(args.gcode, out_dir / "job.gcode", chosen.config, printer)
            result["files"]["job"] = str(out_dir / "job.gcode")
            text += (f"\nThe job with the choice written in: {out_dir / 'job.gcode'} ({done.lines_inserted} lines "
                     f"inserted; planned {done.before_s:.1f} s as sliced -> {done.after_s:.1f} s).")
        except RingtuneError as exc:       # the study stands; say why the job could not be written
            result["files"]["job"] = None
            out.note(f"ringtune tune: job.gcode not written: {exc}")
    if bl:
        for k, src in bl.sources.items():
            result["baselines"][k]["source"] = src
    result.update({"stop": stop.to_dict() if stop else None, "freq_margin": margin, "accel": accel_json, "job_accel": ja_json, "storage": store,
                   "study": args.study, "completed_now": run_.completed_now, "interrupted": run_.interrupted,
                   "elapsed_s": time.time() - t_start})
    lines = [text.rstrip("\n"), "", f"Results in {out_dir}/ — open {out_dir / 'README.txt'} first."]
    if run_.interrupted:
        lines.append(f"Interrupted after {run_.completed_before + run_.completed_now} complete trials; "
                     "run the same command again to resume.")
    out.emit(result, "\n".join(lines))
    return 130 if run_.interrupted else 0


def _also(points, quality: str) -> tuple[str, ...]:
    """The figures the front is taken over besides print time and the quality objective: the other
    visible measures (the choice may make none worse), or path error for a custom evaluator's
    overshoot (a point with a little more overshoot and far less path error stays)."""
    if any("ripple_mm" in p.metrics for p in points):
        return tuple(k for k in VISIBLE_KEYS if k != quality)
    return ("path_error_mm",) if quality != "path_error_mm" else ()


def _measured_stop(choice, baselines, labels, evaluator, settings, printer, space, max_pe, reserve, max_st):
    """:func:`ringtune.agents.tune.stop.measured_stop` from the choice, against the baseline it was held to."""
    def evaluate(configs):
        return evaluator(list(configs), printer, settings.job, **tune_study.evaluator_kwargs(settings))

    bounds = Bounds(max_pe, 1.0 - reserve if reserve > 0 else 0.0, max_st)
    held = choice.held_to or (choice.baseline,)
    names = {k: labels.get(k, pareto.BASELINE_NAMES.get(k, k)) for k in held}
    return measured_stop(choice.point, {k: baselines[k] for k in held}, evaluate, space, bounds, labels=names)


def firmware_names(name: str) -> tuple[str, str, str]:
    """(firmware to tune for, dialect apply.txt is written in, a note or "") from a ``--firmware``
    value: every firmware of :data:`ringtune.shaping.firmware.FIRMWARES` (the names ``export``
    accepts, rrf34 included), in any case."""
    rec = Firmware.named(name, "--firmware")
    return rec.name, rec.name, ""


def _shaping_min_freq(value: float | None) -> float | None:
    if value is not None and not (0 < value <= 1000):
        raise RingtuneError(f"{value:g} Hz is not a frequency: give one in (0, 1000] Hz", "--shaping-min-freq")
    return value


def _accel_range(text: str | None):
    if text is None:
        return None
    try:
        lo, hi = (float(v) for v in text.split(","))
    except ValueError:
        raise RingtuneError(f"must be LO,HI in mm/s² (e.g. 1000,8000), not {text!r}", "--accel-range") from None
    if not (0 < lo <= hi < 1e6):
        raise RingtuneError(f"must be 0 < LO ≤ HI (mm/s²), not {text!r}", "--accel-range")
    return (lo, hi)


def _check_out(out_dir: Path) -> None:
    """--out must be a folder we can write in (or create): say so in words, not an errno."""
    if out_dir.exists() and not out_dir.is_dir():
        raise RingtuneError(f"{out_dir} is a file, not a folder: give a folder for the results "
                            f"(e.g. --out {out_dir.with_suffix('')}-tune)", "--out")
    probe = out_dir.resolve()
    while not probe.exists() and probe.parent != probe:
        probe = probe.parent
    if probe.exists() and not probe.is_dir():
        raise RingtuneError(f"{probe} is a file, so {out_dir} cannot be created", "--out")
    if probe.exists() and not os.access(probe, os.W_OK | os.X_OK):
        what = "folder" if probe == out_dir else f"folder {probe}, where {out_dir} would be created,"
        raise RingtuneError(f"cannot write in the {what} (no permission or a read-only file system); "
                            "choose another --out", "--out")
    try:      # a read-only mount answers os.access with "yes" for root: try it
        with tempfile.TemporaryFile(dir=probe):
            pass
    except OSError as exc:
        raise RingtuneError(f"cannot write in {probe}: {exc.strerror or exc}; choose another --out",
                            "--out") from None


def _remove_if_empty(out_dir: Path) -> None:
    """A failed run leaves no empty results folder it created (a folder holding a study is kept)."""
    try:
        if out_dir.is_dir() and not any(out_dir.iterdir()):
            out_dir.rmdir()
    except OSError:
        pass


class Progress:
    """Progress on stderr only: a tqdm bar on a terminal; otherwise (logs, CI, nohup) a line every
    :func:`~ringtune.agents.cli.common.progress_interval` seconds with the trials done and the best so far."""

    def __init__(self, quality: str, max_pe: float, reserve: float, space, stream=None):
        self.stream = stream or sys.stderr
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.interval = progress_interval()
        self.quality, self.max_pe, self.reserve, self.space = quality, max_pe, reserve, space
        self._bar = None
        self._t0 = self._last = time.time()
        self._done = -1

    def update(self, done: int, total: int, study=None) -> None:
        if self.tty:
            if self._bar is None:
                self._bar = tqdm(total=total, initial=min(done, total), desc="trials", unit="trial",
                                 file=self.stream, dynamic_ncols=True)
            delta = min(done, total) - self._bar.n
            if delta > 0:
                self._bar.update(delta)
            return
        now = time.time()
        if now - self._last >= self.interval or (self._done < 0 and done > 0):
            self._last = now
            self._done = done
            print(f"ringtune tune: {done}/{total} trials, {now - self._t0:.0f} s; {self._best(study)}",
                  file=self.stream, flush=True)

    def _best(self, study) -> str:
        if study is None:
            return "no trial yet"
        try:
            front = pareto_front(study_points(study, self.space, self.quality, self.max_pe, self.reserve))
        except Exception:   # progress never stops a study
            return "best so far: unknown"
        if not front:
            return "no feasible configuration yet"
        f = front[0]
        q = min(front, key=lambda p: p.quality_mm)
        word = {"overshoot_mm": "overshoot", "ripple_mm": "ripple"}.get(self.quality, "path error")
        return (f"best so far: fastest feasible {f.print_time_s:.2f} s at {f.quality_mm * 1000:.1f} µm {word}, "
                f"lowest {word} {q.quality_mm * 1000:.1f} µm at {q.print_time_s:.2f} s ({len(front)} on the front)")

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()


_DEFAULTS = {"printer": None, "gcode": None, "firmware": "klipper", "trials": 200, "storage": None,
             "study": "ringtune", "workers": 1, "seed": 0, "out": "ringtune-out", "pick": None, "weight": None,
             "quality": "ripple", "max_path_error": None, "max_show_through": None, "motor_reserve": None, "freq_margin": None,
             "accel_range": None, "job_accel": "respect", "backend": "mujoco", "evaluator": None,
             "no_baselines": False}


def command_line(args) -> str:
    """The command that reproduces (and resumes) this run: every option given that differs from its
    default, --trials included."""
    parts = ["ringtune tune"]
    for opt, default in _DEFAULTS.items():
        v = getattr(args, opt, default)
        if v == default or v is None:
            continue
        flag = "--" + opt.replace("_", "-")
        if v is True:
            parts.append(flag)
        else:
            text = str(v)
            parts.append(f"{flag} {text!r}" if " " in text else f"{flag} {text}")
    return " ".join(parts)
