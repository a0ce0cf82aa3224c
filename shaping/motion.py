"""Piecewise-constant-acceleration motion: the exact, compact description of commanded movement
that the planner produces and the shapers and the physics consume.

Segment ``i`` spans ``[t[i], t[i+1])``; inside it every axis moves as
``p[i] + v[i]·τ + ½·a[i]·τ²`` with ``τ = time − t[i]``. Before ``t[0]`` the toolhead rests at the
start position; after ``t[-1]`` it rests at the end position. Axes are the columns
``x, y, z, e`` (mm, mm/s, mm/s²).

Everything here is vectorised: evaluation at any (unsorted) times is one ``searchsorted`` plus a
few array operations; on a uniform grid :meth:`Motion.sample` avoids the search altogether.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

AXES = ("x", "y", "z", "e")


def locate(t: np.ndarray, times) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For boundaries ``t`` (n+1,) s: the segment active at each of ``times`` (clipped to the first
    and last), the time into it (s, the times clipped to [t[0], t[-1]]) and whether it is inside."""
    times = np.asarray(times, dtype=float)
    tc = np.clip(times, t[0], t[-1])
    idx = np.searchsorted(t, tc, side="right") - 1
    np.clip(idx, 0, len(t) - 2, out=idx)
    return idx, tc - t[idx], (times >= t[0]) & (times <= t[-1])


def span_rows(t: np.ndarray, t_start: float, t_end: float) -> tuple[float, float, int, int]:
    """For boundaries ``t`` (n+1,) s: [t_start, t_end] clipped to them and the segments i0..i1−1
    it covers; ValueError where it is empty."""
    t_start, t_end = max(t_start, t[0]), min(t_end, t[-1])
    if t_end <= t_start:
        raise ValueError(f"empty window [{t_start}, {t_end}]")
    n = len(t) - 1
    i0 = int(np.clip(np.searchsorted(t, t_start, side="right") - 1, 0, n - 1))
    i1 = int(np.clip(np.searchsorted(t, t_end, side="left"), i0 + 1, n))
    return t_start, t_end, i0, i1


@dataclass
class Motion:
    """Commanded motion as segments of constant acceleration.

    Attributes:
        t: (n+1,) segment boundaries, s, non-decreasing.
        p: (n, 4) position at each segment start, mm (x, y, z, e).
        v: (n, 4) velocity at each segment start, mm/s.
        a: (n, 4) constant acceleration within each segment, mm/s².
        extruding: (n,) True where the segment deposits material (e increases while x/y move).
        move: (n,) index of the planned move (G-code move) each segment belongs to, or -1.
    """

    t: np.ndarray
    p: np.ndarray
    v: np.ndarray
    a: np.ndarray
    extruding: np.ndarray = field(default=None)  # type: ignore[assignment]
    move: np.ndarray = field(default=None)  # type: ignore[assignment]

    def __post_init__(self) -> None:
        self.t = np.ascontiguousarray(self.t, dtype=float)
        n = len(self.t) - 1
        self.p = np.ascontiguousarray(self.p, dtype=float).reshape(n, -1)
        self.v = np.ascontiguousarray(self.v, dtype=float).reshape(n, -1)
        self.a = np.ascontiguousarray(self.a, dtype=float).reshape(n, -1)
        if self.extruding is None:
            self.extruding = np.zeros(n, dtype=bool)
        if self.move is None:
            self.move = np.full(n, -1, dtype=np.int64)
        self.extruding = np.asarray(self.extruding, dtype=bool)
        self.move = np.asarray(self.move, dtype=np.int64)
        if n < 1:
            raise ValueError("Motion needs at least one segment")

    # -- basic facts -----------------------------------------------------------------------------
    @property
    def n_segments(self) -> int:
        return len(self.t) - 1

    @property
    def start_time(self) -> float:
        return float(self.t[0])

    @property
    def end_time(self) -> float:
        return float(self.t[-1])

    @property
    def duration(self) -> float:
        """Total time, s."""
        return float(self.t[-1] - self.t[0])

    @property
    def dt(self) -> np.ndarray:
        """(n,) segment durations, s."""
        return np.diff(self.t)

    def end_state(self) -> tuple[np.ndarray, np.ndarray]:
        """Position (mm) and velocity (mm/s) at the end of each segment, each (n, 4)."""
        d = self.dt[:, None]
        return self.p + self.v * d + 0.5 * self.a * d * d, self.v + self.a * d

    @property
    def start_position(self) -> np.ndarray:
        return self.p[0].copy()

    @property
    def end_position(self) -> np.ndarray:
        return self.end_state()[0][-1]

    # -- evaluation ------------------------------------------------------------------------------
    def _locate(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return locate(self.t, times)

    def position(self, times: np.ndarray) -> np.ndarray:
        """(len(times), 4) position, mm; held constant outside [t[0], t[-1]]."""
        idx, tau, _ = self._locate(times)
        tau = tau[:, None]
        return self.p[idx] + (self.v[idx] + 0.5 * self.a[idx] * tau) * tau

    def velocity(self, times: np.ndarray) -> np.ndarray:
        """(len(times), 4) velocity, mm/s; zero outside [t[0], t[-1]]."""
        idx, tau, inside = self._locate(times)
        return (self.v[idx] + self.a[idx] * tau[:, None]) * inside[:, None]

    def acceleration(self, times: np.ndarray) -> np.ndarray:
        """(len(times), 4) acceleration, mm/s²; zero outside [t[0], t[-1]]."""
        idx, _, inside = self._locate(times)
        return self.a[idx] * inside[:, None]

    def segment_index(self, times: np.ndarray) -> np.ndarray:
        """Index of the segment active at each time (clipped to the first/last segment)."""
        return self._locate(times)[0]

    def sample(self, rate: float, t_start: float | None = None, t_end: float | None = None,
               what: str = "position") -> tuple[np.ndarray, np.ndarray]:
        """Evaluate on the uniform grid ``t_start + k/rate`` up to ``t_end``; returns (times, values).

        Costs O(n + m) (no binary search): segment indices come from a cumulative count of grid
        points per segment. ``what`` is ``position``, ``velocity`` or ``acceleration``.
        """
        t0 = self.t[0] if t_start is None else float(t_start)
        t1 = self.t[-1] if t_end is None else float(t_end)
        m = int(np.floor((t1 - t0) * rate + 1e-9)) + 1
        times = t0 + np.arange(m) / rate
        # first grid index at or after each boundary
        first = np.ceil((self.t - t0) * rate - 1e-9).astype(np.int64)
        np.clip(first, 0, m, out=first)
        counts = np.diff(first)
        idx = np.repeat(np.arange(self.n_segments), counts)
        before = int(first[0])
        after = m - before - len(idx)
        idx = np.concatenate([np.zeros(before, np.int64), idx, np.full(after, self.n_segments - 1)])
        tau = np.clip(times, self.t[0], self.t[-1]) - self.t[idx]
        inside = ((times >= self.t[0]) & (times <= self.t[-1]))[:, None]
        tau = tau[:, None]
        if what == "position":
            return times, self.p[idx] + (self.v[idx] + 0.5 * self.a[idx] * tau) * tau
        if what == "velocity":
            return times, (self.v[idx] + self.a[idx] * tau) * inside
        if what == "acceleration":
            return times, self.a[idx] * inside
        raise ValueError(f"what must be position, velocity or acceleration, not {what!r}")

    # -- building and cutting ----------------------------------------------------------------------
    def shifted(self, delay: float) -> "Motion":
        """The same motion ``delay`` seconds later."""
        return Motion(self.t + delay, self.p, self.v, self.a, self.extruding, self.move)

    def window(self, t_start: float, t_end: float) -> "Motion":
        """The part of the motion inside [t_start, t_end] (segments cut exactly at the edges)."""
        t_start, t_end, i0, i1 = span_rows(self.t, t_start, t_end)
        t = self.t[i0:i1 + 1].copy()
        p = self.p[i0:i1].copy()
        v = self.v[i0:i1].copy()
        a = self.a[i0:i1]
        tau = t_start - t[0]
        p[0] = p[0] + v[0] * tau + 0.5 * a[0] * tau * tau
        v[0] = v[0] + a[0] * tau
        t[0] = t_start
        t[-1] = t_end
        return Motion(t, p, v, a, self.extruding[i0:i1], self.move[i0:i1])

    @staticmethod
    def from_constant_accel(t: np.ndarray, a: np.ndarray, p0=None, v0=None,
                            extruding=None) -> "Motion":
        """Build a motion from boundaries ``t`` (n+1,) and per-segment accelerations ``a`` (n, k),
        integrating position and velocity exactly from ``p0``/``v0`` (default rest at 0)."""
        t = np.asarray(t, float)
        a = np.atleast_2d(np.asarray(a, float))
        if a.shape[0] != len(t) - 1:
            a = a.T
        n, k = a.shape
        d = np.diff(t)[:, None]
        dv = a * d
        v = np.zeros((n, k)) if v0 is None else np.tile(np.asarray(v0, float), (n, 1))
        v = v + np.vstack([np.zeros((1, k)), np.cumsum(dv, axis=0)[:-1]])
        dp = v * d + 0.5 * a * d * d
        p = (np.zeros((n, k)) if p0 is None else np.tile(np.asarray(p0, float), (n, 1)))
        p = p + np.vstack([np.zeros((1, k)), np.cumsum(dp, axis=0)[:-1]])
        return Motion(t, p, v, a, extruding)

    @staticmethod
    def concatenate(parts: list["Motion"]) -> "Motion":
        """Join motions that follow each other in time (each part's t[0] = previous t[-1])."""
        t = np.concatenate([parts[0].t[:1]] + [m.t[1:] for m in parts])
        return Motion(t, *(np.concatenate([getattr(m, name) for m in parts])
                           for name in ("p", "v", "a", "extruding", "move")))
