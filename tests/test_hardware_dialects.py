"""Exported lines per firmware dialect, checked against the syntax in shared/reference/firmware.md
and the RRF M593 seed's worked custom-shaper example."""

from __future__ import annotations

import re

import pytest

from ringtune.hardware.dialects import export_config
from ringtune.hardware.readback import compare, parse_report
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.firmware import FIRMWARES


def cfg(**kw) -> TuneConfig:
    base = dict(shaper_x="mzv", shaper_y="mzv", freq_x=40.0, freq_y=40.0, damping_x=0.1, damping_y=0.1)
    base.update(kw)
    return TuneConfig(**base)


def test_klipper_set_input_shaper_and_cfg_section_keep_damping():
    e = export_config(cfg(shaper_x="ei", shaper_y="mzv", freq_x=51.2, freq_y=46.2, damping_x=0.08), "klipper")
    assert e.lines == ["SET_INPUT_SHAPER SHAPER_FREQ_X=51.2 SHAPER_FREQ_Y=46.2 DAMPING_RATIO_X=0.08 "
                       "DAMPING_RATIO_Y=0.1 SHAPER_TYPE_X=ei SHAPER_TYPE_Y=mzv"]
    assert e.config_text.splitlines() == [
        "[input_shaper]", "shaper_type_x: ei", "shaper_freq_x: 51.2", "damping_ratio_x: 0.08",
        "shaper_type_y: mzv", "shaper_freq_y: 46.2", "damping_ratio_y: 0.1"]
    assert e.config_target == "printer.cfg" and e.readback == ["SET_INPUT_SHAPER"]
    # the report Klipper prints (firmware.md §1.5) parses back to exactly what was meant
    report = ("// shaper_type_x:ei shaper_freq_x:51.200 damping_ratio_x:0.080000\n"
              "// shaper_type_y:mzv shaper_freq_y:46.200 damping_ratio_y:0.100000\n")
    assert all(v["ok"] for v in compare(e.expected, parse_report("klipper", report)).values())
    bad = report.replace("51.200", "51.000")
    res = compare(e.expected, parse_report("klipper", bad))
    assert not res["x.freq"]["ok"] and res["y.freq"]["ok"]


def test_klipper_parameterised_and_disabled_axis_and_damping_limit():
    e = export_config(cfg(shaper_x="mzv(n=5,t=1.1)", shaper_y="none"), "klipper")
    assert e.lines == ["SET_INPUT_SHAPER SHAPER_FREQ_X=40 SHAPER_FREQ_Y=0 DAMPING_RATIO_X=0.1 "
                       "SHAPER_TYPE_X=mzv(n=5,t=1.1)"]
    assert "shaper_freq_y: 0" in e.config_text
    with pytest.raises(RingtuneError, match=r"damping ratio of 3hump_ei 0.25 .*\[0, 0.2\]"):
        export_config(cfg(shaper_x="3hump_ei", damping_x=0.25), "klipper")
    with pytest.raises(RingtuneError, match="nearest it has is '2hump_ei'"):
        export_config(cfg(shaper_x="zvdd"), "klipper")   # same 1.5/f duration, wide band


def test_rrf36_named_shapers():
    assert export_config(cfg(shaper_x="zvd", shaper_y="zvd", freq_x=40.5, freq_y=40.5), "rrf").lines == \
        ['M593 P"zvd" F40.5 S0.1']
    assert export_config(cfg(shaper_x="2hump_ei", shaper_y="ei2", damping_x=0.05, damping_y=0.05),
                         "rrf").lines == ['M593 P"ei2" F40 S0.05']
    assert export_config(cfg(shaper_x="none", shaper_y="none"), "rrf").lines == ['M593 P"none"']
    e = export_config(cfg(), "rrf")
    assert e.save_lines == [] and e.config_target == "config.g"
    rep = "Input shaping 'mzv' at 40.0Hz damping factor 0.10, impulses 0.227 0.407 with delays (ms) 0.00 9.42"
    assert all(v["ok"] for v in compare(e.expected, parse_report("rrf", rep)).values())


def test_rrf_custom_in_both_semantics():
    # the seed's 3.4/3.5 example: M593 P"custom" H0.4:0.7 T0.0135:0.0135
    # = impulses 0.4, 0.3, 0.3 at 0, 13.5 ms, 27 ms
    custom = {"amplitudes": [0.4, 0.3, 0.3], "times": [0.0, 0.0135, 0.027]}
    c = cfg(shaper_x="custom", shaper_y="custom", extra={"custom": custom})
    assert export_config(c, "rrf35").lines == ['M593 P"custom" H0.4:0.7 T0.0135:0.0135']
    assert export_config(c, "rrf34").lines == ['M593 P"custom" H0.4:0.7 T0.0135:0.0135']
    # 3.6: individual amplitudes except the last; cumulative delays of impulses 2..n
    assert export_config(c, "rrf").lines == ['M593 P"custom" H0.4:0.3 T0.0135:0.027']


@pytest.mark.parametrize("custom, msg", [
    ({"amplitudes": [0.5, 0.6], "times": [0, 0.01]}, "sum to 1"),
    ({"amplitudes": [0.5, 0.5], "times": [0, 0.0]}, "strictly increase"),
    ({"amplitudes": [0.2] * 5 + [0.0], "times": [0, 1, 2, 3, 4, 5]}, "2 to 5 impulses"),
    ({"amplitudes": [1.0], "times": [0]}, "2 to 5 impulses"),
])
def test_rrf_custom_refusals(custom, msg):
    with pytest.raises(RingtuneError, match=msg):
        export_config(cfg(shaper_x="custom", shaper_y="custom", extra={"custom": custom}), "rrf")


def test_rrf_ranges_and_one_shaper():
    with pytest.raises(RingtuneError, match="one shaper to all axes"):
        export_config(cfg(freq_y=45.0), "rrf")
    with pytest.raises(RingtuneError, match=r"freq_x: frequency 3.5 Hz is outside RepRapFirmware 3.6.s range \[4, 1000\] Hz"):
        export_config(cfg(freq_x=3.5, freq_y=3.5), "rrf")
    export_config(cfg(freq_x=4.0, freq_y=4.0), "rrf")          # 3.6 goes down to 4 Hz
    with pytest.raises(RingtuneError, match="outside RepRapFirmware 3.5"):
        export_config(cfg(freq_x=5.0, freq_y=5.0), "rrf35")    # 3.5 on Duet 3: 750 kHz / 131070 = 5.72 Hz
    with pytest.raises(RingtuneError, match=r"has no 'zv' shaper .*nearest it has is 'mzv'"):
        export_config(cfg(shaper_x="zv", shaper_y="zv"), "rrf")
    with pytest.raises(RingtuneError, match=r"has no 'ei' shaper .*nearest it has is 'zvd'"):
        export_config(cfg(shaper_x="ei", shaper_y="ei"), "rrf")


def test_rrf35_and_34_l_parameter():
    c = cfg(extra={"reduction_limit": 0.25})
    assert export_config(c, "rrf35").lines == ['M593 P"mzv" F40 S0.1 L0.25']
    assert export_config(c, "rrf").lines == ['M593 P"mzv" F40 S0.1']   # ignored in 3.6
    with pytest.raises(RingtuneError, match="reduction limit"):
        export_config(cfg(extra={"reduction_limit": 0.001}), "rrf35")
    assert export_config(cfg(extra={"min_accel": 10}), "rrf34").lines == ['M593 P"mzv" F40 S0.1 L10']


def test_marlin_classic_zv_only_with_frequency_limit():
    c = cfg(shaper_x="zv", shaper_y="zv", freq_x=41.5, freq_y=37.25, damping_x=0.08, damping_y=0.12,
            freq_limit_hz=25, min_speed_factor=0.3, freq_limit_method="marlin")
    e = export_config(c, "marlin")
    assert e.lines == ["M593 X F41.5 D0.08", "M593 Y F37.25 D0.12", "M201 F25 S30"]
    assert e.save_lines == ["M500"] and e.readback == ["M593"]
    report = "echo:Input Shaping:\necho:  M593 X F41.50 D0.08\necho:  M593 Y F37.25 D0.12\n"
    assert all(v["ok"] for v in compare(e.expected, parse_report("marlin", report)).values())
    with pytest.raises(RingtuneError, match=r"Marlin \(classic input shaping\) has no 'mzv'.*nearest it has is 'zv'"):
        export_config(cfg(), "marlin")
    with pytest.raises(RingtuneError, match="M201 F"):
        export_config(cfg(shaper_x="zv", shaper_y="zv", freq_limit_hz=150, freq_limit_method="marlin"), "marlin")
    assert export_config(cfg(shaper_x="none", shaper_y="zv"), "marlin").lines[0] == "M593 X F0"


def test_marlin_ftm_m493():
    c = cfg(shaper_x="ei(v_tol=0.1)", shaper_y="2hump_ei", freq_x=51.2, freq_y=40, damping_y=0.15)
    e = export_config(c, "marlin-ftm")
    assert e.lines == ["M493 S1", "M493 X C5 A51.2 I0.1 Q0.1", "M493 Y C6 A40 I0.15"]
    report = "M493 S1 D0 H0\nM493 X C5 A51.20 F0.00 I0.10 Q0.10\nM493 Y C6 A40.00 F0.00 I0.15 Q0.05\n"
    assert all(v["ok"] for v in compare(e.expected, parse_report("marlin-ftm", report)).values())
    assert export_config(cfg(shaper_x="zvddd", shaper_y="mzv"), "marlin-ftm").lines[1:] == \
        ["M493 X C4 A40 I0.1", "M493 Y C8 A40 I0.1"]
    with pytest.raises(RingtuneError, match="FT_MOTION"):
        export_config(cfg(freq_x=5), "marlin-ftm")


def test_prusa_m593():
    c = cfg(shaper_x="mzv", shaper_y="ei(v_tol=0.1)", freq_x=50.7, freq_y=40.6)
    e = export_config(c, "prusa")
    assert e.lines == ["M593 X T2 F50.7 D0.1", "M593 Y T3 F40.6 D0.1 R10"]
    assert e.save_lines == ["M593 W"]
    report = "axis X type=MZV freq=50.70 damp=0.10 vr=20.00\naxis Y type=EI freq=40.60 damp=0.10 vr=10.00\n" \
             "axis Z disabled\n"
    assert all(v["ok"] for v in compare(e.expected, parse_report("prusa", report)).values())
    with pytest.raises(RingtuneError, match=r"\[10, 100\]"):
        export_config(cfg(freq_x=120), "prusa")
    with pytest.raises(RingtuneError, match="nearest it has is '2hump_ei'"):
        export_config(cfg(shaper_x="zvdd"), "prusa")
    assert export_config(cfg(shaper_y="none"), "prusa").lines[1] == "M593 Y F0"


@pytest.mark.parametrize("fw", ["klipper", "rrf", "rrf35", "prusa"])
def test_no_frequency_limit_gives_the_limit_command(fw):
    e = export_config(cfg(freq_limit_hz=22.5), fw)
    assert not any(line.startswith("M201") for line in e.lines)
    note = next(n for n in e.notes if "no XY frequency limit" in n)
    assert "ringtune limit FILE.gcode --freq-limit 22.5" in note
    assert "ringtune limit FILE.gcode --freq-limit 22.5" in e.render()


def test_every_dialect_checksum_safe_lines():
    # every exported runtime line must be sendable: no '*', ';' or newline inside a line
    for fw in FIRMWARES:
        shaper = {"marlin": "zv", "rrf": "zvd", "rrf35": "zvd", "rrf34": "zvd"}.get(fw, "mzv")
        for line in export_config(cfg(shaper_x=shaper, shaper_y=shaper), fw).lines:
            assert not re.search(r"[*;\n]", line), line


def test_unknown_firmware():
    with pytest.raises(RingtuneError, match="--firmware"):
        export_config(cfg(), "grbl")


def test_custom_given_in_the_configs_own_rrf_semantics_is_converted():
    # written for RRF 3.5 (cumulative H, durations T) -> exported for 3.6 and back
    c35 = TuneConfig(firmware="rrf35", shaper_x="custom(h=0.4:0.7,t=0.0135:0.0135)",
                     shaper_y="custom(h=0.4:0.7,t=0.0135:0.0135)")
    assert export_config(c35, "rrf").lines == ['M593 P"custom" H0.4:0.3 T0.0135:0.027']
    assert export_config(c35, "rrf35").lines == ['M593 P"custom" H0.4:0.7 T0.0135:0.0135']
    c36 = TuneConfig(firmware="rrf", shaper_x="custom(h=0.4:0.3,t=0.0135:0.027)",
                     shaper_y="custom(h=0.4:0.3,t=0.0135:0.027)")
    assert export_config(c36, "rrf35").lines == ['M593 P"custom" H0.4:0.7 T0.0135:0.0135']
    with pytest.raises(RingtuneError, match="sum to less than 1"):
        export_config(TuneConfig(firmware="rrf", shaper_x="custom(h=0.6:0.5)", shaper_y="custom(h=0.6:0.5)"),
                      "rrf")


@pytest.mark.parametrize("dialect, flavor", [("klipper", "klipper"), ("rrf", "rrf"), ("rrf35", "rrf35"),
                                             ("marlin", "marlin"), ("marlin-ftm", "marlin-ftm"),
                                             ("prusa", "klipper-legacy")])
def test_dialect_shaper_sets_agree_with_the_shaper_registry(dialect, flavor):
    from ringtune.shaping.shapers import available_shapers

    assert set(FIRMWARES[dialect].shapers) == set(available_shapers(flavor))


@pytest.mark.parametrize("fw", ["klipper", "rrf", "prusa", "marlin", "marlin-ftm"])
def test_limit_command_applies_the_tuned_limit_exactly(fw):
    """The `ringtune limit` command in the export parses with the real CLI and carries the config's
    limit, method and minimum speed factor (the command's own defaults are sections / 0.3)."""
    import shlex

    from ringtune.agents.cli.main import build_parser

    shaper = {"marlin": "zv", "rrf": "zvd"}.get(fw, "mzv")
    c = cfg(shaper_x=shaper, shaper_y=shaper, freq_limit_hz=27.5, min_speed_factor=0.55,
            freq_limit_method="nophead")
    notes = export_config(c, fw).notes
    cmd = next(n[n.index("ringtune limit"):] for n in notes if "ringtune limit" in n)
    argv = shlex.split(cmd)
    assert argv[:2] == ["ringtune", "limit"]
    args = build_parser("limit")[0].parse_args(argv[1:])
    assert (args.freq_limit, args.method, args.min_speed_factor) == (27.5, "nophead", 0.55)
    if fw.startswith("marlin"):      # Marlin's own M201 F only for a limit tuned with its algorithm
        assert not any(line.startswith("M201") for line in export_config(c, fw).lines)
        c_marlin = cfg(shaper_x=shaper, shaper_y=shaper, freq_limit_hz=27.5, min_speed_factor=0.55,
                       freq_limit_method="marlin")
        assert "M201 F27.5 S55" in export_config(c_marlin, fw).lines
        assert not any("ringtune limit" in n for n in export_config(c_marlin, fw).notes)


def test_tuned_acceleration_is_applied_and_read_back_or_left_alone_on_request():
    e = export_config(cfg(accel=4000.0), "klipper")
    assert e.lines[-1] == "SET_VELOCITY_LIMIT ACCEL=4000" and e.readback[-1] == "SET_VELOCITY_LIMIT"
    assert any("override this acceleration" in n for n in e.notes)
    # Klipper's own SET_VELOCITY_LIMIT report (toolhead.py: "max_accel: %.6f") reads back as applied
    report = "// max_velocity: 300.000000\n// max_accel: 4000.000000\n// minimum_cruise_ratio: 0.500000"
    assert compare({"accel": 4000.0}, parse_report("klipper", report))["accel"]["ok"]
    assert not any("ACCEL" in line for line in export_config(cfg(accel=4000.0), "klipper", accel=False).lines)
    assert any("--no-accel" in n for n in export_config(cfg(accel=4000.0), "klipper", accel=False).notes)
    assert not any("acceleration" in n for n in export_config(cfg(), "klipper").notes)
    # RRF: M204 P T, report "Maximum printing acceleration %.1f, ..." (Move.cpp); Marlin: "  M204 P%.2f ..."
    # (travel too: every XY move was planned at the tuned acceleration; Marlin's retractions keep R)
    r = export_config(cfg(shaper_x="zvd", shaper_y="zvd", accel=3500.0), "rrf")
    assert r.lines[-1] == "M204 P3500 T3500" and "M204 P3500 T3500" in r.config_text
    assert parse_report("rrf", "Maximum printing acceleration 3500.0, maximum travel acceleration "
                               "10000.0 mm/sec^2")["accel"].value == 3500.0
    m = export_config(cfg(shaper_x="zv", shaper_y="zv", accel=3500.0), "marlin")
    assert m.lines[-1] == "M204 P3500 T3500" and m.readback == ["M593", "M204", "M201"]
    report = parse_report("marlin", "echo:  M204 P3500.00 R1500.00 T3000.00")
    assert report["accel"].value == 3500.0 and report["travel_accel"].value == 3000.0


@pytest.mark.parametrize("fw", ["rrf", "rrf35"])
def test_rrf_refuses_different_custom_shapers_on_x_and_y(fw):
    """One shaper for all axes holds for custom impulses too: Y's must not be dropped silently."""
    x, y = "custom(h=0.4:0.3,t=0.0135:0.027)", "custom(h=0.5:0.2,t=0.01:0.02)"
    with pytest.raises(RingtuneError, match="one shaper to all axes.*custom shapers of X and Y differ"):
        export_config(TuneConfig(firmware="rrf", shaper_x=x, shaper_y=y), fw)
    same = export_config(TuneConfig(firmware="rrf", shaper_x=x, shaper_y=x), fw).lines
    assert same == {"rrf": ['M593 P"custom" H0.4:0.3 T0.0135:0.027'],
                    "rrf35": ['M593 P"custom" H0.4:0.7 T0.0135:0.0135']}[fw]


def test_marlin_export_never_sends_m201_f_for_a_limit_tuned_with_another_method(tmp_path):
    """Issue 14: `export --firmware marlin` printed `M201 F37.5 S30` and, in the same output, "for
    exactly that, leave M201 out and run ringtune limit"; `push --save` then stored that M201."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from fake_printer import FakePrinter

    from ringtune.hardware.push import push

    c = cfg(shaper_x="zv", shaper_y="zv", freq_limit_hz=37.5, min_speed_factor=0.3, freq_limit_method="sections")
    for fw in ("marlin", "marlin-ftm"):
        e = export_config(c, fw)
        assert not any(line.startswith("M201") for line in e.lines + e.save_lines), e.lines
        sent = [ln for ln in e.render_commands().splitlines() if not ln.startswith(";")]
        assert not any("M201" in ln for ln in sent) and "leave M201 out" not in e.render()
        assert any("ringtune limit FILE.gcode --freq-limit 37.5 --method sections" in n for n in e.notes)
    with FakePrinter("marlin", transport="tcp") as fp:
        r = push(c, "marlin", port=fp.url, timeout=2.0, save=True)
    assert r.ok and not any(cmd.startswith("M201") for cmd in fp.executed)
    assert fp.executed[-1] == "M500" and fp.core.eeprom["limit"] == [0.0, 5]   # Marlin's own stays off


@pytest.mark.parametrize("kw, key, allowed", [
    (dict(shaper_x="ei(foo=1)"), "shaper_x", "accepted: v_tol"),
    (dict(shaper_x="mzv(n=2)"), "shaper_x", "n >= 3"),
    (dict(shaper_x="ei(v_tol=5)"), "shaper_x", "(0, 1)"),
    (dict(freq_x=0.0004), "freq_x", "[1, 1000] Hz"),
    (dict(shaper_x="foo"), "shaper_x", "Klipper has zv, mzv, zvd, ei, 2hump_ei, 3hump_ei"),
    (dict(shaper_x="zvdd"), "shaper_x", "it has zv, mzv, zvd, ei, 2hump_ei, 3hump_ei"),
    (dict(shaper_x="ei", damping_x=0.5), "damping_x", "[0, 0.4]"),
])
def test_klipper_refusals_name_the_key_and_the_allowed_range(kw, key, allowed):
    with pytest.raises(RingtuneError) as exc:
        export_config(cfg(**kw), "klipper")
    msg = str(exc.value)
    assert f"config: {key}:" in msg and allowed in msg and "\n" not in msg


@pytest.mark.parametrize("fw, value", [("marlin", 0.0004), ("marlin", 0.015), ("prusa", 0.0004)])
def test_a_frequency_that_would_round_to_another_is_refused_never_changed(fw, value):
    shaper = "zv" if fw == "marlin" else "mzv"
    with pytest.raises(RingtuneError, match=r"freq_x: .*(outside .*range|would be sent as .*give a value in)"):
        export_config(cfg(shaper_x=shaper, shaper_y=shaper, freq_x=value), fw)
    # within the rounding tolerance the value goes out at the firmware's precision, and is said
    e = export_config(cfg(shaper_x=shaper, shaper_y=shaper, freq_x=41.5001), fw)
    assert e.expected["x.freq"] == 41.5 and any("freq_x 41.5001 is sent as 41.5" in n for n in e.notes)


def test_klipper_gets_canonical_shaper_names_and_named_integer_parameters():
    """Klipper knows no alias (`ei2` -> "Unsupported shaper type") and parses parameters with
    `[\\d.]+`, int without a point: n=5.0 would reach range() as a float and crash the host."""
    e = export_config(cfg(shaper_x="EI2", damping_x=0.1, shaper_y="mzv(5.0, 1.1)"), "klipper")
    assert "SHAPER_TYPE_X=2hump_ei" in e.lines[0] and "SHAPER_TYPE_Y=mzv(n=5,t=1.1)" in e.lines[0]


def test_one_record_per_firmware_is_what_config_space_and_export_read():
    """Issue 17: every reader takes the firmware facts from the one record: names are read
    case-insensitively (`Klipper`), rrf34 is a firmware tune accepts as export does, and RRF's one
    shaper for all axes holds in the search space for every RRF version."""
    from ringtune.agents.tune.space import default_space
    from ringtune.envs.printer import load_printer

    assert TuneConfig(firmware="Klipper").firmware == "klipper"
    assert TuneConfig(firmware="rrf34", shaper_x="zvd", shaper_y="zvd").flavor == FIRMWARES["rrf34"].flavor
    printer = load_printer(None)
    for name, fw in FIRMWARES.items():
        assert default_space(printer, name).per_axis is not fw.one_shaper
        assert {s.split("(")[0] for s in default_space(printer, name).shapers} <= set(fw.shapers)
    assert [n for n, fw in FIRMWARES.items() if fw.one_shaper] == ["rrf", "rrf35", "rrf34"]
    assert [n for n, fw in FIRMWARES.items() if fw.freq_limit] == ["marlin", "marlin-ftm"]


@pytest.mark.parametrize("fw", ["klipper", "marlin", "rrf"])
def test_a_per_feature_configuration_says_its_settings_belong_in_the_job(fw):
    """A firmware holds one acceleration: the lines carry the visible walls', and the first note says
    where the per-feature ones go (a rewritten job, a re-slice), not that the slicer should get the
    one value; a configuration with one acceleration keeps that advice."""
    shaper = {"marlin": "zv", "rrf": "mzv"}.get(fw, "ei")   # what each has: Marlin's classic shaping is ZV
    one = TuneConfig(shaper_x=shaper, shaper_y=shaper, freq_x=50.0, freq_y=50.0 if fw == "rrf" else 40.0,
                     accel=4800.0, firmware=fw)                  # RRF: one shaper for both axes
    per = TuneConfig(**{**one.to_dict(), "feature_accel": {"infill": 12000.0}})
    assert per.per_feature and not one.per_feature
    notes = export_config(per).notes
    assert notes[0].startswith("this configuration sets accelerations (or corner rules) per feature")
    assert "the visible walls' 4800 mm/s²" in notes[0] and "ringtune rewrite JOB --config CONFIG -o OUT" in notes[0]
    assert not any("ringtune limit FILE.gcode --accel A" in n for n in notes)
    assert any("ringtune limit FILE.gcode --accel A" in n for n in export_config(one).notes)
    assert not any("per feature" in n for n in export_config(one).notes)
    # a corner rule tuned for the visible walls: Klipper's lines set it (next test); the others' do
    # not, and the note says which
    assert "corner rule" not in notes[0].split("per feature", 1)[1]
    cornered = TuneConfig(**{**per.to_dict(), "corner": 7.0, "min_cruise_ratio": 0.25})
    first = export_config(cornered).notes[0]
    not_carried = ("; nor do they set the visible walls' corner rule it was tuned with (corner 7; "
                   "minimum_cruise_ratio 0.25, in the printer's corner rule's unit): set it on the printer "
                   "as well, or print the job")
    assert first.endswith(not_carried) is (fw != "klipper")
    assert first.endswith(not_carried) is not any("SQUARE_CORNER_VELOCITY" in x for x in export_config(cornered).lines)


#: Klipper's own answer to a bare SET_VELOCITY_LIMIT (toolhead.py cmd_SET_VELOCITY_LIMIT: "%.6f" each),
#: as the console shows it
KLIPPER_LIMITS_REPORT = ("// max_velocity: 300.000000\n// max_accel: 4800.000000\n"
                         "// minimum_cruise_ratio: 0.250000\n// square_corner_velocity: 7.500000\n")


@pytest.mark.parametrize("fw", ["klipper", "kalico"])
def test_klippers_lines_set_the_visible_walls_corner_rule_and_read_it_back(fw):
    """A configuration tuned for Klipper (or Kalico) with a corner rule: one SET_VELOCITY_LIMIT sets
    square_corner_velocity (mm/s) and minimum_cruise_ratio after the acceleration, Klipper's report
    gives them back, the config part names the [printer] keys; --no-accel leaves both alone, and a
    configuration tuned for Marlin (whose corner value is a junction deviation) is not carried."""
    cfg = TuneConfig(shaper_x="ei", shaper_y="mzv", freq_x=51.4, freq_y=46.6, accel=4800.0, firmware=fw,
                     corner=7.5, min_cruise_ratio=0.25, feature_accel={"infill": 12000.0})
    exp = export_config(cfg)
    assert exp.lines[-2:] == ["SET_VELOCITY_LIMIT ACCEL=4800",
                              "SET_VELOCITY_LIMIT SQUARE_CORNER_VELOCITY=7.5 MINIMUM_CRUISE_RATIO=0.25"]
    at = len(exp.lines) - 1
    assert exp.setting_lines["square_corner_velocity"] == exp.setting_lines["minimum_cruise_ratio"] == at
    assert exp.readback.count("SET_VELOCITY_LIMIT") == 1
    assert "#   square_corner_velocity: 7.5\n#   minimum_cruise_ratio: 0.25\n" in exp.config_text
    assert any(n.startswith("the corner rule becomes square_corner_velocity 7.5 mm/s and minimum_cruise_ratio "
                            "0.25") for n in exp.notes)
    checked = compare(exp.expected, parse_report(fw, KLIPPER_LIMITS_REPORT))
    assert {k: v["ok"] for k, v in checked.items() if k in ("accel", "square_corner_velocity",
                                                            "minimum_cruise_ratio")} == \
        {"accel": True, "square_corner_velocity": True, "minimum_cruise_ratio": True}
    other = compare(exp.expected, parse_report(fw, KLIPPER_LIMITS_REPORT.replace("7.500000", "5.000000")))
    assert not other["square_corner_velocity"]["ok"] and other["minimum_cruise_ratio"]["ok"]
    untouched = export_config(cfg, accel=False)
    assert not any("SET_VELOCITY_LIMIT" in x for x in untouched.lines)
    assert "square_corner_velocity" not in untouched.expected
    assert untouched.notes[0].endswith("set it on the printer as well, or print the job")
    marlin_tuned = TuneConfig(**{**cfg.to_dict(), "firmware": "marlin", "shaper_x": "zv", "shaper_y": "zv",
                                 "corner": 0.02})
    assert not any("SQUARE_CORNER" in x for x in export_config(marlin_tuned, fw).lines)
    fine = export_config(TuneConfig(**{**cfg.to_dict(), "corner": 7.1234567}))   # Klipper reports 6 decimals
    assert fine.lines[-1].startswith("SET_VELOCITY_LIMIT SQUARE_CORNER_VELOCITY=7.123457 ")
