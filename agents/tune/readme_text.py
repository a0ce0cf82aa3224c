"""README.txt of ``ringtune tune``'s output folder: what each file is and which to open first."""

from __future__ import annotations

from pathlib import Path

from ringtune.shaping.firmware import FIRMWARES


def _push_hint(best: Path, firmware: str) -> str:
    """The push command for ``firmware``: Klipper is reached through its host (its pseudo-tty, or
    Moonraker), never the MCU's USB line that /dev/ttyUSB0 is on a Klipper machine."""
    if FIRMWARES[firmware].family == "klipper":
        return (f"ringtune push {best} --firmware {firmware} --port ~/printer_data/comms/klippy.serial\n"
                f"                     (Klipper's pty, on the Klipper host; or --moonraker http://HOST:7125)")
    return f"ringtune push {best} --port /dev/ttyUSB0 --firmware {firmware}   (the printer's serial port)"


def _job_entry(out_dir: Path, per_feature: bool) -> str:
    """README.txt's entry for job.gcode (tune --gcode): the job with the choice written in."""
    what = ("""the accelerations and corner rules
                 per feature at each feature change, which a firmware cannot hold (apply.txt
                 alone prints every feature at the visible walls' acceleration), and the shaper"""
            if per_feature else "the shaper and the acceleration")
    best = out_dir / "best.json"
    return f"""6. job.gcode     Your job with the chosen configuration written in: {what}.
                 Print this file; summary.txt gives its planned time as sliced and as written.
                 Another job: ringtune rewrite JOB --config {best} -o OUT
                 or re-slice: ringtune export {best} --slicer prusaslicer|orcaslicer|cura
"""


def readme_text(out_dir: Path, firmware: str, storage: str, command: str, job: bool = False,
                per_feature: bool = False) -> str:
    """README.txt of the output folder: what each file is, which to open first, how to resume.
    ``job``: tune was given a job, and writes it with the choice (job.gcode); ``per_feature``: the
    choice sets accelerations or corner rules per feature."""
    return f"""ringtune tune results — start here
=================================

1. summary.txt   The answer: the chosen input-shaping configuration, and how it compares with
                 Klipper's own rule, with what the printer runs now (when known) and with no
                 shaping on the same printer and job: every visible measure (wall ripple, corner
                 rounding and overshoot, over- and under-extrusion) with both values and the
                 verdict better / same / worse. Then how far each shaper of Klipper's rule
                 climbed (the shaper ladder), what stops the acceleration (measured one step
                 higher), and the whole trade-off (the Pareto front) as a table.
2. pareto.png    The trade-off as a picture: print time (s) against the measures a person sees;
                 every trial, the best trade-offs, the chosen point and the baselines (Klipper's
                 rule, what the printer runs now, no shaping), ruled-out trials marked; its legend
                 says which mark is which. Lower-left is better.
3. apply.txt     The exact {firmware} lines that put the chosen configuration on the printer.
                 Or: ringtune export {out_dir / 'best.json'} --firmware {firmware}
                     {_push_hint(out_dir / 'best.json', firmware)}
4. best.json     The chosen configuration (TuneConfig) for ringtune simulate / export / push.
5. front.csv, trials.csv   Every point of the front and every trial, for your own analysis.
{_job_entry(out_dir, per_feature) if job else ""}
To pick another point of the front: rerun with --pick knee, or --weight W (seconds of print time
you would give for 1 mm less error; e.g. --weight 100). The study itself is kept in {storage}:
running the same command again resumes it with nothing lost:
  {command}
(--trials N extends it to N trials).
"""
