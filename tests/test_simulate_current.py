"""``ringtune simulate`` without --config/--shaper: what the printer runs now ([current], as
`printer from-klipper` writes it), else shaping off; stderr says which, and the configuration line
gives no frequency or damping for an axis without shaping."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import ringtune.envs.data
from ringtune.agents.cli.main import main


def _printer(tmp_path, current: str = "") -> Path:
    text = (Path(ringtune.envs.data.__file__).parent / "ender3.toml").read_text()
    path = tmp_path / "X.toml"
    path.write_text(text + ("\n[current]\n" + current if current else ""))
    return path


def test_no_config_and_no_current_prints_none_alone_and_says_shaping_is_off(tmp_path, capsys):
    p = _printer(tmp_path)
    assert main(["simulate", "--backend", "lti", "--freq-margin", "0", "--printer", str(p)]) == 0
    out, err = capsys.readouterr()
    line = next(s for s in out.splitlines() if s.startswith("config"))
    assert "X none, Y none," in line and "Hz S" not in line, line
    assert "input shaping off" in err


def test_no_config_simulates_what_the_printer_runs_now(tmp_path, capsys):
    """[current] mzv 45 Hz / ei 38 Hz, damping 0.12: the same figures as giving those values as options."""
    p = _printer(tmp_path, 'source = "printer.cfg"\nfirmware = "klipper"\nshaper_x = "mzv"\nfreq_x = 45.0\n'
                           'damping_x = 0.12\nshaper_y = "ei"\nfreq_y = 38.0\ndamping_y = 0.12\n')
    base = ["simulate", "--json", "--backend", "lti", "--freq-margin", "0", "--printer", str(p)]
    assert main(base) == 0
    out, err = capsys.readouterr()
    assert "no --config: simulating what the printer runs now, from [current] (printer.cfg)" in err
    now = json.loads(out)
    c = now["config"]
    assert (c["shaper_x"], c["freq_x"], c["damping_x"]) == ("mzv", 45.0, 0.12)
    assert (c["shaper_y"], c["freq_y"], c["damping_y"]) == ("ei", 38.0, 0.12)
    assert main(base + ["--shaper", "mzv,ei", "--freq", "45,38", "--damping", "0.12",
                        "--accel", str(c["accel"])]) == 0
    given = json.loads(capsys.readouterr().out)
    for key, value in given["metrics"].items():
        if isinstance(value, dict):      # per feature class, and the E-synchronised alternative
            for sub, v in value.items():
                assert now["metrics"][key][sub] == pytest.approx(v), (key, sub)
        else:
            assert now["metrics"][key] == pytest.approx(value), key
    off = main(base + ["--shaper", "none"])
    assert off == 0 and json.loads(capsys.readouterr().out)["config"]["shaper_x"] == "none"
