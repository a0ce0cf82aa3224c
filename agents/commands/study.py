"""``ringtune study``: how each shaper's print time and quality respond to one factor.

Factors: ``freq-error`` (the shaper frequency off by a fraction of its tuned value, -0.3..0.3),
``mass`` (print mass on the bed, kg, 0..1; the shapers stay tuned for the empty bed) and
``accel`` (printing acceleration, mm/s²). Each shaper starts tuned as Klipper's rule tunes it on
the printer's simulated resonance test (shapers outside Klipper's list: the axis's main mode).

``--json`` keys (stable): factor, unit, values, quality, shapers {name: {freq_x, freq_y,
print_time_s: [...], quality_mm: [...], step_loss: [...]}}, plot, csv.
"""

from __future__ import annotations

import argparse
from pathlib import Path

NAME = "study"
HELP = "trade-off study: sweep one factor and plot each shaper's print time and quality"
DESCRIPTION = """\
Sweep one factor and see how every shaper of the firmware responds, in print time and quality:

  freq-error  the shaper frequency wrong by -30 %..+30 % (how robust is each shaper?)
  mass        print mass on the bed, 0..1 kg (a bed slinger's Y resonance drops as the print grows)
  accel       printing acceleration (faster prints against more ringing and smoothing)

Each shaper is tuned first (Klipper's rule on the printer's simulated resonance test) and then
the factor is varied. Writes a PNG (two panels: print time and quality against the factor, one
line per shaper) and a CSV.

examples:
  ringtune study --factor freq-error
  ringtune study --factor mass --values 0,0.25,0.5,1.0 --printer ender3 -o mass.png
  ringtune study --factor accel --firmware rrf --shapers mzv,zvd,zvdd
"""

FACTORS = {"freq-error": ("shaper frequency error", "fraction", (-0.3, 0.3, 13)),
           "mass": ("print mass on the bed", "kg", (0.0, 1.0, 6)),
           "accel": ("acceleration", "mm/s²", None)}


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--factor", choices=tuple(FACTORS), default="freq-error", help="what to sweep (default freq-error)")
    p.add_argument("--values", metavar="A,B,...", help="factor values (default: a range per factor)")
    p.add_argument("--printer", metavar="P", help="printer TOML (default: the embedded Ender-3-class printer)")
    p.add_argument("--gcode", metavar="G", help="G-code job (default: the built-in test print)")
    p.add_argument("--firmware", default="klipper", help="target firmware (default klipper)")
    p.add_argument("--shapers", metavar="S1,S2", help="shapers to compare (default: all the firmware offers)")
    p.add_argument("--quality", choices=("overshoot", "path_error"), default="overshoot")
    p.add_argument("--backend", choices=("mujoco", "lti"), default="mujoco")
    p.add_argument("-o", "--output", metavar="PNG", help="plot file (default ringtune-study-<factor>.png)")


def run(args: argparse.Namespace, out) -> int:
    import dataclasses

    import numpy as np

    from ringtune.agents import klipper_baseline
    from ringtune.envs.evaluate import evaluate_many, resolve_printer
    from ringtune.shaping.config import TuneConfig
    from ringtune.shaping.errors import RingtuneError
    from ringtune.shaping.shapers import available_shapers

    from ringtune.shaping.firmware import FIRMWARES

    if args.firmware not in FIRMWARES:
        raise RingtuneError(f"must be one of {', '.join(FIRMWARES)}", "--firmware")
    printer = resolve_printer(args.printer)
    quality = f"{args.quality}_mm"
    offered = [s for s in available_shapers(FIRMWARES[args.firmware].flavor) if s != "custom"]
    shapers = [s.strip().lower() for s in args.shapers.split(",")] if args.shapers else offered
    bad = [s for s in shapers if s not in offered]
    if bad:
        raise RingtuneError(f"{args.firmware} does not offer {', '.join(bad)} (offers {', '.join(offered)})",
                            "--shapers")
    values = _values(args, printer)
    one = FIRMWARES[args.firmware].one_shaper

    # tuned frequency per shaper and axis: Klipper's per-shaper fit where it has one
    tuned: dict[str, dict[str, float]] = {}
    try:
        fits, _ = klipper_baseline.recommend_for_printer(printer, args.firmware, "head")
    except (ImportError, RingtuneError) as exc:
        out.note(f"ringtune study: Klipper's fit unavailable ({exc}); shapers tuned to the main mode")
        fits = {}
    for s in shapers:
        tuned[s] = {}
        for ax in ("x", "y"):
            table = {f.name: f.freq for f in fits[ax].shapers} if ax in fits else {}
            main = max(getattr(printer, ax).modes, key=lambda m: m.share or 0).freq
            tuned[s][ax] = round(table.get(s, main), 1)
        if one:
            tuned[s]["y"] = tuned[s]["x"]

    results = {s: {"freq_x": tuned[s]["x"], "freq_y": tuned[s]["y"], "print_time_s": [], "quality_mm": [],
                   "step_loss": []} for s in shapers}
    for v in values:
        pr = printer
        configs = []
        for s in shapers:
            fx, fy, acc = tuned[s]["x"], tuned[s]["y"], None
            if args.factor == "freq-error":
                fx, fy = fx * (1 + v), fy * (1 + v)
            elif args.factor == "accel":
                acc = float(v)
            configs.append(TuneConfig(firmware=args.firmware, shaper_x=s, shaper_y=s,
                                      freq_x=0.0 if s == "none" else round(fx, 2),
                                      freq_y=0.0 if s == "none" else round(fy, 2), accel=acc))
        if args.factor == "mass":
            pr = dataclasses.replace(printer, print_mass=float(v))
        for s, m in zip(shapers, evaluate_many(configs, pr, args.gcode, backend=args.backend)):
            results[s]["print_time_s"].append(float(m.print_time_s))
            results[s]["quality_mm"].append(float(getattr(m, quality)))
            results[s]["step_loss"].append(bool(m.step_loss))

    label, unit, _ = FACTORS[args.factor]
    png = Path(args.output or f"ringtune-study-{args.factor}.png")
    csv_path = png.with_suffix(".csv")
    _plot(png, values, results, label, unit, quality, getattr(printer, "name", "printer"),
          Path(args.gcode).name if args.gcode else "built-in test print", args.firmware)
    with open(csv_path, "w") as f:
        f.write(f"{args.factor},shaper,freq_x,freq_y,print_time_s,{quality},step_loss\n")
        for s, r in results.items():
            for i, v in enumerate(values):
                f.write(f"{v:g},{s},{r['freq_x']},{r['freq_y']},{r['print_time_s'][i]:.4f},"
                        f"{r['quality_mm'][i]:.6f},{int(r['step_loss'][i])}\n")
    word = quality.replace("_mm", "").replace("_", " ")
    lines = [f"{label} ({unit}) sweep on {getattr(printer, 'name', 'printer')}, {args.firmware}; "
             f"{word} in µm / print time in s:"]
    head = "  " + f"{'shaper':10}" + "".join(f"{v:>10g} " for v in values)
    lines.append(head)
    for s, r in results.items():
        lines.append("  " + f"{s:10}" + "".join(
            f"{q * 1000:7.1f}/{t:4.2f}" + ("!" if sl else " ")
            for q, t, sl in zip(r["quality_mm"], r["print_time_s"], r["step_loss"])))
    lines.append("  (! = lost steps)")
    lines.append(f"plot: {png}   table: {csv_path}")
    out.emit({"factor": args.factor, "unit": unit, "values": list(values), "quality": quality,
              "shapers": results, "plot": str(png), "csv": str(csv_path)}, "\n".join(lines))
    return 0


def _values(args, printer) -> list[float]:
    import numpy as np

    from ringtune.shaping.errors import RingtuneError

    if args.values:
        try:
            vals = [float(v) for v in args.values.split(",") if v.strip()]
        except ValueError:
            raise RingtuneError("must be numbers separated by commas", "--values") from None
    elif args.factor == "accel":
        a0 = float(printer.limits.accel)
        vals = [round(float(a), -2) for a in np.linspace(0.3 * a0, 2.5 * a0, 8)]
    else:
        lo, hi, n = FACTORS[args.factor][2]
        vals = [round(float(v), 4) for v in np.linspace(lo, hi, n)]
    if not vals:
        raise RingtuneError("no values", "--values")
    if args.factor == "freq-error" and any(v <= -0.9 for v in vals):
        raise RingtuneError("frequency errors must be > -0.9 (fractions, e.g. -0.2 for 20 % low)", "--values")
    if args.factor == "mass" and any(v < 0 for v in vals):
        raise RingtuneError("print mass must be ≥ 0 kg", "--values")
    if args.factor == "accel" and any(v <= 0 for v in vals):
        raise RingtuneError("accelerations must be > 0 mm/s²", "--values")
    return vals


def _plot(path, values, results, label, unit, quality, printer_name, job_name, firmware) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a1, a2) = plt.subplots(2, 1, figsize=(8, 7.5), dpi=120, sharex=True)
    xs = [100 * v for v in values] if unit == "fraction" else values
    xlabel = f"{label} (%)" if unit == "fraction" else f"{label} ({unit})"
    for s, r in results.items():
        ls = "--" if s == "none" else "-"
        a1.plot(xs, r["print_time_s"], ls, marker="o", ms=3, label=s)
        a2.plot(xs, r["quality_mm"], ls, marker="o", ms=3, label=s)
        bad = [i for i, b in enumerate(r["step_loss"]) if b]
        if bad:
            a2.scatter([xs[i] for i in bad], [r["quality_mm"][i] for i in bad], marker="x", c="red", zorder=5)
    a1.set_ylabel("print time (s)")
    a2.set_ylabel(f"{quality.replace('_mm', '').replace('_', ' ')} (mm)")
    a2.set_xlabel(xlabel)
    for a in (a1, a2):
        a.grid(True, alpha=0.3)
    a1.legend(fontsize=8, ncol=4)
    a1.set_title(f"{label}: {printer_name} · {job_name} · {firmware}  (red x = lost steps)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
