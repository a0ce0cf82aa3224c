"""The parsed job: straight moves in machine coordinates plus the settings and events around them
(units mm, mm/s, s). Produced by :func:`ringtune.shaping.gcode.read_gcode`, consumed by the planner
and the frequency limit."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

#: Setting keys a job can change (NaN = never set in the file; the planner then uses the machine's).
#: ``max_accel_*``/``max_vel_*`` are Marlin's and RRF's M201/M203, which Klipper does not have;
#: ``limited_accel_x``/``y`` Kalico's SET_VELOCITY_LIMIT X_ACCEL/Y_ACCEL (its limited kinematics);
#: ``jerk_*`` what M205 X… and RRF's M566 set (RRF has both), ``m205_jerk_*`` what M205 alone sets
#: (Marlin and Prusa have no M566).
SETTING_KEYS = (
    "accel_print", "accel_travel", "accel_retract", "accel_klipper", "accel_to_decel",
    "max_accel_x", "max_accel_y", "max_accel_z", "max_accel_e",
    "max_vel_x", "max_vel_y", "max_vel_z", "max_vel_e",
    "limited_accel_x", "limited_accel_y",
    "jerk_x", "jerk_y", "jerk_z", "jerk_e", "m205_jerk_x", "m205_jerk_y", "m205_jerk_z", "m205_jerk_e",
    "junction_deviation", "square_corner_velocity", "velocity", "min_cruise_ratio",
    "freq_limit_hz", "freq_limit_min_factor",
)
SHAPER_COMMANDS = ("M593", "M493", "SET_INPUT_SHAPER")
LIMIT_COMMANDS = ("M201", "M203", "M204", "M205", "M220", "M566", "SET_VELOCITY_LIMIT")
STOP_COMMANDS = {"G4", "G28", "G29", "M400", "M109", "M190", "M0", "M1", "M600", *SHAPER_COMMANDS}
#: motors off: every firmware drains its queue first (Marlin's and RRF's M84 S… only sets the idle
#: timeout and does not; Klipper reads no word of it)
MOTORS_OFF = ("M84", "M18")
AXES = "XYZE"


@dataclass
class Event:
    """A non-motion command in the job.

    kind: ``shaper`` (M593/M493/SET_INPUT_SHAPER), ``limits`` (M201/M203/M204/M205/M220/
    SET_VELOCITY_LIMIT), ``dwell`` (G4), ``other`` (anything else, kept as it is).
    move: index of the first move after the command (== number of moves before it).
    time: s since the job start; None until the planner fills it in.
    """

    kind: str
    command: str
    params: dict
    line: int
    move: int
    text: str = ""
    time: float | None = None


@dataclass(frozen=True)
class FirmwareRetractionAt:
    """A ``G10``/``G11`` that moves the extruder by the printer's own settings (see
    :mod:`ringtune.shaping.firmware_retraction`), where the reader met it: ``move`` the index of the
    first move after it, ``command``, ``line``, ``feature`` and ``settings`` (indices, as a move's)
    in force there, ``speed_factor`` the M220 factor then, ``alone`` whether only firmware
    retractions stop the head before that move."""

    move: int
    command: str
    line: int
    feature: int
    settings: int
    speed_factor: float
    alone: bool = True


@dataclass
class Job:
    """A parsed job: straight moves in machine coordinates (mm) and what surrounds them.

    Move arrays (n moves): ``line`` source line (1-based), ``start``/``end`` (n, 4) x y z e,
    ``feed`` requested speed (mm/s, M220 applied), ``feature`` index into ``features``,
    ``settings`` index into ``settings_table`` (rows of :data:`SETTING_KEYS`, NaN = unset),
    ``stop_before`` the firmware is at rest before this move, ``dwell_before`` s of dwell before it,
    ``arc`` the move is a chord of a G2/G3 arc. ``limited``: the frequency limit the file's F
    words already carry, from the header ``ringtune limit`` writes in its first lines (None: none).
    ``fw_retractions``: :class:`FirmwareRetractionAt` of each G10/G11 that moves the extruder.
    """

    line: np.ndarray
    start: np.ndarray
    end: np.ndarray
    feed: np.ndarray
    feature: np.ndarray
    settings: np.ndarray
    stop_before: np.ndarray
    dwell_before: np.ndarray
    arc: np.ndarray
    features: list[str]
    settings_table: np.ndarray
    events: list[Event] = field(default_factory=list)
    dwell_after: float = 0.0
    source: str = "<text>"
    n_lines: int = 0
    arc_tolerance: float = 0.01
    limited: tuple | None = None      # (Hz, method, min speed factor) of a ``ringtune limit`` header
    #: (line, kind, axes) of what makes the reader's X/Y position the firmware's or not, in file order:
    #: ``home`` (G28: the firmware is at its endstop, the reader at 0), ``set`` (G92), ``abs`` / ``rel``
    #: (G90 / G91); axes: indices 0 (X) and 1 (Y) it names (:func:`ringtune.shaping.klipper_refusals.known_xy`)
    position_events: list = field(default_factory=list)
    #: the firmware retractions that move E, in file order; the planner adds their E-only moves
    #: where the retraction settings are known (:func:`ringtune.shaping.firmware_retraction.with_firmware_retractions`)
    fw_retractions: list = field(default_factory=list)
    #: (n,) the E-only moves of firmware retractions put in for planning (None: none; the planner folds
    #: them into the rest before the next move: :func:`ringtune.shaping.firmware_retraction.fold_retractions`)
    fw_inserted: np.ndarray | None = None
    #: (number of G2/G3 arcs, the firmware's segments they were cut into — Klipper's resolution, mm, or
    #: a MarlinArcs or DeviationArcs rule — or None: tolerance chords, the lines of those Klipper
    #: refuses: given by R or in relative mode)
    arcs: tuple = (0, None, ())

    @property
    def n_moves(self) -> int:
        return len(self.line)

    @property
    def delta(self) -> np.ndarray:
        return self.end - self.start

    @property
    def extruding(self) -> np.ndarray:
        """(n,) moves that deposit material: E increases while X/Y move."""
        d = self.delta
        return (d[:, 3] > 0) & (np.hypot(d[:, 0], d[:, 1]) > 0)

    def setting(self, key: str) -> np.ndarray:
        """(n,) value of a setting in force at each move (NaN where the file never set it)."""
        col = SETTING_KEYS.index(key)
        return self.settings_table[self.settings, col]

    def sets(self, keys) -> bool:
        """Whether the file sets any of the settings ``keys`` anywhere."""
        table = np.asarray(self.settings_table)
        return bool(self.n_moves) and bool(np.any(~np.isnan(table[:, [SETTING_KEYS.index(k) for k in keys]])))

    def file_setting(self, key: str) -> float:
        """The first value the file set for ``key`` (NaN if never)."""
        col = self.settings_table[:, SETTING_KEYS.index(key)]
        ok = col[~np.isnan(col)]
        return float(ok[0]) if len(ok) else math.nan

    def with_feed(self, feed: np.ndarray) -> "Job":
        """A copy with other requested speeds (mm/s)."""
        return replace(self, feed=np.asarray(feed, float).copy())

    def shaper_events(self) -> list[Event]:
        return [e for e in self.events if e.kind == "shaper"]
