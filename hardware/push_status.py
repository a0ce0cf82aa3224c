"""What a push reports per setting, and the result it returns.

Each setting the export expects (:attr:`ringtune.hardware.export.Export.expected`, plus Marlin's
``limit``) is ``applied`` (acknowledged and read back as meant), ``not applied`` (with why: the
printer's refusal, a line never sent or never acknowledged, a different value read back, or an
acceleration the printer's own per-axis caps hold lower), ``acknowledged (no read-back)`` (Marlin's
``M201 F S``; a line acknowledged before the printer stopped answering) or ``not sent (dry run)``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

from ringtune.hardware.export import Export
from ringtune.hardware.link import Reply
from ringtune.hardware.readback import compare, parse_report
from ringtune.shaping.firmware import FIRMWARES

APPLIED, NOT_APPLIED, ACKED, DRY = "applied", "not applied", "acknowledged (no read-back)", "not sent (dry run)"


@dataclass
class SettingStatus:
    key: str
    meant: object
    reported: object = None
    status: str = NOT_APPLIED
    detail: str = ""


@dataclass
class PushResult:
    """Outcome of a push; ``to_dict()`` is the ``--json`` output of ``ringtune push``."""

    firmware: str
    port: str
    dry_run: bool
    wire: list[str] = field(default_factory=list)
    settings: list[SettingStatus] = field(default_factory=list)
    resets: int = 0
    saved: str | None = None
    save_file: str | None = None
    notes: list[str] = field(default_factory=list)
    printer_state: dict | None = None
    ok: bool = False

    def to_dict(self) -> dict:
        d = asdict(self)
        d["settings"] = {s.key: {k: v for k, v in asdict(s).items() if k != "key"} for s in self.settings}
        return d

    def summary(self) -> str:
        held: dict[bool, list[str]] = {True: [], False: []}
        for s in self.settings:
            held[s.status in (APPLIED, ACKED)].append(s.key)
        return (f"applied: {', '.join(held[True]) or 'nothing'}; "
                f"not applied: {', '.join(held[False]) or 'nothing'}")

    def text(self) -> str:
        out = [f"{FIRMWARES[self.firmware].title} on {self.port}"]
        if self.dry_run:
            out[0] += " (dry run)"
            out.append("would send exactly:")
            out += ["  " + w for w in self.wire]
        for s in self.settings:
            rep = "" if s.reported is None else f" (printer reports {s.reported})"
            out.append(f"  {s.key:<12} {str(s.meant):<10} {s.status}{rep}{' - ' + s.detail if s.detail else ''}")
        out += [f"note: {n}" for n in self.notes]
        if self.printer_state:
            out.append(state_sentence(self.printer_state))
        if self.saved:
            out.append(f"saved: {self.saved}")
        return "\n".join(out)


def state_sentence(state: dict) -> str:
    """What the printer's state after a failed line means for the user."""
    if state.get("state") == "ready":
        return "printer state after the failed line: ready (it did not shut down)"
    if state.get("state") in (None, "unknown"):
        return f"printer state after the failed line: unknown ({state.get('message') or 'no answer'})"
    msg = " ".join(str(state.get("message") or "").split())
    return (f"printer state after the failed line: {state['state']} ({msg}); the printer is not ready: "
            f"recover with FIRMWARE_RESTART, then push again")


def judge_settings(result: PushResult, exp: Export, replies: dict[int, Reply], report: str | None) -> None:
    """Each setting's status from the replies and the read-back; ``ok`` when all hold."""
    result.settings = setting_statuses(exp, replies, report, exp.firmware)
    result.ok = all(s.status in (APPLIED, ACKED) for s in result.settings)


def setting_statuses(exp: Export, replies: dict[int, Reply], report: str | None, firmware: str) -> list[SettingStatus]:
    reported = parse_report(firmware, report) if report is not None else {}
    cmp = compare(exp.expected, reported)
    out = [_status(key, meant, cmp[key], replies.get(exp.setting_lines.get(key, 0)), report)
           for key, meant in exp.expected.items()]
    _judge_axis_caps(out, exp, reported)
    if "limit" in exp.setting_lines:
        idx = exp.setting_lines["limit"]
        st = SettingStatus("limit", exp.lines[idx])
        reply = replies.get(idx)
        if reply is not None and not reply.errors:
            st.status = ACKED
        else:
            st.detail = "printer said: " + "; ".join(reply.errors) if reply else "line not sent"
        out.append(st)
    return out


def _status(key: str, meant, cmp: dict, reply: Reply | None, report: str | None) -> SettingStatus:
    """One setting: applied when acknowledged and read back as meant; else why not."""
    st = SettingStatus(key, meant, cmp["reported"])
    if reply is None:
        st.detail = "line not sent" if report is None else "line never acknowledged"
    elif reply.errors:
        st.detail = "printer said: " + "; ".join(reply.errors)
    elif report is None:
        st.status, st.detail = NOT_APPLIED, "acknowledged but not read back"
    elif cmp["ok"]:
        st.status = APPLIED
    else:
        st.detail = "missing from the printer's report" if cmp["reported"] is None else "printer reports a different value"
    return st


def _caps_below(reported: dict, accel: float) -> dict[str, float]:
    """The read-back X/Y caps (mm/s²) below ``accel``."""
    caps = {ax: float(reported[f"max_accel_{ax}"].value) for ax in "xy" if f"max_accel_{ax}" in reported}
    return {ax: v for ax, v in caps.items() if v < accel}


def _judge_axis_caps(statuses: list[SettingStatus], exp: Export, reported: dict) -> None:
    """An acceleration the printer's own per-axis caps (read back) hold lower is not claimed as
    applied: the printer would not print at it. Caps the config itself sets are settings of their
    own (it was planned with them)."""
    st = {s.key: s for s in statuses}.get("accel")
    if st is None or st.status != APPLIED or {"max_accel_x", "max_accel_y"} & exp.expected.keys():
        return
    low = _caps_below(reported, float(st.meant))
    if not low:
        return
    caps = ", ".join(f"{ax.upper()} {v:g}" for ax, v in low.items())
    raise_line = exp.record.axis_accel_set.format(x=f"{float(st.meant):g}", y=f"{float(st.meant):g}")
    st.status = NOT_APPLIED
    st.detail = (f"set, but the printer's own per-axis caps ({caps} mm/s²) hold those moves lower, so it "
                 f"will not print at {float(st.meant):g}: push a config that carries the caps it was planned "
                 f"with (max_accel_x/max_accel_y, which tune writes), or raise them ({raise_line})")


def timeout_statuses(exp: Export, replies: dict[int, Reply], who: str) -> list[SettingStatus]:
    """Statuses when ``who`` stopped answering before the read-back: a setting whose line was
    acknowledged without error was carried out (Marlin, RRF and Klipper acknowledge after executing;
    Moonraker answers ``ok`` once the script has run); the others were not applied."""
    out = setting_statuses(exp, replies, None, exp.firmware)
    for s in out:
        idx = exp.setting_lines.get(s.key, -1)
        if idx in replies and not replies[idx].errors:
            s.status, s.detail = ACKED, f"acknowledged before {who} stopped answering"
    return out
