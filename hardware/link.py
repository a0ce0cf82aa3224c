"""Host side of the printer serial protocol (``shared/reference/firmware.md`` §5).

Marlin and RepRapFirmware: every line goes out as ``N<n> <cmd>*<cs>`` (XOR checksum in decimal;
RRF may take a 5-digit CRC-16 instead), after an ``M110 N0`` handshake, with one line outstanding
at a time (one ``ok`` per line). The link handles:

- ``Resend: <n>`` / ``rs <n>``: replays exactly the lines asked for, from its history, byte for byte
  (with or without the ``ok`` some Marlin versions send after the request);
- ``echo:busy: ...``: the printer is working; the answer timeout starts again;
- temperature auto-reports and other chatter interleaved with replies: kept out of the reply;
- line noise (non-ASCII bytes, NULs) glued in front of a line, as a board resetting through its
  bootloader sends before ``start``: ignored when recognising ``ok``, ``start``, ``Resend:``, busy
  and error lines, so a noisy ``start`` or ``ok`` is not mistaken for silence;
- ``start``: the printer reset. The link re-handshakes and raises :class:`PrinterReset`, because
  every runtime setting sent before is gone (the caller decides to send again);
- ``Error:`` lines: the error is attached to the line's reply (checksum / line-number errors are left
  to the resend logic);
- RRF drops a line with a bad checksum silently: without an answer within ``retry_after`` the link
  sends the same numbered line again (RRF lines here are idempotent settings, verified by read-back);
- no answer within ``timeout`` s: :class:`LinkTimeout`.

Klipper's pseudo-tty (``mode="klipper"``) takes plain lines: no numbers, no checksums, no handshake;
errors come as ``!! <msg>``. An unknown command is answered with an info line
(``// Unknown command:"X"``, ``klippy/gcode.py``), which :func:`klipper_reply_lines` counts as an error:
the line did nothing.

Ports are anything ``serial.serial_for_url`` opens: ``/dev/ttyUSB0``, ``/tmp/printer``,
``socket://host:port``, ``rfc2217://host:port``, ``loop://``.
"""

from __future__ import annotations

import math
import re
import time
from dataclasses import dataclass, field
from typing import Callable
from urllib.parse import urlsplit, urlunsplit

import serial

from ringtune.shaping.errors import RingtuneError

MODES = ("marlin", "rrf", "klipper")

_RESEND = re.compile(r"^(?:resend|rs)\b[:\s]*(?:N:?)?\s*(\d+)", re.IGNORECASE)
_TEMP = re.compile(r"^\s*(?:ok\s+)?T\d*:\s*-?[\d.]+\s*/\s*-?[\d.]+|^\s*B:\s*-?[\d.]+\s*/")
_BUSY = re.compile(r"^(?:echo:)?\s*busy:", re.IGNORECASE)
_PROTOCOL_ERROR = re.compile(r"checksum|line number|linenumber|last line", re.IGNORECASE)
#: line noise in front of a line: anything but printable ASCII (replacement characters, NULs, ...)
_LEADING_NOISE = re.compile(r"^[^\x20-\x7e]+")


def klipper_reply_lines(messages: list[str]) -> tuple[list[str], list[str]]:
    """(info lines, errors) of Klipper's replies to one command: ``!! msg`` and
    ``// Unknown command:"X"`` are errors; ``ok`` lines are dropped. ``messages`` may hold several
    lines each (Moonraker's console store keeps a multi-line reply as one message)."""
    lines, errors = [], []
    for message in messages:
        for line in str(message).splitlines():
            line = line.strip()
            if line.lower() in ("", "ok"):
                continue
            if line.startswith("!!"):
                errors.append(line[2:].strip())
            elif re.match(r"^(?://\s*|echo:\s*)?Unknown command", line):     # echo: Marlin's, a wrong firmware
                errors.append(re.sub(r"^(?://|echo:)\s*", "", line).strip())
            else:
                lines.append(line)
    return lines, errors


def xor_checksum(data: bytes) -> int:
    """Marlin/RRF line checksum: XOR of every byte (from ``N`` up to, not including, ``*``)."""
    cs = 0
    for b in data:
        cs ^= b
    return cs


def crc16_ccitt(data: bytes) -> int:
    """CRC-16/CCITT, polynomial 0x1021, initial value 0 (RRF's 5-digit checksum)."""
    crc = 0
    for b in data:
        crc ^= b << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else (crc << 1)
            crc &= 0xFFFF
    return crc


def frame(n: int, command: str, crc: bool = False) -> bytes:
    """``N<n> <command>*<checksum>`` (no newline). ``crc`` uses RRF's CRC-16, zero-padded to 5 digits."""
    body = f"N{n} {command}".encode("ascii")
    if crc:
        return body + b"*%05d" % crc16_ccitt(body)
    return body + b"*%d" % xor_checksum(body)


def redact(url: str) -> str:
    """A port or URL fit to print: password, user and secret query values replaced by ``***``."""
    try:
        parts = urlsplit(url)
    except ValueError:
        return "***"
    if not parts.scheme or not parts.netloc:
        return url
    netloc = re.sub(r"^.*@", "***@", parts.netloc)       # user and password, up to the last @
    query = re.sub(r"(?i)(^|&)((?:api[_-]?key|token|access_token|password|pass|key|secret)=)[^&]*",
                   r"\1\2***", parts.query)
    return urlunsplit((parts.scheme, netloc, parts.path, query, ""))


class LinkError(RingtuneError):
    """The printer connection failed."""


class LinkTimeout(LinkError):
    """No acknowledgement in time. ``line`` is the command that was waiting."""

    def __init__(self, message: str, line: str | None = None, where: str | None = None):
        super().__init__(message, where)
        self.line = line


class PrinterReset(LinkError):
    """The printer said ``start`` (it rebooted): settings sent before are gone; link re-handshook."""


@dataclass
class Reply:
    """Answer to one command: text lines (without ok/busy/temperatures), errors, attempts made."""

    command: str
    lines: list[str] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)
    sends: int = 1

    @property
    def text(self) -> str:
        return "\n".join(self.lines)


@dataclass
class _Waiting:
    """One command waiting for its ``ok``: its reply, line number (None: Klipper) and clocks
    (``time.monotonic()`` s): last sign of life, last send, and a resend's lines and replay time."""

    reply: Reply
    n: int | None
    last_life: float
    last_send: float
    pending: list[int] = field(default_factory=list)
    resend_deadline: float | None = None
    last_resend: int | None = None
    same_resend: int = 0


class GcodeLink:
    """One printer connection (use as a context manager).

    Args:
        port: device path or pyserial URL (never logged unredacted).
        mode: ``"marlin"``, ``"rrf"`` or ``"klipper"`` (pty, no checksums).
        baud: serial speed (ignored by socket URLs).
        crc: RRF only: CRC-16 instead of XOR.
        timeout: s without any sign of life (ok / busy) before :class:`LinkTimeout`.
        retry_after: RRF only: s without an answer before the same line is sent again.
        resend_ok_wait: s to wait for the ``ok`` that may follow a ``Resend:`` before replaying.
        max_resends: the same line asked for this many times in a row -> error.
        log: called with each event (``"> N1 M593 ...*12"``, ``"< ok"``, notes).
        serial_obj: an already open serial-like object (tests).
    """

    def __init__(self, port: str, mode: str = "marlin", baud: int = 115200, crc: bool = False,
                 timeout: float = 10.0, retry_after: float = 2.0, resend_ok_wait: float = 0.3,
                 max_resends: int = 10, log: Callable[[str], None] | None = None, serial_obj=None):
        if mode not in MODES:
            raise RingtuneError(f"mode must be one of {', '.join(MODES)}", "link")
        self.port, self.mode, self.baud, self.crc = port, mode, baud, crc
        self.timeout, self.retry_after, self.resend_ok_wait = timeout, retry_after, resend_ok_wait
        self.max_resends = max_resends
        self.log = log or (lambda msg: None)
        self.ser = serial_obj
        self.next_n = 0
        self.history: dict[int, bytes] = {}
        self.resets = 0
        self._buf = b""

    # -- connection --------------------------------------------------------------------------------
    def __enter__(self) -> "GcodeLink":
        self.open()
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def open(self) -> None:
        if self.ser is None:
            try:
                self.ser = serial.serial_for_url(self.port, baudrate=self.baud, timeout=0.05,
                                                 write_timeout=self.timeout)
            except (serial.SerialException, ValueError, OSError) as exc:
                msg = str(exc).replace(self.port, redact(self.port))
                raise LinkError(f"cannot open: {msg}", f"--port {redact(self.port)}") from None
        if self.mode != "klipper":
            self.handshake()

    def close(self) -> None:
        if self.ser is not None:
            try:
                self.ser.close()
            finally:
                self.ser = None

    def handshake(self) -> None:
        """``N0 M110 N0``: line numbering starts again; the next line is N1."""
        self.next_n = 0
        self.history.clear()
        for attempt in range(3):
            try:
                self._send_numbered("M110 N0", handshake=True)
                return
            except PrinterReset:
                self.log(f"printer reset during handshake; handshaking again ({attempt + 1})")
                self.next_n = 0
                self.history.clear()
        raise LinkError("the printer keeps resetting during the handshake", redact(self.port))

    # -- sending -----------------------------------------------------------------------------------
    def send(self, command: str) -> Reply:
        """Send one command and wait for its ``ok``; returns the reply text and any errors."""
        command = command.strip()
        if not command or "\n" in command or "*" in command:
            raise RingtuneError(f"cannot send {command!r}: one non-empty line without '*'", "link")
        if self.mode == "klipper":
            self._write(command.encode("ascii") + b"\n")
            return self._await_ok(command, None)
        return self._send_numbered(command)

    def _send_numbered(self, command: str, handshake: bool = False) -> Reply:
        n = self.next_n
        wire = frame(n, command, self.crc and self.mode == "rrf")
        self.history[n] = wire
        self.next_n = n + 1
        self._write(wire + b"\n")
        return self._await_ok(command, n, handshake)

    def _write(self, data: bytes) -> None:
        self.log("> " + data.decode("ascii", "replace").rstrip("\n"))
        try:
            self.ser.write(data)
            self.ser.flush()
        except Exception as exc:  # serial.SerialException, OSError, socket errors
            raise LinkError(f"write failed: {exc}", redact(self.port)) from None

    def _readline(self, deadline: float) -> str | None:
        while b"\n" not in self._buf:
            if time.monotonic() >= deadline:
                return None
            try:
                chunk = self.ser.read(max(1, getattr(self.ser, "in_waiting", 0) or 1))
            except Exception as exc:
                raise LinkError(f"read failed: {exc}", redact(self.port)) from None
            self._buf += chunk
        raw, _, self._buf = self._buf.partition(b"\n")
        line = raw.decode("utf-8", "replace").strip("\r\x00 ")
        self.log("< " + line)
        return line

    def _await_ok(self, command: str, n: int | None, handshake: bool = False) -> Reply:
        """Read until the ``ok`` of ``command`` (line ``n``; None: Klipper's unnumbered lines)."""
        start = time.monotonic()
        w = _Waiting(Reply(command), n, start, start)
        while True:
            self._replay_due(w, time.monotonic())
            line = self._readline(self._wait_until(w))
            now = time.monotonic()
            if line is None:
                self._on_silence(w, now)
            elif self._on_line(w, line, now, handshake):
                return w.reply

    def _wait_until(self, w: "_Waiting") -> float:
        """When to stop reading: the answer timeout, a resend's replay, RRF's silent-drop retry."""
        return min(w.last_life + self.timeout, w.resend_deadline or math.inf, self._retry_at(w))

    def _retry_at(self, w: "_Waiting") -> float:
        """When RRF's silent-drop retry of a numbered line is due (never for other firmware)."""
        return w.last_send + self.retry_after if self.mode == "rrf" and w.n is not None else math.inf

    def _replay_due(self, w: "_Waiting", now: float) -> None:
        """Replay the lines a resend asked for once its ``ok`` has come or its wait is over."""
        if w.pending and now >= w.resend_deadline:
            self._replay(w.pending)
            w.pending, w.resend_deadline, w.last_send = [], None, now

    def _on_silence(self, w: "_Waiting", now: float) -> None:
        """Nothing read before :meth:`_wait_until`: a replay is due, a timeout, or RRF's retry."""
        if w.pending:
            return                      # the resend's wait passed: replayed at the top of the loop
        if now >= w.last_life + self.timeout:
            raise LinkTimeout(f"no answer to {w.reply.command!r} within {self.timeout:g} s", w.reply.command,
                              redact(self.port))
        if now >= self._retry_at(w):
            # RRF drops a corrupted line without a word: send it again, same number
            self.log(f"no answer to N{w.n} after {self.retry_after:g} s; sending it again")
            self._write(self.history[w.n] + b"\n")
            w.reply.sends += 1
            w.last_send = now

    def _on_line(self, w: "_Waiting", raw_line: str, now: float, handshake: bool) -> bool:
        """Take one line read while waiting; True when it is the awaited ``ok``."""
        line = _LEADING_NOISE.sub("", raw_line)
        low = line.lower()
        resend = _RESEND.match(line) if w.n is not None else None
        if low == "start":
            self._on_reset(w.reply.command, handshake)
        if resend:
            self._on_resend(w, int(resend.group(1)), now)
        elif low.startswith("ok"):
            return self._on_ok(w, line, now)
        elif _BUSY.match(line):
            w.last_life = now
        elif line:
            self._on_text(w.reply, line, raw_line)
        return False

    def _on_reset(self, command: str, handshake: bool) -> None:
        """The printer said ``start``: handshake again (unless handshaking) and raise :class:`PrinterReset`."""
        self.resets += 1
        self.log("printer reset (it said 'start'); handshaking again")
        if not handshake and self.mode != "klipper":
            self.handshake()
        raise PrinterReset(f"the printer reset (said 'start') while {command!r} was waiting; "
                           "its runtime settings are gone", redact(self.port))

    def _on_resend(self, w: "_Waiting", want: int, now: float) -> None:
        """``Resend: want``: replay ``want``…``n`` after the ``ok`` that may follow (or a short wait)."""
        w.last_life = now
        if want > w.n:
            self.log(f"ignoring resend request for N{want}, not sent yet")
            return
        w.same_resend = w.same_resend + 1 if want == w.last_resend else 1
        w.last_resend = want
        if w.same_resend > self.max_resends:
            raise LinkError(f"the printer asked for line N{want} {w.same_resend} times in a row", redact(self.port))
        if any(k not in self.history for k in range(want, w.n + 1)):
            raise LinkError(f"the printer asked for N{want}, which is older than this session", redact(self.port))
        w.pending = list(range(want, w.n + 1))
        w.resend_deadline = now + self.resend_ok_wait
        w.reply.sends += 1

    def _on_ok(self, w: "_Waiting", line: str, now: float) -> bool:
        """An ``ok``: the one after a resend request starts the replay; else the reply is complete
        (text after ``ok`` kept unless it is only the echoed line number)."""
        w.last_life = now
        if w.pending:               # the ok that goes with a Resend request: replay now
            w.resend_deadline = now
            return False
        rest = line[2:].strip()
        if rest and (_TEMP.match(line) or not re.match(r"^N\d+\b", rest)):
            w.reply.lines.append(rest)
        return True

    def _on_text(self, reply: Reply, line: str, raw_line: str) -> None:
        """Any other line: temperatures and ``wait`` dropped; errors, refusals and text kept."""
        low = line.lower()
        if _TEMP.match(line) or low == "wait":
            return
        if low.startswith("error") or line.startswith("!!"):
            text = re.sub(r"^(?:error:?|!!)\s*", "", line, flags=re.IGNORECASE)
            if self.mode == "klipper" or not _PROTOCOL_ERROR.search(text):   # else a Resend follows
                reply.errors.append(text)
        elif self.mode == "klipper":
            info, errors = klipper_reply_lines([line])
            reply.lines += info
            reply.errors += errors
        elif self.mode == "marlin" and (refusal := marlin_refusal(line)):
            reply.errors.append(refusal)
        elif _looks_like_text(raw_line):
            reply.lines.append(line)

    def _replay(self, numbers: list[int]) -> None:
        """Resend exactly the lines asked for; all but the last wait for their own ok first."""
        for k in numbers:
            self.log(f"resending N{k} as asked")
            self._write(self.history[k] + b"\n")
            if k != numbers[-1]:
                self._await_ok(f"(replay N{k})", k)


def marlin_refusal(line: str) -> str | None:
    """Marlin's own words when a line refuses a command (it still answers ``ok``):
    ``echo:Unknown command: "M593 X F40"`` (``gcode.cpp``) and the ``?``-lines of a rejected
    parameter (``?Frequency (F) must be greater than 40.00 or 0 to disable``, ``M593.cpp``)."""
    text = re.sub(r"^(?:echo:|//)\s*", "", line.strip())      # "//": Klipper's form, a wrong firmware
    if text.startswith("Unknown command:") or text.startswith("?"):
        return text
    return None


def _looks_like_text(line: str) -> bool:
    """Reply text rather than line noise: mostly printable ASCII."""
    printable = sum(32 <= ord(c) < 127 for c in line)
    return printable >= 0.9 * len(line)
