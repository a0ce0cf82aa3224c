"""Streaming G-code reader: turns a job into arrays of straight moves plus the settings and events
a firmware would see on the way (units mm, mm/s, mm/s², s).

Understood: ``G0/G1`` (X Y Z E F), ``G2/G3`` arcs (I J or R; split into chords that deviate from the
arc by at most ``arc_tolerance`` mm, Z and E interpolated along), ``G4`` (P ms / S s), ``G90/G91``,
``M82/M83``, ``G20/G21`` (inches/mm), ``G92``, ``G28`` (the named axes, or all, go to 0 — homing takes no time here),
``M201`` (X Y Z E max accel; F S = Marlin XY frequency limit), ``M203`` (max feedrates), ``M204``
(P print, T travel, R retract, S both), ``M205`` (X Y Z E jerk, J junction deviation), ``M220 S``
(speed factor %), Klipper's ``SET_VELOCITY_LIMIT`` (VELOCITY, ACCEL, SQUARE_CORNER_VELOCITY,
ACCEL_TO_DECEL, MINIMUM_CRUISE_RATIO) and ``TUNING_TOWER`` (the command is re-run, as Klipper does,
whenever an extrusion move at a new height changes the value). Shaper changes (``M593``, ``M493``, ``SET_INPUT_SHAPER``)
become events with the index of the move that follows them. Line numbers ``N..`` and checksums
``*..`` are accepted (an XOR checksum that does not match is an error). Every other command is kept
as an event of kind ``other`` (never an error). Slicer feature comments (``;TYPE:``,
``;FEATURE:``, Simplify3D ``; feature ...``) tag the moves after them.

G90/G91 set XYZ and E together as Marlin and RRF do (Klipper's G90 leaves an M83 in force; slicers
write M82/M83 after G90, so real jobs read the same). Commands that make a firmware drain its
queue (``G4``, ``G28``, ``G29``, ``M400``, ``M109``, ``M190``, ``M0/M1``, ``M600``, shaper changes,
``M84``/``M18`` without S) and a firmware retraction (``G10``/``G11`` without P or L that retracts
or restores: an E-only move) set ``stop_before`` on the next move: the planner comes to rest there.

The commands' handlers are mixins of the reader: settings and firmware extensions in
:mod:`ringtune.shaping.gcode_commands`, arcs, dwells, G92 and G28 in
:mod:`ringtune.shaping.gcode_motion_commands`.

Own code rather than a library: the maintained pure-Python parser (gcodeparser) drops Klipper's
extended commands and is slower than this reader's one-regex-per-line path.
"""

from __future__ import annotations

import io
import math
import operator
import re
from functools import reduce
from pathlib import Path
from typing import Iterable

import numpy as np

from ringtune.shaping.bgcode import is_bgcode
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.firmware_retraction import RetractionState
from ringtune.shaping.gcode_file import open_lines, read_gcode_bytes, read_head, refuse_non_gcode
from ringtune.shaping.gcode_sniff import HEAD
from ringtune.shaping.job import (LIMIT_COMMANDS, MOTORS_OFF, SETTING_KEYS, SHAPER_COMMANDS, STOP_COMMANDS,
                                  Event, FirmwareRetractionAt, Job)
from ringtune.shaping.gcode_commands import BOUNDS as _BOUNDS
from ringtune.shaping.gcode_commands import SettingCommands
from ringtune.shaping.gcode_commands import num as _num
from ringtune.shaping.gcode_motion_commands import MotionCommands


_WORD = re.compile(r"([A-Za-z])\s*([^A-Za-z\s]*)")
#: commands whose argument is free text (a message, a file name)
TEXT_COMMANDS = ("M117", "M118", "M23", "M28", "M30", "M32")
#: commands that only set the reader's modes: command -> {attribute: value}
MODE_COMMANDS = {"G20": {"unit": 25.4}, "G21": {"unit": 1.0}, "G90": {"abs_xyz": True, "abs_e": True},
                 "G91": {"abs_xyz": False, "abs_e": False}, "M82": {"abs_e": True}, "M83": {"abs_e": False}}
_CLASSIC = re.compile(r"^([GMTgmt])\s*(\d+(?:\.\d+)?)")
_QUOTED = re.compile(r'([A-Za-z])\s*"([^"]*)"')     # RepRapFirmware string parameters: P"mzv"
#: the header ``ringtune limit`` writes: the file's F words already carry that frequency limit
_LIMITED = re.compile(r"^\s*ringtune limit: method=(\w+) freq_limit=([\d.eE+-]+) Hz min_speed_factor=([\d.eE+-]+)")
_FEATURE = re.compile(r"^\s*(?:TYPE|FEATURE)\s*:\s*(.+?)\s*$|^\s*feature\s+(.+?)\s*$", re.IGNORECASE)

_AXIS_INDEX = {"X": 0, "Y": 1, "Z": 2, "E": 3}
#: G0/G1 word letter -> (largest magnitude, 0-3 axis x y z e | 4 feedrate | -1 other)
_WORD_INFO = {**{k: (_BOUNDS[k], i) for k, i in _AXIS_INDEX.items()}, "F": (_BOUNDS["F"], 4)}
_WORD_INFO.update({k.lower(): v for k, v in list(_WORD_INFO.items())})
_OTHER_WORD = (1e9, -1)
_CHUNK = 1 << 16          # moves collected in Python lists before they go into numpy arrays


def checksum(data: bytes) -> int:
    """The RepRap checksum of a line's bytes before its ``*``: the XOR of them all."""
    return reduce(operator.xor, data, 0)


def _strip_line_number(code: str, where: str) -> str:
    """Remove a leading ``N<n>`` and a trailing ``*<checksum>`` (verifying XOR checksums)."""
    if not code or code[0] not in "Nn":
        if "*" in code:
            code = code[:code.rindex("*")].rstrip()
        return code
    star = code.rfind("*")
    if star >= 0:
        cs = code[star + 1:].strip()
        if not cs.isdigit():
            raise RingtuneError(f"checksum {cs!r} is not a number", where)
        if len(cs) <= 3:
            x = checksum(code[:star].encode("latin-1", "replace"))
            if x != int(cs):
                raise RingtuneError(f"checksum mismatch: line says {cs}, XOR of the line is {x}", where)
        code = code[:star]
    m = re.match(r"[Nn]\s*(-?\d+)\s*", code)
    if not m:
        raise RingtuneError("line number N must be an integer", where)
    return code[m.end():]


class _Reader(SettingCommands, MotionCommands):
    """State machine of one job being read."""

    def __init__(self, source: str, arc_tolerance: float, arc_resolution=None):
        if not arc_tolerance > 0:
            raise RingtuneError(f"arc tolerance must be > 0 mm, not {arc_tolerance}", "arc_tolerance")
        self.source = source
        self.tol = arc_tolerance
        self.resolution = arc_resolution        # the firmware's segments (arcs.arc_resolution; None: tolerance chords)
        self.n_arcs = 0
        self.refused_arcs: list[int] = []        # lines of arcs Klipper refuses (by R, or in relative mode)
        self.position_events: list[tuple] = []    # Job.position_events
        self.pos = [0.0, 0.0, 0.0, 0.0]         # machine position x y z e
        self.offset = [0.0, 0.0, 0.0, 0.0]      # logical = machine - offset
        self.abs_xyz = True
        self.abs_e = True
        self.feed = 25.0                        # mm/s (F1500)
        self.unit = 1.0                         # mm per G-code length unit (G20 inches: 25.4)
        self.speed_factor = 1.0
        self.features = ["unknown"]
        self.feature_idx = {"unknown": 0}
        self.cur_feature = 0
        self.settings = dict.fromkeys(SETTING_KEYS, math.nan)
        self.settings_rows = [tuple(self.settings.values())]
        self.settings_dirty = False
        self.stop = True
        self.dwell = 0.0
        self.retraction = RetractionState()     # a firmware retraction moves E only when it changes it
        self.fw_pending: list[tuple] = []       # firmware retractions: FirmwareRetractionAt's fields
        self.tower: tuple | None = None        # active Klipper TUNING_TOWER
        self.tower_z = math.nan
        self.tower_value = math.nan
        self.events: list[Event] = []
        # move columns
        self.m_line: list[int] = []
        self.m_start: list[tuple] = []
        self.m_end: list[tuple] = []
        self.m_feed: list[float] = []
        self.m_feature: list[int] = []
        self.m_settings: list[int] = []
        self.m_stop: list[bool] = []
        self.m_dwell: list[float] = []
        self.m_arc: list[bool] = []
        self.n_done = 0                          # moves already moved into ``chunks``
        self.chunks: list[list[np.ndarray]] = []
        self.n_lines = 0
        self.limited: tuple | None = None

    # -- helpers ---------------------------------------------------------------------------------
    def _where(self, lineno: int) -> str:
        return f"{self.source}:{lineno}"

    def _emit(self, end: list[float], lineno: int, arc: bool = False) -> None:
        start = self.pos
        if end == start:
            return
        if self.tower is not None and end[3] > start[3] and end[2] != self.tower_z \
                and (end[0] != start[0] or end[1] != start[1]):
            self._tower_step(end[2], lineno)
        if self.settings_dirty:
            self.settings_rows.append(tuple(self.settings.values()))
            self.settings_dirty = False
        self.m_line.append(lineno)
        self.m_start.append(start)
        self.m_end.append(end)
        self.m_feed.append(self.feed * self.speed_factor)
        self.m_feature.append(self.cur_feature)
        self.m_settings.append(len(self.settings_rows) - 1)
        self.m_stop.append(self.stop)
        self.m_dwell.append(self.dwell)
        self.m_arc.append(arc)
        self.stop = False
        self.dwell = 0.0
        self.pos = end           # a new list: never mutated in place afterwards
        if len(self.m_line) >= _CHUNK:
            self._flush()

    _COLUMNS = (("m_line", np.int64), ("m_start", float), ("m_end", float), ("m_feed", float),
                ("m_feature", np.int64), ("m_settings", np.int64), ("m_stop", bool),
                ("m_dwell", float), ("m_arc", bool))

    def _flush(self) -> None:
        """Move the collected move columns into numpy arrays (bounded memory on long jobs)."""
        if not self.m_line:
            return
        self.n_done += len(self.m_line)
        self.chunks.append([np.asarray(getattr(self, name), dtype) for name, dtype in self._COLUMNS])
        for name, _ in self._COLUMNS:
            setattr(self, name, [])

    def _bad_word(self, letter: str, value: str, lineno: int):
        where = self._where(lineno)
        if value == "":
            raise RingtuneError(f"{letter.upper()} needs a value", where)
        _num(value, letter.upper(), where)
        raise RingtuneError(f"{letter}{value} is out of range", where)  # pragma: no cover

    def _fast_move(self, text: str, lineno: int) -> None:
        """G0/G1: the hot path (one regex, one float per word, bounds checked inline)."""
        pos = self.pos
        end = list(pos)
        off = self.offset
        abs_xyz, abs_e = self.abs_xyz, self.abs_e
        unit = self.unit
        for letter, value in _WORD.findall(text):
            try:
                x = float(value)
            except ValueError:
                self._bad_word(letter, value, lineno)
            bound, i = _WORD_INFO.get(letter, _OTHER_WORD)
            if not -bound <= x <= bound:
                self._bad_word(letter, value, lineno)
            if unit != 1.0:
                x *= unit
            if i < 3:
                if i >= 0:
                    end[i] = x + off[i] if abs_xyz else pos[i] + x
            elif i == 3:
                end[3] = x + off[3] if abs_e else pos[3] + x
            else:
                if x <= 0:
                    raise RingtuneError(f"feedrate F{x:g} must be > 0", self._where(lineno))
                self.feed = x / 60.0
        self._emit(end, lineno)

    def _set(self, key: str, value: float) -> None:
        self.settings[key] = value
        self.settings_dirty = True

    # -- the line loop -----------------------------------------------------------------------------
    def feed_lines(self, lines: Iterable[str]) -> None:
        lineno = 0
        for lineno, raw in enumerate(lines, 1):
            semi = raw.find(";")
            if semi >= 0:
                self._comment(raw[semi + 1:], lineno)
                code = raw[:semi].strip()
            else:
                code = raw.strip()
            if code and ("(" in code or code[0] in "Nn" or "*" in code):
                code = self._bare_code(code, lineno)
            if not code:
                continue
            if code[0] in "Gg" and len(code) > 2 and code[1] in "01" and not code[2].isdigit() \
                    and code[2] != ".":
                self._fast_move(code[2:], lineno)
            else:
                self._command(code, lineno)
        self.n_lines = lineno

    def _comment(self, comment: str, lineno: int) -> None:
        """A line's comment: a slicer's feature marker, or (first 3 lines) ringtune's limit header."""
        m = _FEATURE.match(comment)
        if m:
            self._feature(m.group(1) or m.group(2))
        elif lineno <= 3 and (m := _LIMITED.match(comment)):
            self.limited = (float(m.group(2)), m.group(1), float(m.group(3)))

    def _bare_code(self, code: str, lineno: int) -> str:
        """``code`` without RS-274 parenthesised comments, its line number and its checksum."""
        if "(" in code:
            code = re.sub(r"\([^)]*\)", "", code).strip()
        if code and (code[0] in "Nn" or "*" in code):
            code = _strip_line_number(code, self._where(lineno))
        return code

    def _words(self, text: str, lineno: int) -> dict[str, float]:
        words = {}
        if '"' in text:            # quoted strings (RRF M593 P"zvd", M98 P"file.g") are kept as text
            words.update((k.upper(), v) for k, v in _QUOTED.findall(text))
            text = _QUOTED.sub(" ", text)
        for letter, value in _WORD.findall(text):
            letter = letter.upper()
            if value == "":
                words[letter] = math.nan      # a bare letter (G28 X, M593 X): a flag
                continue
            words[letter] = _num(value, letter, self._where(lineno))
        return words

    def _feature(self, name: str) -> None:
        name = name.strip()
        if name not in self.feature_idx:
            self.feature_idx[name] = len(self.features)
            self.features.append(name)
        self.cur_feature = self.feature_idx[name]

    def _event(self, kind: str, command: str, params: dict, lineno: int, text: str) -> None:
        self.events.append(Event(kind, command, params, lineno, self.n_done + len(self.m_line), text))

    def _command(self, code: str, lineno: int) -> None:
        m = _CLASSIC.match(code)
        if m is None or (len(code) > m.end() and code[m.end()] == "_"):
            return self._extended(code, lineno)
        cmd = m.group(1).upper() + m.group(2)
        rest = code[m.end():]
        if cmd in TEXT_COMMANDS:
            self._event("other", cmd, {"text": rest.strip()}, lineno, code)
            return
        if cmd in ("G0", "G1"):
            self._words(rest, lineno)          # a malformed move is an error, named
            self._fast_move(rest, lineno)
        elif cmd in MODE_COMMANDS:
            for attr, value in MODE_COMMANDS[cmd].items():
                setattr(self, attr, value)
            if "abs_xyz" in MODE_COMMANDS[cmd]:
                self.position_events.append((lineno, "abs" if self.abs_xyz else "rel", (0, 1)))
        elif cmd in self._HANDLERS:
            self._HANDLERS[cmd](self, cmd, self._words(rest, lineno), lineno, code)
        elif cmd in LIMIT_COMMANDS or cmd in SHAPER_COMMANDS:
            self._other(cmd, self._words(rest, lineno), lineno, code)
        else:
            self._other(cmd, self._loose_words(rest, lineno), lineno, code)

    def _loose_words(self, text: str, lineno: int) -> dict:
        """The words of a command the planner does not act on; its text where they are not numbers
        (a vendor's own command, e.g. Bambu Studio's ``M1002 judge_flag timelapse_record_flag``,
        which the job's own firmware reads and which is no error in the file)."""
        try:
            return self._words(text, lineno)
        except RingtuneError:
            return {"text": text.strip()}

    def _other(self, cmd: str, words: dict, lineno: int, code: str) -> None:
        """Limit commands (applied and recorded), shaper commands, and the rest (recorded; some stop
        the planner)."""
        if cmd in LIMIT_COMMANDS:
            self._limits(cmd, words, self._where(lineno))
            self._event("limits", cmd, words, lineno, code)
        elif cmd in SHAPER_COMMANDS:
            self.stop = True
            self._event("shaper", cmd, words, lineno, code)
        else:
            if cmd in STOP_COMMANDS or (cmd in MOTORS_OFF and "S" not in words):
                self.stop = True
            elif self.retraction.moves(cmd, words):
                self._retraction_at(cmd, lineno)
            self._event("other", cmd, words, lineno, code)

    def _retraction_at(self, cmd: str, lineno: int) -> None:
        """Note a firmware retraction that moves E, with the feature and settings in force (the head
        stops there: :meth:`_retractions_stop`)."""
        if self.settings_dirty:
            self.settings_rows.append(tuple(self.settings.values()))
            self.settings_dirty = False
        self.fw_pending.append((self.n_done + len(self.m_line), cmd, lineno, self.cur_feature,
                                len(self.settings_rows) - 1, self.speed_factor))

    def _retractions_stop(self, stop: np.ndarray) -> list[FirmwareRetractionAt]:
        """The firmware retractions, each ``alone`` where nothing else stops the head before its
        move; ``stop`` (the moves' stops so far) then stops there too."""
        moves = np.array([p[0] for p in self.fw_pending], np.int64)
        moves = moves[moves < len(stop)]
        alone = ~stop[moves]
        stop[moves] = True
        alone = [*alone, *[True] * len(self.fw_pending)]         # after the last move: nothing to stop
        return [FirmwareRetractionAt(*p, alone=bool(a)) for p, a in zip(self.fw_pending, alone)]

    def job(self) -> Job:
        self._flush()
        cols = []
        for k, (name, dtype) in enumerate(self._COLUMNS):
            parts = [c[k] for c in self.chunks]
            arr = np.concatenate(parts) if parts else np.zeros(0, dtype)
            cols.append(arr.reshape(-1, 4) if name in ("m_start", "m_end") else arr)
        if self.settings_dirty:
            self.settings_rows.append(tuple(self.settings.values()))
        retractions = self._retractions_stop(cols[6])
        return Job(
            line=cols[0], start=cols[1], end=cols[2], feed=cols[3], feature=cols[4],
            settings=cols[5], stop_before=cols[6], dwell_before=cols[7], arc=cols[8],
            features=self.features,
            settings_table=np.asarray(self.settings_rows, float).reshape(-1, len(SETTING_KEYS)),
            events=self.events,
            dwell_after=self.dwell,
            source=self.source,
            n_lines=self.n_lines,
            arc_tolerance=self.tol,
            limited=self.limited,
            fw_retractions=retractions,
            arcs=(self.n_arcs, self.resolution, tuple(self.refused_arcs)),
            position_events=self.position_events,
        )


def read_gcode(path_or_text, arc_tolerance: float = 0.01, source: str | None = None,
               arc_resolution=None) -> Job:
    """Read a G-code job from a file path (streamed line by line) or from G-code text/bytes.

    ``arc_tolerance``: largest distance (mm) between a G2/G3 arc and the chords replacing it;
    ``arc_resolution``: the firmware's own segments instead (:func:`ringtune.shaping.arcs.arc_resolution`:
    Klipper's ``[gcode_arcs] resolution`` in mm, which cuts I/J arcs, or Marlin's, RRF's or Buddy's
    rule, :class:`~ringtune.shaping.arcs.MarlinArcs` or :class:`~ringtune.shaping.arcs.DeviationArcs`;
    None: the tolerance's chords).
    Malformed values raise :class:`RingtuneError` naming ``file:line`` (``source`` names text
    input, default ``<gcode>``). Lines end at ``\n``, ``\r\n`` or ``\r`` for files and text alike,
    so line numbers are those of the file's bytes.
    """
    is_path = isinstance(path_or_text, Path)
    if isinstance(path_or_text, str) and "\n" not in path_or_text:
        p = Path(path_or_text)
        try:
            is_path = p.suffix.lower() in (".gcode", ".gco", ".g", ".nc", ".gc", ".bgcode") or p.is_file()
        except OSError:             # not a possible file name: G-code text
            is_path = False
    if is_path:
        path = Path(path_or_text)
        reader = _Reader(str(path), arc_tolerance, arc_resolution)
        head = read_head(path)
        if is_bgcode(head):          # binary G-code: its plain text, decoded whole
            reader.feed_lines(io.StringIO(read_gcode_bytes(path).decode("utf-8", "replace"), newline=None))
        else:
            refuse_non_gcode(head, str(path))
            reader.feed_lines(open_lines(path))
    else:
        source = source or "<gcode>"
        if isinstance(path_or_text, bytes):
            refuse_non_gcode(path_or_text[:HEAD], source)
            path_or_text = path_or_text.decode("utf-8", "replace")
        reader = _Reader(source, arc_tolerance, arc_resolution)
        reader.feed_lines(io.StringIO(str(path_or_text), newline=None))
    return reader.job()
