"""``ringtune recommend --method policy``: a trained PPO policy's configuration from a resonance test
(measured files or a modelled printer), optionally refined by Optuna on the printer model."""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from ringtune.agents.ppo import Policy, load_policy
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError


def model_from_spectra(spectra: dict[str, tuple[np.ndarray, np.ndarray]], base=None):
    """A printer model for measured resonance PSDs ``{"x": (freqs Hz, psd), …}``: each measured
    axis's modes fitted to its PSD as ``ringtune identify`` fits them; everything a resonance test
    cannot show (moving masses, motor, limits, kinematics) and an unmeasured axis's modes from
    ``base`` (a Printer, TOML path or embedded name; default the embedded default printer)."""
    from ringtune.envs.evaluate import resolve_printer
    from ringtune.envs.identify import identify_psd
    from ringtune.envs.printer import printer_from_dict

    d = resolve_printer(base).to_dict()
    fitted = []
    for ax, (freqs, psd) in spectra.items():
        f, p = np.asarray(freqs, float), np.asarray(psd, float)
        fit = identify_psd(f, p, ax, f"measured {ax}")
        modes = sorted(fit.modes, key=lambda m: -m.share)
        d[ax]["modes"] = [{"freq": m.freq, "damping": min(max(m.damping, 0.005), 0.95), "share": m.share}
                          for m in modes]
        fitted.append(ax)
    d["name"] = f"{d['name']} with {'/'.join(a.upper() for a in fitted)} modes fitted to the measurement"
    return printer_from_dict(d, "model of the measured printer")


def preload() -> None:
    """Import what the inference path imports lazily (scipy's fitting and peak finding for the
    model, MuJoCo), so that a timed inference measures the inference (about 50 ms) and not a
    first import (about 1.3 s)."""
    import mujoco  # noqa: F401
    import scipy.optimize  # noqa: F401
    import scipy.signal  # noqa: F401


def measured_observation(policy: Policy, spectra: dict, printer=None):
    """(env, observation) of measured PSDs ``{"x": (freqs, psd), …}``, as the policy's env would
    show them at reset: their spectrum features and peaks, the starting configuration and, when the
    policy observes metrics, its metrics simulated on ``printer`` (default
    :func:`model_from_spectra` of the same spectra)."""
    if policy.env_kwargs.get("observe_metrics", False) and printer is None:
        printer = model_from_spectra(spectra)
    env = policy.make_env(printer)
    return env, env.observe_measured(spectra)


def decode_measured(env, action, spectra: dict) -> TuneConfig:
    """``action`` decoded around the measured peaks; an axis that was not measured gets shaping off
    (like Klipper's rule in ``recommend``)."""
    config = env.decode(action)
    for ax in ("x", "y"):
        if ax not in spectra:
            config = dataclasses.replace(config, **{f"shaper_{ax}": "none"})
    return config


def recommend_from_psd(policy: Policy, spectra: dict, printer=None) -> TuneConfig:
    """One inference on measured resonance PSDs ``{"x": (freqs, psd), "y": ...}`` -> TuneConfig
    (:func:`measured_observation`, the policy's action, :func:`decode_measured`). ``printer``: the
    model on which the starting answer's metrics are simulated (default: modes fitted to the
    spectra, the rest the default printer's)."""
    env, obs = measured_observation(policy, spectra, printer)
    return decode_measured(env, policy.act(obs), spectra)


def recommend_for_printer(policy: Policy, printer=None, seed: int = 0) -> tuple[TuneConfig, np.ndarray]:
    """One inference on a modelled printer's simulated resonance test (``seed`` its noise) ->
    (TuneConfig, the action). The action decodes with the peaks of that test (``env.peaks_`` of a
    fixed env reset with ``seed``)."""
    env = policy.make_env(printer)
    obs, _ = env.reset(seed=seed)
    action = policy.act(obs)
    return env.decode(action), action


def _axis_spectra(psds: dict[str, list]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """{axis: (freqs, psd)} from ``hardware.accel.PSD`` lists: the measured axis's own column (the
    sum column in the multi-dataset form), un-normalised if the file was normalised, averaged over
    the files of an axis (on the first file's frequencies)."""
    out = {}
    for ax, items in psds.items():
        f0 = np.asarray(items[0].freqs, float)
        acc = np.zeros_like(f0)
        for p in items:
            f = np.asarray(p.freqs, float)
            col = getattr(p, f"psd_{ax}", None)
            v = np.asarray(p.psd_sum if col is None else col, float)
            if getattr(p, "normalized", False):
                v = v * (f + 0.1)
            acc += np.interp(f0, f, v)
        out[ax] = (f0, acc / len(items))
    return out


def run(args, out) -> int:
    """``ringtune recommend --method policy --policy DIR (--accel CSV… [--printer P] | --printer P)
    [--refine N]``.

    Called by ``agents/commands/recommend.py``. ``--json`` keys: method ("policy"), firmware,
    policy (folder), sources ({axis: [files]} or {axis: ["printer:<name>"]}), model (name of the
    printer model the starting answer is simulated on and refined on), config (TuneConfig dict),
    inference_s (s, loading excluded; with --accel it includes fitting the model), refine (null or
    {"trials", "first_cost", "best_cost"}: the environment's cost of the policy's answer and of the
    best trial), output.
    """
    from ringtune.agents.commands.recommend import _load_accel

    if not getattr(args, "policy", None):
        raise RingtuneError("needs --policy DIR (a folder written by `ringtune train -o DIR`)", "--policy")
    policy = load_policy(args.policy)
    trained = policy.env_kwargs.get("firmware", "klipper")
    if args.firmware != trained:
        raise RingtuneError(f"this policy chooses {trained} shapers; train one for {args.firmware} "
                            f"or use --method klipper", "--firmware")
    refine = getattr(args, "refine", None)
    from ringtune.envs.evaluate import resolve_printer

    printer = resolve_printer(None if args.printer in (None, "default") else args.printer) if args.printer else None
    preload()
    t0 = time.perf_counter()
    if args.accel:
        psds, sources = _load_accel(args.accel, args.axes)
        spectra = _axis_spectra(psds)
        env, obs = measured_observation(policy, spectra, printer)
        action = policy.act(obs)
        config = decode_measured(env, action, spectra)
        printer, peaks = env.printer, env.peaks_
    else:
        config, action = recommend_for_printer(policy, printer, args.seed)
        sources = {ax: [f"printer:{getattr(printer, 'name', 'default')}"] for ax in ("x", "y")}
        peaks = None
    inference = time.perf_counter() - t0
    refined = None
    if refine:
        from ringtune.agents.ppo_refine import PrinterCost, optuna_search

        out.note(f"refining with Optuna: {refine} trials, the policy's answer first ...")
        cost = PrinterCost(printer, policy.env_kwargs, seed=args.seed, peaks=peaks)
        res = optuna_search(cost, int(refine), args.seed, first_action=action)
        config = decode_measured(cost.env, res.best_action, spectra) if args.accel else res.best_config
        refined = {"trials": int(refine), "first_cost": res.first_cost, "best_cost": res.best_cost}
    config = dataclasses.replace(config, extra={"method": "policy", "policy": str(policy.path),
                                                "sources": sources, "refine": refined})
    written = None
    if args.output:
        config.save(args.output)
        written = str(args.output)
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
