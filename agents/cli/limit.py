"""``ringtune limit``: frequency-limit post-processor for G-code.

JSON keys (stable): ``input``, ``output`` (path or null when printed to stdout), ``method``,
``freq_limit_hz``, ``min_speed_factor``, ``moves_slowed``, ``lines_changed``, ``f_words_replaced``,
``f_words_added``, ``header`` (the comment written at the top of the output); with ``--accel``: ``accel`` (mm/s²),
``accel_reference`` (the file's highest printing acceleration, mm/s², null when it sets none),
``accel_factor``, ``accel_lines_changed``, ``notes``. Without ``--freq-limit`` the frequency keys are
null / 0. ``frequencies`` ({``commanded_hz``: {``before``, ``after``}: the highest
direction-change frequency at the G-code's speeds F, what a frequency limit acts on;
``planned_hz``: {``before``, ``after``}: the highest after planning, as ``ringtune plan`` reports
it with the same printer; ``junction``, ``junction_reason``, ``ignored_note``: under Klipper's rule, the
output's limit lines Klipper does not act on, in words, else null}).
"""

from __future__ import annotations

import sys
from pathlib import Path

from ringtune.agents.cli.common import GCODE_JOB_HELP, check_gcode_output, gcode_job
from ringtune.agents.cli.options import VALUES
from ringtune.envs.job_plan import limit_job
from ringtune.shaping.errors import RingtuneError

NAME = "limit"
DESCRIPTION = """\
Rewrite a G-code file so that no extrusion path changes direction faster than --freq-limit Hz
(nophead's infill frequency limit). Only the F words that must change are changed (or added where
a slowed stretch begins and ends); every other byte stays as it was, and a comment on the first
line records what was done.

The limit acts on the commanded frequency: the G-code's own speed F over the length of three
zigzag cycles. The printer never reaches F on short zigzags (it accelerates and slows for
corners), so the planned frequency, what the printer does, is lower. Both are reported, before
and after, exactly as `ringtune plan` reports them given the same --printer: a limit above the
planned figure slows moves on paper but changes little on the printer.

Methods:
  sections  slow only the high-frequency stretch of a path (default)
  nophead   slow the whole path to its worst three-cycle stretch (nophead's 2010 algorithm)
  marlin    what Marlin's XY_FREQUENCY_LIMIT (M201 F<Hz> S<%>) does, block by block; its floor
            is the file's own M201 S, else Marlin's default XY_FREQUENCY_MIN_PERCENT 5 %

--accel A rewrites the file's own acceleration commands (M204 P/S/T, M201 X/Y, Klipper
SET_VELOCITY_LIMIT ACCEL) so that its highest printing acceleration becomes A mm/s², every other
one scaled by the same factor (the ratios between features stay); nothing else changes. A sliced
file's commands override what the printer was told, so this is how a tuned acceleration reaches a
job that is already sliced.

examples:
  ringtune limit part.gcode --freq-limit 20 -o part_limited.gcode
  ringtune limit part.gcode --accel 4200 -o part_4200.gcode
  ringtune limit part.gcode --freq-limit 25 --method nophead --min-speed-factor 0.5 -o out.gcode
"""


#: library parameters whose option has another name (see agents/cli/main.py: as_flag)
PARAMETER_FLAGS = {"limit_hz": "--freq-limit"}


def add_arguments(parser) -> None:
    parser.add_argument("file", metavar="FILE.gcode", type=gcode_job, help=f"G-code file to limit, {GCODE_JOB_HELP}")
    parser.add_argument("--freq-limit", metavar="HZ", type=VALUES["freq"], default=None,
                        help="largest direction-change frequency, Hz")
    parser.add_argument("--accel", metavar="A", type=VALUES["accel"], default=None,
                        help="scale the file's acceleration commands so its highest printing "
                             "acceleration becomes A mm/s² (ratios between features kept)")
    parser.add_argument("--method", choices=("sections", "nophead", "marlin"), default="sections",
                        help="which algorithm (default: sections)")
    parser.add_argument("--min-speed-factor", metavar="S", type=VALUES["fraction"], default=None,
                        help="never slow below this fraction of the requested speed "
                             "(default 0.3; marlin: the file's M201 S, else 0.05)")
    parser.add_argument("-o", "--output", metavar="OUT", help="output file (default: stdout)")
    parser.add_argument("--printer", metavar="P", help="printer TOML or embedded name for the planned "
                        "frequencies (default: as `ringtune plan` without --printer)")


def run(args, out) -> int:
    if args.freq_limit is None and args.accel is None:
        raise RingtuneError("give --freq-limit HZ, --accel A or both", "--freq-limit")
    if args.output is None and args.json:
        raise RingtuneError("--json needs -o OUT (stdout carries the JSON)", "--output")
    check_gcode_output("--output", args.output)
    done = limit_job(args.file, args.freq_limit, args.method, args.min_speed_factor, args.accel, args.printer)
    result = _result(args, done)
    if args.output is None:
        sys.stdout.buffer.write(done.data)
        sys.stdout.flush()
        out.note(result["header"], *result["notes"], _said(done.frequencies))
        return 0
    Path(args.output).write_bytes(done.data)
    out.emit(result, _text(args, done))
    return 0


def _result(args, done) -> dict:
    """The JSON of one run (keys in the module docstring)."""
    res, acc = done.limited, done.accel
    limited = ({"method": args.method, "min_speed_factor": res.min_speed_factor, "moves_slowed": res.moves_slowed,
                "lines_changed": res.lines_changed, "f_words_replaced": res.f_words_changed,
                "f_words_added": res.f_words_added} if res else _NOT_LIMITED)
    scaled = ({"accel_reference": acc.reference, "accel_factor": acc.factor, "accel_lines_changed": acc.lines_changed,
               "notes": acc.notes} if acc else dict(_NOT_SCALED, notes=[]))
    return {
        "input": args.file, "output": args.output, "method": limited["method"],
        "freq_limit_hz": args.freq_limit, **{k: limited[k] for k in _LIMITED_KEYS},
        "header": "\n".join(h.header for h in (res, acc) if h is not None),
        "accel": args.accel, **scaled,
        "frequencies": done.frequencies,
    }


#: the limit's JSON keys after freq_limit_hz, and their values when no limit was applied
_LIMITED_KEYS = ("min_speed_factor", "moves_slowed", "lines_changed", "f_words_replaced", "f_words_added")
_NOT_LIMITED = {"method": None, "min_speed_factor": None, "moves_slowed": 0, "lines_changed": 0,
                "f_words_replaced": 0, "f_words_added": 0}
#: the --accel keys when the accelerations were not scaled
_NOT_SCALED = {"accel_reference": None, "accel_factor": None, "accel_lines_changed": 0, "notes": []}


def _said(freqs: dict) -> str:
    """The highest frequencies before and after, in words."""
    c, p = freqs["commanded_hz"], freqs["planned_hz"]
    return (f"highest direction-change frequency (three cycles while extruding): commanded at F "
            f"{c['before']:.1f} -> {c['after']:.1f} Hz (what a frequency limit acts on); planned with "
            f"{freqs['junction']} {p['before']:.1f} -> {p['after']:.1f} Hz (what the printer does)")


def _text(args, done) -> str:
    """The readable summary when the G-code went to a file."""
    res, acc = done.limited, done.accel
    text = []
    if res:
        text.append(f"{args.file} -> {args.output}: {res.moves_slowed} moves slowed, "
                    f"F changed on {res.lines_changed} lines ({res.f_words_changed} replaced, "
                    f"{res.f_words_added} added)")
    if acc:
        text.append(acc.header.lstrip("; ") + "".join(f"\nnote: {n}" for n in acc.notes))
    text.append(f"  {_said(done.frequencies)}")
    if done.frequencies["ignored_note"]:
        text.append(f"  {done.frequencies['ignored_note']}")
    return "\n".join(text)
