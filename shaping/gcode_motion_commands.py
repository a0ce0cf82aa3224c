"""Motion and position commands of the G-code reader besides G0/G1 (mixin of its reader class):
``G2/G3`` arcs (split into chords, :mod:`ringtune.shaping.arcs`), ``G4`` dwell, ``G92`` set
position and ``G28`` home. Units: mm, mm/s, s."""

from __future__ import annotations

import math

from ringtune.shaping.arcs import arc_chords
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.job import AXES


class MotionCommands:
    """Mixin: needs ``_where``, ``_emit``, ``_event``, ``pos``, ``offset``, ``abs_xyz``, ``abs_e``,
    ``feed``, ``unit``, ``tol``, ``stop`` and ``dwell`` attributes of the reader; ``_HANDLERS`` maps
    these commands to their handlers."""

    def _target(self, words: dict[str, float]) -> list[float]:
        end = list(self.pos)
        absolute = (self.abs_xyz, self.abs_xyz, self.abs_xyz, self.abs_e)
        for i, ax in enumerate("XYZE"):
            if ax in words:
                end[i] = words[ax] + self.offset[i] if absolute[i] else self.pos[i] + words[ax]
        return end

    def _feedrate(self, words: dict[str, float], where: str) -> None:
        if "F" in words:
            f = words["F"]
            if f <= 0:
                raise RingtuneError(f"feedrate F{f:g} must be > 0", where)
            self.feed = f / 60.0

    def _arc_command(self, cmd: str, words: dict, lineno: int, code: str) -> None:
        self._arc(cmd == "G2", _finite(words, self._where(lineno)), lineno)

    def _dwell(self, cmd: str, words: dict, lineno: int, code: str) -> None:
        """G4 P<ms> or S<s>: a pause (the planner stops there); S rules where both are given, as in
        Marlin (``G4()``: S read after P) and RRF; ``p_seconds`` what Klipper, which reads P alone, waits."""
        p = words.get("P", 0.0) / 1000.0
        t = words["S"] if "S" in words else p
        if not t >= 0 or not math.isfinite(t):
            raise RingtuneError("dwell time must be >= 0", self._where(lineno))
        self.dwell += t
        self.stop = True
        self._event("dwell", cmd, {"seconds": t, "p_seconds": p}, lineno, code)

    def _set_position(self, cmd: str, words: dict, lineno: int, code: str) -> None:
        """G92: the named axes (all without words) read the given value (NaN: 0) from here on."""
        if not words:
            words = {a: 0.0 for a in AXES}
        for i, ax in enumerate(AXES):
            if ax in words:
                v = 0.0 if math.isnan(words[ax]) else words[ax] * self.unit
                self.offset[i] = self.pos[i] - v
        xy = tuple(i for i in (0, 1) if AXES[i] in words)
        if xy:                                    # a G92 E0 (each layer, each retraction) leaves X/Y as they are
            self.position_events.append((lineno, "set", xy))

    def _home(self, cmd: str, words: dict, lineno: int, code: str) -> None:
        """G28: the named axes (all without words) to 0, offsets cleared; the planner stops."""
        named = [i for i, ax in enumerate("XYZ") if ax in words]
        self.pos = list(self.pos)
        for i in named or (0, 1, 2):
            self.pos[i] = 0.0
            self.offset[i] = 0.0
        self.position_events.append((lineno, "home", tuple(i for i in (named or (0, 1, 2)) if i < 2)))
        self.stop = True
        self._event("other", cmd, words, lineno, code)

    #: classic commands with their own handler (moves, modes and the rest aside)
    _HANDLERS = {"G2": _arc_command, "G3": _arc_command, "G4": _dwell, "G92": _set_position, "G28": _home}

    def _arc(self, clockwise: bool, w: dict[str, float], lineno: int) -> None:
        where = self._where(lineno)
        if self.unit != 1.0:
            w = {k: v * self.unit if k in "XYZEIJRF" else v for k, v in w.items()}
        self._feedrate(w, where)
        end = self._target(w)
        self.n_arcs += 1
        if "R" in w or not self.abs_xyz:          # what Klipper's gcode_arcs refuses
            self.refused_arcs.append(lineno)
        for point in arc_chords(clockwise, w, list(self.pos), end, self.tol, where, self.resolution,
                                self.feed, self.speed_factor):
            self._emit(point, lineno, arc=True)


def _finite(words: dict[str, float], where: str) -> dict[str, float]:
    for k, v in words.items():
        if math.isnan(v):
            raise RingtuneError(f"{k} needs a value", where)
    return words
