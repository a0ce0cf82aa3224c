"""``ringtune push``: apply a TuneConfig on a printer over serial or Moonraker, and verify it.

``--json`` keys (stable):
    firmware, port (secrets redacted), dry_run (bool), ok (bool: every setting applied),
    wire: lines sent / that would be sent (dry run: exactly, numbered and checksummed),
    settings: {key: {meant, reported, status ("applied" | "not applied" |
        "acknowledged (no read-back)" | "not sent (dry run)"), detail}},
    resets: printer resets seen during the push, saved: how it was persisted or null,
    save_file: config file written (RRF, Klipper) or null, notes: remarks,
    printer_state: after a failed line on Klipper, {state ("ready" | "shutdown" | "not ready" |
        "error" | "unknown"), message} (pty: STATUS; Moonraker: /printer/info), else null
Exit status (also in --help): 0 every setting applied and read back; 1 sent, but something not
applied (the report gives the firmware's own words, a wrong firmware it recognised, what stays in
force and how to undo it); 2 nothing sent (bad input, or a value far outside what the printer is
configured for without --force), or the printer stopped answering (the report says what was applied).
"""

from __future__ import annotations

import argparse
import os

from ringtune.agents.cli.common import firmware_name, load_config
from ringtune.agents.cli.options import VALUES
from ringtune.hardware.push import PushError, push
from ringtune.shaping.errors import RingtuneError

NAME = "push"
DESCRIPTION = """\
Send a TuneConfig to a printer, read the settings back and report, per setting, applied or not.

--port is required (there is no guessing): a device (/dev/ttyUSB0, /dev/ttyACM0, COM3), Klipper's
pseudo-tty (/tmp/printer, ~/printer_data/comms/klippy.serial), or a pyserial URL
(socket://host:port for a network serial bridge, rfc2217://host:port). Klipper can also be reached
through Moonraker: --moonraker http://host:7125 (API key: --api-key or $MOONRAKER_API_KEY).

Marlin and RepRapFirmware lines are numbered and checksummed (XOR; --crc for RRF's CRC-16), one
`ok` each, with resend requests, busy messages, temperature reports and printer resets handled.
After sending, the firmware is asked (M593, M493, SET_INPUT_SHAPER; M204, SET_VELOCITY_LIMIT) and
its answer compared. Nothing is sent unless every value passes `ringtune shaper`'s check and the
firmware's range and precision (a value that would round to another one is refused). After a
line Klipper refused, its state is asked; if it shut down, the report says so and how to recover
(FIRMWARE_RESTART).

The config's acceleration is applied too (SET_VELOCITY_LIMIT ACCEL= on Klipper, M204 P on Marlin,
Prusa and RepRapFirmware) and read back; --no-accel leaves it alone. A sliced file's own
acceleration commands override it while it prints (see `ringtune export --slicer`).

--save persists where the firmware can: M500 (Marlin), M593 W (Prusa). RepRapFirmware and Klipper
cannot save these from G-code: the lines are written to a file (--save-file) for config.g or
printer.cfg. --dry-run prints exactly what would be sent and opens nothing.

Before sending, a shaper frequency outside 10-150 Hz (where printers resonate) or an acceleration
more than twice the highest the printer reports (read from it first) is refused; --force sends it
anyway. A line the firmware refuses is reported in its own words (Marlin "?Frequency (F) must be
greater than 40.00", "Unknown command"); a printer that refuses in another firmware's words is named
(Marlin lines sent to Klipper), and after a partial push the report says what stays in force and
how to undo it (Klipper FIRMWARE_RESTART, Marlin and Prusa M501, RepRapFirmware M98 P"config.g").

exit status:
  0  every setting applied and read back
  1  sent, but something not applied (see the report: the firmware's words, what stays, how to undo)
  2  nothing sent: bad input, or a value far outside the printer's limits (--force); or the printer
     stopped answering (the report says what was applied before)

examples:
  ringtune push best.json --firmware marlin --port /dev/ttyUSB0 --save
  ringtune push best.json --firmware rrf --port socket://192.168.1.40:23 --dry-run
  ringtune push best.json --firmware klipper --port /tmp/printer
  ringtune push best.json --firmware klipper --moonraker http://mainsail.local:7125
"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("config", metavar="CONFIG", help="TuneConfig JSON")
    p.add_argument("--firmware", type=firmware_name, help="klipper, kalico, rrf, rrf35, rrf34, marlin, marlin-ftm, prusa "
                   "(default: the config's firmware)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--port", metavar="PORT", help="serial device or pyserial URL (required unless "
                       "--moonraker or --dry-run)")
    where.add_argument("--moonraker", metavar="URL", help="Klipper through Moonraker's HTTP API")
    p.add_argument("--api-key", metavar="KEY", help="Moonraker API key (default $MOONRAKER_API_KEY)")
    p.add_argument("--baud", type=VALUES["baud"], default=115200, help="serial speed (default 115200)")
    p.add_argument("--crc", action="store_true", help="RepRapFirmware: CRC-16 instead of XOR checksums")
    p.add_argument("--timeout", type=VALUES["seconds"], default=10.0,
                   help="seconds without any answer before giving up (default 10)")
    p.add_argument("--save", action="store_true", help="persist the settings (see above)")
    p.add_argument("--save-file", metavar="FILE", help="where --save writes config lines (RRF, Klipper)")
    p.add_argument("--no-accel", action="store_true",
                   help="leave the printer's acceleration (and Klipper's corner rule) alone")
    p.add_argument("--dry-run", action="store_true", help="print exactly what would be sent; send nothing")
    p.add_argument("--force", action="store_true", help="send values far outside what the printer is "
                   "configured for (refused otherwise, nothing sent)")
    p.add_argument("-v", "--verbose", action="store_true", help="show the conversation on stderr")


def run(args, out) -> int:
    cfg = load_config(args.config, out)
    if not args.dry_run and not args.port and not args.moonraker:
        raise RingtuneError("refusing to push without an explicit port: give --port /dev/ttyUSB0 (or "
                            "socket://host:port, rfc2217://host:port, /tmp/printer) or --moonraker URL; "
                            "--dry-run shows what would be sent", "--port")
    log = out.note if args.verbose else None
    out.release()                        # the conversation (-v) goes out live
    try:
        result = push(cfg, args.firmware, port=args.port, moonraker=args.moonraker, baud=args.baud,
                      save=args.save, dry_run=args.dry_run, timeout=args.timeout, crc=args.crc,
                      api_key=args.api_key or os.environ.get("MOONRAKER_API_KEY"),
                      save_path=args.save_file, log=log, accel=not args.no_accel,
                      check_limits=not args.force)
    except PushError as exc:
        out.emit(exc.result.to_dict(), exc.result.text())
        raise
    except RingtuneError as exc:   # name the file the user gave, not the abstract "config"
        raise exc.relocated("config", args.config) from None
    out.emit(result.to_dict(), result.text())
    return 0 if result.ok else 1
