"""The limit commands of a job a Klipper (or Kalico) printer does not act on: Marlin's and RRF's
M201 (per-axis accelerations, the XY frequency limit), M203 (per-axis speeds), M205 (jerk, junction
deviation) and M566 (RRF's jerk), which Klipper does not have, and M204 without S or both P and T,
which it answers with "Invalid M204 command" (toolhead.py ``cmd_M204``) — what PrusaSlicer and
OrcaSlicer write, one per feature, for Marlin 2 or RRF; and the word of SET_VELOCITY_LIMIT its
version does not read: ACCEL_TO_DECEL since 2024 (what OrcaSlicer writes beside each ACCEL),
MINIMUM_CRUISE_RATIO before, unless what is then in effect agrees with it (ACCEL_TO_DECEL = the
acceleration × (1 − MINIMUM_CRUISE_RATIO): a line written for Klippers of both ages, as ``ringtune
rewrite`` writes it, loses nothing on either). The planner runs a job under Klipper's rule as Klipper would
(:func:`ringtune.shaping.lookahead.axis_caps`, :func:`ringtune.shaping.lookahead.klipper_smoothing`,
the job's M204 in :mod:`ringtune.shaping.gcode_commands`); this says so."""

from __future__ import annotations

import numpy as np

#: Marlin and RRF limit commands Klipper has no handler for
KLIPPER_UNKNOWN = ("M201", "M203", "M205", "M566")
#: how a lone M204 is named
LONE_M204 = "M204 without S or both P and T"
#: the SET_VELOCITY_LIMIT word a current Klipper ignores, and the one a Klipper from before 2024 does
WORD_IGNORED = {False: "ACCEL_TO_DECEL", True: "MINIMUM_CRUISE_RATIO"}


def klipper_ignored(job, limits) -> dict[str, list[int]]:
    """{command: the job's line numbers, in order} of its limit commands Klipper does not act on
    (a parsed :class:`ringtune.shaping.job.Job`) where it is planned under Klipper's corner rule
    (``limits``, the :class:`ringtune.shaping.planner.MachineLimits` it is planned with: junction
    ``scv``; ``accel_to_decel`` set: a Klipper from before 2024); empty under any other rule."""
    if not limits.reads_like_klipper:
        return {}
    out: dict[str, list[int]] = {}
    for ev in (ev for ev in job.events if ev.kind == "limits"):
        what = ev.command if ev.command in KLIPPER_UNKNOWN else LONE_M204 if _lone_m204(ev) else None
        if what:
            out.setdefault(what, []).append(int(ev.line))
    lost = _unread_word_lost(job, limits)
    if lost:
        out[f"SET_VELOCITY_LIMIT {WORD_IGNORED[limits.accel_to_decel is not None]}"] = lost
    return out


def _unread_word_lost(job, limits) -> list[int]:
    """The lines whose SET_VELOCITY_LIMIT word the printer's Klipper does not read loses something:
    where a move it governs (before the word's next line) meets the two ages' readings of the cruise
    rule differing. Each reading at a move is what the reader holds in force there (the job's last
    ACCEL or M204, ACCEL_TO_DECEL, MINIMUM_CRUISE_RATIO), else the printer's; they agree where
    ACCEL_TO_DECEL, capped at the acceleration as Klipper caps it, is the acceleration × (1 −
    MINIMUM_CRUISE_RATIO) to 1 mm/s² (Klipper's own rule between the two), or while either is unset."""
    old = limits.accel_to_decel is not None
    word = WORD_IGNORED[old]
    said = [ev for ev in job.events if ev.command == "SET_VELOCITY_LIMIT" and word in ev.params]
    if not said or not job.n_moves:
        return []
    accel = _in_force(job, "accel_klipper", limits.accel)
    atd = _in_force(job, "accel_to_decel", limits.accel_to_decel if old else np.nan)
    ratio = _in_force(job, "min_cruise_ratio", np.nan if old else limits.min_cruise_ratio)
    differ = np.abs(np.minimum(atd, accel) - accel * (1.0 - ratio)) > 1.0      # False where either is NaN
    governing = np.searchsorted([ev.move for ev in said], np.arange(job.n_moves), side="right") - 1
    return [int(said[i].line) for i in np.unique(governing[differ & (governing >= 0)])]


def _in_force(job, key: str, printer_value) -> np.ndarray:
    """(n,) the setting in force at each move, the printer's where the job has not set it."""
    v = job.setting(key)
    return np.where(np.isnan(v), np.nan if printer_value is None else float(printer_value), v)


def _lone_m204(ev) -> bool:
    """An M204 without S or both P and T (Klipper: "Invalid M204 command")."""
    return ev.command == "M204" and "S" not in ev.params and not {"P", "T"} <= set(ev.params)


#: why Klipper does not act on each kind of line (``"M2xx"``: Marlin's and RRF's lines)
WHY = {"M2xx": "it has no M201, M203, M205 or M566, and answers an M204 without S or both P and T with \"Invalid "
               "M204 command\" (sliced for Marlin 2 or RRF? slice it for Klipper, or `ringtune rewrite` writes the "
               "accelerations in Klipper's own SET_VELOCITY_LIMIT)",
       f"SET_VELOCITY_LIMIT {WORD_IGNORED[False]}": "since 2024 it reads no ACCEL_TO_DECEL: its minimum_cruise_ratio "
               "rules (a Klipper from before then: [limits] accel_to_decel, its max_accel_to_decel, in the printer "
               "description)",
       f"SET_VELOCITY_LIMIT {WORD_IGNORED[True]}": "this Klipper, from before 2024 ([limits] accel_to_decel), has no "
               "MINIMUM_CRUISE_RATIO"}


def klipper_ignored_note(ignored: dict[str, list[int]]) -> str | None:
    """One sentence on ``ignored``, what :func:`klipper_ignored` found (None: nothing)."""
    if not ignored:
        return None
    n = sum(len(lines) for lines in ignored.values())
    parts = ", ".join(f"{what} ×{len(lines)} (first on line {lines[0]})" for what, lines in ignored.items())
    kinds = {what if what in WHY else "M2xx" for what in ignored}
    why = "; ".join(text for kind, text in WHY.items() if kind in kinds)
    return f"Klipper does not act on {n} of the job's limit lines or words — {parts}: {why}; planned as Klipper runs the file"
