"""``ringtune graph``: the graphs a Klipper user reads — shapers over the measured spectrum, the
CoreXY belt comparison, and vibration against speed — each a PNG and the same numbers as ``--json``.

A command of its own rather than ``identify --plot``: ``identify`` writes a printer description and
its ``--plot`` shows how well the modes fit; these graphs are read before (and without) building
one, like Klipper's ``calibrate_shaper.py -o`` and Shake&Tune, and two of them are not about files
at all (speeds come from a printer model and a job).

``--json`` keys (stable), per graph:
    shapers: {graph: "shapers", plot, warnings, axes: [{axis, sources, scv (mm/s), freqs_hz,
        psd {x, y, z, sum} (normalised as Klipper: / (f + 0.1 Hz)), fitted_psd, modes [{freq (Hz),
        damping, share}], shapers [{shaper, freq (Hz), damping, flavor, vibrations_pct, smoothing_mm,
        max_accel (mm/s², rounded to 100 as Klipper prints; null: no limit), score, residual (ratio
        per freqs_hz)}], klipper (the pick, same keys), ringtune (the --config's shaper, same keys,
        or null), after_shaper_psd, notes}]}
    belts: {graph: "belts", plot, notes, sources {a, b}, similarity_pct, similarity_definition,
        pairs [{freq_a, amp_a, freq_b, amp_b, freq_diff_hz (B − A), amp_diff_pct ((A − B) / mean)}],
        mismatch ((k_A − k_B)/mean, null without --printer), mismatch_error (one standard error),
        stiffness_a_n_m, stiffness_b_n_m, matched, meaning, freqs_hz {a, b}, psd {a, b},
        model_psd {a, b} (the fitted model, scaled; {} without --printer)}
    speeds: {graph: "speeds", plot, printer, speeds_mm_s, ripple_mm {direction: per speed (peak-to-peak
        across the wall, as simulate's ripple_mm)}, bands [{direction ("x": walls along X, "y", CoreXY "a"/"b":
        the diagonals), lo, hi, peak_speed (mm/s), peak_ripple_mm}], wall_length_mm, corner_deg, accel
        (mm/s²), band_level, orcaslicer {resonance_avoidance, min_resonance_avoidance_speed,
        max_resonance_avoidance_speed} (the worst band; {} without one), notes}
"""

from __future__ import annotations

import argparse
from pathlib import Path

from ringtune.agents.cli.common import GCODE_JOB_HELP, check_output_folder, gcode_job, load_config
from ringtune.agents.cli.options import VALUES
from ringtune.agents.identify.belts import compare_belts, read_belt_tests
from ringtune.agents.identify.belts_plot import pair_rows, plot_belts, summary_lines
from ringtune.agents.identify.graph import shaper_graph
from ringtune.agents.identify.graph_plot import plot_shaper_graph, table_rows
from ringtune.agents.tune.speeds import speed_advice
from ringtune.agents.tune.speeds_plot import band_lines, plot_speeds
from ringtune.envs.printer import load_printer
from ringtune.shaping.errors import RingtuneError

NAME = "graph"
DESCRIPTION = """\
The graphs Klipper users read, from the same files, with ringtune's own numbers beside them.

  shapers ACCEL.csv... [--config best.json]: Klipper's calibrate_shaper graph — each axis's
      spectrum with the modes identify fits to it, every candidate shaper's remaining vibration over
      it, Klipper's pick and (with --config) ringtune's choice marked, and the table of frequency,
      remaining vibrations, smoothing and max_accel, computed as Klipper computes them.

  belts AXIS_1_1.csv AXIS_1_-1.csv [--printer P]: the CoreXY belt comparison (Klipper's
      TEST_RESONANCES AXIS=1,1 and AXIS=1,-1) — both spectra overlaid, their similarity (defined on
      the figure), the paired peaks with their frequency and amplitude differences, and, with a
      CoreXY printer description, the two belts' stiffnesses that explain the difference.

  speeds [--printer P] [--gcode G] [--config C]: vibration against speed — the ripple a typical wall
      of the job (its length-weighted median length, after its median corner) shows at each speed,
      per wall direction (CoreXY: the belts' diagonals too), simulated on the printer model with
      the configuration's acceleration and shapers; the bands to avoid, and the worst one in
      OrcaSlicer's resonance-avoidance keys (outer walls).

examples:
  ringtune graph shapers resonances_x_*.csv resonances_y_*.csv -o shapers.png
  ringtune graph belts resonances_axis=1.000,1.000,0.000_b.csv resonances_axis=1.000,-1.000,0.000_b.csv \\
      --printer voron.toml -o belts.png
  ringtune graph speeds --printer myprinter.toml --gcode job.gcode --config tuned/best.json -o speeds.png
  ringtune graph shapers resonances_*.csv --config tuned/best.json --scv 5 -o shapers.png --json
"""

PLOT_SUFFIXES = (".png", ".pdf", ".svg")


def add_arguments(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="graph", metavar="GRAPH", required=True)
    sh = sub.add_parser("shapers", help="Klipper's shaper graph with ringtune's choice",
                        description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    sh.add_argument("files", nargs="+", metavar="ACCEL.csv", help="Klipper resonance files (one or more per axis)")
    sh.add_argument("-o", "--output", required=True, metavar="OUT.png", help="the graph (.png, .pdf or .svg)")
    sh.add_argument("--config", metavar="best.json", help="a TuneConfig (tune's best.json): mark its shapers")
    sh.add_argument("--scv", type=VALUES["scv"], default=5.0, help="square-corner velocity, mm/s (default 5, Klipper's)")
    sh.add_argument("--axis", choices=("x", "y"), help="axis of every file (default: from the file name)")
    _json_flag(sh)
    be = sub.add_parser("belts", help="CoreXY belt comparison from the two diagonal tests",
                        description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    be.add_argument("files", nargs=2, metavar="DIAGONAL.csv", help="TEST_RESONANCES AXIS=1,1 and AXIS=1,-1 files")
    be.add_argument("-o", "--output", required=True, metavar="OUT.png", help="the graph (.png, .pdf or .svg)")
    be.add_argument("--printer", metavar="P", help="CoreXY printer description (TOML or embedded name): "
                    "turn the difference into the two belts' stiffnesses")
    _json_flag(be)
    sp = sub.add_parser("speeds", help="vibration against speed, bands to avoid (OrcaSlicer keys)",
                        description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    sp.add_argument("-o", "--output", required=True, metavar="OUT.png", help="the graph (.png, .pdf or .svg)")
    sp.add_argument("--printer", metavar="P", help="printer TOML or embedded name (default: the embedded ender3)")
    sp.add_argument("--gcode", metavar="G", type=gcode_job, help=f"the job whose walls to judge, {GCODE_JOB_HELP} "
                    "(default: a 40 mm square's walls)")
    sp.add_argument("--config", metavar="best.json", help="shaping and acceleration printed with (default: "
                    "shaping off at the printer's acceleration)")
    sp.add_argument("--step", type=VALUES["speed"], default=5.0, help="speed step, mm/s (default 5)")
    _json_flag(sp)


def _json_flag(s: argparse.ArgumentParser) -> None:
    s.add_argument("--json", action="store_true", default=argparse.SUPPRESS,
                   help="print one JSON object with stable keys")


def check_plot_path(path: str) -> None:
    """Refuse, before any work, a graph path of the wrong kind or in a missing folder."""
    if Path(path).suffix.lower() not in PLOT_SUFFIXES:
        raise RingtuneError(f"the graph's file name must end in one of {', '.join(PLOT_SUFFIXES)}", f"-o {path}")
    check_output_folder("-o", path)


def run(args, out) -> int:
    return {"shapers": _run_shapers, "belts": _run_belts, "speeds": _run_speeds}[args.graph](args, out)


def _run_speeds(args, out) -> int:
    check_plot_path(args.output)
    printer = load_printer(args.printer)
    if not args.printer:
        out.note(f"note: no --printer: the embedded {printer.name}")
    config = load_config(args.config, out)
    advice = speed_advice(printer, args.gcode, config, step=args.step)
    out.note(*advice.notes, kind="note")
    plot_speeds(advice, args.output, printer.name)
    orca = advice.orcaslicer()
    lines = ["speeds to avoid (ripple ≥ 1/√2 of the direction's worst):", *("  " + b for b in band_lines(advice)),
             "OrcaSlicer (printer settings): " + (", ".join(f"{k} = {v}" for k, v in orca.items()) or "no band"),
             f"wrote {args.output}"]
    out.emit({"graph": "speeds", "plot": args.output, "printer": printer.name, **advice.to_dict()}, "\n".join(lines))
    return 0


def _run_belts(args, out) -> int:
    check_plot_path(args.output)
    printer = load_printer(args.printer) if args.printer else None
    tests, notes = read_belt_tests(args.files)
    c = compare_belts(tests, printer)
    out.note(*notes, *c.notes, kind="note")
    plot_belts(c, args.output)
    lines = summary_lines(c) + ["paired peaks: " + "; ".join(
        f"A {a} Hz / B {b} Hz (B − A {d} Hz, amplitude A − B {p} %)" for a, b, d, p in pair_rows(c)),
        c.meaning(), f"wrote {args.output}"]
    out.emit({"graph": "belts", "plot": args.output, "notes": notes + c.notes, **c.to_dict()}, "\n".join(lines))
    return 0


def _run_shapers(args, out) -> int:
    check_plot_path(args.output)
    config = load_config(args.config, out)
    graphs, warnings = shaper_graph(args.files, config, args.scv, args.axis)
    if not graphs:
        raise RingtuneError("no resonance spectrum among the files (an M956 capture is one move's "
                            "ringing, not a sweep)", args.files[0])
    out.note(*warnings, kind="warning")
    plot_shaper_graph(graphs, args.output)
    lines = []
    for g in graphs:
        lines.append(f"axis {g.axis.upper()} ({', '.join(g.sources)}): Klipper's pick {g.klipper.fit.name} @ "
                     f"{g.klipper.fit.freq:.1f} Hz")
        lines += ["  " + "  ".join(f"{c:>10}" for c in row) for row in table_rows(g)]
    lines.append(f"wrote {args.output}")
    out.emit({"graph": "shapers", "plot": args.output, "warnings": warnings,
              "axes": [g.to_dict() for g in graphs]}, "\n".join(lines))
    return 0
