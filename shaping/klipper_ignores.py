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

from ringtune.shaping.gcode_commands import number_or_none

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
    events = [ev for ev in job.events if ev.kind == "limits"]
    out: dict[str, list[int]] = {}
    for ev in events:
        what = ev.command if ev.command in KLIPPER_UNKNOWN else LONE_M204 if _lone_m204(ev) else None
        if what:
            out.setdefault(what, []).append(int(ev.line))
    lost = _unread_word_lost(events, limits, len(job.line))
    if lost:
        out[f"SET_VELOCITY_LIMIT {WORD_IGNORED[limits.accel_to_decel is not None]}"] = lost
    return out


def _unread_word_lost(events, limits, n_moves: int) -> list[int]:
    """The lines whose SET_VELOCITY_LIMIT word the printer's Klipper does not read loses something:
    where a move planned after that line, before the word's next line, meets the two ages' readings
    of the cruise rule differing (:class:`_Cruise`). ``n_moves``: the job's moves."""
    old = limits.accel_to_decel is not None
    word = WORD_IGNORED[old]
    cruise = _Cruise(limits.accel, limits.accel_to_decel if old else None, None if old else limits.min_cruise_ratio)
    ruled = [ev for ev in events if ev.command in ("SET_VELOCITY_LIMIT", "M204")]
    lost: list[int] = []
    line = None                                   # the word's latest line
    for ev, nxt in zip(ruled, [*ruled[1:], None]):
        if ev.command == "SET_VELOCITY_LIMIT" and word in ev.params:
            line = int(ev.line)
        cruise.take(ev)
        moves_follow = (nxt.move if nxt is not None else n_moves) > ev.move
        if line is not None and moves_follow and not cruise.agrees() and line not in lost:
            lost.append(line)
    return lost


class _Cruise:
    """Klipper's cruise rule as the job has set it so far, read both ways: the acceleration (mm/s²,
    ACCEL or M204), ACCEL_TO_DECEL (mm/s², what a Klipper from before 2024 reads) and
    MINIMUM_CRUISE_RATIO (what a current one reads); each the job's last word, else the printer's, None
    where the printer's age has no such setting and the job has not set it."""

    def __init__(self, accel: float, accel_to_decel: float | None, ratio: float | None):
        self.accel, self.accel_to_decel, self.ratio = float(accel), accel_to_decel, ratio

    def take(self, ev) -> None:
        """The acceleration and cruise words of ``ev`` (SET_VELOCITY_LIMIT or M204)."""
        p = ev.params
        words = ({"ACCEL": _m204_accel(p)} if ev.command == "M204" else
                 {k: number_or_none(p.get(k)) for k in ("ACCEL", "ACCEL_TO_DECEL", "MINIMUM_CRUISE_RATIO")})
        self.accel = words["ACCEL"] or self.accel
        for key, attr in (("ACCEL_TO_DECEL", "accel_to_decel"), ("MINIMUM_CRUISE_RATIO", "ratio")):
            if words.get(key) is not None:
                setattr(self, attr, words[key])

    def agrees(self) -> bool:
        """Whether both readings give the same hill: ACCEL_TO_DECEL (capped at the acceleration, as
        Klipper caps it) = the acceleration × (1 − MINIMUM_CRUISE_RATIO), to 1 mm/s² — Klipper's own
        rule between the two; true while either is unset (the printer's own rules)."""
        if self.accel_to_decel is None or self.ratio is None:
            return True
        return abs(min(self.accel_to_decel, self.accel) - self.accel * (1.0 - self.ratio)) <= 1.0


def _m204_accel(params: dict) -> float | None:
    """The acceleration (mm/s²) Klipper's M204 sets: S, else the lower of P and T where both are given."""
    accel = number_or_none(params.get("S"))
    if accel is None and {"P", "T"} <= set(params):
        accel = min(number_or_none(params["P"]) or 0.0, number_or_none(params["T"]) or 0.0) or None
    return accel


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
