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

NAME = "recommend"
HELP = "instant shaper config from a resonance test (Klipper's calibrate_shaper rule)"
DESCRIPTION = """\
Recommend an input shaper from a resonance test, the way Klipper's calibrate_shaper does.

--accel takes Klipper TEST_RESONANCES files (resonances_x_*.csv, resonances_y_*.csv), calibration
CSVs, or raw accelerometer captures; the axis comes from the file name (resonances_<axis>_...) or,
failing that, from the larger of its psd_x / psd_y columns (--axes overrides). Several files of one
axis are fitted together. --printer runs the simulated resonance test of a modelled printer instead.

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
--refine N hands the policy's answer to Optuna as the first of N trials on that model.

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
    src.add_argument("--printer", metavar="P", help="printer TOML, or 'default': its simulated resonance test; "
                     "with --accel and --method policy, the model the starting answer is simulated on")
    p.add_argument("--method", choices=("klipper", "policy"), default="klipper",
                   help="klipper: Klipper's calibrate_shaper rule (default); policy: a trained PPO policy")
    p.add_argument("--klipper-version", choices=("head", "0.13"), default="head",
                   help="Klipper's current rules (head, default) or the older v0.13 ones")
    p.add_argument("--firmware", default="klipper", help="target firmware (klipper, rrf, rrf35, marlin, "
                   "marlin-ftm, prusa); default klipper")
    p.add_argument("--axes", metavar="A,B", help="axis of each --accel file in order, e.g. x,y")
    p.add_argument("--scv", type=float, default=5.0, help="square-corner velocity for smoothing, mm/s "
                   "(default 5; --printer uses the printer's)")
    p.add_argument("--max-smoothing", type=float, default=None, help="Klipper's MAX_SMOOTHING, mm")
    p.add_argument("--seed", type=int, default=None, help="--printer: scatter the simulated resonance test's "
                   "bins as a measurement would, from this seed (default: the model's expected spectrum, "
                   "no noise, as tune's baseline); --method policy: its seed (default 0)")
    p.add_argument("-o", "--output", metavar="best.json", help="write the TuneConfig here")
    p.add_argument("--policy", metavar="DIR", help="--method policy: folder from `ringtune train` "
                   "(trusted source only: it is unpickled)")
    p.add_argument("--refine", type=int, metavar="N", help="--method policy --printer: refine with N Optuna trials")


def run(args: argparse.Namespace, out) -> int:
    from ringtune.agents.klipper import baseline as klipper_baseline
    from ringtune.shaping.config import TuneConfig
    from ringtune.shaping.errors import RingtuneError

    if not args.accel and not args.printer:
        raise RingtuneError("give --accel CSV… (a measured resonance test) or --printer P (a simulated one)",
                            "recommend")
    if args.method == "policy":
        return _run_policy(args, out)
    if args.accel and args.printer:
        raise RingtuneError("Klipper's rule reads either --accel files or --printer's simulated test, not both",
                            "--printer")
    if args.max_smoothing is not None and args.max_smoothing < 0.05:
        raise RingtuneError("must be ≥ 0.05 mm (as Klipper's)", "--max-smoothing")
    kw = {"max_smoothing": args.max_smoothing}
    if args.accel:
        psds, sources = _load_accel(args.accel, args.axes, out)
        fits, fields = klipper_baseline.recommend_axes(psds, args.firmware, args.klipper_version, args.scv, **kw)
    else:
        from ringtune.agents.klipper.rule import DEFAULT_DAMPING_RATIO
        from ringtune.envs.evaluate import resolve_printer

        printer = resolve_printer(None if args.printer in (None, "default") else args.printer)
        recorded = _recorded(printer, args, out)
        kept = (printer.measurement or {}).get("klipper", {})
        if recorded is not None:        # identify recorded the files: their recommendation, not the model's
            psds, sources = _load_accel([p for p, _ in recorded], ",".join(ax for _, ax in recorded), out)
            scv = float(kept.get("scv", args.scv))
            fits, fields = klipper_baseline.recommend_axes(psds, args.firmware, args.klipper_version, scv, **kw)
        elif kept and args.firmware == "klipper" and args.klipper_version == kept.get("version") \
                and args.max_smoothing is None:     # the files moved: what identify recorded from them
            out.note(f"note: the recommendation {args.printer} recorded from its files ([measurement.klipper]); "
                     "without the files there is no per-shaper table")
            fits = {}
            fields = {"firmware": "klipper", "accel": kept.get("max_accel")}
            for ax in ("x", "y"):
                fields.update({f"shaper_{ax}": kept.get(f"shaper_{ax}", "none"), f"freq_{ax}": kept.get(f"freq_{ax}", 0.0),
                               f"damping_{ax}": DEFAULT_DAMPING_RATIO})
            sources = {ax: [f"{args.printer} [measurement.klipper]"] for ax in ("x", "y") if f"shaper_{ax}" in kept}
        else:
            if printer.measurement.get("files"):
                out.note("note: Klipper's rule runs on the model's simulated resonance test instead")
            try:
                fits, fields = klipper_baseline.klipper_rule_on_simulated_test(printer, args.firmware,
                                                                                args.klipper_version, args.seed, **kw)
            except ImportError as exc:
                raise RingtuneError(f"the simulated resonance test is not available ({exc})", "--printer") from None
            sources = {ax: [f"printer:{getattr(printer, 'name', 'default')} (simulated resonance test)"]
                       for ax in ("x", "y")}
    fields["extra"] = {"method": "klipper", "klipper_version": args.klipper_version,
                       "sources": sources,
                       "klipper": {ax: rec.to_dict() for ax, rec in fits.items()}}
    extra = fields.pop("extra")
    config = TuneConfig(**fields, extra=extra)
    written = _save(config, args.output)

    text = []
    shown = set()
    for ax in ("x", "y"):
        rec = fits.get(ax)
        if rec is None and ax in sources:
            text.append(f"{ax.upper()} ({sources[ax][0]}): {fields_shown(config, ax)}")
            continue
        if rec is None:
            text.append(f"{ax.upper()}: not measured -> shaping off on {ax.upper()}")
            continue
        if id(rec) in shown:
            text.append(f"{ax.upper()}: same as above (one shaper for all axes on {args.firmware})")
            continue
        shown.add(id(rec))
        text.append(f"{ax.upper()} ({', '.join(sources.get(ax, []))}):")
        text += ["  " + line for line in rec.lines()]
    accel = f"{config.accel:.0f} mm/s^2" if config.accel else "unchanged"
    text.append(f"config: {config.shaper_x} @ {config.freq_x:.1f} Hz (X), {config.shaper_y} @ "
                f"{config.freq_y:.1f} Hz (Y), max_accel {accel}")
    text.append(f"written to {written}" if written else "(use -o best.json to save it; then `ringtune export best.json`)")
    out.emit({"method": "klipper", "klipper_version": args.klipper_version, "firmware": args.firmware,
              "axes": {ax: rec.to_dict() for ax, rec in fits.items()}, "sources": sources,
              "config": config.to_dict(), "output": written}, "\n".join(text))
    return 0


def _run_policy(args, out) -> int:
    """``ringtune recommend --method policy --policy DIR (--accel CSV… [--printer P] | --printer P)
    [--refine N]``. ``--json`` keys: method ("policy"), firmware,
    policy (folder), sources ({axis: [files]} or {axis: ["printer:<name>"]}), model (name of the
    printer model the starting answer is simulated on and refined on), config (TuneConfig dict),
    inference_s (s, loading excluded; with --accel it includes fitting the model), refine (null or
    {"trials", "first_cost", "best_cost"}: the environment's cost of the policy's answer and of the
    best trial), output.
    """
    import dataclasses
    import time

    from ringtune.agents.ppo.policy import load_policy
    from ringtune.agents.ppo.recommend import (_axis_spectra, decode_measured, measured_observation,
                                               policy_on_simulated_test, preload)
    from ringtune.envs.evaluate import resolve_printer
    from ringtune.shaping.errors import RingtuneError

    if not getattr(args, "policy", None):
        raise RingtuneError("needs --policy DIR (a folder written by `ringtune train -o DIR`)", "--policy")
    policy = load_policy(args.policy)
    trained = policy.env_kwargs.get("firmware", "klipper")
    if args.firmware != trained:
        raise RingtuneError(f"this policy chooses {trained} shapers; train one for {args.firmware} "
                            f"or use --method klipper", "--firmware")
    refine = getattr(args, "refine", None)
    printer = resolve_printer(None if args.printer in (None, "default") else args.printer) if args.printer else None
    preload()
    t0 = time.perf_counter()
    if args.accel:
        psds, sources = _load_accel(args.accel, args.axes, out)
        spectra = _axis_spectra(psds)
        env, obs = measured_observation(policy, spectra, printer)
        action = policy.act(obs)
        config = decode_measured(env, action, spectra)
        printer, peaks = env.printer, env.peaks_
    else:
        config, action = policy_on_simulated_test(policy, printer, args.seed or 0)
        sources = {ax: [f"printer:{getattr(printer, 'name', 'default')}"] for ax in ("x", "y")}
        peaks = None
    inference = time.perf_counter() - t0
    refined = None
    if refine:
        from ringtune.agents.ppo.refine import PrinterCost, optuna_search

        out.note(f"refining with Optuna: {refine} trials, the policy's answer first ...")
        cost = PrinterCost(printer, policy.env_kwargs, seed=args.seed or 0, peaks=peaks)
        res = optuna_search(cost, int(refine), args.seed or 0, first_action=action)
        config = decode_measured(cost.env, res.best_action, spectra) if args.accel else res.best_config
        refined = {"trials": int(refine), "first_cost": res.first_cost, "best_cost": res.best_cost}
    config = dataclasses.replace(config, extra={"method": "policy", "policy": str(policy.path),
                                                "sources": sources, "refine": refined})
    written = _save(config, args.output)
    accel = f"{config.accel:.0f} mm/s^2" if config.accel else "unchanged"
    model = getattr(printer, "name", "the default printer")
    text = [f"policy {policy.path} (loaded pickles: trusted source assumed), inference {inference * 1e3:.0f} ms",
            *([f"printer model (starting answer's metrics{', refinement' if refine else ''}): {model}"]
              if policy.env_kwargs.get("observe_metrics") or refine else []),
            f"X: {config.shaper_x} @ {config.freq_x:.1f} Hz, damping {config.damping_x:.3f}",
            f"Y: {config.shaper_y} @ {config.freq_y:.1f} Hz, damping {config.damping_y:.3f}",
            f"frequency limit: {config.freq_limit_hz:.0f} Hz" if config.freq_limit_hz else "frequency limit: off",
            f"acceleration: {accel}"]
    if refined:
        text.append(f"refined: cost {refined['first_cost']:.4f} (policy) -> {refined['best_cost']:.4f} "
                    f"after {refine} trials")
    text.append(f"written to {written}" if written else "(use -o best.json to save it)")
    out.emit({"method": "policy", "firmware": args.firmware, "policy": str(policy.path), "sources": sources,
              "model": model,
              "config": config.to_dict(), "inference_s": inference, "refine": refined, "output": written},
             "\n".join(text))
    return 0


def fields_shown(config, ax: str) -> str:
    return f"Recommended shaper is {getattr(config, f'shaper_{ax}')} @ {getattr(config, f'freq_{ax}'):.1f} Hz"


def _recorded(printer, args, out) -> list[tuple[str, str]] | None:
    """The resonance files ``printer`` records in ``[measurement]`` (written by ``ringtune identify``)
    when they are all still here and unchanged, else None (with a note when some are missing)."""
    from ringtune.agents.identify.accelerometer import recorded_files

    files = printer.measurement.get("files") if printer.measurement else None
    if not files:
        return None
    found, missing = recorded_files(printer.measurement, args.printer)
    if missing:
        out.note(f"note: {args.printer} was identified from {', '.join(missing)}, not found here (or changed)")
        return None
    if not found:                                 # only free-decay captures: no sweep for the rule
        return None
    out.note(f"note: Klipper's rule on the resonance files {args.printer} was identified from")
    return found


def _save(config, path) -> str | None:
    """Write the TuneConfig to ``path`` (-o) if given; the path written, or None."""
    if not path:
        return None
    config.save(path)
    return str(path)


def _load_accel(paths: list[str], axes_opt: str | None, out=None):
    """{axis: [PSD, ...]} and {axis: [file, ...]} from the --accel files (the axis from --axes, else
    the file name, else the larger of the psd_x / psd_y columns, said through ``out``)."""
    import numpy as np

    from ringtune.hardware.accel import axis_from_file_name, read_accel, to_psd
    from ringtune.shaping.errors import RingtuneError

    axes = None
    if axes_opt:
        axes = [a.strip().lower() for a in axes_opt.split(",")]
        if len(axes) != len(paths) or any(a not in ("x", "y") for a in axes):
            raise RingtuneError(f"give one axis (x or y) per --accel file ({len(paths)} files)", "--axes")
    psds: dict[str, list] = {}
    sources: dict[str, list[str]] = {}
    for i, path in enumerate(paths):
        items = to_psd(read_accel(path))
        if axes:
            ax = axes[i]
        else:
            ax = axis_from_file_name(path)
            if ax == "z":
                raise RingtuneError("the file name says it measured Z; recommend fits X and Y (if it "
                                    "measured X or Y, say so with --axes)", str(path))
            if ax is None and items[0].psd_x is not None and items[0].psd_y is not None:
                ax = "x" if float(np.sum(items[0].psd_x)) >= float(np.sum(items[0].psd_y)) else "y"
                if out is not None:
                    out.note(f"{path}: the file name does not say the axis; taking {ax.upper()}, the larger of "
                             "its psd_x and psd_y (--axes overrides)")
            elif ax is None:
                raise RingtuneError("cannot tell which axis this file measured; use --axes", str(path))
        psds.setdefault(ax, []).extend(items)
        sources.setdefault(ax, []).append(str(path))
    return psds, sources
