"""``ringtune train``: PPO across randomised printers (stable-baselines3).

``--json`` keys (stable):
    out_dir: the output folder
    timesteps: environment steps done in total (a resumed run counts the earlier ones)
    timesteps_requested: --timesteps N
    rollout_steps: steps PPO collects per update (n_steps × envs); training ends on a whole rollout
    wall_s: wall time of this run, s
    resumed_from: checkpoint resumed from, or null
    eval_timesteps, eval_mean_cost: held-out printers' mean cost at each evaluation
    train_timesteps, train_mean_cost: mean training cost per rollout
    train_reference_cost: the starting answer's cost on the same training printers (or [])
    hpo: null, or {"best_params": {...}, "best_cost": float, "trials": int, "all": [...]}
    files: {"policy", "vecnormalize", "curve", "final", "meta"} paths
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from ringtune.agents.cli.common import progress_interval
from ringtune.agents.cli.options import VALUES, Value
from ringtune.agents.ppo import training as ppo
from ringtune.agents.ppo.hpo import tune_hyperparameters
from ringtune.agents.ppo.rl import rl
from ringtune.agents.ppo.training import DEFAULT_HYPER, DEFAULT_N_ENVS, DEFAULT_TIMESTEPS
from ringtune.shaping.errors import RingtuneError

NAME = "train"
DESCRIPTION = """\
Train a PPO policy (stable-baselines3) on the domain-randomised environment ringtune/Tune-v0: every
episode is a new random printer; the policy sees its simulated resonance-test spectra (X and Y)
and answers with a whole configuration (shaper type, F and S per axis, infill frequency limit,
acceleration); the reward is minus the configuration's cost, tune's judgement as one number: the
print-time ratio to the printer's own acceleration, plus 5 x the summed ln(1 + relative excess) of
every visible measure (ripple, its 90th percentile, corner rounding and overshoot, extrusion,
show-through) over a baseline's (MZV on the resonance peaks) beyond tune's resolution, plus
penalties for lost steps, the motor reserve and the path-error bound.

--timesteps N trains N steps when N is a multiple of PPO's rollout (256 steps per env, so 512
with the default 2 envs); a smaller N shortens the rollout to N (rounded up to a multiple of
--envs); a larger one that is not a multiple ends on the next whole rollout. Either way the command
says so before training, and the JSON has the steps done.

Progress goes to standard error only (with --json, standard output holds the JSON object and
nothing else): a bar on a terminal, else (logs, CI, nohup) a line every 10 s with the steps done
and the held-out printers' best mean cost so far.

Runs --envs environments in subprocesses, normalises observations and rewards (VecNormalize),
evaluates on 16 held-out printers (seeds disjoint from training) at the start and during training,
shows a progress bar, and writes checkpoints. The training reward is the cost relative to a
reference answer (MZV on the peak) on the same printer, each printer shown 4 times: the same
optimum, without the spread between printers. Every evaluation (the starting answer the policy
observes, its answer, the held-out printers' cost) is judged as tune judges: on the printer and
its resonances +-5 % with damping x0.75, the worst counting. The output folder DIR receives policy.zip and
vecnormalize.pkl (the held-out best, the starting policy included), final.zip (the last weights),
best/, training_curve.png, evaluations.npz and meta.json. --resume continues from the newest checkpoint
in DIR up to --timesteps in total. --hpo first tunes PPO's own hyperparameters with Optuna (short
runs; a fifth of the budget), then trains with the best ones.

The policy's shaper frequencies are residuals around each axis's resonance peak (found in the
same resonance-test PSD it observes): 0 puts the shaper on the peak, +-1 an octave above or below,
so the answer transfers to measured spectra; the frequency limit stays off unless chosen.

The defaults (6,144 steps, 2 envs) train in 17 min 25 s on 2 otherwise idle cores (the policy
measured in the README), 27 min 54 s on cores shared with a benchmark.

Policy files are stable-baselines3 zips plus a pickle: loading one runs code from it, so only use
policies you trained or trust.

examples:
  ringtune train -o policy/                       # defaults
  ringtune train --timesteps 4096 --envs 2 --seed 1 -o quick/
  ringtune train -o policy/ --timesteps 20000 --resume
  ringtune recommend --method policy --policy policy/ --printer default
"""


#: a training seed (seeds from MAX_TRAIN_SEED on are the held-out printers)
SEED = Value("a training seed", "", 0, ppo.MAX_TRAIN_SEED, low_closed=True, high_closed=False, integer=True)
#: library parameters whose option has another name (see agents/cli/main.py: as_flag)
PARAMETER_FLAGS = {"n_trials": "--hpo-trials"}


def add_arguments(p) -> None:
    p.add_argument("--timesteps", type=VALUES["count"], default=DEFAULT_TIMESTEPS, metavar="N",
                   help=f"environment steps in total (default {DEFAULT_TIMESTEPS})")
    p.add_argument("--envs", type=VALUES["count"], default=DEFAULT_N_ENVS, metavar="K",
                   help=f"parallel environments, in subprocesses when > 1 (default {DEFAULT_N_ENVS})")
    p.add_argument("--seed", type=SEED, default=0, metavar="S",
                   help=f"seed (default 0; < {ppo.MAX_TRAIN_SEED}: higher seeds are the held-out printers)")
    p.add_argument("-o", "--output", default="policy", metavar="DIR", help="output folder (default ./policy)")
    p.add_argument("--resume", action="store_true", help="continue from the newest checkpoint in DIR")
    p.add_argument("--hpo", action="store_true", help="tune PPO hyperparameters with Optuna first")
    p.add_argument("--hpo-trials", type=VALUES["count"], default=6, metavar="N", help="Optuna trials for --hpo (default 6)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def run(args, out) -> int:
    hyper, hpo = _hpo(args, out) if args.hpo else (None, None)
    hyper, rollout, planned = rollout_for(args.timesteps, args.envs, hyper, args.resume)
    if planned != args.timesteps:
        out.note(f"PPO collects whole rollouts of {rollout // args.envs} steps × {args.envs} env(s) = {rollout}: "
                 f"--timesteps {args.timesteps} trains {planned} steps")
    steps = planned or args.timesteps    # a resumed run's steps are known once its checkpoint loads
    out.note(f"training PPO: {steps} steps on {args.envs} env(s) -> {args.output}")
    out.release()                        # training runs long: its notes and progress go out live
    tty = sys.stderr.isatty()
    lines = [] if tty or args.no_progress else [progress_lines(args.output, steps)]
    with _stdout_to_stderr():
        res = ppo.train(args.output, args.timesteps, args.envs, args.seed, resume=args.resume, hyper=hyper,
                        progress_bar=tty and not args.no_progress, callbacks=lines)
    if args.resume and res.timesteps != args.timesteps:
        out.note(f"trained {res.timesteps} steps in total, not {args.timesteps}: PPO ends on a whole rollout")
    d = Path(args.output)
    files = {"policy": str(d / "policy.zip"), "vecnormalize": str(d / "vecnormalize.pkl"),
             "curve": str(d / "training_curve.png"), "final": str(d / "final.zip"),
             "meta": str(d / "meta.json")}
    out.emit({**res.to_dict(), "timesteps_requested": args.timesteps, "rollout_steps": rollout,
              "hpo": hpo, "files": files}, _text(res, files, d))
    return 0


def _hpo(args, out) -> tuple[dict, dict]:
    """(best hyperparameters, the search's result) of --hpo: Optuna over short runs, a fifth of the budget."""
    if args.resume:
        raise RingtuneError("--hpo starts a new run; it cannot resume", "--hpo")
    out.note(f"tuning PPO hyperparameters: {args.hpo_trials} short runs ...")
    hpo = tune_hyperparameters(Path(args.output) / "hpo", n_trials=args.hpo_trials,
                               budget=max(args.timesteps // 5, 256), n_envs=args.envs, seed=args.seed)
    out.note(f"best hyperparameters: {hpo['best_params']} (held-out cost {hpo['best_cost']:.3f})")
    return hpo["best_params"], hpo


def _text(res, files: dict, d: Path) -> str:
    """What was trained and where it went, in words."""
    text = [f"trained {res.timesteps} steps in {res.wall_s:.0f} s"
            + (f" (resumed from {res.resumed_from})" if res.resumed_from else "")]
    if res.eval_mean_cost:
        text.append("held-out mean cost: " + ", ".join(
            f"{c:.3f}@{t}" for t, c in zip(res.eval_timesteps, res.eval_mean_cost)))
    text.append(f"policy: {files['policy']} (+ {files['vecnormalize']}); curve: {files['curve']}")
    text.append(f"use it: ringtune recommend --method policy --policy {d} --printer default")
    return "\n".join(text)


def rollout_for(timesteps: int, n_envs: int, hyper: dict | None, resume: bool) -> tuple[dict | None, int, int]:
    """(hyperparameters, rollout size, steps a new run will train). PPO updates after whole
    rollouts of ``n_steps`` per env; a budget below one rollout shortens ``n_steps`` to
    ceil(timesteps / envs) (and the minibatch to fit), so that a small run trains what it was asked.
    ``resume`` keeps the checkpoint's rollout (its steps are known only after loading: 0)."""
    h = {**DEFAULT_HYPER, **(hyper or {})}
    n_steps = int(h["n_steps"])
    if resume:
        return hyper, n_steps * n_envs, 0
    if timesteps < n_steps * n_envs:
        n_steps = math.ceil(timesteps / n_envs)
        hyper = {**(hyper or {}), "n_steps": n_steps,
                 "batch_size": max(2, min(int(h["batch_size"]), n_steps * n_envs))}
    rollout = n_steps * n_envs
    return hyper, rollout, math.ceil(timesteps / rollout) * rollout


class _stdout_to_stderr:
    """Everything written to standard output while training (stable-baselines3's progress bar,
    library prints, the environment subprocesses it forks) goes to standard error, so that --json
    output stays one JSON object."""

    def __enter__(self):
        sys.stdout.flush()
        self._warnings = warnings.catch_warnings()
        self._warnings.__enter__()
        # the progress bar's own "rich is experimental" warning is noise to a user
        warnings.filterwarnings("ignore", message="rich is experimental")
        self._redirect = contextlib.redirect_stdout(sys.stderr)
        self._redirect.__enter__()
        try:
            self._saved = os.dup(1)
            os.dup2(2, 1)
        except OSError:          # no file descriptors (an embedding host): the Python level suffices
            self._saved = None
        return self

    def __exit__(self, *exc):
        sys.stderr.flush()
        if self._saved is not None:
            os.dup2(self._saved, 1)
            os.close(self._saved)
        self._redirect.__exit__(*exc)
        self._warnings.__exit__(*exc)
        return False


def progress_lines(out_dir, total: int):
    """A stable-baselines3 callback printing, on stderr, a line every
    :func:`~ringtune.agents.cli.common.progress_interval` s: steps done of ``total`` and the best
    held-out mean cost so far (``out_dir/evaluations.npz``, written at each evaluation)."""
    interval = progress_interval()
    evals = Path(out_dir) / "evaluations.npz"

    class Lines(rl().BaseCallback):
        def _on_training_start(self) -> None:
            self._t0 = self._last = time.time()

        def _on_step(self) -> bool:
            now = time.time()
            if now - self._last >= interval:
                self._last = now
                best = "no held-out evaluation yet"
                try:
                    with np.load(evals) as d:
                        best = f"best held-out mean cost {-np.max(np.mean(d['results'], axis=1)):.3f}"
                except (OSError, KeyError, ValueError):
                    pass
                print(f"ringtune train: {self.num_timesteps}/{total} steps, {now - self._t0:.0f} s; {best}",
                      file=sys.stderr, flush=True)
            return True

    return Lines()
