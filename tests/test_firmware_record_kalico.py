"""Kalico as a firmware record: Klipper's toolhead, shapers and commands, plus the per-axis
acceleration caps of its limited_* kinematics (facts from Kalico's ``klippy/toolhead.py``, which
takes ``X_ACCEL``/``Y_ACCEL`` on SET_VELOCITY_LIMIT when the kinematics has ``max_x_accel``, and
``klippy/kinematics/limited_corexy.py`` / ``limited_cartesian.py``), and the persistence every
record states."""

from ringtune.hardware.dialects import export_config
from ringtune.hardware.push import dry_run_wire
from ringtune.shaping.calibration_prints import accel_lines
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.firmware import FIRMWARES, KALICO_LIMITED, Firmware


def _config(firmware):
    return TuneConfig(firmware=firmware, shaper_x="mzv", shaper_y="ei", freq_x=52.4, freq_y=41.2,
                      damping_x=0.06, damping_y=0.08, accel=7000.0)


def test_kalico_is_klippers_record_plus_its_per_axis_caps():
    kalico, klipper = Firmware.named("Kalico"), FIRMWARES["klipper"]
    assert kalico.name == "kalico" and kalico.title == "Kalico"
    assert (kalico.family, kalico.protocol) == ("klipper", "klipper")
    # its shapers are its own flavour's (Kalico's shaper_defs.py, issue 23): Klipper's names in their
    # pre-2025 closed forms, and its continuous smoothers
    assert kalico.flavor == "kalico" and set(klipper.shapers) <= set(kalico.shapers)
    assert {"smooth_zv", "smooth_mzv", "smooth_ei", "smooth_2hump_ei", "smooth_zvd_ei", "smooth_si"} <= set(kalico.shapers)
    assert (kalico.freq, kalico.damping, kalico.accel) == (klipper.freq, klipper.damping, klipper.accel)
    # per-axis caps: config keys of the limited_* kinematics, set at run time by SET_VELOCITY_LIMIT
    assert kalico.axis_accel_config.format(ax="x") == "max_x_accel"
    assert kalico.axis_accel_set.format(x=9000, y=4000) == "SET_VELOCITY_LIMIT X_ACCEL=9000 Y_ACCEL=4000"
    assert {"limited_cartesian", "limited_corexy"} <= set(KALICO_LIMITED)
    assert not klipper.axis_accel_set and not klipper.axis_accel_config


def test_kalico_export_and_push_speak_klipper():
    k, kal = export_config(_config("klipper")), export_config(_config("kalico"))
    assert kal.lines == k.lines and kal.readback == k.readback and kal.expected == k.expected
    assert kal.config_text == k.config_text and kal.config_target == "printer.cfg"
    assert dry_run_wire(kal) == dry_run_wire(k)            # plain lines, no checksums
    assert kal.render_commands().splitlines()[0] == "; ringtune export for Kalico"


def test_klipper_keeps_nothing_from_set_input_shaper_across_a_restart():
    note = " ".join(export_config(_config("klipper")).notes)
    assert "keeps nothing set by SET_INPUT_SHAPER across a restart" in note
    assert "would not keep damping_ratio" not in note       # the old wording implied it kept the rest
    for name in ("klipper", "kalico"):
        assert "survives a restart: only printer.cfg" in FIRMWARES[name].persists


def test_every_record_says_what_persists_and_which_accelerations_it_keeps_apart():
    for fw in FIRMWARES.values():
        assert fw.persists, fw.name
        assert fw.accel_roles[0] == "print"
    assert FIRMWARES["marlin"].accel_roles == ("print", "retract", "travel")     # M204 P R T
    assert FIRMWARES["rrf"].accel_roles == ("print", "travel")                   # M204 P T
    assert FIRMWARES["klipper"].accel_roles == ("print",)                        # one max_accel


def test_the_acceleration_ladder_raises_kalicos_axis_caps_too():
    assert accel_lines("kalico", 8000) == ["SET_VELOCITY_LIMIT X_ACCEL=8000 Y_ACCEL=8000",
                                           "SET_VELOCITY_LIMIT ACCEL=8000"]
    assert accel_lines("klipper", 8000) == ["SET_VELOCITY_LIMIT ACCEL=8000"]
    assert accel_lines("marlin", 8000) == ["M201 X8000 Y8000", "M204 P8000 T8000"]
    assert accel_lines("rrf", 8000, axis_maxima=False) == ["M204 P8000 T8000"]


def test_damping_is_searched_per_axis_where_the_firmware_takes_it_per_axis():
    from ringtune.agents.tune.report import describe
    from ringtune.agents.tune.space import config_from_params, default_space, params_from_config
    from ringtune.envs.printer import load_printer

    class Trial:                      # a fixed answer to every Optuna question
        def suggest_categorical(self, name, choices):
            return "mzv" if "mzv" in choices else choices[-1]

        def suggest_float(self, name, lo, hi):
            return {"damping_x": 0.05, "damping_y": 0.055}.get(name, lo)

    from ringtune.agents.tune.space import suggest_params

    printer = load_printer(None)
    for fw, keys in (("klipper", {"damping_x", "damping_y"}), ("marlin", {"damping_x", "damping_y"}),
                     ("prusa", {"damping_x", "damping_y"}), ("rrf", {"damping"})):
        space = default_space(printer, fw)
        p = suggest_params(Trial(), space)
        assert keys <= set(p) and not ({"damping", "damping_x", "damping_y"} - keys) & set(p), (fw, p)
        cfg = config_from_params(p, space)
        assert params_from_config(cfg, space).keys() >= keys
    cfg = config_from_params(suggest_params(Trial(), default_space(printer, "klipper")),
                             default_space(printer, "klipper"))
    assert (cfg.damping_x, cfg.damping_y) == (0.05, 0.055)
    # the summary line says each axis's damping, not one number for both
    line = describe(cfg)
    assert "S 0.050" in line and "S 0.055" in line
    same = describe(TuneConfig(shaper_x="ei", shaper_y="mzv", damping_x=0.1, damping_y=0.1))
    assert same.count("S 0.100") == 1
