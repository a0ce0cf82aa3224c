"""``ringtune response``: residual vibration against frequency for several shapers, like the
graph Klipper's ``calibrate_shaper.py`` draws.

``--json`` keys (stable): ``freq`` (Hz, design frequency), ``flavor``, ``plant_damping`` (list; the
curve is the maximum over these plant damping ratios, as Klipper does), ``freqs_hz`` (grid),
``shapers``: list of {``name``, ``damping``, ``residual`` (fraction 0..1 per grid frequency),
``band90_hz`` [lo, hi], ``duration_s``, ``smoothing_mm``, ``max_accel`` (null if no limit)}, ``plot`` (path or null),
``psd`` (path or null).
"""

from __future__ import annotations

import matplotlib
import matplotlib.pyplot as plt
import numpy as np

from ringtune.agents.cli.options import VALUES, ListOf, flavor_name
from ringtune.agents.cli.shaper import band_text
from ringtune.hardware.accel import read_resonances_csv
from ringtune.shaping.analysis import responses
from ringtune.shaping.shapers import get_shaper

NAME = "response"
DESCRIPTION = """\
Compare shapers by how much vibration they leave at each frequency: 100 % means no help, 0 %
means perfect cancellation. The curve is Klipper's estimate (maximum over the plant damping
ratios given, by default Klipper's 0.075, 0.1 and 0.15). With --plot a PNG is written; with --psd
a Klipper resonances CSV is drawn behind the curves, as in Klipper's shaper graph.

example:
  ringtune response zv mzv ei 2hump_ei --freq 40 --plot shapers.png
  ringtune response zvd ei2 ei3 --freq 45 --flavor rrf --json
"""

KLIPPER_TEST_DAMPING = (0.075, 0.1, 0.15)


def add_arguments(parser) -> None:
    parser.add_argument("names", metavar="NAME", nargs="+", help="shaper names (see `ringtune shaper --help`)")
    parser.add_argument("--freq", type=VALUES["freq"], required=True, help="shaper frequency, Hz (all shapers)")
    parser.add_argument("--damping", type=VALUES["damping_ratio"], default=None,
                        help="shaper damping ratio (firmware default)")
    parser.add_argument("--flavor", type=flavor_name, default="klipper",
                        help="firmware formulas (see `ringtune shaper --help`)")
    parser.add_argument("--plant-damping", type=ListOf(VALUES["damping_ratio"]),
                        default=list(KLIPPER_TEST_DAMPING),
                        help="comma list of plant damping ratios; the curve is the max over them "
                        "(default 0.075,0.1,0.15 as Klipper)")
    parser.add_argument("--fmax", type=VALUES["freq"], default=None,
                        help="highest frequency shown, Hz (default 3×freq)")
    parser.add_argument("--points", type=VALUES["points"], default=400, help="grid points (default 400)")
    parser.add_argument("--plot", default=None, metavar="OUT.png", help="write the graph here")
    parser.add_argument("--psd", default=None, metavar="CSV", help="Klipper resonances CSV to draw behind")


def run(args, out) -> int:
    flavor = args.flavor
    dampings = args.plant_damping
    fmax = 3 * args.freq if args.fmax is None else args.fmax
    freqs = np.linspace(0, fmax, args.points + 1)[1:]
    shapers = [get_shaper(n, args.freq, args.damping, flavor, where=f"shaper {n!r}") for n in args.names]
    rows = responses(shapers, freqs, dampings)
    psd = None
    if args.psd:
        psd = read_resonances_csv(args.psd)
        if isinstance(psd, list):
            psd = psd[0]
    if args.plot:
        _plot(args, flavor, freqs, rows, dampings, psd)
    result = {"freq": args.freq, "flavor": flavor, "plant_damping": dampings, "freqs_hz": freqs,
              "shapers": rows, "plot": args.plot, "psd": args.psd}
    out.emit(result, _text(args, flavor, dampings, rows))
    return 0


def _text(args, flavor: str, dampings: list[float], rows: list[dict]) -> str:
    """The table a person reads: each shaper's 90 % band, duration, smoothing and max_accel."""
    lines = [f"residual vibration at {args.freq:g} Hz design frequency ({flavor}; plant damping "
             f"{', '.join(f'{z:g}' for z in dampings)})",
             f"  {'shaper':<22} {'90% band':>20} {'duration ms':>12} {'smoothing':>10} {'max_accel':>10}"]
    for r in rows:
        acc = "no limit" if r["max_accel"] is None else f"{r['max_accel']:.0f}"
        lines.append(f"  {r['name']:<22} {band_text(*r['band90_hz']):>20} {r['duration_s'] * 1e3:12.2f} "
                     f"{r['smoothing_mm']:10.4f} {acc:>10}")
    if args.plot:
        lines.append(f"graph written to {args.plot}")
    return "\n".join(lines)


def _plot(args, flavor, freqs, rows, dampings, psd) -> None:
    matplotlib.use("Agg")
    fig, ax = plt.subplots(figsize=(10, 6))
    if psd is not None:
        keep = psd.freqs <= freqs[-1]
        ax.plot(psd.freqs[keep], psd.psd_sum[keep], color="steelblue", lw=2, label="measured PSD (sum)")
        ax.set_ylabel("power spectral density")
        ax2, ls = ax.twinx(), "--"
    else:
        ax2, ls = ax, "-"          # one axis: the residual scale keeps its ticks
    for r in rows:
        ax2.plot(freqs, 100 * r["residual"], ls=ls,
                 label=f"{r['name']} (smoothing {r['smoothing_mm']:.3f} mm, max accel "
                       f"{'-' if r['max_accel'] is None else format(r['max_accel'], '.0f')})")
    ax2.axhline(10, color="grey", lw=0.8, ls=":")
    ax2.axvline(args.freq, color="grey", lw=0.8, ls=":")
    ax2.set_ylabel("remaining vibration, %")
    ax2.set_ylim(0, 105)
    ax.set_xlabel("vibration frequency, Hz")
    ax.set_xlim(0, freqs[-1])
    ax.set_title(f"Input shaper response at {args.freq:g} Hz ({flavor}; plant damping "
                 f"{', '.join(f'{z:g}' for z in dampings)}; dotted: 10 % line)")
    handles, labels = [], []
    for a in {ax, ax2}:
        h, lab = a.get_legend_handles_labels()
        handles += h
        labels += lab
    ax2.legend(handles, labels, loc="upper right", fontsize="small")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(args.plot, dpi=110)
    plt.close(fig)
