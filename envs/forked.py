"""A batch of independent evaluations split over the cores in forked processes (Linux).

After the study, ``tune`` judges its refinements in batches in one process: MuJoCo's rollout runs
its windows in threads, but planning, shaping and the metrics are Python on one core. Splitting
the batch into one contiguous part per core, each evaluated in a forked child (the parent keeps the
last part), keeps both cores busy; each configuration's figures are what it gets alone (its
windows are simulated and measured on their own), so the split changes no figure.

A fork per batch costs more than it looks on a long job: besides the fork itself (about 35 ms for
``tune``'s process), parent and child both re-fault every page they write afterwards (copy on
write), so each half of a batch ran some 30 % slower than in one process and a batch of four split
in two took as long as in one process. :class:`Helpers` forks its helper processes once and sends
them each batch's part through a pipe: each half then runs at one process's speed.
"""

from __future__ import annotations

import multiprocessing
import os
import pickle
import signal
import sys
from typing import Callable, Sequence, TypeVar

from ringtune.shaping.errors import RingtuneError

T = TypeVar("T")
R = TypeVar("R")

#: fork is what makes the split cheap (no re-import, closures need no pickling); elsewhere: serial
CAN_FORK = sys.platform.startswith("linux")


def split_map(fn: Callable[[list[T]], Sequence[R]], items: Sequence[T], parts: int | None = None) -> list[R]:
    """``fn(items)`` computed as ``fn`` of contiguous parts of ``items``, one per core (``parts``:
    how many; default the cores), in forked children, the results concatenated in order. ``fn``
    must return one result per item and depend on nothing but its part. Serial where the platform
    cannot fork or there is one part."""
    items = list(items)
    k = min(parts or os.cpu_count() or 1, len(items))
    if k < 2 or not CAN_FORK:
        return list(fn(items))
    chunks = _parts(items, k)
    ctx = multiprocessing.get_context("fork")
    children = []
    for chunk in chunks[:-1]:
        recv, send = ctx.Pipe(duplex=False)
        proc = ctx.Process(target=_child, args=(fn, chunk, send), daemon=True)
        proc.start()
        send.close()
        children.append((recv, proc))
    try:
        last = list(fn(chunks[-1]))
        out: list[R] = []
        for recv, proc in children:
            out.extend(_result(recv, proc))
        return out + last
    finally:
        for recv, proc in children:
            recv.close()
            if proc.is_alive():
                proc.terminate()
            proc.join()


class Helpers:
    """Helper processes forked once and kept for many batches (one per core beside this one).

    ``map(fn, items, *args)`` gives what :func:`split_map` of ``lambda part: fn(part, *args)``
    gives (contiguous parts, the last computed here, results in order; serial where the platform
    cannot fork or there is one part), without a fork per call. The helpers are forked at the first
    ``map`` and know the functions :meth:`register`-ed by then (and everything those close over, as
    it was then); parts and ``args`` are pickled to them. A function registered later, or not at
    all, is split with :func:`split_map`. An error anywhere closes the helpers (the next ``map``
    forks new ones) and is raised here. Use as a context manager, or :meth:`close`."""

    def __init__(self, parts: int | None = None):
        self.parts = parts or os.cpu_count() or 1
        self._fns: list[Callable] = []
        self._known = 0                 # functions the running helpers were forked with
        self._helpers: list = []        # (connection, process)

    def register(self, fn: Callable) -> Callable:
        """Make ``fn(part, *args) -> one result per item`` callable in the helpers; returns ``fn``."""
        self._fns.append(fn)
        return fn

    def map(self, fn: Callable, items: Sequence[T], *args) -> list:
        items = list(items)
        k = min(self.parts, len(items))
        if k < 2 or not CAN_FORK:
            return list(fn(items, *args))
        index = next((i for i, f in enumerate(self._fns) if f is fn), None)
        if index is None or (self._helpers and index >= self._known):
            return split_map(lambda part: fn(part, *args), items, k)
        self._grow(k - 1)
        chunks = _parts(items, k)
        try:
            for (conn, _proc), chunk in zip(self._helpers, chunks[:-1]):
                conn.send((index, chunk, args))
            last = list(fn(chunks[-1], *args))
            out: list = []
            for conn, proc in self._helpers[:k - 1]:
                out.extend(_result(conn, proc))
            return out + last
        except BaseException:
            self.close()                # a helper may still owe a reply: start afresh
            raise

    def _grow(self, n: int) -> None:
        """At least ``n`` helpers running (forked as a batch first needs them: a small batch on a
        machine of many cores forks no more than it uses)."""
        ctx = multiprocessing.get_context("fork")
        if not self._helpers:
            self._known = len(self._fns)
        while len(self._helpers) < n:
            here, there = ctx.Pipe()
            proc = ctx.Process(target=_serve, args=(self._fns, there), daemon=True)
            proc.start()
            there.close()
            self._helpers.append((here, proc))

    def close(self) -> None:
        """End the helpers (they hold nothing to save)."""
        for conn, proc in self._helpers:
            conn.close()
            proc.terminate()
            proc.join()
        self._helpers = []

    def __enter__(self) -> "Helpers":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def in_background(fn: Callable[..., R], *args) -> Callable[[], R]:
    """``fn(*args)`` computed in a forked child while this process goes on; the function returned
    waits for it and gives its result, or raises its error here. Computed at once where the
    platform cannot fork."""
    if not CAN_FORK:
        try:
            value = fn(*args)
        except Exception as e:          # noqa: BLE001 - raised when the result is asked, as forked
            error = e
            return lambda: _raise(error)
        return lambda: value
    ctx = multiprocessing.get_context("fork")
    recv, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(lambda _none: [fn(*args)], None, send), daemon=True)
    proc.start()
    send.close()

    def result() -> R:
        try:
            return _result(recv, proc)[0]
        finally:
            recv.close()
            proc.join()

    return result


def _raise(e: BaseException):
    raise e


def _parts(items: list, k: int) -> list[list]:
    """``items`` in ``k`` contiguous parts of near-equal length."""
    bounds = [round(i * len(items) / k) for i in range(k + 1)]
    return [items[bounds[i]:bounds[i + 1]] for i in range(k)]


def _serve(fns: list, conn) -> None:
    """A helper's life: answer each ``(function index, part, args)`` until the pipe closes. Ctrl-C
    is the parent's to handle (it ends the helpers)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    while True:
        try:
            index, chunk, args = conn.recv()
        except (EOFError, OSError):
            return
        _answer(conn, fns[index], chunk, *args)


def _child(fn, chunk, send) -> None:
    """In the forked child: ``fn(chunk)``, or the error it raised, sent back through ``send``."""
    try:
        _answer(send, fn, chunk)
    finally:
        send.close()


def _answer(conn, fn, *args) -> None:
    """``fn(*args)`` as a list, or the error it raised, sent back through ``conn``."""
    try:
        msg = ("ok", list(fn(*args)))
    except BaseException as e:          # noqa: BLE001 - the parent re-raises it
        msg = ("err", e)
    try:
        conn.send(msg)
    except (pickle.PicklingError, TypeError, AttributeError) as e:
        what = f"{type(msg[1]).__name__}: {msg[1]}" if msg[0] == "err" else f"its results could not be sent back ({e})"
        conn.send(("err", RingtuneError(f"an evaluation process failed: {what}")))


def _result(recv, proc) -> list:
    """A child's results, or its error raised here."""
    try:
        status, value = recv.recv()
    except EOFError:
        proc.join()
        raise RingtuneError(f"an evaluation process ended without a result (exit code {proc.exitcode})") from None
    if status == "err":
        raise value
    return value
