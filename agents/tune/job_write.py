"""``tune --gcode``'s job with the choice written in (job.gcode beside best.json), rewritten in a
forked child while the report is drawn, and the summary's sentences on it."""

from __future__ import annotations

from pathlib import Path
from typing import Callable

from ringtune.envs.forked import in_background
from ringtune.envs.job_rewrite import RewrittenJob, first_layer_words, rewrite_file, shaper_words
from ringtune.envs.planned_job import resolve_job
from ringtune.hardware.dialects import shaper_commands
from ringtune.shaping.config_plan import for_firmware
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.gcode_file import binary_note


def start_job(gcode: str, out_dir: Path, config, printer) -> Callable[[], RewrittenJob | RingtuneError]:
    """Start writing ``out_dir``/job.gcode, ``gcode`` with ``config`` written in; returns the
    function that waits for it: the rewrite, or the error that kept the job from being rewritten."""
    Path(out_dir).mkdir(parents=True, exist_ok=True)
    return in_background(_rewritten, gcode, Path(out_dir), config, printer)


def _rewritten(gcode: str, out_dir: Path, config, printer) -> RewrittenJob | RingtuneError:
    try:
        parsed = resolve_job(gcode, for_firmware(printer.limits, config))[1]    # as rewrite_file reads it
        return rewrite_file(gcode, out_dir / "job.gcode", config, printer, parsed=parsed,
                            shaper_lines=shaper_commands)
    except RingtuneError as exc:
        return exc


def job_written(done: RewrittenJob | RingtuneError, gcode: str, out_dir: Path, result: dict,
                note: Callable[[str], None]) -> str:
    """Name the job (:func:`start_job`'s result) in ``result``'s files and ``job_gcode``; the
    summary's sentence on it. A job that could not be rewritten leaves the study standing: its file
    is None and a note says why."""
    if isinstance(done, RingtuneError):
        result["files"]["job"] = None
        note(f"ringtune tune: job.gcode not written: {done}")
        return ""
    result["files"]["job"] = str(out_dir / "job.gcode")
    result["job_gcode"] = {"path": str(out_dir / "job.gcode"), "lines_inserted": done.lines_inserted,
                           "print_time_as_sliced_s": done.before_s, "print_time_s": done.after_s,
                           "first_layer_kept_mm_s2": done.first_layer}
    text = (f"\nThe job with the choice written in: {out_dir / 'job.gcode'} ({done.lines_inserted} lines "
            f"inserted; planned {done.before_s:.1f} s as sliced -> {done.after_s:.1f} s, the file as the printer "
            "runs it).")
    binary = binary_note(gcode)
    if binary:
        note(f"ringtune tune: job.gcode: {binary}")
        text += f"\nNote: {binary}."
    if done.first_layer:
        note(f"ringtune tune: job.gcode: {first_layer_words(done.first_layer)}")
        text += f"\nNote: {first_layer_words(done.first_layer)}."
    if done.shaper_replaced:
        ln, was = done.shaper_replaced[0]
        said = (f"the job sets its own input shaper (line {ln}: {was}), which would replace the tuned one while it "
                f"prints; job.gcode has {shaper_words([n for n, _t in done.shaper_replaced])}")
        note(f"ringtune tune: {said}")
        text += f"\nNote: {said}."
    result["job_gcode"]["shaper_replaced"] = [{"line": n, "text": t} for n, t in done.shaper_replaced]
    if abs(done.after_s - done.config_s) > 1e-4 * done.config_s:     # the F words' rounding aside
        warn = (f"job.gcode plans at {done.after_s:.1f} s as the printer runs it, not the {done.config_s:.1f} s "
                "tune judged the choice at: a setting the file cannot carry differs (please report it)")
        note(f"ringtune tune: {warn}")
        text += f"\nWARNING: {warn}."
    return text
