"""Push a TuneConfig to a printer: send, read back, compare, report per setting, optionally save.

Flow (serial: Marlin, Prusa, RRF over :class:`GcodeLink`; Klipper over its pty or Moonraker):

1. the dialect's lines (:func:`ringtune.hardware.dialects.export_config`: shaping, Marlin's own
   frequency limit, the acceleration unless ``accel=False``), one ``ok`` each; every value was
   checked against the firmware's ranges and precision before the port is opened;
2. the read-back commands (``M593``, ``M493``, ``SET_INPUT_SHAPER``; ``M204``,
   ``SET_VELOCITY_LIMIT``), parsed and compared with the intent; every setting is reported
   ``applied`` / ``not applied`` (with why) / ``acknowledged (no read-back)`` (Marlin's ``M201 F S``
   has no report; :mod:`ringtune.hardware.push_status`). Klipper answers an unknown command with
   an info line (``// Unknown command``), not an error: it counts as the line failing. Over
   Moonraker each line's replies are read from the console store, so the report is the same as
   over the pty;
3. after a failed line, Klipper is asked for its state (``STATUS`` on the pty, ``/printer/info``
   through Moonraker); a printer that shut down is said, with how to recover (``FIRMWARE_RESTART``);
4. ``--save``: ``M500`` (Marlin), ``M593 W`` (Prusa) once everything was verified; RRF and Klipper
   cannot persist these from G-code, so the config lines are written to a file and the report says
   where they belong (``config.g``, ``printer.cfg``).

A printer reset during the push (``start``) is said and the whole config is sent again. A printer
that stops answering ends the push with :class:`PushError`, whose message lists what was applied
and what was not. ``dry_run`` returns exactly the bytes that would be sent, numbered and checksummed.
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable

from ringtune.hardware.dialects import export_config
from ringtune.hardware.export import Export
from ringtune.hardware.link import (GcodeLink, LinkError, LinkTimeout, PrinterReset, Reply, frame,
    klipper_reply_lines, redact)
from ringtune.hardware.moonraker import Moonraker
from ringtune.hardware.push_checks import check_acceleration, check_frequencies, undo_note, wrong_firmware_note
from ringtune.hardware.push_status import (ACKED, APPLIED, DRY, NOT_APPLIED, PushResult, judge_settings,
    setting_statuses, timeout_statuses)
from ringtune.hardware.readback import parse_report
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.firmware import FIRMWARES


class PushError(RingtuneError):
    """The push failed part-way; ``result`` says per setting what was and was not applied."""

    def __init__(self, message: str, result: PushResult, where: str | None = None):
        super().__init__(message, where)
        self.result = result


def _refused(replies) -> bool:
    """Whether the printer refused any of ``replies`` (:class:`Reply` objects)."""
    return any(r.errors for r in replies)


def dry_run_wire(exp: Export, save: bool = False, crc: bool = False) -> list[str]:
    """Exactly what a push sends, in order (numbered and checksummed for Marlin/RRF)."""
    protocol = FIRMWARES[exp.firmware].protocol
    cmds = exp.lines + exp.readback + (exp.save_lines if save else [])
    if protocol == "klipper":
        return list(cmds)
    crc = crc and protocol == "rrf"
    return [frame(n, c, crc).decode() for n, c in enumerate(["M110 N0", *cmds])]     # N0: the handshake


def push(config: TuneConfig, firmware: str | None = None, port: str | None = None,
         moonraker: str | None = None, baud: int = 115200, save: bool = False, dry_run: bool = False,
         timeout: float = 10.0, crc: bool = False, api_key: str | None = None,
         save_path: str | Path | None = None, log: Callable[[str], None] | None = None,
         max_resets: int = 3, link_options: dict | None = None, accel: bool = True,
         check_limits: bool = False) -> PushResult:
    """Apply ``config`` on the printer at ``port`` (or Moonraker at ``moonraker``) and verify it;
    ``accel`` False leaves the printer's acceleration as it is. ``check_limits``: refuse, before
    sending anything, a shaper frequency or an acceleration far outside what the printer is
    configured for (:mod:`ringtune.hardware.push_checks`; the acceleration is read from it first)."""
    exp = export_config(config, firmware, accel=accel)
    if check_limits:
        check_frequencies(exp.expected)
    firmware = exp.firmware
    where = redact(moonraker or port or "(no port)")
    result = PushResult(firmware, where, dry_run, notes=list(exp.notes))
    if moonraker and FIRMWARES[firmware].family != "klipper":
        raise RingtuneError("Moonraker speaks only for Klipper; use --port for other firmware", "--moonraker")
    if dry_run:
        return _dry_run(exp, result, save, save_path, crc)
    _check_destination(exp, port, moonraker, save, save_path)
    if moonraker:
        replies, report = _push_moonraker(exp, moonraker, api_key, timeout, log, result, check_limits)
    else:
        replies, report = _push_serial(exp, port, baud, crc, timeout, log, result, max_resets,
                                       link_options or {}, save, check_limits)
    if not result.settings:
        judge_settings(result, exp, replies, report)
    _explain(result, exp, replies)
    if save:
        _save_file(exp, result, save_path)
    return result


def _dry_run(exp: Export, result: PushResult, save: bool, save_path, crc: bool) -> PushResult:
    """``result`` of a dry run: exactly the wire that would be sent, every setting "not sent"."""
    result.wire = dry_run_wire(exp, save, crc)
    result.settings = setting_statuses(exp, {}, None, exp.firmware)      # the settings a push reports
    for st in result.settings:
        st.status, st.detail = DRY, ""
    if save and exp.config_text:
        result.notes.append(f"--save would write the {exp.config_target} lines to "
                            f"{_save_target(exp, save_path)} (--save-file FILE for another)")
    result.ok = True
    return result


def _check_destination(exp: Export, port, moonraker, save: bool, save_path) -> None:
    """Refuse before touching the printer: no explicit port, or a --save file in no directory
    (after the push a failed write would hide its report)."""
    if not port and not moonraker:
        raise RingtuneError("refusing to push without an explicit port: give --port /dev/ttyUSB0 "
                            "(or socket://host:port, rfc2217://host:port) or --moonraker URL", "--port")
    target = _save_target(exp, save_path) if save else None
    if target is not None and not target.parent.is_dir():
        raise RingtuneError("no such directory for the config file", f"--save-file {save_path}")


def _explain(result: PushResult, exp: Export, replies: dict[int, Reply]) -> None:
    """Notes beyond the statuses: the wrong firmware recognised from its refusals; a printer that
    is not ready (:func:`_withdraw`); what stays applied after a partial push and how to undo it."""
    wrong = wrong_firmware_note(exp.firmware, [e for r in replies.values() for e in r.errors])
    if wrong:
        result.notes.append(wrong)
    _withdraw(result, exp)
    if not result.ok:
        note = undo_note(exp.firmware, [s.key for s in result.settings
                                        if s.status in (APPLIED, ACKED) or s.detail.startswith("set, but")])
        if note:
            result.notes.append(note)


def _withdraw(result: PushResult, exp: Export) -> None:
    """A printer that is not ready after the push (Klipper shut down) holds none of it: every
    setting is not applied, and the notes on what the settings would do are withdrawn."""
    state = (result.printer_state or {}).get("state")
    if state in (None, "", "ready"):
        return
    result.ok = False
    result.notes = [n for n in result.notes if n not in exp.notes]
    for st in result.settings:
        st.status, st.detail = NOT_APPLIED, (f"the printer is {state}: nothing of this push is in force"
                                             + (f" ({st.detail})" if st.detail else ""))


def _check_before(exp: Export, ask: Callable[[str], Reply], check_limits: bool) -> None:
    """With ``check_limits``, read the printer's accelerations (``ask`` runs one command) and refuse
    one far above them before anything is sent."""
    if check_limits and "accel" in exp.expected:
        check_acceleration(exp.expected["accel"], _configured(exp, [ask(c) for c in exp.readback]))


def _configured(exp: Export, answers: list[Reply]) -> dict:
    """The accelerations the printer reports before the push (mm/s²), by read-back key."""
    reported = parse_report(exp.firmware, "\n".join(a.text for a in answers))
    keys = ("accel", "travel_accel", "max_accel_x", "max_accel_y")
    return {k: float(reported[k].value) for k in keys if k in reported}


def _send_all(exp: Export, link: GcodeLink, result: PushResult, replies: dict, save: bool,
              protocol: str) -> tuple[dict[int, Reply], str]:
    """One attempt: every line sent (``replies`` filled), the read-back asked; Klipper's state after
    a refusal, and --save's EEPROM write where the firmware has one. (replies, report text)."""
    replies.clear()
    for i, cmd in enumerate(exp.lines):
        replies[i] = link.send(cmd)
    answers = [link.send(c) for c in exp.readback]
    report = "\n".join(a.text for a in answers)
    if protocol == "klipper" and _refused([*replies.values(), *answers]):
        result.printer_state = _klipper_state(link)
    if save and exp.save_lines:
        judge_settings(result, exp, replies, report)
        _save_eeprom(exp, result, link)
    return replies, report


def _push_serial(exp, port, baud, crc, timeout, log, result, max_resets, link_options, save, check_limits=False):
    protocol = FIRMWARES[exp.firmware].protocol
    replies: dict[int, Reply] = {}
    link = GcodeLink(port, protocol, baud, crc=crc, timeout=timeout, log=log, **link_options)
    try:
        link.open()          # a handshake without answer is a timeout like any other: nothing applied
        _check_before(exp, link.send, check_limits)
        for attempt in range(max_resets + 1):
            try:
                return _send_all(exp, link, result, replies, save, protocol)
            except PrinterReset:
                result.resets += 1
                result.notes.append("the printer reset during the push (it said 'start'); "
                                    "re-handshook and sent every setting again")
        raise RingtuneError(f"the printer reset {result.resets} times during the push; giving up", redact(port))
    except LinkTimeout as exc:
        result.settings = timeout_statuses(exp, replies, "the printer")
        raise PushError(f"printer stopped answering ({exc.bare}); {result.summary()}", result,
                        redact(port)) from None
    finally:
        link.close()


def _klipper_state(link: GcodeLink) -> dict:
    """Klipper's state over its pty: ``STATUS`` answers ``Klipper state: Ready``, or an error with
    the state message when it is not ready (shutdown, error)."""
    try:
        reply = link.send("STATUS")
    except LinkError as exc:
        return {"state": "unknown", "message": exc.bare}
    if reply.errors:      # Klipper sends a multi-line error's first line as "!!", the rest as "//"
        text = " ".join(reply.errors + [ln.lstrip("/ ") for ln in reply.lines])
        return {"state": "shutdown" if "shutdown" in text.lower() else "not ready", "message": text}
    if "klipper state: ready" in reply.text.lower():
        return {"state": "ready", "message": "Printer is ready"}     # klippy.py message_ready, as Moonraker says
    return {"state": "unknown", "message": reply.text.strip()}


def _console_after(console: list[str], cmd: str) -> list[str]:
    """The console messages that followed the last time ``cmd`` was run."""
    last = max((i for i, m in enumerate(console) if m.strip() == cmd), default=None)
    return [] if last is None else console[last + 1:]


def _moonraker_run(mr, cmd: str, sink: dict | None = None, key: int = 0) -> Reply:
    """Run one line through Moonraker and gather its replies from the console store, so that the
    reply is what the pty would have given (errors, ``// Unknown command``). The reply goes into
    ``sink[key]`` as soon as the line has run (a console that then stops answering does not hide
    that it ran)."""
    reply = Reply(cmd)
    t0 = mr.newest()
    try:
        mr.script(cmd)
    except LinkTimeout:
        raise
    except LinkError as exc:
        reply.errors.append(getattr(exc, "message", None) or exc.bare)
    if sink is not None:
        sink[key] = reply
    lines, errors = klipper_reply_lines(_console_after(mr.console(50, since=t0), cmd))
    reply.lines += lines
    reply.errors += [e for e in errors if not any(e in r or r in e for r in reply.errors)]
    return reply


def _push_moonraker(exp, url, api_key, timeout, log, result, check_limits=False):
    mr = Moonraker(url, api_key=api_key, timeout=timeout, log=log)
    replies: dict[int, Reply] = {}
    try:
        _check_before(exp, lambda c: _moonraker_run(mr, c), check_limits)
        for i, cmd in enumerate(exp.lines):
            _moonraker_run(mr, cmd, replies, i)
        answers = [_moonraker_run(mr, c) for c in exp.readback]
        if _refused([*replies.values(), *answers]):
            result.printer_state = mr.state()
    except LinkTimeout as exc:
        result.settings = timeout_statuses(exp, replies, "Moonraker")
        raise PushError(f"Moonraker stopped answering ({exc.bare}); {result.summary()}", result,
                        redact(url)) from None
    return replies, "\n".join(a.text for a in answers)


def _save_eeprom(exp: Export, result: PushResult, link: GcodeLink) -> None:
    if not result.ok:
        result.notes.append("not saved: not every setting was verified on the printer")
        return
    for line in exp.save_lines:
        reply = link.send(line)
        if reply.errors:
            result.notes.append(f"{line} failed: {'; '.join(reply.errors)}")
            return
    result.saved = f"{' '.join(exp.save_lines)} sent (the printer stores it in EEPROM)"


#: family of a firmware that cannot persist the config from G-code -> (--save's default file, what
#: to do with it)
_SAVE_FILES = {
    "klipper": ("ringtune-input_shaper.cfg", "replace the [input_shaper] section of printer.cfg with it "
                "(SET_INPUT_SHAPER's values are lost at a restart, and SAVE_CONFIG does not save them)"),
    "rrf": ("ringtune-config.g", "add these lines to config.g (RepRapFirmware's M500 does not store M593)"),
}


def _save_target(exp: Export, save_path) -> Path | None:
    """Where ``--save`` writes the config lines (firmware that cannot persist them), else None."""
    if exp.save_lines or not exp.config_text:
        return None
    return Path(save_path or _SAVE_FILES[exp.record.family][0])


def _save_file(exp: Export, result: PushResult, save_path) -> None:
    path = _save_target(exp, save_path)
    if path is None:
        return
    if not result.ok:
        result.notes.append("config file not written: not every setting was verified on the printer")
        return
    try:
        path.write_text(exp.config_text)
    except OSError as exc:   # the settings are on the printer: report that, and the failed write
        result.notes.append(f"could not write {path}: {exc.strerror or exc}; the lines for "
                            f"{exp.config_target} are:\n{exp.config_text.rstrip()}")
        return
    result.save_file = str(path)
    result.saved = (f"{FIRMWARES[exp.firmware].title} cannot persist this from G-code: wrote {path}; "
                    f"{_SAVE_FILES[exp.record.family][1]}")
