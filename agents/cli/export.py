"""``ringtune export``: a TuneConfig in a firmware's own dialect, and in a slicer's printer profile.

The output has up to three parts:

- commands: G-code lines that apply the config now, with the firmware's own comment syntax (``;``),
  so the whole part can be sent to the printer as a file;
- config: what belongs in the firmware's config file (Klipper's ``[input_shaper]`` section for
  printer.cfg, RRF's config.g lines), for firmware that cannot save these from G-code;
- slicer (``--slicer``): the acceleration settings of that slicer's profile, so that the tuned
  acceleration reaches the sliced G-code (a slicer's own M204 / SET_VELOCITY_LIMIT lines override
  what the printer was told).

``-o FILE`` writes the commands to FILE, the config part to ``FILE-<target>`` (``x-printer.cfg``,
``x-config.g``) and the slicer part to ``FILE-<slicer>.<ext>``; ``--part`` picks one part.

``--json`` keys (stable):
    firmware: firmware name
    lines: G-code lines that apply the config now
    save_lines: lines that persist it (M500, M593 W), possibly empty
    config_text: text for the firmware's config file, or null; config_target: where it belongs
    readback: commands that report the settings
    expected: setting -> value the read-back should show
    notes: remarks (e.g. no frequency limit here, and the `ringtune limit` command to use instead)
    slicer: {slicer, extension, settings, text, notes, effective (feature class -> mm/s² the
        re-sliced G-code gives it), version} or null
    output: path written (the commands, or the part asked for), or null; files: every path written
"""

from __future__ import annotations

import argparse
from pathlib import Path

from ringtune.agents.cli.common import check_output_folder, firmware_name, load_config
from ringtune.hardware.dialects import export_config
from ringtune.hardware.slicer_profile import slicer_profile
from ringtune.shaping.errors import RingtuneError

NAME = "export"
DESCRIPTION = """\
Turn a TuneConfig (JSON from `ringtune tune` or `recommend`) into the firmware's own lines:

  klipper     SET_INPUT_SHAPER ... and an [input_shaper] printer.cfg section (keeps damping_ratio)
  rrf         RepRapFirmware 3.6: M593 P"type" F S (custom: H individual amplitudes, T delays)
  rrf35/rrf34 RepRapFirmware 3.5/3.4: M593 (custom: H cumulative amplitudes, T durations; L)
  marlin      Marlin input shaping: M593 X/Y F D (ZV only); M201 F S for a limit tuned with
              Marlin's own algorithm (others: the `ringtune limit` command, no M201 F)
  marlin-ftm  Marlin FT_MOTION: M493 S1, M493 X/Y C A I [Q]
  prusa       Prusa-Firmware-Buddy: M593 X/Y T F D [R], saved with M593 W

The config's acceleration is set too (SET_VELOCITY_LIMIT ACCEL= on Klipper, M204 P elsewhere)
unless --no-accel. A sliced file's own acceleration commands override it while it prints:
--slicer prusaslicer|orcaslicer|cura writes that slicer's own per-feature acceleration keys (from
the config's feature_accel, else its accel) to load into its profile and re-slice; where one key
governs several feature classes it takes the lowest, and the notes say what each class gets
(--slicer-version 2.5: PrusaSlicer 2.5's fewer keys).

Every value is checked as `ringtune shaper` checks it, plus the firmware's range and precision: a
value that would round to another one is refused, never changed; a shaper the firmware lacks is
refused with the nearest one it has.

The command part uses the firmware's comment syntax, so it can be sent as a file; the config-file
part (printer.cfg section, config.g lines) is written separately: -o gives two files, or choose
one with --part commands|config|slicer.

examples:
  ringtune export best.json --firmware klipper
  ringtune export best.json --firmware klipper -o shaping.gcode      # + shaping-printer.cfg
  ringtune export best.json --firmware klipper --part config >> printer.cfg
  ringtune export best.json --firmware rrf -o config-shaping.g
  ringtune export best.json --firmware marlin --slicer prusaslicer
  ringtune export best.json --slicer prusaslicer --slicer-version 2.5 --part slicer -o tuned.ini
"""

PARTS = ("commands", "config", "slicer")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("config", metavar="CONFIG", help="TuneConfig JSON")
    p.add_argument("--firmware", type=firmware_name, help="klipper, kalico, rrf, rrf35, rrf34, marlin, marlin-ftm, prusa "
                   "(default: the config's firmware)")
    p.add_argument("-o", "--output", metavar="FILE", help="write the commands here, the config-file and "
                   "slicer parts beside it (else print them)")
    p.add_argument("--part", choices=PARTS, help="only this part (default: all there are)")
    p.add_argument("--no-accel", action="store_true",
                   help="leave the printer's acceleration (and Klipper's corner rule) alone")
    p.add_argument("--slicer", choices=("prusaslicer", "orcaslicer", "cura"),
                   help="also write this slicer's per-feature acceleration settings")
    p.add_argument("--slicer-version", metavar="X.Y", help="the slicer's version where its keys differ "
                   "(PrusaSlicer before 2.6: perimeter, infill, bridge and default only; default: the current)")


def _sibling(output, suffix: str):
    out = Path(output)
    return out.with_name(f"{out.stem}-{suffix}")


def run(args, out) -> int:
    check_output_folder("-o", args.output)
    cfg = load_config(args.config, out)
    try:
        exp = export_config(cfg, args.firmware, accel=not args.no_accel)
        slicer = slicer_profile(cfg, args.slicer, exp.firmware, args.slicer_version) if args.slicer else None
    except RingtuneError as exc:   # name the file the user gave, not the abstract "config"
        raise exc.relocated("config", args.config) from None
    if cfg.per_feature:      # a firmware holds one acceleration: the per-feature ones belong in the job
        out.note(f"ringtune export: {args.config} sets accelerations per feature (or the corner rule): the lines "
                 f"below carry the visible walls' {cfg.accel or 0:g} mm/s²; `ringtune rewrite JOB --config "
                 f"{args.config} -o OUT` writes the rest into a job at each feature change")
    parts = _parts(exp, slicer, args)
    files = _write(parts, args) if args.output else []
    out.emit({"firmware": exp.firmware, "lines": exp.lines, "save_lines": exp.save_lines,
              "config_text": exp.config_text, "config_target": exp.config_target,
              "readback": exp.readback, "expected": exp.expected, "notes": exp.notes,
              "slicer": slicer.to_dict() if slicer else None,
              "output": next(iter(files), None), "files": files},
             "\n".join(f"wrote {f}" for f in files) if files else "\n".join(t for t, _ in parts.values()).rstrip("\n"))
    return 0


def _parts(exp, slicer, args) -> dict[str, tuple[str, str | None]]:
    """{part: (text, the name it takes beside -o)} of the parts asked for (--part), else of every
    part there is."""
    _check_part(exp, slicer, args.part)
    parts = {"commands": (exp.render_commands(), None),
             "config": (exp.render_config(), "printer.cfg" if exp.config_target == "printer.cfg" else "config.g"),
             "slicer": (slicer.render(), f"{args.slicer}.{slicer.extension}") if slicer else (None, None)}
    wanted = [args.part] if args.part else [k for k in PARTS if parts[k][0] is not None]
    return {k: parts[k] for k in wanted}


def _check_part(exp, slicer, part: str | None) -> None:
    """A part asked for must exist: the slicer part needs --slicer, the config part a firmware with a
    config file."""
    if part == "slicer" and slicer is None:
        raise RingtuneError("give --slicer prusaslicer|orcaslicer|cura for the slicer part", "--part")
    if part == "config" and exp.config_text is None:
        raise RingtuneError(f"{exp.record.title} has no config-file part: its settings are saved from "
                            f"G-code ({' '.join(exp.save_lines) or 'not at all'}); use --part commands",
                            "--part")


def _write(parts: dict, args) -> list[str]:
    """Write the commands to -o and the other parts beside it (a single --part goes to -o itself);
    the files written."""
    files = []
    for k, (text, name) in parts.items():
        path = Path(args.output) if (k == "commands" or args.part) else _sibling(args.output, name)
        path.write_text(text)
        files.append(str(path))
    return files
