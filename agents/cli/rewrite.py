"""``ringtune rewrite``: a sliced job rewritten for a tuned configuration.

JSON keys (stable): ``input``, ``output``, ``firmware``, ``junction``, ``lines_inserted``,
``f_lines_changed`` (the frequency limit's F words), ``print_time_before_s`` (as sliced),
``print_time_after_s`` (the rewritten file), ``print_time_config_s`` (the configuration on the
original, as ``tune`` reports it), ``feature_accel`` ({class: mm/s²}), ``corner``,
``min_cruise_ratio`` (these three null where nothing is set per feature: a configuration judged with
the job's own accelerations standing, ``job_accel`` ``respect``), ``header``, ``first_layer_kept``
(null, or the lowest acceleration the job gives the first layer it slows itself, mm/s², which the
rewrite keeps wherever it is lower than the per-feature one: said on stderr too), ``shaper_replaced``
([{``line``, ``text``}]: the job's own shaper commands that would have moved the printer off the
configuration's shaper, each replaced by the configuration's shaper command: said on stderr too).
"""

from __future__ import annotations

from ringtune.agents.cli.common import GCODE_JOB_HELP, check_gcode_output, gcode_job, load_config
from ringtune.envs.job_rewrite import first_layer_words, rewrite_file, shaper_words
from ringtune.hardware.dialects import shaper_commands
from ringtune.shaping.gcode_file import binary_note

NAME = "rewrite"
DESCRIPTION = """\
Write a tuned configuration into a sliced job, in the firmware's own dialect: before each feature
change (and, on Klipper, each travel) the acceleration of that feature class, the corner rule and
minimum_cruise_ratio once at the start, the per-axis caps raised once where the firmware has them
(Marlin, Prusa, RRF: M201 X Y), and the configuration's frequency limit (as `ringtune limit`).
Lines are only inserted, never changed (apart from the limit's F words, and a shaper command of the
job's own that would move the printer off the configuration's shaper: the configuration's shaper
command takes its place, with a comment quoting it); a comment on the first line says what was
done. The same commands follow any acceleration command of the job itself, so the job's own values
never rule a move — unless tune judged the configuration with the job's own acceleration commands
standing (--job-accel respect, recorded in best.json) and it sets nothing per feature: then they
stand in the file too, and only the frequency limit and a Y schedule are written.

  Klipper/Kalico  SET_VELOCITY_LIMIT ACCEL=... [SQUARE_CORNER_VELOCITY=... MINIMUM_CRUISE_RATIO=...
                  ACCEL_TO_DECEL=...]   (ACCEL_TO_DECEL = ACCEL x (1 - minimum_cruise_ratio) where
                  the configuration sets a ratio: a Klipper from before 2024 has no
                  MINIMUM_CRUISE_RATIO and would keep its own; a newer one ignores the word)
  Marlin, Prusa   M204 P... T...  (+ M205 J... or M205 X... Y..., M201 X... Y...)
  RepRapFirmware  M204 P... T...  (+ M566 X... Y... in mm/min, M201 X... Y...)

The planned time before (as sliced) and after (the rewritten file) are printed, planned on
--printer as `tune` plans: the rewritten file's time is the one tune reported for the configuration.

examples:
  ringtune rewrite part.gcode --config tuned/best.json -o part_tuned.gcode
  ringtune rewrite part.gcode --config best.json --printer my.toml -o out.gcode --json
"""


def add_arguments(parser) -> None:
    parser.add_argument("file", metavar="JOB.gcode", type=gcode_job, help=f"sliced G-code job, {GCODE_JOB_HELP}")
    parser.add_argument("--config", metavar="C", required=True, help="TuneConfig JSON (tune's best.json)")
    parser.add_argument("-o", "--output", metavar="OUT", required=True, help="rewritten G-code file")
    parser.add_argument("--printer", metavar="P", help="printer TOML or embedded name (default: the built-in printer, "
                        "as tune)")


def run(args, out) -> int:
    check_gcode_output("--output", args.output)
    cfg = load_config(args.config, out)
    done = rewrite_file(args.file, args.output, cfg, args.printer, shaper_lines=shaper_commands)
    fc = done.commands
    result = {"input": args.file, "output": args.output, "firmware": cfg.firmware, "junction": done.junction,
              "lines_inserted": done.lines_inserted, "f_lines_changed": done.f_lines_changed,
              "print_time_before_s": done.before_s, "print_time_after_s": done.after_s,
              "print_time_config_s": done.config_s, "feature_accel": dict(fc.accel) if fc else None,
              "corner": fc.corner if fc else None, "min_cruise_ratio": fc.min_cruise_ratio if fc else None,
              "header": done.header, "first_layer_kept": done.first_layer,
              "shaper_replaced": [{"line": ln, "text": t} for ln, t in done.shaper_replaced]}
    binary = binary_note(args.file)
    if binary:
        out.note(f"ringtune rewrite: {binary}")
    if done.first_layer:
        out.note(f"ringtune rewrite: {first_layer_words(done.first_layer)}")
    if done.shaper_replaced:
        out.note(f"ringtune rewrite: {shaper_words([ln for ln, _t in done.shaper_replaced])}")
    saved = done.before_s - done.after_s
    text = (f"{args.file} -> {args.output}: {done.lines_inserted} lines inserted"
            + (f", F changed on {done.f_lines_changed} lines (frequency limit)" if done.f_lines_changed else "")
            + f"\n  planned on the printer: {done.before_s:.1f} s as sliced -> {done.after_s:.1f} s rewritten "
            f"({saved:+.1f} s saved, {100 * saved / max(done.before_s, 1e-9):.1f} %); the configuration on the "
            f"original as tune plans it: {done.config_s:.1f} s")
    out.emit(result, text)
    return 0

