"""Push over a fake printer (pty and loopback TCP) that misbehaves the ways real ones do."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fake_printer import FakeMoonraker, FakePrinter, Faults  # noqa: E402

from ringtune.hardware.link import GcodeLink, LinkTimeout, crc16_ccitt, frame, redact  # noqa: E402
from ringtune.hardware.push import PushError, dry_run_wire, push  # noqa: E402
from ringtune.hardware.push_status import APPLIED  # noqa: E402
from ringtune.hardware.dialects import export_config  # noqa: E402
from ringtune.shaping.config import TuneConfig  # noqa: E402
from ringtune.shaping.errors import RingtuneError  # noqa: E402

pytestmark = pytest.mark.timeout(60)

MARLIN = TuneConfig(firmware="marlin", shaper_x="zv", shaper_y="zv", freq_x=41.5, freq_y=37.25,
                    damping_x=0.08, damping_y=0.12, freq_limit_hz=25, min_speed_factor=0.3,
                    freq_limit_method="marlin")


def test_frames_match_the_reference_examples():
    assert frame(0, "M110 N0") == b"N0 M110 N0*125"
    assert frame(1, "G28") == b"N1 G28*18"
    assert frame(2, "M593 X F40 D0.1") == b"N2 M593 X F40 D0.1*127"
    assert crc16_ccitt(b"N100 G0 X100 F6000") == 51369       # RRF docs example
    assert frame(100, "G0 X100 F6000", crc=True) == b"N100 G0 X100 F6000*51369"


def test_redact_hides_secrets():
    assert redact("http://user:hunter2@printer.local:7125/?token=abc&x=1") == \
        "http://***@printer.local:7125/?token=***&x=1"
    assert redact("/dev/ttyUSB0") == "/dev/ttyUSB0"
    assert "pw" not in redact("rfc2217://me:pw@10.0.0.2:2217")


def _all_faults(**kw) -> Faults:
    # received-line indices: 0 is the handshake; faults land on the settings lines and the read-back
    return Faults(corrupt={1}, resend={2}, garbage={2, 5}, temps={1, 3, 6}, busy={3}, reset={4}, **kw)


@pytest.mark.parametrize("transport, ok_after_resend", [("pty", True), ("tcp", False)])
def test_marlin_push_survives_every_fault(transport, ok_after_resend):
    faults = _all_faults(busy_s=1.3, ok_after_resend=ok_after_resend)
    with FakePrinter("marlin", faults, transport=transport) as fp:
        r = push(MARLIN, port=fp.url, timeout=1.0, save=True)   # busy lasts longer than the timeout
    sent = export_config(MARLIN).lines
    # after the reset, every setting line was carried out exactly once, in order
    assert fp.resets == 1
    assert fp.sessions[0] == sent[:1]        # before the reset: X once, despite its two resends
    assert fp.executed == sent + ["M593", "M500"]
    assert r.ok and r.resets == 1 and any("reset" in n for n in r.notes)
    assert {s.key: s.status for s in r.settings} == {
        "x.freq": APPLIED, "x.damping": APPLIED, "y.freq": APPLIED, "y.damping": APPLIED,
        "limit": "acknowledged (no read-back)"}
    assert fp.core.shaping == {"x": [41.5, 0.08], "y": [37.25, 0.12]} and fp.core.limit == (25.0, 30)
    assert fp.core.eeprom["shaping"] == {"x": [41.5, 0.08], "y": [37.25, 0.12]}
    assert "M500" in r.saved


@pytest.mark.parametrize("transport", ["pty", "tcp"])
def test_line_noise_glued_to_ok_start_and_resend_is_not_a_lost_answer(transport):
    """Boards that reset through a bootloader at another baud rate send bytes of noise in front
    of ``start``; noise on the line can land in front of any ``ok`` or ``Resend:``. Each must still
    be recognised: a missed ``start`` would leave the push waiting for an ``ok`` that never comes."""
    # received lines: 0 handshake, 1 X (asked again), 2 X again, 3 Y -> reset, 4 handshake, 5.. again
    faults = Faults(noise={0, 1, 2, 3, 4, 6}, resend={1}, reset={3}, temps={6})
    with FakePrinter("marlin", faults, transport=transport) as fp:
        t0 = time.monotonic()
        r = push(MARLIN, port=fp.url, timeout=1.0, save=True)
        elapsed = time.monotonic() - t0
    assert elapsed < 3.0                     # no answer was waited out
    assert fp.resets == 1 and r.resets == 1
    assert fp.sessions[0] == export_config(MARLIN).lines[:1]      # before the reset: X once
    assert fp.executed == export_config(MARLIN).lines + ["M593", "M500"]
    assert r.ok and fp.core.shaping == {"x": [41.5, 0.08], "y": [37.25, 0.12]}


def test_rrf_push_retries_silently_dropped_lines_and_verifies():
    cfg = TuneConfig(firmware="rrf", shaper_x="zvd", shaper_y="zvd", freq_x=40.5, freq_y=40.5,
                     damping_x=0.1, damping_y=0.1)
    faults = Faults(corrupt={1, 2}, resend={3}, temps={1}, garbage={3}, reset={4})
    with FakePrinter("rrf", faults, transport="pty") as fp:
        r = push(cfg, port=fp.url, timeout=3.0, save=True, save_path=Path(fp.url).name + ".g",
                 link_options={"retry_after": 0.3})
    assert fp.sessions[0] == []              # every copy before the reset was lost or refused
    assert fp.executed == ['M593 P"zvd" F40.5 S0.1', "M593"]
    assert r.ok and r.resets == 1
    assert {s.key: (s.status, s.reported) for s in r.settings} == {
        "all.type": (APPLIED, "zvd"), "all.freq": (APPLIED, 40.5), "all.damping": (APPLIED, 0.1)}
    saved = Path(r.save_file)
    assert saved.read_text() == 'M593 P"zvd" F40.5 S0.1\n' and "config.g" in r.saved
    saved.unlink()


def test_rrf_error_line_is_reported():
    with FakePrinter("rrf", transport="tcp") as fp, GcodeLink(fp.url, "rrf", timeout=2.0) as link:
        reply = link.send("M593 P\"zvd\" F2")
        assert reply.errors == ["M593: parameter 'F' too low"]
        assert "disabled" in link.send("M593").text


def test_rrf_crc_option_is_accepted_by_number_format():
    wire = dry_run_wire(export_config(TuneConfig(firmware="rrf", shaper_x="mzv", shaper_y="mzv")), crc=True)
    assert wire[0] == "N0 M110 N0*%05d" % crc16_ccitt(b"N0 M110 N0")
    assert all(len(w.rsplit("*", 1)[1]) == 5 for w in wire)


@pytest.mark.parametrize("fw, shaper, save_key", [("marlin-ftm", "mzv", "M500"), ("prusa", "ei", "M593 W")])
def test_ftm_and_prusa_push_and_save(fw, shaper, save_key):
    cfg = TuneConfig(firmware=fw, shaper_x=shaper, shaper_y="zv", freq_x=48.0, freq_y=36.5,
                     damping_x=0.1, damping_y=0.15)
    with FakePrinter(fw, Faults(temps={2}, resend={2}), transport="tcp") as fp:
        r = push(cfg, port=fp.url, timeout=2.0, save=True)
    assert r.ok, r.text()
    assert fp.executed == export_config(cfg).lines + export_config(cfg).readback + [save_key]
    assert save_key in r.saved and fp.core.eeprom is not None


def test_printer_that_stops_answering_fails_within_timeout_and_says_what_was_applied():
    faults = Faults(hang_after=1)     # executes the X line, then goes silent
    with FakePrinter("marlin", faults, transport="pty") as fp:
        t0 = time.monotonic()
        with pytest.raises(PushError) as exc:
            push(MARLIN, port=fp.url, timeout=0.8)
        elapsed = time.monotonic() - t0
    assert 0.8 <= elapsed < 0.8 + 1.0        # the timeout, not some multiple of it
    msg = str(exc.value)
    assert "stopped answering" in msg and "no answer to 'M593 Y F37.25 D0.12' within 0.8 s" in msg
    assert "applied: x.freq, x.damping; not applied: y.freq, y.damping, limit" in msg
    statuses = {s.key: s.status for s in exc.value.result.settings}
    assert statuses["x.freq"].startswith("acknowledged") and statuses["y.freq"] == "not applied"


@pytest.mark.parametrize("fw", ["marlin", "rrf"])
def test_printer_silent_from_the_handshake_says_nothing_was_applied(fw):
    cfg = MARLIN if fw == "marlin" else TuneConfig(firmware="rrf", shaper_x="zvd", shaper_y="zvd")
    keys = list(export_config(cfg).expected) + (["limit"] if fw == "marlin" else [])
    with FakePrinter(fw, Faults(hang_after=0), transport="tcp") as fp:
        t0 = time.monotonic()
        with pytest.raises(PushError) as exc:
            push(cfg, port=fp.url, timeout=0.6)
        elapsed = time.monotonic() - t0
    assert 0.6 <= elapsed < 0.6 + 1.0
    assert fp.executed == []
    assert "no answer to 'M110 N0' within 0.6 s" in str(exc.value)
    assert f"applied: nothing; not applied: {', '.join(keys)}" in str(exc.value)
    assert all(s.status == "not applied" for s in exc.value.result.settings)


def test_klipper_through_pty_without_checksums():
    cfg = TuneConfig(firmware="klipper", shaper_x="ei", shaper_y="mzv", freq_x=51.2, freq_y=46.2,
                     damping_x=0.08, damping_y=0.1, freq_limit_hz=20)
    log: list[str] = []
    with FakePrinter("klipper", transport="pty") as fp:
        r = push(cfg, port=fp.url, timeout=2.0, log=log.append)
    assert r.ok
    assert fp.executed == ["SET_INPUT_SHAPER SHAPER_FREQ_X=51.2 SHAPER_FREQ_Y=46.2 DAMPING_RATIO_X=0.08 "
                           "DAMPING_RATIO_Y=0.1 SHAPER_TYPE_X=ei SHAPER_TYPE_Y=mzv", "SET_INPUT_SHAPER"]
    assert not any("*" in line or line.startswith("> N") for line in log)
    assert fp.core.axes == {"x": ["ei", 51.2, 0.08], "y": ["mzv", 46.2, 0.1]}
    assert any("ringtune limit FILE.gcode --freq-limit 20" in n for n in r.notes)


def test_klipper_through_moonraker_never_logs_secrets(tmp_path):
    cfg = TuneConfig(firmware="klipper", shaper_x="mzv", shaper_y="2hump_ei", freq_x=44.0, freq_y=60.0,
                     damping_x=0.1, damping_y=0.1)
    log: list[str] = []
    with FakeMoonraker(api_key="k3y") as mr:
        url = mr.url.replace("http://", "http://bob:s3cret@") + "/?token=t0ken"
        r = push(cfg, moonraker=url, api_key="k3y", timeout=2.0, save=True,
                 save_path=tmp_path / "is.cfg", log=log.append)
        with pytest.raises(RingtuneError, match="HTTP 401"):
            push(cfg, moonraker=mr.url, api_key="wrong", timeout=2.0)
    assert r.ok, r.text()
    assert mr.scripts[0].startswith("SET_INPUT_SHAPER SHAPER_FREQ_X=44 SHAPER_FREQ_Y=60")
    assert mr.scripts[1] == "SET_INPUT_SHAPER"
    assert fp_axes(mr) == {"x": ["mzv", 44.0, 0.1], "y": ["2hump_ei", 60.0, 0.1]}
    text = "\n".join(log) + r.text() + str(r.to_dict())
    for secret in ("s3cret", "t0ken", "k3y"):
        assert secret not in text
    # the log names each request by its real path, with the token redacted in the query
    assert f"POST {mr.url}/printer/gcode/script?token=***" in log
    assert f"GET {mr.url}/server/gcode_store?count=50&token=***" in log
    assert "damping_ratio_y: 0.1" in (tmp_path / "is.cfg").read_text()
    assert "printer.cfg" in r.saved


@pytest.mark.parametrize("hang_after, applied", [(0, False), (1, True)])
def test_moonraker_that_stops_answering_fails_within_timeout_and_says_what_was_applied(hang_after, applied):
    """hang_after=1: SET_INPUT_SHAPER ran ({"result": "ok"}), then the read-back got no answer."""
    cfg = TuneConfig(firmware="klipper", shaper_x="mzv", shaper_y="ei", freq_x=44.0, freq_y=60.0)
    keys = list(export_config(cfg).expected)
    with FakeMoonraker(hang_after=hang_after) as mr:
        t0 = time.monotonic()
        with pytest.raises(PushError) as exc:
            push(cfg, moonraker=mr.url, timeout=0.6)
        elapsed = time.monotonic() - t0
    assert 0.6 <= elapsed < 0.6 + 1.0
    msg = str(exc.value)
    assert "Moonraker stopped answering" in msg
    if applied:
        assert f"applied: {', '.join(keys)}; not applied: nothing" in msg
        assert mr.core.axes["x"] == ["mzv", 44.0, 0.1]
    else:
        assert f"applied: nothing; not applied: {', '.join(keys)}" in msg


def fp_axes(mr):
    return mr.core.axes


def test_dry_run_prints_exact_wire_and_needs_no_port():
    r = push(MARLIN, dry_run=True, save=True)
    assert r.wire == ["N0 M110 N0*125", "N1 M593 X F41.5 D0.08*95", "N2 M593 Y F37.25 D0.12*101",
                      "N3 M201 F25 S30*50", "N4 M593*40", "N5 M500*35"]
    assert all(s.status == "not sent (dry run)" for s in r.settings)


def test_push_refuses_without_port():
    with pytest.raises(RingtuneError, match="explicit port"):
        push(MARLIN)


def test_link_times_out_on_silence():
    with FakePrinter("marlin", Faults(hang_after=0), transport="tcp") as fp:
        link = GcodeLink(fp.url, "marlin", timeout=0.5)
        with pytest.raises(LinkTimeout, match="no answer to 'M110 N0' within 0.5 s"):
            link.open()
        link.close()


class ScriptedSerial:
    """A serial port whose printer answers each written line from a script (list per write)."""

    def __init__(self, answers):
        self.answers = list(answers)
        self.written: list[bytes] = []
        self.buf = b""
        self.in_waiting = 0

    def write(self, data):
        self.written.append(data)
        if self.answers:
            self.buf += "".join(a + "\n" for a in self.answers.pop(0)).encode()
        self.in_waiting = len(self.buf)

    def flush(self):
        pass

    def read(self, n):
        out, self.buf = self.buf[:n], self.buf[n:]
        self.in_waiting = len(self.buf)
        if not out:
            time.sleep(0.01)
        return out

    def close(self):
        pass


def test_resend_of_earlier_lines_replays_exactly_those_lines():
    answers = [["ok"],                       # N0 M110 handshake
               ["ok"],                       # N1 accepted
               ["Resend: 1", "ok"],          # N2: printer lost track and asks again from N1
               ["ok"],                       # replayed N1
               ["ok"]]                       # replayed N2
    ser = ScriptedSerial(answers)
    link = GcodeLink("scripted", "marlin", timeout=1.0, serial_obj=ser)
    link.open()
    link.send("M593 X F40 D0.1")
    link.send("M593 Y F40 D0.1")
    assert ser.written == [b"N0 M110 N0*125\n", frame(1, "M593 X F40 D0.1") + b"\n",
                           frame(2, "M593 Y F40 D0.1") + b"\n", frame(1, "M593 X F40 D0.1") + b"\n",
                           frame(2, "M593 Y F40 D0.1") + b"\n"]


def test_repeated_resend_gives_up():
    ser = ScriptedSerial([["ok"]] + [["Resend: 1", "ok"]] * 20)
    link = GcodeLink("scripted", "marlin", timeout=1.0, max_resends=3, serial_obj=ser)
    link.open()
    with pytest.raises(RingtuneError, match="asked for line N1 4 times"):
        link.send("M593")


def test_loop_url_opens_through_pyserial():
    # loop:// returns what is written: in Klipper mode the line "ok" is its own acknowledgement
    with GcodeLink("loop://", "klipper", timeout=1.0) as link:
        assert link.send("ok").errors == []


def test_save_file_in_a_missing_directory_is_refused_before_anything_is_sent(tmp_path):
    cfg = TuneConfig(firmware="rrf", shaper_x="zvd", shaper_y="zvd", freq_x=40.5, freq_y=40.5)
    with FakePrinter("rrf", transport="tcp") as fp:
        with pytest.raises(RingtuneError, match="no such directory"):
            push(cfg, port=fp.url, timeout=1.0, save=True, save_path=tmp_path / "nope" / "c.g")
    assert fp.executed == [] and fp.received == 0


@pytest.mark.parametrize("fw, shaper, accel_of", [
    ("marlin", "zv", lambda core: core.accel["P"]),
    ("rrf", "zvd", lambda core: core.accel["P"]),
    ("prusa", "mzv", lambda core: core.accel["P"]),
    ("klipper", "mzv", lambda core: core.max_accel)])
def test_push_applies_and_reads_back_the_acceleration_and_no_accel_leaves_it(fw, shaper, accel_of):
    # the fakes' M201 X/Y (500, 3000) are below 4250: the config carries the caps it was planned with
    caps = {} if fw == "klipper" else {"max_accel_x": 4250.0, "max_accel_y": 4250.0}
    cfg = TuneConfig(firmware=fw, shaper_x=shaper, shaper_y=shaper, freq_x=40.5, freq_y=40.5, accel=4250.0,
                     **caps)
    with FakePrinter(fw, transport="tcp") as fp:
        before = accel_of(fp.core)
        r = push(cfg, port=fp.url, timeout=2.0, accel=False)
        assert r.ok and "accel" not in {s.key for s in r.settings} and accel_of(fp.core) == before
        assert not any(c.startswith(("M201", "M204", "SET_VELOCITY_LIMIT")) for c in fp.executed)
        r = push(cfg, port=fp.url, timeout=2.0)
    assert accel_of(fp.core) == 4250.0
    st = next(s for s in r.settings if s.key == "accel")
    assert r.ok and st.status == APPLIED and st.reported == 4250.0
    assert any("override this acceleration" in n for n in r.notes)


def test_klipper_unknown_command_counts_as_a_failed_line_on_pty_and_moonraker():
    """Klipper answers an unknown command with an info line, not "!!" (gcode.py); a printer.cfg
    without [input_shaper] has no SET_INPUT_SHAPER. Both links give the same per-setting report."""
    from fake_printer import KlipperCore

    cfg = TuneConfig(firmware="klipper", shaper_x="ei", shaper_y="mzv", freq_x=51.2, freq_y=46.2, accel=4000.0)
    with FakePrinter("klipper", core=KlipperCore(input_shaper=False)) as fp:
        a = push(cfg, port=fp.url, timeout=2.0)
    with FakeMoonraker(core=KlipperCore(input_shaper=False)) as mr:
        b = push(cfg, moonraker=mr.url, timeout=2.0)
    for r in (a, b):
        assert not r.ok and r.printer_state == {"state": "ready", "message": "Printer is ready"}
        st = {s.key: (s.status, s.detail) for s in r.settings}
        assert st["x.freq"] == ("not applied", 'printer said: Unknown command:"SET_INPUT_SHAPER"')
        assert st["accel"][0] == APPLIED
    assert a.text().splitlines()[1:] == b.text().splitlines()[1:]
