"""export and push against the real thing: Klipper 84104bb (host + Linux-process MCU) and the
Moonraker release from the package index (session fixture ``real_klipper``, tests/real_klipper.py).

Truth here is Klipper itself: its config parser (a restart with the exported section comes up
"Ready"), its G-code parser (no "Unknown command", no "!!"), its own reports (``SET_INPUT_SHAPER``,
``SET_VELOCITY_LIMIT``), its state (``STATUS``, ``/printer/info``) and its log ("Transition to
shutdown"). One Klipper session; restarts only where another printer.cfg is needed (the exported
section; none), and the default one is restored at the end.
"""

from __future__ import annotations

import json
import re
import sys
import time
import urllib.request
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

from ringtune.agents.cli.main import main  # noqa: E402

pytestmark = [pytest.mark.timeout(600), pytest.mark.slow]

TUNED = {"firmware": "klipper", "shaper_x": "ei", "shaper_y": "mzv(n=5,t=1.1)", "freq_x": 51.2,
         "freq_y": 46.25, "damping_x": 0.08, "damping_y": 0.12, "accel": 4200, "freq_limit_hz": 25}

#: (config changes, key named, allowed range named): refused before anything is sent
HOSTILE = [
    ({"shaper_x": "ei(foo=1)"}, "shaper_x", "accepted: v_tol"),
    ({"shaper_x": "mzv(n=2)"}, "shaper_x", "n >= 3"),
    ({"shaper_x": "mzv(n=2)", "freq_x": 0}, "freq_x", "(0, 1000] Hz"),
    ({"shaper_x": "ei(v_tol=5)"}, "shaper_x", "(0, 1)"),
    ({"freq_x": 0.0004}, "freq_x", "[1, 1000] Hz"),
    ({"freq_x": 0}, "freq_x", "(0, 1000] Hz"),
    ({"freq_x": 1e6}, "freq_x", "[0, 1000]"),
    ({"damping_x": 1.5}, "damping_x", "[0, 0.99]"),
    ({"damping_x": -0.1}, "damping_x", "[0, 0.99]"),
    ({"shaper_x": "ei", "damping_x": 0.5}, "damping_x", "[0, 0.4]"),
    ({"shaper_x": "no_such_shaper"}, "shaper_x", "Klipper has zv, mzv, zvd, ei, 2hump_ei, 3hump_ei"),
    ({"shaper_x": "zvdd"}, "shaper_x", "it has zv, mzv, zvd, ei, 2hump_ei, 3hump_ei"),
]


def _write(tmp_path: Path, name: str, data: dict) -> Path:
    p = tmp_path / name
    p.write_text(json.dumps(data))
    return p


def _newest(url: str) -> tuple:
    with urllib.request.urlopen(f"{url}/server/gcode_store?count=1", timeout=10) as r:
        last = json.load(r)["result"]["gcode_store"]
    return (last[-1]["time"], last[-1]["message"]) if last else None


def _store(url: str, settle: float = 0.3, wait: float = 5.0) -> tuple:
    """The newest entry of Moonraker's console store (time, message), once it has stood for
    ``settle`` s (a command's "ok" lands just after its report): it changes with anything Klipper
    answers, on the pty or through Moonraker."""
    last, end = _newest(url), time.monotonic() + wait
    while time.monotonic() < end:
        time.sleep(settle)
        now = _newest(url)
        if now == last:
            break
        last = now
    return last


def _klipper_report(svc) -> dict[str, str]:
    """Klipper's own SET_INPUT_SHAPER and SET_VELOCITY_LIMIT reports, as key -> printed value."""
    text = svc.send("SET_INPUT_SHAPER", "SET_VELOCITY_LIMIT")
    return dict(re.findall(r"(\w+_[xy]|max_accel):\s*(\S+)", text))


def _ready(svc, log_mark: int) -> None:
    assert "Klipper state: Ready" in svc.status()
    assert "Transition to shutdown" not in svc.log.read_text(errors="replace")[log_mark:]


@pytest.fixture(scope="module")
def klipper(real_klipper):
    yield real_klipper
    real_klipper.restart(None)     # leave the session's Klipper with klipperd's own printer.cfg


def test_hostile_configs_are_refused_before_anything_is_sent(klipper, tmp_path, capsys):
    before = _klipper_report(klipper)
    mark = len(klipper.log.read_text(errors="replace"))
    store = _store(klipper.moonraker_url)
    for i, (change, key, allowed) in enumerate(HOSTILE):
        cfg = _write(tmp_path, f"hostile{i}.json", {**TUNED, **change})
        for target in (["--port", klipper.pty], ["--moonraker", klipper.moonraker_url]):
            assert main(["push", str(cfg), *target, "--json"]) == 2, change
            captured = capsys.readouterr()
            err = captured.err.strip()
            assert captured.out == "" and "\n" not in err, err
            assert f"{cfg}: {key}:" in err and allowed in err, (change, err)
    assert _store(klipper.moonraker_url) == store      # Klipper answered nothing: nothing was sent
    assert _klipper_report(klipper) == before
    _ready(klipper, mark)


def test_push_over_pty_and_moonraker_applies_and_reads_back_with_the_acceleration(klipper, tmp_path, capsys):
    cfg = _write(tmp_path, "best.json", TUNED)
    mark = len(klipper.log.read_text(errors="replace"))
    for target, accel in (([ "--port", klipper.pty], 4200.0), (["--moonraker", klipper.moonraker_url], 3700.0)):
        cfg = _write(tmp_path, "best.json", {**TUNED, "accel": accel})
        assert main(["push", str(cfg), *target, "--json"]) == 0
        d = json.loads(capsys.readouterr().out)
        assert d["ok"] and d["printer_state"] is None
        assert {k: v["status"] for k, v in d["settings"].items()} == {
            k: "applied" for k in ("x.freq", "y.freq", "x.damping", "y.damping", "x.type", "y.type", "accel")}
        # Klipper's own report, read independently of ringtune's parser
        rep = _klipper_report(klipper)
        assert (rep["shaper_type_x"], rep["shaper_freq_x"], rep["damping_ratio_x"]) == ("ei", "51.200", "0.080000")
        assert (rep["shaper_type_y"], rep["shaper_freq_y"], rep["damping_ratio_y"]) == \
            ("mzv(n=5,t=1.1)", "46.250", "0.120000")
        assert float(rep["max_accel"]) == accel
    # --no-accel leaves Klipper's acceleration as it was
    cfg = _write(tmp_path, "other.json", {**TUNED, "accel": 9000})
    assert main(["push", str(cfg), "--port", klipper.pty, "--no-accel", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert "accel" not in d["settings"] and float(_klipper_report(klipper)["max_accel"]) == 3700.0
    # --save: Klipper cannot save these from G-code, so the printer.cfg section is written
    saved = tmp_path / "is.cfg"
    # 9000 mm/s² is 2.4× the 3700 Klipper is configured for: refused unless --force (nothing sent)
    assert main(["push", str(cfg), "--moonraker", klipper.moonraker_url, "--save", "--save-file", str(saved)]) == 2
    assert "--force" in capsys.readouterr().err and not saved.exists()
    assert main(["push", str(cfg), "--moonraker", klipper.moonraker_url, "--save", "--save-file", str(saved),
                 "--force"]) == 0
    assert "damping_ratio_y: 0.12" in saved.read_text() and "printer.cfg" in capsys.readouterr().out
    _ready(klipper, mark)


def _klipper_corner(svc) -> dict[str, str]:
    """Klipper's own SET_VELOCITY_LIMIT report of its corner rule, as key -> printed value."""
    return dict(re.findall(r"(square_corner_velocity|minimum_cruise_ratio):\s*(\S+)", svc.send("SET_VELOCITY_LIMIT")))


def test_push_sets_the_visible_walls_corner_rule_and_reads_it_back(klipper, tmp_path, capsys):
    """A configuration tuned with a corner rule for the visible walls: push sets Klipper's
    square_corner_velocity and minimum_cruise_ratio and reads them back, over the pty and Moonraker."""
    before = _klipper_corner(klipper)
    mark = len(klipper.log.read_text(errors="replace"))
    try:
        for target, scv, mcr in ((["--port", klipper.pty], 7.5, 0.25),
                                 (["--moonraker", klipper.moonraker_url], 9.0, 0.0)):
            cfg = _write(tmp_path, "best.json", {**TUNED, "corner": scv, "min_cruise_ratio": mcr})
            assert main(["push", str(cfg), *target, "--json"]) == 0
            d = json.loads(capsys.readouterr().out)
            assert d["ok"]
            assert {k: d["settings"][k]["status"] for k in ("square_corner_velocity", "minimum_cruise_ratio")} == \
                {"square_corner_velocity": "applied", "minimum_cruise_ratio": "applied"}
            assert _klipper_corner(klipper) == {"square_corner_velocity": f"{scv:.6f}",
                                                "minimum_cruise_ratio": f"{mcr:.6f}"}
    finally:
        klipper.send("SET_VELOCITY_LIMIT SQUARE_CORNER_VELOCITY={square_corner_velocity} "
                     "MINIMUM_CRUISE_RATIO={minimum_cruise_ratio}".format(**before))
    assert _klipper_corner(klipper) == before
    _ready(klipper, mark)


def test_the_exported_command_part_sent_as_a_file_is_all_understood(klipper, tmp_path, capsys):
    cfg = _write(tmp_path, "best.json", TUNED)
    out = tmp_path / "shaping.gcode"
    assert main(["export", str(cfg), "-o", str(out)]) == 0
    assert (tmp_path / "shaping-printer.cfg").exists()
    lines = out.read_text().splitlines()
    assert any(ln.startswith(";") for ln in lines) and not any(ln.startswith("#") for ln in lines)
    transcript = klipper.send(*lines)
    replies = [ln for ln in transcript.splitlines() if ln.startswith("< ")]
    assert len([r for r in replies if r == "< ok"]) == len(lines)          # every line answered
    assert "Unknown command" not in transcript and "!!" not in transcript, transcript
    assert float(_klipper_report(klipper)["max_accel"]) == 4200.0


def test_a_line_that_shuts_klipper_down_is_reported_with_the_way_back(klipper, tmp_path, capsys, monkeypatch):
    """What push says when a line crashes Klipper (validation never lets one through, so the line
    is forced here): ``ei(foo=1)`` makes Klipper's host raise a TypeError and shut down."""
    import ringtune.hardware.push as push_mod
    from ringtune.hardware.dialects import export_config

    def crashing(config, firmware=None, accel=True):
        exp = export_config(config, firmware, accel)
        exp.lines[0] = exp.lines[0].replace("SHAPER_TYPE_X=ei", "SHAPER_TYPE_X=ei(foo=1)")
        return exp

    monkeypatch.setattr(push_mod, "export_config", crashing)
    cfg = _write(tmp_path, "best.json", TUNED)
    for target in (["--port", klipper.pty], ["--moonraker", klipper.moonraker_url]):
        assert main(["push", str(cfg), *target, "--json"]) == 1
        d = json.loads(capsys.readouterr().out)
        assert d["printer_state"]["state"] == "shutdown" and not d["ok"]
        assert d["settings"]["x.type"]["status"] == "not applied"
        assert main(["push", str(cfg), *target]) == 1
        text = capsys.readouterr().out
        assert "shutdown" in text and "FIRMWARE_RESTART" in text
    assert "Transition to shutdown" in klipper.log.read_text(errors="replace")


def test_the_exported_printer_cfg_section_parses_in_klipper(klipper, tmp_path, capsys):
    cfg = _write(tmp_path, "best.json", TUNED)
    assert main(["export", str(cfg), "--part", "config"]) == 0
    section = capsys.readouterr().out
    assert section.lstrip().startswith("#") and "[input_shaper]" in section
    klipper.restart(section)          # also recovers from the previous test's shutdown
    rep = _klipper_report(klipper)
    assert "Klipper state: Ready" in klipper.status()
    assert (rep["shaper_type_x"], rep["shaper_freq_x"], rep["damping_ratio_x"]) == ("ei", "51.200", "0.080000")
    assert (rep["shaper_type_y"], rep["shaper_freq_y"], rep["damping_ratio_y"]) == \
        ("mzv(n=5,t=1.1)", "46.250", "0.120000")


@pytest.mark.parametrize("firmware", ["klipper", "kalico"])
def test_a_config_with_per_axis_caps_still_parses_and_kalicos_part_keeps_them(klipper, tmp_path, capsys, firmware):
    """A tuned configuration that carries per-axis caps (a limited_corexy printer's): mainline
    Klipper's part is unchanged (the caps are said in a note: it has none); Kalico's keeps them with
    its own key names (limited_*.py: max_x_accel, max_y_accel), beside max_accel, as comment lines
    for the [printer] section; both parts still parse in real Klipper."""
    # Kalico's shaper_defs.py has no parametrised shapers (mzv(n=…, t=…) is mainline Klipper's)
    shaper_y = TUNED["shaper_y"] if firmware == "klipper" else "mzv"
    cfg = _write(tmp_path, "best.json", {**TUNED, "firmware": firmware, "shaper_y": shaper_y,
                                         "max_accel_x": 10010, "max_accel_y": 4130})
    assert main(["export", str(cfg), "--part", "config"]) == 0
    section = capsys.readouterr().out
    has_caps = "#   max_x_accel: 10010" in section and "#   max_y_accel: 4130" in section
    assert has_caps == (firmware == "kalico")
    assert "# and in the [printer] section: max_accel: 4200" in section
    klipper.restart(section)
    assert "Klipper state: Ready" in klipper.status()
    assert _klipper_report(klipper)["shaper_type_x"] == "ei"


def test_a_line_that_fails_gives_the_same_report_over_pty_and_moonraker(klipper, tmp_path, capsys):
    """Klipper without [input_shaper]: SET_INPUT_SHAPER is an unknown command (an info line, not an
    error); the acceleration still applies. Same per-setting report, text and JSON, same exit."""
    klipper.restart("")
    cfg = _write(tmp_path, "best.json", TUNED)
    texts, jsons = [], []
    for target in (["--port", klipper.pty], ["--moonraker", klipper.moonraker_url]):
        assert main(["push", str(cfg), *target]) == 1
        texts.append(capsys.readouterr().out.splitlines()[1:])       # first line names the port
        assert main(["push", str(cfg), *target, "--json"]) == 1
        d = json.loads(capsys.readouterr().out)
        d.pop("port")
        jsons.append(d)
    assert texts[0] == texts[1] and jsons[0] == jsons[1]
    d = jsons[0]
    assert d["settings"]["accel"]["status"] == "applied"
    assert d["settings"]["x.freq"]["status"] == "not applied"
    assert 'Unknown command:"SET_INPUT_SHAPER"' in d["settings"]["x.freq"]["detail"]
    assert d["printer_state"]["state"] == "ready"
    assert "printer state after the failed line: ready" in "\n".join(texts[0])
