"""`ringtune train --json`: standard output is one JSON object (the progress bar wrote into it), and
`--timesteps N` trains N or says how it rounds (`--timesteps 64` trained 256) — issue 14."""

from __future__ import annotations

import json

import pytest

from ringtune.agents.ppo import training as ppo
from ringtune.agents.cli.main import main
from ringtune.agents.cli.train import rollout_for


@pytest.mark.slow
def test_train_json_is_one_json_object_and_trains_exactly_n(tmp_path, monkeypatch, capfd):
    """A tiny real run (4 steps, one held-out printer instead of eight to keep it short), captured
    at the file-descriptor level: whatever stable-baselines3 and its progress bar write goes to
    stderr; stdout parses as JSON, and 4 steps were trained, not a whole 256-step rollout; stderr
    not being a terminal, progress comes as lines."""
    monkeypatch.setattr(ppo, "EVAL_SEEDS", ppo.EVAL_SEEDS[:1])
    monkeypatch.setenv("RINGTUNE_PROGRESS_S", "0")      # stderr is not a terminal: a line per step
    assert main(["train", "--json", "--timesteps", "4", "--envs", "1", "-o", str(tmp_path / "pol")]) == 0
    out, err = capfd.readouterr()
    res = json.loads(out)
    assert res["timesteps"] == res["timesteps_requested"] == 4 and res["rollout_steps"] == 4
    assert json.loads((tmp_path / "pol" / "meta.json").read_text())["timesteps"] == 4
    assert "training PPO: 4 steps" in err
    progress = [ln for ln in err.splitlines() if ln.startswith("ringtune train: ")]
    assert progress and progress[-1].startswith("ringtune train: 4/4 steps") and "held-out mean cost" in progress[-1]


@pytest.mark.parametrize("n,envs,rollout,trained", [
    (64, 1, 64, 64),          # below one rollout: the rollout shrinks to N
    (64, 2, 64, 64),
    (65, 2, 66, 66),          # ... to a multiple of the envs
    (512, 2, 512, 512),       # whole default rollouts (256 steps × 2 envs)
    (1000, 2, 512, 1024),     # otherwise the next whole rollout
])
def test_rollout_rounding(n, envs, rollout, trained):
    hyper, r, planned = rollout_for(n, envs, None, resume=False)
    assert (r, planned) == (rollout, trained)
    if hyper is not None:     # a shortened rollout keeps a minibatch that fits in it
        assert hyper["batch_size"] <= hyper["n_steps"] * envs


def test_train_says_how_it_rounds_before_training(tmp_path, monkeypatch, capsys):
    seen = {}

    def fake_train(out_dir, timesteps, n_envs, seed, **kw):
        seen.update(kw)
        return ppo.TrainResult(tmp_path, 1024, 0.1)

    monkeypatch.setattr(ppo, "train", fake_train)
    assert main(["train", "--timesteps", "1000", "--envs", "2", "-o", str(tmp_path)]) == 0
    err = capsys.readouterr().err
    assert "rollouts of 256 steps × 2 env(s) = 512: --timesteps 1000 trains 1024 steps" in err
    assert main(["train", "--timesteps", "64", "--envs", "2", "-o", str(tmp_path)]) == 0
    assert "rollouts" not in capsys.readouterr().err and seen["hyper"]["n_steps"] == 32
