"""``ringtune study``: how each shaper's print time and quality respond to one factor (the sweep is
:mod:`ringtune.agents.tune.sweep`).

Factors: ``freq-error`` (the shaper frequency off by a fraction of its tuned value, -0.3..0.3),
``mass`` (print mass on the bed, kg, 0..1; the shapers stay tuned for the empty bed) and
``accel`` (printing acceleration, mm/s²). Each shaper starts tuned as Klipper's rule tunes it on
the printer's simulated resonance test (shapers outside Klipper's list: the axis's main mode).

``--json`` keys (stable): factor, unit, values, quality, freq_margin (fraction), judgement (how the
quality was judged, in words), shapers {name: {freq_x, freq_y, print_time_s: [...], quality_mm:
[...], step_loss: [...]}}, plot, csv.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

from ringtune.agents.cli.common import GCODE_JOB_HELP, firmware_name, gcode_job, judgement, say_unmeasured
from ringtune.agents.cli.options import VALUES, number_list
from ringtune.agents.tune.pareto import words
from ringtune.agents.tune.sweep import (FACTORS, factor_values, offered_shapers, plot_sweep, sweep,
    tuned_frequencies, write_csv)
from ringtune.envs.planned_job import resolve_printer
from ringtune.envs.variants import DEFAULT_FREQ_MARGIN

NAME = "study"
#: the --quality choices: a visible measure or a whole-path one, in mm (``<name>_mm`` of the metrics)
STUDY_QUALITIES = ("ripple", "ripple_p90", "corner_in", "corner_out", "overshoot", "path_error")
DESCRIPTION = """\
Sweep one factor and see how every shaper of the firmware responds, in print time and quality:

  freq-error  the shaper frequency wrong by -30 %..+30 % (how robust is each shaper?)
  mass        print mass on the bed, 0..1 kg (a bed slinger's Y resonance drops as the print grows)
  accel       printing acceleration (faster prints against more ringing and smoothing)

Each shaper is tuned first (Klipper's rule on the printer's simulated resonance test) and then
the factor is varied. Quality is judged as `ringtune tune` judges it, the worst of the model and
of its resonances --freq-margin per cent lower and higher with damping ×0.75 (default 5), except for
freq-error, whose sweep itself moves the shaper against the resonances: that one judges the exact
model unless --freq-margin is given. The output says which. --quality picks the measure: ripple (the
default, as tune's: the worst visible wall's peak-to-peak ripple), ripple_p90 (its 90th
percentile), corner_in / corner_out (the visible corners' rounding / overshoot), overshoot or
path_error (the whole path's, hidden features included). Writes a PNG (two panels: print time and
the measure against the factor, one line per shaper) and a CSV.

examples:
  ringtune study --factor freq-error
  ringtune study --factor mass --values 0,0.25,0.5,1.0 --printer ender3 -o mass.png
  ringtune study --factor accel --firmware rrf --shapers mzv,zvd,zvdd
"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--factor", choices=("freq-error", "mass", "accel"), default="freq-error",
                   help="what to sweep (default freq-error)")
    p.add_argument("--values", metavar="A,B,...", type=number_list, help="factor values (default: a range per factor)")
    p.add_argument("--printer", metavar="P", help="printer TOML (default: the embedded Ender-3-class printer)")
    p.add_argument("--gcode", metavar="G", type=gcode_job,
                   help=f"G-code job, {GCODE_JOB_HELP} (default: the built-in test print)")
    p.add_argument("--firmware", type=firmware_name, default="klipper", help="target firmware (default klipper)")
    p.add_argument("--shapers", metavar="S1,S2", help="shapers to compare (default: all the firmware offers)")
    p.add_argument("--quality", choices=STUDY_QUALITIES, default="ripple",
                   help="the measure plotted against the factor (default ripple, as tune)")
    p.add_argument("--backend", choices=("mujoco", "lti"), default="mujoco")
    p.add_argument("--freq-margin", metavar="PCT", type=VALUES["margin_percent"], default=None,
                   help="judge also with every resonance PCT %% lower and higher, the worst counts (default "
                        "5 as tune, 0 for --factor freq-error)")
    p.add_argument("-o", "--output", metavar="PNG", help="plot file (default ringtune-study-<factor>.png)")


def run(args: argparse.Namespace, out) -> int:
    if args.freq_margin is None:
        margin = 0.0 if args.factor == "freq-error" else DEFAULT_FREQ_MARGIN
    else:
        margin = args.freq_margin / 100.0
    printer = resolve_printer(args.printer)
    say_unmeasured(printer, out)
    quality = f"{args.quality}_mm"
    shapers = offered_shapers(args.firmware, args.shapers.split(",") if args.shapers else None)
    values = factor_values(args.factor, printer, args.values)
    tuned = tuned_frequencies(printer, args.firmware, shapers, note=lambda m: out.note(f"ringtune study: {m}"))
    results = sweep(printer, args.gcode, args.firmware, args.factor, values, tuned, quality, args.backend,
                    freq_margin=margin)
    png = Path(args.output or f"ringtune-study-{args.factor}.png")
    csv_path = png.with_suffix(".csv")
    name = getattr(printer, "name", "printer")
    job = Path(args.gcode).name if args.gcode else "built-in test print"
    judged = judgement(margin)
    plot_sweep(png, args.factor, values, results, quality, f"{name} · {job} · {args.firmware}\nquality judged {judged}")
    write_csv(csv_path, args.factor, values, results, quality)
    shapers_json = {s: dataclasses.asdict(r) for s, r in results.items()}
    out.emit({"factor": args.factor, "unit": FACTORS[args.factor][1], "values": list(values), "quality": quality,
              "freq_margin": margin, "judgement": judged, "shapers": shapers_json, "plot": str(png),
              "csv": str(csv_path)},
             _text(args, name, values, results, quality, judged) + f"\nplot: {png}   table: {csv_path}")
    return 0


def _text(args, name: str, values, results: dict, quality: str, judged: str) -> str:
    """The sweep as a table: per shaper and factor value, quality (µm) / print time (s), ! for lost steps."""
    label, unit, _ = FACTORS[args.factor]
    word = words(quality)[0]
    lines = [f"{label} ({unit}) sweep on {name}, {args.firmware}; {word} in µm / print time in s; "
             f"quality judged {judged}:",
             "  " + f"{'shaper':10}" + "".join(f"{v:>10g} " for v in values)]
    for s, r in results.items():
        lines.append("  " + f"{s:10}" + "".join(
            f"{q * 1000:7.1f}/{t:4.2f}" + ("!" if sl else " ")
            for q, t, sl in zip(r.quality_mm, r.print_time_s, r.step_loss)))
    lines.append("  (! = lost steps)")
    return "\n".join(lines)
