"""``ringtune testprint``: calibration prints for printers without an accelerometer.

``--json`` keys (stable):
    kind: "ringing" | "accel"; firmware; output (path written, or null)
    bands (ringing): [{number, z0, z1 (mm), freq_x, freq_y (Hz, 0 = off), shaper, damping, lines}];
        speed (wall speed, mm/s), accel (mm/s²)
    rungs (accel): [{number, accel (mm/s²), of_tuned (fraction)}]; tuned_accel (mm/s²)
    measure: lines saying what to measure or look for (also written into the file)
    notes: what was decided for you (defaults)
"""

from __future__ import annotations

import argparse
from pathlib import Path

from ringtune.agents.cli.common import check_output_folder, firmware_name, load_config
from ringtune.agents.cli.options import VALUES, Value
from ringtune.agents.identify.testprints import accel_ladder, ringing_tower
from ringtune.envs.printer import load_printer
from ringtune.shaping import calibration_prints as cp
from ringtune.shaping.errors import RingtuneError

NAME = "testprint"
DESCRIPTION = """\
Write a calibration print in the firmware's own G-code, with what to measure as comments.

  ringing  a single-wall square tower printed at one constant speed with sharp corners, for
           measuring ringing without an accelerometer. --no-shaping: shaping off, measure the
           ripple spacing with calipers and run `ringtune identify --ripples` (seed 000:
           frequency = speed / spacing). --bands F0:F1:N: N height bands, each printed with the
           shaper at another frequency (the lines `ringtune export` writes: M593, M493,
           SET_INPUT_SHAPER); pick the calmest band per axis and run
           `ringtune identify --tower-band`.
  accel    a check of a tuned acceleration on the machine before you print with it: rungs of
           fast moves from the current acceleration up to the tuned one and 20 % beyond, each
           returning to a reference point where it draws a short dash; a dash out of line means
           skipped steps.

The band or ladder table and what to look for are printed and written into the file. The file
starts by heating (--hotend, --bed) and homing (G28); it assumes a bed with room around --centre.

examples:
  ringtune testprint ringing --firmware marlin --no-shaping -o ripples.gcode
  ringtune identify --ripples X=2.1,Y=2.5 --speed 100 -o printer.toml
  ringtune testprint ringing --firmware klipper --bands 30:70:9 -o tower.gcode
  ringtune identify --tower-band X=4,Y=6 --tower tower.gcode -o printer.toml
  ringtune testprint accel --firmware rrf --config best.json --printer printer.toml -o accel.gcode
"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("kind", choices=("ringing", "accel"), help="which print")
    p.add_argument("--firmware", type=firmware_name, required=True,
                   help="klipper, marlin, marlin-ftm, rrf, rrf35, rrf34, prusa")
    p.add_argument("--printer", metavar="P", help="printer TOML or embedded name (default: ender3): "
                   "its acceleration and speed limits")
    p.add_argument("-o", "--output", metavar="FILE.gcode", help="write the G-code here (else only the table)")
    p.add_argument("--centre", metavar="X,Y", help="middle of the print on the bed, mm (default 110,110)")
    p.add_argument("--nozzle", type=float, help="nozzle diameter, mm (0.4)")
    p.add_argument("--layer", type=float, help="layer height, mm (0.2)")
    p.add_argument("--filament", type=float, help="filament diameter, mm (1.75)")
    p.add_argument("--hotend", type=HOTEND, help="nozzle temperature, °C (210, PLA)")
    p.add_argument("--bed", type=BED, help="bed temperature, °C (60, PLA)")
    r = p.add_argument_group("ringing")
    r.add_argument("--speed", type=VALUES["speed"], help="ringing: wall speed, mm/s (default 100, at most the "
                   "printer's); accel: speed of the fast moves (default the printer's top speed)")
    r.add_argument("--accel", type=VALUES["accel"], help="ringing: acceleration, mm/s² (default the printer's)")
    mode = r.add_mutually_exclusive_group()
    mode.add_argument("--bands", type=bands, metavar="F0:F1:N", help="N bands of shaper frequency from F0 to F1 Hz "
                      "(default 25:75:11)")
    mode.add_argument("--no-shaping", action="store_true", help="shaping off: measure ripples")
    r.add_argument("--band-height", type=VALUES["length"], default=4.0, help="height of each band, mm (4)")
    r.add_argument("--height", type=VALUES["length"], help="tower height with --no-shaping, mm (10)")
    r.add_argument("--shaper", help="shaper of the bands (default: the narrowest the firmware has, zv or mzv)")
    r.add_argument("--damping", type=VALUES["damping_ratio"], help="shaper damping of the bands (default: the firmware's)")
    r.add_argument("--side", type=VALUES["length"], default=60.0, help="side of the square tower, mm (60)")
    a = p.add_argument_group("accel")
    a.add_argument("--config", metavar="best.json", help="accel: the tuned TuneConfig (its accel and shaper)")
    a.add_argument("--from", dest="start_accel", type=VALUES["accel"], metavar="A",
                   help="accel: first rung, mm/s² (default: the printer's current acceleration)")
    a.add_argument("--rungs", type=VALUES["count"], default=5, help="accel: rungs from --from to the tuned value (5), "
                   "then 110 %% and 120 %%")
    a.add_argument("--reach", type=VALUES["length"], default=40.0, help="accel: mm each way from the reference point (40)")
    a.add_argument("--reps", type=VALUES["count"], default=3, help="accel: pattern repetitions per rung (3)")


def _centre(text: str | None, out) -> tuple[float, float]:
    if text is None:
        out.note("centre of the print on the bed: X110 Y110 (an Ender-3's 220 mm bed); give --centre X,Y")
        return 110.0, 110.0
    try:
        x, y = (float(v) for v in text.split(","))
    except ValueError:
        raise RingtuneError(f"expected X,Y in mm, not {text!r}", "--centre") from None
    return x, y


#: plausible targets: a nozzle hot enough to extrude anything printable and within what a hotend
#: survives (PTFE-lined ones stop near 250 °C, all-metal ones near 300-450 °C); a bed off or up to 150 °C
HOTEND = Value("a nozzle temperature", "°C", 150.0, 450.0, low_closed=True)
BED = Value("a bed temperature", "°C", 0.0, 150.0, low_closed=True)
#: what the print assumes when not told (said on stderr)
MATERIAL = {"nozzle": 0.4, "layer": 0.2, "filament": 1.75, "hotend": 210.0, "bed": 60.0}


def _material(args, out) -> None:
    missing = [k for k, v in MATERIAL.items() if getattr(args, k) is None]
    for k in missing:
        setattr(args, k, MATERIAL[k])
    if missing:
        out.note("assumed " + ", ".join(f"--{k} {MATERIAL[k]:g}" for k in missing)
                 + " (mm, °C; PLA on a 0.4 mm nozzle)")


#: Hz: where a ringing tower's bands may lie — printers' X/Y resonances and the shapers that cancel
#: them (FT_MOTION and Prusa Buddy start at 10 Hz; Klipper's rule tests shaper frequencies up to 150 Hz)
BAND_RANGE = (10.0, 150.0)


def bands(text: str) -> tuple[float, float, int]:
    """argparse type of --bands ``F0:F1:N`` -> (F0 Hz, F1 Hz, N bands), the bands within
    :data:`BAND_RANGE`."""
    try:
        f0, f1, n = text.split(":")              # not three parts: a ValueError too
        f0, f1, n = float(f0), float(f1), int(n)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected F0:F1:N (Hz, Hz, bands), not {text!r}") from None
    for f in (f0, f1):
        if not BAND_RANGE[0] <= f <= BAND_RANGE[1]:
            raise argparse.ArgumentTypeError(
                f"a band at {f:g} Hz is outside {BAND_RANGE[0]:g}-{BAND_RANGE[1]:g} Hz, where printers resonate "
                "and shapers are tuned (FT_MOTION and Prusa start at 10 Hz, Klipper's rule tests up to 150 Hz)")
    return f0, f1, n


#: the bands without --bands: 25 to 75 Hz in 5 Hz steps
DEFAULT_BANDS = (25.0, 75.0, 11)


def run(args, out) -> int:
    check_output_folder("-o", args.output)
    printer = load_printer(args.printer)
    cx, cy = _centre(args.centre, out)
    _material(args, out)
    ext = cp.Extrusion(args.nozzle, args.layer, args.filament)
    ext.validate()
    lim = printer.limits
    _check_kind(args)
    result, text, gcode = _PRINTS[args.kind](args, out, printer, lim, cx, cy, ext)
    if args.output:
        Path(args.output).write_text(gcode)
        out.note(f"wrote {args.output}")
    out.emit({"kind": args.kind, "firmware": args.firmware, "output": args.output, **result}, text)
    return 0


def _ladder_speed(given, config, velocity: float, name: str) -> tuple[float, str]:
    """Speed of the ladder's fast moves (mm/s) and why: ``--speed``, else the top speed the tuned
    acceleration was judged at (``top_speed_mm_s`` in the config, written by ``tune``), else the
    printer's velocity limit."""
    if given is not None:
        return float(given), "--speed"
    top = config.extra.get("top_speed_mm_s")
    if type(top) in (int, float) and 0 < top <= velocity:     # a number, not a bool
        return float(top), "the top speed the tuned acceleration was judged at (the config's top_speed_mm_s)"
    return float(velocity), f"{name}'s top speed"


def _on_the_bed(option: str, what: str, x_min: float, y_min: float) -> None:
    """Refuse a print that would move below X0 or Y0, off the bed of any printer (--centre too near
    the front-left corner for this size)."""
    if x_min < 0 or y_min < 0:
        raise RingtuneError(f"{what} reaches X{x_min:.1f} Y{y_min:.1f}, off the bed; move --centre or make "
                            "it smaller", option)


#: options of one kind of print only: kind -> ((destination, flag), …)
ONLY_FOR = {"accel": (("config", "--config"), ("start_accel", "--from")),
            "ringing": (("bands", "--bands"), ("no_shaping", "--no-shaping"), ("accel", "--accel"))}


def _check_kind(args) -> None:
    """Refuse an option of the other kind of print."""
    for kind, options in ONLY_FOR.items():
        given = [flag for dest, flag in options if getattr(args, dest)]
        if given and kind != args.kind:
            flags = [flag for _, flag in options]
            raise RingtuneError(f"{', '.join(flags[:-1])} and {flags[-1]} belong to testprint {kind}", given[0])


def _tower_bands(args, out):
    """(F0 Hz, F1 Hz, N) of the tower's bands, or None with --no-shaping."""
    if args.no_shaping:
        return None
    if args.bands is None:
        out.note("bands 25:75:11 (25 to 75 Hz in 5 Hz steps); give --bands F0:F1:N")
        return DEFAULT_BANDS
    return args.bands


def _ringing(args, out, printer, lim, cx, cy, ext):
    if args.height is not None and not args.no_shaping:
        raise RingtuneError("goes with --no-shaping (with bands the height is N × --band-height)", "--height")
    speed, accel = _wall_speed_and_accel(args, out, printer, lim)
    height = 10.0 if args.height is None else args.height
    bands = _tower_bands(args, out)
    # the prime line runs 12 mm in front of the tower, the brim 3 lines around it
    _on_the_bed("--side", f"a {args.side:g} mm tower at X{cx:g} Y{cy:g} with its brim and prime line",
                cx - args.side / 2 - 3 * ext.line_width, cy - args.side / 2 - 12.0)
    geom = cp.TowerGeometry(cx - args.side / 2, cy - args.side / 2, args.side, speed,
                            min(25.0, speed), min(150.0, lim.velocity))
    plan = ringing_tower(args.firmware, speed=speed, accel=accel, bands=bands, band_height=args.band_height,
                         height=height, shaper=args.shaper, damping=args.damping, geometry=geom,
                         ext=ext, hotend=args.hotend, bed=args.bed, printer_name=printer.name)
    out.note(*plan.notes)
    table = [b.table_line().lstrip("; ") for b in plan.bands]
    result = {"bands": [{"number": b.number, "z0": b.z0, "z1": b.z1, "freq_x": b.freq_x, "freq_y": b.freq_y,
                         "shaper": b.shaper, "damping": b.damping, "lines": b.lines} for b in plan.bands],
              "measure": plan.measure, "notes": plan.notes, "speed": speed, "accel": accel}
    return result, "\n".join(["band table:", *table, "", *plan.measure]), plan.gcode


def _wall_speed_and_accel(args, out, printer, lim) -> tuple[float, float]:
    """The tower's wall speed (mm/s) and acceleration (mm/s²): given, else the printer's (said);
    the wall must be long enough to reach the speed and then show several ripples."""
    speed = args.speed
    if speed is None:
        speed = min(100.0, lim.velocity)
        out.note(f"wall speed {speed:g} mm/s (--speed to change; faster spreads the ripples wider)")
    if speed > lim.velocity:
        raise RingtuneError(f"{speed:g} mm/s is above {printer.name}'s top speed {lim.velocity:g} mm/s", "--speed")
    accel = args.accel
    if accel is None:
        accel = lim.accel
        out.note(f"acceleration {accel:.0f} mm/s²: {printer.name}'s (--accel to change)")
    if speed ** 2 / accel > args.side / 3:
        raise RingtuneError(f"at {accel:.0f} mm/s² the head needs {speed ** 2 / (2 * accel):.1f} mm to reach "
                            f"{speed:g} mm/s: too much of a {args.side:g} mm wall; raise --accel or --side",
                            "--speed")
    return speed, accel


def _accel(args, out, printer, lim, cx, cy, ext):
    if not args.config:
        raise RingtuneError("testprint accel needs the tuned configuration", "--config")
    config = load_config(args.config, out)
    if config.accel is None:
        raise RingtuneError("has no accel: nothing to check (tune with an acceleration search, or add "
                            '"accel": A)', args.config)
    start = args.start_accel if args.start_accel is not None else _start_accel(out, printer, lim, config)
    speed, whence = _ladder_speed(args.speed, config, lim.velocity, printer.name)
    if args.speed is None:
        out.note(f"fast moves at {speed:g} mm/s: {whence} (--speed to change)")
    _on_the_bed("--reach", f"{args.reach:g} mm each way from X{cx:g} Y{cy:g}", cx - args.reach, cy - args.reach)
    geom = cp.LadderGeometry(cx, cy, args.reach, speed, args.reps)
    try:
        plan = accel_ladder(args.firmware, config, start_accel=start, rungs=args.rungs, geometry=geom,
                            ext=ext, hotend=args.hotend, bed=args.bed, printer_name=printer.name)
    except RingtuneError as exc:
        raise exc.relocated("config", args.config) from None
    out.note(*plan.notes)
    tuned = float(config.accel)
    result = {"rungs": [{"number": k, "accel": a, "of_tuned": a / tuned} for k, a in enumerate(plan.accels, 1)],
              "tuned_accel": tuned, "measure": plan.table, "notes": plan.notes}
    return result, "\n".join(["ladder table:", *plan.table]), plan.gcode


def _start_accel(out, printer, lim, config) -> float:
    """The ladder's first rung without --from: what the printer runs now, else its limit (said)."""
    current = printer.current
    if current.get("accel"):
        start, whence = float(current["accel"]), f"what {printer.name} runs now ([current] accel)"
    else:
        start, whence = lim.accel, f"{printer.name}'s [limits] accel"
    if start < float(config.accel):
        out.note(f"first rung {start:.0f} mm/s²: {whence} (--from to change)")
    else:
        out.note(f"starting acceleration {start:.0f} mm/s²: {whence} (--from to change)")
    return start


#: kind -> the function that makes that print: (result, text, G-code)
_PRINTS = {"ringing": _ringing, "accel": _accel}
