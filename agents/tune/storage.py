"""Optuna storages for the tuning study, and clean-up of trials whose worker died.

- :func:`make_storage`: ``journal:PATH`` (Optuna's append-only journal file: file lock, safe for
  several processes on one machine, survives SIGKILL; ~10 ms per trial) — the default — or any
  RDB URL (``sqlite:///study.db``, ``postgresql+psycopg2://user:pw@host/db``) with Optuna's
  heartbeat, so stale RUNNING trials of dead workers on any machine are failed and re-run once.
- :func:`reap_dead_workers`: on this host, a RUNNING trial whose worker process is gone is failed
  at once and its parameters queued for one re-run; trials a Ctrl-C aborted likewise.
- :func:`await_finished`: block until the trials up to a number have finished (workers in step).
"""

from __future__ import annotations

import os
import socket
import sqlite3
import time
import warnings
from pathlib import Path

import optuna
from optuna.storages import RDBStorage, RetryHeartbeatStaleTrialCallback
from optuna.storages.journal import JournalFileBackend, JournalFileOpenLock
from optuna.trial import TrialState
from sqlalchemy import event

from ringtune.shaping.errors import RingtuneError

HEARTBEAT_S = 1
GRACE_S = 4


def default_storage(out_dir: str | Path) -> str:
    """The default storage of an output folder: an Optuna journal file beside the results."""
    return f"journal:{Path(out_dir) / 'study.journal'}"


def make_storage(url: str):
    """An Optuna storage for ``url``.

    - ``journal:PATH`` (or a path ending ``.journal``): Optuna's append-only journal file (file
      lock; safe for several processes on one machine; survives SIGKILL) — the default, because
      it costs ~10 ms per trial where SQLite through Optuna's ORM costs ~150–250 ms;
    - any RDB URL (``sqlite:///study.db``, ``postgresql+psycopg2://user:pw@host/db``): with
      Optuna's heartbeat, so stale RUNNING trials of dead workers on any machine are failed and
      re-run once.
    """
    if isinstance(url, (str, os.PathLike)) and (str(url).startswith("journal:") or str(url).endswith(".journal")):
        return _journal_storage(str(url))
    if not isinstance(url, str) or "://" not in url:
        raise RingtuneError("storage must be journal:PATH or an Optuna RDB URL such as sqlite:///study.db "
                            f"or postgresql+psycopg2://user:pw@host/db, not {url!r}", "storage")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
            return _rdb_storage(url)
    except ImportError as exc:
        raise RingtuneError(f"storage {url.split(':')[0]!r} needs a driver that is not installed ({exc})",
                            "storage") from None
    except Exception as exc:  # sqlalchemy OperationalError etc.: one line, naming the option
        raise RingtuneError(f"cannot open storage: {str(exc).splitlines()[0]}", "storage") from None


def _journal_storage(url: str):
    """Optuna's journal file storage at ``journal:PATH`` (``journal://PATH``) or ``PATH.journal``."""
    path = url.removeprefix("journal:").removeprefix("//")
    if not path:
        raise RingtuneError("journal storage needs a file path, e.g. journal:out/study.journal", "storage")
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    try:
        return optuna.storages.JournalStorage(JournalFileBackend(path, lock_obj=JournalFileOpenLock(path, grace_period=5)))
    except OSError as exc:
        raise RingtuneError(f"cannot open journal storage: {exc}", "storage") from None


def _rdb_storage(url: str) -> RDBStorage:
    """An RDB storage with Optuna's heartbeat (stale trials retried once); SQLite in WAL mode with a
    60 s busy timeout."""
    heartbeat = dict(heartbeat_interval=HEARTBEAT_S, grace_period=GRACE_S,
                     heartbeat_stale_trial_callback=RetryHeartbeatStaleTrialCallback(max_retry=1))
    if not url.startswith("sqlite"):
        return RDBStorage(url, **heartbeat)
    _sqlite_wal(url)
    storage = RDBStorage(url, **heartbeat, engine_kwargs={"connect_args": {"timeout": 60}})
    _sqlite_fast(storage)
    return storage


def _sqlite_wal(url: str) -> None:
    """Put a SQLite study file in WAL mode (persistent; many readers, one writer, far fewer fsyncs)."""
    path = url.split(":///", 1)[-1]
    if path in ("", ":memory:"):
        return
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    con = sqlite3.connect(path, timeout=60)
    try:
        con.execute("PRAGMA journal_mode=WAL")
    finally:
        con.close()


def _sqlite_fast(storage) -> None:
    """WAL with synchronous=NORMAL on every connection: a commit no longer waits for the disk.

    A crash (even SIGKILL) cannot corrupt the file or lose a committed trial; only a power cut may
    lose the last few commits (their trials are then simply re-run)."""
    def on_connect(dbapi_con, _record):
        cur = dbapi_con.cursor()
        cur.execute("PRAGMA synchronous=NORMAL")
        cur.close()

    event.listen(storage.engine, "connect", on_connect)
    storage.engine.dispose()


def _this_worker() -> str:
    return f"{socket.gethostname()}:{os.getpid()}"


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def reap_dead_workers(study) -> list[int]:
    """Fail RUNNING trials whose worker process on this host is gone; queue each for one re-run.

    Returns the numbers of the trials failed. Trials of other hosts are left to the heartbeat.
    """
    host = socket.gethostname()
    storage = study._storage
    failed = []
    for t in study.get_trials(deepcopy=False, states=(TrialState.RUNNING,)):
        owner = t.user_attrs.get("worker", "")
        h, _, pid = owner.rpartition(":")
        if h != host or not pid.isdigit() or _pid_alive(int(pid)):
            continue
        try:
            if storage.set_trial_state_values(t._trial_id, state=TrialState.FAIL):
                failed.append(t)
        except optuna.exceptions.UpdateFinishedTrialError:
            continue
    for t in failed:
        _requeue(study, t)
    _requeue_interrupted(study)
    return [t.number for t in failed]


def _requeue(study, trial, trials=None) -> None:
    """Queue a failed trial's parameters once more (a retry is never retried again)."""
    if trial.system_attrs.get("failed_trial") is not None:
        return
    trials = trials if trials is not None else study.get_trials(deepcopy=False)
    if any(t.system_attrs.get("failed_trial") == trial.number for t in trials):
        return
    study.add_trial(optuna.create_trial(state=optuna.trial.TrialState.WAITING, params=trial.params,
                                        distributions=trial.distributions,
                                        system_attrs={"failed_trial": trial.number}))


def _requeue_interrupted(study) -> None:
    """Failed trials that a Ctrl-C aborted mid-evaluation are re-run once."""
    trials = study.get_trials(deepcopy=False)
    for t in trials:
        if t.state.name == "FAIL" and t.user_attrs.get("interrupted"):
            _requeue(study, t, trials)


#: s between looks at the storage while a trial waits for the ones before it
AWAIT_POLL_S = 0.01
#: s between checks, while waiting, for trials of this host whose worker process is gone
AWAIT_REAP_S = 1.0


def await_finished(study, upto: int) -> None:
    """Block until every trial numbered ``upto`` or lower has finished (complete, pruned or failed);
    a trial whose worker died is failed on the way: of this host at once (:func:`reap_dead_workers`),
    of another by Optuna's heartbeat where the storage has one."""
    if upto < 0:
        return
    open_states = (TrialState.RUNNING, TrialState.WAITING)
    reaped = time.monotonic()
    while any(t.number <= upto for t in study.get_trials(deepcopy=False, states=open_states)):
        if time.monotonic() - reaped > AWAIT_REAP_S:
            reap_dead_workers(study)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
                optuna.storages.fail_stale_trials(study)
            reaped = time.monotonic()
        time.sleep(AWAIT_POLL_S)
