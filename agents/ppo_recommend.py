"""``ringtune recommend --method policy``: a trained PPO policy's configuration from a resonance test
(measured files or a modelled printer), optionally refined by Optuna on the printer model."""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from ringtune.agents.ppo import load_policy, recommend_for_printer, recommend_from_psd
from ringtune.shaping.errors import RingtuneError

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
    """``ringtune recommend --method policy --policy DIR (--accel CSV… | --printer P) [--refine N]``.

    Called by ``agents/commands/recommend.py``. ``--json`` keys: method ("policy"), firmware,
    policy (folder), sources ({axis: [files]} or {axis: ["printer:<name>"]}), config (TuneConfig
    dict), inference_s (s, loading excluded), refine (null or {"trials", "first_cost",
    "best_cost"}: the environment's cost of the policy's answer and of the best trial), output.
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
    t0 = time.perf_counter()
    if args.accel:
        if refine:
            raise RingtuneError("refining needs a printer model to simulate: use --printer P", "--refine")
        psds, sources = _load_accel(args.accel, args.axes)
        config = recommend_from_psd(policy, _axis_spectra(psds))
        action = None
    else:
        from ringtune.envs.evaluate import resolve_printer

        printer = resolve_printer(None if args.printer in (None, "default") else args.printer)
        config, action = recommend_for_printer(policy, printer, args.seed)
        sources = {ax: [f"printer:{getattr(printer, 'name', 'default')}"] for ax in ("x", "y")}
    inference = time.perf_counter() - t0
    refined = None
    if refine:
        from ringtune.agents.ppo_refine import PrinterCost, optuna_search

        out.note(f"refining with Optuna: {refine} trials, the policy's answer first ...")
        res = optuna_search(PrinterCost(printer, policy.env_kwargs, seed=args.seed), int(refine), args.seed, first_action=action)
        config = res.best_config
        refined = {"trials": int(refine), "first_cost": res.first_cost, "best_cost": res.best_cost}
    config = dataclasses.replace(config, extra={"method": "policy", "policy": str(policy.path),
                                                "sources": sources, "refine": refined})
    written = None
    if args.output:
        config.save(args.output)
        written = str(args.output)
    accel = f"{config.accel:.0f} mm/s^2" if config.accel else "unchanged"
    text = [f"policy {policy.path} (loaded pickles: trusted source assumed), inference {inference * 1e3:.0f} ms",
            f"X: {config.shaper_x} @ {config.freq_x:.1f} Hz, damping {config.damping_x:.3f}",
            f"Y: {config.shaper_y} @ {config.freq_y:.1f} Hz, damping {config.damping_y:.3f}",
            f"frequency limit: {config.freq_limit_hz:.0f} Hz" if config.freq_limit_hz else "frequency limit: off",
            f"acceleration: {accel}"]
    if refined:
        text.append(f"refined: cost {refined['first_cost']:.4f} (policy) -> {refined['best_cost']:.4f} "
                    f"after {refine} trials")
    text.append(f"written to {written}" if written else "(use -o best.json to save it)")
    out.emit({"method": "policy", "firmware": args.firmware, "policy": str(policy.path), "sources": sources,
              "config": config.to_dict(), "inference_s": inference, "refine": refined, "output": written},
             "\n".join(text))
    return 0
