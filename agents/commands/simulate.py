"""``ringtune simulate``: print time and print quality of one configuration on a job.

JSON keys (stable): ``printer`` (name), ``job`` (G-code path or ``"built-in test print"``),
``backend``, ``config`` (TuneConfig dict), ``metrics`` {``print_time_s``, ``path_error_mm``,
``overshoot_mm``, ``ringing_mm``, ``peak_accel``, ``step_loss``, ``motor_load``}, ``windows``
(list of {``t0``, ``t1``, ``kind``, ``path_error_mm``, ``overshoot_mm``, ``ringing_mm``,
``peak_accel``, ``step_loss``, ``motor_load``}), ``plots`` (list of PNG paths, empty without ``--plot``),
``trace`` (with ``--trace`` only: the CSV path; columns in ``ringtune.envs.trace``).
"""

from __future__ import annotations

from pathlib import Path

from ringtune.shaping.errors import RingtuneError

NAME = "simulate"
HELP = "simulate a configuration on a job: print time, path error, overshoot, ringing, step loss"
DESCRIPTION = """\
Simulate one input-shaping configuration on a print job and report what a person would see.

Print time comes from the planner over the whole job; quality comes from the MuJoCo printer on
the job's quality windows (sharpest corners, fastest zigzags):

  print_time_s   planned print time of the whole job, s
  path_error_mm  largest distance of the nozzle from the extrusion path while extruding
  overshoot_mm   largest outward excursion past the path at corners and reversals
  ringing_mm     worst RMS oscillation across a straight wall after a direction change
  peak_accel     largest toolhead acceleration, mm/s²
  step_loss      whether a motor was asked for more force than it has at that speed
  motor_load     largest fraction of that force it was asked for (1 = the edge of step loss)

The configuration comes from a TuneConfig JSON (--config, as written by `ringtune tune`) or from
--shaper/--freq/--damping/--freq-limit (one value for both axes, or "X,Y"). Without any, shaping
is off. Without --printer the embedded Ender-3-class printer is used; without --gcode the built-in
test print.

examples:
  ringtune simulate --shaper mzv --freq 48 --damping 0.1
  ringtune simulate --shaper zv,mzv --freq 51,46 --freq-limit 30 --firmware rrf --plot plots/
  ringtune simulate --printer my.toml --gcode part.gcode --config best.json --json
  ringtune simulate --gcode ripples.gcode --trace nozzle.csv   # what the model prints
"""


def add_arguments(parser) -> None:
    parser.add_argument("--printer", metavar="P", help="printer TOML or embedded name (default: ender3)")
    parser.add_argument("--gcode", metavar="G", help="G-code file (default: the built-in test print)")
    parser.add_argument("--config", metavar="C", help="TuneConfig JSON file")
    parser.add_argument("--shaper", metavar="S", help="shaper name, or X,Y (e.g. mzv or zv,ei); 'none' = off")
    parser.add_argument("--freq", metavar="F", help="shaper frequency in Hz, or X,Y")
    parser.add_argument("--damping", metavar="D", help="shaper damping ratio, or X,Y (default: the firmware's)")
    parser.add_argument("--freq-limit", metavar="L", type=float, help="infill frequency limit in Hz (0 = off)")
    parser.add_argument("--firmware", metavar="FW", help="firmware whose shapers are used (default: klipper)")
    parser.add_argument("--accel", metavar="A", type=float, help="printing acceleration, mm/s² (default: the printer's)")
    parser.add_argument("--backend", choices=("mujoco", "lti"), default="mujoco",
                        help="physics: mujoco (default) or lti (exact linear, fast screening)")
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


def build_config(args, out=None):
    """The TuneConfig from --config and/or the individual options (options override the file)."""
    from ringtune.agents.commands import load_config
    from ringtune.shaping.config import TuneConfig
    from ringtune.shaping.firmware import FIRMWARES
    from ringtune.shaping.shapers import default_damping

    if args.config:
        cfg = load_config(args.config, out).to_dict()
    else:
        cfg = {"shaper_x": "none", "shaper_y": "none"}
    if args.firmware:
        cfg["firmware"] = args.firmware
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
        record = FIRMWARES.get(str(cfg.get("firmware", "klipper")).lower())
        if record is not None:  # an unknown firmware is reported by TuneConfig below
            cfg["damping_x"] = cfg["damping_y"] = default_damping(record.flavor)
    if args.freq_limit is not None:
        cfg["freq_limit_hz"] = args.freq_limit
    if args.accel is not None:
        cfg["accel"] = args.accel
    where = args.config or "options"
    config = TuneConfig.from_dict(cfg, where)
    from ringtune.shaping.shapers import shapers_from_config

    try:  # the firmware must offer the shapers: say which option (or file) asked for them
        shapers_from_config(config)
    except RingtuneError as exc:
        if shaper:
            raise RingtuneError(exc.bare, "--shaper") from None
        raise exc.relocated("config", where) from None
    return config


def run(args, out) -> int:
    from ringtune.envs.evaluate import evaluate_detailed, resolve_printer

    config = build_config(args, out)
    if args.gcode and not Path(args.gcode).is_file():
        raise RingtuneError("no such G-code file", f"--gcode {args.gcode}")
    if args.plot:  # before simulating: a folder that cannot be made fails now, in one line
        try:
            Path(args.plot).mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise RingtuneError(f"cannot create the plot folder: {exc.strerror or exc}",
                                f"--plot {args.plot}") from None
    printer = resolve_printer(args.printer)
    out.note(f"simulating {config.shaper_x}/{config.shaper_y} on {printer.name} ({args.backend}) ...")
    ev = evaluate_detailed([config], printer, args.gcode, backend=args.backend)[0]
    if args.trace:
        from ringtune.agents.trace_option import write_trace_option

        write_trace_option(args.trace, ev, config, printer, args.gcode, args.backend, out)
    m = ev.metrics
    windows = []
    for w, part in zip(ev.planned.windows, m.details.get("windows", [])):
        windows.append({"t0": float(w.t0), "t1": float(w.t1), "kind": str(getattr(w, "kind", "")),
                        **{k: part[k] for k in ("path_error_mm", "overshoot_mm", "ringing_mm",
                                                "peak_accel", "step_loss", "motor_load")}})
    plots = []
    if args.plot:
        from ringtune.envs.plots import plot_evaluation

        plots = [str(p) for p in plot_evaluation(ev, args.plot)]
    result = {
        "printer": printer.name,
        "job": args.gcode or "built-in test print",
        "backend": args.backend,
        "config": config.to_dict(),
        "metrics": m.to_dict(),
        "windows": windows,
        "plots": plots,
        **({"trace": args.trace} if args.trace else {}),
    }
    c = config
    lines = [
        f"printer {printer.name}, job {result['job']}, backend {args.backend}",
        f"config  {c.firmware}: X {c.shaper_x} {c.freq_x:g} Hz S {c.damping_x:g}, "
        f"Y {c.shaper_y} {c.freq_y:g} Hz S {c.damping_y:g}, freq limit "
        f"{(f'{c.freq_limit_hz:g} Hz' if c.freq_limit_hz else 'off')}"
        + (f", accel {c.accel:g} mm/s²" if c.accel else ""),
        f"print time   {m.print_time_s:10.2f} s",
        f"path error   {m.path_error_mm:10.4f} mm",
        f"overshoot    {m.overshoot_mm:10.4f} mm",
        f"ringing      {m.ringing_mm:10.4f} mm RMS",
        f"peak accel   {m.peak_accel:10.0f} mm/s²",
        f"step loss    {'YES' if m.step_loss else 'no':>10}",
        f"motor load   {m.motor_load * 100:>9.0f} %  of the force the motors have",
        f"({len(windows)} quality windows simulated)",
    ] + [f"plot: {p}" for p in plots]
    out.emit(result, "\n".join(lines))
    return 0
