"""The job's own shaper commands, applied as the firmware applies them: a timeline of shaper settings.

A job may set input shaping itself: a ringing test print turns it off (``M593 X F0``,
``SET_INPUT_SHAPER SHAPER_FREQ_X=0``), a tower changes the frequency band by band. Each command
changes the settings it names, for the moves after it; the reader stops the planner there
(``stop_before``), and the plan keeps the stop where the firmware waits for the motion to end
(:func:`stops_for`):

- Klipper ``SET_INPUT_SHAPER``: ``SHAPER_TYPE[_X|_Y]``, ``SHAPER_FREQ_X|Y`` (0 = off),
  ``DAMPING_RATIO_X|Y``; an axis turned off keeps its type, so a later ``SHAPER_FREQ_X=50`` alone
  turns it on again with it (Klipper's InputShaperParams); where shaping starts off, the type is
  Klipper's default, ``mzv`` (the command exists only with an ``[input_shaper]`` section, whose
  ``shaper_type`` defaults to it);
- Marlin ``M593 [X] [Y] F D`` (classic ZV; no axis letter: both; ``F0`` = off; a ``D`` outside 0–1
  is skipped, the rest applies); Prusa ``M593 ... T F D`` (``T`` the type index; an axis turned
  off keeps nothing: the next change turns it on from Buddy's defaults, :func:`_prusa_m593`);
  RepRapFirmware ``M593 P"type" F S`` (one shaper for all axes, ``P"none"`` = off; without P the
  type stays, so a Marlin job's ``M593 F15`` sets its frequency,
  and an F outside its range — ``F0`` among them — fails the command, which changes nothing);
- Marlin FT_MOTION ``M493 [X] [Y] C A I`` (``C`` the mode, 0 = off; ``S0`` turns FT_MOTION off).

A command that changes only what an axis that is off keeps (its damping, a type) is no step: the
shaping is the same; what it stores applies once the axis is on again.

Each firmware acts on its own commands only (:data:`ACTED_ON`): a job sliced for another firmware
keeps its shaping there (:func:`foreign_shapers` names what it ignores).

:func:`shaper_timeline` folds them into (time s, :class:`TuneConfig`) steps starting from the
configuration given; :func:`shape_timeline` shapes a motion piece by piece, each piece with the
shapers in force, the pieces superposed as displacements (shaping is linear), which is what the
firmware does with each move.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ringtune.shaping.apply import shape_motion
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.firmware import FIRMWARES
from ringtune.shaping.gcode_commands import number_or_none
from ringtune.shaping.job import STOP_COMMANDS
from ringtune.shaping.layer_commands import PRUSA_WEIGHT_ADJUST, prusa_weight_frequency
from ringtune.shaping.motion import Motion
from ringtune.shaping.shapers import shapers_from_config

_FTM_MODES = ("none", "zv", "zvd", "zvdd", "zvddd", "ei", "2hump_ei", "3hump_ei", "mzv")
#: Prusa-Firmware-Buddy's M593 T (input_shaper::Type, first zv to last ei_3hump; another T is skipped)
_PRUSA_TYPES = ("zv", "zvd", "mzv", "ei", "2hump_ei", "3hump_ei")
_RRF_NAMES = {"ei2": "2hump_ei", "ei3": "3hump_ei"}
#: the settings a shaper command changes
_SHAPING = ("shaper_x", "shaper_y", "freq_x", "freq_y", "damping_x", "damping_y")
#: the shaper commands each firmware family acts on; it does not have a job's others (Klipper
#: answers "Unknown command" to an M593, Marlin to a SET_INPUT_SHAPER)
ACTED_ON = {"klipper": ("SET_INPUT_SHAPER",), "marlin": ("M593",), "prusa": ("M593",), "marlin-ftm": ("M493",),
            "rrf": ("M593",)}


def acted_on(firmware: str) -> tuple[str, ...]:
    """The shaper commands ``firmware`` (a name of :data:`ringtune.shaping.firmware.FIRMWARES`) acts on."""
    return ACTED_ON[FIRMWARES[firmware].family]


def foreign_shapers(job, firmware: str) -> dict[str, list[int]]:
    """{command: the job's line numbers, in order} of the shaper commands of a parsed job that
    ``firmware`` does not have (:data:`ACTED_ON`): they change nothing there."""
    acts = acted_on(firmware)
    out: dict[str, list[int]] = {}
    for ev in job.events:
        if _foreign(ev, acts):
            out.setdefault(ev.command, []).append(int(ev.line))
    return out


def _foreign(ev, acts: tuple[str, ...]) -> bool:
    """Whether job event ``ev`` is a shaper command of another firmware than the one acting on ``acts``."""
    return ev.kind == "shaper" and ev.command not in acts


#: per firmware family, the parameters of its own shaper command that make it wait for the motion to
#: stop (empty: any parameter does). Klipper's SET_INPUT_SHAPER flushes the step
#: generation whenever it has parameters (klippy/extras/input_shaper.py); Marlin's M593 synchronises
#: the planner when it sets F (stepper.cpp: set_shaping_frequency), not for D alone; RepRapFirmware's
#: M593 waits for standstill when it changes F, S, P, H or T, not for L (AxisShaper.cpp: "changing
#: just the minimum acceleration is OK"); Prusa's M593 empties the queues
#: (``set_axis_config``: planner.synchronize()) when it sets T, F, D or R, not for its weight rule (A,
#: M) or W alone (Prusa-Firmware-Buddy M593.cpp, input_shaper_config.cpp). Without parameters each
#: only reports. Marlin's M493 (M493.cpp @00317b4) sets C, A, I, Q, D, F and H without waiting; its S
#: switches fixed-time motion on or off (ftMotion.toggle, not read): planned as a stop.
STOPPING_WORDS = {"klipper": (), "marlin": ("F",), "rrf": tuple("FSPHT"), "prusa": tuple("TFDR"), "marlin-ftm": ("S",)}


def stops_for(ev, firmware: str) -> bool:
    """Whether ``firmware`` waits for the motion to stop at the shaper command of job event ``ev``:
    its own command in a form that changes the shaping (:data:`STOPPING_WORDS`), never another
    firmware's (it drains no queue for a command it does not know: Klipper answers "Unknown
    command" and goes on)."""
    if _foreign(ev, acted_on(firmware)):
        return False
    words = STOPPING_WORDS[FIRMWARES[firmware].family]
    return bool(ev.params) and (not words or any(w in ev.params for w in words))


def with_firmware_shaper_stops(job, config: TuneConfig):
    """``job`` as ``config``'s firmware runs it: no full stop before a move that only shaper commands
    it makes no stop for precede (the reader stops the planner at every shaper command): another
    firmware's, or its own in a form that only reports or leaves the queue running
    (:func:`stops_for`); on Prusa's, a full stop at each printed weight it acts on
    (:func:`weight_stops`), where ``config`` shapes Y, which the weight rule moves."""
    firmware = config.firmware
    idle = {ev.move for ev in job.events if ev.kind == "shaper" and not stops_for(ev, firmware)}
    weights = weight_stops(job, config)
    if not idle and not weights:      # every plan of a study passes here: most jobs have neither
        return job
    others = {ev.move for ev in job.events if ev.command in STOP_COMMANDS
              and (ev.kind != "shaper" or stops_for(ev, firmware))}
    moves = sorted(m for m in idle - others - weights if 0 < m < job.n_moves)
    added = sorted(m for m in weights if 0 < m < job.n_moves and not job.stop_before[m])
    if not moves and not added:
        return job
    stop = job.stop_before.copy()
    stop[moves] = False
    stop[added] = True
    return replace(job, stop_before=stop)


def weight_stops(job, config: TuneConfig) -> set[int]:
    """The moves before which Prusa's firmware stops for a printed weight: ``M74 W<g>`` (g > 0) sets Y's
    shaper by its weight rule through the call that empties the queues first (Prusa-Firmware-Buddy
    M74.cpp, input_shaper_config.cpp ``set_axis_config``), while the rule is on (its default; ``M593
    M0`` turns it off, ``M593 A`` or ``M`` > 0 on) and ``config`` shapes Y. Empty on any other firmware."""
    if FIRMWARES[config.firmware].family != "prusa" or shapers_from_config(config)[0]["y"] is None:
        return set()
    on, out = True, set()
    for ev in job.events:
        if ev.command == "M593" and ("A" in ev.params or "M" in ev.params):
            on = number_or_none(ev.params.get("M")) != 0
        elif ev.command == "M74" and on and (number_or_none(ev.params.get("W")) or 0) > 0:
            out.add(ev.move)
    return out


def prusa_weight_note(job, firmware: str) -> str | None:
    """Where ``firmware`` is Prusa's and the job gives it the printed weight (``M74 W<g>``, which
    PrusaSlicer's MK4 profiles write at every layer change): one sentence on what its own linear rule
    does with it (:func:`ringtune.shaping.layer_commands.prusa_weight_frequency`; ``M593 A M`` of the
    job set the rule), and what ringtune judges instead. None otherwise."""
    if FIRMWARES[firmware].family != "prusa":
        return None
    weights = [(ev.line, number_or_none(ev.params.get("W"))) for ev in job.events if ev.command == "M74"]
    weights = [(line, w) for line, w in weights if w is not None]
    if not weights:
        return None
    rule = dict(zip("AM", PRUSA_WEIGHT_ADJUST))          # M593 A<Hz> M<g> set it, the last one standing
    for ev in job.events:
        if ev.command == "M593":
            rule.update((k, number_or_none(ev.params[k])) for k in "AM" if number_or_none(ev.params.get(k)) is not None)
    delta, limit = rule["A"], rule["M"]
    heaviest = max(w for _l, w in weights)
    shift = prusa_weight_frequency(0.0, heaviest, delta, limit)
    return (f"the job gives the firmware the printed weight (M74 W ×{len(weights)}, first on line {weights[0][0]}): "
            f"Prusa's own rule moves Y's shaper frequency with it, by {shift:+.1f} Hz at its heaviest "
            f"({heaviest:.0f} g; {delta:g} Hz at {limit:g} g), as the mass on the bed lowers Y's mode; ringtune "
            "judges the whole job at the printer description's print_mass with Y's frequency as configured "
            "(neither the mode's fall nor the firmware's shift), and the job written keeps the lines "
            "(`ringtune schedule` sets the rule from the model); the firmware empties its queues to change the "
            "shaper, so each line is a full stop, as the plan has it")


def foreign_shapers_note(found: dict[str, list[int]], firmware: str) -> str | None:
    """One sentence on :func:`foreign_shapers` (None: there are none)."""
    if not found:
        return None
    parts = ", ".join(f"{c} ×{len(lines)} (first on line {lines[0]})" for c, lines in found.items())
    return (f"{FIRMWARES[firmware].title} has no {' or '.join(found)}: the job's {parts} change nothing there, and "
            "are applied neither in the simulation nor in the job written (sliced for another firmware?)")


def _indexed(table: tuple, v) -> str | None:
    """``table[int(v)]`` for a numeric ``v`` inside the table, else None."""
    i = number_or_none(v)
    return table[int(i)] if i is not None and 0 <= int(i) < len(table) else None


def _set_axis(cfg: dict, ax: str, shaper: str | None, freq: float | None, damping: float | None) -> None:
    """Apply one axis's change: frequency 0 or shaper ``none`` turns it off (a damping, or a
    frequency beside ``none``, is kept for when it is on again, as the firmwares keep them)."""
    if damping is not None:
        cfg[f"damping_{ax}"] = damping
    if freq is not None and freq > 0:
        cfg[f"freq_{ax}"] = freq
    if freq is not None and freq <= 0 or shaper == "none":
        cfg[f"shaper_{ax}"] = "none"
    elif shaper is not None:
        cfg[f"shaper_{ax}"] = shaper


#: Klipper's shaper_type where the [input_shaper] section names none
KLIPPER_DEFAULT_TYPE = "mzv"


def _klipper_freq(cfg: dict, ax: str, p: dict) -> float:
    """Hz an axis runs at after a SET_INPUT_SHAPER: as given, else as it was (0 where off)."""
    freq = number_or_none(p.get(f"SHAPER_FREQ_{ax.upper()}"))
    if freq is not None:
        return freq
    return 0.0 if cfg[f"shaper_{ax}"] == "none" else cfg[f"freq_{ax}"]


def _klipper(cfg: dict, p: dict) -> None:
    """Klipper's SET_INPUT_SHAPER: each axis's type (``kept_<ax>``: the one it keeps while off),
    frequency (0: off) and damping, each as given or as it was."""
    for ax in "xy":
        kind = p.get("SHAPER_TYPE", p.get(f"SHAPER_TYPE_{ax.upper()}"))
        kept = str(kind).lower() if kind is not None else cfg[f"kept_{ax}"]
        freq = _klipper_freq(cfg, ax, p)
        damping = number_or_none(p.get(f"DAMPING_RATIO_{ax.upper()}"))
        if damping is not None:
            cfg[f"damping_{ax}"] = damping
        if kept != "none":
            cfg[f"kept_{ax}"] = kept
        if kept == "none" or freq <= 0:
            cfg[f"shaper_{ax}"] = "none"
        else:
            cfg[f"shaper_{ax}"], cfg[f"freq_{ax}"] = kept, freq


def _axes(p: dict) -> str:
    named = "".join(ax for ax in "xy" if ax.upper() in p)
    return named or "xy"


def _m593(cfg: dict, p: dict) -> None:
    """Marlin's M593 (classic ZV; Prusa's: :func:`_prusa_m593`, RepRapFirmware's: :func:`_rrf_m593`)."""
    for ax in _axes(p):
        freq = number_or_none(p.get("F"))
        shaper = "zv" if freq and cfg.get(f"shaper_{ax}") == "none" else None
        _set_axis(cfg, ax, shaper, freq, number_or_none(p.get("D")))


#: Prusa-Firmware-Buddy's ``axis_x_default`` / ``axis_y_default`` (input_shaper_config.hpp: MZV at
#: 50.7 and 40.6 Hz, damping 0.1): what an axis that is off starts from when an M593 changes it
PRUSA_AXIS_DEFAULTS = {"x": ("mzv", 50.7, 0.1), "y": ("mzv", 40.6, 0.1)}


def _prusa_m593(cfg: dict, p: dict, freq_span) -> None:
    """Prusa-Firmware-Buddy's M593 (M593.cpp): a D outside 0–1, a negative F, a T outside its types or
    an R not above 0 is skipped; F0 turns the axis off; any other change of an axis (D, F, T, R) turns
    it on from where it is, or, where it is off, from Buddy's defaults (:data:`PRUSA_AXIS_DEFAULTS`:
    it keeps nothing of an axis it turned off), the frequency clamped to ``freq_span`` (10–100 Hz)."""
    d, f = _within(p.get("D"), 0.0, 1.0), _within(p.get("F"), 0.0, math.inf)
    kind, r = _indexed(_PRUSA_TYPES, p.get("T")), _within(p.get("R"), 1e-300, math.inf)
    if all(v is None for v in (d, f, kind, r)):
        return
    for ax in _axes(p):
        if f == 0.0:
            cfg[f"shaper_{ax}"] = "none"
            continue
        base = PRUSA_AXIS_DEFAULTS[ax] if cfg[f"shaper_{ax}"] == "none" else _axis(cfg, ax)
        cfg[f"shaper_{ax}"], cfg[f"damping_{ax}"] = _or(kind, base[0]), _or(d, base[2])
        cfg[f"freq_{ax}"] = min(max(_or(f, base[1]), freq_span.lo), freq_span.hi)


def _within(word, lo: float, hi: float) -> float | None:
    """A command word's number where it lies in [lo, hi], else None (absent, or one the firmware skips)."""
    v = number_or_none(word)
    return v if v is not None and lo <= v <= hi else None


def _or(value, default):
    """``value``, or ``default`` where it is None."""
    return default if value is None else value


def _marlin_d_kept(p: dict) -> dict:
    """Marlin's M593 without a ``D`` outside 0–1, which it answers "?Zeta (D) value out of range"
    and skips, setting the rest of the command (M593.cpp)."""
    return p if "D" not in p or _within(p["D"], 0.0, 1.0) is not None else {k: v for k, v in p.items() if k != "D"}


def _m493(cfg: dict, p: dict) -> None:
    if number_or_none(p.get("S")) == 0:
        for ax in "xy":
            _set_axis(cfg, ax, "none", None, None)
        return
    if not any(k in p for k in "CAI"):
        return
    kind = _indexed(_FTM_MODES, p.get("C"))
    for ax in _axes(p):
        _set_axis(cfg, ax, kind, number_or_none(p.get("A")), number_or_none(p.get("I")))


def _rrf_m593(cfg: dict, p: dict, freq_span) -> None:
    """RepRapFirmware's M593, one shaper for all axes: P its type (none given, as in a Marlin job's
    ``M593 F30``: the type stays), F and S its frequency and damping; an F outside the firmware's
    range (``freq_span``; F0, Marlin's "off", among them) fails the whole command, which then changes
    nothing (AxisShaper::Configure's limited F)."""
    freq, damping = number_or_none(p.get("F")), number_or_none(p.get("S"))
    if freq is not None and not freq_span.lo <= freq <= freq_span.hi:
        return
    name = str(p.get("P", "")).strip().lower().replace("-", "").replace("_", "") or None
    for ax in "xy":
        _set_axis(cfg, ax, _RRF_NAMES.get(name, name), freq, damping)


_APPLY = {"SET_INPUT_SHAPER": _klipper, "M593": _m593, "M493": _m493}


def _settings(config: TuneConfig) -> dict:
    """The shaping fields of ``config`` as a command changes them, with the type each axis keeps
    while off (``kept_x``, ``kept_y``: its own, or Klipper's default where it is off)."""
    d = {k: getattr(config, k) for k in _SHAPING}
    for ax in "xy":
        d[f"kept_{ax}"] = KLIPPER_DEFAULT_TYPE if d[f"shaper_{ax}"] == "none" else d[f"shaper_{ax}"]
    return d


def _shaping(d: dict) -> dict:
    """``d`` without what only a command reads (the kept types)."""
    return {k: d[k] for k in _SHAPING}


def _apply(command: str, cfg: dict, params: dict, firmware: str) -> None:
    """Apply one shaper command to ``cfg`` (:func:`_settings`) as ``firmware`` reads it."""
    fw = FIRMWARES[firmware]
    if command == "M593" and fw.family == "rrf":
        _rrf_m593(cfg, params, fw.freq)
    elif command == "M593" and fw.family == "marlin":
        _m593(cfg, _marlin_d_kept(params))
    elif command == "M593" and fw.family == "prusa":
        _prusa_m593(cfg, params, fw.freq)
    else:
        _APPLY[command](cfg, params)


def shaper_timeline(events, config: TuneConfig) -> list[tuple[float, TuneConfig]]:
    """[(from time s, configuration)]: ``config`` from the start, then after each shaper event
    (planned, so with a ``time``) that ``config.firmware`` acts on (:data:`ACTED_ON`) the
    configuration its command leaves. A command that leaves the
    shaping as it was adds no step. Values the firmware would refuse are refused here too (the
    configuration's own check), naming the event's line."""
    return [(-math.inf, config)] + [(float(ev.time), nxt) for ev, nxt in _changes(events, config)]


def _changes(events, config: TuneConfig):
    """(event, the configuration it leaves) of each planned shaper event that changes the shaping,
    in order, from ``config`` (:func:`shaper_timeline`)."""
    cur, d = config, _settings(config)
    acts = acted_on(config.firmware)
    for ev in events:
        if ev.kind != "shaper" or ev.time is None or ev.command not in acts:
            continue
        before = dict(d)
        _apply(ev.command, d, ev.params, cur.firmware)
        try:
            nxt = replace(cur, **_shaping(d))
        except RingtuneError as exc:
            raise RingtuneError(f"{ev.command}: {exc.bare}", f"line {ev.line}") from None
        changed = any(_axis(d, ax) != _axis(before, ax) for ax in "xy")
        cur = nxt              # what an axis that is off stores travels on with it
        if changed:
            yield ev, nxt


def overriding(job, config: TuneConfig) -> list:
    """The shaper commands (events) of a parsed job (:class:`ringtune.shaping.job.Job`) that would
    move the printer off ``config``'s shaping for a move: each applied alone to ``config`` changes it
    (a command that sets what ``config`` sets, or nothing, is not one; nor is one after the job's
    last move, an end G-code's). The job rewriter puts ``config``'s own shaper command in their
    place, so ``config`` rules every move, as ``tune`` judges it; then none of the rest moves it either."""
    now = _settings(config)
    acts = acted_on(config.firmware)
    out = []
    for ev in job.events:
        if ev.kind != "shaper" or ev.command not in acts or ev.move >= job.n_moves:
            continue
        d = dict(now)
        _apply(ev.command, d, ev.params, config.firmware)
        if any(_axis(d, ax) != _axis(now, ax) for ax in "xy"):
            out.append(ev)
    return out



def _axis(d: dict, ax: str) -> tuple:
    """What shapes axis ``ax`` in settings ``d``: its shaper, frequency and damping, or off."""
    return ("none",) if d[f"shaper_{ax}"] == "none" else (d[f"shaper_{ax}"], d[f"freq_{ax}"], d[f"damping_{ax}"])


def config_at(timeline: list[tuple[float, TuneConfig]], t: float) -> TuneConfig:
    """The configuration in force at time ``t`` (s)."""
    cfg = timeline[0][1]
    for t0, c in timeline:
        if t0 <= t:
            cfg = c
    return cfg


def describe_timeline(timeline: list[tuple[float, TuneConfig]], events) -> str:
    """One sentence: how many shaper changes the job makes (at least one) and the first: the line
    that makes it (a command the firmware refuses changes nothing)."""
    n = len(timeline) - 1
    first, c = next(_changes(events, timeline[0][1]))
    axes = ", ".join(f"{ax.upper()} " + ("off" if getattr(c, f"shaper_{ax}") == "none" else
                                          f"{getattr(c, f'shaper_{ax}')} {getattr(c, f'freq_{ax}'):g} Hz")
                     for ax in "xy")
    return (f"the job's own shaper commands are applied as the firmware would ({n} change{'s' * (n != 1)}; "
            f"first at line {first.line}, {first.text or first.command}: {axes})")


def shape_timeline(motion: Motion, timeline: list[tuple[float, TuneConfig]]) -> Motion:
    """``motion`` shaped piece by piece: the moves between two changes with the shapers then in
    force, the pieces' displacements superposed (module docstring)."""
    bounds = [motion.start_time] + [t for t, _ in timeline[1:] if motion.start_time < t < motion.end_time]
    bounds.append(motion.end_time)
    parts = []
    for (lo, hi) in zip(bounds[:-1], bounds[1:]):
        if hi - lo <= 1e-12:
            continue
        piece = motion.window(lo, hi)
        shapers, centred = shapers_from_config(config_at(timeline, 0.5 * (lo + hi)))
        parts.append(shape_motion(piece, shapers, centred) if any(shapers.values()) else piece)
    if len(parts) == 1:
        return parts[0]
    return _superpose(parts)


def _superpose(parts: list[Motion]) -> Motion:
    """p0 + Σ (part − its start position): one Motion on the union of the parts' breakpoints."""
    t = np.unique(np.concatenate([m.t for m in parts]))
    starts, mids = t[:-1], 0.5 * (t[:-1] + t[1:])
    p = parts[0].start_position + sum(m.position(starts) - m.start_position for m in parts)
    v = sum(m.velocity(starts) for m in parts)
    a = sum(m.acceleration(mids) for m in parts)
    ext = np.zeros(len(starts), bool)
    move = np.full(len(starts), -1, np.int64)
    for m in parts:
        inside = (mids >= m.start_time) & (mids < m.end_time)
        idx = np.clip(m.segment_index(mids), 0, m.n_segments - 1)
        ext |= inside & m.extruding[idx]
        move = np.where(inside & (m.move[idx] >= 0), m.move[idx], move)
    return Motion(t, p, v, a, ext, move)
