"""Infill direction-change frequency limit: slow extrusion where the toolhead would shake at a rate
the machine cannot follow (speeds mm/s, lengths mm, frequencies Hz).

Three methods, all returning a new :class:`Job` with lowered requested speeds:

- ``nophead`` (nophead, "Frequency limit", 2010): per extrusion path and per axis, the path is cut
  into runs between direction changes on that axis; a window of six consecutive runs is three
  cycles, its wavelength λ = (sum of the six run lengths along the path) / 3; the path's wavelength is
  the shortest such λ over both axes. The whole path runs at ``min(v, limit·λ)``.
- ``sections`` (the improvement nophead names but did not build): every run gets the shortest λ of
  the three-cycle windows that contain it, so only the high-frequency stretch is slowed and the rest
  of the path runs at full speed.
- ``marlin``: Marlin's ``XY_FREQUENCY_LIMIT`` (``M201 F<Hz> S<min %>``), block by block: an axis is
  throttled only if it reversed direction in each of the last three segments, all shorter than the
  minimum interval ``1/F``; the speed factor becomes ``max(least/interval, S)``.

``min_speed_factor`` floors every slowed speed at that fraction of the requested one (Marlin's S);
None takes the method's default: for ``marlin`` the job's own ``M201 S`` or else Marlin's
``XY_FREQUENCY_MIN_PERCENT`` (5 %), for the others 0.3.
"""

from __future__ import annotations

import math

import numpy as np

from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.geometry_cache import by_geometry
from ringtune.shaping.job import Job

METHODS = ("nophead", "sections", "marlin")
CYCLES = 3          # nophead: fewer than three cycles is too short for resonance to build up
#: default floor of the slowed speed, fraction of the requested one (nophead / sections)
MIN_SPEED_FACTOR = 0.3
#: Marlin's Configuration_adv.h XY_FREQUENCY_MIN_PERCENT 5 (used until an M201 S sets another)
MARLIN_MIN_SPEED_FACTOR = 0.05


def resolve_min_speed_factor(job: Job, method: str, min_speed_factor: float | None) -> float:
    """The floor a method uses: the given value, else (``marlin``) the job's M201 S or Marlin's 5 %,
    else 0.3."""
    if min_speed_factor is not None:
        return float(min_speed_factor)
    if method == "marlin":
        s = job.file_setting("freq_limit_min_factor")
        return s if s == s else MARLIN_MIN_SPEED_FACTOR
    return MIN_SPEED_FACTOR


def _geometry(job: Job):
    delta = job.end - job.start
    xyz = np.sqrt(np.einsum("ij,ij->i", delta[:, :3], delta[:, :3]))
    d = np.where(xyz > 0, xyz, np.abs(delta[:, 3]))
    return delta, d


def extrusion_paths(job: Job, features=None) -> np.ndarray:
    """(n,) path id of each move: maximal runs of consecutive, connected extruding moves; -1 for
    moves that are not part of an extrusion path (travel, retraction, excluded features)."""
    delta, _ = _geometry(job)
    ext = (delta[:, 3] > 0) & (np.hypot(delta[:, 0], delta[:, 1]) > 0)
    if features is not None:
        wanted = [i for i, name in enumerate(job.features)
                  if any(f.lower() in name.lower() for f in features)]
        ext &= np.isin(job.feature, wanted)
    n = len(ext)
    connected = np.zeros(n, bool)
    if n > 1:
        connected[1:] = np.all(job.start[1:] == job.end[:-1], axis=1) & ~job.stop_before[1:]
    new = ext & ~(np.concatenate(([False], ext[:-1])) & connected)
    pid = np.cumsum(new) - 1
    return np.where(ext, pid, -1)


def _runs(sign: np.ndarray, path: np.ndarray, d: np.ndarray):
    """Runs between direction changes of one axis inside paths (moves with path -1 excluded).

    Returns run id per selected move, run lengths, run path ids, for the selected moves ``sel``."""
    sel = np.flatnonzero(path >= 0)
    s = sign[sel]
    p = path[sel]
    m = len(sel)
    idx = np.arange(m)
    nz = s != 0
    # moves without motion on the axis join the run they are in: forward fill, then back fill
    last = np.maximum.accumulate(np.where(nz, idx, -1))
    ok = (last >= 0)
    ok[ok] &= p[last[ok]] == p[ok]
    filled = np.where(ok, s[np.maximum(last, 0)], 0)
    nxt = np.minimum.accumulate(np.where(nz, idx, m)[::-1])[::-1]
    ok2 = (filled == 0) & (nxt < m)
    ok2[ok2] &= p[np.minimum(nxt[ok2], m - 1)] == p[ok2]
    filled = np.where(ok2, s[np.minimum(nxt, m - 1)], filled)
    new = np.ones(m, bool)
    if m > 1:
        new[1:] = (p[1:] != p[:-1]) | (filled[1:] != filled[:-1])
    run = np.cumsum(new) - 1
    lengths = np.bincount(run, weights=d[sel], minlength=run[-1] + 1 if m else 0)
    run_path = p[new]
    return sel, run, lengths, run_path


def _window_wavelengths(lengths: np.ndarray, run_path: np.ndarray) -> np.ndarray:
    """λ of the window of 2·CYCLES runs starting at each run (inf where the path ends first)."""
    k = 2 * CYCLES
    r = len(lengths)
    lam = np.full(r, np.inf)
    if r >= k:
        csum = np.concatenate(([0.0], np.cumsum(lengths)))
        w = (csum[k:] - csum[:-k]) / CYCLES
        same = run_path[k - 1:] == run_path[:r - k + 1]
        lam[:r - k + 1] = np.where(same, w, np.inf)
    return lam


def path_wavelengths(job: Job, method: str = "sections", features=None) -> np.ndarray:
    """(n,) shortest three-cycle wavelength (mm of path) governing each move (inf = no limit;
    read-only: computed once per job geometry, :mod:`ringtune.shaping.geometry_cache`).

    ``nophead``: one value per whole path; ``sections``: per run between direction changes."""
    arrays = (job.start, job.end, job.feature, job.stop_before)
    extra = (method, tuple(features) if features is not None else None, tuple(job.features))
    return by_geometry("path_wavelengths", arrays, extra, lambda: _path_wavelengths(job, method, features))


def _path_wavelengths(job: Job, method: str, features) -> np.ndarray:
    delta, d = _geometry(job)
    path = extrusion_paths(job, features)
    out = np.full(job.n_moves, np.inf)
    if not np.any(path >= 0):
        return out
    k = 2 * CYCLES
    for axis in (0, 1):
        sel, run, lengths, run_path = _runs(np.sign(delta[:, axis]), path, d)
        lam = _window_wavelengths(lengths, run_path)
        if method == "nophead":
            per_path = np.full(path.max() + 1, np.inf)
            np.minimum.at(per_path, run_path, lam)
            move_lam = per_path[path[sel]]
        else:
            # each run: the shortest λ among windows that contain it (starts r-5 .. r)
            padded = np.concatenate((np.full(k - 1, np.inf), lam))
            local = np.lib.stride_tricks.sliding_window_view(padded, k).min(axis=1)
            move_lam = local[run]
        out[sel] = np.minimum(out[sel], move_lam)
    return out


def commanded_frequencies(job: Job, features=None) -> np.ndarray:
    """(n,) direction-change frequency of each move at its commanded speed, Hz: the requested
    speed (the G-code's F, mm/s) over the shortest three-cycle wavelength around it (``sections``
    wavelengths, mm); 0 where no three cycles surround the move. This is the figure a frequency
    limit acts on: after ``apply_freq_limit(job, L)`` no move exceeds L unless its floor
    (``min_speed_factor``) holds it above. The printer's accelerations and corners make the planned
    figure lower (``shaping.testprints.direction_change_frequencies``)."""
    lam = path_wavelengths(job, "sections", features)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(np.isfinite(lam) & (lam > 0), job.feed / lam, 0.0)


def apply_freq_limit(job: Job, limit_hz: float | None = None, method: str = "sections",
                     min_speed_factor: float | None = None, features=None,
                     max_velocity: tuple | None = None) -> Job:
    """A copy of ``job`` whose requested speeds respect a direction-change frequency limit (Hz).

    ``limit_hz`` None takes the job's own ``M201 F``; 0 or no limit returns the job unchanged.
    ``min_speed_factor`` None: see :func:`resolve_min_speed_factor`. ``features``: substrings of
    slicer feature names to limit (None = every extrusion path). ``max_velocity``: per-axis caps
    (x, y, z, e; mm/s) the Marlin emulation uses for its speed factor when the job sets no M203.
    """
    if method not in METHODS:
        raise RingtuneError(f"method must be one of {', '.join(METHODS)}, not {method!r}", "method")
    min_speed_factor = resolve_min_speed_factor(job, method, min_speed_factor)
    if limit_hz is None:
        limit_hz = job.file_setting("freq_limit_hz")
        if limit_hz != limit_hz:
            return job
    if not (math.isfinite(limit_hz) and limit_hz >= 0):
        raise RingtuneError(f"frequency limit must be a number >= 0 Hz, not {limit_hz}", "limit_hz")
    if not 0 < min_speed_factor <= 1:
        raise RingtuneError(f"minimum speed factor must be in (0, 1], not {min_speed_factor}",
                            "min_speed_factor")
    if limit_hz == 0 or job.n_moves == 0:
        return job
    if method == "marlin":
        return job.with_feed(job.feed * marlin_speed_factors(job, limit_hz, min_speed_factor,
                                                             max_velocity))
    lam = path_wavelengths(job, method, features)
    cap = limit_hz * lam
    new = np.where(job.feed > cap, np.maximum(cap, min_speed_factor * job.feed), job.feed)
    return job.with_feed(new)


def _lround(x: np.ndarray) -> np.ndarray:
    return np.floor(np.asarray(x, float) + 0.5)


def marlin_speed_factors(job: Job, limit_hz: float, min_factor: float,
                         max_velocity: tuple | None = None) -> np.ndarray:
    """(n,) factor (≤ 1) Marlin's XY_FREQUENCY_LIMIT applies to each move's requested speed.

    Follows ``Planner::_populate_block``: direction bits set for negative motion (a zero move
    counts as positive), ``segment_time_us = LROUND(LROUND(1e6·d/F) / speed_factor)`` with
    the max-feedrate speed factor, history of the last three segments per axis (reset by a segment
    longer than the minimum interval). The history starts at zero as Marlin's static variables do
    (so a short first segment that moves in -X or -Y is throttled); Cartesian direction bits (on
    CoreXY Marlin tests the A/B motors instead); SLOWDOWN (buffer-starved slowing) not modelled.
    """
    delta, d = _geometry(job)
    n = job.n_moves
    feed = job.feed
    u = delta / d[:, None]
    # Marlin's speed factor from the per-axis maximum feedrates (M203)
    caps = []
    for i, ax in enumerate("xyze"):
        machine = np.inf if max_velocity is None or max_velocity[i] <= 0 else max_velocity[i]
        v = job.setting(f"max_vel_{ax}")
        caps.append(np.where(np.isnan(v), machine, np.where(v > 0, v, np.inf)))
    caps = np.stack(caps, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(np.abs(u) > 0, caps / (np.abs(u) * feed[:, None]), np.inf)
    sf = np.minimum(1.0, ratio.min(axis=1))
    min_int = float(_lround(1e6 / limit_hz))
    seg = _lround(_lround(1e6 * d / feed) / sf)
    bits = delta[:, :2] < 0
    old = np.vstack([np.zeros((1, 2), bool), bits[:-1]])
    changed = bits ^ old
    long_ = seg > min_int
    s0 = np.where(changed, seg[:, None], min_int)                       # xs0, ys0
    # Marlin's history is ``static int32_t xs0, xs1, xs2, ...``: zero before the first block
    s0_prev = np.vstack([np.zeros((1, 2)), s0[:-1]])
    s0_prev2 = np.vstack([np.zeros((2, 2)), s0[:-2]])[:n]
    long_prev = np.concatenate(([False], long_[:-1]))
    s1 = np.where(long_[:, None], min_int, s0_prev)
    s2 = np.where((long_ | long_prev)[:, None], min_int, s0_prev2)
    worst = np.maximum(np.maximum(s0, s1), s2)                         # per axis
    least = worst.min(axis=1)
    throttle = (seg < min_int) & (least < min_int)
    f = np.maximum(sf * least / min_int, min_factor)
    new_sf = np.where(throttle, np.minimum(sf, f), sf)
    return new_sf / sf
