"""A trained PPO policy's configuration from a resonance test (measured PSDs or a modelled printer's
simulated test): the library behind ``ringtune recommend --method policy``
(``agents/cli/recommend.py``)."""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import numpy as np

from ringtune.agents.identify.accelerometer import resonance_psds
from ringtune.agents.ppo.guard import Guard, hold_to_start, start_action
from ringtune.agents.ppo.policy import Policy, load_policy
from ringtune.agents.ppo.refine import PrinterCost, optuna_search
from ringtune.envs.planned_job import resolve_printer
from ringtune.envs.identify import identify_psd
from ringtune.envs.printer import printer_from_dict
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError


def model_from_spectra(spectra: dict[str, tuple[np.ndarray, np.ndarray]], base=None):
    """A printer model for measured resonance PSDs ``{"x": (freqs Hz, psd), …}``: each measured
    axis's modes fitted to its PSD as ``ringtune identify`` fits them; everything a resonance test
    cannot show (moving masses, motor, limits, kinematics) and an unmeasured axis's modes from
    ``base`` (a Printer, TOML path or embedded name; default the embedded default printer)."""
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


def policy_on_simulated_test(policy: Policy, printer=None, seed: int = 0) -> tuple[TuneConfig, np.ndarray]:
    """One inference on a modelled printer's simulated resonance test (``seed`` its noise) ->
    (TuneConfig, the action). The action decodes with the peaks of that test (``env.peaks_`` of a
    fixed env reset with ``seed``)."""
    env = policy.make_env(printer)
    obs, _ = env.reset(seed=seed)
    action = policy.act(obs)
    return env.decode(action), action


def axis_spectra(psds: dict[str, list]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
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


def _silent(_message: str) -> None:
    """A ``note`` that says nothing."""


@dataclass
class PolicyPick:
    """A trained policy's answer (``ringtune recommend --method policy``): the TuneConfig (its
    ``extra`` says how it was made), the policy, where the data came from per axis, the model
    the starting answer was simulated on, the inference time (s, loading excluded; with files it
    includes fitting the model), the guard (None or :class:`ringtune.agents.ppo.guard.Guard`: the
    policy's answer against its starting answer on the model) and the refinement (None or {trials,
    first_cost, best_cost})."""

    config: TuneConfig
    policy: Policy
    sources: dict[str, list[str]]
    model: str
    inference_s: float
    refined: dict | None
    guard: Guard | None = None


def policy_pick(policy_dir, firmware: str = "klipper", accel: list | None = None, printer=None,
                axes: str | None = None, seed: int = 0, refine: int | None = None, note=_silent,
                guard: bool = True) -> PolicyPick:
    """The policy in ``policy_dir`` on the resonance files ``accel`` (modes fitted to them; the
    rest of the model from ``printer``, TOML or embedded name) or on ``printer``'s simulated
    resonance test (``seed`` its noise). ``guard``: the policy's answer and its starting answer
    judged on the model, the lower cost kept (:mod:`ringtune.agents.ppo.guard`); ``refine``: that
    many Optuna trials on the model, the answer kept first."""
    policy = load_policy(policy_dir)
    trained = policy.env_kwargs.get("firmware", "klipper")
    if firmware != trained:
        raise RingtuneError(f"this policy chooses {trained} shapers; train one for {firmware} "
                            f"or use --method klipper", "firmware")
    printer = resolve_printer(None if printer in (None, "default") else printer) if printer else None
    t0 = time.perf_counter()
    spectra, peaks = None, None
    if accel:
        psds, sources = resonance_psds(accel, axes, note)
        spectra = axis_spectra(psds)
        env, obs = measured_observation(policy, spectra, printer)
        action = policy.act(obs)
        config = decode_measured(env, action, spectra)
        printer, peaks = env.printer, env.peaks_
    else:
        config, action = policy_on_simulated_test(policy, printer, seed)
        sources = {ax: [f"printer:{getattr(printer, 'name', 'default')}"] for ax in ("x", "y")}
    inference = time.perf_counter() - t0
    refined, held = None, None
    cost = PrinterCost(printer, policy.env_kwargs, seed=seed, peaks=peaks) if guard or refine else None
    if guard:
        note("judging the policy's answer against its starting answer on the model ...")
        kept, held = hold_to_start(cost, action, start_action(policy.env_kwargs))
        if held.kept == "start":
            action = kept
            config = decode_measured(cost.env, kept, spectra) if accel else cost.env.decode(kept)
    if refine:
        first = "the answer the guard kept" if guard else "the policy's answer"
        note(f"refining with Optuna: {refine} trials, {first} first ...")
        res = optuna_search(cost, int(refine), seed, first_action=action)
        config = decode_measured(cost.env, res.best_action, spectra) if accel else res.best_config
        refined = {"trials": int(refine), "first_cost": res.first_cost, "best_cost": res.best_cost}
    config = dataclasses.replace(config, extra={"method": "policy", "policy": str(policy.path), "sources": sources,
                                                "guard": held.to_dict() if held else None, "refine": refined})
    return PolicyPick(config, policy, sources, getattr(printer, "name", "the default printer"), inference, refined,
                      held)
