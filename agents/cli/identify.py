"""``ringtune identify``: the printer from the user's files — vibration modes from accelerometer files;
masses, motors, limits and kinematics from what the user gives — written as a printer description.

``--json`` keys (stable):
    fits: list per measurement of {axis, kind ("psd" | "decay"), source, method, r2, notes, warnings,
        modes: [{freq (Hz), damping, share, peak_freq (Hz, measured peak), fitted_peak (Hz)}]}
    loaded_fits: the same for the --added-mass files ([] without)
    added_mass: {axis: {axis, added_mass_kg, f0_hz, f1_hz, mass_kg, mass_error_kg (one standard error),
        stiffness_n_m}}
    klipper: Klipper's recommendation from the files ([measurement.klipper]), or {}
    belts: with --belts, the CoreXY belt comparison written as [belts] mismatch: {similarity_pct,
        mismatch ((k_A - k_B)/mean), mismatch_error, stiffness_a_n_m, stiffness_b_n_m, matched,
        meaning} (see `ringtune graph belts`); else null
    defaults: what is still a default, one sentence each (also on stderr and in the TOML)
    warnings: doubts about the files and fits, one sentence each (also on stderr)
    toml: the printer description text
    output: path written, or null
    plot: path of the plot, or null
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from ringtune.agents.cli import identify_ripples
from ringtune.agents.cli.common import check_output_folder
from ringtune.agents.cli.options import VALUES, PerAxis, motor_spec, moving_mass
from ringtune.agents.identify.from_files import identify_from_files, read_facts
from ringtune.envs.identify import plot_fits
from ringtune.hardware.klipper_config import printer_facts_from_moonraker
from ringtune.hardware.moonraker_files import fetch_printer_files
from ringtune.shaping.errors import RingtuneError

NAME = "identify"
DESCRIPTION = """\
Fit the vibration modes (frequency, damping ratio, share of the response) of each axis to
accelerometer measurements, and write them with everything else you know about the printer as a
printer description for simulate/tune.

Takes Klipper TEST_RESONANCES / calibration CSVs (freq,psd_x,...), Klipper raw captures
(#time,accel_x,...; turned into a PSD exactly as Klipper does), and RepRapFirmware M956 CSVs
(Sample,X,Y,Z ... Rate N, overflows M). A resonance PSD is fitted with base-excited modes
(C·f^p·|T(f)|² + noise floor); an M956 capture, which holds the ringing after one move, with
damped sinusoids. The axis comes from the file name (resonances_x_..., ...-X54-161-...) or --axis.
An axis you did not measure keeps the modes of --base (default: the embedded Ender-3-class
printer), and says so. The files (name, SHA-256) and Klipper's recommendation from them are kept in
the TOML's [measurement], so tune's "Klipper's rule" is what your Klipper would say.

The rest of the printer:
  --klipper-config printer.cfg | --marlin M503.txt | --rrf config.g: kinematics, limits, motors
      (run current, rotation distance, microsteps, motor names) and the shaping the printer runs now.
  --motor NAME[:RUN_CURRENT[:VOLTAGE]] (every axis) or --motor X=NAME...,Y=NAME...: a motor the
      configuration does not name (e.g. LDO-42STH48-2504AC:1.2:24); on a CoreXY/CoreXZ X= is
      motor A (stepper_x) and Y= motor B (stepper_y). See `ringtune motor NAME`.
  --kinematics cartesian|corexy|corexz: when no configuration gives it.
  --mass X=KG,Y=KG: weighed moving masses (X: toolhead and carriage; Y: the bed on a bed slinger,
      the gantry with the toolhead on a CoreXY).
  --added-mass KG LOADED.csv...: a second resonance test with KG fixed to what moves (the toolhead
      for X and, on a CoreXY, Y; the BED for Y on a bed slinger). The added mass lowers each
      frequency from f0 to f1, which gives the moving mass m = KG/((f0/f1)² - 1) and the stiffness
      k = m·(2π f0)² per axis. Per axis: --added-mass X=0.2,Y=0.5 LOADED.csv...
Whatever is still a default (masses, motor, kinematics, limits) is printed on stderr and written
as a comment in the TOML, with what it decides.

--moonraker URL takes the files from the printer instead: the newest resonance test of each axis
(and the two diagonal belt tests of a CoreXY) from Moonraker's config and gcodes folders — Klipper
writes them to /tmp, which Moonraker does not serve, so copy them into the config folder first —
and printer.cfg with the .cfg files beside it (else what Klipper loaded, the configfile object).
They are saved under their own names in --fetch-dir (default: the folder of -o, else here), so the
TOML records files that exist; a different file of the same name there is never overwritten.

examples:
  ringtune identify resonances_x_20210821_152037.csv resonances_y_20210630_230110.csv \\
      -o ender3.toml --plot fit.png
  ringtune identify resonances_x_*.csv resonances_y_*.csv --klipper-config printer.cfg -o mine.toml
  ringtune identify resonances_x_1.csv resonances_y_1.csv --added-mass 0.25 \\
      resonances_x_2.csv resonances_y_2.csv -o mine.toml      # 250 g on the toolhead / bed
  ringtune identify resonances_*.csv --mass X=0.62,Y=1.4 --motor omc-17hs19-2004s1:0.8 --kinematics corexy
  ringtune identify 1-T0-X54-161-0-none.csv --axis x --json
  ringtune identify --moonraker http://voron.local:7125 -o voron.toml   # files and printer.cfg from the printer
  ringtune identify resonances_x_*.csv resonances_y_*.csv --kinematics corexy \\
      --belts resonances_axis=1.000,1.000,0.000_b.csv resonances_axis=1.000,-1.000,0.000_b.csv -o voron.toml

Without an accelerometer (prints from `ringtune testprint ringing`):
  ringtune identify --ripples X=2.2,Y=2.6 --speed 100 [--decay X=1.9,Y=2.1] -o printer.toml
  ringtune identify --tower-band X=4,Y=3 --tower tower.gcode -o printer.toml
"""


#: image formats the plot can be written in (matplotlib picks the format from the suffix)
PLOT_SUFFIXES = (".png", ".pdf", ".svg", ".jpg", ".jpeg")


#: the options that describe the rest of the printer (they go with accelerometer files)
REST_OF_PRINTER = ("--klipper-config", "--marlin", "--rrf", "--motor", "--mass", "--belts", "--added-mass")
#: the belt comparison's keys in --json (``belts``)
BELT_KEYS = ("similarity_pct", "mismatch", "mismatch_error", "stiffness_a_n_m", "stiffness_b_n_m", "matched", "meaning")
#: per-axis masses, kg (identify takes both axes' weighed masses, or neither)
MASSES = PerAxis(moving_mass, "mass", bare=False)



def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("files", nargs="*", metavar="ACCEL.csv", help="accelerometer files (any supported format)")
    p.add_argument("-o", "--output", metavar="printer.toml", help="write the printer description here")
    p.add_argument("--plot", metavar="out.png", help="plot measured against fitted spectra / decays")
    p.add_argument("--axis", choices=("x", "y"), help="axis of every file (default: from the file name)")
    p.add_argument("--max-modes", type=VALUES["modes"], default=3, help="modes per axis at most (default 3)")
    p.add_argument("--fmin", type=VALUES["hz_from_0"], default=5.0, help="lowest frequency fitted, Hz (default 5)")
    p.add_argument("--fmax", type=VALUES["freq"], default=135.0, help="highest frequency fitted, Hz (default 135, "
                   "the end of Klipper's default sweep)")
    p.add_argument("--damping-method", choices=("fit", "half-power"), default="fit",
                   help="damping from the curve fit (default) or each peak's half-power width")
    p.add_argument("--name", default=None, help="printer name in the TOML (default: the firmware "
                   "configuration's folder or file name, e.g. ender3, else the accelerometer files' folder)")
    p.add_argument("--base", metavar="P", help="printer TOML (or embedded name) for unmeasured axes' modes")
    g = p.add_argument_group("the rest of the printer")
    cfg = g.add_mutually_exclusive_group()
    cfg.add_argument("--klipper-config", metavar="printer.cfg", help="Klipper configuration (includes followed)")
    cfg.add_argument("--marlin", metavar="M503.txt", help="Marlin settings as M503 prints them")
    cfg.add_argument("--rrf", metavar="config.g", help="RepRapFirmware config.g")
    cfg.add_argument("--moonraker", metavar="URL", help="fetch the newest resonance files and printer.cfg from a "
                     "Klipper printer through Moonraker (http://host:7125) instead of giving them")
    g.add_argument("--api-key", metavar="KEY", help="Moonraker API key (default $MOONRAKER_API_KEY)")
    g.add_argument("--fetch-dir", metavar="DIR", help="where --moonraker saves the files (default: the folder of "
                   "-o, else the working folder)")
    g.add_argument("--kinematics", choices=("cartesian", "corexy", "corexz"),
                   help="kinematics, when no configuration gives it (default cartesian, said aloud)")
    g.add_argument("--motor", type=PerAxis(motor_spec, "motor"), metavar="NAME[:A[:V]]", help="motor name, run current (A RMS) and driver voltage "
                   "(V) of every axis, or per axis X=NAME:A:V,Y=...")
    g.add_argument("--mass", type=MASSES, metavar="X=KG,Y=KG", help="weighed moving masses, kg (on a bed slinger Y is the bed)")
    g.add_argument("--belts", nargs=2, metavar="DIAGONAL.csv", help="CoreXY: the TEST_RESONANCES AXIS=1,1 and "
                   "AXIS=1,-1 files; the two belts' stiffness difference goes into [belts] (see `ringtune graph belts`)")
    g.add_argument("--added-mass", nargs="+", metavar="KG LOADED.csv",
                   help="added-mass method: KG (or X=KG,Y=KG) fixed to the toolhead (X; Y on a CoreXY) or the "
                   "bed (Y on a bed slinger), then the resonance files measured with it")
    identify_ripples.add_arguments(p)


def _check_output(option: str, path) -> None:
    """Refuse, before any work, an output the command could not write (missing or read-only folder,
    a folder in its place), so that nothing is half-written."""
    check_output_folder(option, path)
    if not path:
        return
    p = Path(path)
    folder = p.parent
    if not os.access(folder, os.W_OK) or (p.exists() and not os.access(p, os.W_OK)):
        raise RingtuneError("not writable (permission denied)", f"{option} {path}")
    try:                                  # a read-only file system passes os.access for root
        probe = folder / f".ringtune-write-test-{os.getpid()}"
        probe.touch()
        probe.unlink()
    except OSError as exc:
        raise RingtuneError(f"cannot write there ({exc.strerror})", f"{option} {path}") from None


def _added_mass(values: list[str] | None) -> tuple[dict, list[str]]:
    """--added-mass KG|X=KG,Y=KG LOADED.csv… -> ({axis or "all": kg}, [loaded file, …])."""
    if not values:
        return {}, []
    if len(values) < 2:
        raise RingtuneError("expected KG (or X=KG,Y=KG) then the resonance files measured with it", "--added-mass")
    try:
        return PerAxis(VALUES["mass"], "added mass")(values[0]), values[1:]
    except argparse.ArgumentTypeError as exc:
        raise RingtuneError(str(exc), "--added-mass") from None


def _check(args) -> None:
    """Refuse what cannot work before any file is read."""
    if args.plot and Path(args.plot).suffix.lower() not in PLOT_SUFFIXES:
        raise RingtuneError(f"the plot's file name must end in one of {', '.join(PLOT_SUFFIXES)}",
                            f"--plot {args.plot}")
    if not args.fmin < args.fmax:
        raise RingtuneError("need 0 <= --fmin < --fmax", "--fmin")
    _check_output("-o", args.output)
    _check_output("--plot", args.plot)


def _from_moonraker(args, out) -> None:
    """Fetch the files and the configuration into --fetch-dir and point the arguments at them."""
    if args.files or args.belts:
        raise RingtuneError("fetches the resonance files from the printer; give no files with it", "--moonraker")
    _check_output("-o", args.output)
    dest = _fetch_dir(args)
    key = args.api_key or os.environ.get("MOONRAKER_API_KEY")
    got = fetch_printer_files(args.moonraker, dest, api_key=key)
    out.note(*got.notes, kind="note")
    args.files = [str(p) for p in got.axes]
    args.facts = _moonraker_facts(args, got.config, key, out)
    kinematics = args.kinematics or args.facts.description.get("kinematics")
    if got.belts and kinematics == "corexy":
        args.belts = [str(p) for p in got.belts]


def _fetch_dir(args):
    """--fetch-dir, else the folder of -o, else the working folder (it must exist)."""
    dest = Path(args.fetch_dir) if args.fetch_dir else (Path(args.output).parent if args.output else Path("."))
    if not dest.is_dir():
        raise RingtuneError("no such directory", f"--fetch-dir {dest}")
    return dest


def _moonraker_facts(args, config, key, out):
    """The fetched printer.cfg's facts, else those of the configuration Klipper loaded."""
    if config is not None:
        args.klipper_config = str(config)
        return read_facts({"klipper_config": args.klipper_config})[0]
    out.note("note: no printer.cfg in Moonraker's config folder: the configuration Klipper loaded is used")
    return printer_facts_from_moonraker(args.moonraker, api_key=key)


# -- the command ------------------------------------------------------------------------------------

def run(args, out) -> int:
    if args.moonraker:
        _from_moonraker(args, out)
    if identify_ripples.wanted(args) or not args.files:   # no accelerometer: ripples or a tower
        return _without_accelerometer(args, out)
    _check(args)
    dm, loaded_files = _added_mass(args.added_mass)
    got = identify_from_files(
        args.files, configs={"klipper_config": args.klipper_config, "marlin": args.marlin, "rrf": args.rrf},
        axis=args.axis, max_modes=args.max_modes, fmin=args.fmin, fmax=args.fmax, damping=args.damping_method,
        kinematics=args.kinematics, base=args.base, masses=args.mass, motors=args.motor,
        added_mass=dm, loaded_files=loaded_files, name=args.name, facts=getattr(args, "facts", None),
        belts=args.belts, note=out.note)
    out.note(*got.warnings, kind="warning")
    out.note(*got.description.notes, kind="note")
    out.note(*got.description.defaults, kind="default")
    _write(args, got, out)
    out.emit(_result(got, args), _text(got, args.output))
    return 0


def _result(got, args) -> dict:
    """The ``--json`` object of an identification from accelerometer files."""
    return {"fits": [f.to_dict() for f in got.measurement.fits], "loaded_fits": [f.to_dict() for f in got.loaded_fits],
            "added_mass": {ax: a.to_dict() for ax, a in got.added.items()}, "klipper": got.klipper,
            "belts": None if got.belts is None else {k: v for k, v in got.belts.to_dict().items() if k in BELT_KEYS},
            "defaults": got.description.defaults, "warnings": got.warnings, "toml": got.toml,
            "output": args.output, "plot": args.plot}


def _without_accelerometer(args, out) -> int:
    """The ripple / tower path (:mod:`ringtune.agents.cli.identify_ripples`); the rest of the
    printer then comes from --base."""
    given = [flag for flag in REST_OF_PRINTER if getattr(args, flag[2:].replace("-", "_"))]
    if given:
        maker = {"--marlin": f"printer from-marlin {args.marlin}", "--rrf": f"printer from-rrf {args.rrf}"}.get(
            given[0], f"printer from-klipper {args.klipper_config or 'printer.cfg'}")
        raise RingtuneError("goes with accelerometer files; with --ripples/--tower-band give the rest of "
                            f"the printer as --base P (e.g. from `ringtune {maker} -o P`)", given[0])
    args.name = args.name or "identified"
    return identify_ripples.run(args, out)


def _write(args, got, out) -> None:
    """The plot, then the TOML (a failed plot leaves nothing half-written)."""
    if args.plot:
        _written(lambda: plot_fits(got.measurement.fits + got.loaded_fits, args.plot),
                 "cannot write the plot", "--plot", args.plot, out)
    if args.output:
        _written(lambda: Path(args.output).write_text(got.toml), "cannot write", "-o", args.output, out)


def _written(write, refusal: str, option: str, path: str, out) -> None:
    """Run ``write`` (it writes ``path``, given by ``option``) and say so; an OSError is refused in
    one line naming the option."""
    try:
        write()
    except OSError as exc:
        raise RingtuneError(f"{refusal} ({exc.strerror or exc})", f"{option} {path}") from None
    out.note(f"wrote {path}")


def _fit_lines(fit) -> list[str]:
    """One fit in words: the file, axis and r², then each mode and the fit's notes."""
    lines = [f"{Path(fit.source).name}: axis {fit.axis.upper()}, {fit.kind} fit ({fit.method}), r² = {fit.r2:.3f}"]
    for m in fit.modes:
        peak = f", measured peak {m.peak_freq:.1f} Hz" if m.peak_freq else ""
        lines.append(f"  {m.freq:7.2f} Hz  damping {m.damping:.3f}  share {m.share:.2f}{peak}")
    return lines + [f"  note: {n}" for n in fit.notes]


def _text(got, output) -> str:
    """The fits, the added-mass results and Klipper's pick in words (and the TOML when not written)."""
    lines = [line for fit in got.measurement.fits + got.loaded_fits for line in _fit_lines(fit)]
    for ax, a in got.added.items():
        lines.append(f"{ax.upper()} added mass {a.dm:g} kg: dominant mode {a.f0:.2f} -> {a.f1:.2f} Hz, moving "
                     f"mass {a.mass:.3f} ± {a.mass_error:.3f} kg (±1 standard error), stiffness {a.stiffness:.4g} N/m (m = dm/((f0/f1)² − 1), k = m(2π f0)²)")
    klipper = got.klipper
    if klipper:
        picks = ", ".join(f"{ax.upper()} {klipper[f'shaper_{ax}']} @ {klipper[f'freq_{ax}']:.1f} Hz"
                          for ax in ("x", "y") if f"shaper_{ax}" in klipper)
        accel = f", max_accel {klipper['max_accel']:.0f} mm/s²" if "max_accel" in klipper else ""
        lines.append(f"Klipper's rule on these files (calibrate_shaper, current rules, scv {got.scv:g} mm/s): "
                     f"{picks}{accel}")
    if not output:
        lines += ["", got.toml]
    return "\n".join(lines)
