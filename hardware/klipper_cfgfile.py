"""Klipper's configuration file syntax: sections, includes, comments and the SAVE_CONFIG block.

Read the way Klipper 84104bb reads it (``klippy/configfile.py``; facts, not its code):

- everything from the first ``#`` on a line is a comment; ``;`` starts a comment only after
  whitespace (Python ``configparser`` inline comments), or at the start of a line;
- ``option: value`` or ``option = value``; option names are case-insensitive (lower-cased); a line
  indented deeper than its option continues the value (multi-line values, e.g. ``gcode:``);
- a section may appear several times: its options merge, a later value replaces an earlier one;
- ``[include SPEC]`` reads, at that point, every file matching the glob ``SPEC`` relative to the
  *including* file's folder, in sorted order. Klipper refuses a plain file name that does not exist
  and accepts a glob that matches nothing; here both are a note (:attr:`KlipperCfg.notes`) and
  reading goes on, because a configuration copied without its macros still describes the printer;
- the main file's auto-saved block, after ``#*# <---------------------- SAVE_CONFIG ...``, is
  read last with its ``#*# `` prefixes removed. Klipper 84104bb lets it fill in what the file above
  does not set, and ignores a saved option the file above also sets (``_strip_duplicates`` on load;
  its next SAVE_CONFIG comments the hand-written one out instead). Both cases are kept here, the
  second with a note naming both values.
"""

from __future__ import annotations

import glob
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

from ringtune.hardware.config_dialect import refuse_other_dialect
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.textfile import read_text_file

#: the line that opens Klipper's auto-saved block (``AUTOSAVE_HEADER`` in klippy/configfile.py)
AUTOSAVE_LINE = "#*# <---------------------- SAVE_CONFIG ---------------------->"

_SECTION = re.compile(r"\[(?P<header>.+)\]")
_OPTION = re.compile(r"(?P<option>.*?)\s*[=:]\s*(?P<value>.*)$")
#: what starts each line of the SAVE_CONFIG block (``#*# `` or a bare ``#*#``)
_SAVED_PREFIX = re.compile(r"^#\*# ?")
#: an inline comment: ``;`` after whitespace (``configparser``'s inline_comment_prefixes)
_INLINE_SEMICOLON = re.compile(r"(?<=\s);")


@dataclass
class KlipperCfg:
    """A configuration as Klipper merges it.

    ``sections``: section name -> {option (lower case) -> raw value string}, section names as
    written; ``origin``: (section, option) -> ``"file:line"`` of the value in force; ``files``: every
    file read, in order; ``notes``: what could not be read (missing includes, files that are not
    configurations); ``unread``: the files Klipper would read that could not be (a missing
    include, a file that is not a configuration): what they set is unknown; ``ignored_saved``:
    (section, option, note) for each SAVE_CONFIG value that the file above overrides (a caller notes
    those of the sections it uses).
    """

    sections: dict[str, dict[str, str]] = field(default_factory=dict)
    origin: dict[tuple[str, str], str] = field(default_factory=dict)
    files: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    unread: list[str] = field(default_factory=list)
    ignored_saved: list[tuple[str, str, str]] = field(default_factory=list)

    def section(self, name: str) -> dict[str, str] | None:
        """The section ``name`` (case-insensitive, as Moonraker reports names), or None."""
        for key, value in self.sections.items():
            if key.lower() == name.lower():
                return value
        return None


def _strip_comment(line: str) -> str:
    pos = line.find("#")
    return line if pos < 0 else line[:pos]


def _content(raw: str) -> str:
    """A line without its comment, stripped; "" for a blank or comment line (``;`` at its start)."""
    line = _strip_comment(raw).strip()
    return "" if line.startswith(";") else line


def _strip_inline_semicolon(value: str) -> str:
    """``value`` up to its first ``;`` after whitespace (an inline comment)."""
    return _INLINE_SEMICOLON.split(value, maxsplit=1)[0]


class _Reader:
    def __init__(self, cfg: KlipperCfg):
        self.cfg = cfg
        self.visiting: set[str] = set()
        self.cur: str | None = None          # current section
        self.opt: str | None = None          # option whose value may continue
        self.indent = 0

    def set(self, section: str, option: str, value: str, where: str) -> None:
        self.cfg.sections.setdefault(section, {})[option] = value
        self.cfg.origin[(section, option)] = where

    def feed(self, text: str, name: str, first_line: int = 1, saved: bool = False) -> None:
        """Read lines of ``name`` (``first_line`` = number of the first); includes are followed."""
        self.cur = self.opt = None
        for n, raw in enumerate(text.split("\n"), first_line):
            stripped = _content(raw)
            if not stripped:
                continue                      # blank and comment lines never end a value here
            indent = len(raw) - len(raw.lstrip())
            if self.opt is not None and indent > self.indent:
                old = self.cfg.sections[self.cur][self.opt]
                self.cfg.sections[self.cur][self.opt] = (old + "\n" + _strip_inline_semicolon(stripped)).strip()
                continue
            self.opt = None
            m = _SECTION.match(stripped)
            if m:
                self._section(m.group("header").strip(), name, f"{name}:{n}", saved)
            else:
                self._option(stripped, indent, f"{name}:{n}", saved)

    def _section(self, header: str, name: str, where: str, saved: bool) -> None:
        """A ``[section]`` line: an include is followed (not in the SAVE_CONFIG block), else the
        options that follow belong to ``header``."""
        if header.startswith("include ") and not saved:
            self.include(header[8:].strip(), name, where)
            self.cur = None
            return
        self.cur = header
        self.cfg.sections.setdefault(header, {})

    def _option(self, stripped: str, indent: int, where: str, saved: bool) -> None:
        """An ``option: value`` line of the current section; a SAVE_CONFIG value that a line above
        the block already sets is ignored (Klipper lets that one win), and said."""
        if self.cur is None:
            raise RingtuneError(f"an option before any [section]: {stripped!r}", where)
        m = _OPTION.match(stripped)
        if not m or not m.group("option"):
            raise RingtuneError(f"not an 'option: value' line: {stripped!r}", where)
        option = m.group("option").strip().lower()
        value = _strip_inline_semicolon(m.group("value")).strip()
        if saved and option in self.cfg.sections.get(self.cur, {}) \
                and not self.cfg.origin[(self.cur, option)].endswith("(saved)"):
            self.cfg.ignored_saved.append((self.cur, option,
                f"{where}: SAVE_CONFIG value [{self.cur}] {option} = {value} is ignored: "
                f"{self.cfg.origin[(self.cur, option)]} sets {self.cfg.sections[self.cur][option]!r}, "
                "and Klipper lets the value above the SAVE_CONFIG block win"))
            return
        self.set(self.cur, option, value, where + (" (saved)" if saved else ""))
        self.opt, self.indent = option, indent

    def include(self, spec: str, including: str, where: str) -> None:
        pattern = os.path.join(os.path.dirname(including), spec)
        matches = sorted(glob.glob(pattern))
        if not matches:
            if glob.has_magic(pattern):
                self.cfg.notes.append(f"{where}: warning: [include {spec}] matches no file (nothing read "
                                      "from it)")
            else:
                self.cfg.notes.append(f"{where}: warning: [include {spec}]: no such file "
                                      f"{os.path.normpath(pattern)} (Klipper itself would refuse to start; "
                                      "read on without it)")
                self.cfg.unread.append(os.path.normpath(pattern))
            return
        for path in matches:
            self.read_file(path)

    def read_file(self, path: str) -> None:
        real = os.path.realpath(path)
        if real in self.visiting:
            raise RingtuneError("includes itself (recursive [include])", path)
        self.visiting.add(real)
        try:
            text = Path(path).read_text(encoding="utf-8-sig", errors="replace").replace("\r\n", "\n")
        except OSError as exc:
            raise RingtuneError(f"cannot read: {exc.strerror}", path) from None
        first = next((ln for ln in map(_content, text.split("\n")) if ln), "")
        if first and not _SECTION.match(first):
            # e.g. a symbolic link kept as a one-line text file (git without symlinks): Klipper
            # could not read it either
            self.cfg.notes.append(f"{path}:1: warning: not a configuration (text before any [section]: "
                                  f"{first[:60]!r}, a symbolic link kept as text?); nothing read from it")
            self.cfg.unread.append(path)
        else:
            self.cfg.files.append(path)
            self.feed(text, path)
        self.visiting.discard(real)


def split_autosave(text: str) -> tuple[str, str, int]:
    """(regular part, saved block without its ``#*# `` prefixes, line number of the block's first
    line). The block is empty when the file has none. The header's "DO NOT EDIT" line is blanked
    (line numbers stay those of the file)."""
    lines = text.split("\n")
    for i, line in enumerate(lines):
        if line.strip() == AUTOSAVE_LINE:
            saved = [_SAVED_PREFIX.sub("", ln, count=1) for ln in lines[i + 1:]]
            if saved and saved[0].startswith("DO NOT EDIT"):
                saved[0] = ""
            return "\n".join(lines[:i]), "\n".join(saved), i + 2
    return text, "", 0


def read_klipper_cfg(path: str | Path) -> KlipperCfg:
    """Read ``printer.cfg`` with its includes and SAVE_CONFIG block (see the module docstring)."""
    path = str(path)
    text = read_text_file(path, "Klipper configuration").replace("\r\n", "\n")
    refuse_other_dialect(text, path, "klipper")
    cfg = KlipperCfg()
    reader = _Reader(cfg)
    regular, saved, first = split_autosave(text)
    real = os.path.realpath(path)
    reader.visiting.add(real)
    cfg.files.append(path)
    reader.feed(regular, path)
    reader.visiting.discard(real)
    if saved:
        reader.feed(saved, path, first_line=first, saved=True)
    return cfg
