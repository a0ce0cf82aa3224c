"""``ringtune limit --accel``: a sliced job's own acceleration commands scaled to the tuned value,
the ratios between features kept, nothing else changed. Checked with the project's independent
G-code reader (``shaping.gcode.read_gcode``: what a firmware would see per move) on a real
PrusaSlicer file and on per-feature slicer output."""

from __future__ import annotations

import json

import numpy as np
import pytest

from ringtune.agents.cli.main import main
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.gcode import read_gcode
from ringtune.shaping.gcode_post import rewrite_accel_bytes
from ringtune.shaping.job import SETTING_KEYS

SCALED = ("accel_print", "accel_travel", "accel_klipper", "accel_to_decel", "max_accel_x", "max_accel_y")


def _per_move(job, key):
    return job.settings_table[job.settings, SETTING_KEYS.index(key)]


def _same_motion(a, b):
    assert a.n_moves == b.n_moves
    for name in ("start", "end", "feed", "feature", "stop_before", "dwell_before"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def test_real_prusaslicer_job_gets_the_tuned_acceleration_and_nothing_else(data_dir):
    """The ianalexis Ender 3 tower caps everything with M201 X1500 Y1500 / M204 P1500 T1500 (issue 14):
    at --accel 3000 exactly those numbers double; R (retraction) and Z/E maxima stay."""
    src = data_dir / "gcode/ianalexis_ender3_marlin/ringing_tower.gcode"
    data = src.read_bytes()
    out, res = rewrite_accel_bytes(data, 3000.0, str(src))
    assert res.reference == 1500.0 and res.factor == 2.0 and res.lines_changed == 2
    old, new = data.splitlines(), out.splitlines()
    assert new[0].startswith(b"; ringtune limit --accel 3000") and len(new) == len(old) + 1
    differ = [(a, b) for a, b in zip(old, new[1:]) if a != b]
    assert differ == [
        (b"M201 X1500 Y1500 Z100 E5000 ; sets maximum accelerations, mm/sec^2",
         b"M201 X3000 Y3000 Z100 E5000 ; sets maximum accelerations, mm/sec^2"),
        (b"M204 P1500 R1000 T1500 ; sets acceleration (P, T) and retract acceleration (R), mm/sec^2",
         b"M204 P3000 R1000 T3000 ; sets acceleration (P, T) and retract acceleration (R), mm/sec^2")]
    a, b = read_gcode(data, source="in"), read_gcode(out, source="out")
    _same_motion(a, b)
    assert np.all(_per_move(b, "accel_print") == 3000.0) and np.all(_per_move(b, "max_accel_x") == 3000.0)
    for key in ("accel_retract", "max_accel_z", "max_accel_e"):
        assert np.array_equal(_per_move(a, key), _per_move(b, key), equal_nan=True)


def test_per_feature_accelerations_keep_their_ratios_and_checksums_stay_valid():
    job = (b"M204 S5000 ; default\n"
           b";TYPE:External perimeter\nM204 P2000\nG1 X10 Y0 E1 F3000\n"
           b";TYPE:Internal infill\nM204 P5000 T8000\nG1 X10 Y10 E2\n"
           b"N7 SET_VELOCITY_LIMIT ACCEL=2500 ACCEL_TO_DECEL=1250*63\nG1 X0 Y10 E3\n")
    job = job.replace(b"*63", b"*%d" % _xor(b"N7 SET_VELOCITY_LIMIT ACCEL=2500 ACCEL_TO_DECEL=1250"))
    out, res = rewrite_accel_bytes(job, 4000.0)
    assert res.reference == 5000.0 and res.factor == pytest.approx(0.8)
    a, b = read_gcode(job), read_gcode(out)          # raises on a checksum that does not match
    _same_motion(a, b)
    for key in SCALED:
        before, after = _per_move(a, key), _per_move(b, key)
        set_ = ~np.isnan(before)
        np.testing.assert_allclose(after[set_], 0.8 * before[set_])
    assert max(np.nanmax(_per_move(b, k)) for k in ("accel_print", "accel_klipper")) == 4000.0


def _xor(body: bytes) -> int:
    x = 0
    for ch in body:
        x ^= ch
    return x


def test_a_job_without_acceleration_commands_is_left_as_it_is_and_says_so(tmp_path, capsys):
    src = tmp_path / "plain.gcode"
    src.write_bytes(b"G1 X10 F3000\nG1 Y10\n")
    dst = tmp_path / "out.gcode"
    assert main(["limit", str(src), "--accel", "4000", "-o", str(dst), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["accel_reference"] is None and d["accel_lines_changed"] == 0 and d["notes"]
    assert dst.read_bytes().split(b"\n", 1)[1] == src.read_bytes()
    with pytest.raises(RingtuneError, match="--accel"):
        rewrite_accel_bytes(b"M204 P1000\n", 0.0)
    assert main(["limit", str(src), "-o", str(dst)]) == 2
    assert "--freq-limit HZ, --accel A" in capsys.readouterr().err


@pytest.mark.parametrize("output", [False, True])
@pytest.mark.parametrize("flags", [["--accel", "3000"], ["--freq-limit", "20"]])
def test_a_binary_file_is_refused_and_nothing_is_written(flags, output, tmp_path, capsys):
    """`limit bin.cfg --accel 3000` copied the binary to stdout or to -o: one line, exit 2, no output."""
    binary = tmp_path / "bin.cfg"
    binary.write_bytes(bytes(range(256)) * 8)
    out = tmp_path / "out.gcode"
    argv = ["limit", str(binary), *flags] + (["-o", str(out)] if output else [])
    assert main(argv) == 2
    std = capsys.readouterr()
    assert std.out == "" and not out.exists()
    assert std.err.strip() == f"ringtune limit: error: {binary}: not a text file (binary data), not G-code"


def test_a_folder_is_refused(tmp_path, capsys):
    assert main(["limit", str(tmp_path), "--accel", "3000"]) == 2
    assert f"{tmp_path}: is a directory, not a G-code file" in capsys.readouterr().err
