"""A batch of independent evaluations split over the cores in forked processes (Linux).

After the study, ``tune`` judges its refinements in batches in one process: MuJoCo's rollout runs
its windows in threads, but planning, shaping and the metrics are Python on one core. Splitting
the batch into one contiguous part per core, each evaluated in a forked child (the parent keeps the
last part), keeps both cores busy; each configuration's figures are what it gets alone (its
windows are simulated and measured on their own), so the split changes no figure.
"""

from __future__ import annotations

import multiprocessing
import os
import pickle
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
    bounds = [round(i * len(items) / k) for i in range(k + 1)]
    chunks = [items[bounds[i]:bounds[i + 1]] for i in range(k)]
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


def _child(fn, chunk, send) -> None:
    """In the forked child: ``fn(chunk)``, or the error it raised, sent back through ``send``."""
    try:
        msg = ("ok", list(fn(chunk)))
    except BaseException as e:          # noqa: BLE001 - the parent re-raises it
        msg = ("err", e)
    try:
        send.send(msg)
    except (pickle.PicklingError, TypeError, AttributeError) as e:
        what = f"{type(msg[1]).__name__}: {msg[1]}" if msg[0] == "err" else f"its results could not be sent back ({e})"
        send.send(("err", RingtuneError(f"an evaluation process failed: {what}")))
    finally:
        send.close()


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
