"""Windows that are the same motion elsewhere in the job, simulated and measured once.

A sliced job repeats itself: the same layer many times, the same object twice on the bed. Two
windows whose commands — shaped and unshaped motion, the extruder's, the feature of every segment —
are the same relative to their own start (time, position) give the same response on a printer
whose mechanics do not depend on where the head is (the linear model, ``backend="lti"``), so the
same measures at shifted times and places. Commands are compared to :data:`DECIMALS` decimals
(s, mm, mm/s, mm/s²: 0.1 µs, 0.01 µm): the planner's arithmetic on absolute times leaves noise far
below that, and a difference at that size moves a measure by far less than the 1 µm the verdicts
resolve. A measure's place (``t``, ``x``, ``y`` … in its details) is moved to the window it stands for.
"""

from __future__ import annotations

import copy
import hashlib
from collections import OrderedDict

import numpy as np

from ringtune.envs.metrics import Metrics

#: decimals each command is compared to, by unit (s, mm, mm/s, mm/s²)
DECIMALS = {"t": 7, "p": 5, "v": 4, "a": 2}


def _rounded(x: np.ndarray, unit: str) -> np.ndarray:
    """``x`` to :data:`DECIMALS` of ``unit``, −0 as 0 (a noise below zero rounds to −0.0, other bytes)."""
    return np.round(x, DECIMALS[unit]) + 0.0


def _motion_key(m, t0: float, p0: np.ndarray) -> bytes:
    """``m``'s segments relative to time ``t0`` and position ``p0`` (x, y, z, e), rounded."""
    if m is None:
        return b"-"
    parts = (_rounded(m.t - t0, "t"), _rounded(m.p - p0[:m.p.shape[1]], "p"), _rounded(m.v, "v"),
             _rounded(m.a, "a"), m.extruding)
    return b"|".join(np.ascontiguousarray(x).tobytes() + str(x.shape).encode() for x in parts)


def _origin(run) -> np.ndarray:
    return np.asarray(run.path.p[0], float)


def signature(run) -> str:
    """A digest of everything a window's simulation and measures depend on, relative to its start."""
    p0 = _origin(run)
    h = hashlib.sha1()
    for m in (run.shaped, run.path):
        h.update(_motion_key(m, run.t0, p0))
    for m in (run.e_command, run.e_synced):         # one column: the extruder, from its own start
        h.update(_motion_key(m, run.t0, m.p[0] if m is not None else p0))
    h.update(_rounded(np.array([run.t1 - run.t0]), "t").tobytes())
    h.update(repr((run.lag, run.settle, run.anticipate, run.corner_tail,
                   sorted(run.seen_classes) if run.seen_classes is not None else None)).encode())
    h.update(b"-" if run.classes is None else np.asarray(run.classes).tobytes())
    return h.hexdigest()


def distinct(runs: list) -> tuple[list[int], list[int]]:
    """(index of the first of each distinct window, for every window the position of its own in
    that list)."""
    first: dict[str, int] = {}
    firsts, of = [], []
    for i, run in enumerate(runs):
        key = signature(run)
        if key not in first:
            first[key] = len(firsts)
            firsts.append(i)
        of.append(first[key])
    return firsts, of


def _shift(node, dt: float, dx: float, dy: float):
    """``node`` (a details tree) with every time moved by ``dt`` s and every x, y by ``dx``, ``dy`` mm."""
    if isinstance(node, list):
        return [_shift(v, dt, dx, dy) for v in node]
    if not isinstance(node, dict):
        return node
    out = {}
    for k, v in node.items():
        if isinstance(v, (dict, list)):
            out[k] = _shift(v, dt, dx, dy)
        elif isinstance(v, float) and (k == "t" or k.startswith("t_") or k.endswith("_t")):
            out[k] = v + dt
        elif isinstance(v, float) and k in ("x", "y"):
            out[k] = v + (dx if k == "x" else dy)
        else:
            out[k] = v
    return out


def moved(m: Metrics, source, target) -> Metrics:
    """Window ``source``'s measures ``m`` as window ``target``'s (the same motion elsewhere): its
    places moved by the difference of the two windows' starts."""
    if target is source:
        return m
    return _moved(m, source.t0, _origin(source), target)


def _moved(m: Metrics, t0: float, origin: np.ndarray, target) -> Metrics:
    """Measures ``m`` of a window that started at time ``t0`` and position ``origin``, as window
    ``target``'s."""
    d = _origin(target) - origin
    out = copy.copy(m)
    out.details = _shift(m.details, float(target.t0 - t0), float(d[0]), float(d[1]))
    return out


class WindowMemo:
    """Measures of windows already simulated, remembered by printer, backend and :func:`signature`:
    a window whose commands are those of one measured before, on the same printer, takes its
    measures (moved to its place, :func:`moved`) instead of a simulation.

    After the study ``tune`` walks one setting at a time (a feature group's acceleration, a corner
    rule): a candidate changes the moves of one feature, and most of its quality windows (8–9 of
    13 on the two copies of the part) are its start's, shifted in time. The commands are compared
    as :func:`signature` compares them (to 0.1 µs and 0.01 µm), so a remembered window's figures
    are a fresh simulation's to the rounding of its shifted clock (far below the 1 µm the verdicts
    resolve), not to the bit. Holds at most ``size`` windows, the oldest forgotten first."""

    def __init__(self, size: int = 4096):
        self.size = size
        self._known: OrderedDict = OrderedDict()      # key -> (metrics, the start time and place they are at)
        self._printers: dict = {}                     # id(printer) -> (printer, its description)
        self.hits = 0
        self.misses = 0

    def key(self, printer, backend: str, run) -> tuple:
        """What a window's measures depend on: the printer's description, the backend, the commands."""
        got = self._printers.get(id(printer))
        if got is None or got[0] is not printer:
            if len(self._printers) > 64:
                self._printers.clear()
            got = self._printers[id(printer)] = (printer, printer.to_toml())
        return got[1], backend, signature(run)

    def get(self, key: tuple, run) -> Metrics | None:
        """The measures remembered for ``key``, moved to ``run``'s place, or None."""
        hit = self._known.get(key)
        if hit is None:
            self.misses += 1
            return None
        self.hits += 1
        self._known.move_to_end(key)
        return _moved(*hit, run)

    def put(self, key: tuple, run, metrics: Metrics) -> None:
        """Remember ``metrics``, measured on window ``run``, for ``key``."""
        self._known[key] = (metrics, run.t0, _origin(run).copy())
        self._known.move_to_end(key)
        while len(self._known) > self.size:
            self._known.popitem(last=False)
