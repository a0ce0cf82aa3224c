"""``ringtune simulate``: print time and print quality of one configuration on a job.

JSON keys (stable): ``printer`` (name), ``job`` (G-code path or ``"built-in test print"``),
``backend``, ``config`` (TuneConfig dict), ``metrics`` {``print_time_s``, ``path_error_mm``,
``overshoot_mm``, ``ringing_mm``, ``peak_accel``, ``step_loss``, ``motor_load``, ``ripple_mm``,
``ripple_p90_mm``, ``corner_in_mm``, ``corner_out_mm``, ``extrusion_over_pct``,
``extrusion_under_pct``, ``e_lag_mm``, ``show_through_mm``, ``features`` ({class: {the same measures
per feature class, ringtune.envs.metrics.FEATURE_KEYS}}), ``extrusion_if_synced``
({``extrusion_over_pct``, ``extrusion_under_pct``, ``e_lag_mm``} with the firmware's E
synchronisation on, empty where it has none off by default)} (definitions: ringtune.envs.metrics),
``e_timing`` (the firmware's extruder under shaping: shaped, delayed or neither), ``e_sync`` (how to
synchronise it, "" where not applicable), ``freq_margin``
(fraction: the metrics are the worst of the printer and its resonances this much lower and
higher, as ``tune`` judges; 0 = the exact model; default: the ``freq_margin`` a tune best.json
records, else tune's default), ``judgement`` (that, in words), ``variants``
(list of {``factor`` (every resonance × it), ``metrics``}), ``windows`` (list of {``t0``, ``t1``,
``kind``, ``step_loss`` and every scalar key of ``metrics``}, each the worst over the variants), ``plots`` (list of PNG paths, empty without
``--plot``), ``trace`` (with ``--trace`` only: the CSV path; columns in ``ringtune.envs.trace``; the printer as
modelled, not a detuned variant), ``job_shapers`` (the job's own shaper changes applied: list of
{``time``, ``config``}, empty when the job sets none), ``job_accel`` (``respect`` or ``replace``),
``baselines`` ({klipper|current|none: {``label``, ``config``, ``metrics``}}, judged as the
configuration is; empty with ``--no-baselines``), ``versus`` ({baseline: {measure: {``value``,
``baseline``, ``verdict`` better|same|worse}}} for print time and every visible measure, at tune's
resolution; ringtune.agents.tune.versus),
``binding`` (the firmware limits that hold some moves below the configuration's acceleration, each
measured by the planner without it: list of {``name``, ``value`` mm/s², ``what``, ``moves``,
``time_s``, ``time_without_s``}, as ``tune``'s).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

from ringtune.agents.cli.common import (GCODE_JOB_HELP, firmware_name, gcode_job,
                                       judgement, load_config, say_unmeasured)
from ringtune.agents.cli.trace_option import write_trace_option
from ringtune.agents.tune.baselines import current_config
from ringtune.agents.tune.binding import binding_limits, binding_sentences
from ringtune.agents.tune.study import DEFAULT_FREQ_MARGIN
from ringtune.agents.tune.versus import baseline_evaluations, table as versus_table, versus_all
from ringtune.envs.evaluate import (evaluate_judged, job_accel_commands, planned_job, resolve_job,
                                    resolve_printer, variant_factors)
from ringtune.envs.metrics import Metrics
from ringtune.envs.plots import plot_evaluation
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.config_plan import job_accel_mode
from ringtune.shaping.e_timing import E_TIMING_WORDS
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.feature_settings import per_feature_text
from ringtune.shaping.firmware import FIRMWARES
from ringtune.shaping.job_shapers import describe_timeline, shaper_timeline
from ringtune.shaping.shapers import default_damping, shapers_from_config

NAME = "simulate"
DESCRIPTION = """\
Simulate one input-shaping configuration on a print job and report what a person would see.

Print time comes from the planner over the whole job; quality comes from the MuJoCo printer on
the job's quality windows (sharpest corners, fastest zigzags):

  print_time_s   planned print time of the whole job, s
  ripple_mm      worst peak-to-peak of the nozzle across a visible straight wall (outer walls,
                 top surfaces, overhangs, unlabelled moves); ripple_p90_mm its 90th percentile
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
and of the printer with all its resonances --freq-margin per cent lower and higher (default 5; a
real printer's frequencies drift by that much; a best.json from tune that records another margin
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
    parser.add_argument("--plot", metavar="DIR", help="write path, ringing and accelerometer plots (PNG) to DIR")
    parser.add_argument("--trace", metavar="OUT.csv", help="write the simulated nozzle path (t, commanded and "
                        "nozzle x y, ...) of the whole job, or of its quality windows if it is long")


def _pair(text: str | None, option: str, number: bool) -> tuple | None:
    if text is None:
        return None
    parts = [p.strip() for p in str(text).split(",")]
    if len(parts) == 1:
        parts = parts * 2
    if len(parts) != 2 or not all(parts):
        raise RingtuneError("give one value or two separated by a comma (X,Y)", option)
    if not number:
        return tuple(parts)
    try:
        return tuple(float(p) for p in parts)
    except ValueError:
        raise RingtuneError(f"not a number: {text!r}", option) from None


def _base_config(args, printer) -> tuple[dict, list[str]]:
    """What is simulated when neither --config nor --shaper/--freq/--damping says: what the printer
    runs now (its ``[current]`` section), else no shaping; and the notes that say so."""
    notes: list[str] = []
    note = notes.append
    if printer is not None and printer.current:
        cur = printer.current
        firmware = args.firmware or str(cur.get("firmware") or "klipper")
        cfg, why = current_config(printer, firmware)
        if cfg is not None:
            note(f"no --config: simulating what the printer runs now, from [current] "
                 f"({cur.get('source') or printer.name})")
            d = cfg.to_dict()
            d.pop("extra", None)
            d["job_accel"] = "respect"    # the printer runs the job's own acceleration commands
            return d, notes
        note(why)
    note("no --config or --shaper: simulating with input shaping off (give --config best.json or "
         "--shaper S --freq F to simulate a configuration)")
    return {"shaper_x": "none", "shaper_y": "none"}, notes


def build_config(args, out=None, printer=None):
    """The TuneConfig from --config and/or the individual options (options override the file);
    without either, what ``printer`` runs now (``[current]``), else no shaping."""
    cfg, notes = _start(args, out, printer)     # the notes are said once the options are known to be good
    shaper = _pair(args.shaper, "--shaper", False)
    freq = _pair(args.freq, "--freq", True)
    damping = _pair(args.damping, "--damping", True)
    if shaper:
        cfg["shaper_x"], cfg["shaper_y"] = shaper
        if not freq and not args.config and any(s != "none" for s in shaper):
            raise RingtuneError("a shaper needs a frequency", "--freq")
    if freq:
        cfg["freq_x"], cfg["freq_y"] = freq
    if damping:
        cfg["damping_x"], cfg["damping_y"] = damping
    elif shaper and not args.config:
        _default_damping(cfg)
    if args.freq_limit is not None:
        cfg["freq_limit_hz"] = args.freq_limit
    _other_keys(cfg, args)
    _check_options(freq, damping, args)
    config = _named_config(cfg, args, shaper, freq, damping)
    for n in notes if out is not None else ():
        out.note(n)
    return config


def _start(args, out, printer) -> tuple[dict, list[str]]:
    """(config dict the options then override, notes): --config's, else (no shaper option) what the
    printer runs now, else no shaping; with --firmware's firmware."""
    notes: list[str] = []
    if args.config:
        cfg = load_config(args.config, out).to_dict()
    elif args.shaper is None and args.freq is None and args.damping is None:
        cfg, notes = _base_config(args, printer)
    else:
        cfg = {"shaper_x": "none", "shaper_y": "none"}
    if args.firmware:
        cfg["firmware"] = args.firmware
    return cfg, notes


def _default_damping(cfg: dict) -> None:
    """Shapers given without --damping take their firmware's default damping ratio."""
    record = FIRMWARES.get(str(cfg.get("firmware", "klipper")).lower())
    if record is not None:  # an unknown firmware is reported by TuneConfig below
        cfg["damping_x"] = cfg["damping_y"] = default_damping(record.flavor)


def _named_config(cfg: dict, args, shaper, freq, damping) -> TuneConfig:
    """The TuneConfig of ``cfg``; a bad value is refused naming the option that gave it (or the
    file), and shapers the firmware does not offer naming --shaper (or the file)."""
    where = args.config or "options"
    try:
        config = TuneConfig.from_dict(cfg, where)
    except RingtuneError as exc:   # a value an option gave: name the option, not the config key
        key = (exc.where or "").rpartition(": ")[2]
        given = {"--freq": freq, "--damping": damping, "--shaper": shaper, "--firmware": args.firmware,
                 "--freq-limit": args.freq_limit, "--accel": args.accel, "--max-accel": args.max_accel,
                 "--freq-limit-method": args.freq_limit_method, "--min-speed-factor": args.min_speed_factor,
                 "--feature-accel": args.feature_accel, "--corner": args.corner,
                 "--min-cruise-ratio": args.min_cruise_ratio}
        flag = _KEY_FLAG.get(key.partition(".")[0])
        if flag and given.get(flag) is not None:
            raise RingtuneError(exc.bare, flag) from None
        raise
    try:  # the firmware must offer the shapers: say which option (or file) asked for them
        shapers_from_config(config)
    except RingtuneError as exc:
        if shaper:
            raise RingtuneError(exc.bare, "--shaper") from None
        raise exc.relocated("config", where) from None
    return config


#: TuneConfig key -> the option that sets it
_KEY_FLAG = {"freq_x": "--freq", "freq_y": "--freq", "damping_x": "--damping", "damping_y": "--damping",
             "shaper_x": "--shaper", "shaper_y": "--shaper", "firmware": "--firmware",
             "freq_limit_hz": "--freq-limit", "accel": "--accel", "max_accel_x": "--max-accel",
             "max_accel_y": "--max-accel", "freq_limit_method": "--freq-limit-method",
             "min_speed_factor": "--min-speed-factor", "feature_accel": "--feature-accel", "corner": "--corner",
             "min_cruise_ratio": "--min-cruise-ratio"}


def _in_range(values, lo: float, hi: float, option: str, what: str) -> None:
    bad = [v for v in values if v is not None and not (math.isfinite(v) and lo <= v <= hi)]
    if bad:
        raise RingtuneError(f"{bad[0]:g} is not {what}", option)


def _other_keys(cfg: dict, args) -> None:
    """The TuneConfig keys without a shaper of their own: acceleration, caps, limit method and
    speed factor, the job-acceleration mode (an extra key of tune's best.json)."""
    caps = _pair(args.max_accel, "--max-accel", True) or (None, None)
    _in_range(caps, 1.0, 1e6, "--max-accel", "an acceleration cap: give mm/s² > 0")
    msf = args.min_speed_factor
    _in_range((msf,), 0.01, 1.0, "--min-speed-factor", "a speed factor: give one in [0.01, 1]")
    given = {"accel": args.accel, "max_accel_x": caps[0], "max_accel_y": caps[1],
             "freq_limit_method": args.freq_limit_method, "min_speed_factor": msf, "job_accel": args.job_accel,
             "feature_accel": _feature_accel(args.feature_accel), "corner": args.corner,
             "min_cruise_ratio": args.min_cruise_ratio}
    cfg.update({k: v for k, v in given.items() if v is not None})


def _feature_accel(text: str | None) -> dict | None:
    """``CLASS=A,CLASS=A`` -> {class: mm/s²} (the classes are checked by TuneConfig)."""
    if text is None:
        return None
    out = {}
    for part in text.split(","):
        name, eq, value = part.partition("=")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            raise RingtuneError(f"{part!r} is not CLASS=mm/s² (e.g. infill=10000)", "--feature-accel") from None
        if not eq:
            raise RingtuneError(f"{part!r} is not CLASS=mm/s² (e.g. infill=10000)", "--feature-accel")
    return out


def _check_options(freq, damping, args) -> None:
    """The options' values in their own units, named by option (TuneConfig's own check would name
    its keys: ``options: freq_x: -40.0 is out of range``)."""
    for f in freq or ():
        if not (math.isfinite(f) and 0 <= f <= 1000):
            raise RingtuneError(f"{f:g} Hz is not a shaper frequency: give one in (0, 1000] Hz", "--freq")
    for z in damping or ():
        if not (math.isfinite(z) and 0 <= z <= 0.99):
            raise RingtuneError(f"{z:g} is not a damping ratio: give one in [0, 0.99] (e.g. 0.1)", "--damping")
    if args.freq_limit is not None and not (math.isfinite(args.freq_limit) and 0 <= args.freq_limit <= 1000):
        raise RingtuneError(f"{args.freq_limit:g} Hz is not a frequency limit: give one in [0, 1000] Hz "
                            "(0 = off)", "--freq-limit")
    if args.accel is not None and not (math.isfinite(args.accel) and 0 < args.accel <= 1e6):
        raise RingtuneError(f"{args.accel:g} mm/s² is not a printing acceleration: give one in (0, 1e6] mm/s²",
                            "--accel")


def _axis(shaper: str, freq: float, damping: float) -> str:
    """One axis of the configuration line: ``mzv 48 Hz S 0.1``, or ``none`` alone (no shaping has
    no frequency or damping)."""
    return "none" if shaper == "none" else f"{shaper} {freq:g} Hz S {damping:g}"


def freq_margin(args, config=None) -> float:
    """--freq-margin PCT as a fraction; default: the margin the configuration was tuned with
    (``freq_margin`` in a best.json from tune), else tune's default."""
    if args.freq_margin is None:
        recorded = (config.extra or {}).get("freq_margin") if config is not None else None
        if isinstance(recorded, (int, float)) and not isinstance(recorded, bool) and 0 <= recorded < 0.5:
            return float(recorded)
        return DEFAULT_FREQ_MARGIN
    if not 0 <= args.freq_margin < 50:
        raise RingtuneError(f"must be a percentage in [0, 50), not {args.freq_margin:g}", "--freq-margin")
    return args.freq_margin / 100.0


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
    if job_accel_commands(parsed):
        mode = job_accel_mode(config) if config.accel is not None else "respect"
        notes.append("the job's own acceleration commands " + (
            "stand (--job-accel respect), as the printer would run them" if mode == "respect" else
            f"are replaced by the configuration's {config.accel:g} mm/s² (--job-accel replace)"))
    for n in notes:
        out.note(n)
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
        "variants": [{"factor": f, "metrics": e.metrics.to_dict()} for f, e in zip(factors, evs)],
        "windows": windows,
        "plots": plots,
        "job_shapers": changes,
        "job_accel": job_accel_mode(config),
        "binding": [dataclasses.asdict(b) for b in bindings],
        **({"trace": args.trace} if args.trace else {}),
    }
    lines = _text(result, m, config, printer, judged, len(evs)) + _binding_said(bindings, config)
    lines += _baselines(result, m, args, base)
    lines += [f"plot: {p}" for p in plots]
    out.emit(result, "\n".join(lines))
    return 0


def _inputs(args, out) -> tuple:
    """(printer, config, frequency margin) the options give; a bad option, a missing job or a plot
    folder that cannot be made is refused before anything is simulated."""
    if args.freq_margin is not None:    # a bad option is refused before any note is printed
        freq_margin(args)
    printer = resolve_printer(args.printer)
    say_unmeasured(printer, out)
    config = build_config(args, out, printer)
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
                                job_accel=job_accel_mode(config),
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
    mine = m.to_dict()
    result["versus"] = versus_all(mine, ms)
    return ["", "against each baseline (the same job and judgement):"] + versus_table(mine, ms, bl.labels, name="this")


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
    """Per quality window: its span and kind, each measure the worst over the printer variants."""
    keys = ("step_loss",) + Metrics.SCALAR_KEYS
    windows = []
    for i, w in enumerate(evs[0].planned.windows):
        parts = [e.metrics.details["windows"][i] for e in evs]
        windows.append({"t0": float(w.t0), "t1": float(w.t1), "kind": str(getattr(w, "kind", "")),
                        **{k: (any(p[k] for p in parts) if k == "step_loss" else max(p[k] for p in parts))
                           for k in keys}})
    return windows


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
