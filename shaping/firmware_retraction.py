"""Firmware retraction: ``G10`` and ``G11`` (without ``P`` or ``L``) ask the printer to retract and restore
the filament by its own settings — Klipper's ``[firmware_retraction]`` (``SET_RETRACTION``; no
section: an unknown command, nothing moves), Marlin's M207/M208 (FWRETRACT), RepRapFirmware's M207
(``G10`` with ``P`` or ``L`` is RRF's tool offset or temperature, not a retraction). Each is an
E-only move (the reader records it, :class:`RetractionState`: not at a G10 while retracted, nor a G11
while not).

Where the settings are known — the printer's (``[limits]`` ``retract_length``, ``retract_speed``,
``unretract_extra_length``, ``unretract_speed``: what ``printer from-klipper|from-marlin|from-rrf``
read) or the job's own commands before it (Klipper ``SET_RETRACTION``; Marlin ``M207 S F``,
``M208 S F``; RRF ``M207 S R F T``) — :func:`with_firmware_retractions` adds the E-only move each
makes, as the firmware itself does, and the planner treats it as a slicer's own E-only move (Klipper
comes to rest at it; a length of 0 moves nothing and the head goes on). Klipper runs
``G1 E-length F(int(60·speed))`` (its M220 speed factor applies); Marlin and RRF move at their own
speeds (no M220). A ``G11`` restores the length plus the extra (Marlin and RRF restore what the
``G10`` took: the same unless a job changes the length while retracted). The job's E words are
unchanged by it (the firmwares keep the G-code's E position). The planner plans each E-only move
among the job's, then folds it into the rest before the next move (:func:`fold_retractions`), so a
plan's moves stay the job's as read. Where the settings are not known, the head stops there (the
reader's ``stop_before``: the printer assumed to retract, as a slicer's retraction stops Klipper),
the moves take no time, and :func:`firmware_retraction_note` says what that leaves out.

Z hop (Marlin's and RRF's ``M207 Z``, Kalico's ``z_hop_height`` and ``SET_RETRACTION Z_HOP_HEIGHT``;
``[limits] retract_zlift``): after a ``G10``'s E move the head rises by it, and before a ``G11``'s it
comes down by what the ``G10`` raised (:class:`HopRule`): Marlin (``fwretract.cpp``: above 0.01 mm)
and RRF (``RetractFilament``: above 0) at the Z axis's top speed — planned where the printer gives it
(``[limits] max_velocity``), else left out and said; Kalico (``firmware_retraction.py``, only where
the length is above 0) by ``G1 Z… F(int(0.8·max_velocity·60))``, which M220 scales and the Z caps bound.
Mainline Klipper has none.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from itertools import chain

import numpy as np

from ringtune.shaping.errors import RingtuneError

#: for the sentence's example: Klipper's default speeds (mm/s) at a 1 mm retraction
EXAMPLE_MM, EXAMPLE_OUT_MM_S, EXAMPLE_BACK_MM_S = 1.0, 20.0, 10.0
#: the settings, as MachineLimits names them
KEYS = ("retract_length", "retract_speed", "unretract_extra_length", "unretract_speed", "retract_zlift")
#: Kalico's Z hop speed, a share of the printer's max_velocity (``ZHOP_MOVE_SPEED_FRACTION``)
KALICO_HOP_SHARE = 0.8
#: per firmware reading (:func:`dialect`): the job's command -> (word, setting, divisor to mm or mm/s),
#: applied in order (RRF's F sets both speeds, then T the restore's own); RRF's M208 is the axis limits
_WORDS = {
    "klipper": {"SET_RETRACTION": (("RETRACT_LENGTH", "retract_length", 1), ("RETRACT_SPEED", "retract_speed", 1),
                                   ("UNRETRACT_EXTRA_LENGTH", "unretract_extra_length", 1),
                                   ("UNRETRACT_SPEED", "unretract_speed", 1), ("Z_HOP_HEIGHT", "retract_zlift", 1))},
    "marlin": {"M207": (("S", "retract_length", 1), ("F", "retract_speed", 60), ("Z", "retract_zlift", 1)),
               "M208": (("S", "unretract_extra_length", 1), ("F", "unretract_speed", 60))},
    "rrf": {"M207": (("S", "retract_length", 1), ("F", "retract_speed", 60), ("F", "unretract_speed", 60),
                     ("R", "unretract_extra_length", 1), ("T", "unretract_speed", 60), ("Z", "retract_zlift", 1))},
}


def is_firmware_retraction(command: str, words) -> bool:
    """Whether ``command`` with ``words`` (its letters) retracts or restores by the printer's own
    settings: ``G10``/``G11`` without ``P`` or ``L``."""
    return command in ("G10", "G11") and not {"P", "L"} & set(words)


class RetractionState:
    """Whether the filament is retracted by firmware, as the firmwares keep it (Klipper's
    ``firmware_retraction.py`` ``is_retracted``, Marlin's ``retracted[]``, RRF's per tool): a ``G10``
    while retracted, or a ``G11`` while not, moves nothing; Klipper's ``SET_RETRACTION`` clears it."""

    def __init__(self):
        self.retracted = False

    def reset(self) -> None:
        """Klipper's ``SET_RETRACTION``: whatever was retracted is forgotten."""
        self.retracted = False

    def moves(self, command: str, words) -> bool:
        """Whether ``command`` (with ``words``) makes the extruder move: an E-only move, at which
        the head comes to rest. Assumes the printer retracts by a length above 0 (Klipper's
        ``[firmware_retraction]`` defaults to 0, and then nothing moves)."""
        if not is_firmware_retraction(command, words) or self.retracted == (command == "G10"):
            return False
        self.retracted = command == "G10"
        return True


def firmware_retractions(job) -> dict[str, list[int]]:
    """{``"G10"`` / ``"G11"``: the job's line numbers, in order} of its firmware retractions and
    restores that move the extruder (a parsed :class:`ringtune.shaping.job.Job`); empty when it has none."""
    out: dict[str, list[int]] = {}
    for r in job.fw_retractions:
        out.setdefault(r.command, []).append(int(r.line))
    return out


@dataclass(frozen=True)
class Retraction:
    """One firmware retraction as planned: the reader's record (``at``), the E it moves (mm; None:
    the settings are not known) at ``speed`` (mm/s), where the settings came from, and its Z hop
    (``hop`` mm, up at a G10, down at a G11; at ``hop_speed`` mm/s, 0: the Z top speed is not known)."""

    at: object
    e: float | None
    speed: float | None
    source: str
    hop: float = 0.0
    hop_speed: float = 0.0


@dataclass(frozen=True)
class HopRule:
    """How a firmware makes a retraction's Z hop: above ``least`` mm, at ``speed`` mm/s (0: not
    known), scaled by the M220 factor to the power ``m220`` (1: it is, 0: not), and whether a
    retraction of no length hops too."""

    least: float
    speed: float
    m220: int
    without_length: bool


#: the least Z hop Marlin makes (``retract_zraise > 0.01``); RRF and Kalico make any above 0
_LEAST_HOP = {"marlin": 0.01}


def hop_rule(limits, kind: str) -> HopRule:
    """The :class:`HopRule` of the firmware reading a job with ``limits`` as ``kind`` (:func:`dialect`):
    Kalico's ``G1 Z… F%d`` at 0.8 × max_velocity (none at length 0), else the Z axis's top speed
    (``[limits] max_velocity`` z; 0: not given)."""
    if kind == "klipper":
        return HopRule(0.0, math.floor(KALICO_HOP_SHARE * limits.velocity * 60) / 60, 1, False)
    return HopRule(_LEAST_HOP.get(kind, 0.0), float((limits.max_velocity or (0.0,) * 4)[2]), 0, True)


def dialect(limits) -> str:
    """How the firmware of ``limits`` reads retraction commands: ``klipper``, ``rrf`` (M203 in mm/min)
    or ``marlin`` (Marlin and Prusa, and an unknown firmware on Marlin's corner rules)."""
    if limits.reads_like_klipper:
        return "klipper"
    return "rrf" if limits.m203_per_minute else "marlin"


def _num(value, what: str, where: str) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise RingtuneError(f"{what} must be a number, not {value!r}", where) from None
    if not math.isfinite(x):
        raise RingtuneError(f"{what} must be a finite number, not {value!r}", where)
    return x


def job_settings(ev, kind: str, where: str) -> dict[str, float]:
    """What a job's command (an :class:`ringtune.shaping.job.Event`) sets of :data:`KEYS` on a
    firmware of ``kind`` (:func:`dialect`): empty for other commands. Speeds in mm/s."""
    out = {}
    for word, key, scale in _WORDS[kind].get(ev.command, ()):
        if word in ev.params:
            out[key] = _num(ev.params[word], f"{ev.command} {word}", where) / scale
    return out


def retraction_plan(job, limits) -> list[Retraction]:
    """Each of ``job``'s firmware retractions with the E it moves and its speed, on a firmware with
    ``limits`` (a :class:`ringtune.shaping.planner.MachineLimits`): the printer's settings (its
    ``unretract_extra_length`` only where it gives ``retract_length``), changed by the job's own
    commands as they come (module docstring)."""
    if not job.fw_retractions:          # every trial plans the job: nothing to walk through
        return []
    kind = dialect(limits)
    values = {k: getattr(limits, k) if limits.retract_length is not None else None for k in KEYS}
    values["retract_zlift"] = limits.retract_zlift          # none unless given
    source = dict.fromkeys(KEYS, "the printer's")
    pending = [ev for ev in job.events if ev.command in _WORDS[kind]][::-1]     # the job's own, last first
    rule = hop_rule(limits, kind)
    out, raised = [], 0.0
    for r in job.fw_retractions:
        while pending and pending[-1].line < r.line:
            ev = pending.pop()
            for k, v in job_settings(ev, kind, f"{job.source}:{ev.line}").items():
                values[k], source[k] = v, f"line {ev.line}"
        p, raised = _hopped(_one(r, kind, values, source), values["retract_zlift"], rule, raised)
        out.append(p)
    return out


def _hopped(p: Retraction, zlift: float, rule: HopRule, raised: float):
    """(``p`` with its Z hop, the hop raised after it): a G10's ``zlift`` (mm) as ``rule`` makes it, a
    G11's the ``raised`` of the G10 before it down."""
    if p.e is None or not (p.e or rule.without_length):
        return p, raised
    hop = -raised if p.at.command == "G11" else zlift * (zlift > rule.least)
    speed = rule.speed * p.at.speed_factor ** rule.m220
    return (replace(p, hop=hop, hop_speed=speed) if hop else p), max(hop, 0.0)


def _one(r, kind: str, values: dict, source: dict) -> Retraction:
    """The retraction ``r`` under ``values`` (None where not known). A G11 restores the length in force
    plus the extra (Klipper's rule; Marlin and RRF restore what the G10 took, the same unless the job
    changes the length while retracted). A length of 0 moves nothing, whatever the speed."""
    keys = ("retract_length", "retract_speed") if r.command == "G10" else (
        "retract_length", "unretract_extra_length", "unretract_speed")
    length, extra, speed = values["retract_length"], values[keys[-2]], values[keys[-1]]
    if r.command == "G10":
        e = None if length is None else -length
    else:
        e = None if None in (length, extra) else length + extra
    if e is None or (e and speed is None):
        return Retraction(r, None, None, "")
    if kind == "klipper" and e:      # G1 E… F%d: whole mm/min, then the M220 factor
        speed = math.floor(speed * 60) / 60 * r.speed_factor
    return Retraction(r, e, speed, " and ".join(sorted({source[k] for k in keys})))


def with_firmware_retractions(job, limits):
    """``job`` with the E-only move of each firmware retraction whose settings are known
    (:func:`retraction_plan`) inserted where the firmware makes it and marked in ``fw_inserted``
    (the planner plans them, then folds each into a rest: :func:`fold_retractions`), and the reader's
    stop lifted where only such retractions made it (the planner decides there as at a slicer's own
    E-only move; a length of 0 moves nothing and the head goes on); its ``fw_retractions`` then
    empty (planned once). The same object when none is known."""
    known = [p for p in retraction_plan(job, limits) if p.e is not None]
    if not known:
        return job
    cache = job.__dict__.setdefault("_fw_planned", {})
    key = tuple((p.at.line, p.e, p.speed, p.hop, p.hop_speed) for p in known)
    if key not in cache:
        cache.clear()
        cache[key] = _inserted(job, known)
    return cache[key]


def _moves(p: Retraction) -> list[tuple]:
    """The moves ``p`` makes, in order, as (move index, line, feature, settings, speed mm/s, ΔE, ΔZ):
    a G10's E move then its hop, a G11's descent then its E move (those of no length, and a hop whose
    speed is not known, left out)."""
    base = (p.at.move, p.at.line, p.at.feature, p.at.settings)
    e = [(*base, p.speed, p.e, 0.0)] if p.e else []
    z = [(*base, p.hop_speed, 0.0, p.hop)] if p.hop_speed else []
    return e + z if p.at.command == "G10" else z + e


def _inserted(job, known: list[Retraction]):
    """The new job of :func:`with_firmware_retractions`: the E-only moves (and Z hops) in, marked in
    ``fw_inserted``, the events' move indices after them."""
    n = job.n_moves
    stop = job.stop_before.copy()
    alone = np.array([(p.at.move, p.at.alone) for p in known], np.int64)
    stop[alone[(alone[:, 1] > 0) & (alone[:, 0] < n), 0]] = False
    t = np.array(list(chain.from_iterable(map(_moves, known))), float).reshape(-1, 7)
    at, lines = t[:, 0].astype(np.int64), t[:, 1].astype(np.int64)
    start = np.vstack([job.start, job.end[-1:]])[at]        # where the head is: the next move's start, else the end
    end = start.copy()
    end[:, 3] += t[:, 5]
    end[:, 2] += t[:, 6]
    new = dict(start=start, end=end, line=lines, feed=t[:, 4], feature=t[:, 2].astype(np.int64),
               settings=t[:, 3].astype(np.int64), stop_before=False, dwell_before=0.0, arc=False)
    # an event comes after the inserted moves before its move, and at its move after those from earlier lines
    key = at * 2**32 + lines
    events = [replace(ev, move=ev.move + int(np.searchsorted(key, ev.move * 2**32 + ev.line))) for ev in job.events]
    job = replace(job, stop_before=stop)
    cols = {k: np.insert(getattr(job, k), at, v, axis=0) for k, v in new.items()}
    return replace(job, events=events, fw_retractions=[], fw_inserted=np.insert(np.zeros(n, bool), at, True), **cols)


def fold_retractions(job, per_move: tuple, seconds: np.ndarray):
    """``job`` (with ``fw_inserted``) and the planner's ``per_move`` arrays (entry and exit v², then
    the others, each (n,…)) without the inserted E-only moves: the head rests through each, so its
    ``seconds`` go to the rest before the next move (after the last, ``dwell_after``); each move keeps
    the entry and exit the plan gave it. So the plan's moves are the job's as read."""
    keep = ~job.fw_inserted
    into = np.cumsum(keep)[job.fw_inserted]                 # the move after each, among those kept
    rest = np.bincount(into, weights=seconds[job.fw_inserted] + job.dwell_before[job.fw_inserted],
                       minlength=int(keep.sum()) + 1)
    kept = without_inserted(job)
    kept.dwell_before = kept.dwell_before + rest[:-1]
    kept.dwell_after = job.dwell_after + float(rest[-1])
    return kept, tuple(a[keep] for a in per_move)


def without_inserted(job):
    """``job`` without the E-only moves :func:`with_firmware_retractions` put in (the events' indices
    back to the moves as read)."""
    if job.fw_inserted is None:
        return job
    keep = ~job.fw_inserted
    before = np.concatenate(([0], np.cumsum(keep)))
    cols = {k: getattr(job, k)[keep] for k in ("line", "start", "end", "feed", "feature", "settings",
                                              "stop_before", "dwell_before", "arc")}
    return replace(job, events=[replace(ev, move=int(before[ev.move])) for ev in job.events], fw_inserted=None, **cols)


def firmware_retraction_note(job, limits) -> str | None:
    """One sentence on ``job``'s firmware retractions on a firmware with ``limits``: how they are
    planned, or what leaving them out costs where the settings are not known (None: none)."""
    plan = retraction_plan(job, limits)
    if not plan:
        return None
    parts = ", ".join(f"{cmd} ×{len(lines)} (first on line {lines[0]})"
                      for cmd, lines in sorted(firmware_retractions(job).items()))
    known = [p for p in plan if p.e is not None]
    unknown = [p for p in plan if p.e is None]
    return f"the job retracts by firmware — {parts}: " + "; ".join(filter(None, (_known_words(known),
                                                                                 _unknown_words(unknown),
                                                                                 _hop_words(known))))


def _known_words(known: list[Retraction]) -> str:
    if not known:
        return ""
    src = sorted({p.source for p in known})
    return (f"{len(known)} planned as the E-only moves the firmware makes, by "
            + "; ".join(_source_words(s) for s in src) + f" settings ({_settings_words(known)})")


def _unknown_words(unknown: list[Retraction]) -> str:
    if not unknown:
        return ""
    out, back = EXAMPLE_MM / EXAMPLE_OUT_MM_S, EXAMPLE_MM / EXAMPLE_BACK_MM_S
    total = sum(out if p.at.command == "G10" else back for p in unknown)
    return (f"{len(unknown)} planned as stops that take no time: the length and speeds are the printer's "
            "(Klipper's [firmware_retraction], Marlin's M207/M208, RRF's M207), not in the printer description "
            "([limits] retract_length, retract_speed, unretract_extra_length, unretract_speed; `ringtune printer "
            "from-klipper|from-marlin|from-rrf` reads them) nor set by the job before them (the printer assumed to "
            "retract: Klipper's retract_length defaults to 0, and then the head does not stop); at "
            f"{EXAMPLE_MM:g} mm out at {EXAMPLE_OUT_MM_S:g} mm/s ({out:.2f} s) and back at {EXAMPLE_BACK_MM_S:g} "
            f"mm/s ({back:.2f} s) they would add {total:.1f} s in all")


def _words(p: Retraction) -> str:
    """``G10 -0.8 mm at 35 mm/s`` (with its hop: ``, Z +0.4 mm at 5 mm/s``), or ``G11 moves no filament``."""
    head = f"{p.at.command} {p.e:+.4g} mm at {p.speed:.4g} mm/s" if p.e else f"{p.at.command} moves no filament"
    return head + (f", Z {p.hop:+.4g} mm at {p.hop_speed:.4g} mm/s" if p.hop_speed else "")


def _hop_words(known: list[Retraction]) -> str:
    """The Z hops of ``known`` left out for want of the Z axis's top speed, or ""."""
    left = [p for p in known if p.hop > 0 and not p.hop_speed]
    if not left:
        return ""
    return (f"the Z hop of {left[0].hop:g} mm at {len(left)} of them (up, and down at the G11) is left out: the firmware "
            "moves it at the Z axis's top speed, which the printer description does not give ([limits] max_velocity z)")


def _source_words(source: str) -> str:
    return source if source.startswith("the printer") else f"the job's own ({source})"


def _settings_words(known: list[Retraction]) -> str:
    """The distinct (E, speed) pairs of ``known`` in words (the first three, and how many more)."""
    pairs = list(dict.fromkeys(map(_words, known)))
    return ", ".join(pairs[:3]) + f" and {len(pairs) - 3} more" * (len(pairs) > 3)
