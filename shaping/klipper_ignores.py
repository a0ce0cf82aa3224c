"""The limit commands of a job a Klipper (or Kalico) printer does not act on: Marlin's and RRF's
M201 (per-axis accelerations, the XY frequency limit), M203 (per-axis speeds), M205 (jerk, junction
deviation) and M566 (RRF's jerk), which Klipper does not have, and M204 without S or both P and T,
which it answers with "Invalid M204 command" (toolhead.py ``cmd_M204``) — what PrusaSlicer and
OrcaSlicer write, one per feature, for Marlin 2 or RRF; and the word of SET_VELOCITY_LIMIT its
version does not read: ACCEL_TO_DECEL since 2024 (what OrcaSlicer writes beside each ACCEL),
MINIMUM_CRUISE_RATIO before. The planner runs a job under Klipper's rule as Klipper would
(:func:`ringtune.shaping.lookahead.axis_caps`, :func:`ringtune.shaping.lookahead.klipper_smoothing`,
the job's M204 in :mod:`ringtune.shaping.gcode_commands`); this says so."""

from __future__ import annotations

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
    out: dict[str, list[int]] = {}
    old = limits.accel_to_decel is not None
    for ev in job.events if limits.reads_like_klipper else ():
        what = _ignored_as(ev, old)
        if what:
            out.setdefault(what, []).append(int(ev.line))
    return out


def _ignored_as(ev, old: bool) -> str | None:
    """How :func:`klipper_ignored` names a job event Klipper does not act on (None: it does)."""
    if ev.kind != "limits":
        return None
    if ev.command in KLIPPER_UNKNOWN:
        return ev.command
    if ev.command == "SET_VELOCITY_LIMIT":
        return _word_ignored(ev.params, old)
    return LONE_M204 if _lone_m204(ev) else None


def _word_ignored(params: dict, old: bool) -> str | None:
    """The SET_VELOCITY_LIMIT word among ``params`` that Klipper's version does not read, named;
    None where the line's other word says the same (:func:`_words_agree`)."""
    word = WORD_IGNORED[old]
    return f"SET_VELOCITY_LIMIT {word}" if word in params and not _words_agree(params) else None


def _words_agree(params: dict) -> bool:
    """Whether a SET_VELOCITY_LIMIT line's ACCEL_TO_DECEL is its ACCEL × (1 − its MINIMUM_CRUISE_RATIO)
    (to 1 mm/s²), Klipper's own rule between the two: a line written for Klippers of both ages (as
    ``ringtune rewrite`` writes it) runs the same on either, and the word one does not read loses
    nothing."""
    try:
        accel, atd, ratio = (float(params[k]) for k in ("ACCEL", "ACCEL_TO_DECEL", "MINIMUM_CRUISE_RATIO"))
    except (KeyError, TypeError, ValueError):
        return False
    return abs(atd - accel * (1.0 - ratio)) <= 1.0


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
