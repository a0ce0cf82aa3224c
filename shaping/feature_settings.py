"""Acceleration and corner rule per feature class, move by move (mm/s², mm/s, mm).

One function decides, for every move of a parsed job, the acceleration and corner settings a
per-feature :class:`~ringtune.shaping.config.TuneConfig` puts in force there
(:func:`move_settings`). The planner uses them through :func:`with_feature_settings` (they become
the job's own settings, as if the job had set them), and the job rewriter
(:mod:`ringtune.shaping.rewrite`) writes the same values into the file as firmware commands
wherever they change — so a rewritten file plans to the same time as the configuration did.

How each firmware takes an acceleration per feature:

- Klipper / Kalico (junction rule ``scv``): one acceleration for every move
  (``SET_VELOCITY_LIMIT ACCEL``), so the value in force follows the move's *effective class*: the
  class of its feature label when it extrudes; ``travel`` for an X/Y move that does not, unless it
  lands on or leaves a visible extrusion (every move of the hop into an outer wall's seam, the move
  off its end): then the class of that extrusion, so what a person sees at the seam is the wall's; a move
  without X/Y motion (retract, unretract, Z hop) keeps the class of the move before it, so it never
  costs a command of its own;
- Marlin, Prusa, RepRapFirmware (``jd`` / ``jerk``): ``M204 P`` is the printing acceleration,
  taken by every move with E (the label's class), ``M204 T`` the travel acceleration, taken by
  moves without E — set together at each label change, and around the seam's travel, whose
  ``T`` is the wall's; ``M204 R`` (retraction) is left as it is.

On a first layer the job slows itself (its own acceleration there below what it gives a printing
move later: a slicer's first-layer acceleration, for adhesion, which the model does not judge),
every move keeps the job's own acceleration where it is lower than the class's
(:func:`first_layer_caps`), as re-slicing with the tuned accelerations would.

The corner value (``square_corner_velocity``, ``M205 J``, ``M205 X Y`` or ``M566 X Y``, by the
printer's junction rule) and Klipper's ``minimum_cruise_ratio`` are one for the whole job, or per
class where the configuration sets them so (``feature_corner``, ``feature_min_cruise_ratio``): then
the value in force follows the move's effective class in every dialect (one command sets it for
printing and travel alike), and the rewriter writes it at each change.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field, replace
from typing import Any, Callable

import numpy as np

from ringtune.shaping.features import FEATURE_CLASSES, class_indices, seen_classes
from ringtune.shaping.firmware import FIRMWARES
from ringtune.shaping.job import SETTING_KEYS, Job
from ringtune.shaping.layers import layer_starts
from ringtune.shaping.planner import reads_like_klipper

TRAVEL = FEATURE_CLASSES.index("travel")


@dataclass(frozen=True)
class FeatureCommands:
    """What a per-feature configuration sets, resolved for one printer.

    accel: class -> mm/s² for every class of :data:`FEATURE_CLASSES` (absent ones at ``default``);
    corner: the corner rule value in the junction rule's unit (None: left as it is); junction:
    ``scv`` | ``jd`` | ``jerk``; min_cruise_ratio: Klipper's (None: left as it is); caps: (X, Y)
    per-axis acceleration caps, mm/s² (``M201 X Y``; None: none, Klipper); class_corner,
    class_mcr: class -> the corner value / minimum_cruise_ratio where a class has its own (the
    others take ``corner`` / ``min_cruise_ratio``, or ``corner_now`` / ``mcr_now``, the printer's);
    atd_now: a Klipper from before 2024, its max_accel_to_decel (mm/s², kept where no
    minimum_cruise_ratio is set; None: a current Klipper); klipper_reading: whether the firmware reads
    a job as Klipper does (:attr:`ringtune.shaping.planner.MachineLimits.reads_like_klipper`; None:
    as the junction rule implies) — which settings carry the X/Y caps."""

    accel: dict
    junction: str
    corner: float | None = None
    min_cruise_ratio: float | None = None
    caps: tuple | None = None
    class_corner: dict = field(default_factory=dict)
    class_mcr: dict = field(default_factory=dict)
    corner_now: float | None = None
    mcr_now: float | None = None
    atd_now: float | None = None
    klipper_reading: bool | None = None

    @property
    def reads_like_klipper(self) -> bool:
        return reads_like_klipper(self.klipper_reading, self.junction)

    @classmethod
    def from_config(cls, config, limits) -> "FeatureCommands":
        """From a :class:`TuneConfig` and the printer's :class:`MachineLimits` (its junction rule
        and, where the config has no ``accel``, its acceleration)."""
        default = float(config.accel if config.accel is not None else limits.accel)
        accel = {c: float(config.feature_accel.get(c, default)) for c in FEATURE_CLASSES}
        scv = limits.junction == "scv"
        mcr = config.min_cruise_ratio if scv else None
        now = corner_value(limits)
        return cls(accel, limits.junction, config.corner, mcr, _caps(config.firmware, limits, accel, config.axis_caps),
                   dict(config.feature_corner), dict(config.feature_min_cruise_ratio) if scv else {},
                   float(now), float(limits.min_cruise_ratio), limits.accel_to_decel if scv else None,
                   limits.reads_like_klipper)


def corner_value(limits) -> float:
    """The printer's own corner value in its junction rule's unit (``MachineLimits``): Klipper's
    square_corner_velocity (mm/s), Marlin's junction deviation (mm), or the lower of its X/Y jerks
    (mm/s)."""
    return float({"scv": limits.square_corner_velocity, "jd": limits.junction_deviation,
                  "jerk": min(limits.jerk[:2])}[limits.junction])


def _caps(firmware: str, limits, accel: dict, own: tuple = (None, None)) -> tuple | None:
    """The X/Y caps a per-feature job runs with, mm/s²: the configuration's own (``own``:
    :attr:`TuneConfig.axis_caps`, None per axis where it has none), else the machine's; on a
    firmware set by ``M201`` an axis without a known cap gets the highest feature acceleration, so
    the printer's stored M201 cannot hold the job back; None on Klipper without caps."""
    machine = (limits.max_accel or (0, 0))[:2]
    known = [float(o) if o else (float(c) if c and c > 0 else None) for o, c in zip(own, machine)]
    fw = FIRMWARES[firmware]
    if fw.axis_accel_set and not fw.axis_accel_config:
        top = max(accel.values())
        return tuple(c if c is not None else top for c in known)
    return None if None in known else tuple(known)


def label_classes(job: Job) -> np.ndarray:
    """(n,) index into :data:`FEATURE_CLASSES` of each move's feature label."""
    return class_indices(job.features)[job.feature] if job.n_moves else np.zeros(0, np.int64)


def effective_classes(job: Job) -> np.ndarray:
    """(n,) class index per move as Klipper's one acceleration follows it (module docstring):
    label class when extruding, ``travel`` for X/Y moves without E — except a travel next to a
    visible extrusion, which takes its class (:func:`_seam_travel`) —, moves without X/Y motion
    keep the class of the move before them."""
    return _classes(job)[0]


def _per_job(fn: Callable[[Job], Any]) -> Callable[[Job], Any]:
    """``fn(job)`` cached for the last few jobs by identity: a tuning run plans one job hundreds of
    times, and a job's moves are not changed in place (each job is kept alive while cached, so its
    id is not reused)."""
    cache: dict[int, tuple] = {}

    @functools.wraps(fn)
    def cached(job: Job):
        hit = cache.get(id(job))
        if hit is not None and hit[0] is job:
            return hit[1]
        out = fn(job)
        if len(cache) >= 8:
            cache.pop(next(iter(cache)))
        cache[id(job)] = (job, out)
        return out
    return cached


@_per_job
def _classes(job: Job) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(:func:`effective_classes`, :func:`label_classes`, (n,) True on the seam's travel: the
    travel moves that took a visible extrusion's class, and the moves without X/Y motion after
    them); cached per job."""
    d = job.delta
    label = label_classes(job)
    xy = np.hypot(d[:, 0], d[:, 1]) > 0
    extruding = xy & (d[:, 3] > 0)
    own = np.where(xy & ~extruding, TRAVEL, label)
    cls = _seam_travel(own, xy, extruding)
    idx = np.arange(job.n_moves)
    last = np.maximum.accumulate(np.where(xy, idx, -1))     # the latest move with X/Y motion
    at = np.maximum(last, 0)
    return np.where(last >= 0, cls[at], label), label, (last >= 0) & (cls[at] != own[at])


#: the accelerations a first layer the job slows itself keeps at the job's own where that is lower
FIRST_LAYER_KEYS = ("accel_klipper", "accel_print", "accel_travel")


@_per_job
def first_layer_caps(job: Job) -> dict[str, np.ndarray]:
    """{setting of :data:`FIRST_LAYER_KEYS`: (n,) the job's own value on the moves of its first
    layer, NaN elsewhere} for each setting whose first-layer value the job keeps below the highest
    it gives a printing move later (a slicer's first-layer acceleration, for adhesion, which the
    model does not judge; a value set once for the whole job is no slowdown); cached per job."""
    out: dict[str, np.ndarray] = {}
    starts = layer_starts(job) if job.n_moves else []
    if len(starts) >= 2:
        first = np.zeros(job.n_moves, bool)
        first[starts[0]:starts[1]] = True
        ext = job.extruding
        for key in FIRST_LAYER_KEYS:
            own = job.setting(key)
            here, later = own[first & ext], own[~first & ext]
            here, later = here[~np.isnan(here)], later[~np.isnan(later)]
            if len(here) and len(later) and here.min() < later.max():
                out[key] = np.where(first, own, np.nan)
    return out


def _seam_travel(cls: np.ndarray, xy: np.ndarray, extruding: np.ndarray) -> np.ndarray:
    """``cls`` with the travel moves (X/Y without E) next to a visible extrusion (moves without X/Y
    motion between skipped) in that extrusion's class: every travel of the hops that land on it
    (the travel moves from the last extrusion before it), else the one that leaves it. Why: the
    travel's decelerations ring into the wall it lands on (the seam a person sees: a slicer that
    hops in several moves, CuraEngine's G0s, decelerates hard just before the last short one) and a
    shaper spreads its acceleration back over the end of the wall it leaves
    (:mod:`ringtune.shaping.seams`); at the wall's own settings the seam is the wall's. ``other``
    counts as visible only in a job that labels nothing visible (else it is a purge line)."""
    k = np.flatnonzero(xy)
    if len(k) < 2:
        return cls
    c, ext = cls[k], extruding[k]
    seen = seen_classes(FEATURE_CLASSES[i] for i in np.unique(c[ext]))
    vis = ext & np.isin(c, [FEATURE_CLASSES.index(v) for v in seen])
    travel = ~ext & (c == TRAVEL)
    n = len(c)
    nxt = np.minimum.accumulate(np.where(travel, n, np.arange(n))[::-1])[::-1]   # the next non-travel move
    lands = travel & (nxt < n) & vis[np.minimum(nxt, n - 1)]
    leaves = travel & ~lands & np.r_[False, vis[:-1]]
    out = cls.copy()
    out[k[lands]] = c[nxt[lands]]
    out[k[leaves]] = c[np.flatnonzero(leaves) - 1]
    return out


#: the settings the corner value sets, by junction rule
_CORNER_KEYS = {"scv": ("square_corner_velocity",), "jd": ("junction_deviation",),
                "jerk": ("jerk_x", "jerk_y", "m205_jerk_x", "m205_jerk_y")}


def _accels(fc: FeatureCommands, eff: np.ndarray, label: np.ndarray, seam: np.ndarray) -> dict[str, np.ndarray]:
    """{accel_klipper, accel_print, accel_travel: mm/s² in force at each move} for ``fc`` (module
    docstring: Klipper's one acceleration, or Marlin/RRF's print and travel pair); ``eff``,
    ``label``, ``seam``: :func:`_classes`."""
    table = np.array([fc.accel[c] for c in FEATURE_CLASSES])
    if fc.junction == "scv":
        a = table[eff]
        return dict(accel_klipper=a, accel_print=a, accel_travel=a)
    p, t = table[label], np.where(seam, table[eff], fc.accel["travel"])   # M204 T: the seam's the wall's
    return dict(accel_print=p, accel_travel=t, accel_klipper=np.minimum(p, t))


def _per_class(eff: np.ndarray, by_class: dict, whole: float | None, now: float | None) -> np.ndarray | None:
    """(n,) value in force at each move: ``by_class`` (class -> value) following the effective
    class ``eff``, the others ``whole`` (else ``now``, the printer's); None when neither is set."""
    if not by_class and whole is None:
        return None
    default = float(whole if whole is not None else now)
    table = np.array([float(by_class.get(c, default)) for c in FEATURE_CLASSES])
    return table[eff] if by_class else np.full(len(eff), default)


def move_settings(job: Job, fc: FeatureCommands) -> dict[str, np.ndarray]:
    """{setting key of :data:`SETTING_KEYS`: (n,) value in force at each move} for ``fc``; on a
    first layer the job slows itself, its own acceleration where lower (:func:`first_layer_caps`)."""
    return _settings(fc, *_classes(job), first_layer_caps(job))


def _settings(fc: FeatureCommands, eff: np.ndarray, label: np.ndarray, seam: np.ndarray,
              caps: dict[str, np.ndarray] | None = None) -> dict[str, np.ndarray]:
    """:func:`move_settings` for moves of effective class ``eff``, label class ``label`` and seam
    flag ``seam`` (each (n,)) under the first-layer ``caps`` (each (n,), NaN: none): every value is
    a function of those."""
    n = len(eff)
    out = _accels(fc, eff, label, seam)
    for key, cap in (caps or {}).items():
        out[key] = np.fmin(out[key], cap)          # NaN (no cap) keeps ours
    corner = _per_class(eff, fc.class_corner, fc.corner, fc.corner_now)
    if corner is not None:
        out.update(dict.fromkeys(_CORNER_KEYS[fc.junction], corner))
    mcr = _per_class(eff, fc.class_mcr, fc.min_cruise_ratio, fc.mcr_now) if fc.junction == "scv" else None
    if mcr is not None:
        out.update(min_cruise_ratio=mcr, accel_to_decel=_accel_to_decel(fc, eff, out["accel_klipper"], mcr))
    for ax, cap in zip("xy", fc.caps or ()):
        if cap is not None:
            out[f"{caps_setting(fc.reads_like_klipper)}_{ax}"] = np.full(n, float(cap))
    return out


def _accel_to_decel(fc: FeatureCommands, eff: np.ndarray, accel: np.ndarray, mcr: np.ndarray) -> np.ndarray:
    """(n,) ACCEL_TO_DECEL, mm/s², as the rewrite writes it beside each ACCEL for a Klipper from
    before 2024 (no MINIMUM_CRUISE_RATIO): the acceleration × (1 − minimum_cruise_ratio); on such a
    Klipper (``fc.atd_now``), where the configuration sets no ratio, its own max_accel_to_decel as
    it runs it, min(that, the acceleration)."""
    atd = accel * (1.0 - mcr)
    if fc.atd_now is None:
        return atd
    own = _per_class(eff, fc.class_mcr, fc.min_cruise_ratio, math.nan)     # NaN: none set
    unset = np.ones(len(eff), bool) if own is None else np.isnan(own)
    return np.where(unset, np.minimum(fc.atd_now, accel), atd)


def sets_corner(job: Job) -> bool:
    """Whether the parsed job sets a corner rule or minimum_cruise_ratio of its own (M205 J / X Y,
    M566, SET_VELOCITY_LIMIT SQUARE_CORNER_VELOCITY= / MINIMUM_CRUISE_RATIO=)."""
    return job.sets(sorted({k for ks in _CORNER_KEYS.values() for k in ks} | {"min_cruise_ratio"}))


def caps_setting(klipper: bool) -> str:
    """The prefix of the job settings that carry the X/Y acceleration caps for a firmware reading the
    job as Klipper does (``klipper``): Kalico's SET_VELOCITY_LIMIT X_ACCEL/Y_ACCEL
    (``limited_accel``); else M201 X Y (``max_accel``), as Marlin and RRF read it."""
    return "limited_accel" if klipper else "max_accel"


def with_feature_settings(job: Job, fc: FeatureCommands) -> Job:
    """A copy of ``job`` whose per-move settings carry ``fc`` (:func:`move_settings`), over
    whatever the job set itself — as the rewritten file will.

    The values are worked out once per (effective class, label class, seam) that occurs, not per
    move (they depend on nothing else), so a tuning run re-plans a long job cheaply."""
    if job.n_moves == 0:
        return job
    eff, label, seam = _classes(job)
    caps = first_layer_caps(job)
    capped, n_caps = _cap_codes(caps, job.n_moves)
    nc = len(FEATURE_CLASSES)
    size = 2 * nc * nc * n_caps
    key = ((eff * nc + label) * 2 + seam) * n_caps + capped
    first = np.full(size, -1)
    first[key[::-1]] = np.arange(job.n_moves)[::-1]
    reps = first[first >= 0]                     # one move of each key that occurs
    values = _settings(fc, eff[reps], label[reps], seam[reps], {k: v[reps] for k, v in caps.items()})
    if not values:
        return job
    keys = list(values)
    cols = [SETTING_KEYS.index(k) for k in keys]
    stacked = np.stack([np.nan_to_num(values[k], nan=-1.0) for k in keys], axis=1)
    combos, rep_code = np.unique(stacked, axis=0, return_inverse=True)
    lookup = np.zeros(size, np.int64)
    lookup[key[reps]] = np.asarray(rep_code).reshape(-1)
    pair = job.settings.astype(np.int64) * len(combos) + lookup[key]
    rows, new_index = _dense_unique(pair)
    base = np.asarray(job.settings_table, float)[rows // len(combos)].copy()
    vals = combos[rows % len(combos)]
    base[:, cols] = np.where(vals == -1.0, np.nan, vals)
    return replace(job, settings=new_index.astype(job.settings.dtype), settings_table=base)


def _cap_codes(caps: dict[str, np.ndarray], n: int) -> tuple[np.ndarray, int]:
    """((n,) code of each move's first-layer caps, 0 for none; how many codes there are)."""
    if not caps:
        return np.zeros(n, np.int64), 1
    stack = np.stack([np.nan_to_num(v, nan=-1.0) for v in caps.values()], axis=1)
    rows = np.flatnonzero(np.any(stack != -1.0, axis=1))
    codes = np.zeros(n, np.int64)
    if not len(rows):
        return codes, 1
    uniq, inv = np.unique(stack[rows], axis=0, return_inverse=True)
    codes[rows] = np.asarray(inv).reshape(-1) + 1
    return codes, len(uniq) + 1


def _dense_unique(codes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(codes, return_inverse=True)`` for non-negative integers, by a table when their
    range is small (no sort)."""
    top = int(codes.max()) + 1
    if top > 4 * len(codes) + 1024:
        rows, inv = np.unique(codes, return_inverse=True)
        return rows, np.asarray(inv).reshape(-1)
    present = np.zeros(top, bool)
    present[codes] = True
    rank = np.cumsum(present) - 1
    return np.flatnonzero(present), rank[codes]


def per_feature_words(config) -> str:
    """What a configuration sets per feature, in words: ``"inner_wall 11000, infill 11000, travel
    9100; corner 5; minimum_cruise_ratio 0.3"`` ("" when nothing)."""
    parts = []
    groups = accel_groups({c: a for c, a in config.feature_accel.items() if a != config.accel})
    if groups:
        parts.append(", ".join(groups))
    parts += corner_words(config.corner, config.min_cruise_ratio)
    parts += class_corner_words(config.feature_corner, config.feature_min_cruise_ratio)
    return "; ".join(parts)


def per_feature_text(config) -> str:
    """:func:`per_feature_words` for one line of a report: ``" (inner_wall 11000, …)"`` ("" when
    nothing)."""
    words = per_feature_words(config)
    return f" ({words})" if words else ""


def accel_groups(accel: dict, fmt: str = ".0f") -> list[str]:
    """``["inner_wall/infill 11000", "travel 9100"]``: the classes of a per-class table (class ->
    value, here mm/s²) grouped by their value, lowest first, each value in format ``fmt``."""
    groups: dict[float, list[str]] = {}
    for cls, a in accel.items():
        groups.setdefault(a, []).append(cls)
    return [f"{'/'.join(names)} {a:{fmt}}" for a, names in sorted(groups.items())]


def class_corner_words(corner: dict, min_cruise_ratio: dict) -> list[str]:
    """``["corner infill/travel 15", "minimum_cruise_ratio infill/travel 0"]``: the per-class values
    (class -> value) grouped by value (:func:`accel_groups`)."""
    return [f"{name} {g}" for name, table in (("corner", corner), ("minimum_cruise_ratio", min_cruise_ratio))
            for g in accel_groups(table, "g")]


def corner_words(corner: float | None, min_cruise_ratio: float | None) -> list[str]:
    """``["corner 5", "minimum_cruise_ratio 0.3"]``: those of the two that are set (not None)."""
    return [f"{name} {v:g}" for name, v in (("corner", corner), ("minimum_cruise_ratio", min_cruise_ratio))
            if v is not None]
