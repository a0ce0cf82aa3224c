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
    belts: see ``ringtune graph belts --help``
    speeds: see ``ringtune graph speeds --help``
"""

from __future__ import annotations

import argparse

NAME = "graph"
HELP = "Klipper-style graphs: shapers over the spectrum, CoreXY belts, vibration against speed (PNG + --json)"
DESCRIPTION = """\
The graphs Klipper users read, from the same files, with ringtune's own numbers beside them.

  shapers ACCEL.csv... [--config best.json]: Klipper's calibrate_shaper graph — each axis's
      spectrum with the modes identify fits to it, every candidate shaper's remaining vibration over
      it, Klipper's pick and (with --config) ringtune's choice marked, and the table of frequency,
      remaining vibrations, smoothing and max_accel, computed as Klipper computes them.

examples:
  ringtune graph shapers resonances_x_*.csv resonances_y_*.csv -o shapers.png
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
    sh.add_argument("--scv", type=float, default=5.0, help="square-corner velocity, mm/s (default 5, Klipper's)")
    sh.add_argument("--axis", choices=("x", "y"), help="axis of every file (default: from the file name)")
    _json_flag(sh)


def _json_flag(s: argparse.ArgumentParser) -> None:
    s.add_argument("--json", action="store_true", default=argparse.SUPPRESS,
                   help="print one JSON object with stable keys")


def check_plot_path(path: str) -> None:
    """Refuse, before any work, a graph path of the wrong kind or in a missing folder."""
    from pathlib import Path

    from ringtune.agents.cli.common import check_output_folder
    from ringtune.shaping.errors import RingtuneError

    if Path(path).suffix.lower() not in PLOT_SUFFIXES:
        raise RingtuneError(f"the graph's file name must end in one of {', '.join(PLOT_SUFFIXES)}", f"-o {path}")
    check_output_folder("-o", path)


def run(args, out) -> int:
    return {"shapers": _run_shapers}[args.graph](args, out)


def _run_shapers(args, out) -> int:
    from ringtune.agents.cli.common import load_config
    from ringtune.agents.identify.graph import shaper_graph
    from ringtune.agents.identify.graph_plot import plot_shaper_graph, table_rows
    from ringtune.shaping.errors import RingtuneError

    check_plot_path(args.output)
    if not args.scv >= 0:
        raise RingtuneError(f"must be ≥ 0 mm/s, not {args.scv}", "--scv")
    config = load_config(args.config, out) if args.config else None
    graphs, warnings = shaper_graph(args.files, config, args.scv, args.axis)
    if not graphs:
        raise RingtuneError("no resonance spectrum among the files (an M956 capture is one move's "
                            "ringing, not a sweep)", args.files[0])
    for w in warnings:
        out.note(f"warning: {w}")
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
