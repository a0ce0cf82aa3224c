"""The job's own shaper commands, applied as the firmware applies them: a timeline of shaper settings.

A job may set input shaping itself: a ringing test print turns it off (``M593 X F0``,
``SET_INPUT_SHAPER SHAPER_FREQ_X=0``), a tower changes the frequency band by band. Each command
changes the settings it names, for the moves after it; the reader stops the planner there
(``stop_before``), and the plan keeps the stop where the firmware waits for the motion to end
(:func:`stops_for`); each firmware's command read as that firmware reads it
(:mod:`ringtune.shaping.shaper_commands`). A command that changes only what an axis that is off
keeps is no step: the shaping is the same.

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
from ringtune.shaping.shaper_commands import READERS, apply_command, axis_of, settings_of, shaping_of
from ringtune.shaping.shapers import shapers_from_config

#: the shaper commands each firmware family acts on; it does not have a job's others (Klipper
#: answers "Unknown command" to an M593, Marlin to a SET_INPUT_SHAPER)
ACTED_ON = {family: tuple(c for c, f in READERS if f == family) for _c, family in READERS}


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
    cur, d = config, settings_of(config)
    acts = acted_on(config.firmware)
    for ev in events:
        if ev.kind != "shaper" or ev.time is None or ev.command not in acts:
            continue
        before = dict(d)
        _named(ev, apply_command, ev.command, d, ev.params, cur.firmware)
        nxt = _named(ev, replace, cur, **shaping_of(d))
        changed = any(axis_of(d, ax) != axis_of(before, ax) for ax in "xy")
        cur = nxt              # what an axis that is off stores travels on with it
        if changed:
            yield ev, nxt


def _named(ev, fn, *args, **kwargs):
    """``fn(*args, **kwargs)``; a :class:`RingtuneError` it raises names the event's command and line
    (a value the firmware refuses, as the configuration's own check refuses it)."""
    try:
        return fn(*args, **kwargs)
    except RingtuneError as exc:
        raise RingtuneError(f"{ev.command}: {exc.bare}", f"line {ev.line}") from None


def overriding(job, config: TuneConfig) -> list:
    """The shaper commands (events) of a parsed job (:class:`ringtune.shaping.job.Job`) that would
    move the printer off ``config``'s shaping for a move: each applied alone to ``config`` changes it
    (a command that sets what ``config`` sets, or nothing, is not one; nor is one after the job's
    last move, an end G-code's). The job rewriter puts ``config``'s own shaper command in their
    place, so ``config`` rules every move, as ``tune`` judges it; then none of the rest moves it either."""
    now = settings_of(config)
    acts = acted_on(config.firmware)
    out = []
    for ev in job.events:
        if ev.kind != "shaper" or ev.command not in acts or ev.move >= job.n_moves:
            continue
        d = dict(now)
        _named(ev, apply_command, ev.command, d, ev.params, config.firmware)
        if any(axis_of(d, ax) != axis_of(now, ax) for ax in "xy"):
            out.append(ev)
    return out



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
