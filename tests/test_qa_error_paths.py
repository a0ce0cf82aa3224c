"""Error paths a new user meets on the finished commands (export, push, testprint, identify --ripples):
a folder where a file belongs, a binary file where a JSON one belongs. Each is one line on stderr that
names the file or flag and says what is wrong, exit 2, nothing on stdout, never a raw OS message."""

from __future__ import annotations

import pytest

from ringtune.agents.cli.main import main
from ringtune.shaping.config import TuneConfig


def _one_line_error(argv, capsys) -> str:
    assert main(argv) == 2
    cap = capsys.readouterr()
    assert cap.out == ""
    last = cap.err.strip().splitlines()[-1]
    assert "Errno" not in last and "codec" not in last, last
    return last


@pytest.fixture
def best(tmp_path):
    path = tmp_path / "best.json"
    TuneConfig(firmware="klipper", shaper_x="mzv", shaper_y="mzv", freq_x=45.0, freq_y=40.0,
               accel=4000.0).save(path)
    return path


@pytest.mark.parametrize("argv, flag", [
    (["export", "{best}", "--firmware", "klipper", "-o", "{dir}"], "-o"),
    (["testprint", "ringing", "--firmware", "marlin", "-o", "{dir}"], "-o"),
    (["testprint", "accel", "--firmware", "klipper", "--config", "{best}", "-o", "{dir}"], "-o"),
    (["identify", "--ripples", "X=2,Y=2.5", "--speed", "100", "-o", "{dir}"], "-o"),
])
def test_an_output_that_is_a_folder_is_refused(argv, flag, best, tmp_path, capsys):
    argv = [a.format(best=best, dir=tmp_path) for a in argv]
    last = _one_line_error(argv, capsys)
    assert f"{flag} {tmp_path}: is a directory" in last, last


@pytest.mark.parametrize("argv", [
    ["export", "{cfg}", "--firmware", "klipper"],
    ["push", "{cfg}", "--firmware", "klipper", "--dry-run"],
    ["testprint", "accel", "--firmware", "klipper", "--config", "{cfg}"],
])
def test_a_config_that_is_a_folder_or_binary_is_named(argv, tmp_path, capsys):
    binary = tmp_path / "best.bin"
    binary.write_bytes(bytes(range(256)) * 4)
    for cfg, words in ((tmp_path, "is a directory"), (binary, "not a text file")):
        last = _one_line_error([a.format(cfg=cfg) for a in argv], capsys)
        assert f"{cfg}: {words}" in last, last


@pytest.mark.parametrize("argv", [
    ["testprint", "ringing", "--firmware", "marlin", "--printer", "{p}"],
    ["motor", "ldo-42sth40-1684ac"],                      # control: no printer, must pass
])
def test_a_binary_printer_description_is_named(argv, tmp_path, capsys):
    binary = tmp_path / "printer.toml"
    binary.write_bytes(bytes(range(256)) * 4)
    if "{p}" not in argv:
        assert main(argv) == 0
        capsys.readouterr()
        return
    last = _one_line_error([a.format(p=binary) for a in argv], capsys)
    assert f"{binary}: not a text file" in last, last


def _raw_read(args, out):
    """A command body that trips over a raw OS/codec error (what the CLI must still say in one line)."""
    with open(args.config, encoding="utf-8") as fh:
        return len(fh.read())


def test_raw_folder_and_decoding_errors_reaching_the_cli_name_the_file(
        tmp_path, capsys, monkeypatch):
    """IsADirectoryError / UnicodeDecodeError escaping a command printed '[Errno 21] ...' or
    "'utf-8' codec can't decode byte ..." with no file named."""
    import ringtune.agents.cli.export as export

    monkeypatch.setattr(export, "run", _raw_read)
    last = _one_line_error(["export", str(tmp_path), "--firmware", "klipper"], capsys)
    assert last == f"ringtune export: error: {tmp_path}: is a directory, not a file", last
    binary = tmp_path / "best.json"
    binary.write_bytes(b'{"a": "\xff\xfe"}')
    last = _one_line_error(["export", str(binary), "--firmware", "klipper"], capsys)
    assert last.startswith(f"ringtune export: error: {binary}: not a text file"), last


def test_a_permission_error_names_the_file(tmp_path, capsys, monkeypatch):
    import ringtune.agents.cli.export as export

    locked = tmp_path / "locked.json"

    def run(args, out):
        raise PermissionError(13, "Permission denied", str(locked))   # tests may run as root

    monkeypatch.setattr(export, "run", run)
    last = _one_line_error(["export", str(locked), "--firmware", "klipper"], capsys)
    assert last == f"ringtune export: error: {locked}: permission denied", last
