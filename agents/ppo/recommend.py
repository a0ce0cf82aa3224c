"""A trained PPO policy's configuration from a resonance test (measured PSDs or a modelled printer's
simulated test): the library behind ``ringtune recommend --method policy``
(``agents/cli/recommend.py``)."""

from __future__ import annotations

import dataclasses

import numpy as np

from ringtune.agents.ppo.policy import Policy
from ringtune.shaping.config import TuneConfig


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


def policy_on_simulated_test(policy: Policy, printer=None, seed: int = 0) -> tuple[TuneConfig, np.ndarray]:
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

