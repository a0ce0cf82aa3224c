"""The limit commands of a job a Klipper (or Kalico) printer does not act on: Marlin's and RRF's
M201 (per-axis accelerations, the XY frequency limit), M203 (per-axis speeds), M205 (jerk, junction
deviation) and M566 (RRF's jerk), which Klipper does not have, and M204 without S or both P and T,
which it answers with "Invalid M204 command" (toolhead.py ``cmd_M204``) — what PrusaSlicer and
OrcaSlicer write, one per feature, for Marlin 2 or RRF. The planner runs a job under Klipper's rule
as Klipper would (:func:`ringtune.shaping.lookahead.axis_caps`, the job's M204 in
:mod:`ringtune.shaping.gcode_commands`); this says so."""

from __future__ import annotations

#: Marlin and RRF limit commands Klipper has no handler for
KLIPPER_UNKNOWN = ("M201", "M203", "M205", "M566")
#: how a lone M204 is named
LONE_M204 = "M204 without S or both P and T"


def klipper_ignored(job, junction: str) -> dict[str, list[int]]:
    """{command: the job's line numbers, in order} of its limit commands Klipper does not act on
    (a parsed :class:`ringtune.shaping.job.Job`) where it is planned under Klipper's corner rule
    (``junction`` ``scv``); empty under any other rule."""
    out: dict[str, list[int]] = {}
    for ev in job.events if junction == "scv" else ():
        what = _ignored_as(ev)
        if what:
            out.setdefault(what, []).append(int(ev.line))
    return out


def _ignored_as(ev) -> str | None:
    """How :func:`klipper_ignored` names a job event Klipper does not act on (None: it does)."""
    if ev.kind != "limits":
        return None
    if ev.command in KLIPPER_UNKNOWN:
        return ev.command
    lone = ev.command == "M204" and "S" not in ev.params and not {"P", "T"} <= set(ev.params)
    return LONE_M204 if lone else None


def klipper_ignored_note(ignored: dict[str, list[int]]) -> str | None:
    """One sentence on ``ignored``, what :func:`klipper_ignored` found (None: nothing)."""
    if not ignored:
        return None
    n = sum(len(lines) for lines in ignored.values())
    parts = ", ".join(f"{what} ×{len(lines)} (first on line {lines[0]})" for what, lines in ignored.items())
    return (f"Klipper does not act on {n} of the job's limit lines — {parts}: it has no M201, M203, M205 or "
            "M566, and answers an M204 without S or both P and T with \"Invalid M204 command\"; planned as "
            "Klipper runs the file (sliced for Marlin 2 or RRF? slice it for Klipper, or `ringtune rewrite` "
            "writes the accelerations in Klipper's own SET_VELOCITY_LIMIT)")
