"""Errors that were one line but not clear (issue 14, "Smaller things"): each names what is wrong
in the user's terms — the file that is not G-code and what it is, the option and its unit, any
case of a firmware name."""

from __future__ import annotations

import json

import pytest

from ringtune.agents.cli.main import main


def _error(capsys, argv) -> str:
    assert main(argv) == 2
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert out == ""
    return lines[0]


def _png(path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    ax.plot([0, 1, 0, 2])
    fig.savefig(path)
    plt.close(fig)
    return path


def test_plan_of_a_png_says_it_is_an_image(tmp_path, capsys):
    """`plan fit.png` printed the reader's complaint about a line of the PNG's bytes."""
    png = _png(tmp_path / "fit.png")
    line = _error(capsys, ["plan", str(png)])
    assert line == f"ringtune plan: error: {png}: a PNG image, not G-code"
    assert line.isprintable()


def test_plan_of_a_printer_toml_says_give_it_with_printer(tmp_path, capsys):
    """`plan myprinter.toml` said `line number N must be an integer` (the `name = ...` line)."""
    from pathlib import Path

    import ringtune.envs.data

    toml = tmp_path / "myprinter.toml"
    toml.write_text((Path(ringtune.envs.data.__file__).parent / "ender3.toml").read_text())
    line = _error(capsys, ["plan", str(toml)])
    assert "TOML file" in line and "--printer" in line and "line number" not in line


def test_gcode_sniff_knows_real_files_from_the_data(data_dir):
    from ringtune.shaping.gcode_sniff import HEAD, not_gcode

    for g in sorted((data_dir / "gcode").glob("*/*.gcode")):
        assert not_gcode(g.read_bytes()[:HEAD]) is None, g
    csv = next(iter(sorted((data_dir / "accel").rglob("*.csv"))))
    assert "CSV" in not_gcode(csv.read_bytes()[:HEAD])
    for cfg in sorted((data_dir / "klipper_config").glob("*/printer.cfg")):
        assert not_gcode(cfg.read_bytes()[:HEAD]) is not None, cfg
    # the part's own model, before slicing: named as a model, with what to do
    stl = (data_dir / "part" / "ringtune_part.stl").read_bytes()[:HEAD]
    assert not_gcode(stl).startswith("looks like an STL model (slice it first")
    obj = b"# made by hand\no cube\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1 2 3\n"
    assert not_gcode(obj).startswith("looks like an OBJ model (slice it first")


@pytest.mark.parametrize("argv,expected", [
    (["--shaper", "mzv", "--freq", "-40"], "--freq: -40 Hz is not a shaper frequency"),
    (["--shaper", "mzv", "--freq", "40", "--damping", "1.5"], "--damping: 1.5 is not a damping ratio"),
    (["--freq-limit", "-3"], "--freq-limit: -3 Hz is not a frequency limit"),
    (["--accel", "0"], "--accel: 0 mm/s² is not a printing acceleration"),
    (["--shaper", "mzv", "--freq", "0"], "--freq: "),
])
def test_simulate_names_the_option_not_the_config_key(argv, expected, capsys):
    """`simulate --freq -40` said `options: freq_x: -40.0 is out of range [0, 1000]`."""
    line = _error(capsys, ["simulate", "--backend", "lti", *argv])
    assert expected in line and "options:" not in line and "freq_x" not in line.split("shaper_x")[0]


@pytest.mark.parametrize("argv", [
    ["study", "--json", "--firmware", "Klipper", "--values", "0", "--shapers", "mzv", "--backend", "lti"],
    ["simulate", "--json", "--firmware", "RRF", "--shaper", "zvd", "--freq", "40", "--backend", "lti",
     "--freq-margin", "0"],
])
def test_firmware_names_in_any_case(argv, tmp_path, capsys):
    """`Klipper` was refused (`study`, `recommend`): every --firmware goes through the firmware
    record's parser, once, in the CLI."""
    if argv[0] == "study":
        argv = argv + ["-o", str(tmp_path / "s.png")]
    assert main(argv) == 0
    res = json.loads(capsys.readouterr().out)
    if argv[0] == "simulate":
        assert res["config"]["firmware"] == "rrf"


def test_recommend_takes_a_capitalised_firmware(capsys):
    assert main(["recommend", "--json", "--printer", "default", "--firmware", "Klipper"]) == 0
    assert json.loads(capsys.readouterr().out)


def test_unknown_firmware_is_refused_once_naming_the_option(capsys):
    line = _error(capsys, ["simulate", "--firmware", "Duet"])
    assert "--firmware" in line and "klipper" in line and "'Duet'" in line


def _binary_without_nul(seed: int, n: int) -> bytes:
    import random

    r = random.Random(seed)
    return bytes(r.randrange(1, 256) for _ in range(n))


@pytest.mark.parametrize("seed", [550, 1649, 77])
def test_plan_of_a_binary_file_says_not_a_text_file(seed, tmp_path, capsys):
    """Random bytes with no NUL (seeds whose lines happened to read as G-code, or as nothing)
    gave 'the job has no moves' or a line-number complaint: a binary file is not a text file."""
    path = tmp_path / "bin.cfg"
    path.write_bytes(_binary_without_nul(seed, 500 if seed == 77 else 3000))
    line = _error(capsys, ["plan", str(path)])
    assert line == f"ringtune plan: error: {path}: not a text file (binary data), not G-code", line


def test_gcode_with_a_latin1_comment_is_still_gcode(capsys):
    """The binary rule leaves a text file in another 8-bit encoding alone (a degree sign in cp1252)."""
    from ringtune.shaping.gcode import read_gcode

    job = read_gcode("; nozzle 210 \xb0C\nG1 X10 F600\nG1 Y10\n".encode("cp1252"), source="t.gcode")
    assert job.n_moves == 2


def _dry_run(tmp_path):
    """A job that moves and extrudes nothing (a "no extrusion" flavour's: no E words)."""
    moves = "".join(f"G1 X{x} Y{y} F6000\n" for x, y in [(10, 10), (60, 10), (60, 60), (10, 60), (10, 10)] * 20)
    path = tmp_path / "dry.gcode"
    path.write_text(";TYPE:External perimeter\nG28\nG1 Z0.2 F3000\n" + moves)
    return path


def test_a_job_that_extrudes_nothing_is_refused_by_what_judges_it(tmp_path, capsys):
    """simulate of a no-extrusion job crashed with a KeyError, and tune "tuned" it on print time alone
    (no quality window: nothing printed to judge); both now say so, and plan still times it."""
    job = _dry_run(tmp_path)
    line = _error(capsys, ["simulate", "--gcode", str(job)])
    assert line.startswith(f"ringtune simulate: error: {job}: the job extrudes nothing")
    assert "`ringtune plan`" in line
    assert main(["tune", "--gcode", str(job), "--trials", "2", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.strip().splitlines()[-1].startswith(
        f"ringtune tune: error: {job}: the job extrudes nothing")
    assert not (tmp_path / "out").exists()
    assert main(["plan", str(job), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["print_time_s"] > 0
