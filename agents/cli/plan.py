"""``ringtune plan``: planned print time and move statistics of a G-code job.

JSON keys (stable): ``job`` (path or ``"built-in test print"``), ``junction`` (scv | jd | jerk),
``limits`` (the MachineLimits used, before the job's own M201/M203/M204/M205/SET_VELOCITY_LIMIT
lines, which apply from where they appear unless ``--no-job-limits``), ``print_time_s``,
``print_time``, ``moves``, ``extruding_moves``, ``lines``, ``path_length_mm``,
``time_by_feature`` ({feature: s}), ``junction_reason`` (why that junction rule, in words),
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

NAME = "plan"
HELP = "plan a G-code job: print time, moves, time by feature, highest direction-change frequencies"
DESCRIPTION = """\
Read a G-code job and plan it as the firmware would: trapezoidal speed profiles with look-ahead
over the whole job and the firmware's junction rule:

  scv   Klipper square-corner velocity (with minimum_cruise_ratio)
  jd    Marlin junction deviation
  jerk  classic jerk (Marlin, and PrusaSlicer's own time estimator)

Without --junction the rule is the printer's `junction` (--printer), else what the job's own
commands imply (SET_VELOCITY_LIMIT SQUARE_CORNER_VELOCITY -> scv, M205 J -> jd, M205 X/Y ->
jerk), else the firmware the slicer wrote it for (gcode_flavor / FLAVOR: klipper -> scv,
marlin2 -> jd as Marlin 2 ships, marlin (legacy), reprapfirmware, repetier -> jerk), else the
printer's corner setting, else scv; the output says which rule and why. Limits the job sets in its header
(M201/M203/M204/M205, SET_VELOCITY_LIMIT) override the printer's; a job's own Marlin
XY_FREQUENCY_LIMIT (M201 F<Hz> S<%>) slows its zigzags as Marlin would. When the slicer wrote
its own time estimate into the file, it is shown beside ours.

Direction-change frequencies (three cycles of zigzag while extruding) are given two ways:
commanded, at the G-code's own speeds F (what `ringtune limit` and a firmware frequency limit act
on), and planned, with the accelerations and corners of the rule above (what the printer does, always lower).
`ringtune limit` reports the same two figures, before and after.

--config applies a TuneConfig's frequency limit, acceleration and per-axis caps (its accel replaces
the job's M204/SET_VELOCITY_LIMIT accelerations unless its job_accel is "respect"); a shaper "daa"
in it (or --daa F) plans with RepRapFirmware 3.3's Dynamic Acceleration Adjustment. --trajectory
writes the commanded toolhead position t,x,y,z,e (after planning, frequency limit and the config's
input shaping, changed where the job's own shaper commands stand, as simulate does).

examples:
  ringtune plan ringing_tower.gcode
  ringtune plan part.gcode --printer my.toml --json
  ringtune plan part.gcode --junction jerk --trajectory traj.csv --rate 2000
  ringtune plan                                   # the built-in test print
"""


def add_arguments(parser) -> None:
    parser.add_argument("file", nargs="?", metavar="FILE.gcode", help="G-code job (default: the built-in test print)")
    parser.add_argument("--printer", metavar="P", help="printer TOML or embedded name: its limits and junction rule")
    parser.add_argument("--config", metavar="C", help="TuneConfig JSON: frequency limit, accel, shapers for --trajectory")
    parser.add_argument("--junction", choices=("auto", "scv", "jd", "jerk"), default="auto",
                        help="junction rule (default auto: the printer's, else what the job's commands imply)")
    parser.add_argument("--no-job-limits", action="store_true", help="ignore the limits the job itself sets")
    parser.add_argument("--daa", metavar="HZ", type=float, help="RRF <= 3.3 Dynamic Acceleration Adjustment at HZ")
    parser.add_argument("--top", metavar="N", type=int, default=5, help="how many top frequencies to list (default 5)")
    parser.add_argument("--trajectory", metavar="OUT.csv", help="write the commanded position t,x,y,z,e "
                        "(- for standard output; the summary then goes to standard error)")
    parser.add_argument("--rate", metavar="HZ", type=float, default=1000.0, help="trajectory sample rate (default 1000)")


def _hms(seconds: float) -> str:
    s = int(round(seconds))
    h, rem = divmod(s, 3600)
    m, s = divmod(rem, 60)
    return f"{h}h {m:02d}m {s:02d}s" if h else f"{m}m {s:02d}s"


def run(args, out) -> int:
    import time
    from dataclasses import asdict

    import numpy as np

    from ringtune.shaping.config_plan import plan_with_config
    from ringtune.shaping.errors import RingtuneError
    from ringtune.shaping.gcode import read_gcode
    from ringtune.shaping.slicer import slicer_estimate
    from ringtune.shaping.testprints import builtin_test_print

    if args.rate <= 0 or not np.isfinite(args.rate):
        raise RingtuneError("must be a positive number of samples per second", "--rate")
    if args.top < 0:
        raise RingtuneError("must be >= 0", "--top")
    t0 = time.perf_counter()
    if args.file:
        from pathlib import Path

        job = read_gcode(Path(args.file))
        name = args.file
    else:
        job = builtin_test_print()
        name = "built-in test print"
    t_read = time.perf_counter() - t0

    cfg = None
    if args.config:
        from ringtune.agents.cli.common import load_config
        cfg = load_config(args.config, out)
    limits, junction, why = planning_limits(job, args.file, args.printer, args.junction)
    t1 = time.perf_counter()
    configured = plan_with_config(job, limits, cfg, use_job_limits=not args.no_job_limits, daa_freq=args.daa)
    t_plan = time.perf_counter() - t1
    p, limits, daa = configured.plan, configured.limits, configured.daa_hz
    freq_info = None if configured.freq_limit is None else asdict(configured.freq_limit)

    top = planned_frequencies(p, args.top)
    top_cmd = commanded_frequencies(configured.job, args.top)
    kinds: dict[str, int] = {}
    for e in p.events:
        kinds[e.kind] = kinds.get(e.kind, 0) + 1
    shaper_events = [{"line": e.line, "command": e.command, "time": e.time, "params": e.params}
                     for e in p.events if e.kind == "shaper"]
    estimate = slicer_estimate(args.file) if args.file else None
    traj = None
    if args.trajectory:
        if args.trajectory == "-" and args.json:
            raise RingtuneError("'-' writes the CSV to standard output, which --json needs; give a file",
                                "--trajectory")
        traj = _write_trajectory(p, cfg, args.trajectory, args.rate)

    result = {
        "job": name,
        "junction": junction,
        "junction_reason": why,
        "limits": {k: v for k, v in asdict(limits).items()},
        "print_time_s": p.print_time,
        "print_time": _hms(p.print_time),
        "moves": len(p.moves),
        "extruding_moves": int(p.moves.extruding.sum()),
        "lines": job.n_lines,
        "path_length_mm": float(p.moves.length.sum()),
        "time_by_feature": p.time_by_feature(),
        "top_frequencies": top,
        "top_commanded_frequencies": top_cmd,
        "max_planned_freq_hz": top[0]["freq_hz"] if top else 0.0,
        "max_commanded_freq_hz": top_cmd[0]["freq_hz"] if top_cmd else 0.0,
        "shaper_events": shaper_events,
        "events": kinds,
        "slicer_estimate_s": estimate,
        "vs_slicer": (p.print_time / estimate - 1) if estimate else None,
        "freq_limit": freq_info,
        "daa_hz": daa,
        "read_s": t_read,
        "plan_s": t_plan,
        "trajectory": traj,
    }
    lines = [f"{name}: {result['print_time']} ({p.print_time:.1f} s) planned with {junction} "
             f"({JUNCTION_NAMES[junction]}): {why}",
             f"  moves {result['moves']} ({result['extruding_moves']} extruding), "
             f"path {result['path_length_mm'] / 1000:.2f} m, read {t_read:.3f} s, plan {t_plan:.3f} s"]
    if estimate:
        lines.append(f"  slicer's own estimate {_hms(estimate)} ({estimate:.0f} s): ours {100 * result['vs_slicer']:+.2f} %")
    if freq_info:
        lines.append(f"  frequency limit {freq_info['hz']:g} Hz ({freq_info['method']}): "
                     f"{freq_info['moves_slowed']} moves slowed")
    if daa:
        lines.append(f"  DAA at {daa:g} Hz")
    lines.append("  time by feature:")
    for k, v in sorted(result["time_by_feature"].items(), key=lambda kv: -kv[1]):
        lines.append(f"    {k:<28} {_hms(v):>10}  {100 * v / max(p.print_time, 1e-12):5.1f} %")
    if top or top_cmd:
        lines.append("  highest direction-change frequencies (three cycles of zigzag while extruding):")
        lines.append("    commanded, at the G-code's F (what a frequency limit acts on):")
        lines.extend(f"    {t['freq_hz']:7.1f} Hz  line {t['line']}" for t in top_cmd)
        lines.append(f"    planned with {junction} (accelerations and corners: what the printer does):")
        lines.extend(f"    {t['freq_hz']:7.1f} Hz  line {t['line']}  at {t['t']:.1f} s" for t in top)
    if shaper_events:
        lines.append(f"  shaper changes in the job: {len(shaper_events)} "
                     f"(first at line {shaper_events[0]['line']}, {shaper_events[0]['time']:.1f} s)")
    if traj == "-":
        out.note("\n".join(lines))          # stdout holds the CSV
        return 0
    if traj:
        lines.append(f"  trajectory written to {traj}")
    out.emit(result, "\n".join(lines))
    return 0


#: the junction rules, in words
JUNCTION_NAMES = {"scv": "Klipper's square-corner velocity", "jd": "Marlin's junction deviation",
                  "jerk": "classic jerk"}
#: slicer G-code flavour -> the rule that firmware plans corners with by default (Marlin 2 ships
#: with junction deviation, CLASSIC_JERK off; legacy Marlin, RepRapFirmware's M566 and Repetier
#: use jerk; Smoothieware junction deviation)
FLAVOR_JUNCTION = {"klipper": "scv", "marlin2": "jd", "marlin": "jerk", "reprapfirmware": "jerk",
                   "reprap": "jerk", "repetier": "jerk", "smoothie": "jd"}


def planning_limits(job, path=None, printer=None, junction: str = "auto"):
    """The machine limits a job is planned with, the junction rule and why (in words).

    Rule: ``junction`` if not ``"auto"``; else the printer's ``[limits] junction``; else what the
    job's own commands imply; else the slicer's flavour (:data:`FLAVOR_JUNCTION`, read from the
    file at ``path``); else the printer's corner setting; else scv. ``plan`` and ``limit`` both
    plan through here, so they report the same planned frequencies."""
    from dataclasses import replace

    from ringtune.shaping.planner import MachineLimits

    given: dict = {}
    if printer:
        from ringtune.envs.printer import load_printer

        pr = load_printer(printer)
        limits, given = pr.machine_limits(), dict(pr.limits_dict)
    else:
        limits = MachineLimits()
    fs = job.file_setting
    flavor = None
    if path:
        from ringtune.shaping.slicer import slicer_flavor

        flavor = slicer_flavor(path)
    if junction != "auto":
        why = "--junction"
    elif "junction" in given:
        junction, why = given["junction"], f"the printer's [limits] junction ({printer})"
    elif fs("square_corner_velocity") == fs("square_corner_velocity"):
        junction, why = "scv", "the job sets SQUARE_CORNER_VELOCITY (Klipper)"
    elif fs("junction_deviation") == fs("junction_deviation"):
        junction, why = "jd", "the job sets M205 J (Marlin's junction deviation)"
    elif fs("jerk_x") == fs("jerk_x") or fs("jerk_y") == fs("jerk_y"):
        junction, why = "jerk", "the job sets M205 X/Y (jerk: legacy Marlin, and PrusaSlicer's own estimate)"
    elif flavor in FLAVOR_JUNCTION:
        junction = FLAVOR_JUNCTION[flavor]
        why = f"the slicer wrote the job for {flavor}"
    else:
        corner = [k for k, j in (("square_corner_velocity", "scv"), ("junction_deviation", "jd"),
                                 ("jerk", "jerk")) if k in given]
        if corner:
            junction = {"square_corner_velocity": "scv", "junction_deviation": "jd", "jerk": "jerk"}[corner[0]]
            why = f"the printer gives {corner[0]} ({printer})"
        else:
            junction = "scv"
            why = ("nothing names a rule (no printer rule, no M205 or SET_VELOCITY_LIMIT, no slicer "
                   "flavour): Klipper's, the default; --junction jd|jerk for Marlin")
    limits = replace(limits, junction=junction)
    if junction != "scv":
        limits = replace(limits, min_cruise_ratio=0.0)
    return limits, junction, why


def planned_frequencies(p, top: int) -> list[dict]:
    """The ``top`` highest planned direction-change frequencies (one per G-code line):
    [{freq_hz, line, t}], three cycles of zigzag while extruding, in planned time."""
    import numpy as np

    from ringtune.shaping.testprints import direction_change_frequencies

    tz, fz, lz = direction_change_frequencies(p)
    out, seen = [], set()
    for i in np.argsort(-fz, kind="stable"):
        if len(out) >= top:
            break
        if int(lz[i]) not in seen:
            seen.add(int(lz[i]))
            out.append({"freq_hz": float(fz[i]), "line": int(lz[i]), "t": float(tz[i])})
    return out


def commanded_frequencies(job, top: int) -> list[dict]:
    """The ``top`` highest direction-change frequencies at the G-code's commanded speeds (one per
    line): [{freq_hz, line}] (``shaping.freqlimit.commanded_frequencies``)."""
    import numpy as np

    from ringtune.shaping.freqlimit import commanded_frequencies as per_move

    f = per_move(job)
    out = []
    for i in np.argsort(-f, kind="stable")[:max(top, 0)]:
        if f[i] <= 0:
            break
        out.append({"freq_hz": float(f[i]), "line": int(job.line[i])})
    return out


def _write_trajectory(p, cfg, path, rate) -> str:
    import numpy as np

    motion = p.motion
    if cfg is not None:   # the config's shapers, changed where the job's own shaper commands stand
        from ringtune.shaping.job_shapers import shape_timeline, shaper_timeline

        motion = shape_timeline(motion, shaper_timeline(p.events, cfg))
    t, pos = motion.sample(rate)
    data = np.column_stack([t, pos[:, :4]])
    if path == "-":
        import sys

        np.savetxt(sys.stdout, data, delimiter=",", header="t,x,y,z,e", comments="", fmt="%.6f")
        return "-"
    np.savetxt(path, data, delimiter=",", header="t,x,y,z,e", comments="", fmt="%.6f")
    return str(path)
