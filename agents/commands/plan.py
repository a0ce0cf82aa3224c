"""``ringtune plan``: planned print time and move statistics of a G-code job.

JSON keys (stable): ``job`` (path or ``"built-in test print"``), ``junction`` (scv | jd | jerk),
``limits`` (the MachineLimits used, before the job's own M201/M203/M204/M205/SET_VELOCITY_LIMIT
lines, which apply from where they appear unless ``--no-job-limits``), ``print_time_s``,
``print_time``, ``moves``, ``extruding_moves``, ``lines``, ``path_length_mm``,
``time_by_feature`` ({feature: s}), ``top_frequencies`` (list of {``freq_hz``, ``line``, ``t``}:
highest direction-change frequencies while extruding, planned time, three cycles each),
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

Without --junction the rule follows --printer, or else the job's own commands
(SET_VELOCITY_LIMIT -> scv, M205 J -> jd, M205 X/Y -> jerk). Limits the job sets in its header
(M201/M203/M204/M205, SET_VELOCITY_LIMIT) override the printer's; a job's own Marlin
XY_FREQUENCY_LIMIT (M201 F<Hz> S<%>) slows its zigzags as Marlin would. When the slicer wrote
its own time estimate into the file, it is shown beside ours.

--config applies a TuneConfig's frequency limit and acceleration (its accel replaces the job's
M204/SET_VELOCITY_LIMIT accelerations); a shaper "daa" in it (or --daa F)
plans with RepRapFirmware 3.3's Dynamic Acceleration Adjustment. --trajectory writes the commanded
toolhead position t,x,y,z,e (after planning, frequency limit and the config's input shaping).

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
    from dataclasses import asdict, replace

    import numpy as np

    from ringtune.shaping.config_plan import plan_with_config
    from ringtune.shaping.errors import RingtuneError
    from ringtune.shaping.gcode import read_gcode
    from ringtune.shaping.planner import MachineLimits, guess_junction
    from ringtune.shaping.slicer import slicer_estimate
    from ringtune.shaping.testprints import builtin_test_print, direction_change_frequencies

    if args.rate <= 0 or not np.isfinite(args.rate):
        raise RingtuneError("must be a positive number of samples per second", "--rate")
    if args.top < 0:
        raise RingtuneError("must be >= 0", "--top")
    t0 = time.perf_counter()
    if args.file:
        from pathlib import Path

        if not Path(args.file).is_file():
            raise RingtuneError("no such G-code file", args.file)
        job = read_gcode(Path(args.file))
        name = args.file
    else:
        job = builtin_test_print()
        name = "built-in test print"
    t_read = time.perf_counter() - t0

    cfg = None
    if args.config:
        from ringtune.agents.commands import load_config
        cfg = load_config(args.config, out)
    if args.printer:
        from ringtune.envs.printer import load_printer
        limits = load_printer(args.printer).machine_limits()
        junction = limits.junction
    else:
        limits = MachineLimits()
        junction = guess_junction(job)
    if args.junction != "auto":
        junction = args.junction
    limits = replace(limits, junction=junction)
    if junction != "scv":
        limits = replace(limits, min_cruise_ratio=0.0)
    t1 = time.perf_counter()
    configured = plan_with_config(job, limits, cfg, use_job_limits=not args.no_job_limits, daa_freq=args.daa)
    t_plan = time.perf_counter() - t1
    p, limits, daa = configured.plan, configured.limits, configured.daa_hz
    freq_info = None if configured.freq_limit is None else asdict(configured.freq_limit)

    tz, fz, lz = direction_change_frequencies(p)
    order = np.argsort(-fz)
    top, seen = [], set()
    for i in order:
        if len(top) >= args.top:
            break
        if int(lz[i]) in seen:
            continue
        seen.add(int(lz[i]))
        top.append({"freq_hz": float(fz[i]), "line": int(lz[i]), "t": float(tz[i])})
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
        "limits": {k: v for k, v in asdict(limits).items()},
        "print_time_s": p.print_time,
        "print_time": _hms(p.print_time),
        "moves": len(p.moves),
        "extruding_moves": int(p.moves.extruding.sum()),
        "lines": job.n_lines,
        "path_length_mm": float(p.moves.length.sum()),
        "time_by_feature": p.time_by_feature(),
        "top_frequencies": top,
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
    lines = [f"{name}: {result['print_time']} ({p.print_time:.1f} s) planned with {junction}",
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
    if top:
        lines.append("  highest direction-change frequencies (3 cycles, planned):")
        for t in top:
            lines.append(f"    {t['freq_hz']:7.1f} Hz  line {t['line']}  at {t['t']:.1f} s")
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


def _write_trajectory(p, cfg, path, rate) -> str:
    import numpy as np

    motion = p.motion
    if cfg is not None:
        from ringtune.shaping.apply import shape_motion
        from ringtune.shaping.shapers import shapers_from_config

        shapers, centred = shapers_from_config(cfg)
        if any(s is not None for s in shapers.values()):
            motion = shape_motion(motion, shapers, centred)
    t, pos = motion.sample(rate)
    data = np.column_stack([t, pos[:, :4]])
    if path == "-":
        import sys

        np.savetxt(sys.stdout, data, delimiter=",", header="t,x,y,z,e", comments="", fmt="%.6f")
        return "-"
    np.savetxt(path, data, delimiter=",", header="t,x,y,z,e", comments="", fmt="%.6f")
    return str(path)
