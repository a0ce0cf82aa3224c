"""``ringtune limit``: frequency-limit post-processor for G-code.

JSON keys (stable): ``input``, ``output`` (path or null when printed to stdout), ``method``,
``freq_limit_hz``, ``min_speed_factor``, ``moves_slowed``, ``lines_changed``, ``f_words_replaced``,
``f_words_added``, ``header`` (the comment written at the top of the output).
"""

from __future__ import annotations

NAME = "limit"
HELP = "slow only the zigzags that shake: rewrite F words so direction changes stay under a frequency"
DESCRIPTION = """\
Rewrite a G-code file so that no extrusion path changes direction faster than --freq-limit Hz
(nophead's infill frequency limit). Only the F words that must change are changed (or added where
a slowed stretch begins and ends); every other byte stays as it was, and a comment on the first
line records what was done.

Methods:
  sections  slow only the high-frequency stretch of a path (default)
  nophead   slow the whole path to its worst three-cycle stretch (nophead's 2010 algorithm)
  marlin    what Marlin's XY_FREQUENCY_LIMIT (M201 F<Hz> S<%>) does, block by block; its floor
            is the file's own M201 S, else Marlin's default XY_FREQUENCY_MIN_PERCENT 5 %

examples:
  ringtune limit part.gcode --freq-limit 20 -o part_limited.gcode
  ringtune limit part.gcode --freq-limit 25 --method nophead --min-speed-factor 0.5 -o out.gcode
"""


#: library parameters whose option has another name (see agents/cli.py: as_flag)
PARAMETER_FLAGS = {"limit_hz": "--freq-limit"}


def add_arguments(parser) -> None:
    parser.add_argument("file", metavar="FILE.gcode", help="G-code file to limit")
    parser.add_argument("--freq-limit", metavar="HZ", type=float, required=True,
                        help="largest direction-change frequency, Hz")
    parser.add_argument("--method", choices=("sections", "nophead", "marlin"), default="sections",
                        help="which algorithm (default: sections)")
    parser.add_argument("--min-speed-factor", metavar="S", type=float, default=None,
                        help="never slow below this fraction of the requested speed "
                             "(default 0.3; marlin: the file's M201 S, else 0.05)")
    parser.add_argument("-o", "--output", metavar="OUT", help="output file (default: stdout)")


def run(args, out) -> int:
    import sys

    from ringtune.shaping.errors import RingtuneError
    from ringtune.shaping.gcode_post import limit_file

    if not args.freq_limit > 0:
        raise RingtuneError("must be a frequency > 0 Hz", "--freq-limit")
    if args.min_speed_factor is not None and not 0 < args.min_speed_factor <= 1:
        raise RingtuneError("must be in (0, 1]", "--min-speed-factor")
    if args.output is None and args.json:
        raise RingtuneError("--json needs -o OUT (stdout carries the JSON)", "--output")
    data, res = limit_file(args.file, args.output, args.freq_limit, args.method, args.min_speed_factor)
    result = {
        "input": args.file, "output": args.output, "method": args.method,
        "freq_limit_hz": args.freq_limit, "min_speed_factor": res.min_speed_factor,
        "moves_slowed": res.moves_slowed, "lines_changed": res.lines_changed,
        "f_words_replaced": res.f_words_changed, "f_words_added": res.f_words_added,
        "header": res.header,
    }
    if args.output is None:
        sys.stdout.buffer.write(data)
        sys.stdout.flush()
        out.note(res.header)
        return 0
    out.emit(result, f"{args.file} -> {args.output}: {res.moves_slowed} moves slowed, "
                     f"F changed on {res.lines_changed} lines ({res.f_words_changed} replaced, "
                     f"{res.f_words_added} added)")
    return 0
