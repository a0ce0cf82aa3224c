"""The ``ringtune`` command line: one entry point, one module per subcommand.

Conventions every subcommand follows:

- ``--json`` prints one JSON object with stable keys on stdout and nothing else there (progress
  bars and notes go to stderr);
- bad input is one line on stderr, ``ringtune <command>: error: <what and where>``, exit status 2;
  never a traceback (``RINGTUNE_DEBUG=1`` shows it for developers);
- Ctrl-C exits with status 130 after saying what was kept.
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import sys
import time
from dataclasses import dataclass, field
from types import ModuleType
from typing import Any

from ringtune.agents import __version__
from ringtune.shaping.errors import RingtuneError

#: every command and its one-line help, in the order ``ringtune --help`` lists them (the main job
#: first, then the tools). The command ``NAME`` lives in ``ringtune.agents.cli.NAME``; only the
#: command being run is imported (the rest of the library loads with it), so ``ringtune --help``
#: lists them from here alone.
COMMANDS = {
    "tune": "find the best print-time / quality trade-offs (Optuna Pareto study) — the main job",
    "recommend": "instant shaper config from a resonance test (Klipper's calibrate_shaper rule)",
    "simulate": "simulate a configuration on a job: print time and what a person sees, against Klipper's pick",
    "study": "trade-off study: sweep one factor and plot each shaper's print time and quality",
    "train": "train a PPO policy that recommends a configuration from a resonance test (random printers)",
    "shaper": "impulses, duration, lag, 90 % band and smoothing of one input shaper",
    "response": "residual vibration vs frequency for several shapers (Klipper-style graph)",
    "graph": "Klipper-style graphs: shapers over the spectrum, CoreXY belts, vibration against speed (PNG + --json)",
    "plan": "plan a G-code job: print time, moves, time by feature, highest direction-change frequencies",
    "schedule": "bed slingers: the Y shaper frequency by layer as the print's mass grows, inserted into the job",
    "limit": "slow only the zigzags that shake: rewrite F words so direction changes stay under a frequency",
    "rewrite": "write a tuned configuration into a sliced job: acceleration per feature, corner rule, frequency limit",
    "identify": "the printer from your files: modes from accelerometer data, the rest from your config (TOML)",
    "testprint": "calibration prints: ringing tower (ripples / shaper bands) and acceleration ladder",
    "printer": "the printer description (TOML) from its firmware configuration: Klipper, Moonraker, "
               "Marlin M503, RRF config.g",
    "motor": "a stepper's force at the belt against speed, from its datasheet constants",
    "export": "write a tuning config in a firmware's own dialect (M593, M493, SET_INPUT_SHAPER, ...)",
    "push": "send a tuning config to the printer, read it back and report what was applied",
}

EXAMPLES = """\
examples:
  ringtune tune                                  tune the built-in Ender-3-class printer (main job)
  ringtune identify resonances_x.csv resonances_y.csv --klipper-config printer.cfg -o my.toml
  ringtune tune --printer my.toml --gcode job.gcode
                                                 your printer (modes from its resonance test) on your own
                                                 sliced job: writes it back with the choice in
                                                 (ringtune-out/job.gcode)
  ringtune shaper mzv --freq 40 --damping 0.1    impulses, duration, lag and band of a shaper
  ringtune response zv mzv ei --freq 40 --plot r.png
  ringtune plan job.gcode --json                 print time and move statistics
  ringtune limit job.gcode --freq-limit 20 -o out.gcode
  ringtune recommend --accel resonances_x.csv resonances_y.csv --method klipper
  ringtune export best.json --firmware klipper

every command takes --help and --json.
"""


#: notes are held this long (s) after a command starts: one that fails in that time prints its error
#: line alone; after it they go out as they come. Long commands (tune, train, push) release them
#: once their input is checked, so their progress is live.
NOTE_HOLD_S = 10.0


@dataclass
class Output:
    """Where a command's result goes: JSON on stdout, or readable text. Notes (stderr) are held
    until the result, or until the command has run :data:`NOTE_HOLD_S`; a command that fails
    before then drops them, so bad input gets its one error line and nothing before it."""

    json: bool = False
    stream: Any = field(default_factory=lambda: sys.stdout)
    held: list[str] = field(default_factory=list)
    started: float = field(default_factory=time.monotonic)

    def emit(self, result: dict, text: str | None = None) -> None:
        """Print ``result`` as JSON (``--json``) or ``text`` (else a readable rendering of result)."""
        self.release()
        if self.json:
            json.dump(_jsonable(result), self.stream, indent=2, sort_keys=False)
            self.stream.write("\n")
        else:
            self.stream.write((text if text is not None else _render(result)).rstrip("\n") + "\n")

    def note(self, *messages: str, kind: str = "") -> None:
        """Remarks for the person at the terminal, one line each (stderr, so ``--json`` output stays
        clean); ``kind`` (``"note"``, ``"warning"``) leads each as ``kind: message``."""
        self.held += [f"{kind}: {m}" for m in messages] if kind else messages
        if time.monotonic() - self.started > NOTE_HOLD_S:
            self.release()

    def release(self) -> None:
        """Print the held notes (from now on every note goes out as it comes)."""
        for message in self.held:
            print(message, file=sys.stderr)
        self.held.clear()
        self.started = -float("inf")


def _jsonable(obj: Any) -> Any:
    """``obj`` with numpy arrays and scalars as lists and numbers (their ``tolist``), NaN as null and
    paths as strings."""
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if callable(getattr(obj, "tolist", None)):      # numpy array or scalar
        return _jsonable(obj.tolist())
    if isinstance(obj, float) and obj != obj:  # NaN is not JSON
        return None
    if hasattr(obj, "__fspath__"):
        return os.fspath(obj)
    return obj


def _render(result: dict, indent: int = 0) -> str:
    lines = []
    pad = " " * indent
    for key, value in result.items():
        if isinstance(value, dict):
            lines.append(f"{pad}{key}:")
            lines.append(_render(value, indent + 2))
        elif isinstance(value, float):
            lines.append(f"{pad}{key}: {value:.6g}")
        else:
            lines.append(f"{pad}{key}: {value}")
    return "\n".join(lines)


class _Parser(argparse.ArgumentParser):
    """argparse with the convention above: a usage error is one line on stderr, exit status 2
    (argparse's own would print the whole usage block first)."""

    def error(self, message: str):  # noqa: D401 - argparse's hook
        # "argument --freq: must be …" reads as every other error: "--freq: must be …"
        message = message.removeprefix("argument ")
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


#: library parameter -> the option that carries it, where the two names differ on every command
#: that has the option (a command module's ``PARAMETER_FLAGS`` adds its own)
PARAMETER_OPTIONS = {"study_name": "study", "n_envs": "envs"}
#: command -> {library parameter: --flag}, filled by :func:`build_parser`
_FLAGS: dict[str, dict[str, str]] = {}


def _parameter_flags(parser: argparse.ArgumentParser, module: Any) -> dict[str, str]:
    """{parameter: --flag} for one command: each option's destination (``min_speed_factor`` ->
    ``--min-speed-factor``), :data:`PARAMETER_OPTIONS`, and the module's ``PARAMETER_FLAGS``."""
    flags = {}
    for action in parser._actions:
        long = [o for o in action.option_strings if o.startswith("--")]
        if long:
            flags[action.dest] = long[0]
    for param, dest in PARAMETER_OPTIONS.items():
        if dest in flags:
            flags.setdefault(param, flags[dest])
    flags.update(getattr(module, "PARAMETER_FLAGS", {}))
    return flags


def as_flag(exc: RingtuneError, command: str) -> RingtuneError:
    """A library error naming a parameter (``where="method"``) as the command's flag (``--method``):
    the library speaks of its parameters, the user of the options they typed."""
    if command not in _FLAGS:
        build_parser(command)
    flag = _FLAGS[command].get(exc.where or "")
    return RingtuneError(exc.bare, flag) if flag else exc


def build_parser(command: str | None = None) -> tuple[argparse.ArgumentParser, ModuleType | None]:
    """The ``ringtune`` parser listing every command of :data:`COMMANDS`, and the module of
    ``command``: only that one is imported and only its options are added (``None``: no command
    module, as ``ringtune --help`` needs)."""
    parser = _Parser(
        prog="ringtune",
        description="Measured input-shaping tuning for 3D printers: firmware-faithful shapers and "
        "planners drive a MuJoCo printer; Optuna and PPO trade print time against what a person sees on "
        "the part; the result goes out in the printer's own firmware dialect.",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"ringtune {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    module = None
    for name, one_line in COMMANDS.items():
        # argparse %-formats help strings (not descriptions): the texts are plain prose
        p = sub.add_parser(name, help=one_line.replace("%", "%%"), description=one_line,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        if name == command:
            module = importlib.import_module(f"ringtune.agents.cli.{name}")
            p.description = getattr(module, "DESCRIPTION", one_line)
            p.add_argument("--json", action="store_true", help="print one JSON object with stable keys")
            module.add_arguments(p)
            _FLAGS[name] = _parameter_flags(p, module)
    return parser, module


def command_named(argv: list[str]) -> str | None:
    """The command ``argv`` runs (its first word that is not an option), if it is one of
    :data:`COMMANDS`."""
    word = next((a for a in argv if not a.startswith("-")), None)
    return word if word in COMMANDS else None


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    parser, module = build_parser(command_named(argv))
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:        # a usage error (argparse said it in one line): its status
        if exc.code:
            return exc.code
        raise                        # --help, --version
    if not args.command:
        parser.print_help()
        return 0
    out = Output(json=args.json)
    try:
        rc = int(module.run(args, out) or 0)
        out.release()
        sys.stdout.flush()          # a closed pipe shows here, not in the interpreter's last flush
        return rc
    except BrokenPipeError:
        # the reader went away (``ringtune plan f.gcode --json | head``): stop quietly, as cat does;
        # stdout is pointed at devnull so that the interpreter's final flush does not complain
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except (OSError, ValueError) as exc:      # RingtuneError is a ValueError
        return _fail(args.command, _message(exc, args))
    except KeyboardInterrupt:
        print(f"ringtune {args.command}: interrupted", file=sys.stderr)
        return 130


def _message(exc: Exception, args) -> str:
    """The one line a failure prints: what and where, in the words of the options the user typed."""
    if isinstance(exc, RingtuneError):
        return str(as_flag(exc, args.command))
    if isinstance(exc, FileNotFoundError):
        return f"{exc.filename}: no such file"
    if isinstance(exc, (IsADirectoryError, NotADirectoryError, PermissionError)):
        return _os_error(exc)
    if isinstance(exc, UnicodeDecodeError):
        return (f"{_undecodable(args)}: not a text file (binary data, or text not in "
                f"UTF-8: byte {exc.object[exc.start:exc.start + 1]!r} at offset {exc.start})")
    return str(exc) or type(exc).__name__


def _os_error(exc: OSError) -> str:
    """``<file>: is a directory`` from an OSError's own file name and words (no ``[Errno 21]``)."""
    words = (exc.strerror or type(exc).__name__).lower()
    if isinstance(exc, IsADirectoryError):
        words += ", not a file"
    name = exc.filename if exc.filename is not None else "a file"
    return f"{name}: {words}"


def _undecodable(args) -> str:
    """The file among the command's arguments that is not UTF-8 text (a UnicodeDecodeError names
    no file), else a phrase that says it was one of them."""
    values = []
    for value in vars(args).values():
        values.extend(value if isinstance(value, (list, tuple)) else [value])
    for value in values:
        if isinstance(value, (str, os.PathLike)) and os.path.isfile(value):
            try:
                with open(value, "rb") as fh:
                    fh.read().decode("utf-8")
            except UnicodeDecodeError:
                return os.fspath(value)
            except OSError:
                continue
    return "one of the files given"


def _fail(command: str, message: str) -> int:
    if os.environ.get("RINGTUNE_DEBUG"):
        raise
    print(f"ringtune {command}: error: {message}", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main())
