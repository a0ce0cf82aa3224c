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
            if not line or line.lower() == "ok":
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
    netloc = parts.netloc
    if "@" in netloc:
        netloc = "***@" + netloc.rsplit("@", 1)[1]
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
            if chunk:
                self._buf += chunk
        raw, _, self._buf = self._buf.partition(b"\n")
        line = raw.decode("utf-8", "replace").strip("\r\x00 ")
        self.log("< " + line)
        return line

    def _await_ok(self, command: str, n: int | None, handshake: bool = False) -> Reply:
        reply = Reply(command)
        start = time.monotonic()
        last_life = start
        last_send = start
        same_resend = 0
        last_resend = None
        pending: list[int] = []       # line numbers to replay once the resend's ok has come / timed out
        resend_deadline = None
        while True:
            now = time.monotonic()
            if pending and resend_deadline is not None and now >= resend_deadline:
                self._replay(pending)
                pending, resend_deadline = [], None
                last_send = now
            wait_until = min(last_life + self.timeout,
                             resend_deadline if resend_deadline else float("inf"),
                             last_send + self.retry_after if self.mode == "rrf" and n is not None
                             else float("inf"))
            line = self._readline(wait_until)
            now = time.monotonic()
            if line is None:
                if pending:
                    continue  # resend_deadline passed: replay at the top of the loop
                if now >= last_life + self.timeout:
                    raise LinkTimeout(f"no answer to {command!r} within {self.timeout:g} s", command,
                                      redact(self.port))
                if self.mode == "rrf" and n is not None and now >= last_send + self.retry_after:
                    # RRF drops a corrupted line without a word: send it again, same number
                    self.log(f"no answer to N{n} after {self.retry_after:g} s; sending it again")
                    self._write(self.history[n] + b"\n")
                    reply.sends += 1
                    last_send = now
                continue
            raw_line, line = line, _LEADING_NOISE.sub("", line)
            if not line:
                continue
            low = line.lower()
            if low == "start":
                self.resets += 1
                self.log("printer reset (it said 'start'); handshaking again")
                if not handshake and self.mode != "klipper":
                    self.handshake()
                raise PrinterReset(f"the printer reset (said 'start') while {command!r} was waiting; "
                                   "its runtime settings are gone", redact(self.port))
            m = _RESEND.match(line)
            if m and n is not None:
                want = int(m.group(1))
                last_life = now
                if want > n:
                    self.log(f"ignoring resend request for N{want}, not sent yet")
                    continue
                same_resend = same_resend + 1 if want == last_resend else 1
                last_resend = want
                if same_resend > self.max_resends:
                    raise LinkError(f"the printer asked for line N{want} {same_resend} times in a row",
                                    redact(self.port))
                missing = [k for k in range(want, n + 1) if k not in self.history]
                if missing:
                    raise LinkError(f"the printer asked for N{want}, which is older than this session",
                                    redact(self.port))
                pending = list(range(want, n + 1))
                resend_deadline = now + self.resend_ok_wait
                reply.sends += 1
                continue
            if low.startswith("ok"):
                last_life = now
                if pending:       # the ok that goes with a Resend request: now replay
                    self._replay(pending)
                    pending, resend_deadline = [], None
                    last_send = now
                    continue
                rest = line[2:].strip()
                if rest and not re.match(r"^N\d+\b", rest) and not _TEMP.match(line):
                    reply.lines.append(rest)
                elif rest and _TEMP.match(line):
                    reply.lines.append(rest)
                return reply
            if _BUSY.match(line):
                last_life = now
                continue
            if _TEMP.match(line) or low == "wait":
                continue
            if low.startswith("error") or line.startswith("!!"):
                text = re.sub(r"^(?:error:?|!!)\s*", "", line, flags=re.IGNORECASE)
                if self.mode != "klipper" and _PROTOCOL_ERROR.search(text):
                    continue  # a Resend follows; handled there
                reply.errors.append(text)
                continue
            if self.mode == "klipper":
                info, errors = klipper_reply_lines([line])
                reply.lines += info
                reply.errors += errors
                continue
            refusal = marlin_refusal(line) if self.mode == "marlin" else None
            if refusal:
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
