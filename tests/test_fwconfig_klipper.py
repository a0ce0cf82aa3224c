"""Klipper configurations in: the four real printers of tests/data/klipper_config (SOURCES.md) and
the syntax rules of Klipper's own reader (klippy/configfile.py at 84104bb), each on a small file.

Expected values are read from the .cfg text by :func:`cfg_value` (a naive line scan, independent
of the reader under test) at the file and section cited in each row; the literal numbers in the
comments are what those lines say.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from ringtune.hardware.klipper_cfgfile import read_klipper_cfg
from ringtune.hardware.klipper_config import printer_facts_from_klipper
from ringtune.shaping.errors import RingtuneError


def cfg_value(path: Path, section: str, key: str) -> str:
    """``key``'s value under ``[section]`` in one file: the first ``key:``/``key =`` line after the
    header, text after ``#`` or `` ;`` dropped."""
    inside = False
    for line in path.read_text().splitlines():
        s = line.strip()
        if s.startswith("["):
            inside = s.split("]")[0] == f"[{section}"
            continue
        if inside and re.match(rf"{re.escape(key)}\s*[:=]", s):
            value = re.split(r"[:=]", s, maxsplit=1)[1]
            return re.split(r"#|\s;", value)[0].strip()
    raise AssertionError(f"{path}: no {key} in [{section}]")


def _num(path, section, key) -> float:
    return float(cfg_value(path, section, key))


# config -> where each fact is written: (file, section, key)
CASES = {
    "ender3": dict(
        kin=("printer.cfg", "printer", "kinematics"),                       # l.187 cartesian
        accel=("printer.cfg", "printer", "max_accel"),                      # l.191 4900
        scv=("printer.cfg", "printer", "square_corner_velocity"),           # l.193 5
        rd=("printer.cfg", "stepper_x", "rotation_distance"),               # l.11 40
        micro=("printer.cfg", "stepper_x", "microsteps"),                   # l.10 16
        run=("printer.cfg", "tmc2209 stepper_x", "run_current"),            # l.21 0.580
        shaper="printer.cfg",                                               # l.180-184 ei 51.2, mzv 46.2
    ),
    "switchwire": dict(
        kin=("printer.cfg", "printer", "kinematics"),                       # l.6 corexz
        accel=("printer.cfg", "printer", "max_accel"),                      # l.10 5000
        scv=("printer.cfg", "printer", "square_corner_velocity"),           # l.17 8.0
        rd=("printer.cfg", "stepper_x", "rotation_distance"),               # l.31 40
        micro=("printer.cfg", "stepper_x", "microsteps"),                   # l.32 32
        run=("printer.cfg", "tmc2209 stepper_x", "run_current"),            # l.47 0.9
        motor=("autotune.cfg", "autotune_tmc stepper_x", "motor"),          # l.2 ldo-42sth40-1684ac
        shaper="printer.cfg",                                               # l.151-159 ei 60.0/0.088, mzv 37.2/0.068
    ),
    "v0": dict(
        kin=("printer.cfg", "printer", "kinematics"),                       # l.45 corexy
        accel=("printer.cfg", "printer", "max_accel"),                      # l.47 25000
        scv=("printer.cfg", "printer", "square_corner_velocity"),           # l.50 7.0
        rd=("config/axis.cfg", "stepper_x", "rotation_distance"),           # l.22 40
        micro=("config/axis.cfg", "stepper_x", "microsteps"),               # l.23 32
        run=("config/axis.cfg", "tmc2209 stepper_x", "run_current"),        # l.44 0.700
        motor=("config/autotune.cfg", "autotune_tmc stepper_x", "motor"),   # l.11 fysetc-35hsh7402-24b-400a
        shaper="config/pi.cfg",                                             # l.12-16 ei 116.6, ei 77.4
    ),
    "v24": dict(
        kin=("printer.cfg", "printer", "kinematics"),                       # l.30 limited_corexy
        accel=("printer.cfg", "printer", "max_accel"),                      # l.34 8994
        scv=("printer.cfg", "printer", "square_corner_velocity"),           # l.40 7.0
        rd=("steppers.cfg", "stepper_x", "rotation_distance"),              # l.24 40
        micro=("steppers.cfg", "stepper_x", "microsteps"),                  # l.25 64
        run=("steppers.cfg", "tmc2240 stepper_x", "run_current"),           # l.44 0.9
        motor=("autotune.cfg", "autotune_tmc stepper_x", "motor"),          # l.9 ldo-42sth40-2004mah
        shaper="input_shaper.cfg",                                          # l.1-8 ei 73.8/0.050, ei 47.4/0.055
    ),
}


def _motor(desc: dict, axis: str) -> dict:
    return desc.get(axis, {}).get("motor") or desc["motor"]


@pytest.mark.parametrize("printer", sorted(CASES))
def test_each_real_configuration_imports_with_the_values_of_its_files(printer, data_dir):
    root = data_dir / "klipper_config" / printer
    case = CASES[printer]
    facts = printer_facts_from_klipper(root / "printer.cfg")
    d = facts.description

    def val(what):
        f, sec, key = case[what]
        return cfg_value(root / f, sec, key)

    kin = val("kin")
    assert d["kinematics"] == kin.removeprefix("limited_")
    assert d["limits"]["accel"] == float(val("accel")) == d["current"]["accel"]
    assert d["limits"]["square_corner_velocity"] == float(val("scv"))
    for ax in "xy":                            # same motors, drivers and belts on X and Y in all four
        f, _, key = case["rd"]
        assert _motor(d, ax)["rotation_distance"] == _num(root / f, f"stepper_{ax}", key)
        assert _motor(d, ax)["microsteps"] == int(val("micro"))
        f, sec, key = case["run"]
        assert _motor(d, ax)["run_current"] == _num(root / f, sec.replace("stepper_x", f"stepper_{ax}"), key)
    if "motor" in case:
        f, sec, key = case["motor"]
        assert _motor(d, "x")["name"] == cfg_value(root / f, sec, key)
        assert _motor(d, "x")["voltage"] == _num(root / f, sec, "voltage")
    else:
        assert "name" not in _motor(d, "x")
        assert any("stepper_x's motor is not named" in n for n in facts.notes)
    shaper_file = root / case["shaper"]
    for ax in "xy":
        assert d["current"][f"shaper_{ax}"] == cfg_value(shaper_file, "input_shaper", f"shaper_type_{ax}")
        assert d["current"][f"freq_{ax}"] == _num(shaper_file, "input_shaper", f"shaper_freq_{ax}")
        try:
            damping = _num(shaper_file, "input_shaper", f"damping_ratio_{ax}")
        except AssertionError:                 # not in the file: Klipper's default, said aloud
            damping = 0.1                      # shaper_defs.DEFAULT_DAMPING_RATIO
            assert any(f"damping_ratio_{ax} not set: Klipper's default 0.1" in n for n in facts.notes)
        assert d["current"][f"damping_{ax}"] == damping
    assert d["current"]["firmware"] == ("kalico" if kin.startswith("limited_") else "klipper")


def test_v0_inline_motor_constants_are_written(data_dir):
    """v0 names fysetc-35hsh7402-24b-400a and defines it in config/autotune.cfg:1-8: those constants
    are the motor (max_current -> rated_current)."""
    f = data_dir / "klipper_config" / "v0" / "config" / "autotune.cfg"
    sec = "motor_constants fysetc-35hsh7402-24b-400a"
    d = printer_facts_from_klipper(data_dir / "klipper_config" / "v0" / "printer.cfg").description
    m = d["motor"]                             # X and Y equal: one [motor]
    assert m["name"] == "fysetc-35hsh7402-24b-400a"
    assert m["resistance"] == _num(f, sec, "resistance") == 2.8
    assert m["inductance"] == _num(f, sec, "inductance") == 0.0055
    assert m["holding_torque"] == _num(f, sec, "holding_torque") == 0.42
    assert m["rated_current"] == _num(f, sec, "max_current") == 1.5
    assert m["steps_per_revolution"] == _num(f, sec, "steps_per_revolution") == 200


def test_an_inline_definition_wins_over_a_builtin_name(tmp_path):
    """ldo-42sth40-1684ac is in the built-in table (motors.md: R 1.65, L 0.0036, T 0.45, I 1.68);
    a [motor_constants] of that name in the user's files replaces it."""
    (tmp_path / "printer.cfg").write_text(
        "[printer]\nkinematics: corexy\nmax_velocity: 300\nmax_accel: 3000\n"
        "[stepper_x]\nmicrosteps: 16\nrotation_distance: 40\n[stepper_y]\nmicrosteps: 16\nrotation_distance: 40\n"
        "[include motors.cfg]\n")
    (tmp_path / "motors.cfg").write_text(
        "[motor_constants ldo-42sth40-1684ac]\nresistance: 2.0\ninductance: 0.004\nholding_torque: 0.5\n"
        "max_current: 1.5\nsteps_per_revolution: 200\n"
        "[autotune_tmc stepper_x]\nmotor: ldo-42sth40-1684ac\nvoltage: 48\n"
        "[autotune_tmc stepper_y]\nmotor: ldo-42sth40-1684ac\nvoltage: 48\n")
    m = printer_facts_from_klipper(tmp_path / "printer.cfg").description["motor"]
    assert (m["resistance"], m["inductance"], m["holding_torque"], m["rated_current"], m["voltage"]) == \
        (2.0, 0.004, 0.5, 1.5, 48.0)


def test_v24_steppers_name_the_builtin_2004mah_not_the_inline_2004mac(data_dir):
    """v24/autotune.cfg:1-6 defines ldo-42sth40-2004mac, but its steppers name ldo-42sth40-2004mah
    (l.9, l.14). The stepper's named motor is what counts: 2004mah, which is not defined in the
    files, so its constants are the built-in table's (none written here); the unused inline
    definition is named in a note."""
    facts = printer_facts_from_klipper(data_dir / "klipper_config" / "v24" / "printer.cfg")
    m = facts.description["motor"]
    assert m["name"] == "ldo-42sth40-2004mah"
    assert not {"resistance", "inductance", "holding_torque", "rated_current"} & set(m)
    assert m["steps_per_revolution"] == 400 and m["microsteps"] == 64      # steppers.cfg:25-26
    assert any("[motor_constants ldo-42sth40-2004mac]" in n and "neither stepper_x nor stepper_y" in n
               for n in facts.notes)


# rows of shared/reference/motors.md (klipper_tmc_autotune's motor_database.cfg at 3d1ab9f):
# R Ω, L H, holding torque N·m, rated current A, steps per revolution
MOTORS_MD = {"ldo-42sth40-1684ac": (1.65, 0.0036, 0.45, 1.68, 200),
             "ldo-42sth40-2004mah": (1.1, 0.0028, 0.35, 2.0, 400)}


@pytest.mark.parametrize("printer", ["switchwire", "v24"])
def test_motors_named_but_not_defined_get_the_builtin_constants(printer, data_dir, tmp_path, capsys):
    """switchwire (autotune.cfg:2) and v24 (autotune.cfg:9) name motors their files do not define:
    the constants are the built-in table's (motors.md rows), and the command keeps the name."""
    from ringtune.agents.cli import main as cli
    from ringtune.envs import motors

    name = printer_facts_from_klipper(data_dir / "klipper_config" / printer / "printer.cfg").description[
        "motor"]["name"]
    c = motors.lookup_motor(name)
    assert (c.resistance, c.inductance, c.holding_torque, c.rated_current, c.steps_per_revolution) == \
        MOTORS_MD[name]
    out = tmp_path / "p.toml"
    assert cli.main(["printer", "from-klipper", str(data_dir / "klipper_config" / printer / "printer.cfg"),
                     "-o", str(out)]) == 0
    assert f'name = "{name}"' in out.read_text() and "not in the built-in table" not in capsys.readouterr().err


def test_v24_missing_includes_are_named_in_warnings_and_the_fork_kinematics_in_a_note(data_dir):
    facts = printer_facts_from_klipper(data_dir / "klipper_config" / "v24" / "printer.cfg")
    text = "\n".join(facts.notes)
    assert "printer.cfg:190: warning: [include K-ShakeTune/*.cfg] matches no file" in text
    for name in ("Line_Purge", "Voron_Purge", "Smart_Park"):          # KAMP_Settings.cfg:4-6
        assert re.search(rf"KAMP_Settings.cfg:\d: warning: \[include ./KAMP/{name}.cfg\]: no such file", text)
    assert "kinematics limited_corexy" in text and "modelled as corexy" in text
    # Kalico's caps are kept whatever today's max_accel (8994): max_x_accel 10010 (printer.cfg:35)
    # still holds once the acceleration is raised; max_y_accel 4130 (printer.cfg:36); the belts'
    # shares bind (limited_corexy), and the firmware is Kalico
    limits = facts.description["limits"]
    assert limits["max_accel"][:2] == [10010.0, 4130.0]
    assert limits["axis_rule"] == "limited_corexy"
    assert facts.description["current"]["firmware"] == "kalico"


def test_old_names_step_distance_and_max_accel_to_decel(tmp_path):
    """step_distance (mm per microstep) -> rotation_distance = step_distance · full_steps ·
    microsteps; max_accel_to_decel -> minimum_cruise_ratio = 1 − max_accel_to_decel / max_accel."""
    (tmp_path / "printer.cfg").write_text(
        "[printer]\nkinematics: cartesian\nmax_velocity: 300\nmax_accel: 4000\nmax_accel_to_decel: 1000\n"
        "[stepper_x]\nstep_distance: 0.0125\n[tmc2208 stepper_x]\nmicrosteps: 16\nrun_current: 0.8\n"
        "[stepper_y]\nstep_distance: .00625\nmicrosteps: 16\nfull_steps_per_rotation: 400\n")
    facts = printer_facts_from_klipper(tmp_path / "printer.cfg")
    d = facts.description
    assert d["x"]["motor"]["rotation_distance"] == pytest.approx(0.0125 * 200 * 16)    # 40 mm
    # Y: rotation_distance 0.00625 × 400 × 16 = 40 mm, but with no motor named its 400 steps per
    # revolution are kept as steps per mm, which must be 1 / step_distance
    assert d["y"]["motor"]["steps_per_mm"] == pytest.approx(1 / 0.00625)
    assert "steps_per_revolution" not in d["y"]["motor"]
    assert d["limits"]["min_cruise_ratio"] == pytest.approx(1 - 1000 / 4000)
    assert any("old step_distance" in n for n in facts.notes)
    assert d["limits"]["accel_to_decel"] == 1000
    assert any("a Klipper from before 2024" in n for n in facts.notes)
    # the successor wins when both are there
    (tmp_path / "printer.cfg").write_text(
        "[printer]\nkinematics: cartesian\nmax_velocity: 300\nmax_accel: 4000\nmax_accel_to_decel: 1000\n"
        "minimum_cruise_ratio: 0.3\n")
    limits = printer_facts_from_klipper(tmp_path / "printer.cfg").description["limits"]
    assert limits["min_cruise_ratio"] == 0.3 and "accel_to_decel" not in limits     # a Klipper of 2024 on


def test_syntax_comments_multiline_repeated_sections_and_glob_includes(tmp_path):
    (tmp_path / "parts").mkdir()
    (tmp_path / "parts" / "a.cfg").write_text("[input_shaper]\nshaper_freq_x: 40 ; first\n")
    (tmp_path / "parts" / "b.cfg").write_text("[input_shaper]\nshaper_freq_x = 45.5#second, read after a.cfg\n")
    (tmp_path / "printer.cfg").write_text(
        "[printer]\nKinematics: cartesian   # a comment\nmax_velocity: 300 ; another\nmax_accel: 3000\n"
        "[gcode_macro X]\ngcode:\n    G28\n    G1 X10 ; not a value end\n\n    G1 X20\n"
        "[include parts/*.cfg]\n[include nothing/*.cfg]\n"
        "[printer]\nmax_accel: 3500\n")
    cfg = read_klipper_cfg(tmp_path / "printer.cfg")
    assert cfg.section("printer") == {"kinematics": "cartesian", "max_velocity": "300", "max_accel": "3500"}
    assert cfg.section("gcode_macro X")["gcode"] == "G28\nG1 X10\nG1 X20"
    assert cfg.section("input_shaper")["shaper_freq_x"] == "45.5"               # b.cfg sorted after a.cfg
    assert cfg.origin[("input_shaper", "shaper_freq_x")].endswith("b.cfg:2")
    assert any("[include nothing/*.cfg] matches no file" in n for n in cfg.notes)


def test_save_config_block_fills_in_and_the_value_above_it_wins_a_conflict(tmp_path):
    """Klipper 84104bb (configfile.py load_main_config/_strip_duplicates): a saved option the file
    above does not set is used; one it also sets is ignored (the real-Klipper test checks this)."""
    (tmp_path / "printer.cfg").write_text(
        "[printer]\nkinematics: cartesian\nmax_velocity: 300\nmax_accel: 3000\n"
        "[input_shaper]\nshaper_freq_y: 40\n\n"
        "#*# <---------------------- SAVE_CONFIG ---------------------->\n"
        "#*# DO NOT EDIT THIS BLOCK OR BELOW. The contents are auto-generated.\n#*#\n"
        "#*# [input_shaper]\n#*# shaper_type_x = ei\n#*# shaper_freq_x = 52.4\n#*# shaper_freq_y = 35.0\n#*#\n")
    facts = printer_facts_from_klipper(tmp_path / "printer.cfg")
    cur = facts.description["current"]
    assert (cur["shaper_x"], cur["freq_x"]) == ("ei", 52.4)
    assert (cur["shaper_y"], cur["freq_y"]) == ("mzv", 40.0)                    # mzv: Klipper's default
    assert any("shaper_freq_y = 35.0 is ignored" in n for n in facts.notes)
    assert any("shaper_type_y not set: Klipper's default mzv" in n for n in facts.notes)


@pytest.mark.parametrize("kin,ok", [("limited_corexz", "corexz"), ("delta", None), ("corexz", "corexz")])
def test_kinematics_mapped_or_refused_naming_file_and_value(kin, ok, tmp_path):
    (tmp_path / "printer.cfg").write_text(f"[printer]\nmax_velocity: 300\nmax_accel: 3000\nkinematics: {kin}\n")
    if ok:
        assert printer_facts_from_klipper(tmp_path / "printer.cfg").description["kinematics"] == ok
        return
    with pytest.raises(RingtuneError) as exc:
        printer_facts_from_klipper(tmp_path / "printer.cfg")
    assert f"printer.cfg:4: kinematics '{kin}'" in str(exc.value)


def test_the_extruders_own_limits_on_retractions_as_written_or_klippers_defaults(tmp_path, data_dir):
    """[extruder] max_extrude_only_velocity / _accel -> [limits] extrude_only_*; unset, Klipper's defaults
    (kinematics/extruder.py): max_velocity and max_accel × 4·nozzle_diameter² / (π·(filament/2)²)."""
    facts = printer_facts_from_klipper(data_dir / "klipper_config" / "ender3" / "printer.cfg")
    limits = facts.description["limits"]
    ratio = 4 * 0.4 ** 2 / (3.141592653589793 * 0.875 ** 2)          # its nozzle 0.400, filament 1.750
    assert limits["extrude_only_velocity"] == pytest.approx(250 * ratio) and limits["max_velocity"] == [0, 0, 40, 0]
    assert limits["extrude_only_accel"] == pytest.approx(4900 * ratio) and limits["max_accel"] == [0, 0, 100, 0]
    assert sum("max_extrude_only_" in n and "Klipper's default" in n for n in facts.notes) == 2   # velocity, accel
    # what its extruder refuses: max_extrude_cross_section unset (4 × 0.4² mm², said), the distance as written
    assert limits["max_extrude_ratio"] == pytest.approx(ratio) and limits["nozzle_diameter"] == 0.4
    assert limits["extrude_only_distance"] == 150.0
    assert sum("max_extrude_cross_section not set" in n for n in facts.notes) == 1
    (tmp_path / "printer.cfg").write_text(
        "[printer]\nkinematics: cartesian\nmax_velocity: 300\nmax_accel: 4000\n"
        "[extruder]\nnozzle_diameter: 0.6\nfilament_diameter: 1.75\nmax_extrude_only_velocity: 120\n"
        "max_extrude_only_accel: 6000\n")
    facts = printer_facts_from_klipper(tmp_path / "printer.cfg")
    limits = facts.description["limits"]
    assert (limits["extrude_only_velocity"], limits["extrude_only_accel"]) == (120.0, 6000.0)
    assert "max_velocity" not in limits and "max_accel" not in limits
    assert not any("max_extrude_only_v" in n or "max_extrude_only_a" in n for n in facts.notes)
    assert limits["max_extrude_ratio"] == pytest.approx(4 * 0.6 ** 2 / (3.141592653589793 * 0.875 ** 2))
    assert limits["extrude_only_distance"] == 50.0                                       # Klipper's default, said
    assert sum("max_extrude_only_distance not set" in n for n in facts.notes) == 1
    (tmp_path / "printer.cfg").write_text("[printer]\nkinematics: cartesian\nmax_velocity: 300\nmax_accel: 4000\n")
    assert "extrude_only_accel" not in printer_facts_from_klipper(tmp_path / "printer.cfg").description["limits"]


@pytest.mark.parametrize("name,where", [("ender3", "printer.cfg"), ("switchwire", "printer.cfg"),
                                        ("v0", "config/axis.cfg"), ("v24", "steppers.cfg")])
def test_where_the_toolhead_may_go_is_each_rails_position_min_and_max(data_dir, name, where):
    folder = data_dir / "klipper_config" / name
    limits = printer_facts_from_klipper(folder / "printer.cfg").description["limits"]
    for ax in "xy":
        try:
            low = _num(folder / where, f"stepper_{ax}", "position_min")
        except AssertionError:
            low = 0.0                                                   # Klipper's default (stepper.py)
        assert limits[f"travel_{ax}"] == [low, _num(folder / where, f"stepper_{ax}", "position_max")]


def test_a_rail_without_position_max_gives_no_travel_and_one_below_its_min_is_refused(tmp_path):
    head = "[printer]\nkinematics: cartesian\nmax_velocity: 300\nmax_accel: 4000\n"
    (tmp_path / "printer.cfg").write_text(head + "[stepper_x]\nposition_min: -5\nposition_max: 230\n[stepper_y]\n")
    limits = printer_facts_from_klipper(tmp_path / "printer.cfg").description["limits"]
    assert limits["travel_x"] == [-5.0, 230.0] and "travel_y" not in limits
    (tmp_path / "printer.cfg").write_text(head + "[stepper_x]\nposition_min: 10\nposition_max: 10\n")
    with pytest.raises(RingtuneError) as exc:
        printer_facts_from_klipper(tmp_path / "printer.cfg")
    assert "position_max" in str(exc.value) and "printer.cfg" in str(exc.value)
