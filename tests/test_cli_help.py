"""Every listed subcommand exists, teaches with --help, and fails bad input in one line."""

from __future__ import annotations

import subprocess
import sys

import pytest

from ringtune.agents import cli


def test_every_listed_command_is_implemented():
    _, modules = cli.build_parser()
    assert sorted(modules) == sorted(cli.COMMAND_MODULES)


def test_top_level_help_lists_every_command(capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(["--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    for name in cli.COMMAND_MODULES:
        assert f"    {name}" in out


@pytest.mark.parametrize("name", cli.COMMAND_MODULES)
def test_each_command_help_has_an_example_and_json(name, capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main([name, "--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    assert "--json" in out
    assert "ringtune " + name in out  # usage line, and the examples name the command
    assert "%%" not in out


def test_bad_value_is_one_line_and_exit_2_without_traceback():
    proc = subprocess.run([sys.executable, "-m", "ringtune.agents.cli", "shaper", "mzv", "--freq", "-3"],
                          capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and proc.stderr.startswith("ringtune shaper: error:")
    assert "Traceback" not in proc.stderr
