"""PPO (stable-baselines3) on the domain-randomised tuning environment: the policy, the env it acts in,
its starting answer (:data:`PRIOR`), and loading a trained one.

The policy maps what an accelerometer sees (the resonance-test spectra of X and Y, binned as
``ringtune/Tune-v0`` bins them), together with one simulation of its starting answer (:data:`PRIOR`)
on the printer's model, to a whole configuration in one step: shaper type, F and S per axis, the
infill frequency limit and the acceleration. F is a residual around each axis's resonance peak,
the acceleration a residual around the acceleration that simulation suggests
(:mod:`ringtune.envs.accel_model`). Episodes are one step long (a contextual bandit), so the
reward is the configuration's cost on that printer, negated (see :class:`ringtune.envs.env.TuneEnv`).
Training it (the output folder, the seeds): :mod:`ringtune.agents.ppo.training`.

Security: :func:`load_policy` unpickles files (stable-baselines3 zips can carry pickled objects,
``vecnormalize.pkl`` is a pickle). Load only policies from a source you trust.
"""

from __future__ import annotations

import json
import pickle
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ringtune.agents.ppo.rl import rl
from ringtune.envs.actions import encode_config
from ringtune.envs.env import TuneEnv
from ringtune.envs.variants import DEFAULT_FREQ_MARGIN
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError

#: keyword arguments of the training env (on top of ``randomize=True``)
#: (the exact linear backend "lti": same costs as MuJoCo to ~1e-4 on the linear printer model, ~1.6×
#: cheaper per step; evaluations outside training use the env's default, MuJoCo)
#: F is decoded relative to each axis's resonance peak (a residual around a physical anchor, which
#: transfers to measured spectra) and the frequency limit is off unless the policy chooses it.
#: The policy also observes the metrics of its starting answer (:data:`PRIOR`) on the printer's model
#: (``observe_metrics``, ``start_action`` filled in by :func:`resolve_env_kwargs`): how much that
#: printer rings, overshoots or loses steps at 4000 mm/s² is what decides how hard it can be driven,
#: and a spectrum alone does not show it (the motor's force reserve, the moving masses)
#: ``freq_margin`` (tune's, 0.05): every evaluation (the starting answer it observes, its answer, the reward) is
#: judged as ``tune`` judges, on the printer and its resonances ±5 % with damping ×0.75. Trained on
#: the printer alone, a policy learns answers its twins punish: the benchmark, which judges as tune
#: does, then finds it worse than its own starting answer
DEFAULT_ENV_KWARGS: dict[str, Any] = {"tune_accel": True, "observe_metrics": True, "backend": "lti",
                                      "freq_anchor": "peak", "freq_limit_gate": True, "accel_anchor": "model",
                                      "freq_margin": DEFAULT_FREQ_MARGIN}


# -- environments -----------------------------------------------------------------------------------
def resolve_env_kwargs(env_kwargs: dict | None = None) -> dict:
    """:data:`DEFAULT_ENV_KWARGS` updated by ``env_kwargs``; an env that observes metrics without a
    ``start_action`` starts from :data:`PRIOR` (the training reference: its evaluation at reset is
    reused as the reference reward). JSON-ready (the action as a list)."""
    kw = {**DEFAULT_ENV_KWARGS, **(env_kwargs or {})}
    if kw.get("observe_metrics") and kw.get("start_action") is None:
        kw["start_action"] = [float(v) for v in prior_action(kw)]
    return kw


#: where the untrained policy's mean answer starts: MZV on the resonance peak (50 Hz with an
#: absolute action), damping 0.075, no frequency limit, 4000 mm/s² (with the model-anchored
#: acceleration: 4000 is the starting configuration the env simulates, and the untrained policy
#: answers the anchor that simulation gives). The best constant answer on
#: training printers: of MZV/ZVD/EI × 3000–6000 mm/s² × damping 0.05–0.1 on seeds 1000–1029, MZV
#: with damping 0.05–0.075 at 4000–6000 mm/s² (mean cost 1.11–1.13; EI 1.19); of MZV at
#: 3000–5000 mm/s² on seeds 1030–1129, 4000 (1.264; 5000: 1.273, where more printers lose steps).
#: Training refines a sound population answer (e.g. lower accelerations for low resonances)
PRIOR = {"shaper": "mzv", "freq": 50.0, "damping": 0.075, "accel": 4000.0}


def prior_action(env_kwargs: dict) -> np.ndarray:
    """:data:`PRIOR` as an action of the env ``env_kwargs`` describe (peak-anchored: F on the peak)."""
    spec = TuneEnv(randomize=True, **{**env_kwargs, "start_action": None}).spec_
    name = PRIOR["shaper"] if PRIOR["shaper"] in spec.shapers else spec.shapers[-1]
    prior = TuneConfig(firmware=spec.firmware, shaper_x=name, shaper_y=name, freq_x=PRIOR["freq"],
                       freq_y=PRIOR["freq"], damping_x=PRIOR["damping"], damping_y=PRIOR["damping"],
                       freq_limit_hz=0.0, accel=PRIOR["accel"] if spec.tune_accel else None)
    return encode_config(prior, spec, (PRIOR["freq"],) * 2)


# -- using a trained policy -------------------------------------------------------------------------
@dataclass
class Policy:
    """A loaded policy: the SB3 model, its observation normaliser and the env it was trained on."""

    model: Any
    vecnorm: Any
    meta: dict
    path: Path

    @property
    def env_kwargs(self) -> dict:
        return dict(self.meta.get("env_kwargs", DEFAULT_ENV_KWARGS))

    def make_env(self, printer=None, backend: str = "mujoco"):
        """A fixed-printer env with the training env's action/observation layout."""
        return TuneEnv(printer=printer, randomize=False, **{**self.env_kwargs, "backend": backend})

    def act(self, obs: np.ndarray) -> np.ndarray:
        """Deterministic action for one raw (unnormalised) observation."""
        o = self.vecnorm.normalize_obs(np.asarray(obs, np.float32)[None, :])
        action, _ = self.model.predict(o, deterministic=True)
        return np.clip(np.asarray(action[0], dtype=np.float32), -1.0, 1.0)


def load_policy(policy_dir: str | Path, which: str = "policy") -> Policy:
    """Load ``policy_dir/policy.zip`` and ``vecnormalize.pkl`` (``which="final"``: the weights at
    the end of training; ``"best"``: ``best/``). **Trusts its source**: both files can carry pickled Python objects that run
    code when loaded; load only policies you trained or got from someone you trust."""
    sb3 = rl()                      # without the rl extra, that is the first thing to say
    d = Path(policy_dir)
    if which not in ("policy", "final", "best"):
        raise RingtuneError(f"which must be 'policy', 'final' or 'best', not {which!r}", "which")
    zp, pk = {"policy": (d / "policy.zip", d / "vecnormalize.pkl"),
              "final": (d / "final.zip", d / "final_vecnormalize.pkl"),
              "best": (d / "best/best_model.zip", d / "best/vecnormalize.pkl")}[which]
    for p in (zp, pk, d / "meta.json"):
        if not p.is_file():
            raise RingtuneError(f"not a trained policy folder: {p.name} is missing (run `ringtune train -o DIR`)",
                                str(d))
    model = sb3.PPO.load(str(zp), device="cpu")
    with open(pk, "rb") as fh:
        vecnorm = pickle.load(fh)
    vecnorm.training = False
    vecnorm.norm_reward = False
    meta = json.loads((d / "meta.json").read_text())
    policy = Policy(model, vecnorm, meta, d)
    want = policy.make_env().observation_space.shape
    if tuple(model.observation_space.shape) != tuple(want):
        raise RingtuneError(f"this policy observes {model.observation_space.shape[0]} values but this version of "
                            f"ringtune shows {want[0]} (an older observation layout); train it again", str(d))
    return policy
