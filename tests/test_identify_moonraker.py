"""``identify --moonraker`` against the real Moonraker (fixture ``real_klipper``): the newest resonance
files and printer.cfg fetched through the file API give the same TOML as ``identify`` on the same
files and configuration given locally."""

from __future__ import annotations

import json
import os
import shutil
import urllib.request

import pytest

from ringtune.agents.cli.main import main
from ringtune.hardware.moonraker_files import newest_tests, resonance_test_of

ENDER = "accel/klipper_psd/bassco_ender3"
X = "resonances_x_20210821_152037.csv"
Y = "resonances_y_20210630_230110.csv"


def _config_root(url: str) -> str:
    with urllib.request.urlopen(url + "/server/files/roots", timeout=10) as r:
        roots = json.loads(r.read())["result"]
    return next(r["path"] for r in roots if r["name"] == "config")


def test_which_test_a_file_holds():
    assert resonance_test_of(X) == "x" and resonance_test_of("sub/" + Y) == "y"
    assert resonance_test_of("resonances_axis=1.000,-1.000,0.000_belt.csv") == "1,-1"
    assert resonance_test_of("resonances_axis=1.000,1.000_belt.csv") == "1,1"
    assert resonance_test_of("raw_data_x_20210821.csv") is None and resonance_test_of("printer.cfg") is None
    best = newest_tests([("config", {"path": "resonances_x_a.csv", "modified": 5.0}),
                         ("gcodes", {"path": "resonances_x_b.csv", "modified": 9.0}),
                         ("config", {"path": "resonances_y_a.csv", "modified": 1.0})])
    assert best["x"] == ("gcodes", {"path": "resonances_x_b.csv", "modified": 9.0}) and set(best) == {"x", "y"}


@pytest.mark.slow
def test_identify_moonraker_gives_the_toml_of_the_same_local_files(real_klipper, data_dir, tmp_path, capsys,
                                                                   monkeypatch):
    root = _config_root(real_klipper.moonraker_url)
    placed = [os.path.join(root, n) for n in ("printer.cfg", X, Y, "resonances_x_older.csv")]
    shutil.copy(real_klipper.printer_cfg, placed[0])
    shutil.copy(data_dir / ENDER / X, placed[1])
    shutil.copy(data_dir / ENDER / Y, placed[2])
    shutil.copy(data_dir / "accel/klipper_psd/bassco_voron_v24/resonances_x_20230306_224517.csv", placed[3])
    os.utime(placed[3], (1.0e9, 1.0e9))              # an older X test: not the one to take
    try:
        a, b = tmp_path / "a", tmp_path / "b"
        a.mkdir()
        b.mkdir()
        monkeypatch.chdir(a)
        assert main(["identify", "--moonraker", real_klipper.moonraker_url, "--name", "p", "-o", "p.toml",
                     "--json"]) == 0
        fetched = json.loads(capsys.readouterr().out)
        for f in (X, Y):
            shutil.copy(data_dir / ENDER / f, b / f)
        shutil.copy(real_klipper.printer_cfg, b / "printer.cfg")
        monkeypatch.chdir(b)
        assert main(["identify", X, Y, "--klipper-config", "printer.cfg", "--name", "p", "-o", "p.toml",
                     "--json"]) == 0
        local = json.loads(capsys.readouterr().out)
    finally:
        for p in placed:
            if os.path.exists(p):
                os.remove(p)
    assert (a / "p.toml").read_text() == (b / "p.toml").read_text()
    assert fetched["klipper"] == local["klipper"] and fetched["klipper"]["shaper_x"] == "ei"
    assert sorted(os.listdir(a)) == sorted(["p.toml", "printer.cfg", X, Y])      # the older X test stayed there


def test_identify_moonraker_without_resonance_files_says_where_they_are(real_klipper, tmp_path, capsys):
    code = main(["identify", "--moonraker", real_klipper.moonraker_url, "--fetch-dir", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "/tmp" in err and "config" in err
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("extra", [["x.csv"], ["--klipper-config", "printer.cfg"]])
def test_identify_moonraker_takes_no_files(extra, capsys):
    try:
        code = main(["identify", "--moonraker", "http://127.0.0.1:9", *extra])
    except SystemExit as exc:            # argparse's usage error (one line too)
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "ringtune identify: error:" in err
