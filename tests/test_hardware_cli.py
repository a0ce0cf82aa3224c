"""ringtune identify / export / push on the command line."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fake_printer import FakePrinter  # noqa: E402

from ringtune.agents.cli.main import main  # noqa: E402
from ringtune.hardware.slicer_profile import slicer_profile  # noqa: E402
from ringtune.shaping.config import TuneConfig  # noqa: E402

pytestmark = pytest.mark.timeout(60)


@pytest.fixture
def config(tmp_path) -> Path:
    p = tmp_path / "best.json"
    p.write_text(json.dumps({"firmware": "marlin", "shaper_x": "zv", "shaper_y": "zv", "freq_x": 41.5,
                             "freq_y": 37.25, "damping_x": 0.08, "damping_y": 0.12, "freq_limit_hz": 25.0,
                             "min_speed_factor": 0.3, "freq_limit_method": "marlin"}))
    return p


def test_export_json_and_file(config, tmp_path, capsys):
    assert main(["export", str(config), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["lines"] == ["M593 X F41.5 D0.08", "M593 Y F37.25 D0.12", "M201 F25 S30"]
    assert d["save_lines"] == ["M500"]
    out = tmp_path / "k.cfg"
    assert main(["export", str(config), "--firmware", "klipper", "-o", str(out)]) == 0
    text = out.read_text()
    assert "SET_INPUT_SHAPER SHAPER_FREQ_X=41.5 SHAPER_FREQ_Y=37.25" in text
    assert "ringtune limit FILE.gcode --freq-limit 25" in text
    assert "damping_ratio_y: 0.12" in (tmp_path / "k-printer.cfg").read_text()   # the printer.cfg part


def test_export_refusal_is_one_line(config, capsys):
    assert main(["export", str(config), "--firmware", "rrf"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "has no 'zv' shaper" in err[0] and "nearest it has is 'mzv'" in err[0]


def test_push_refuses_without_port_and_help_teaches(config, capsys):
    assert main(["push", str(config)]) == 2
    err = capsys.readouterr().err
    assert "explicit port" in err and "--port" in err
    with pytest.raises(SystemExit):
        main(["push", "--help"])
    helptext = capsys.readouterr().out
    for word in ("socket://", "rfc2217://", "/tmp/printer", "--moonraker", "M500", "--dry-run"):
        assert word in helptext


def test_push_dry_run(config, capsys):
    assert main(["push", str(config), "--dry-run", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["wire"][:2] == ["N0 M110 N0*125", "N1 M593 X F41.5 D0.08*95"] and d["dry_run"]


def test_push_over_tcp_and_timeout_exit(config, capsys):
    with FakePrinter("marlin", transport="tcp") as fp:
        assert main(["push", str(config), "--port", fp.url, "--timeout", "2", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["ok"] and d["settings"]["x.freq"]["status"] == "applied"
    from fake_printer import Faults
    with FakePrinter("marlin", Faults(hang_after=2), transport="tcp") as fp:
        assert main(["push", str(config), "--port", fp.url, "--timeout", "0.5"]) == 2
    captured = capsys.readouterr()
    assert "not applied: limit" in captured.err and "stopped answering" in captured.err


@pytest.mark.slow
def test_identify_writes_toml_and_plot(data_dir, tmp_path, capsys):
    files = sorted((data_dir / "accel/klipper_psd/bassco_ender3").glob("*.csv"))
    toml, png = tmp_path / "p.toml", tmp_path / "fit.png"
    assert main(["identify", *map(str, files), "-o", str(toml), "--plot", str(png), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert [f["axis"] for f in d["fits"]] == ["x", "y"]
    assert toml.read_text() == d["toml"] and png.stat().st_size > 20000


def test_identify_bad_file_is_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("freq,psd_x,psd_y,psd_z,psd_xyz\n5.0,1,2,3,6\n6.0,1,oops,3,6\n")
    assert main(["identify", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and f"{bad}:3" in err


@pytest.mark.parametrize("argv, where", [
    (["identify", "{psd}", "--plot", "{tmp}/fit.txt"], "--plot"),
    (["identify", "{psd}", "--plot", "{tmp}/no/fit.png"], "no such directory"),
    (["identify", "{psd}", "-o", "{tmp}/no/p.toml"], "no such directory"),
    (["export", "{config}", "-o", "{tmp}/no/x.g"], "no such directory"),
    (["push", "{config}", "--firmware", "klipper", "--port", "/dev/null", "--save",
      "--save-file", "{tmp}/no/x.cfg"], "no such directory"),
])
def test_bad_output_paths_are_one_line_before_any_work(argv, where, config, data_dir, tmp_path, capsys):
    psd = data_dir / "accel/klipper_psd/bassco_ender3/resonances_x_20210821_152037.csv"
    argv = [a.format(psd=psd, tmp=tmp_path, config=config) for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and where in err and "Traceback" not in err
    assert not list(tmp_path.rglob("*.png")) and not (tmp_path / "no").exists()


def test_export_parts_are_separate_and_the_command_part_uses_semicolons(tmp_path, capsys):
    p = tmp_path / "k.json"
    p.write_text(json.dumps({"firmware": "klipper", "shaper_x": "ei", "shaper_y": "mzv", "freq_x": 51.2,
                             "freq_y": 46.2, "accel": 4000}))
    out = tmp_path / "shaping.gcode"
    assert main(["export", str(p), "-o", str(out), "--slicer", "prusaslicer", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["files"] == [str(out), str(tmp_path / "shaping-printer.cfg"), str(tmp_path / "shaping-prusaslicer.ini")]
    commands = out.read_text().splitlines()
    assert all(ln.startswith(";") or ln.split()[0] in ("SET_INPUT_SHAPER", "SET_VELOCITY_LIMIT") for ln in commands)
    assert "[input_shaper]" in (tmp_path / "shaping-printer.cfg").read_text()
    ini = (tmp_path / "shaping-prusaslicer.ini").read_text()
    assert "machine_max_acceleration_extruding = 4000,4000" in ini and "default_acceleration = 4000" in ini
    assert main(["export", str(p), "--part", "config"]) == 0
    assert capsys.readouterr().out.splitlines()[1] == "[input_shaper]"
    assert main(["export", str(p), "--part", "config", "--firmware", "marlin"]) == 2   # mzv: Marlin lacks it
    capsys.readouterr()
    q = tmp_path / "m.json"
    q.write_text(json.dumps({"firmware": "marlin", "shaper_x": "zv", "shaper_y": "zv", "accel": 4000}))
    assert main(["export", str(q), "--part", "config"]) == 2
    assert "no config-file part" in capsys.readouterr().err
    assert main(["export", str(q), "--slicer", "cura", "--part", "slicer"]) == 0
    cura = capsys.readouterr().out
    assert "acceleration_enabled = True" in cura and "acceleration_print = 4000" in cura


@pytest.mark.parametrize("slicer, why", [("prusaslicer", "no per-feature corner setting"),
                                         ("orcaslicer", "bridge infill, which is seen, under infill_jerk"),
                                         ("cura", "M205 X Y, which Klipper ignores")])
def test_a_slicer_profile_says_why_it_leaves_the_corner_rule_to_the_rewrite(slicer, why, tmp_path, capsys):
    p = tmp_path / "k.json"
    p.write_text(json.dumps({"firmware": "klipper", "shaper_x": "ei", "shaper_y": "mzv", "freq_x": 51.2, "freq_y": 46.2,
                             "accel": 4800, "feature_accel": {"infill": 12400}, "feature_corner": {"infill": 30}}))
    assert main(["export", str(p), "--slicer", slicer, "--part", "slicer"]) == 0
    text = capsys.readouterr().out
    assert why in text and "`ringtune rewrite` writes them" in text
    settings = slicer_profile(TuneConfig.from_dict(json.loads(p.read_text())), slicer).settings
    assert settings and not [k for k in settings if "jerk" in k]
