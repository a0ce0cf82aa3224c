"""``ringtune simulate``: print time and print quality of one configuration on a job.

JSON keys (stable): ``printer`` (name), ``job`` (G-code path or ``"built-in test print"``),
``backend``, ``config`` (TuneConfig dict), ``metrics`` {``print_time_s``, ``path_error_mm``,
``overshoot_mm``, ``ringing_mm``, ``peak_accel``, ``step_loss``, ``motor_load``, ``ripple_mm``,
``ripple_p90_mm``, ``corner_in_mm``, ``corner_out_mm``, ``extrusion_over_pct``,
``extrusion_under_pct``, ``e_lag_mm``, ``show_through_mm``, ``features`` ({class: {the same measures
per feature class, ringtune.envs.metrics.FEATURE_KEYS}}), ``extrusion_if_synced``
({``extrusion_over_pct``, ``extrusion_under_pct``, ``e_lag_mm``} with the firmware's E
synchronisation on, empty where it has none off by default)} (definitions:
ringtune.envs.window_metrics), ``e_timing`` (the firmware's extruder under shaping: shaped, delayed
or neither), ``e_sync`` (how to synchronise it, "" where not applicable), ``freq_margin``
(fraction: the metrics are the worst of the printer and its resonances this much lower and
higher, damping ×0.75, as ``tune`` judges; 0 = the exact model; default: the ``freq_margin`` a tune
best.json records, else tune's default), ``judgement`` (that, in words), ``variants`` (list of
{``factor`` (every resonance × it), ``damping_factor`` (every damping ratio × it), ``metrics``}),
``windows`` (list of {``t0``, ``t1``, ``kind``, ``step_loss`` and every scalar key of ``metrics``},
each the worst over the variants), ``plots`` (list of PNG paths, empty without
``--plot``), ``trace`` (with ``--trace`` only: the CSV path; columns in ``ringtune.envs.trace``; the printer as
modelled, not a detuned variant), ``job_shapers`` (the job's own shaper changes applied: list of
{``time``, ``config``}, empty when the job sets none), ``job_accel`` (``respect`` or ``replace``),
``baselines`` ({klipper|current|none: {``label``, ``config``, ``metrics``}}, judged as the
configuration is; empty with ``--no-baselines``), ``versus`` ({baseline: {measure: {``value``,
``baseline``, ``verdict`` better|same|worse}}} for print time and every visible measure, at tune's
resolution; ringtune.agents.tune.versus),
``binding`` (the firmware limits that hold some moves below the configuration's acceleration, each
measured by the planner without it: list of {``name``, ``value`` mm/s², ``what``, ``moves``,
``time_s``, ``time_without_s``}, as ``tune``'s), ``whole_job`` (with ``--whole-job`` only: the
configuration and Klipper's pick on the quality windows and over all of the job, the printer as
modelled, the exact linear backend: {``where``, ``seconds``, ``baseline`` (bool), ``measures``
({key: {``windows``: [this, pick], ``whole``: [this, pick], ``verdict_windows``, ``verdict_whole``}}),
``differ``, ``worse`` (keys), ``outer_wall_worst`` ({key: {``value`` mm, ``t`` s, ``x``, ``y`` mm,
``line``}}: where this configuration's outer wall has its worst corner over the whole job)};
ringtune.agents.tune.whole_job_check).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from ringtune.agents.cli.common import GCODE_JOB_HELP, firmware_name, gcode_job, judgement, say_unmeasured
from ringtune.agents.cli.simulate_config import build_config, freq_margin, max_path_error, motor_reserve
from ringtune.agents.cli.trace_option import write_trace_option
from ringtune.agents.tune.binding import binding_limits, binding_sentences
from ringtune.agents.tune.pareto import point_from_metrics
from ringtune.agents.tune.versus import baseline_evaluations, table as versus_table, versus_all
from ringtune.agents.tune.whole_job_check import whole_job_check
from ringtune.envs.evaluate import evaluate_judged
from ringtune.envs.planned_job import job_accel_commands, planned_job, resolve_job, resolve_printer
from ringtune.envs.metrics import Metrics
from ringtune.envs.plots import plot_evaluation
from ringtune.envs.variants import DEFAULT_FREQ_MARGIN, variant_factors
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.config_plan import for_firmware, job_accel_mode
from ringtune.shaping.e_timing import E_TIMING_WORDS
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.feature_settings import per_feature_text
from ringtune.shaping.firmware import FIRMWARES, Firmware
from ringtune.shaping.job_shapers import describe_timeline, shaper_timeline
from ringtune.shaping.reading_notes import reading_notes

NAME = "simulate"
DESCRIPTION = """\
Simulate one input-shaping configuration on a print job and report what a person would see.

Print time comes from the planner over the whole job; quality comes from the MuJoCo printer on
the job's quality windows (sharpest corners, fastest zigzags):

  print_time_s   planned print time of the whole job, s
  ripple_mm      worst peak-to-peak of the nozzle across a visible straight wall (outer walls,
                 top surfaces, overhangs; unlabelled moves where the job labels none of these, else
                 they are a purge line); ripple_p90_mm its 90th percentile
  corner_in_mm   worst rounding of a visible corner (inwards); corner_out_mm its overshoot
  extrusion_over_pct / extrusion_under_pct
                 worst excess / shortfall of material over 1 mm of path, with the firmware's own
                 extruder timing under shaping (seed 002); e_lag_mm how far it runs ahead
  show_through_mm  worst excursion of hidden features (infill, inner walls) towards the walls
  path_error_mm  largest distance of the nozzle from the extrusion path while extruding
  overshoot_mm   largest outward excursion past the path at corners and reversals
  ringing_mm     worst RMS oscillation across a straight wall after a direction change
  peak_accel     largest toolhead acceleration, mm/s²
  step_loss      whether a motor was asked for more force than it has at that speed
  motor_load     largest fraction of that force it was asked for (1 = the edge of step loss)

Every figure is judged as `ringtune tune` judges its trials: the worst of the printer as modelled
and of the printer with all its resonances --freq-margin per cent lower and higher and its damping
ratios ×0.75 (default 5; a real printer's frequencies drift by that much, and a fitted damping ratio
is less certain still; a best.json from tune that records another margin
is judged with that one). --freq-margin 0 judges the exact model only. So
`simulate --config best.json` on tune's printer and job prints tune's figures for that
configuration, to the digit.

The configuration comes from a TuneConfig JSON (--config, as written by `ringtune tune`) or from
--shaper/--freq/--damping/--freq-limit (one value for both axes, or "X,Y"); every TuneConfig key
has its option (--freq-limit-method, --min-speed-factor, --accel, --max-accel X,Y, --job-accel,
--feature-accel CLASS=A,..., --corner V, --min-cruise-ratio R),
which overrides the file's value.

The job runs as the printer would run it, as `ringtune plan` plans it: its own acceleration
commands (M201, M204, SET_VELOCITY_LIMIT) stand unless --job-accel replace (or a best.json's
job_accel) replaces them with the configuration's acceleration, and its own shaper commands (a
ringing test print's M593 X F0, a tower's SET_INPUT_SHAPER per band) change the shaping from where
they stand; stderr says so. Without --config and
--shaper/--freq/--damping: what the printer runs now when its description has a [current] section
(`ringtune printer from-klipper` writes one), else shaping off; stderr says which. Without --printer the embedded Ender-3-class printer is used; without --gcode the built-in
test print.

examples:
  ringtune simulate --shaper mzv --freq 48 --damping 0.1
  ringtune simulate --shaper zv,mzv --freq 51,46 --freq-limit 30 --firmware rrf --plot plots/
  ringtune simulate --printer my.toml --gcode part.gcode --config best.json --json
  ringtune simulate --config best.json --freq-margin 0     # the exact model only
  ringtune simulate --gcode ripples.gcode --trace nozzle.csv   # what the model prints
  ringtune simulate --gcode part --config best.json --whole-job # do the windows' verdicts hold?
"""


def add_arguments(parser) -> None:
    parser.add_argument("--printer", metavar="P", help="printer TOML or embedded name (default: ender3)")
    parser.add_argument("--gcode", metavar="G", type=gcode_job,
                        help=f"G-code file, {GCODE_JOB_HELP} (default: the built-in test print)")
    parser.add_argument("--config", metavar="C", help="TuneConfig JSON file")
    parser.add_argument("--shaper", metavar="S", help="shaper name, or X,Y (e.g. mzv or zv,ei); 'none' = off")
    parser.add_argument("--freq", metavar="F", help="shaper frequency in Hz, or X,Y")
    parser.add_argument("--damping", metavar="D", help="shaper damping ratio, or X,Y (default: the firmware's)")
    parser.add_argument("--freq-limit", metavar="L", type=float, help="infill frequency limit in Hz (0 = off)")
    parser.add_argument("--firmware", type=firmware_name, metavar="FW", help="firmware whose shapers are used (default: klipper)")
    parser.add_argument("--accel", metavar="A", type=float, help="printing acceleration, mm/s² (default: the printer's)")
    parser.add_argument("--max-accel", metavar="X,Y", help="per-axis acceleration caps, mm/s² (TuneConfig "
                        "max_accel_x/max_accel_y; default: the printer's)")
    parser.add_argument("--feature-accel", metavar="CLASS=A,...", help="acceleration per feature class, mm/s² "
                        "(TuneConfig feature_accel, e.g. infill=10000,travel=9000,inner_wall=10000)")
    parser.add_argument("--corner", metavar="V", type=float, help="the corner rule's value in the printer's junction "
                        "rule: square_corner_velocity mm/s, junction deviation mm, jerk mm/s (TuneConfig corner)")
    parser.add_argument("--min-cruise-ratio", metavar="R", type=float, help="Klipper's minimum_cruise_ratio in [0, 1)")
    parser.add_argument("--freq-limit-method", choices=("sections", "nophead", "marlin"),
                        help="how the frequency limit slows the zigzags (default sections)")
    parser.add_argument("--min-speed-factor", metavar="K", type=float,
                        help="lowest fraction of the commanded speed the frequency limit may slow to (default 0.3)")
    parser.add_argument("--job-accel", choices=("respect", "replace"),
                        help="the job's own acceleration commands stand (respect) or the configuration's "
                             "acceleration replaces them (replace); default: the config's job_accel, else replace")
    parser.add_argument("--backend", choices=("mujoco", "lti"), default="mujoco",
                        help="physics: mujoco (default) or lti (exact linear, fast screening)")
    parser.add_argument("--freq-margin", metavar="PCT", type=float, default=None,
                        help="judge also with every resonance PCT %% lower and higher, the worst counts, as "
                             f"tune does (default: the margin a tune best.json records, else {DEFAULT_FREQ_MARGIN * 100:g}; "
                             "0 = the exact model only)")
    parser.add_argument("--no-baselines", action="store_true",
                        help="skip the baselines (Klipper's pick, what the printer runs now, no shaping) that every "
                             "visible measure is compared with")
    parser.add_argument("--whole-job", action="store_true",
                        help="also simulate all of the job, not only its quality windows, with Klipper's pick beside "
                             "it (the printer as modelled, the exact linear backend; about a minute for a 20-minute "
                             "job): every visible measure on the windows and over the whole job, and whether the "
                             "verdicts against the pick hold")
    parser.add_argument("--plot", metavar="DIR", help="write path, ringing and accelerometer plots (PNG) to DIR")
    parser.add_argument("--trace", metavar="OUT.csv", help="write the simulated nozzle path (t, commanded and "
                        "nozzle x y, ...) of the whole job, or of its quality windows if it is long")


def _axis(shaper: str, freq: float, damping: float) -> str:
    """One axis of the configuration line: ``mzv 48 Hz S 0.1``, or ``none`` alone (no shaping has
    no frequency or damping)."""
    return "none" if shaper == "none" else f"{shaper} {freq:g} Hz S {damping:g}"


def job_commands(printer, gcode, config, out) -> list[dict]:
    """What the job's own commands do to this simulation, said aloud (``out.note``): its
    acceleration commands (standing or replaced, :func:`ringtune.shaping.config_plan.job_accel_mode`)
    and its shaper commands; returns the shaper changes ({``time`` s, ``config``}, the steps of
    :func:`ringtune.shaping.job_shapers.shaper_timeline`)."""
    _, parsed = resolve_job(gcode)
    plan = planned_job(printer, gcode, config).plan
    timeline = shaper_timeline(plan.events, config)
    notes = []
    if len(timeline) > 1:
        notes.append(describe_timeline(timeline, plan.events))
    limits = for_firmware(resolve_printer(printer).limits, config)
    notes.extend(reading_notes(parsed, limits, config.firmware))
    if job_accel_commands(parsed, limits):
        mode = job_accel_mode(config) if config.accel is not None else "respect"
        notes.append("the job's own acceleration commands " + (
            "stand (--job-accel respect), as the printer would run them" if mode == "respect" else
            f"are replaced by the configuration's {config.accel:g} mm/s² (--job-accel replace)"))
    out.note(*notes)
    return [{"time": t, "config": c.to_dict()} for t, c in timeline[1:]]


def run(args, out) -> int:
    printer, config, margin = _inputs(args, out)
    judged = judgement(margin)
    changes = job_commands(printer, args.gcode, config, out)
    bindings = binding_limits(printer, args.gcode, config, job_accel=job_accel_mode(config))
    out.note(f"simulating {config.shaper_x}/{config.shaper_y} on {printer.name} ({args.backend}), {judged} ...")
    m, evs = evaluate_judged([config], printer, args.gcode, backend=args.backend, freq_margin=margin,
                             job_shapers=True)[0]
    if args.trace:   # the printer as modelled (variant 1.0)
        write_trace_option(args.trace, evs[0], config, printer, args.gcode, args.backend, out)
    windows = _windows(evs)
    factors = variant_factors(margin)
    base = _baseline_runs(args, printer, config, margin, out)
    plots = _plots(evs, args, margin, judged, base) if args.plot else []
    result = {
        "printer": printer.name,
        "job": args.gcode or "built-in test print",
        "backend": args.backend,
        "config": config.to_dict(),
        "metrics": m.to_dict(),
        "e_timing": FIRMWARES[config.firmware].e_timing,
        "e_sync": FIRMWARES[config.firmware].e_sync,
        "freq_margin": margin,
        "judgement": judged,
        "variants": [{"factor": v.freq, "damping_factor": v.damping, "metrics": e.metrics.to_dict()}
                     for v, e in zip(factors, evs)],
        "windows": windows,
        "plots": plots,
        "job_shapers": changes,
        "job_accel": job_accel_mode(config),
        "binding": [dataclasses.asdict(b) for b in bindings],
        **({"trace": args.trace} if args.trace else {}),
    }
    lines = _text(result, m, config, printer, judged, len(evs)) + _binding_said(bindings, config)
    lines += _baselines(result, m, args, base)
    lines += _whole_job(result, args, printer, config, base, out) if args.whole_job else []
    lines += [f"plot: {p}" for p in plots]
    out.emit(result, "\n".join(lines))
    return 0


def _inputs(args, out) -> tuple:
    """(printer, config, frequency margin) the options give; a bad option, a missing job or a plot
    folder that cannot be made is refused before anything is simulated."""
    freq_margin(args)                   # a bad option is refused before any note is printed
    printer = resolve_printer(args.printer)
    say_unmeasured(printer, out)
    config = build_config(args, out, printer)
    said = Firmware.named(config.firmware).junction_note(printer.limits.junction)
    if said:
        out.note(f"ringtune simulate: {said}")
    margin = freq_margin(args, config)
    if args.gcode and not Path(args.gcode).is_file():
        raise RingtuneError("no such G-code file", f"--gcode {args.gcode}")
    if args.plot:  # before simulating: a folder that cannot be made fails now, in one line
        try:
            Path(args.plot).mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise RingtuneError(f"cannot create the plot folder: {exc.strerror or exc}",
                                f"--plot {args.plot}") from None
    return printer, config, margin


def _plots(evs, args, margin: float, judged: str, base) -> list[str]:
    """The evaluation's plots in ``--plot``, against Klipper's pick (``base``: :func:`_baseline_runs`)."""
    label, kevs = _plot_baseline(base)
    return [str(p) for p in plot_evaluation(evs, args.plot, factors=variant_factors(margin), judged=judged,
                                            baseline=kevs, baseline_label=label)]


def _binding_said(bindings, config) -> list[str]:
    """The sentences on the firmware limits that hold moves lower, and how to run with other
    per-axis caps when such a cap binds and the config sets none."""
    said = binding_sentences(bindings, config.accel)
    xy_caps = {"M201 X", "M201 Y", "max_x_accel", "max_y_accel"}      # binding.cap_names' per-axis caps
    if config.max_accel_x is None and any(b.name in xy_caps for b in bindings):
        said.append("  --max-accel X,Y runs it with other per-axis caps (tune's configurations carry the caps "
                    "they were planned with, and export sets them)")
    return said


def _baseline_runs(args, printer, config: TuneConfig, margin: float, out):
    """(Baselines, {key: (judged Metrics, Evaluations)}) of the baselines, simulated once for the
    comparison table and the plots, judged as the configuration is; None when neither wants them."""
    if getattr(args, "no_baselines", False) and not args.plot:
        return None
    return baseline_evaluations(printer, config.firmware, args.gcode, backend=args.backend, freq_margin=margin,
                                job_accel=job_accel_mode(config), motor_reserve=motor_reserve(config),
                                max_path_error_mm=max_path_error(config),
                                note=lambda s: out.note(s.replace("ringtune tune", "ringtune simulate")))


def _baselines(result: dict, m, args, base) -> list[str]:
    """Fill ``baselines`` and ``versus`` of ``result``; the text table."""
    result["baselines"], result["versus"] = {}, {}
    if getattr(args, "no_baselines", False) or base is None:
        return []
    bl, runs = base
    ms = {k: judged.to_dict() for k, (judged, _) in runs.items()}
    result["baselines"] = {k: {"label": bl.labels[k], "config": bl.configs[k].to_dict(), "metrics": ms[k]}
                           for k in ms}
    # as tune compares them: every visible class's own measures, and on each printer variant
    mine = point_from_metrics(TuneConfig(), m)
    points = {k: point_from_metrics(bl.configs[k], judged) for k, (judged, _) in runs.items()}
    result["versus"] = versus_all(mine, points)
    return ["", "against each baseline (the same job and judgement):"] + versus_table(mine, points, bl.labels,
                                                                                        name="this")


def _whole_job(result: dict, args, printer, config: TuneConfig, base, out) -> list[str]:
    """Fill ``whole_job`` of ``result`` (:func:`ringtune.agents.tune.whole_job_check.whole_job_check`,
    against Klipper's pick when the baselines have one); the text table."""
    pick = base[0].configs.get("klipper") if base is not None else None
    out.note("simulating all of the job" + (" and Klipper's pick" if pick else "") + " (the exact linear model) ...")
    check = whole_job_check(config, printer, args.gcode, pick, job_accel=job_accel_mode(config))
    result["whole_job"] = check.to_dict()
    against = ", against Klipper's pick" if pick else " (no Klipper's pick to compare: --no-baselines or none)"
    return ["", f"over the whole job ({check.seconds:.0f} s to simulate), the printer as modelled, the exact linear "
                f"model{against}", f"  {check.where}"] + check.table("this", "Klipper's pick")


def _plot_baseline(base):
    """(label, Evaluations per variant) of Klipper's pick for the plots: the pick recorded from the
    resonance files, else Klipper's rule on the model's simulated resonance test; (label, None)
    when there is none (the baselines say why)."""
    label = "Klipper's pick"
    if base is None or "klipper" not in base[0].configs:
        return label, None
    bl, runs = base
    kcfg = bl.configs["klipper"]
    label += (" from the resonance files" if bl.sources.get("klipper") == "measurement"
              else " on the simulated resonance test")
    label += f" ({kcfg.shaper_x} {kcfg.freq_x:.1f} / {kcfg.shaper_y} {kcfg.freq_y:.1f} Hz, {kcfg.accel:.0f} mm/s²)"
    return label, runs["klipper"][1]


def _windows(evs) -> list[dict]:
    """Per quality window: its span and kind, each measure the worst over the printer variants
    (step loss, a bool: whether any variant lost steps)."""
    keys = ("step_loss",) + Metrics.SCALAR_KEYS
    per_window = zip(evs[0].planned.windows, zip(*(e.metrics.details["windows"] for e in evs)))
    return [{"t0": float(w.t0), "t1": float(w.t1), "kind": str(getattr(w, "kind", "")),
             **{k: max(p[k] for p in parts) for k in keys}} for w, parts in per_window]


def _text(result: dict, m, c, printer, judged: str, n_variants: int) -> list[str]:
    """The text report's lines (µm for lengths)."""
    um = 1000.0
    fw = FIRMWARES[c.firmware]
    lines = [
        f"printer {printer.name}, job {result['job']}, backend {result['backend']}",
        f"config  {c.firmware}: X {_axis(c.shaper_x, c.freq_x, c.damping_x)}, "
        f"Y {_axis(c.shaper_y, c.freq_y, c.damping_y)}, freq limit "
        f"{(f'{c.freq_limit_hz:g} Hz' if c.freq_limit_hz else 'off')}"
        + (f", accel {c.accel:g} mm/s²" if c.accel else "") + per_feature_text(c),
        f"judged  {judged}",
        f"print time   {m.print_time_s:10.3f} s",
        f"ripple       {m.ripple_mm * um:10.1f} µm peak-to-peak, worst visible wall "
        f"(90th percentile {m.ripple_p90_mm * um:.1f} µm)",
        f"corner in    {m.corner_in_mm * um:10.1f} µm rounding, worst visible corner",
        f"corner out   {m.corner_out_mm * um:10.1f} µm overshoot, worst visible corner",
        f"extrusion    {m.extrusion_over_pct:+9.1f} % / {-m.extrusion_under_pct:+.1f} % material over 1 mm "
        f"of path; extruder up to {m.e_lag_mm * um:.0f} µm off the nozzle ({fw.title}: "
        f"{E_TIMING_WORDS[fw.e_timing]})",
    ]
    if m.extrusion_if_synced:
        s = m.extrusion_if_synced
        lines.append(f"  E synced   {s['extrusion_over_pct']:+9.1f} % / {-s['extrusion_under_pct']:+.1f} %, "
                     f"up to {s['e_lag_mm'] * um:.0f} µm, if you {fw.e_sync}")
    lines += [
        f"show-through {m.show_through_mm * um:10.1f} µm hidden features towards the walls",
        f"path error   {m.path_error_mm * um:10.1f} µm",
        f"overshoot    {m.overshoot_mm * um:10.1f} µm",
        f"ringing      {m.ringing_mm * um:10.1f} µm RMS",
        f"peak accel   {m.peak_accel:10.0f} mm/s²",
        f"step loss    {'YES' if m.step_loss else 'no':>10}",
        f"motor load   {m.motor_load * 100:>9.0f} %  of the force the motors have",
        f"({len(result['windows'])} quality windows simulated"
        + (f" on each of {n_variants} printer variants)" if n_variants > 1 else ")"),
    ]
    return lines
