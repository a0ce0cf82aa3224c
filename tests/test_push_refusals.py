"""Issue 25: push against the fake printers. Every line a firmware refuses is reported in the
firmware's own words; a printer answering in another firmware's words is named; after a partial
push the report says what stays in force and how to undo it; a value far outside what the printer
is configured for is refused before anything is sent (--force sends it); a printer that shut down
holds nothing of the push; the exit statuses are the documented ones (0, 1, 2)."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import pytest

sys.path.insert(0, os.path.dirname(__file__))

from fake_printer import FakeMoonraker, FakePrinter, KlipperCore, MarlinCore  # noqa: E402

from ringtune.agents.cli.main import main  # noqa: E402
from ringtune.hardware.push import push  # noqa: E402
from ringtune.hardware.push_status import APPLIED, NOT_APPLIED  # noqa: E402
from ringtune.shaping.config import TuneConfig  # noqa: E402
from ringtune.shaping.errors import RingtuneError  # noqa: E402

ZV = TuneConfig(firmware="marlin", shaper_x="zv", shaper_y="zv", freq_x=45.0, freq_y=38.0, damping_x=0.1,
                damping_y=0.1, accel=450.0)           # under the fake Marlin's M201 caps (500)
KLIPPER = TuneConfig(firmware="klipper", shaper_x="ei", shaper_y="mzv", freq_x=51.4, freq_y=46.6, accel=4000.0)


def _status(result):
    return {s.key: (s.status, s.detail) for s in result.settings}


def test_a_marlin_without_input_shaping_is_reported_in_its_own_words_and_the_way_back_given():
    with FakePrinter("marlin", core=MarlinCore(input_shaping=False)) as fp:
        r = push(ZV, port=fp.url, timeout=2.0)
    st = _status(r)
    assert not r.ok and st["x.freq"][0] == NOT_APPLIED
    assert st["x.freq"][1].startswith('printer said: Unknown command: "M593 X') and "missing" not in st["x.freq"][1]
    assert st["accel"][0] == APPLIED
    undo = [n for n in r.notes if n.startswith("still in force")]
    assert len(undo) == 1 and "accel" in undo[0] and "M501" in undo[0]
    assert not any("answers as" in n for n in r.notes)          # it is Marlin: no wrong-firmware note


def test_a_frequency_marlin_refuses_is_reported_with_its_message():
    cfg = TuneConfig(**{**ZV.to_dict(), "freq_x": 35.0, "freq_y": 38.0})
    with FakePrinter("marlin", core=MarlinCore(min_freq=40.0)) as fp:
        r = push(cfg, port=fp.url, timeout=2.0)
    st = _status(r)
    assert st["x.freq"] == (NOT_APPLIED, "printer said: ?Frequency (F) must be greater than 40.00 or 0 to disable")
    assert "different value" not in st["x.freq"][1]


def test_marlin_lines_sent_to_klipper_name_the_firmware_that_answered():
    cfg = TuneConfig(**{**ZV.to_dict(), "firmware": "marlin-ftm"})
    with FakePrinter("klipper") as fp:
        r = push(cfg, port=fp.url, timeout=2.0)
    assert not r.ok
    note = next(n for n in r.notes if "answers as" in n)
    assert "Klipper" in note and 'Unknown command:"M493"' in note and "--firmware klipper" in note


def test_klipper_lines_sent_to_marlin_name_the_firmware_that_answered():
    with FakePrinter("marlin") as fp:
        r = push(KLIPPER, port=fp.url, timeout=2.0)
    assert not r.ok
    note = next(n for n in r.notes if "answers as" in n)
    assert "Marlin" in note and 'Unknown command: "SET_INPUT_SHAPER' in note and "--firmware marlin" in note


def test_an_acceleration_far_above_what_the_printer_is_configured_for_is_refused_before_sending():
    far = TuneConfig(**{**KLIPPER.to_dict(), "accel": 25000.0})
    with FakePrinter("klipper") as fp:
        with pytest.raises(RingtuneError, match=r"8\.3× the highest the printer is configured for \(3000"):
            push(far, port=fp.url, timeout=2.0, check_limits=True)
        assert fp.core.max_accel == 3000.0 and fp.core.axes["x"][1] == 0.0      # nothing set
        r = push(far, port=fp.url, timeout=2.0, check_limits=False)            # --force
        assert fp.core.max_accel == 25000.0 and r.ok


def test_a_shaper_frequency_far_outside_printers_is_refused_before_the_port_opens():
    wild = TuneConfig(**{**KLIPPER.to_dict(), "freq_x": 250.0})
    with pytest.raises(RingtuneError, match="250 Hz is far outside 10-150 Hz"):
        push(wild, port="/nonexistent/port", check_limits=True)


@pytest.mark.parametrize("transport", ["pty", "moonraker"])
def test_a_printer_that_shut_down_holds_nothing_and_the_promised_effects_are_withdrawn(transport):
    core = KlipperCore(shutdown_on="SET_VELOCITY_LIMIT")
    if transport == "pty":
        with FakePrinter("klipper", core=core) as fp:
            r = push(KLIPPER, port=fp.url, timeout=2.0)
    else:
        with FakeMoonraker(core=core) as mr:
            r = push(KLIPPER, moonraker=mr.url, timeout=2.0)
    assert not r.ok and r.printer_state["state"] == "shutdown"
    assert all(s.status == NOT_APPLIED and s.detail.startswith("the printer is shutdown") for s in r.settings)
    assert not any("acceleration becomes" in n for n in r.notes)
    assert "FIRMWARE_RESTART" in r.text()


def test_exit_statuses_are_the_documented_ones(tmp_path, capsys):
    ok, far = tmp_path / "ok.json", tmp_path / "far.json"
    KLIPPER.save(ok)
    TuneConfig(**{**KLIPPER.to_dict(), "accel": 25000.0}).save(far)
    zv = tmp_path / "zv.json"
    ZV.save(zv)
    with FakePrinter("klipper") as fp:
        assert main(["push", str(ok), "--port", fp.url, "--timeout", "2"]) == 0
        assert main(["push", str(far), "--port", fp.url, "--timeout", "2"]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "--force" in err
        assert main(["push", str(far), "--port", fp.url, "--timeout", "2", "--force", "--json"]) == 0
        assert json.loads(capsys.readouterr().out)["ok"] is True
    with FakePrinter("marlin", core=MarlinCore(input_shaping=False)) as fp:
        assert main(["push", str(zv), "--port", fp.url, "--timeout", "2", "--json"]) == 1
        res = json.loads(capsys.readouterr().out)
        assert res["settings"]["x.freq"]["detail"].startswith("printer said: Unknown command")
    assert "exit status" in Path(__file__).parent.parent.joinpath("agents/cli/push.py").read_text()
    parser_help = _help_text(capsys)
    assert "0  every setting applied" in parser_help and "1  sent, but something not applied" in parser_help


def _help_text(capsys) -> str:
    with pytest.raises(SystemExit):
        main(["push", "--help"])
    return capsys.readouterr().out
