"""``ringtune identify``: vibration modes from accelerometer files, written as a printer description.

``--json`` keys (stable):
    fits: list per measurement of {axis, kind ("psd" | "decay"), source, method, r2, notes,
        modes: [{freq (Hz), damping, share, peak_freq (Hz, measured peak), fitted_peak (Hz)}]}
    toml: the printer description text
    output: path written, or null
    plot: path of the plot, or null
"""

from __future__ import annotations

import argparse

from ringtune.agents import identify_ripples

NAME = "identify"
HELP = "fit vibration modes to accelerometer data and write a printer description (TOML)"
DESCRIPTION = """\
Fit the vibration modes (frequency, damping ratio, share of the response) of each axis to
accelerometer measurements, and write them as a printer description for simulate/tune.

Takes Klipper TEST_RESONANCES / calibration CSVs (freq,psd_x,...), Klipper raw captures
(#time,accel_x,...; turned into a PSD exactly as Klipper does), and RepRapFirmware M956 CSVs
(Sample,X,Y,Z ... Rate N, overflows M). A resonance PSD is fitted with base-excited modes
(C·f^p·|T(f)|² + noise floor); an M956 capture, which holds the ringing after one move, with
damped sinusoids. The axis comes from the file name (resonances_x_..., ...-X54-161-...) or --axis.
An axis you did not measure keeps the modes of --base (default: the embedded Ender-3-class printer).

examples:
  ringtune identify resonances_x_20210821_152037.csv resonances_y_20210630_230110.csv \\
      -o ender3.toml --plot fit.png
  ringtune identify 1-T0-X54-161-0-none.csv --axis x --json

Without an accelerometer (prints from `ringtune testprint ringing`):
  ringtune identify --ripples X=2.2,Y=2.6 --speed 100 [--decay X=1.9,Y=2.1] -o printer.toml
  ringtune identify --tower-band X=4,Y=3 --tower tower.gcode -o printer.toml
"""


#: image formats the plot can be written in (matplotlib picks the format from the suffix)
PLOT_SUFFIXES = (".png", ".pdf", ".svg", ".jpg", ".jpeg")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("files", nargs="*", metavar="ACCEL.csv", help="accelerometer files (any supported format)")
    p.add_argument("-o", "--output", metavar="printer.toml", help="write the printer description here")
    p.add_argument("--plot", metavar="out.png", help="plot measured against fitted spectra / decays")
    p.add_argument("--axis", choices=("x", "y"), help="axis of every file (default: from the file name)")
    p.add_argument("--max-modes", type=int, default=3, help="modes per axis at most (default 3)")
    p.add_argument("--fmin", type=float, default=5.0, help="lowest frequency fitted, Hz (default 5)")
    p.add_argument("--fmax", type=float, default=135.0, help="highest frequency fitted, Hz (default 135, "
                   "the end of Klipper's default sweep)")
    p.add_argument("--damping-method", choices=("fit", "half-power"), default="fit",
                   help="damping from the curve fit (default) or each peak's half-power width")
    p.add_argument("--name", default="identified", help="printer name in the TOML")
    p.add_argument("--kinematics", choices=("cartesian", "corexy"), default="cartesian")
    p.add_argument("--base", metavar="P", help="printer TOML (or embedded name) for unmeasured axes")
    identify_ripples.add_arguments(p)


def run(args, out) -> int:
    from pathlib import Path

    from ringtune.agents.commands import check_output_folder
    from ringtune.envs.identify import identify_files, plot_fits, printer_toml
    from ringtune.shaping.errors import RingtuneError

    if identify_ripples.wanted(args) or not args.files:   # no accelerometer: ripples or a tower
        return identify_ripples.run(args, out)
    if args.max_modes < 1 or args.max_modes > 5:
        raise RingtuneError("must be 1 to 5", "--max-modes")
    if not 0 <= args.fmin < args.fmax:
        raise RingtuneError("need 0 <= --fmin < --fmax", "--fmin")
    check_output_folder("-o", args.output)
    check_output_folder("--plot", args.plot)
    if args.plot and Path(args.plot).suffix.lower() not in PLOT_SUFFIXES:
        raise RingtuneError(f"the plot's file name must end in one of {', '.join(PLOT_SUFFIXES)}",
                            f"--plot {args.plot}")
    fits = identify_files(args.files, axis=args.axis, max_modes=args.max_modes, fmin=args.fmin,
                          fmax=args.fmax, damping=args.damping_method)
    toml = printer_toml(fits, name=args.name, kinematics=args.kinematics, base=args.base)
    if args.output:
        Path(args.output).write_text(toml)
        out.note(f"wrote {args.output}")
    if args.plot:
        plot_fits(fits, args.plot)
        out.note(f"wrote {args.plot}")
    lines = []
    for fit in fits:
        lines.append(f"{Path(fit.source).name}: axis {fit.axis.upper()}, {fit.kind} fit ({fit.method}), "
                     f"r² = {fit.r2:.3f}")
        for m in fit.modes:
            peak = f", measured peak {m.peak_freq:.1f} Hz" if m.peak_freq else ""
            lines.append(f"  {m.freq:7.2f} Hz  damping {m.damping:.3f}  share {m.share:.2f}{peak}")
        lines += [f"  note: {n}" for n in fit.notes]
    if not args.output:
        lines += ["", toml]
    out.emit({"fits": [f.to_dict() for f in fits], "toml": toml, "output": args.output, "plot": args.plot},
             "\n".join(lines))
    return 0
