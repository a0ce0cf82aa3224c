"""Training the PPO policy (:mod:`ringtune.agents.ppo.policy`) on random printers: :func:`train`, its
vector environments, checkpoints, training curve and output folder.

Output folder of :func:`train` (``-o DIR``):

| file | what |
|---|---|
| ``policy.zip`` | the policy to use (stable-baselines3 format): the one that scored best on the held-out printers, the starting policy included |
| ``vecnormalize.pkl`` | its observation/reward normalisation statistics (``VecNormalize.save``) |
| ``final.zip``, ``final_vecnormalize.pkl`` | the weights and statistics at the end of training |
| ``best/best_model.zip``, ``best/vecnormalize.pkl`` | the held-out best as ``EvalCallback`` saved it |
| ``checkpoints/`` | ``ppo_<steps>_steps.zip`` + ``ppo_vecnormalize_<steps>_steps.pkl`` (resume) |
| ``evaluations.npz`` | held-out evaluations (timesteps, rewards), EvalCallback's format |
| ``training_curve.npz``, ``training_curve.png`` | mean training cost per rollout and held-out cost vs timesteps |
| ``meta.json`` | env keyword arguments, seeds, hyperparameters, timesteps done, wall time |

Seeds: training worker ``k`` is seeded ``seed + k`` (then draws a new printer from its own stream
every episode); the held-out printers of the evaluation callback are ``reset(seed=s)`` for
``s`` in :data:`EVAL_SEEDS`; the benchmark uses :data:`BENCH_SEEDS`. :func:`train` refuses
training seeds that reach into those ranges.
"""

from __future__ import annotations

import json
import shutil
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

import gymnasium as gym
import matplotlib
import matplotlib.pyplot as plt
import numpy as np

from ringtune.agents.ppo.callbacks import curve_callback, held_out_callback
from ringtune.agents.ppo.policy import prior_action, resolve_env_kwargs
from ringtune.agents.ppo.reward import ReferenceRelative
from ringtune.agents.ppo.rl import rl
from ringtune.envs.env import TuneEnv
from ringtune.shaping.errors import RingtuneError

#: held-out printers of the evaluation callback (never used for training; the policy kept is the one
#: whose mean cost on them is lowest, and one printer's cost can move by half between two policies:
#: 16, not 8, so that no single printer decides which is kept)
EVAL_SEEDS = tuple(range(900_000, 900_016))
#: the benchmark's unseen printers (benchmarks/bench_ppo.py)
BENCH_SEEDS = tuple(range(950_000, 950_020))
#: training seeds must stay below this
MAX_TRAIN_SEED = 800_000
#: ``ringtune train`` defaults (acceptance 4: ≤ 20 min on 2 cores; one episode ~0.35 s per free core with
#: the lti backend, judged on the printer and its twins as tune judges: 3 evaluations of 3 printers)
DEFAULT_TIMESTEPS = 6_144
DEFAULT_N_ENVS = 2
#: (``reference_reward``/``printer_repeats``: the training reward is relative to
#: :data:`~ringtune.agents.ppo.policy.PRIOR` on the same printer, each printer shown 4 times; see
#: :mod:`ringtune.agents.ppo.reward`. A small ``log_std_init`` explores near the prior instead of
#: averaging over far-off configurations)
DEFAULT_HYPER: dict[str, Any] = {
    "learning_rate": 3e-4, "n_steps": 256, "batch_size": 128, "n_epochs": 5, "gamma": 0.0,
    "gae_lambda": 1.0, "ent_coef": 0.0, "clip_range": 0.2, "log_std_init": -2.0, "net_arch": [128, 128],
    "log_std_freq": -3.0, "reference_reward": True, "printer_repeats": 4,
}


# -- environments -----------------------------------------------------------------------------------
def _pinned_env(seed: int, env_kwargs: dict):
    """A Tune-v0 env whose every reset uses ``seed`` (the same held-out printer each time)."""
    class PinnedSeed(gym.Wrapper):
        def reset(self, *, seed=None, options=None):  # noqa: ARG002 - the pinned seed wins
            return self.env.reset(seed=self._pinned, options=options)

    w = PinnedSeed(TuneEnv(randomize=True, **env_kwargs))
    w._pinned = int(seed)
    return rl().Monitor(w)


def _make_train_env(rank: int, seed: int, env_kwargs: dict, hyper: dict):
    def thunk():
        env = TuneEnv(randomize=True, **env_kwargs)
        if hyper.get("reference_reward"):
            start = env_kwargs.get("observe_metrics") and env_kwargs.get("start_action") is not None
            ref = None if start else prior_action(env_kwargs)       # None: the observed starting answer
            env = ReferenceRelative(env, ref, hyper.get("printer_repeats", 1))
        env = rl().Monitor(env)
        env.reset(seed=seed + rank)
        return env
    return thunk


def _make_eval_env_fn(s: int, env_kwargs: dict):
    return lambda: _pinned_env(s, env_kwargs)


def make_vec_envs(n_envs: int, seed: int, env_kwargs: dict, subprocess: bool = True,
                  hyper: dict | None = None):
    """(training VecEnv, held-out eval VecEnv), both not yet normalised. The held-out printers
    always score the plain cost; training uses the reference-relative reward when
    ``hyper["reference_reward"]`` (:mod:`ringtune.agents.ppo.reward`)."""
    sb3 = rl()
    hyper = {**DEFAULT_HYPER, **(hyper or {})}
    fns = [_make_train_env(k, seed, env_kwargs, hyper) for k in range(n_envs)]
    venv = sb3.SubprocVecEnv(fns) if subprocess and n_envs > 1 else sb3.DummyVecEnv(fns)
    venv.seed(seed)
    eval_env = sb3.DummyVecEnv([_make_eval_env_fn(s, env_kwargs) for s in EVAL_SEEDS])
    return venv, eval_env


# -- training -----------------------------------------------------------------------------------------
def _publish_best(out: Path) -> None:
    """``policy.zip`` + ``vecnormalize.pkl`` := the held-out best (``best/``), else the final weights."""
    best = (out / "best" / "best_model.zip", out / "best" / "vecnormalize.pkl")
    src = best if all(p.is_file() for p in best) else (out / "final.zip", out / "final_vecnormalize.pkl")
    shutil.copyfile(src[0], out / "policy.zip")
    shutil.copyfile(src[1], out / "vecnormalize.pkl")


@dataclass
class TrainResult:
    out_dir: Path
    timesteps: int
    wall_s: float
    eval_timesteps: list = field(default_factory=list)
    eval_mean_cost: list = field(default_factory=list)
    train_timesteps: list = field(default_factory=list)
    train_mean_cost: list = field(default_factory=list)
    train_reference_cost: list = field(default_factory=list)   # the prior's, same printers (or empty)
    resumed_from: str | None = None

    def to_dict(self) -> dict:
        return {"out_dir": str(self.out_dir), "timesteps": self.timesteps, "wall_s": self.wall_s,
                "eval_timesteps": self.eval_timesteps, "eval_mean_cost": self.eval_mean_cost,
                "train_timesteps": self.train_timesteps, "train_mean_cost": self.train_mean_cost,
                "train_reference_cost": self.train_reference_cost,
                "resumed_from": self.resumed_from}


def latest_checkpoint(out_dir: str | Path) -> tuple[Path, Path] | None:
    """(policy zip, vecnormalize pkl) of the newest checkpoint in ``out_dir/checkpoints``, or None."""
    ck = Path(out_dir) / "checkpoints"
    best = None
    for z in ck.glob("ppo_*_steps.zip"):
        steps = int(z.stem.split("_")[1])
        pkl = ck / f"ppo_vecnormalize_{steps}_steps.pkl"
        if pkl.is_file() and (best is None or steps > best[0]):
            best = (steps, z, pkl)
    return None if best is None else (best[1], best[2])


def _check_train_args(seed: int, n_envs: int, timesteps: int) -> None:
    """Refuse a training seed among the held-out printers', no environment, or no step."""
    if not 0 <= seed < MAX_TRAIN_SEED:
        raise RingtuneError(f"must be in [0, {MAX_TRAIN_SEED}) (higher seeds are the held-out printers)", "seed")
    if n_envs < 1:
        raise RingtuneError("needs at least one environment", "n_envs")
    if timesteps < 1:
        raise RingtuneError("must be ≥ 1", "timesteps")


def _start_model(sb3, venv, out: Path, resume: bool, env_kwargs: dict, hyper: dict, seed: int, verbose: int):
    """(normalised env, PPO model, checkpoint resumed from or None): the newest checkpoint in ``out``
    (``resume``), else a new model with ``hyper`` and the prior answer."""
    if resume:
        ck = latest_checkpoint(out)
        if ck is None:
            raise RingtuneError("no checkpoint to resume from (train without --resume first)", str(out))
        venv = sb3.VecNormalize.load(str(ck[1]), venv)
        model = sb3.PPO.load(str(ck[0]), env=venv, device="cpu")
        model.set_logger(_logger(sb3, verbose))
        return venv, model, str(ck[0])
    venv = sb3.VecNormalize(venv, norm_obs=True, norm_reward=True, clip_obs=10.0, gamma=0.99)
    policy_kwargs = {"net_arch": list(hyper["net_arch"]), "log_std_init": hyper["log_std_init"]}
    model = sb3.PPO("MlpPolicy", venv, learning_rate=hyper["learning_rate"], n_steps=hyper["n_steps"],
                    batch_size=hyper["batch_size"], n_epochs=hyper["n_epochs"], gamma=hyper["gamma"],
                    gae_lambda=hyper["gae_lambda"], ent_coef=hyper["ent_coef"],
                    clip_range=hyper["clip_range"], policy_kwargs=policy_kwargs, seed=seed,
                    device="cpu", verbose=verbose)
    model.set_logger(_logger(sb3, verbose))
    _set_prior(model, env_kwargs, hyper)
    return venv, model, None


def _logger(sb3, verbose: int):
    """stable-baselines3's logger writing to stdout when ``verbose`` and nowhere else (its default
    makes an empty SB3-<date> folder in the temporary directory at every learn)."""
    return sb3.Logger(None, [sb3.HumanOutputFormat(sys.stdout)] if verbose else [])


def _previous_best(out: Path, resume: bool) -> float | None:
    """The best held-out mean reward of the run resumed (None: a new run, or none evaluated)."""
    if not (resume and (out / "evaluations.npz").is_file()):
        return None
    return float(np.max(np.mean(np.load(out / "evaluations.npz")["results"], axis=1)))


def _curves(res: TrainResult, out: Path, resume: bool, curve) -> None:
    """``res``'s held-out evaluations and training curve (a resumed run's before this one's), the
    curve saved to ``training_curve.npz``."""
    ev = out / "evaluations.npz"
    if ev.is_file():
        d = np.load(ev)
        res.eval_timesteps = d["timesteps"].astype(int).tolist()
        res.eval_mean_cost = [float(-np.mean(r)) for r in d["results"]]
    prev = out / "training_curve.npz"
    before = np.load(prev) if resume and prev.is_file() else {}
    res.train_timesteps = _saved(before, "train_timesteps", int) + curve.timesteps
    res.train_mean_cost = _saved(before, "train_mean_cost", float) + curve.costs
    res.train_reference_cost = _saved(before, "train_reference_cost", float) + curve.reference_costs
    if len(res.train_reference_cost) != len(res.train_mean_cost):
        res.train_reference_cost = []
    np.savez(prev, train_timesteps=np.asarray(res.train_timesteps), train_mean_cost=np.asarray(res.train_mean_cost),
             train_reference_cost=np.asarray(res.train_reference_cost))


def _saved(npz, key: str, kind: type) -> list:
    """The curve ``key`` a resumed run saved (an ``.npz`` mapping), as a list of ``kind``; [] when absent."""
    return npz[key].astype(kind).tolist() if key in npz else []


def train(out_dir: str | Path, timesteps: int = DEFAULT_TIMESTEPS, n_envs: int = DEFAULT_N_ENVS,
          seed: int = 0, *, resume: bool = False, env_kwargs: dict | None = None,
          hyper: dict | None = None, eval_freq: int | None = None, checkpoint_freq: int | None = None,
          progress_bar: bool = True, subprocess: bool = True, verbose: int = 0,
          callbacks: Sequence = ()) -> TrainResult:
    """Train PPO on ``ringtune/Tune-v0`` (random printers) and write the output folder.

    ``timesteps``: total environment steps (= episodes = evaluated configurations), counting
    those of a resumed run. ``eval_freq`` / ``checkpoint_freq``: in total steps (default: eight
    evaluations and checkpoints per run). ``resume``: continue from the newest checkpoint in
    ``out_dir`` (error if none). ``hyper`` overrides :data:`DEFAULT_HYPER`. ``callbacks``: more
    stable-baselines3 callbacks (e.g. the CLI's progress lines).
    """
    sb3 = rl()
    _check_train_args(seed, n_envs, timesteps)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    env_kwargs = resolve_env_kwargs(env_kwargs)
    hyper = {**DEFAULT_HYPER, **(hyper or {})}
    sb3.torch.set_num_threads(1)
    t0 = time.perf_counter()
    venv, eval_env = make_vec_envs(n_envs, seed, env_kwargs, subprocess, hyper)
    try:
        venv, model, resumed = _start_model(sb3, venv, out, resume, env_kwargs, hyper, seed, verbose)
        eval_venv = sb3.VecNormalize(eval_env, training=False, norm_obs=True, norm_reward=False, clip_obs=10.0)
        every = max(eval_freq or timesteps // 8, n_envs) // n_envs
        ck_every = max(checkpoint_freq or timesteps // 8, n_envs) // n_envs
        curve = curve_callback()
        callbacks = sb3.CallbackList([
            held_out_callback(eval_venv, len(EVAL_SEEDS), every, out, _previous_best(out, resume)),
            sb3.CheckpointCallback(save_freq=ck_every, save_path=str(out / "checkpoints"), name_prefix="ppo",
                                   save_vecnormalize=True),
            curve,
            *callbacks,
        ])
        remaining = timesteps - model.num_timesteps
        if remaining > 0:
            model.learn(total_timesteps=remaining, callback=callbacks, progress_bar=progress_bar,
                        reset_num_timesteps=not resume)
        model.save(str(out / "final.zip"))
        venv.save(str(out / "final_vecnormalize.pkl"))
        _publish_best(out)
    finally:
        venv.close()
        eval_env.close()
    wall = time.perf_counter() - t0
    res = TrainResult(out, int(model.num_timesteps), wall, resumed_from=resumed)
    _curves(res, out, resume, curve)
    meta = {"env_id": "ringtune/Tune-v0", "env_kwargs": env_kwargs, "hyper": hyper, "seed": seed,
            "n_envs": n_envs, "timesteps": res.timesteps, "wall_s": wall, "eval_seeds": list(EVAL_SEEDS),
            "resumed_from": resumed}
    (out / "meta.json").write_text(json.dumps(meta, indent=2))
    plot_training_curve(res, out / "training_curve.png")
    return res


def _set_prior(model, env_kwargs: dict, hyper: dict) -> None:
    """Start the policy's mean action at :data:`~ringtune.agents.ppo.policy.PRIOR` (the action
    head's bias, its weights zeroed: they still learn, their gradient is the advantage times the hidden layer), instead of the centre of every range (47 Hz, a 60 Hz frequency limit, 3162 mm/s²).
    With ``hyper["log_std_freq"]`` the F entries explore with that log std (the cost is sharpest
    in F: a few per cent off the resonance costs more than a different damping)."""
    torch = rl().torch
    with torch.no_grad():
        model.policy.action_net.weight.zero_()     # exactly the prior on every printer at first
        model.policy.action_net.bias.copy_(torch.as_tensor(prior_action(env_kwargs)))
        if hyper.get("log_std_freq") is not None:
            labels = TuneEnv(randomize=True, **env_kwargs).spec_.labels()
            for i, name in enumerate(labels):
                if name.startswith("freq_") and name != "freq_limit_hz" or name == "freq":
                    model.policy.log_std[i] = float(hyper["log_std_freq"])


def plot_training_curve(res: TrainResult, path: str | Path) -> None:
    """Mean cost per training rollout and on the held-out printers, vs environment steps."""
    matplotlib.use("Agg")
    fig, ax = plt.subplots(figsize=(7, 4))
    if res.train_timesteps:
        ax.plot(res.train_timesteps, res.train_mean_cost, ".-", alpha=0.6, label="training (stochastic policy)")
        if res.train_reference_cost:
            ax.plot(res.train_timesteps, res.train_reference_cost, ":", color="grey",
                    label="starting answer on the same printers")
    if res.eval_timesteps:
        ax.plot(res.eval_timesteps, res.eval_mean_cost, "o-",
                label=f"held-out printers ({len(EVAL_SEEDS)}, deterministic)")
        k = int(np.argmin(res.eval_mean_cost))
        ax.plot([res.eval_timesteps[k]], [res.eval_mean_cost[k]], "*", ms=16, color="C3",
                label=f"published policy.zip (held-out best, {res.eval_mean_cost[k]:.3f})")
    ax.set_xlabel("environment steps (evaluated configurations)")
    ax.set_ylabel("cost = −reward (time ratio + weighted errors)")
    ax.set_title("PPO training on randomised printers")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
