"""``ringtune export``: a TuneConfig in a firmware's own G-code / config dialect.

``--json`` keys (stable):
    firmware: dialect name
    lines: G-code lines that apply the config now
    save_lines: lines that persist it (M500, M593 W), possibly empty
    config_text: text for the firmware's config file, or null; config_target: where it belongs
    readback: commands that report the settings
    expected: setting -> value the read-back should show
    notes: remarks (e.g. no frequency limit here, and the `ringtune limit` command to use instead)
    output: path written, or null
"""

from __future__ import annotations

import argparse

NAME = "export"
HELP = "write a tuning config in a firmware's own dialect (M593, M493, SET_INPUT_SHAPER, ...)"
DESCRIPTION = """\
Turn a TuneConfig (JSON from `ringtune tune` or `recommend`) into the firmware's own lines:

  klipper     SET_INPUT_SHAPER ... and an [input_shaper] printer.cfg section (keeps damping_ratio)
  rrf         RepRapFirmware 3.6: M593 P"type" F S (custom: H individual amplitudes, T delays)
  rrf35/rrf34 RepRapFirmware 3.5/3.4: M593 (custom: H cumulative amplitudes, T durations; L)
  marlin      Marlin input shaping: M593 X/Y F D (ZV only) and M201 F S for the frequency limit
  marlin-ftm  Marlin FT_MOTION: M493 S1, M493 X/Y C A I [Q]
  prusa       Prusa-Firmware-Buddy: M593 X/Y T F D [R], saved with M593 W

Each firmware's ranges are enforced, and a shaper it lacks is refused with the nearest one it
has. Firmware without an XY frequency limit gets the `ringtune limit` command that applies the
limit to the G-code instead.

examples:
  ringtune export best.json --firmware klipper
  ringtune export best.json --firmware rrf -o config-shaping.g
"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("config", metavar="CONFIG", help="TuneConfig JSON")
    p.add_argument("--firmware", help="klipper, rrf, rrf35, rrf34, marlin, marlin-ftm, prusa "
                   "(default: the config's firmware)")
    p.add_argument("-o", "--output", metavar="FILE", help="write the export here (else print it)")


def run(args, out) -> int:
    from pathlib import Path

    from ringtune.agents.commands import check_output_folder, load_config
    from ringtune.hardware.dialects import export_config
    from ringtune.shaping.errors import RingtuneError

    check_output_folder("-o", args.output)
    cfg = load_config(args.config, out)
    try:
        exp = export_config(cfg, args.firmware)
    except RingtuneError as exc:   # name the file the user gave, not the abstract "config"
        raise exc.relocated("config", args.config) from None
    text = exp.render()
    if args.output:
        Path(args.output).write_text(text)
    out.emit({"firmware": exp.firmware, "lines": exp.lines, "save_lines": exp.save_lines,
              "config_text": exp.config_text, "config_target": exp.config_target,
              "readback": exp.readback, "expected": exp.expected, "notes": exp.notes,
              "output": args.output}, text if not args.output else f"wrote {args.output}")
    return 0
