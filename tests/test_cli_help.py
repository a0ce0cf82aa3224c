"""Every listed subcommand exists, teaches with --help, and fails bad input in one line."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from ringtune.agents.cli import main as cli


def test_every_listed_command_is_implemented():
    """Each name of the registry is a module ``cli/NAME.py`` with the command contract, and every
    command module of the folder is listed."""
    folder = Path(__file__).resolve().parent.parent / "agents" / "cli"
    helpers = {"__init__", "main", "common", "options", "identify_ripples", "trace_option", "simulate_config"}
    assert {p.stem for p in folder.glob("*.py")} - helpers == set(cli.COMMANDS)
    for name in cli.COMMANDS:
        _, module = cli.build_parser(name)
        assert module.__name__ == f"ringtune.agents.cli.{name}" and module.NAME == name
        assert callable(module.add_arguments) and callable(module.run)
        assert not hasattr(module, "HELP"), f"{name}: the one-line help lives in main.COMMANDS only"


def _imported_after(argv: list[str], *, block: tuple[str, ...] = ()) -> tuple[int, set[str], str]:
    """(exit status, the ringtune and heavy modules loaded, stderr) of ``ringtune argv`` in a fresh
    interpreter; ``block``: modules made unimportable (as on a core install without them)."""
    code = ("import sys, json\n"
            "class Absent:\n"
            "    def find_spec(self, name, path=None, target=None):\n"
            f"        if name.split('.')[0] in {list(block)!r}:\n"
            "            raise ModuleNotFoundError(f'No module named {name!r}', name=name)\n"
            "sys.meta_path.insert(0, Absent())\n"
            "from ringtune.agents.cli.main import main\n"
            "try:\n    rc = main(sys.argv[1:])\nexcept SystemExit as e:\n    rc = e.code\n"
            "names = [m for m in sys.modules if m.startswith(('ringtune.', 'torch', 'stable_baselines3',"
            " 'optuna', 'mujoco', 'matplotlib', 'scipy'))]\n"
            "print(json.dumps(names), file=sys.stderr)\n"
            "sys.exit(rc)\n")
    proc = subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, text=True)
    *err, names = proc.stderr.strip().splitlines()
    return proc.returncode, set(json.loads(names)), "\n".join(err)


def test_top_level_help_imports_no_command_and_a_command_help_only_its_own():
    """``ringtune --help`` lists the commands from the registry alone; ``ringtune tune --help``
    imports the tune command and no other command module."""
    rc, names, _ = _imported_after(["--help"])
    assert rc == 0
    assert not {n for n in names if n.startswith("ringtune.agents.cli.")} - {
        "ringtune.agents.cli.main"}, names
    assert not {n for n in names if n.split(".")[0] in ("optuna", "mujoco", "matplotlib", "torch")}
    rc, names, _ = _imported_after(["tune", "--help"])
    commands = {n.split(".")[-1] for n in names if n.startswith("ringtune.agents.cli.")}
    assert rc == 0 and commands & set(cli.COMMANDS) == {"tune"}, commands


@pytest.mark.slow
def test_without_the_rl_extra_every_command_starts_and_policy_says_so_in_one_line(tmp_path):
    """A core install (no torch, no stable-baselines3): every command's help works, Klipper's rule
    runs, and ``recommend --method policy`` is one line naming the extra, exit 2."""
    block = ("torch", "stable_baselines3")
    for name in ("recommend", "train"):       # the commands that reach agents/ppo (the rest: the graph)
        rc, names, err = _imported_after([name, "--help"], block=block)
        assert rc == 0 and "ringtune.agents.ppo.policy" in names, (name, err)
    rc, names, err = _imported_after(["recommend", "--printer", "default", "--method", "policy",
                                      "--policy", str(tmp_path)], block=block)
    assert rc == 2 and err.count("\n") == 0, err
    assert err.startswith("ringtune recommend: error:") and "pip install 'ringtune[rl]'" in err, err


def test_top_level_help_lists_every_command(capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(["--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    for name in cli.COMMANDS:
        assert f"    {name}" in out


@pytest.mark.parametrize("name", cli.COMMANDS)
def test_each_command_help_has_an_example_and_json(name, capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main([name, "--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    assert "--json" in out
    assert "ringtune " + name in out  # usage line, and the examples name the command
    assert "%%" not in out


def test_bad_value_is_one_line_and_exit_2_without_traceback():
    proc = subprocess.run([sys.executable, "-m", "ringtune.agents.cli.main", "shaper", "mzv", "--freq", "-3"],
                          capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and proc.stderr.startswith("ringtune shaper: error:")
    assert "Traceback" not in proc.stderr


@pytest.mark.parametrize("argv,what", [
    (["tune", "--trials", "abc"], "--trials"),                                   # argparse type error
    (["tune", "--trials", "0"], "--trials"),
    (["tune", "--storage", "bogus", "--no-baselines"], "--storage"),             # not a storage URL
    (["tune", "--storage", "postgresql+psycopg2://u:p@127.0.0.1:1/db", "--no-baselines"], "--storage"),
    (["tune", "--gcode", "/nonexistent/job.gcode"], "--gcode /nonexistent/job.gcode: no such G-code file"),
    (["recommend", "--accel", "/nonexistent/resonances_x.csv"], "no such file"),
    (["recommend", "--method", "klipper"], "--accel"),                           # required group missing
    (["recommend", "--printer", "default", "--klipper-version", "0.9"], "--klipper-version"),
    (["study", "--factor", "bogus"], "--factor"),
    (["train", "--timesteps", "x"], "--timesteps"),
])
def test_bad_input_of_tune_recommend_study_train_is_one_line_exit_2(argv, what, tmp_path, capsys):
    """Usage errors (argparse's) and value errors (RingtuneError) alike: one stderr line naming the
    option, status 2, no traceback, nothing on stdout."""
    if argv[0] == "tune":
        argv = argv + ["--out", str(tmp_path / "out")]
    try:
        rc = cli.main(argv)
    except SystemExit as exc:
        rc = exc.code
    cap = capsys.readouterr()
    assert rc == 2, cap.err
    lines = cap.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"ringtune {argv[0]}: error:") and what in lines[0], lines
    assert "Traceback" not in cap.err and cap.out == ""


def test_a_reader_that_goes_away_ends_the_command_quietly(tmp_path):
    """``ringtune … --json | head``: no 'Broken pipe' error line and no traceback, status 141
    (SIGPIPE's, as a shell reports for cat)."""
    job = tmp_path / "job.gcode"
    job.write_text("G28\n" + "".join(f"G1 X{i % 50} Y{i % 37} E{i * 0.01:.2f} F3000\n" for i in range(400)))
    proc = subprocess.Popen([sys.executable, "-m", "ringtune.agents.cli.main", "plan", str(job), "--json"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()            # the reader leaves before the command has written anything
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 141
    assert "Broken pipe" not in err and "Traceback" not in err


def test_export_refusal_names_the_config_file(tmp_path, capsys):
    cfg = tmp_path / "best.json"
    cfg.write_text('{"firmware": "klipper", "shaper_x": "mzv", "shaper_y": "ei2", "freq_x": 50, "freq_y": 40}')
    assert cli.main(["export", str(cfg), "--firmware", "rrf"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"error: {cfg}: RepRapFirmware 3.6 applies one shaper to all axes" in err[0]
    cfg.write_text('{"firmware": "klipper", "shaper_x": "ei", "shaper_y": "ei", "freq_x": 50, "freq_y": 40}')
    assert cli.main(["export", str(cfg), "--firmware", "rrf"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"error: {cfg}: shaper_x: RepRapFirmware 3.6 has no 'ei' shaper" in err[0]


def test_a_misspelt_config_key_is_warned_about_not_silently_defaulted(tmp_path, capsys):
    from ringtune.shaping.config import TuneConfig

    cfg = tmp_path / "c.json"
    cfg.write_text('{"firmware": "klipper", "shaper_x": "mzv", "shaper_y": "mzv", "freq_x": 50, "freqq_y": 40,'
                   ' "dampnig_x": 0.1, "source": "ringtune tune", "metrics": {}, "chosen_by": "knee",'
                   ' "printer": "ender3-class", "job": "built-in test print"}')
    assert sorted(TuneConfig.load(cfg).likely_typos()) == [
        "unknown key 'dampnig_x' kept as an extra key; did you mean 'damping_x'?",
        "unknown key 'freqq_y' kept as an extra key; did you mean 'freq_y'?"]
    assert cli.main(["export", str(cfg), "--firmware", "klipper"]) == 0
    err = capsys.readouterr().err
    assert f"{cfg}: warning: unknown key 'freqq_y'" in err and "'source'" not in err and "'printer'" not in err


# -- library errors name the parameter; the command names the flag ----------------------------------

def test_library_errors_name_their_parameter_and_the_command_the_flag(tmp_path, capsys):
    from ringtune.shaping.errors import RingtuneError
    from ringtune.shaping.freqlimit import apply_freq_limit
    from ringtune.shaping.testprints import builtin_test_print

    with pytest.raises(RingtuneError) as info:
        apply_freq_limit(builtin_test_print(), -1.0, "sections")
    assert info.value.where == "limit_hz"                                # the library's word
    assert cli.as_flag(info.value, "limit").where == "--freq-limit"           # the option of `limit`
    assert cli.as_flag(RingtuneError("x", "method"), "limit").where == "--method"
    assert cli.as_flag(RingtuneError("x", "study_name"), "tune").where == "--study"
    assert cli.as_flag(RingtuneError("x", "config: freq_x"), "simulate").where == "config: freq_x"
    # through the command line: one line naming the flag the user typed
    assert cli.main(["tune", "--workers", "0", "--trials", "1", "--out", str(tmp_path / "o")]) == 2
    assert capsys.readouterr().err.strip() == "ringtune tune: error: --workers: must be ≥ 1"


def test_every_command_that_writes_a_file_or_folder_takes_dash_o():
    """Where a command has an output option (``--output``, ``--out``), ``-o`` is its short form, so
    ``ringtune identify … -o my.toml`` and ``ringtune tune … -o out`` read alike."""
    with_output = []
    for name in cli.COMMANDS:
        parser, _ = cli.build_parser(name)
        sub = next(a for a in parser._actions if a.dest == "command").choices[name]
        outs = [a for a in sub._actions if {"--output", "--out"} & set(a.option_strings)]
        for action in outs:
            assert "-o" in action.option_strings, f"{name}: {action.option_strings} has no -o"
        with_output += [name] * bool(outs)
    assert {"tune", "identify", "rewrite", "export"} <= set(with_output)
