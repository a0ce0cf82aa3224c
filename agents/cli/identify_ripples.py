"""``ringtune identify --ripples`` / ``--tower-band``: the command-line path of identify without an
accelerometer (the library is :mod:`ringtune.agents.identify.ripples`).

``--json`` keys (stable, this path): source ("ripples" | "tower"), modes {x|y: {freq (Hz, natural),
damping, how}}, measurement (as written to ``[measurement]``), toml (the description), output.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from ringtune.agents.cli.common import check_output_folder
from ringtune.agents.identify.ripples import identify_modes, printer_text
from ringtune.shaping.errors import RingtuneError


def add_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("without an accelerometer (ringtune testprint ringing)")
    g.add_argument("--ripples", metavar="X=MM,Y=MM", help="ripple spacing per axis, mm (crest to crest, "
                   "after the first two ripples past the corner)")
    g.add_argument("--speed", type=float, metavar="V", help="wall speed the ripples were printed at, mm/s")
    g.add_argument("--decay", metavar="X=R,Y=R", help="height of a ripple over the next one's (damping "
                   "by the logarithmic decrement)")
    g.add_argument("--tower-band", metavar="X=N,Y=N", help="band of the ringing tower with the least "
                   "ringing, per axis (1 = lowest)")
    g.add_argument("--tower", metavar="ringing.gcode", help="the tower's G-code (its band table)")



def wanted(args) -> bool:
    """True when the command line asks for the ripple or tower path."""
    return any(getattr(args, k, None) for k in ("ripples", "tower_band", "tower", "decay", "speed"))


def run(args, out) -> int:
    for opt in ("plot", "axis"):
        if getattr(args, opt, None):
            raise RingtuneError("goes with accelerometer files, not with --ripples/--tower-band", f"--{opt}")
    check_output_folder("-o", args.output)
    modes, meas, files = identify_modes(args, out)
    text = printer_text(modes, meas, files, args.name, args.base, out)
    if args.output:
        Path(args.output).write_text(text)
        out.note(f"wrote {args.output}")
    lines = [f"{ax.upper()}: {f:7.2f} Hz  damping {z:.3f}   ({c})" for ax, (f, z, c) in sorted(modes.items())]
    if not args.output:
        lines += ["", text]
    out.emit({"source": meas["source"],
              "modes": {ax: {"freq": f, "damping": z, "how": c} for ax, (f, z, c) in modes.items()},
              "measurement": meas, "toml": text, "output": args.output}, "\n".join(lines))
    return 0
