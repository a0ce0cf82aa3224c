"""The job rewriter (issue 22): real files of three slicers (PrusaSlicer for Marlin, Simplify3D for
Klipper, Cura for an Ultimaker read as RepRapFirmware, and the test part sliced whole by CuraEngine for
Marlin 2's junction deviation) get the chosen commands at every feature
change and nothing else; the rewritten file plans to the time ``tune`` reports for the
configuration; the layer hook inserts where a layer starts.

The expected acceleration of each move is computed here from the raw label (``feature_class``) and
the move itself (extruding or not), and the acceleration in force read back from the rewritten
file by the G-code reader — what a firmware would hold at that move."""

from __future__ import annotations

import difflib
import json
from dataclasses import replace

import numpy as np
import pytest

from ringtune.agents.cli.main import main
from ringtune.envs.planned_job import planned_job
from ringtune.envs.job_rewrite import HEADER, rewrite_gcode_bytes
from ringtune.envs.printer import load_printer
from ringtune.hardware.dialects import shaper_commands
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.config_plan import plan_with_config
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.feature_settings import FeatureCommands
from ringtune.shaping.features import feature_class
from ringtune.shaping.gcode import read_gcode
from ringtune.shaping.klipper_ignores import klipper_ignored
from ringtune.shaping.planner import MachineLimits
from ringtune.shaping.layers import layer_starts
from ringtune.shaping.rewrite import rewrite_job

FEATURES = {"outer_wall": 2500.0, "top_surface": 3500.0, "support": 4000.0, "infill": 9000.0,
            "travel": 12000.0}
#: (file, firmware, junction rule, corner value in that rule's unit)
SLICED = [("gcode/ianalexis_ender3_marlin/ringing_tower.gcode", "marlin", "jerk", 9.0),      # PrusaSlicer
          ("gcode/bassco_ender3/ringing_tower.gcode", "klipper", "scv", 8.0),                # Simplify3D
          ("gcode/fastlb_cura_um2/platte_klein_cut.gcode", "rrf", "jerk", 9.0),              # Cura
          pytest.param("part/part_cura.gcode", "marlin", "jd", 0.02, marks=pytest.mark.slow)]  # Cura, whole


def _printer(junction: str):
    """The default printer with the junction rule of the firmware under test."""
    return replace(load_printer(None), limits_dict={"accel": 3000, "velocity": 300, "junction": junction})


def _config(firmware: str, junction: str, corner: float, **kw) -> TuneConfig:
    """RepRapFirmware: one shaper for all axes (both mzv at 45 Hz: it has no zv)."""
    shaper = "mzv" if firmware == "rrf" else "zv"
    return TuneConfig(firmware=firmware, shaper_x=shaper, shaper_y=shaper, freq_x=45.0,
                      freq_y=45.0 if firmware == "rrf" else 40.0, accel=6000.0,
                      feature_accel=dict(FEATURES), corner=corner,
                      min_cruise_ratio=0.25 if junction == "scv" else None, **kw)


def _expected_accel(job, cfg: TuneConfig, junction: str) -> tuple[np.ndarray, np.ndarray]:
    """(printing, travel) acceleration each move must run with, from the label and the move."""
    def acc(cls):
        return cfg.feature_accel.get(cls, cfg.accel)
    labels = np.array([acc(feature_class(job.features[f])) for f in job.feature])
    if junction != "scv":          # M204 P by the label, T for travel: the seam's travel's the wall's
        return labels, np.array([acc(c) if seam else acc("travel") for c, seam in _effective(job)])
    out = _one_value(job, acc)
    return out, out


def _effective(job) -> list[tuple]:
    """Per move: (the class its settings follow, True on the seam's travel), by a loop: the label's
    class when it extrudes, ``travel`` for an X/Y move without E — unless the next X/Y move that
    extrudes, past any travel between (else the X/Y move before), is of a visible class: then that
    class (the seam's travel: every move of a hop onto the wall, the move off its end,
    ``shaping/feature_settings.py``; ``other`` is visible only in a job labelling nothing visible);
    a move without X/Y keeps the one before it (before any X/Y move: its label's, no seam)."""
    xy = [i for i, (a, b) in enumerate(zip(job.start, job.end)) if np.hypot(*(b - a)[:2]) > 0]
    cls = {i: feature_class(job.features[job.feature[i]]) if job.end[i][3] > job.start[i][3] else "travel"
           for i in xy}
    seen = {"outer_wall", "top_surface", "bridge_overhang"}
    if not any(cls[i] in seen for i in xy):
        seen.add("other")
    eff = {i: (c, False) for i, c in cls.items()}
    for n, i in enumerate(xy):
        if cls[i] != "travel":
            continue
        nxt = next((cls[j] for j in xy[n + 1:] if cls[j] != "travel"), None)
        prv = cls[xy[n - 1]] if n > 0 else None
        if nxt in seen:
            eff[i] = (nxt, True)
        elif prv in seen:
            eff[i] = (prv, True)
    out, prev = [], None
    for i in range(job.n_moves):
        prev = eff.get(i, prev)
        out.append(prev if prev is not None else (feature_class(job.features[job.feature[i]]), False))
    return out


def _one_value(job, value_of) -> np.ndarray:
    """The value each move runs with where one command sets it for printing and travel alike:
    ``value_of`` of the class :func:`_effective` gives it."""
    return np.array([value_of(c) for c, _seam in _effective(job)])


#: per-class corner settings (the corners nobody sees): twice the job-wide corner, no cruise smoothing
BEHIND = ("infill", "support", "solid_infill", "travel")


@pytest.mark.parametrize("per_class", [False, True], ids=["job-wide corner", "corner per class"])
@pytest.mark.parametrize("path,firmware,junction,corner", SLICED)
def test_every_feature_change_carries_the_commands_and_nothing_else_changes(data_dir, path, firmware,
                                                                            junction, corner, per_class):
    src = (data_dir / path).read_bytes()
    cfg = _config(firmware, junction, corner)
    if per_class:
        cfg = replace(cfg, feature_corner=dict.fromkeys(BEHIND, 2 * corner),
                      feature_min_cruise_ratio=dict.fromkeys(BEHIND, 0.0) if junction == "scv" else {})
    printer = _printer(junction)
    done = rewrite_gcode_bytes(src, cfg, printer, path, shaper_lines=shaper_commands)
    old = src.decode("utf-8", "surrogateescape").splitlines()
    new = done.data.decode("utf-8", "surrogateescape").splitlines()
    # the job's own shaper commands (the PrusaSlicer tower's M593 F per layer) are replaced by the
    # configuration's (Marlin: M593 X, then M593 Y), the first line quoting the job's: the file then
    # shapes as tune judged it; with those put back, the diff has only inserted lines, each one of
    # ours (the header, a command of the firmware's dialect)
    own = {ev.line for ev in read_gcode(src, source=path).events if ev.kind == "shaper" and ev.command == "M593"}
    assert [ln for ln, _t in done.shaper_replaced] == sorted(own) and bool(own) == ("ianalexis" in path)
    first, *rest = shaper_commands(cfg)
    mark = f"{first} ; ringtune: in place of the job's own "
    restored, k = [], 0
    while k < len(new):
        if new[k].startswith(mark):
            assert new[k + 1:k + 1 + len(rest)] == rest
            restored.append(new[k][len(mark):])
            k += 1 + len(rest)
        else:
            restored.append(new[k])
            k += 1
    assert sum(line.startswith(mark) for line in new) == len(own)
    ops = difflib.SequenceMatcher(None, [ln.strip() for ln in old], [ln.strip() for ln in restored],
                                  autojunk=False).get_opcodes()
    assert {op for op, *_ in ops} <= {"equal", "insert"}
    added = [line for op, _, _, j1, j2 in ops if op == "insert" for line in restored[j1:j2]]
    assert len(added) == done.lines_inserted + 1 and added[0].startswith(HEADER)
    words = {"klipper": ("SET_VELOCITY_LIMIT ",), "marlin": ("M204 P", "M205 J" if junction == "jd" else "M205 X",
                                                             "M201 X"),
             "rrf": ("M204 P", "M566 X", "M201 X")}[firmware]
    assert all(line.startswith(words) for line in added[1:])
    # every move runs with its feature's acceleration, as the reader (the firmware) holds it
    job = read_gcode(done.data, source="out")
    want_p, want_t = _expected_accel(job, cfg, junction)
    want_corner = _one_value(job, lambda c: cfg.feature_corner.get(c, corner))
    assert (np.ptp(want_corner) > 0) == per_class        # the job has moves of both kinds
    if junction == "scv":
        assert np.array_equal(job.setting("accel_klipper"), want_p)
        assert np.array_equal(job.setting("square_corner_velocity"), want_corner)
        assert np.array_equal(job.setting("min_cruise_ratio"),
                              _one_value(job, lambda c: cfg.feature_min_cruise_ratio.get(c, 0.25)))
    else:
        assert np.array_equal(job.setting("accel_print"), want_p)
        assert np.array_equal(job.setting("accel_travel"), want_t)
        if junction == "jd":
            assert np.allclose(job.setting("junction_deviation"), want_corner)
        else:
            assert np.allclose(job.setting("jerk_x"), want_corner) and np.allclose(job.setting("jerk_y"), want_corner)
        assert np.all(job.setting("max_accel_x") >= max(FEATURES.values()))
    # the planned time of the rewritten file is tune's figure for the configuration
    tune_s = planned_job(printer, (data_dir / path), cfg).print_time
    assert done.config_s == pytest.approx(tune_s, rel=1e-12)
    assert done.after_s == pytest.approx(tune_s, rel=1e-9)
    assert plan_with_config(job, printer.limits, cfg).plan.print_time == pytest.approx(tune_s, rel=1e-9)
    # where the file sets every acceleration a move takes (Marlin's M204 R in the job: not Cura's, not RRF's
    # M204), it plans to that time as it stands
    if firmware != "rrf" and np.all(np.isfinite(job.setting("accel_retract"))):
        assert plan_with_config(job, printer.limits, None).plan.print_time == pytest.approx(tune_s, rel=1e-9)


@pytest.mark.parametrize("firmware", ["marlin", "rrf"])
def test_stored_axis_caps_the_configuration_raises_are_raised_in_the_file(data_dir, firmware):
    """A printer whose stored X/Y caps are 500 mm/s² (Marlin's M201 from its M503): the configuration
    raises them (every trial carries its caps, as export sends them), and the rewritten file raises
    them itself — planned as the file stands on that printer, no configuration over it, it takes
    tune's time, not the time the stored caps would give. For RRF the file's M203 is written in
    mm/min, as RRF reads it and PrusaSlicer's RRF flavour writes it."""
    path = "gcode/ianalexis_ender3_marlin/ringing_tower.gcode"
    source = (data_dir / path).read_bytes()
    if firmware == "rrf":
        source = source.replace(b"M203 X500 Y500 Z10 E60 ; sets maximum feedrates, mm / sec",
                                b"M203 X30000 Y30000 Z600 E3600 ; sets maximum feedrates, mm / min")
    printer = replace(load_printer(None), limits_dict={"accel": 500, "velocity": 300, "junction": "jerk",
                                                       "max_accel": [500, 500, 100, 5000]})
    cfg = replace(_config(firmware, "jerk", 9.0), max_accel_x=12000.0, max_accel_y=12000.0)
    done = rewrite_gcode_bytes(source, cfg, printer, path, shaper_lines=shaper_commands)
    assert "M201 X12000 Y12000" in done.data.decode()
    tune_s = planned_job(printer, read_gcode(source), cfg).print_time
    job = read_gcode(done.data, source="out")
    assert np.all(job.setting("max_accel_x") == 12000.0) and np.all(job.setting("max_accel_y") == 12000.0)
    if firmware == "marlin":     # the file sets every acceleration a move takes
        assert plan_with_config(job, printer.limits, None).plan.print_time == pytest.approx(tune_s, rel=1e-9)
    assert done.after_s == pytest.approx(tune_s, rel=1e-9)
    capped = plan_with_config(read_gcode(source), printer.limits,
                              replace(cfg, max_accel_x=500.0, max_accel_y=500.0)).plan.print_time
    assert capped > 1.05 * tune_s


def test_a_first_layer_the_job_slows_itself_keeps_its_own_acceleration(data_dir):
    """A job that slows its first layer (M204 P1500, then 4000 above, as slicers do for adhesion)
    rewritten per feature: every printing move of the first layer runs at the lower of the job's
    1500 and its class's, as re-slicing would keep it; above it the classes' values; the planned
    time is the configuration's; a value set once for the whole job (a machine-limits header) is no
    slowdown and is overruled as before. Expected values worked out here from the layers by hand."""
    layer = ";TYPE:External perimeter\nG1 X20 Y0 E1 F6000\n;TYPE:Internal infill\nG1 X20 Y20 E1\nG1 X0 Y20 E1\n"
    slowed = "G90\nM83\nM204 P1500\nG1 Z0.2 F600\n" + layer + "G1 Z0.4\nM204 P4000\n" + layer
    header = "G90\nM83\nM204 P1500\nG1 Z0.2 F600\n" + layer + "G1 Z0.4\n" + layer
    cfg = TuneConfig(firmware="marlin", accel=3000.0, feature_accel={"infill": 9000.0}, corner=9.0)
    printer = _printer("jerk")
    done = rewrite_gcode_bytes(slowed.encode(), cfg, printer, "slowed")
    job = read_gcode(done.data, source="out")
    ext = job.extruding
    # moves: Z, wall, infill, infill (layer 0, at Z 0.2) | Z, wall, infill, infill (layer 1)
    assert job.setting("accel_print")[ext].tolist() == [1500.0, 1500.0, 1500.0, 3000.0, 9000.0, 9000.0]
    assert done.first_layer == 1500.0 and done.after_s == pytest.approx(done.config_s, rel=1e-9)
    assert done.config_s == pytest.approx(planned_job(printer, slowed, cfg).print_time, rel=1e-12)
    kept = rewrite_gcode_bytes(header.encode(), cfg, printer, "header")
    assert read_gcode(kept.data).setting("accel_print")[ext].tolist() == [3000.0, 9000.0, 9000.0] * 2
    assert kept.first_layer is None


def test_rewrite_says_the_first_layer_it_keeps(tmp_path, capsys):
    layer = ";TYPE:External perimeter\nG1 X20 Y0 E1 F6000\n;TYPE:Internal infill\nG1 X20 Y20 E1\nG1 X0 Y20 E1\n"
    src, conf = tmp_path / "slowed.gcode", tmp_path / "best.json"
    src.write_text("G90\nM83\nM204 P1500\nG1 Z0.2 F600\n" + layer + "G1 Z0.4\nM204 P4000\n" + layer)
    conf.write_text(json.dumps(TuneConfig(accel=3000.0, feature_accel={"infill": 9000.0}).to_dict()))
    assert main(["rewrite", str(src), "--config", str(conf), "-o", str(tmp_path / "out.gcode"), "--json"]) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out)["first_layer_kept"] == 1500.0
    assert "slows its own first layer to 1500 mm/s²" in captured.err and "keeps the job's own" in captured.err


def test_job_accelerations_after_ours_are_overruled_and_the_retract_one_stays():
    """A slicer's own M204 at a feature change comes after our line would: ours follows it again;
    the job's retract acceleration (M204 R) is left alone."""
    text = ("M204 P1000 R700 T1000\n;TYPE:External perimeter\nM204 P800\nG1 X20 Y0 E1 F6000\nG1 E0.2\n"
            ";TYPE:Internal infill\nM204 P5000\nG1 X20 Y20 E2\nG1 X0 Y20 E3\n")
    cfg = TuneConfig(firmware="marlin", accel=4000.0, feature_accel={"outer_wall": 2000.0, "infill": 8000.0})
    limits = MachineLimits(accel=3000, junction="jd")
    out = rewrite_job(text.splitlines(keepends=True), "marlin", FeatureCommands.from_config(cfg, limits))
    job = read_gcode("".join(out))
    assert job.setting("accel_print").tolist() == [2000.0, 2000.0, 8000.0, 8000.0]
    assert np.all(job.setting("accel_retract") == 700.0)
    assert "".join(out).count("M204 P2000 T4000") == 1 and "".join(out).count("M204 P8000 T4000") == 1


def test_a_move_runs_at_its_feature_acceleration_analytically():
    """Two moves from rest to rest (a dwell between): each takes d/v + v/a with its own class's a."""
    text = ";TYPE:External perimeter\nG1 X100 Y0 E5 F6000\nG4 P0\n;TYPE:Internal infill\nG1 X0 Y0 E10\n"
    limits = MachineLimits(accel=3000, velocity=300, junction="scv", min_cruise_ratio=0.0)
    cfg = TuneConfig(accel=4000.0, feature_accel={"outer_wall": 1000.0, "infill": 5000.0})
    plan = plan_with_config(read_gcode(text), limits, cfg).plan
    v, d = 100.0, 100.0
    assert plan.moves.duration.tolist() == pytest.approx([d / v + v / 1000.0, d / v + v / 5000.0], rel=1e-12)


def test_layer_inserts_go_before_each_layers_first_move():
    text = ("G28\nG1 Z0.2 F600\nG1 X10 Y0 E1 F3000\nG1 X10 Y10 E2\n"      # layer 0 at Z 0.2
            "G1 Z0.6\nG1 Z0.4\nG1 X0 Y10 E3\n"                             # hop, then layer 1 at Z 0.4
            "G1 X0 Y0 Z0.8 F3000\nG1 X5 Y0 E4\n")                           # layer 2 at Z 0.8
    lines = text.splitlines(keepends=True)
    job = read_gcode(text)
    assert len(layer_starts(job)) == 3
    out = rewrite_job(lines, "klipper", None, {1: ["SET_INPUT_SHAPER SHAPER_FREQ_Y=40"], 2: ["; two"]})
    assert [ln for ln in out if ln not in lines] == ["SET_INPUT_SHAPER SHAPER_FREQ_Y=40\n", "; two\n"]
    assert out.index("SET_INPUT_SHAPER SHAPER_FREQ_Y=40\n") == out.index("G1 Z0.6\n") - 1
    assert out.index("; two\n") == out.index("G1 X0 Y0 Z0.8 F3000\n") - 1
    with pytest.raises(RingtuneError, match="layer 5"):
        rewrite_job(lines, "klipper", None, {5: ["x"]})


def test_frequency_limit_composes_with_the_rewrite(data_dir):
    path = data_dir / "gcode/ringtune_builtin_2025/test_print.gcode"    # zigzags sweeping 10-80 Hz
    cfg = _config("marlin", "jerk", 9.0, freq_limit_hz=20.0)
    printer = _printer("jerk")
    done = rewrite_gcode_bytes(path.read_bytes(), cfg, printer, str(path))
    assert done.f_lines_changed > 0 and done.data.splitlines()[1].startswith(b"; ringtune limit")
    # F words are written to 0.1 mm/min: the rewritten file plans within 0.01 % of tune's figure
    assert done.after_s == pytest.approx(planned_job(printer, path, cfg).print_time, rel=1e-4)


@pytest.mark.parametrize("freq_limit_hz", [0.0, 20.0], ids=["no limit", "F words changed"])
def test_a_job_already_read_rewrites_to_the_same_bytes(data_dir, freq_limit_hz):
    """tune hands the rewrite the job it read (``parsed``): the same file, times and insertions as
    reading the bytes again, with the frequency limit's F words changed or not."""
    path = data_dir / "gcode/ringtune_builtin_2025/test_print.gcode"
    cfg = _config("klipper", "scv", 9.0, freq_limit_hz=freq_limit_hz)
    printer = _printer("scv")
    data = path.read_bytes()
    fresh = rewrite_gcode_bytes(data, cfg, printer, str(path))
    given = rewrite_gcode_bytes(data, cfg, printer, str(path), parsed=read_gcode(path))
    assert given.data == fresh.data and given.lines_inserted == fresh.lines_inserted > 0
    assert (given.before_s, given.after_s, given.config_s) == (fresh.before_s, fresh.after_s, fresh.config_s)
    assert (given.f_lines_changed > 0) == (freq_limit_hz > 0)


def test_rewrite_command(tmp_path, data_dir, capsys):
    cfg = _config("klipper", "scv", 8.0)
    (tmp_path / "best.json").write_text(json.dumps(cfg.to_dict()))
    src = data_dir / "gcode/bassco_ender3/ringing_tower.gcode"
    out = tmp_path / "job.gcode"
    assert main(["rewrite", str(src), "--config", str(tmp_path / "best.json"), "-o", str(out), "--json"]) == 0
    r = json.loads(capsys.readouterr().out)
    assert r["print_time_after_s"] == pytest.approx(r["print_time_config_s"], rel=1e-9)
    assert r["print_time_after_s"] < r["print_time_before_s"] and r["feature_accel"]["travel"] == 12000.0
    assert out.read_bytes().startswith(HEADER.encode())
    (tmp_path / "bad.json").write_text('{"feature_accel": {"walls": 3000}}')
    assert main(["rewrite", str(src), "--config", str(tmp_path / "bad.json"), "-o", str(out)]) == 2
    assert "not a feature class" in capsys.readouterr().err


def test_config_round_trip_and_refusals(tmp_path):
    cfg = _config("klipper", "scv", 8.0)
    cfg.save(tmp_path / "c.json")
    back = TuneConfig.load(tmp_path / "c.json")
    assert back == cfg and back.feature_accel == FEATURES and back.per_feature
    assert "feature_accel" not in TuneConfig().to_dict() and not TuneConfig().per_feature
    for bad, where in (({"feature_accel": {"infill": 0}}, "feature_accel.infill"),
                       ({"feature_accel": {"infill": "fast"}}, "feature_accel.infill"),
                       ({"corner": -2}, "corner"), ({"min_cruise_ratio": 1.0}, "min_cruise_ratio")):
        with pytest.raises(RingtuneError, match=where):
            TuneConfig.from_dict(bad)


def test_simulate_takes_every_per_feature_key_as_an_option(capsys):
    argv = ["simulate", "--backend", "lti", "--shaper", "mzv", "--freq", "45,40", "--accel", "5000", "--json",
            "--feature-accel", "infill=10000,travel=9000", "--corner", "7", "--min-cruise-ratio", "0.2"]
    assert main(argv) == 0
    res = json.loads(capsys.readouterr().out)
    cfg = TuneConfig(shaper_x="mzv", shaper_y="mzv", freq_x=45.0, freq_y=40.0, accel=5000.0,
                     feature_accel={"infill": 10000.0, "travel": 9000.0}, corner=7.0, min_cruise_ratio=0.2)
    assert res["metrics"]["print_time_s"] == planned_job(load_printer(None), None, cfg).print_time
    assert main(argv[:-6] + ["--feature-accel", "infill"]) == 2
    assert "--feature-accel" in capsys.readouterr().err


def test_line_endings_and_odd_bytes_are_kept():
    """CRLF endings, a form feed and a non-UTF-8 byte in comments: inserted lines take the file's
    ending, every input byte is kept, and the commands sit before the right moves."""
    src = (b"; made by hand \xff\r\n;TYPE:External perimeter\r\nG1 X10 Y0 E1 F3000 ; \x0c odd\r\n"
           b";TYPE:Internal infill\r\nG1 X10 Y10 E2\r\n")
    cfg = TuneConfig(accel=3000.0, feature_accel={"outer_wall": 1500.0, "infill": 9000.0})
    done = rewrite_gcode_bytes(src, cfg, _printer("scv"))
    out = done.data.split(b"\r\n")
    assert b"".join(ln for ln in out if b"ringtune" not in ln) == src.replace(b"\r\n", b"")
    assert out[out.index(b"G1 X10 Y10 E2") - 1] == b"SET_VELOCITY_LIMIT ACCEL=9000 ; ringtune: infill"
    wall = out.index(b"G1 X10 Y0 E1 F3000 ; \x0c odd")
    assert out[wall - 1] == b"SET_VELOCITY_LIMIT ACCEL=1500 ; ringtune: outer_wall"


#: a Klipper job setting its own acceleration per feature, two moves from rest to rest (a dwell between)
OWN_ACCEL = (";TYPE:External perimeter\nM204 S1000\nG1 X100 Y0 E5 F6000\nG4 P0\n"
             ";TYPE:Internal infill\nM204 S5000\nG1 X0 Y0 E10\n")


@pytest.mark.parametrize("mode, per_feature, accels", [
    ("respect", False, (1000.0, 5000.0)),            # the job's own commands stand, as tune judged
    ("replace", False, (4000.0, 4000.0)),            # the configuration's one acceleration replaces them
    ("respect", True, (2000.0, 8000.0)),             # per-feature settings overrule them in either mode
])
def test_the_rewritten_file_runs_each_move_as_tune_judged_it(mode, per_feature, accels):
    """Truth: each move takes d/v + v/a (100 mm at 100 mm/s from rest to rest) with the acceleration
    it runs at — the job's own where tune judged the configuration with them standing and it sets
    nothing per feature (then the file is the input under the header), else the configuration's."""
    printer = replace(load_printer(None), limits_dict={"accel": 3000, "velocity": 300, "junction": "scv",
                                                       "min_cruise_ratio": 0.0})
    cfg = TuneConfig(firmware="klipper", accel=4000.0, extra={"job_accel": mode},
                     feature_accel={"outer_wall": 2000.0, "infill": 8000.0} if per_feature else {})
    done = rewrite_gcode_bytes(OWN_ACCEL.encode(), cfg, printer)
    truth = sum(1.0 + 100.0 / a for a in accels)
    assert done.after_s == pytest.approx(truth, rel=1e-9) and done.config_s == pytest.approx(truth, rel=1e-9)
    body = done.data.decode().split("\n", 1)[1]
    assert (body == OWN_ACCEL) == (mode == "respect" and not per_feature)
    assert (done.commands is None) == (body == OWN_ACCEL)


def test_rewrite_command_with_the_jobs_own_accelerations_standing(tmp_path, capsys):
    src, conf, dst = tmp_path / "own.gcode", tmp_path / "best.json", tmp_path / "out.gcode"
    src.write_text(OWN_ACCEL)
    conf.write_text(json.dumps(TuneConfig(firmware="klipper", accel=4000.0, extra={"job_accel": "respect"}).to_dict()))
    assert main(["rewrite", str(src), "--config", str(conf), "-o", str(dst), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["lines_inserted"] == 0 and res["feature_accel"] is None and res["corner"] is None
    assert "the job's own acceleration commands stand" in res["header"] and res["junction"] == "scv"
    assert dst.read_text().split("\n", 1)[1] == OWN_ACCEL


#: two layers of one 100 mm wall from rest to rest at 100 mm/s; the job slows its first (M204 S/P 1000)
SLOWED_FIRST = ("G90\nM83\n{a1}\nG1 Z0.2 F600\nG4 P0\n;TYPE:External perimeter\nG1 X100 Y0 E5 F6000\nG4 P0\n"
                "G1 Z0.4 F600\nG4 P0\n{a2}\n;TYPE:External perimeter\nG1 X0 Y0 E5 F6000\nG4 P0\n")


@pytest.mark.parametrize("firmware, junction, a1, a2", [
    ("klipper", "scv", "M204 S1000", "M204 S5000"),
    ("marlin", "jd", "M204 P1000", "M204 P5000"),
    ("marlin", "scv", "M204 P1000", "M204 P5000"),      # Marlin read as Marlin on a printer described with scv
])
def test_one_acceleration_replacing_the_jobs_own_is_judged_as_the_file_runs_it(firmware, junction, a1, a2):
    """``--job-accel replace`` with one acceleration (4000 mm/s²): the rewrite writes it at every
    feature change and keeps the first layer the job slows itself; tune's plan of the configuration
    is that file's. Truth: each wall takes 1 + 100/a s (100 mm at 100 mm/s from rest to rest) with a
    = 1000 on the first layer and 4000 on the second, plus the Z moves (0.2 mm at 10 mm/s, the
    same in every plan, taken from the plan itself)."""
    printer = replace(load_printer(None), limits_dict={"accel": 3000, "velocity": 300, "junction": junction,
                                                       "min_cruise_ratio": 0.0})
    text = SLOWED_FIRST.format(a1=a1, a2=a2)
    cfg = TuneConfig(firmware=firmware, accel=4000.0, extra={"job_accel": "replace"})
    done = rewrite_gcode_bytes(text.encode(), cfg, printer, "slowed")
    plan = planned_job(printer, text, cfg).plan
    walls = plan.moves.extruding
    assert plan.moves.duration[walls].tolist() == pytest.approx([1 + 100 / 1000, 1 + 100 / 4000], rel=1e-12)
    assert done.config_s == pytest.approx(plan.print_time, rel=1e-12)
    assert done.after_s == pytest.approx(done.config_s, rel=1e-12) and done.first_layer == 1000.0


@pytest.mark.parametrize("old", [False, True], ids=["Klipper since 2024", "Klipper before 2024"])
def test_a_klipper_rewrite_loses_no_word_on_either_age(data_dir, old):
    """Where every group shares the corner rule, the rewrite writes MINIMUM_CRUISE_RATIO once and
    ACCEL_TO_DECEL beside each ACCEL: together they say the same on either Klipper, so nothing of
    ringtune's own file is named as not acted on (a tune of the Cura job named the first ACCEL line)."""
    path = data_dir / "gcode/fastlb_cura_um2/platte_klein_cut.gcode"
    cfg = TuneConfig(firmware="klipper", accel=3300.0, feature_accel={"infill": 3300.0, "travel": 3300.0},
                     corner=8.0, min_cruise_ratio=0.5, feature_corner={"infill": 8.0},
                     feature_min_cruise_ratio={"infill": 0.5})
    printer = replace(load_printer(None), limits_dict={
        "accel": 3000, "velocity": 300, "junction": "scv", "min_cruise_ratio": 0.25,
        **({"accel_to_decel": 1000.0} if old else {})})
    done = rewrite_gcode_bytes(path.read_bytes(), cfg, printer, str(path))
    text = done.data.decode()
    assert "MINIMUM_CRUISE_RATIO=0.5" in text and "ACCEL=3300 ACCEL_TO_DECEL=1650" in text
    assert klipper_ignored(read_gcode(text), printer.limits) == {}
    # a word that disagrees with what is in effect is still named
    bad = text.replace("ACCEL=3300 ACCEL_TO_DECEL=1650", "ACCEL=3300 ACCEL_TO_DECEL=3000", 1)
    assert klipper_ignored(read_gcode(bad), printer.limits) != {}
