"""``ringtune recommend``: an instant configuration from a resonance test (Klipper's rule).

``--json`` keys (stable):
    method: "klipper" | "policy"
    klipper_version: "head" | "0.13"
    firmware: target firmware
    axes: {"x": {...}, "y": {...}} per measured axis — version, scv, shaper, freq (Hz), max_accel
        (mm/s², rounded as Klipper prints it) and "shapers": the per-shaper table (shaper, freq,
        vibrations_pct, smoothing (mm), score, max_accel, max_accel_rounded)
    sources: {"x": [files], "y": [files]} (or {"x": ["printer:<name>"], ...})
    config: the TuneConfig written (dict)
    output: path written, or null
"""

from __future__ import annotations

import argparse

from ringtune.agents.cli.common import firmware_name
from ringtune.agents.tune.tuning import target_firmware
from ringtune.envs.planned_job import resolve_printer
from ringtune.agents.cli.options import VALUES
from ringtune.agents.klipper.recommend import klipper_pick
from ringtune.agents.ppo.recommend import policy_pick
from ringtune.shaping.errors import RingtuneError

NAME = "recommend"
DESCRIPTION = """\
Recommend an input shaper from a resonance test, the way Klipper's calibrate_shaper does.

--accel (or the files alone, as identify takes them) takes Klipper TEST_RESONANCES files
(resonances_x_*.csv, resonances_y_*.csv), calibration CSVs, or raw accelerometer captures; the axis
comes from the file name (resonances_<axis>_...) or, failing that, from the larger of its psd_x /
psd_y columns (--axes overrides). Several files of one axis are fitted together. --printer runs the simulated resonance test of a modelled printer instead.

--klipper-version head (default) uses current Klipper's formulas and rules; 0.13 the older ones
(v0.13.0 and the releases of 2021-2023). --firmware aims the rule at another firmware's shapers
(RepRapFirmware: one shaper and frequency for both axes, fitted on both PSDs). An axis without a
measurement gets shaping off ("none") in the written config.

--method policy --policy DIR uses a PPO policy trained by `ringtune train -o DIR`: one inference,
well under a second. Policy folders hold pickles (stable-baselines3 zip, VecNormalize statistics):
loading one runs code from it, so only use policies you trained or trust. The policy sees the
resonance spectra and the simulated metrics of its starting answer on a model of the printer: with
--accel alone, modes fitted to the files and the default printer's masses, motor and limits; give
--printer P too (e.g. from `ringtune identify` plus your [motor] and masses) to use your own model.
The policy's answer is then judged against the answer it started from (MZV on the peaks) on that
model, by the cost training used (tune's judgement as one number), and the lower kept: one more
simulation, and never worse on the model than where the policy began (--no-guard: its answer as it is).
--refine N hands the answer kept to Optuna as the first of N trials on that model.

example:
  ringtune recommend --accel resonances_x_20210821_152037.csv resonances_y_20210630_230110.csv \\
      --klipper-version 0.13 -o best.json
  ringtune export best.json --firmware klipper
"""


#: library parameters whose option has another name (see agents/cli/main.py: as_flag)
PARAMETER_FLAGS = {"version": "--klipper-version", "n_trials": "--refine"}


def add_arguments(p: argparse.ArgumentParser) -> None:
    src = p.add_argument_group("what to recommend for (--accel, --printer, or both with --method policy)")
    src.add_argument("--accel", nargs="+", metavar="CSV", help="Klipper resonance / raw accelerometer CSV files")
    src.add_argument("files", nargs="*", metavar="CSV", help="the same, without --accel (as identify takes them)")
    src.add_argument("--printer", metavar="P", help="printer TOML, or 'default': its simulated resonance test; "
                     "with --accel and --method policy, the model the starting answer is simulated on")
    p.add_argument("--method", choices=("klipper", "policy"), default="klipper",
                   help="klipper: Klipper's calibrate_shaper rule (default); policy: a trained PPO policy")
    p.add_argument("--klipper-version", choices=("head", "0.13"), default="head",
                   help="Klipper's current rules (head, default) or the older v0.13 ones")
    p.add_argument("--firmware", type=firmware_name, default=None,
                   help="target firmware (klipper, kalico, rrf, rrf35, marlin, marlin-ftm, prusa); default: the "
                   "one --printer's description names ([current] firmware), else klipper")
    p.add_argument("--axes", metavar="A,B", help="axis of each --accel file in order, e.g. x,y")
    p.add_argument("--scv", type=VALUES["scv"], default=5.0, help="square-corner velocity for smoothing, mm/s "
                   "(default 5; --printer uses the printer's)")
    p.add_argument("--max-smoothing", type=VALUES["smoothing"], default=None,
                   help="Klipper's MAX_SMOOTHING, mm (at least 0.05, as Klipper's)")
    p.add_argument("--seed", type=int, default=None, help="--printer: scatter the simulated resonance test's "
                   "bins as a measurement would, from this seed (default: the model's expected spectrum, "
                   "no noise, as tune's baseline); --method policy: its seed (default 0)")
    p.add_argument("-o", "--output", metavar="best.json", help="write the TuneConfig here")
    p.add_argument("--policy", metavar="DIR", help="--method policy: folder from `ringtune train` "
                   "(trusted source only: it is unpickled)")
    p.add_argument("--refine", type=VALUES["count"], metavar="N", help="--method policy --printer: refine with N Optuna trials")
    p.add_argument("--no-guard", dest="guard", action="store_false",
                   help="--method policy: the policy's answer as it is, not judged against its starting answer")


def run(args: argparse.Namespace, out) -> int:
    args.accel = [*(args.accel or []), *args.files] or None
    if not args.accel and not args.printer:
        raise RingtuneError("give the resonance files (CSV…, or --accel CSV…: a measured resonance test) or "
                            "--printer P (a simulated one)", "recommend")
    if args.firmware is None:
        printer = resolve_printer(None if args.printer == "default" else args.printer) if args.printer else None
        args.firmware = target_firmware(None, printer, out.note, "ringtune recommend").name
    if args.method == "policy":
        return _run_policy(args, out)
    if args.accel and args.printer:
        raise RingtuneError("Klipper's rule reads either --accel files or --printer's simulated test, not both",
                            "--printer")
    pick = klipper_pick(args.accel, args.printer, args.firmware, args.klipper_version, args.scv,
                        args.max_smoothing, args.seed, args.axes, out.note)
    written = _save(pick.config, args.output)
    out.emit({"method": "klipper", "klipper_version": args.klipper_version, "firmware": args.firmware,
              "axes": {ax: rec.to_dict() for ax, rec in pick.fits.items()}, "sources": pick.sources,
              "config": pick.config.to_dict(), "output": written}, _klipper_text(pick, args.firmware, written))
    return 0


def _klipper_text(pick, firmware: str, written: str | None) -> str:
    """Klipper's per-shaper table of each axis, then the config, in words."""
    config, text, shown = pick.config, [], set()
    for ax in ("x", "y"):
        rec = pick.fits.get(ax)
        if rec is None and ax in pick.sources:
            text.append(f"{ax.upper()} ({pick.sources[ax][0]}): {fields_shown(config, ax)}")
        elif rec is None:
            text.append(f"{ax.upper()}: not measured -> shaping off on {ax.upper()}")
        elif id(rec) in shown:
            text.append(f"{ax.upper()}: same as above (one shaper for all axes on {firmware})")
        else:
            shown.add(id(rec))
            text.append(f"{ax.upper()} ({', '.join(pick.sources.get(ax, []))}):")
            text += ["  " + line for line in rec.lines()]
    accel = f"{config.accel:.0f} mm/s^2" if config.accel else "unchanged"
    text.append(f"config: {config.shaper_x} @ {config.freq_x:.1f} Hz (X), {config.shaper_y} @ "
                f"{config.freq_y:.1f} Hz (Y), max_accel {accel}")
    text.append(f"written to {written}" if written else "(use -o best.json to save it; then `ringtune export best.json`)")
    return "\n".join(text)


def _run_policy(args, out) -> int:
    """``ringtune recommend --method policy --policy DIR (--accel CSV… [--printer P] | --printer P)
    [--refine N]``. ``--json`` keys: method ("policy"), firmware,
    policy (folder), sources ({axis: [files]} or {axis: ["printer:<name>"]}), model (name of the
    printer model the starting answer is simulated on and refined on), config (TuneConfig dict),
    inference_s (s, loading excluded; with --accel it includes fitting the model), guard (null with
    --no-guard, or {"kept": "policy" | "start", "policy_cost", "start_cost"}: the environment's cost
    of the policy's answer and of its starting answer on the model), refine (null or {"trials",
    "first_cost", "best_cost"}: the environment's cost of the answer kept and of the best trial), output.
    """
    if not args.policy:
        raise RingtuneError("needs --policy DIR (a folder written by `ringtune train -o DIR`)", "--policy")
    pick = policy_pick(args.policy, args.firmware, args.accel, args.printer, args.axes, args.seed or 0, args.refine,
                       out.note, guard=args.guard)
    written = _save(pick.config, args.output)
    out.emit({"method": "policy", "firmware": args.firmware, "policy": str(pick.policy.path),
              "sources": pick.sources, "model": pick.model, "config": pick.config.to_dict(),
              "inference_s": pick.inference_s, "guard": pick.guard.to_dict() if pick.guard else None,
              "refine": pick.refined, "output": written},
             _policy_text(pick, written))
    return 0


def _policy_text(pick, written: str | None) -> str:
    """The policy's answer in words."""
    config, refined = pick.config, pick.refined
    accel = f"{config.accel:.0f} mm/s^2" if config.accel else "unchanged"
    text = [f"policy {pick.policy.path} (loaded pickles: trusted source assumed), "
            f"inference {pick.inference_s * 1e3:.0f} ms",
            *([f"printer model (starting answer's metrics{', refinement' if refined else ''}): {pick.model}"]
              if pick.policy.env_kwargs.get("observe_metrics") or refined else []),
            f"X: {config.shaper_x} @ {config.freq_x:.1f} Hz, damping {config.damping_x:.3f}",
            f"Y: {config.shaper_y} @ {config.freq_y:.1f} Hz, damping {config.damping_y:.3f}",
            f"frequency limit: {config.freq_limit_hz:.0f} Hz" if config.freq_limit_hz else "frequency limit: off",
            f"acceleration: {accel}"]
    if pick.guard is not None:
        text.append(pick.guard.sentence())
    if refined:
        first = "the answer kept" if pick.guard is not None else "policy"
        text.append(f"refined: cost {refined['first_cost']:.4f} ({first}) -> {refined['best_cost']:.4f} "
                    f"after {refined['trials']} trials")
    text.append(f"written to {written}" if written else "(use -o best.json to save it)")
    return "\n".join(text)


def fields_shown(config, ax: str) -> str:
    return f"Recommended shaper is {getattr(config, f'shaper_{ax}')} @ {getattr(config, f'freq_{ax}'):.1f} Hz"


def _save(config, path) -> str | None:
    """Write the TuneConfig to ``path`` (-o) if given; the path written, or None."""
    if not path:
        return None
    config.save(path)
    return str(path)
