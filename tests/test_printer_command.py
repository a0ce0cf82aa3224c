"""``ringtune printer from-klipper / from-marlin / from-rrf``: the TOML written, --json, notes on
stderr, motor names checked against the built-in table, one-line errors."""

from __future__ import annotations

import json
import tomllib
from types import SimpleNamespace

import pytest

from ringtune.agents.cli import main as cli
from ringtune.agents.cli import printer as printer_cmd
from ringtune.envs.printer import load_printer

CONFIGS = ("ender3", "switchwire", "v0", "v24")


@pytest.mark.parametrize("name", CONFIGS)
def test_every_real_configuration_writes_a_toml_that_says_what_it_does_not_know(name, data_dir, tmp_path,
                                                                              capsys):
    out = tmp_path / f"{name}.toml"
    cfg = data_dir / "klipper_config" / name / "printer.cfg"
    assert cli.main(["printer", "from-klipper", str(cfg), "-o", str(out), "--json"]) == 0
    cap = capsys.readouterr()
    res = json.loads(cap.out)
    assert sorted(res) == ["description", "firmware", "notes", "output", "source", "toml"]
    assert res["output"] == str(out) and out.read_text() == res["toml"]
    data = tomllib.loads(res["toml"])
    desc = res["description"]
    assert data["name"] == name and data["kinematics"] == desc["kinematics"]
    assert data["limits"] == desc["limits"] and data["current"] == desc["current"]
    for ax in "xy":
        assert data.get(ax, {}).get("motor") == desc.get(ax, {}).get("motor")
        assert data[ax]["modes"]                                   # the loader requires modes
    assert data.get("motor") == desc.get("motor")
    # every note is on stderr and in the TOML's comments; the modes are said to be defaults
    for note in res["notes"]:
        assert note in cap.err and f"#   - {note}" in res["toml"]
    assert "default modes" in res["toml"] and "`ringtune identify` replaces them" in res["toml"]
    # ender3 names no motor (no [autotune_tmc]): the default motor is said to be one
    assert any(n.startswith("no motor named or described") for n in res["notes"]) == (name == "ender3")
    p = load_printer(out)                                          # the contract's loader reads it
    assert p.kinematics == desc["kinematics"] and p.current == desc["current"]
    assert p.limits.accel == desc["limits"]["accel"]


def test_v24_warnings_on_stderr_name_the_missing_includes(data_dir, capsys):
    cfg = data_dir / "klipper_config" / "v24" / "printer.cfg"
    assert cli.main(["printer", "from-klipper", str(cfg)]) == 0
    cap = capsys.readouterr()
    assert "printer.cfg:190: warning: [include K-ShakeTune/*.cfg] matches no file" in cap.err
    assert tomllib.loads(cap.out)["kinematics"] == "corexy"            # the TOML on stdout without -o


def _facts_with_motor(table: dict):
    from ringtune.hardware.firmware_facts import FirmwareFacts

    return FirmwareFacts({"kinematics": "corexy", "motor": dict(table)}, [], "x.cfg")


@pytest.mark.parametrize("known,inline,kept", [
    (True, False, True),      # in the table: the name is enough
    (True, True, True),       # in the table and defined inline: the inline constants are written too
    (False, True, True),      # unknown but defined inline: the constants describe it, the name stays
    (False, False, False),    # unknown and no constants: dropped, said aloud
])
def test_motor_names_are_checked_against_the_builtin_table(known, inline, kept, monkeypatch):
    table = {"name": "acme-42-99", "run_current": 1.0}
    if inline:
        table.update(resistance=1.0, inductance=0.002, holding_torque=0.4, rated_current=1.5)
    monkeypatch.setattr(printer_cmd, "lookup_motor",
                        lambda name: SimpleNamespace(resistance=1.1) if known else None)
    facts = _facts_with_motor(table)
    notes: list[str] = []
    comments: dict = {}
    printer_cmd.check_motor_names(facts.description, notes, comments)
    assert ("name" in facts.description["motor"]) == kept
    if not known:
        assert any("acme-42-99 is not in the built-in table" in n for n in notes)
        assert any("acme-42-99" in c for c in comments.get("motor", [])) == (not inline)
    if inline:
        assert facts.description["motor"]["holding_torque"] == 0.4


def test_from_marlin_and_from_rrf_through_the_command(tmp_path, capsys):
    m503 = tmp_path / "m503.txt"
    m503.write_text("echo:  M92 X80.00 Y80.00\necho:  M204 P1200.00 T1500.00\necho:  M593 X F41.00 D0.12\n")
    assert cli.main(["printer", "from-marlin", str(m503), "--kinematics", "corexy", "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["firmware"] == "marlin" and res["description"]["kinematics"] == "corexy"
    assert tomllib.loads(res["toml"])["current"]["freq_x"] == 41.0
    cfg = tmp_path / "config.g"
    cfg.write_text("M669 K2\nM92 X80 Y80\nM204 P900 T900\n")
    assert cli.main(["printer", "from-rrf", str(cfg), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["firmware"] == "rrf" and tomllib.loads(res["toml"])["kinematics"] == "corexz"


def test_bad_kinematics_is_one_line_naming_file_and_line(tmp_path, capsys):
    cfg = tmp_path / "printer.cfg"
    cfg.write_text("[printer]\nkinematics: delta\nmax_velocity: 300\nmax_accel: 3000\n")
    assert cli.main(["printer", "from-klipper", str(cfg)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"ringtune printer: error: {cfg}:2: kinematics 'delta'" in err[0]


@pytest.mark.parametrize("source", ["from-klipper", "from-marlin", "from-rrf"])
def test_a_folder_or_a_binary_file_is_one_line_saying_what_it_is(source, tmp_path, capsys):
    binary = tmp_path / "firmware.bin"
    binary.write_bytes(bytes(range(256)) * 8)          # what a user gets by picking the wrong file
    for path, words in ((tmp_path, "is a directory"), (binary, "not a text file")):
        assert cli.main(["printer", source, str(path)]) == 2
        cap = capsys.readouterr()
        err = cap.err.strip().splitlines()
        assert len(err) == 1 and cap.out == "", cap.err
        assert err[0].startswith(f"ringtune printer: error: {path}: {words}") and "\ufffd" not in err[0]


def test_output_to_a_folder_is_refused_before_reading(data_dir, tmp_path, capsys):
    cfg = data_dir / "klipper_config" / "ender3" / "printer.cfg"
    assert cli.main(["printer", "from-klipper", str(cfg), "-o", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"--output {tmp_path}: is a directory" in err[0]


def test_no_note_claims_a_builtin_motor_the_table_does_not_have(data_dir, capsys):
    # the V0 defines fysetc-35hsh7402-24b-400a inline; the built-in table has no motor of that name,
    # so no note may say that the inline constants override a built-in entry
    from ringtune.envs.motors import lookup_motor

    assert lookup_motor("fysetc-35hsh7402-24b-400a") is None
    cfg = data_dir / "klipper_config" / "v0" / "printer.cfg"
    assert cli.main(["printer", "from-klipper", str(cfg), "--json"]) == 0
    notes = json.loads(capsys.readouterr().out)["notes"]
    assert any("fysetc-35hsh7402-24b-400a is not in the built-in table" in n for n in notes)
    assert not [n for n in notes if "precedence over a built-in" in n or "built-in table's entry" in n]


def test_a_run_current_without_a_motor_is_said_to_have_no_effect(data_dir, capsys):
    # the Ender 3's configuration gives run_current 0.58 A but names no motor: the loader then uses
    # the default motor's force, which the run current does not change; the note must say so
    cfg = data_dir / "klipper_config" / "ender3" / "printer.cfg"
    assert cli.main(["printer", "from-klipper", str(cfg), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["description"]["motor"]["run_current"] == 0.58
    p = load_printer_text(res["toml"])
    assert p.motor.stepper is None                       # the old-form default motor: run_current unused
    note = next(n for n in res["notes"] if n.startswith("no motor named or described"))
    assert "run_current is kept but counts only once the motor is named" in note


def load_printer_text(text):
    import tomllib as _t

    from ringtune.envs.printer import printer_from_dict

    return printer_from_dict(_t.loads(text))


def test_a_per_axis_limit_above_the_overall_one_is_kept(data_dir, capsys):
    # the Voron 2.4 (limited_corexy) sets max_x_accel 10010 over max_accel 8994: once tune raises the
    # acceleration past 10010, Kalico still caps X there (limited_corexy.py keeps max_x_accel), so
    # the cap is kept, not dropped as "no cap of its own"
    cfg = data_dir / "klipper_config" / "v24" / "printer.cfg"
    assert cli.main(["printer", "from-klipper", str(cfg), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["description"]["limits"]["max_accel"][:2] == [10010.0, 4130.0]
    assert not any("no cap of its own" in n for n in res["notes"]), res["notes"]


def test_from_marlin_without_kinematics_says_what_the_description_becomes(tmp_path, capsys):
    # M503 has no kinematics line; the TOML leaves it out and the loader then takes cartesian:
    # the note must say so (a CoreXY user would otherwise tune a bed slinger without a word)
    from test_fwconfig_marlin_rrf import M503

    f = tmp_path / "m503.txt"
    f.write_text(M503)
    assert cli.main(["printer", "from-marlin", str(f), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert "kinematics" not in tomllib.loads(res["toml"])
    assert load_printer_text(res["toml"]).kinematics == "cartesian"
    note = next(n for n in res["notes"] if "does not report the kinematics" in n)
    assert "loads as cartesian" in note and "--kinematics" in note
