"""``ringtune printer``: a printer description (TOML) from the printer's own firmware configuration.

Subcommands: ``from-klipper printer.cfg`` (or ``--moonraker URL``), ``from-marlin M503.txt``,
``from-rrf config.g``. The readers are :mod:`ringtune.hardware.klipper_config`,
:mod:`ringtune.hardware.marlin_config` and :mod:`ringtune.hardware.rrf_config`.

JSON keys (stable): ``source`` (file or URL read), ``firmware`` (klipper | marlin | rrf),
``description`` (what the configuration gives, in printer-description form, without the default
modes), ``notes`` (list of what could not be known, was mapped or is a default), ``toml`` (the text
written), ``output`` (path written, or null).
"""

from __future__ import annotations

import argparse
import os
import tomllib
from importlib import resources
from pathlib import Path
from urllib.parse import urlsplit

from ringtune.agents.cli.common import check_output_folder
from ringtune.envs.motors import lookup_motor
from ringtune.envs.printer import printer_from_dict
from ringtune.envs.printer_defaults import DEFAULTS
from ringtune.envs.toml_writer import toml_value
from ringtune.hardware.firmware_facts import MOTOR_CONSTANTS, motor_tables, without_motor
from ringtune.hardware.klipper_config import printer_facts_from_klipper, printer_facts_from_moonraker
from ringtune.hardware.marlin_config import printer_facts_from_marlin
from ringtune.hardware.rrf_config import printer_facts_from_rrf
from ringtune.shaping.errors import RingtuneError

NAME = "printer"
DESCRIPTION = """\
Write a printer description from what the printer's firmware already knows: kinematics, limits,
each motor's drive (rotation_distance, microsteps, run current, supply voltage, named motor or its
constants) and the input shaper it runs today (kept in [current] as a baseline for tune). Modes
come from a measurement: the description gets default modes, marked as such, until `ringtune
identify` replaces them. Everything the configuration does not say is printed on stderr and
written as a comment.

  from-klipper printer.cfg   Klipper's configuration with its [include]s and SAVE_CONFIG block
  from-klipper --moonraker URL
                             the same, read from a running printer (the values as Klipper parsed them)
  from-marlin M503.txt       the answer of M503 (M92, M201, M203, M204, M205, M906, M593)
  from-rrf config.g          RepRapFirmware (M669, M92, M201, M203, M204, M566, M906, M593)

examples:
  ringtune printer from-klipper ~/printer_data/config/printer.cfg -o myprinter.toml
  ringtune printer from-klipper --moonraker http://voron.local:7125 -o voron.toml
  ringtune printer from-marlin m503.txt --kinematics cartesian -o ender.toml
  ringtune printer from-rrf sys/config.g --json
"""

FIRMWARES = {"from-klipper": "klipper", "from-marlin": "marlin", "from-rrf": "rrf"}


def add_arguments(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="source", metavar="SOURCE", required=True)
    specs = {
        "from-klipper": ("printer.cfg", "Klipper's printer.cfg (its includes are read too)",
                         "ringtune printer from-klipper printer.cfg -o myprinter.toml\n"
                         "  ringtune printer from-klipper --moonraker http://voron.local:7125 --json"),
        "from-marlin": ("M503.txt", "the printer's answer to M503, saved as text",
                        "ringtune printer from-marlin m503.txt --kinematics cartesian -o ender.toml"),
        "from-rrf": ("config.g", "RepRapFirmware's config.g",
                     "ringtune printer from-rrf sys/config.g -o duet.toml"),
    }
    for name, (metavar, what, example) in specs.items():
        s = sub.add_parser(name, help=what, description=f"ringtune printer {name}: {what}.\n\n"
                           f"example:\n  {example}", formatter_class=argparse.RawDescriptionHelpFormatter)
        s.add_argument("file", metavar=metavar, nargs="?" if name == "from-klipper" else None, help=what)
        if name == "from-klipper":
            s.add_argument("--moonraker", metavar="URL", help="read a running printer through Moonraker "
                           "instead of a file (http://host:7125)")
            s.add_argument("--api-key", metavar="KEY", help="Moonraker API key (default $MOONRAKER_API_KEY)")
        if name == "from-marlin":
            s.add_argument("--kinematics", choices=("cartesian", "corexy", "corexz"),
                           help="M503 does not say it (default: not written; the loader's cartesian)")
        s.add_argument("-o", "--output", metavar="printer.toml", help="write the description here "
                       "(default: print it)")
        s.add_argument("--name", help="printer name in the TOML (default: from the file or host)")
        s.add_argument("--json", action="store_true", default=argparse.SUPPRESS,
                       help="print one JSON object with stable keys")


# -- the built-in motor table (ringtune.envs.motors.lookup_motor) -----------------------------------
def check_motor_names(description: dict, notes: list[str], comments: dict[str, list[str]]) -> None:
    """Keep a motor ``name`` when the built-in table knows it or the configuration gives its
    constants; else drop it, say so, and leave a comment where its constants belong."""
    for where, table in motor_tables(description).items():
        name = table.get("name")
        if name is None:
            continue
        known = lookup_motor(name)
        inline = all(k in table for k in MOTOR_CONSTANTS)
        if known is not None:
            if inline:
                notes.append(f"[{where}] {name}: the configuration's own [motor_constants] are written; they "
                             "take precedence over the built-in table's entry of that name")
            continue
        if inline:                       # the loader takes an unknown name that comes with its constants
            notes.append(f"[{where}] motor {name} is not in the built-in table; its constants come from "
                         "the configuration's [motor_constants]")
        else:
            del table["name"]
            without_motor(table, notes, f"[{where}]")
            comments.setdefault(where, []).append(f"motor {name}: not in the built-in table; give holding_torque, "
                                                  "rated_current, resistance, inductance here")
            notes.append(f"[{where}] motor {name} is not in the built-in table and the configuration gives no "
                         "constants: the motor's force stays the default until you give them")


# -- TOML ---------------------------------------------------------------------------------------
_KEY_COMMENTS = {
    "accel": "mm/s²", "travel_accel": "mm/s²", "retract_accel": "mm/s² (E-only moves)", "velocity": "mm/s",
    "square_corner_velocity": "mm/s",
    "junction_deviation": "mm", "max_accel": "mm/s² per axis x, y, z, e (0 = no cap)",
    "max_velocity": "mm/s per axis x, y, z, e (0 = no cap)", "jerk": "mm/s per axis x, y, z, e",
    "rotation_distance": "mm of belt per motor revolution", "run_current": "A RMS", "voltage": "V",
    "resistance": "Ω per phase", "inductance": "H per phase", "holding_torque": "N·m",
    "rated_current": "A (datasheet)", "steps_per_revolution": "full steps", "steps_per_mm": "microsteps per mm",
    "freq_x": "Hz", "freq_y": "Hz",
}


#: the comment a table always carries
_TABLE_COMMENTS = {"current": ["what the printer runs today (firmware configuration): a baseline for tune"]}


def _table(lines: list[str], name: str, table: dict, comments: list[str] = ()) -> None:
    lines.append("")
    lines.extend(f"# {c}" for c in comments)
    lines.append(f"[{name}]")
    for k, v in table.items():
        unit = _KEY_COMMENTS.get(k)
        text = f"{k} = {toml_value(v)}"
        lines.append(f"{text:<34} # {unit}" if unit else text)


def description_toml(name: str, description: dict, notes: list[str], source: str, command: str,
                     comments: dict[str, list[str]]) -> str:
    """The TOML text: what the configuration gives, default modes marked as defaults, notes as
    comments."""
    # the embedded default printer, read from the package itself (load_printer(None) looks for a
    # path "ender3" first, and a folder of that name in the working directory shadows it)
    embedded = resources.files("ringtune.envs.data") / "ender3.toml"
    default = printer_from_dict(tomllib.loads(embedded.read_text()), "<embedded ender3.toml>").to_dict()
    lines = [f"# Printer description from {source} (ringtune printer {command}).",
             "# What the configuration does not say, and what was mapped:"]
    lines += [f"#   - {n}" for n in notes] or ["#   (nothing)"]
    lines += [f"name = {toml_value(name)}"]
    if "kinematics" in description:
        lines.append(f"kinematics = {toml_value(description['kinematics'])}")
    for key in ("limits", "current", "motor"):
        if description.get(key):
            _table(lines, key, description[key], _TABLE_COMMENTS.get(key, []) + comments.get(key, []))
    for ax in ("x", "y"):
        lines.append("")
        lines.append(f"# default modes (the embedded {default['name']} printer's), not this printer's: "
                     f"`ringtune identify` replaces them; mass: the default {DEFAULTS[f'mass_{ax}']:g} kg")
        lines.append(f"[{ax}]")
        lines.append(f"modes = {toml_value(default[ax]['modes'])}")
        motor = description.get(ax, {}).get("motor")
        if motor:
            _table(lines, f"{ax}.motor", motor, comments.get(f"{ax}.motor", []))
    lines += ["", f"# nothing measured yet: the modes above are the embedded {default['name']} printer's; tune, "
              "recommend and simulate say so while this reads \"none\"", "[measurement]", 'source = "none"']
    return "\n".join(lines) + "\n"


# -- the command --------------------------------------------------------------------------------
#: source -> how its file is read (from-klipper's --moonraker: :func:`_read`)
_READERS = {"from-klipper": lambda args: printer_facts_from_klipper(args.file),
            "from-marlin": lambda args: printer_facts_from_marlin(args.file, args.kinematics),
            "from-rrf": lambda args: printer_facts_from_rrf(args.file)}


def _read(args):
    """(FirmwareFacts, the printer's name when --name gives none): from the file, or from Moonraker."""
    if args.source == "from-klipper" and (args.file is None) == (args.moonraker is None):
        raise RingtuneError("give printer.cfg or --moonraker URL (one of them)", "from-klipper")
    if getattr(args, "moonraker", None):
        facts = printer_facts_from_moonraker(args.moonraker,
                                             api_key=args.api_key or os.environ.get("MOONRAKER_API_KEY"))
        return facts, urlsplit(args.moonraker).hostname or "printer"
    facts = _READERS[args.source](args)
    p = Path(args.file)
    default_name = p.resolve().parent.name if p.stem in ("printer", "config", "M503", "m503") else p.stem
    return facts, default_name or "printer"


def run(args, out) -> int:
    check_output_folder("--output", args.output)
    facts, default_name = _read(args)
    description = facts.description
    notes = list(facts.notes)
    comments: dict[str, list[str]] = {}
    check_motor_names(description, notes, comments)
    notes += _unnamed_motor(description)
    notes.append("modes are defaults until `ringtune identify` measures them; masses are defaults")
    text = description_toml(args.name or default_name, description, notes, facts.source, args.source, comments)
    if args.output:
        Path(args.output).write_text(text)
    for n in notes:
        out.note(n if ": warning: " in n else f"note: {n}")
    plural = "s" if len(notes) != 1 else ""
    out.emit({"source": facts.source, "firmware": FIRMWARES[args.source], "description": description,
              "notes": notes, "toml": text, "output": args.output},
             f"{facts.source} -> {args.output} ({len(notes)} note{plural} above)" if args.output else text)
    return 0


def _unnamed_motor(description: dict) -> list[str]:
    """The note a description without a named or described motor needs (the default motor's force
    is used), else none."""
    tables = motor_tables(description).values()
    if any("name" in t or all(k in t for k in MOTOR_CONSTANTS) for t in tables):
        return []
    drive = sorted({k for t in tables for k in ("run_current", "voltage") if k in t})
    unused = (f"; {' and '.join(drive)} {'are kept but count' if len(drive) > 1 else 'is kept but counts'} "
              "only once the motor is named") if drive else ""
    return [f"no motor named or described: the force at the belt is the default motor's "
            f"({DEFAULTS['motor_force']:g} N, falling above {DEFAULTS['corner_speed']:g} mm/s){unused}; "
            "name the motor ([motor] name = …) or give its constants"]
