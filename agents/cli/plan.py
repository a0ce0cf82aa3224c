"""``ringtune plan``: planned print time and move statistics of a G-code job.

JSON keys (stable): ``job`` (path or ``"built-in test print"``), ``junction`` (scv | jd | jerk),
``limits`` (the MachineLimits used, before the job's own M201/M203/M204/M205/SET_VELOCITY_LIMIT
lines, which apply from where they appear unless ``--no-job-limits`` — under Klipper's rule only
those Klipper acts on), ``ignored_by_firmware`` ({command: [line numbers]} of the limit lines
Klipper does not act on, under its rule; else empty) and ``ignored_note`` (that in words, or
null), ``macro_calls`` ({command: [line numbers]} of the commands that are not Klipper's own —
macros of the printer.cfg, whose commands are not in the file — where the job is read as Klipper
reads it; else empty) and ``macro_note`` (that in words, or null), ``firmware_retraction``
({``G10``/``G11``: [line numbers]} of the job's firmware retractions: E-only moves, the head comes
to rest), ``firmware_retraction_planned`` (how many of them are planned as the E-only moves the
firmware makes, by the printer's ``[limits]`` retract_length, retract_speed, unretract_extra_length
and unretract_speed or the job's own SET_RETRACTION/M207/M208 before them; the others as stops
that take no time) and ``firmware_retraction_note`` (that in words, or null), ``arcs`` (how many
G2/G3 arcs the job has) and ``arcs_note`` (how they are cut: Klipper's ``[gcode_arcs]`` segments
under Klipper's reading, else chords within 0.01 mm; null without arcs), ``extruder_alone_note``
(read as Klipper reads it: that the job's retractions, moves of the extruder alone, are planned at the
toolhead's acceleration and speed since the printer gives no max_extrude_only_accel / _velocity; else
null), ``klipper_refusals`` (read as Klipper reads it, the moves it refuses, each
{``line``, ``kind``: ``out_of_range_x`` | ``out_of_range_y`` | ``too_wide`` | ``too_long``, ``value``,
``limit``}: where the move ends against stepper_x's / stepper_y's position_min or position_max
(``[limits] travel_x`` / ``travel_y``), filament per mm of path against max_extrude_cross_section's,
or mm of filament moved alone against max_extrude_only_distance; Klipper stops the print at the
first) and ``klipper_refusals_note`` (that in words, or null), ``flavor_note`` (a job sliced for
another firmware than the printer's: its limit lines that firmware reads in other units — M203 in
mm/min on RepRapFirmware, mm/s elsewhere — or not at all — M566 on Marlin —, in words; else null), ``print_time_s``,
``print_time``, ``moves``, ``extruding_moves``, ``lines``, ``path_length_mm``,
``time_by_feature`` ({feature: s}), ``feature_classes`` ({feature: the class it is judged as}),
``junction_reason`` (why that junction rule, in words),
``top_frequencies`` (list of {``freq_hz``, ``line``, ``t``}: highest *planned* direction-change
frequencies while extruding, three cycles each, in planned time: what the printer does),
``top_commanded_frequencies`` (list of {``freq_hz``, ``line``}: highest direction-change
frequencies at the G-code's commanded speeds F: what a frequency limit acts on),
``max_planned_freq_hz``, ``max_commanded_freq_hz``,
``shaper_events`` (list of {``line``, ``command``, ``time``, ``params``}), ``events`` ({kind:
count}), ``slicer_estimate_s`` (what the slicer wrote in the file, or null), ``vs_slicer``
(our / slicer − 1, or null), ``freq_limit`` (null or {``hz``, ``method``, ``moves_slowed``,
``source``: ``"config"`` or ``"job M201 F"``}),
``daa_hz``, ``read_s``, ``plan_s``, ``trajectory`` (CSV path or null).
"""

from __future__ import annotations

import csv
import sys

import numpy as np

from ringtune.agents.cli.common import GCODE_JOB_HELP, gcode_job, load_config
from ringtune.agents.cli.options import VALUES
from ringtune.envs.job_plan import hms, plan_job
from ringtune.shaping.firmware import JUNCTION_NAMES
from ringtune.shaping.e_timing import firmware_trajectory, sample_features
from ringtune.shaping.errors import RingtuneError

NAME = "plan"
DESCRIPTION = """\
Read a G-code job and plan it as the firmware would: trapezoidal speed profiles with look-ahead
over the whole job and the firmware's junction rule:

  scv   Klipper square-corner velocity (with minimum_cruise_ratio)
  jd    Marlin junction deviation
  jerk  classic jerk (Marlin, and PrusaSlicer's own time estimator)

Without --junction the rule is the printer's `junction` (--printer), else scv for a --config made
for Klipper or Kalico (their one rule), else what the job's own
commands imply (SET_VELOCITY_LIMIT SQUARE_CORNER_VELOCITY -> scv, M205 J -> jd, M205 X/Y ->
jerk), else the firmware the slicer wrote it for (gcode_flavor / FLAVOR: klipper -> scv,
marlin2 -> jd as Marlin 2 ships, marlin (legacy), reprapfirmware, repetier -> jerk), else the
printer's corner setting, else scv; the output says which rule and why. Limits the job sets in its header
(M201/M203/M204/M205, SET_VELOCITY_LIMIT) override the printer's, M203 in mm/s unless the firmware
reads mm/min (RepRapFirmware; on a printer naming no firmware, a job sliced for it); a job's own Marlin
XY_FREQUENCY_LIMIT (M201 F<Hz> S<%>) slows its zigzags as Marlin would. When the slicer wrote
its own time estimate into the file, it is shown beside ours (Cura's `;TIME:`; where CuraEngine run
alone left its placeholder, 6666 s for any model, its last `;TIME_ELAPSED:`).

Direction-change frequencies (three cycles of zigzag while extruding) are given two ways:
commanded, at the G-code's own speeds F (what `ringtune limit` and a firmware frequency limit act
on), and planned, with the accelerations and corners of the rule above (what the printer does, always lower).
`ringtune limit` reports the same two figures, before and after.

--config applies a TuneConfig's frequency limit, acceleration and per-axis caps (its accel replaces
the job's M204/SET_VELOCITY_LIMIT accelerations unless its job_accel is "respect"); a shaper "daa"
in it (or --daa F) plans with RepRapFirmware 3.3's Dynamic Acceleration Adjustment. --trajectory writes the commanded
toolhead position t,x,y,z,e (after planning, frequency limit and the config's input shaping)
and a feature column: the job's own label of the move X/Y are on (`External perimeter`, `WALL-OUTER`,
…; empty outside any move), so the outer walls can be picked out; its e column is the extruder as that firmware commands it under shaping: shaped with X/Y
(RepRapFirmware), delayed with them, or on the planner's clock (Klipper and Prusa, whose X/Y are
time-centred; Marlin, whose X/Y lag by the shaper's ΣAᵢTᵢ, so E leads them): compare it with the
path to see the extrusion error `simulate` reports.

examples:
  ringtune plan ringing_tower.gcode
  ringtune plan part.gcode --printer my.toml --json
  ringtune plan part.gcode --junction jerk --trajectory traj.csv --rate 2000
  ringtune plan                                   # the built-in test print
"""


def add_arguments(parser) -> None:
    parser.add_argument("file", nargs="?", metavar="FILE.gcode", type=gcode_job,
                        help=f"G-code job, {GCODE_JOB_HELP} (default: the built-in test print)")
    parser.add_argument("--printer", metavar="P", help="printer TOML or embedded name: its limits and junction rule "
                        "(default: the embedded Ender-3-class printer, as every command)")
    parser.add_argument("--config", metavar="C", help="TuneConfig JSON: frequency limit, accel, shapers for --trajectory")
    parser.add_argument("--junction", choices=("auto", "scv", "jd", "jerk"), default="auto",
                        help="junction rule (default auto: the printer's, else what the job's commands imply)")
    parser.add_argument("--no-job-limits", action="store_true", help="ignore the limits the job itself sets")
    parser.add_argument("--daa", metavar="HZ", type=VALUES["freq"], help="RRF <= 3.3 Dynamic Acceleration Adjustment at HZ")
    parser.add_argument("--top", metavar="N", type=VALUES["top"], default=5, help="how many top frequencies to list (default 5)")
    parser.add_argument("--trajectory", metavar="OUT.csv", help="write the commanded position t,x,y,z,e and the "
                        "feature label of the move X/Y are on "
                        "(- for standard output; the summary then goes to standard error)")
    parser.add_argument("--rate", metavar="HZ", type=VALUES["rate"], default=1000.0, help="trajectory sample rate (default 1000)")


def run(args, out) -> int:
    if args.trajectory == "-" and args.json:
        raise RingtuneError("'-' writes the CSV to standard output, which --json needs; give a file",
                            "--trajectory")
    cfg = load_config(args.config, out)
    planned = plan_job(args.file, args.printer, cfg, args.junction, not args.no_job_limits, args.daa, args.top)
    traj = _write_trajectory(planned.configured.plan, cfg, args.trajectory, args.rate) if args.trajectory else None
    result = {**planned.to_dict(), "trajectory": traj}
    text = _text(result)
    if traj == "-":
        out.note(text)          # stdout holds the CSV
        return 0
    out.emit(result, text + (f"\n  trajectory written to {traj}" if traj else ""))
    return 0


def _text(r: dict) -> str:
    """The readable report of a planned job (:meth:`JobPlan.to_dict`)."""
    t = r["print_time_s"]
    lines = [f"{r['job']}: {r['print_time']} ({t:.1f} s) planned with {r['junction']} "
             f"({JUNCTION_NAMES[r['junction']]}): {r['junction_reason']}",
             f"  moves {r['moves']} ({r['extruding_moves']} extruding), "
             f"path {r['path_length_mm'] / 1000:.2f} m, read {r['read_s']:.3f} s, plan {r['plan_s']:.3f} s"]
    estimate, fl = r["slicer_estimate_s"], r["freq_limit"]
    if estimate:
        lines.append(f"  slicer's own estimate {hms(estimate)} ({estimate:.0f} s): ours {100 * r['vs_slicer']:+.2f} %")
    if fl:
        lines.append(f"  frequency limit {fl['hz']:g} Hz ({fl['method']}): {fl['moves_slowed']} moves slowed")
    if r["daa_hz"]:
        lines.append(f"  DAA at {r['daa_hz']:g} Hz")
    for key in ("ignored_note", "macro_note", "firmware_retraction_note", "arcs_note", "extruder_alone_note",
                "klipper_refusals_note", "flavor_note"):
        if r[key]:
            lines.append(f"  {r[key]}")
    lines.append("  time by feature (the job's label, the class ringtune judges it as):")
    for k, v in sorted(r["time_by_feature"].items(), key=lambda kv: -kv[1]):
        lines.append(f"    {k:<28} {r['feature_classes'][k]:<16} {hms(v):>10}  {100 * v / max(t, 1e-12):5.1f} %")
    top, top_cmd = r["top_frequencies"], r["top_commanded_frequencies"]
    if top or top_cmd:
        lines.append("  highest direction-change frequencies (three cycles of zigzag while extruding):")
        lines.append("    commanded, at the G-code's F (what a frequency limit acts on):")
        lines.extend(f"    {f['freq_hz']:7.1f} Hz  line {f['line']}" for f in top_cmd)
        lines.append(f"    planned with {r['junction']} (accelerations and corners: what the printer does):")
        lines.extend(f"    {f['freq_hz']:7.1f} Hz  line {f['line']}  at {f['t']:.1f} s" for f in top)
    events = r["shaper_events"]
    if events:
        lines.append(f"  shaper changes in the job: {len(events)} "
                     f"(first at line {events[0]['line']}, {events[0]['time']:.1f} s)")
    return "\n".join(lines)


def _write_trajectory(p, cfg, path, rate) -> str:
    """Write t,x,y,z,e,feature as the firmware commands them (X/Y shaped, E with the firmware's own
    timing under shaping: ringtune.shaping.e_timing; feature: the job's label of the move X/Y are
    on) to ``path`` ('-': standard output)."""
    t, pos = firmware_trajectory(p.motion, cfg, rate)
    labels = sample_features(p, cfg, t)
    target = sys.stdout if path == "-" else open(path, "w", newline="")
    try:
        target.write("t,x,y,z,e,feature\n")
        w = csv.writer(target, lineterminator="\n")
        nums = np.char.mod("%.6f", np.column_stack([t, pos[:, :4]]))
        w.writerows(row.tolist() + [label] for row, label in zip(nums, labels))
    finally:
        if target is not sys.stdout:
            target.close()
    return "-" if path == "-" else str(path)
