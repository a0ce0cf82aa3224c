"""``ringtune train``: PPO across randomised printers (stable-baselines3).

``--json`` keys (stable):
    out_dir: the output folder
    timesteps: environment steps done in total (a resumed run counts the earlier ones)
    wall_s: wall time of this run, s
    resumed_from: checkpoint resumed from, or null
    eval_timesteps, eval_mean_cost: held-out printers' mean cost at each evaluation
    train_timesteps, train_mean_cost: mean training cost per rollout
    train_reference_cost: the starting answer's cost on the same training printers (or [])
    hpo: null, or {"best_params": {...}, "best_cost": float, "trials": int, "all": [...]}
    files: {"policy", "vecnormalize", "curve", "final", "meta"} paths
"""

from __future__ import annotations

NAME = "train"
HELP = "train a PPO policy that recommends a configuration from a resonance test (random printers)"
DESCRIPTION = """\
Train a PPO policy (stable-baselines3) on the domain-randomised environment ringtune/Tune-v0: every
episode is a new random printer; the policy sees its simulated resonance-test spectra (X and Y)
and answers with a whole configuration (shaper type, F and S per axis, infill frequency limit,
acceleration); the reward is minus the configuration's cost (print-time ratio plus weighted path
error, overshoot and ringing; step loss penalised).

Runs --envs environments in subprocesses, normalises observations and rewards (VecNormalize),
evaluates on 8 held-out printers (seeds disjoint from training) at the start and during training,
shows a progress bar, and writes checkpoints. The training reward is the cost relative to a
reference answer (MZV on the peak) on the same printer, each printer shown 4 times: the same
optimum, without the spread between printers. The output folder DIR receives policy.zip and
vecnormalize.pkl (the held-out best, the starting policy included), final.zip (the last weights),
best/, training_curve.png, evaluations.npz and meta.json. --resume continues from the newest checkpoint
in DIR up to --timesteps in total. --hpo first tunes PPO's own hyperparameters with Optuna (short
runs; a fifth of the budget), then trains with the best ones.

The policy's shaper frequencies are residuals around each axis's resonance peak (found in the
same resonance-test PSD it observes): 0 puts the shaper on the peak, +-1 an octave above or below,
so the answer transfers to measured spectra; the frequency limit stays off unless chosen.

The defaults (12288 steps, 2 envs) took 16.1 min on 2 cores shared with other jobs (load
average ~3); one step costs ~0.1 s on a free core, so about 12 min on 2 free cores.

Policy files are stable-baselines3 zips plus a pickle: loading one runs code from it, so only use
policies you trained or trust.

examples:
  ringtune train -o policy/                       # defaults
  ringtune train --timesteps 4096 --envs 2 --seed 1 -o quick/
  ringtune train -o policy/ --timesteps 20000 --resume
  ringtune recommend --method policy --policy policy/ --printer default
"""


#: library parameters whose option has another name (see agents/cli.py: as_flag)
PARAMETER_FLAGS = {"n_trials": "--hpo-trials"}


def add_arguments(p) -> None:
    from ringtune.agents.ppo import DEFAULT_N_ENVS, DEFAULT_TIMESTEPS

    p.add_argument("--timesteps", type=int, default=DEFAULT_TIMESTEPS, metavar="N",
                   help=f"environment steps in total (default {DEFAULT_TIMESTEPS})")
    p.add_argument("--envs", type=int, default=DEFAULT_N_ENVS, metavar="K",
                   help=f"parallel environments, in subprocesses when > 1 (default {DEFAULT_N_ENVS})")
    p.add_argument("--seed", type=int, default=0, metavar="S", help="seed (default 0; < 800000)")
    p.add_argument("-o", "--output", default="policy", metavar="DIR", help="output folder (default ./policy)")
    p.add_argument("--resume", action="store_true", help="continue from the newest checkpoint in DIR")
    p.add_argument("--hpo", action="store_true", help="tune PPO hyperparameters with Optuna first")
    p.add_argument("--hpo-trials", type=int, default=6, metavar="N", help="Optuna trials for --hpo (default 6)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def run(args, out) -> int:
    from pathlib import Path

    from ringtune.agents import ppo
    from ringtune.shaping.errors import RingtuneError

    if args.envs < 1:
        raise RingtuneError("needs at least one environment", "--envs")
    if args.timesteps < 1:
        raise RingtuneError("must be ≥ 1", "--timesteps")
    if not 0 <= args.seed < ppo.MAX_TRAIN_SEED:
        raise RingtuneError(f"must be in [0, {ppo.MAX_TRAIN_SEED}) (higher seeds are the held-out printers)",
                            "--seed")
    hyper, hpo = None, None
    if args.hpo:
        if args.resume:
            raise RingtuneError("--hpo starts a new run; it cannot resume", "--hpo")
        from ringtune.agents.ppo_hpo import tune_hyperparameters

        out.note(f"tuning PPO hyperparameters: {args.hpo_trials} short runs ...")
        hpo = tune_hyperparameters(Path(args.output) / "hpo", n_trials=args.hpo_trials,
                                   budget=max(args.timesteps // 5, 256), n_envs=args.envs, seed=args.seed)
        hyper = hpo["best_params"]
        out.note(f"best hyperparameters: {hyper} (held-out cost {hpo['best_cost']:.3f})")
    out.note(f"training PPO: {args.timesteps} steps on {args.envs} env(s) -> {args.output}")
    res = ppo.train(args.output, args.timesteps, args.envs, args.seed, resume=args.resume, hyper=hyper,
                    progress_bar=not args.no_progress)
    d = Path(args.output)
    files = {"policy": str(d / "policy.zip"), "vecnormalize": str(d / "vecnormalize.pkl"),
             "curve": str(d / "training_curve.png"), "final": str(d / "final.zip"),
             "meta": str(d / "meta.json")}
    result = {**res.to_dict(), "hpo": hpo, "files": files}
    text = [f"trained {res.timesteps} steps in {res.wall_s:.0f} s"
            + (f" (resumed from {res.resumed_from})" if res.resumed_from else "")]
    if res.eval_mean_cost:
        text.append("held-out mean cost: " + ", ".join(
            f"{c:.3f}@{t}" for t, c in zip(res.eval_timesteps, res.eval_mean_cost)))
    text.append(f"policy: {files['policy']} (+ {files['vecnormalize']}); curve: {files['curve']}")
    text.append(f"use it: ringtune recommend --method policy --policy {d} --printer default")
    out.emit(result, "\n".join(text))
    return 0
