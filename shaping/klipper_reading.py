"""Where Klipper comes to rest and waits otherwise than a job's commands read everywhere: it has no
Marlin shaper commands (M593, M493), nor G29, M0, M1 or M600 unless a macro of the printer.cfg
defines them, so the head does not stop there (an unknown command is answered and the look-ahead
runs on); its G4 takes P (ms) alone (``toolhead.py`` ``cmd_G4``), so an S word waits nothing. Its
M84/M18 turns the motors off whatever the words (an S word is Marlin's idle timeout): it comes to
rest and, where a motor is on (one has moved, or G28 homed, since the job began or the last M84),
dwells 0.1 s before turning them off and 0.1 s after (``stepper_enable.py``, DISABLE_STALL_TIME) and
flushes its steps (:data:`MOTORS_OFF_DWELL`); at the job's start the motors are taken as off (a
printer idle since its last job). The planner, reading a job as Klipper does, plans with
:func:`klipper_rests`."""

from __future__ import annotations

import numpy as np

from ringtune.shaping.job import MOTORS_OFF

#: commands the reader stops at that Klipper does not have
KLIPPER_NO_STOP = frozenset({"M593", "M493", "G29", "M0", "M1", "M600"})
#: s an M84/M18 that turns a motor off adds: DISABLE_STALL_TIME (0.1 s) before and after, and the step
#: flush it makes, twice the kinematic flush delay (SDS_CHECK_TIME, 1 ms; an input shaper's or pressure
#: advance's scan window lengthens it by up to tens of ms, not modelled)
MOTORS_OFF_DWELL = 2 * 0.100 + 2 * 0.001


def klipper_rests(job) -> tuple[np.ndarray, np.ndarray, float]:
    """(stop_before, dwell_before, dwell_after) of ``job`` as Klipper runs it: no rest where only
    commands of :data:`KLIPPER_NO_STOP` stopped the head, no wait for a G4's S word, a rest and
    :data:`MOTORS_OFF_DWELL` at each M84/M18 that finds a motor on (worked out once per job: the
    study plans one job many times)."""
    cached = getattr(job, "_klipper_rests", None)
    if cached is None:
        cached = _rests(job)
        job._klipper_rests = cached        # type: ignore[attr-defined]
    return cached


def _rests(job) -> tuple[np.ndarray, np.ndarray, float]:
    n = job.n_moves
    stop = _unknown_unstopped(job, job.stop_before)
    off = [ev.move for ev in job.events if ev.command in MOTORS_OFF and 0 < ev.move < n]
    if off:
        stop = stop.copy()
        stop[off] = True                                    # an S word too
    dwell, after = job.dwell_before.copy(), job.dwell_after
    for move, s in _waits(job):
        if move < n:
            dwell[move] += s
        else:
            after += s
    return stop, dwell, after


def _waits(job) -> list[tuple[int, float]]:
    """(move, s) Klipper waits before ``move`` beyond the reader's dwells: a G4's P where it gives S
    too (the reader took S), and :data:`MOTORS_OFF_DWELL` at each M84/M18 that finds a motor on."""
    g4 = [(ev.move, ev.params["p_seconds"] - ev.params["seconds"]) for ev in job.events
          if ev.kind == "dwell" and ev.params["seconds"] != ev.params["p_seconds"]]
    return g4 + [(m, MOTORS_OFF_DWELL) for m in _motors_on_at(job)]


def _unknown_unstopped(job, stop: np.ndarray) -> np.ndarray:
    """``stop`` without the rests only commands of :data:`KLIPPER_NO_STOP` made."""
    n = job.n_moves
    unknown = {ev.move for ev in job.events if ev.command in KLIPPER_NO_STOP and 0 < ev.move < n}
    unknown -= {ev.move for ev in job.events if ev.move in unknown and _stops(ev)}   # another stops there
    if not unknown:
        return stop
    stop = stop.copy()
    stop[list(unknown)] = False
    return stop


def _motors_on_at(job) -> list[int]:
    """The moves (indices) before which an M84/M18 finds a motor on: a move (E alone included) or a
    G28 since the job began or the previous one (the job's events are in file order)."""
    out, on, done = [], False, 0
    for ev in job.events:
        if ev.move > done:
            on, done = True, ev.move
        if ev.command == "G28":
            on = True
        elif ev.command in MOTORS_OFF:
            if on:
                out.append(ev.move)
            on = False
    return out


def _stops(ev) -> bool:
    """Whether the command of ``ev`` brings Klipper to rest (a dwell, a wait, homing, a shaper change,
    a firmware retraction; not one of :data:`KLIPPER_NO_STOP`)."""
    return ev.command not in KLIPPER_NO_STOP and (ev.kind in ("dwell", "shaper") or ev.command in _REST)


#: commands of Klipper's own the reader stops at besides dwells and shaper changes
_REST = frozenset({"G28", "M400", "M109", "M190", "G10", "G11", *MOTORS_OFF})
