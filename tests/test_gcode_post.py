"""Acceptance 6: `ringtune limit` output differs from its input only in F words it had to change."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from ringtune.agents.cli.main import main
from ringtune.shaping.freqlimit import apply_freq_limit
from ringtune.shaping.gcode import read_gcode
from ringtune.shaping.gcode_post import limit_gcode_bytes
from ringtune.shaping.planner import MachineLimits, plan
from ringtune.shaping.testprints import builtin_test_gcode

F_WORD = re.compile(rb"\s*F[-+]?[\d.]+")


def _assert_only_f_words_differ(src: bytes, out: bytes) -> int:
    first, rest = out.split(b"\n", 1)
    assert first.startswith(b"; ringtune limit:")
    a = src.splitlines(keepends=True)
    b = rest.splitlines(keepends=True)
    assert len(a) == len(b)
    changed = 0
    for x, y in zip(a, b):
        if x == y:
            continue
        changed += 1
        code_x, _, comment_x = x.partition(b";")
        code_y, _, comment_y = y.partition(b";")
        assert comment_x == comment_y
        assert F_WORD.sub(b"", code_x).rstrip() == F_WORD.sub(b"", code_y).rstrip(), (x, y)
    return changed


@pytest.mark.parametrize("method", ["sections", "nophead", "marlin"])
def test_builtin_only_f_words_change_and_speeds_are_what_the_limit_asked(method):
    src = builtin_test_gcode().encode()
    out, res = limit_gcode_bytes(src, 25.0, method)
    changed = _assert_only_f_words_differ(src, out)
    assert changed == res.lines_changed > 0
    # re-reading the output gives exactly the limited speeds
    job = read_gcode(src.decode())
    want = apply_freq_limit(job, 25.0, method).feed
    got = read_gcode(out.decode()).feed
    np.testing.assert_allclose(got, want, rtol=1e-3)      # F written to 0.1 mm/min


def test_real_file_limit_is_minimal(data_dir, tmp_path):
    path = data_dir / "gcode/bassco_ender3/ringing_tower.gcode"
    src = path.read_bytes()
    out_path = tmp_path / "limited.gcode"
    code = main(["limit", str(path), "--freq-limit", "10", "-o", str(out_path)])
    assert code == 0
    out = out_path.read_bytes()
    changed = _assert_only_f_words_differ(src, out)
    assert changed > 0
    job, new = read_gcode(src.decode()), read_gcode(out.decode())
    np.testing.assert_allclose(new.feed, apply_freq_limit(job, 10.0, "sections").feed, rtol=1e-3)
    lim = MachineLimits(junction="scv")
    assert plan(new, lim).print_time > plan(job, lim).print_time


def test_no_change_when_nothing_exceeds_the_limit():
    src = builtin_test_gcode().encode()
    out, res = limit_gcode_bytes(src, 500.0, "sections")
    assert res.lines_changed == 0
    assert out.split(b"\n", 1)[1] == src


def test_checksummed_lines_get_a_new_checksum():
    def cs(s):
        x = 0
        for ch in s.encode():
            x ^= ch
        return f"{s}*{x}"

    body = ["N0 M83", "N1 G1 X0 Y0 F2160"]
    y = 0.0
    for k in range(12):
        y += 0.1
        body.append(f"N{k + 2} G1 X{0.59 if k % 2 == 0 else 0} Y{y:.1f} E0.03")
    src = ("\n".join(cs(b) for b in body) + "\n").encode()
    out, res = limit_gcode_bytes(src, 10.0, "nophead")
    assert res.lines_changed >= 1
    read_gcode(out.decode())                                     # the new checksums verify
    strip = re.compile(rb"\*\d+")
    assert _assert_only_f_words_differ(strip.sub(b"", src), strip.sub(b"", out)) == res.lines_changed


def test_limit_cli_json_and_errors(tmp_path, capsys):
    src = tmp_path / "t.gcode"
    src.write_text(builtin_test_gcode())
    out = tmp_path / "o.gcode"
    assert main(["limit", str(src), "--freq-limit", "25", "--method", "nophead", "-o", str(out), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["method"] == "nophead" and res["lines_changed"] > 0 and res["moves_slowed"] > 0
    assert main(["limit", str(src), "--freq-limit", "-3", "-o", str(out)]) == 2
    assert "--freq-limit" in capsys.readouterr().err
    assert main(["limit", str(tmp_path / "missing.gcode"), "--freq-limit", "20", "-o", str(out)]) == 2


def test_limit_errors_name_the_file_and_line(tmp_path, capsys):
    """A malformed value is a one-line error (exit 2) naming the input file and its line."""
    bad = tmp_path / "bad.gcode"
    bad.write_text("G1 X10 F600\nG1 X1..2 E1\n")
    assert main(["limit", str(bad), "--freq-limit", "20", "-o", str(tmp_path / "o.gcode")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and f"{bad}:2" in err and "Traceback" not in err


def test_line_numbers_follow_the_bytes_whatever_the_comments_hold():
    """Comments may hold characters Python's str.splitlines treats as line breaks (\\x1c, \\x0c,
    U+2028): the F words must still land on the lines that were limited."""
    src = builtin_test_gcode().encode()
    out0, res0 = limit_gcode_bytes(src, 25.0, "sections")
    odd = "; odd \x1c\x0c\u2028 comment\n".encode()
    out, res = limit_gcode_bytes(odd + src, 25.0, "sections")
    assert res.lines_changed == res0.lines_changed
    assert out.split(b"\n", 1)[1] == odd + out0.split(b"\n", 1)[1]
