"""The study's storage behaviour: resume after SIGINT and SIGKILL, several workers, PostgreSQL,
seeded reproducibility. The physics is replaced by tests/study_objective.py (deterministic and
cheap) — these tests are about trials in storage, not about metric values."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
import uuid
from pathlib import Path

import pytest

from ringtune.agents.tune.study import StudySettings, count_states, open_study, run_study
from ringtune.shaping.errors import RingtuneError

TESTS = Path(__file__).resolve().parent
EVALUATOR = "study_objective:evaluate"


def _settings(storage: str, n: int, seed: int | None = 3, name: str = "ringtune") -> StudySettings:
    return StudySettings(storage=storage, study_name=name, n_trials=n, seed=seed, evaluator=EVALUATOR)


def _env(**extra) -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(TESTS), env.get("PYTHONPATH", "")])
    env.update({k: str(v) for k, v in extra.items()})
    return env


def _start_worker(settings: StudySettings, **env) -> subprocess.Popen:
    p = subprocess.Popen([sys.executable, "-m", "ringtune.agents.tune.study", "worker", "0"], stdin=subprocess.PIPE,
                         text=True, env=_env(**env), start_new_session=True)
    p.stdin.write(json.dumps(settings.to_dict()))
    p.stdin.close()
    return p


def _complete(settings: StudySettings) -> dict[int, tuple]:
    from optuna.trial import TrialState

    study = open_study(settings)
    return {t.number: (tuple(sorted(t.params.items())), tuple(t.values))
            for t in study.get_trials(states=(TrialState.COMPLETE,))}


def _wait_for(path: Path, proc: subprocess.Popen, timeout: float = 60.0) -> None:
    t0 = time.time()
    while not path.exists():
        assert proc.poll() is None, "worker ended before reaching the trial to interrupt"
        assert time.time() - t0 < timeout
        time.sleep(0.05)


@pytest.fixture
def in_tests_path(monkeypatch):
    monkeypatch.syspath_prepend(str(TESTS))


@pytest.mark.slow
@pytest.mark.parametrize("storage", ["journal", "sqlite"])
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGINT])
def test_interrupt_mid_trial_then_resume_loses_and_repeats_nothing(tmp_path, in_tests_path, sig, storage):
    url = f"journal:{tmp_path / 'study.journal'}" if storage == "journal" else f"sqlite:///{tmp_path / 'study.db'}"
    settings = _settings(url, n=24)
    hang = tmp_path / "hang"
    proc = _start_worker(settings, RINGTUNE_TEST_HANG_AT=9, RINGTUNE_TEST_HANG_FILE=hang)
    _wait_for(hang, proc)                       # the 9th trial is being evaluated right now
    before = _complete(settings)
    assert len(before) == 8
    os.kill(proc.pid, sig)
    if sig == signal.SIGINT:
        # the first Ctrl-C lets the trial finish; this one hangs, so a second Ctrl-C aborts it
        time.sleep(0.5)
        os.kill(proc.pid, signal.SIGINT)
    proc.wait(timeout=30)
    assert _complete(settings) == before        # nothing completed was lost

    run = run_study(settings)                   # resume in this process, like rerunning the command
    after = _complete(settings)
    assert len(after) == 24 and run.completed_now == 16
    assert all(after[n] == v for n, v in before.items())           # kept unchanged
    params = [p for p, _ in after.values()]
    assert len(set(params)) == len(params)                          # nothing evaluated twice
    counts = count_states(run.study)
    assert counts["RUNNING"] == 0 and counts["FAIL"] == 1            # the interrupted trial, failed...
    fail = next(t for t in run.study.get_trials() if t.state.name == "FAIL")
    assert any(t.system_attrs.get("failed_trial") == fail.number and t.state.name == "COMPLETE"
               for t in run.study.get_trials())                     # ...and re-run once


def test_first_ctrl_c_finishes_the_running_trial(tmp_path, in_tests_path):
    settings = _settings(f"journal:{tmp_path / 'study.journal'}", n=200)
    proc = _start_worker(settings, RINGTUNE_TEST_SLEEP=0.2)
    t0 = time.time()
    while len(_complete(settings)) < 3:
        assert time.time() - t0 < 60
        time.sleep(0.1)
    os.kill(proc.pid, signal.SIGINT)
    assert proc.wait(timeout=30) == 0
    counts = count_states(open_study(settings))
    assert counts["RUNNING"] == 0 and counts["FAIL"] == 0 and 3 <= counts["COMPLETE"] < 200


@pytest.mark.parametrize("start", ["forked", "spawned"])
def test_two_workers_finish_exactly_n_without_duplicates(tmp_path, in_tests_path, monkeypatch, start):
    """Forked workers (a journal study on Linux) and spawned ones (``python -m ... worker``, as on
    an RDB storage or where the platform cannot fork) alike."""
    from ringtune.agents.tune import workers as local_workers
    from ringtune.agents.tune.space import params_from_config

    monkeypatch.setattr(local_workers, "CAN_FORK", start == "forked")
    monkeypatch.setenv("RINGTUNE_TEST_SLEEP", "0.01")     # both workers get trials (see below)
    from ringtune.agents.tune.study import load_space
    from ringtune.shaping.config import TuneConfig

    settings = _settings(f"journal:{tmp_path / 'study.journal'}", n=20)
    space = load_space(settings)
    warm = [TuneConfig(shaper_x=s, shaper_y=s, freq_x=50.0, freq_y=40.0, accel=3000.0) for s in ("zv", "mzv", "ei")]
    settings.enqueue = [params_from_config(c, space) for c in warm]     # warm start: each run exactly once
    os.environ["PYTHONPATH"] = os.pathsep.join([str(TESTS), os.environ.get("PYTHONPATH", "")])
    try:
        run = run_study(settings, workers=2)
    finally:
        os.environ["PYTHONPATH"] = os.environ["PYTHONPATH"].split(os.pathsep, 1)[1]
    done = _complete(settings)
    assert len(done) == 20 and run.completed_now == 20
    params = [p for p, _ in done.values()]
    assert len(set(params)) == 20
    for p in settings.enqueue:
        assert sum(1 for q, _ in done.values() if dict(q) == p) == 1
    workers = {t.user_attrs["worker"] for t in run.study.get_trials() if t.state.name == "COMPLETE"}
    assert len(workers) == 2                    # both processes did part of the work
    assert os.getpid() not in {int(w.rsplit(":", 1)[1]) for w in workers}


def test_a_forked_worker_that_fails_is_an_error(tmp_path, in_tests_path, monkeypatch):
    """A forked worker's error reaches ``run_study`` as the spawned one's exit code did."""
    from ringtune.agents.tune import study as study_mod

    def broken(settings, index, **kwargs):
        raise RingtuneError("the job is gone", "job")

    monkeypatch.setattr(study_mod, "run_worker", broken)
    settings = _settings(f"journal:{tmp_path / 'study.journal'}", n=4)
    with pytest.raises(RingtuneError, match=r"2 worker process\(es\) failed \(exit codes \[2, 2\]\)"):
        run_study(settings, workers=2)


def test_seeded_single_worker_runs_reproduce_exactly(tmp_path, in_tests_path):
    a = _settings(f"journal:{tmp_path / 'a.journal'}", n=15, seed=11)
    b = _settings(f"journal:{tmp_path / 'b.journal'}", n=15, seed=11)
    c = _settings(f"journal:{tmp_path / 'c.journal'}", n=15, seed=12)
    for s in (a, b, c):
        run_study(s)
    assert _complete(a) == _complete(b)
    assert _complete(a) != _complete(c)


def test_seeded_two_worker_runs_reproduce_exactly(tmp_path, in_tests_path, monkeypatch):
    """Two local workers share the seed and run in step (study.py): trial n sees only the trials
    numbered n − 2·2 and lower, after waiting for them, so which worker runs which trial — here one
    or the other made to lag behind — changes nothing; another seed does."""
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(TESTS), os.environ.get("PYTHONPATH", "")]))
    # a trial of at least 10 ms: a forked worker starts at once, and with trials of no cost the
    # first could finish them all before the second has opened the study
    monkeypatch.setenv("RINGTUNE_TEST_SLEEP", "0.01")
    runs = {}
    for key, seed, parity in (("a", 11, "0"), ("b", 11, "1"), ("c", 12, "0")):
        monkeypatch.setenv("RINGTUNE_TEST_SLOW_PARITY", parity)
        runs[key] = _settings(f"journal:{tmp_path / (key + '.journal')}", n=30, seed=seed)
        run = run_study(runs[key], workers=2)
        assert run.completed_now == 30
        workers = {t.user_attrs["worker"] for t in run.study.get_trials() if t.state.name == "COMPLETE"}
        assert len(workers) == 2                # both processes did part of the work
    assert _complete(runs["a"]) == _complete(runs["b"])
    assert _complete(runs["a"]) != _complete(runs["c"])


def test_sqlite_storage_resumes_too(tmp_path, in_tests_path):
    settings = _settings(f"sqlite:///{tmp_path / 'study.db'}", n=6)
    run_study(settings)
    settings.n_trials = 9
    run = run_study(settings)
    assert run.completed_before == 6 and run.completed_now == 3 and len(_complete(settings)) == 9


@pytest.mark.postgres
@pytest.mark.slow
def test_postgresql_two_workers(in_tests_path):
    url = os.environ.get("RINGTUNE_PG_URL")
    if not url:
        pytest.skip("RINGTUNE_PG_URL is not set (no PostgreSQL server; .ci/run starts one when it can)")
    settings = _settings(url, n=10, name=f"ringtune-test-{uuid.uuid4().hex[:8]}")
    os.environ["PYTHONPATH"] = os.pathsep.join([str(TESTS), os.environ.get("PYTHONPATH", "")])
    try:
        run = run_study(settings, workers=2)
    finally:
        os.environ["PYTHONPATH"] = os.environ["PYTHONPATH"].split(os.pathsep, 1)[1]
    done = _complete(settings)
    assert len(done) == 10 and len({p for p, _ in done.values()}) == 10 and run.completed_now == 10


def test_seeded_run_stopped_and_resumed_reproduces_the_straight_run(tmp_path, in_tests_path):
    """study.py's promise: a seeded single-worker run gives the same trials whether it ran in one
    go or was stopped and resumed (the sampler is reseeded from (seed, trial number))."""
    straight = _settings(f"journal:{tmp_path / 'a.journal'}", n=16, seed=21)
    run_study(straight)
    pieces = _settings(f"journal:{tmp_path / 'b.journal'}", n=7, seed=21)
    run_study(pieces)
    pieces.n_trials = 16
    run_study(pieces)
    assert _complete(pieces) == _complete(straight)


@pytest.mark.slow
def test_seeded_tune_cli_on_the_real_simulation_reproduces_exactly(tmp_path, capsys):
    """`ringtune tune --seed S` twice (real evaluator, one worker): identical trials, front and choice."""
    from ringtune.agents.cli.main import main

    outs = []
    for k in range(2):
        out = tmp_path / f"run{k}"
        assert main(["tune", "--json", "--trials", "8", "--seed", "4", "--no-baselines", "--backend", "lti",
                     "--out", str(out)]) == 0
        res = json.loads(capsys.readouterr().out)
        outs.append(((out / "trials.csv").read_text(), res["chosen"], (out / "best.json").read_text()))
    assert outs[0] == outs[1]
