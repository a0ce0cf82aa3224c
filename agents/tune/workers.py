"""The local worker processes of a study (``tune --workers N``): forked or spawned.

A study on a journal file (the default storage) forks its workers (Linux): each starts with what
this process has already imported and computed — the modules, the printer, the job parsed and
planned, its quality windows — where a spawned worker spends about 2 s importing and parsing
before its first trial (a fifth of a short study's wall time on a sliced job). A worker's figures
do not depend on how it started: caches hold only what a worker would compute itself. A study on
an RDB URL spawns them (``python -m ringtune.agents.tune.study worker``): a forked child would
inherit the database driver's open connections. Both kinds answer ``poll``, ``wait`` and
``terminate`` as :class:`subprocess.Popen` does.
"""

from __future__ import annotations

import json
import multiprocessing
import subprocess
import sys
from typing import Any, Callable

from ringtune.envs.forked import CAN_FORK


class ForkedWorker:
    """A worker forked from this process (``poll``/``wait``/``terminate`` as :class:`subprocess.Popen`)."""

    def __init__(self, target: Callable[[], int]):
        self._proc = multiprocessing.get_context("fork").Process(target=_exit_with, args=(target,), daemon=False)
        self._proc.start()

    def poll(self) -> int | None:
        return self._proc.exitcode

    def wait(self, timeout: float | None = None) -> int:
        self._proc.join(timeout)
        if self._proc.exitcode is None:
            raise subprocess.TimeoutExpired("forked worker", timeout)
        return self._proc.exitcode

    def terminate(self) -> None:
        self._proc.terminate()


def _exit_with(target: Callable[[], int]) -> None:
    """In the forked child: run ``target`` and end with its exit code."""
    sys.exit(target())


def start_workers(settings: dict, workers: int, run: Callable[[int], int], storage_url: str) -> list:
    """``workers`` worker processes: forked (each runs ``run(index)``, which returns its exit code)
    where this platform can fork and ``storage_url`` is a journal file, else spawned
    (``python -m ringtune.agents.tune.study worker INDEX WORKERS``, ``settings`` as JSON on stdin)."""
    if CAN_FORK and _is_journal(storage_url):
        return [ForkedWorker(lambda i=i: run(i)) for i in range(workers)]
    payload = json.dumps(settings)
    procs = [subprocess.Popen([sys.executable, "-m", "ringtune.agents.tune.study", "worker", str(i), str(workers)],
                              stdin=subprocess.PIPE, text=True) for i in range(workers)]
    for p in procs:
        p.stdin.write(payload)
        p.stdin.close()
    return procs


def _is_journal(url: Any) -> bool:
    return isinstance(url, str) and (url.startswith("journal:") or url.endswith(".journal"))
