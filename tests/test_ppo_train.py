"""PPO training pipeline (acceptance 1): both checkers on the training env, a run with several
subprocess environments, its files, resume from a checkpoint, loading and one-shot recommendation."""

from __future__ import annotations

import dataclasses
import json
import warnings

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from ringtune.agents.cli import train as train_cmd  # noqa: E402
from ringtune.agents.ppo import policy as ppo  # noqa: E402
from ringtune.agents.ppo import recommend as ppo_recommend  # noqa: E402
from ringtune.agents.ppo import training as ppo_training  # noqa: E402
from ringtune.envs.env import TuneEnv  # noqa: E402
from ringtune.shaping.config import TuneConfig  # noqa: E402
from ringtune.shaping.errors import RingtuneError  # noqa: E402

#: a small job with four sharp extruding corners: cheap to evaluate, still rings
SQUARE_JOB = "G21\nG90\nM83\nG1 X20 Y20 F12000\n" + "".join(
    "G1 X60 Y20 E1 F12000\nG1 X60 Y60 E1\nG1 X20 Y60 E1\nG1 X20 Y20 E1\n" for _ in range(2))


def _training_env():
    return TuneEnv(randomize=True, **ppo.resolve_env_kwargs())


@pytest.mark.slow
def test_both_checkers_pass_on_the_training_env():
    from gymnasium.utils.env_checker import check_env as gym_check
    from stable_baselines3.common.env_checker import check_env as sb3_check

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a checker warning is a failure too
        sb3_check(_training_env(), warn=True)
        gym_check(_training_env(), skip_render_check=True)


def test_held_out_seeds_are_disjoint_from_training_and_benchmark():
    assert max(ppo_training.EVAL_SEEDS) < min(ppo_training.BENCH_SEEDS)
    assert ppo_training.MAX_TRAIN_SEED <= min(ppo_training.EVAL_SEEDS)
    with pytest.raises(RingtuneError, match="held-out"):
        ppo_training.train("/nonexistent", 10, seed=ppo_training.EVAL_SEEDS[0])


def test_pinned_eval_env_shows_the_same_printer_every_reset():
    env = ppo_training._pinned_env(ppo_training.EVAL_SEEDS[0], ppo.resolve_env_kwargs({"job": SQUARE_JOB}))
    o1, _ = env.reset()
    p1 = env.unwrapped.printer.to_dict()
    o2, _ = env.reset(seed=123)
    assert np.array_equal(o1, o2) and env.unwrapped.printer.to_dict() == p1


@pytest.mark.slow
def test_subprocess_training_writes_policy_resumes_and_recommends(tmp_path, monkeypatch):
    monkeypatch.setattr(ppo_training, "EVAL_SEEDS", ppo_training.EVAL_SEEDS[:2])   # the mechanics, not the set
    kw = {"job": SQUARE_JOB}
    hyper = {"n_steps": 16, "batch_size": 16, "n_epochs": 2, "net_arch": [16, 16]}
    out = tmp_path / "pol"
    res = ppo_training.train(out, timesteps=32, n_envs=2, seed=3, env_kwargs=kw, hyper=hyper, eval_freq=32,
                             checkpoint_freq=32, progress_bar=True)
    assert res.timesteps == 32
    for name in ("policy.zip", "vecnormalize.pkl", "final.zip", "final_vecnormalize.pkl", "meta.json",
                 "training_curve.png", "evaluations.npz", "best/best_model.zip", "best/vecnormalize.pkl"):
        assert (out / name).is_file(), name
    meta = json.loads((out / "meta.json").read_text())
    assert meta["n_envs"] == 2 and meta["env_kwargs"]["job"] == SQUARE_JOB
    # the held-out printers are scored at the start and after 32 steps, finite costs
    assert res.eval_timesteps == [0, 32]
    assert np.all(np.isfinite(res.eval_mean_cost)) and min(res.eval_mean_cost) > 0.5
    # the policy to use is the held-out best, with the statistics it was trained under
    assert (out / "policy.zip").read_bytes() == (out / "best" / "best_model.zip").read_bytes()
    assert (out / "vecnormalize.pkl").read_bytes() == (out / "best" / "vecnormalize.pkl").read_bytes()
    assert ppo_training.latest_checkpoint(out)[0].name == "ppo_32_steps.zip"

    # resume (in-process envs to keep the test short)
    res2 = ppo_training.train(out, timesteps=64, n_envs=2, seed=3, env_kwargs=kw, hyper=hyper, eval_freq=1000,
                              checkpoint_freq=32, resume=True, progress_bar=False, subprocess=False)
    assert res2.resumed_from.endswith("ppo_32_steps.zip") and res2.timesteps == 64
    assert len(res2.train_timesteps) > len(res.train_timesteps)     # the curve continues

    policy = ppo.load_policy(out)
    # a policy whose observation layout differs from this version's env is refused in one clear error
    import shutil

    old = tmp_path / "old"
    shutil.copytree(out, old)
    meta["env_kwargs"]["accel_anchor"] = "absolute"           # one observation entry fewer
    (old / "meta.json").write_text(json.dumps(meta))
    with pytest.raises(RingtuneError, match="older observation layout"):
        ppo.load_policy(old)
    config, action = ppo_recommend.policy_on_simulated_test(policy, None, seed=0)
    assert isinstance(config, TuneConfig) and action.shape == (8,) and np.all(np.abs(action) <= 1)
    config.validate()
    assert 15 <= config.freq_x <= 150 and 15 <= config.freq_y <= 150 and 1000 <= config.accel <= 10000
    _check_recommend_cli(out)


def _check_recommend_cli(policy_dir):
    """`ringtune recommend --method policy` on a real file and on a modelled printer with --refine."""
    import io

    from ringtune.agents.cli.main import Output
    from ringtune.agents.cli import recommend
    from pathlib import Path

    def run(argv):
        import argparse

        p = argparse.ArgumentParser()
        recommend.add_arguments(p)
        args = p.parse_args(argv)
        args.json = True
        buf = io.StringIO()
        assert recommend.run(args, Output(json=True, stream=buf)) == 0
        return json.loads(buf.getvalue())

    real = Path(__file__).resolve().parent / "data" / "accel" / "klipper_psd" / "bassco_voron_v24"
    if real.is_dir():
        d = run(["--method", "policy", "--policy", str(policy_dir), "--accel", *map(str, sorted(real.glob("*.csv")))])
        assert d["method"] == "policy" and d["refine"] is None and d["inference_s"] > 0  # its speed is a benchmark, not a test
        TuneConfig.from_dict(d["config"]).validate()
    d = run(["--method", "policy", "--policy", str(policy_dir), "--printer", "default", "--refine", "2"])
    assert d["refine"]["trials"] == 2 and d["refine"]["best_cost"] <= d["refine"]["first_cost"]
    # the guard: the policy's one-shot answer and the answer it starts from (PRIOR, encoded by the
    # policy module), each scored independently by the environment's cost; the lower kept, and the
    # study's first trial is the answer kept
    from ringtune.agents.ppo.refine import PrinterCost

    policy = ppo.load_policy(policy_dir)
    one_shot, _ = ppo_recommend.policy_on_simulated_test(policy, None, seed=0)
    scorer = PrinterCost(None, policy.env_kwargs, seed=0)
    mine, start = scorer.of_config(one_shot), scorer.of_action(ppo.prior_action(policy.env_kwargs))
    assert d["guard"]["policy_cost"] == pytest.approx(mine, rel=1e-6)
    assert d["guard"]["start_cost"] == pytest.approx(start, rel=1e-6)
    assert d["guard"]["kept"] == ("start" if start < mine else "policy")
    assert d["refine"]["first_cost"] == pytest.approx(min(mine, start), rel=1e-6)
    # without the guard: the policy's own answer, as it is
    d = run(["--method", "policy", "--policy", str(policy_dir), "--printer", "default", "--no-guard"])
    assert d["guard"] is None
    assert dataclasses.replace(TuneConfig.from_dict(d["config"]), extra={}) == dataclasses.replace(one_shot, extra={})


def test_load_policy_names_the_missing_file(tmp_path):
    with pytest.raises(RingtuneError, match="policy.zip is missing"):
        ppo.load_policy(tmp_path)


def test_cli_errors_are_one_line(capsys, tmp_path):
    from ringtune.agents.cli.main import main

    for argv, what in ((["recommend", "--method", "policy", "--printer", "default"], "--policy"),
                       (["recommend", "--method", "policy", "--policy", str(tmp_path), "--printer", "default"],
                        "policy.zip is missing"),
                       (["train", "--envs", "0", "-o", str(tmp_path)], "--envs"),
                       (["recommend"], "give the resonance files (CSV…, or --accel CSV…"),
                       (["recommend", "--accel", "x.csv", "--printer", "default"], "not both"),
                       (["train", "--seed", "900000", "-o", str(tmp_path)], "--seed")):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and what in err[0], (argv, err)


def test_recommend_help_says_policy_files_must_be_trusted(capsys):
    """Issue 6: loading a policy unpickles it; `recommend --help` says so (and `train --help`)."""
    from ringtune.agents.cli.main import main

    for cmd in ("recommend", "train"):
        with pytest.raises(SystemExit):
            main([cmd, "--help"])
        text = " ".join(capsys.readouterr().out.split())
        assert "pickle" in text and "only use policies you trained or trust" in text, cmd


TRAIN_JSON_KEYS = {"out_dir", "timesteps", "wall_s", "resumed_from", "eval_timesteps", "eval_mean_cost",
                   "train_timesteps", "train_mean_cost", "train_reference_cost", "hpo", "files",
                   "timesteps_requested", "rollout_steps"}


def test_train_cli_json_keys_and_hpo_hands_its_best_to_training(tmp_path, monkeypatch, capsys):
    """`ringtune train --hpo --json`: the documented keys; the hyperparameters Optuna found are the
    ones the final training uses; --hpo with --resume is one clear line."""
    from ringtune.agents.cli.main import main

    seen = {}
    found = {"learning_rate": 1e-3, "n_steps": 64, "n_epochs": 4, "log_std_init": -2.0, "ent_coef": 1e-4,
             "net_arch": [64, 64]}

    def fake_hpo(out_dir, n_trials, budget, n_envs, seed):
        seen["hpo"] = (str(out_dir), n_trials, budget, n_envs, seed)
        return {"best_params": found, "best_cost": 1.2, "trials": n_trials, "all": []}

    def fake_train(out_dir, timesteps, n_envs, seed, **kw):
        seen["train"] = kw
        return ppo_training.TrainResult(tmp_path / "pol", timesteps, 0.1)

    monkeypatch.setattr(train_cmd, "tune_hyperparameters", fake_hpo)     # as the command calls it
    monkeypatch.setattr(ppo_training, "train", fake_train)
    out = tmp_path / "pol"
    assert main(["train", "--json", "--hpo", "--hpo-trials", "3", "--timesteps", "2000", "--envs", "2",
                 "--seed", "5", "-o", str(out)]) == 0
    res = json.loads(capsys.readouterr().out)
    assert set(res) == TRAIN_JSON_KEYS
    assert set(res["files"]) == {"policy", "vecnormalize", "curve", "final", "meta"}
    assert seen["hpo"] == (str(out / "hpo"), 3, 400, 2, 5) and seen["train"]["hyper"] == found
    assert res["hpo"]["best_params"] == found
    assert main(["train", "--hpo", "--resume", "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--hpo" in err[0]


@pytest.mark.slow
def test_hpo_runs_short_trainings_and_returns_the_best(tmp_path, monkeypatch):
    """ppo_hpo.tune_hyperparameters for real (tiny budget, small nets): every trial is a training run
    scored on the held-out printers; the best is the lowest of those scores."""
    from ringtune.agents.ppo import hpo as ppo_hpo

    def small(trial):
        return {"learning_rate": trial.suggest_float("learning_rate", 1e-4, 3e-3, log=True),
                "n_steps": 8, "batch_size": 8, "n_epochs": trial.suggest_int("n_epochs", 1, 3),
                "net_arch": [8, 8]}

    monkeypatch.setattr(ppo_hpo, "suggest_hyper", small)
    monkeypatch.setattr(ppo_training, "EVAL_SEEDS", ppo_training.EVAL_SEEDS[:2])   # the mechanics, not the set
    res = ppo_hpo.tune_hyperparameters(tmp_path, n_trials=2, budget=8, n_envs=1, seed=2,
                                       env_kwargs={"job": SQUARE_JOB})
    assert res["trials"] == 2 and len(res["all"]) == 2
    costs = [r["cost"] for r in res["all"]]
    assert all(np.isfinite(costs)) and res["best_cost"] == min(costs)
    assert res["best_params"] == res["all"][int(np.argmin(costs))]["hyper"]
    assert json.loads((tmp_path / "hpo.json").read_text())["best_cost"] == res["best_cost"]
    for k in range(2):
        assert (tmp_path / f"trial_{k}" / "policy.zip").is_file()
