"""``ringtune tune``: the main job — an Optuna Pareto study of print time against quality.

``--json`` keys (stable): out, trials, front_size, settled_on_model ({why: trials} of those whose
twins were not simulated: "over a bound on the model alone" | "beaten on the model alone"), quality,
max_path_error_mm, motor_reserve, max_show_through_mm, freq_margin, refined (false with --no-refine:
no ladder, stop or walk ran), resolution {distance_mm, distance_rel, time_rel, pct_abs},
chosen {config, print_time_s, quality_mm, path_error_mm, overshoot_mm, motor_load, measures (every
metrics figure: ripple_mm, ripple_p90_mm, corner_in_mm, corner_out_mm, extrusion_over_pct,
extrusion_under_pct, e_lag_mm, show_through_mm, ...), chosen_by, against (the baseline it is at least
as fast as), held_to (every baseline it has no visible measure worse than), why, rewrite_jobs (the
`ringtune limit` command every job needs, or null)}, baselines
{klipper|current|none: {config, print_time_s, quality_mm, path_error_mm, overshoot_mm, motor_load,
measures, step_loss, breaks, label, source}}, versus {baseline: {print_time_s|ripple_mm|ripple_p90_mm|
corner_in_mm|corner_out_mm|extrusion_over_pct|extrusion_under_pct|outer_wall:<the same five>: {value,
baseline (each the worst over the printer and its twins), verdict better|same|worse (worse where worse on any
of them), and where the verdict comes from one twin only: on [freq factor, damping factor], value_there,
baseline_there}}}, stop (null, or the measured stop: {kind measure|bound|ceiling|time|budget|not
searched, key (a job's figure, or a class's own as "outer_wall:ripple_mm"), baseline (whose value it exceeds,
for a measure), value, baseline_value, variant (null, or the [freq factor, damping factor] of the printer
variant those two values are of), accel (the step that stops it, mm/s²), config, moved,
from_accel, to_accel, evaluations, sentence}), shaper_ladder (null, or each shaper of Klipper's rule
climbing the accelerations: {moved, from_accel, to_accel, config, evaluations, screened, offered,
tried [{shaping, highest_passing_accel}], sentence}), hidden_raise (null, or the walk raising the features nobody
sees: {raised [{parameter, from, to}], from_print_time_s, to_print_time_s, evaluations, screened (on the
exact model first), budget (the study's
trials), cut (it stopped at that budget), sentence, held [{parameter, value, top, tried (the next value tried,
null at its top), kind (measure|bound|time), key, baseline, measured, limit, variant (as the stop's),
screened (seen on the exact model alone)}]: what holds each setting walked}), vs_baselines {key: {baseline, faster_s, faster_pct, better_mm,
better_pct, dominates, metrics {print_time_s|every visible measure|feasible: better|same|worse},
path_error_better_mm, path_error_better_pct}}, dominates_klipper, dominates_current (null or {config,
print_time_s, quality_mm, ...comparison}), accel {range, searched, basis, chosen, stopped_by,
headroom, defaults (what of the motor bound is a default: "x.mass", "y.motor", ...; [] when none),
binding (the firmware limits that hold some moves of the chosen configuration lower: list of {name
(the firmware's own: "M201 X", "max_y_accel", "M204 R"), value (mm/s²), what, moves, time_s,
time_without_s (the planner with that limit removed)})},
job_accel {mode, commands, cap_mm_s2, searched, print_time_as_sliced_s, print_time_replaced_s,
replaced_accel, saved_s}, per_feature (null when not searched, else {accel {visible|top_surface|
hidden_walls|infill|solid_infill|travel: mm/s²}, ranges {group: {top_speed_mm_s, range, basis}}, corner, junction,
min_cruise_ratio, why (why it was searched), ceiling_print_time_s, seam_check (null, or the walk's end
judged at every seam of what is seen: {seams, held, taken_back, failure, print_time_s, simulated,
outer_wall_worst_mm {figure: {walk_end, walk_start, windows}}, sentence})}),
judged_on (where the measures are taken: the job's quality windows, in words), plot_arrows,
files {readme, summary, plot, best, apply, front, trials, job (with --gcode: the rewritten job)},
job_gcode (with --gcode, where the file was written:
{path, lines_inserted, print_time_as_sliced_s, print_time_s (as the printer runs the file), first_layer_kept_mm_s2}),
storage, study, completed_now, interrupted, elapsed_s, timings_s (wall-clock s of each step, summing to
elapsed_s: setup_s, study_s, choice_s, refine_s, report_s, and refine_parts {wider_check_s,
shaper_ladder_s, measured_stop_s, walk_s, seam_check_s: those that ran}).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time

from tqdm import tqdm

from ringtune.agents.cli.common import GCODE_JOB_HELP, firmware_name, gcode_job, progress_interval
from ringtune.agents.tune.pareto import pareto_front
from ringtune.agents.tune.study_results import study_points
from ringtune.agents.tune.request import TuneRequest
from ringtune.agents.tune.tuning import tune
from ringtune.shaping.builtin_jobs import BUILTIN_JOBS, job_path

NAME = "tune"
DESCRIPTION = """\
Tune input shaping for a printer and a job: an Optuna multi-objective study over the shaper types
the target firmware offers, the shaper frequency F per axis (one F on RepRapFirmware), the damping
S, the infill frequency limit and its method, and the acceleration. Each trial is simulated; a
configuration is ruled out when it loses steps, when its nozzle leaves the path by more than
--max-path-error (0.1 mm by default: heavy smoothing cuts corners inwards, which overshoot alone
would not see), or when it asks a motor for more than 1 − --motor-reserve of the force it has at
its speed (80 %: modelling error must not become skipped steps). Every configuration is judged on
the printer and on the printer with all resonances --freq-margin per cent lower and higher
(default 5) and every damping ratio ×0.75: the worst counts, because a real printer's
frequencies drift and a damping ratio fitted to a resonance test is less certain still (Klipper
judges its shapers over dampings 0.075–0.15 for the same reason).

The acceleration is searched up to where the weakest motor would need all its force at the job's
top speed (from the printer's motors and moving masses; --accel-range LO,HI overrides), from 0.3×
the printer's own acceleration, or lower to reach Klipper's pick and what the printer runs now. The
firmware's max_accel does not cap it (the tuned value is what you set as max_accel); a per-axis cap
(max_y_accel, M201 Y) still limits that axis's moves, in every trial alike. A job that
sets its own accelerations (M201/M204, SET_VELOCITY_LIMIT) keeps them with --job-accel respect (the
default: the print as sliced; the acceleration is then not searched where it has no effect); with
--job-accel replace the tuned acceleration replaces them (what re-slicing would give), and the
summary gives both print times.

Per feature (--per-feature, default auto: on when the acceleration is searched and the job has
features nobody sees, unless --job-accel respect keeps the job's own accelerations): the visible
walls (outer walls, overhangs, unlabelled moves) take the main acceleration, which the study
searches with the shapers as it would without per-feature settings. From its choice, each other
group (infill with support, internal solid infill, travel, then the inner walls and the top
surfaces) is walked up toward the top of its range, where the weakest motor keeps its reserve at
that group's own top speed; then the corner rule (Klipper's square_corner_velocity, Marlin's
junction deviation or jerk, RRF's M566) and Klipper's minimum_cruise_ratio, for the job and apart
for the corners nobody sees (infill, support and travel; solid infill's apart, its extrusion being
judged as seen): each step judged as every
trial, kept only with no visible measure worse than the baselines' or than the choice's own before
the walk, on the judged printers and on wider ones (it spends no visible quality). The summary
says what holds each setting where it stays (measured at the next value tried) and the walk's
ceiling: the planned time with every setting nobody sees at its top, no quality judged. A walk
that ends less than 0.5 % faster than it started (the same time, by the summary's resolution) is
not taken: it would load the motors for nothing. One shaper configuration serves the whole job.
With --gcode, job.gcode beside best.json is the job with the choice written in (as `ringtune
rewrite` writes it).

Baselines: Klipper's rule — the recommendation recorded from your resonance files by `ringtune
identify` when the printer has one, else the rule on the model's simulated resonance test (said so);
where at the rule's max_accel (a ceiling set by smoothing alone) its pick loses steps, runs the
motors over their reserve or has more path error than the bound, the pick at the highest
acceleration found within them (said so); what the printer runs now, when the printer description
has a [current] section; no shaping.
Objectives: print time, the worst visible wall's ripple and corner deviation (rounding or
overshoot); hidden features reaching the outer wall by more than --max-show-through are ruled out.
The configuration chosen by default is the fastest one with no visible measure (ripple and its 90th
percentile, corner rounding and overshoot, over- and under-extrusion) worse than the best baseline's
("same quality, faster"); the baselines are candidates too, so where the study tried none as fast at
their quality the choice is the baseline itself, and what follows climbs from it (the knee of the
front only without a usable baseline; --pick knee|fastest-at-baseline-quality|weight, --weight W).
Then each shaper Klipper's rule fits climbs higher accelerations at its frequency and above,
designed for more damping (the shaper ladder: the rule's max_accel, measured), and the fastest that
keeps every measure becomes the choice. Then its acceleration is stepped up 5 % at a time with the
same judgement until a measure gets worse or a bound binds (the summary names it, with both values);
where the ladder and the stop together end less than 0.5 % faster than the study's choice (the same
time), neither is taken and the summary says where they ended.
The study's choice, the ladder, the stop and the walk also simulate what they take on three printers
further off the model than the twins (resonances ×0.85, ×1 and ×1.15 at half the damping), each
alone: what is worse there than the baselines is not taken (the study's choice gives way to a slower
study point that holds there, or to the baseline), since a step that only rides the twins'
resolution ripples more on a printer a little further off. Differences under 1 µm or 5 % of a
distance, 1 point or 5 % of extrusion and 0.5 % of print time count as the same. --no-refine takes
the study's choice as the study left it, with none of the ladder, the stop or the walk: what the
search alone finds (the same folder without it later resumes the study and runs them).

With no arguments it tunes the built-in Ender-3-class printer on the built-in test print into
./ringtune-out/ in about a minute; open ringtune-out/README.txt first. Running the same command
again resumes the study (also after Ctrl-C or a crash); --trials N extends it to N trials.
Progress goes to stderr: a bar on a terminal, else a line every 10 s (RINGTUNE_PROGRESS_S=N sets it).

examples:
  ringtune tune
  ringtune tune --printer my-printer.toml --gcode benchy.gcode --firmware rrf --trials 400 --workers 2
  ringtune tune --gcode tower.gcode --job-accel replace      # what re-slicing at a tuned accel gives
  ringtune tune --gcode part.gcode --per-feature on          # writes tuned/job.gcode with the choice in it
  ringtune tune --storage postgresql+psycopg2://user:pw@db-host/ringtune --study ender3 --workers 4
"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--printer", metavar="P", help="printer TOML (default: the embedded Ender-3-class printer)")
    p.add_argument("--gcode", metavar="G", type=gcode_job,
                   help=f"G-code job, {GCODE_JOB_HELP} (default: the built-in test print)")
    p.add_argument("--firmware", type=firmware_name, default=None,
                   help="target firmware: klipper, kalico, rrf, rrf35, rrf34, marlin, marlin-ftm, prusa (any "
                   "case); default: the one the printer description names ([current] firmware, as `ringtune "
                   "printer from-klipper|from-marlin|from-rrf` writes it), else klipper")
    p.add_argument("--trials", type=int, default=200, help="total complete trials of the study (default 200)")
    p.add_argument("--storage", metavar="URL", help="Optuna storage: journal:PATH (default "
                   "journal:OUT/study.journal), sqlite:///file.db, postgresql+psycopg2://user:pw@host/db")
    p.add_argument("--study", default="ringtune", metavar="NAME", help="study name in the storage (default ringtune)")
    p.add_argument("--workers", type=int, default=1, help="local worker processes (default 1); they run "
                   "in step, so a seeded run reproduces exactly with the same --workers (2 on 2 cores: "
                   "about two thirds of the wall time)")
    p.add_argument("--seed", type=int, default=0, help="sampler seed (default 0)")
    p.add_argument("-o", "--out", default="ringtune-out", metavar="DIR", help="output folder (default ringtune-out)")
    p.add_argument("--pick", choices=("fastest-at-baseline-quality", "knee", "weight"), default=None,
                   help="which front point to choose: the fastest with no worse quality than the best baseline "
                        "(default), the knee, or the one minimising print time + W × error (--weight)")
    p.add_argument("--weight", type=float, default=None, metavar="W",
                   help="with --pick weight (implied): seconds of print time worth 1 mm less error")
    p.add_argument("--quality", choices=("ripple", "overshoot", "path_error"), default="ripple",
                   help="the study's second objective besides print time and corner deviation: ripple_mm "
                        "(default: the worst visible wall's peak-to-peak), overshoot_mm or path_error_mm; the "
                        "choice judges every visible measure whichever it is")
    p.add_argument("--max-show-through", type=float, default=None, metavar="MM",
                   help="rule out configurations whose hidden features (infill, inner walls) reach the outer wall "
                        "by more than MM (default: the job's own gap between infill and outer wall where the job states "
                        "its perimeters, widths and infill overlap (PrusaSlicer family), else 0.05; 0 = no bound)")
    p.add_argument("--max-path-error", type=float, default=None, metavar="MM",
                   help="rule out configurations whose path error (corner rounding, overshoot and ringing) "
                        "exceeds MM (default 0.1; 0 = no bound)")
    p.add_argument("--motor-reserve", type=float, default=None, metavar="PCT",
                   help="rule out configurations that ask a motor for more than 100 − PCT %% of the force it "
                        "has at its speed (default 20; 0 = no bound)")
    p.add_argument("--freq-margin", type=float, default=None, metavar="PCT",
                   help="also judge every configuration with the printer's resonances PCT %% lower and "
                        "higher; the worst counts (default 5; 0 = the exact model only)")
    p.add_argument("--shaping-min-freq", metavar="HZ", type=float, default=None,
                   help="Marlin classic: your build's SHAPING_MIN_FREQ (default: a stock build's 40 Hz, the "
                        "lower of SHAPING_FREQ_X/Y); the search stays above it")
    p.add_argument("--accel-range", metavar="LO,HI", default=None,
                   help="acceleration search range, mm/s² (default: from the printer's motors and masses at the "
                        "job's top speed); LO = HI fixes it")
    p.add_argument("--job-accel", choices=("respect", "replace"), default="respect",
                   help="a job's own M201/M204/SET_VELOCITY_LIMIT accelerations: respect them (default, the "
                        "print as sliced) or replace them by the tuned acceleration (what re-slicing would give)")
    p.add_argument("--per-feature", choices=("auto", "on", "off"), default="auto",
                   help="an acceleration per feature group (infill, solid infill, travel, inner walls, top "
                        "surfaces; the visible walls take the main one), the corner rule and minimum_cruise_ratio, "
                        "and apart for the corners nobody sees (solid infill's on their own), walked up from the study's choice as far as every "
                        "visible measure stays the choice's own (default auto: when the acceleration is searched and the job has "
                        "features nobody sees)")
    p.add_argument("--backend", choices=("mujoco", "lti"), default="mujoco", help="physics (default mujoco)")
    p.add_argument("--evaluator", metavar="MODULE:FUNC", default=None,
                   help="advanced: score configs with your own f(configs, printer, job) -> metrics")
    p.add_argument("--no-baselines", action="store_true", help="skip the baselines (Klipper's rule, what the "
                   "printer runs now, no shaping)")
    p.add_argument("--no-refine", action="store_true",
                   help="take the study's choice as the study left it: no shaper ladder, measured stop or walk "
                        "where nobody looks after it (what the search alone finds, for a study of what they add; "
                        "quicker on a long job)")


def run(args: argparse.Namespace, out) -> int:
    request = TuneRequest(**{f.name: getattr(args, f.name) for f in dataclasses.fields(TuneRequest)
                             if f.name != "command"}, command=command_line(args))
    tuned = tune(request, note=out.note, release=out.release, progress=Progress)
    out.emit(tuned.result, tuned.text)
    return 130 if tuned.interrupted else 0


class Progress:
    """Progress on stderr only: a tqdm bar on a terminal; otherwise (logs, CI, nohup) a line every
    :func:`~ringtune.agents.cli.common.progress_interval` seconds with the trials done and the best so far."""

    def __init__(self, quality: str, max_pe: float, reserve: float, space, stream=None):
        self.stream = stream or sys.stderr
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.interval = progress_interval()
        self.quality, self.max_pe, self.reserve, self.space = quality, max_pe, reserve, space
        self._bar = None
        self._t0 = self._last = time.time()
        self._done = -1

    def update(self, done: int, total: int, study=None) -> None:
        if self.tty:
            if self._bar is None:
                tqdm.monitor_interval = 0      # no monitor thread: the study's workers fork from this process
                self._bar = tqdm(total=total, initial=min(done, total), desc="trials", unit="trial",
                                 file=self.stream, dynamic_ncols=True)
            delta = min(done, total) - self._bar.n
            if delta > 0:
                self._bar.update(delta)
            return
        now = time.time()
        if now - self._last >= self.interval or (self._done < 0 and done > 0):
            self._last = now
            self._done = done
            print(f"ringtune tune: {done}/{total} trials, {now - self._t0:.0f} s; {self._best(study)}",
                  file=self.stream, flush=True)

    def _best(self, study) -> str:
        if study is None:
            return "no trial yet"
        try:
            front = pareto_front(study_points(study, self.space, self.quality, self.max_pe, self.reserve))
        except Exception:   # progress never stops a study
            return "best so far: unknown"
        if not front:
            return "no feasible configuration yet"
        f = front[0]
        q = min(front, key=lambda p: p.quality_mm)
        word = {"overshoot_mm": "overshoot", "ripple_mm": "ripple"}.get(self.quality, "path error")
        return (f"best so far: fastest feasible {f.print_time_s:.2f} s at {f.quality_mm * 1000:.1f} µm {word}, "
                f"lowest {word} {q.quality_mm * 1000:.1f} µm at {q.print_time_s:.2f} s ({len(front)} on the front)")

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()


#: each option's default: the request's own (every field of TuneRequest but the command line)
_DEFAULTS = {f.name: f.default for f in dataclasses.fields(TuneRequest) if f.name != "command"}


def command_line(args) -> str:
    """The command that reproduces (and resumes) this run: every option given that differs from its
    default, --trials included."""
    parts = ["ringtune tune"]
    for opt, default in _DEFAULTS.items():
        v = getattr(args, opt, default)
        if v == default or v is None:
            continue
        flag = "--" + opt.replace("_", "-")
        if v is True:
            parts.append(flag)
        else:
            text = _builtin_name(str(v)) if opt == "gcode" else str(v)
            parts.append(f"{flag} {text!r}" if " " in text else f"{flag} {text}")
    return " ".join(parts)


def _builtin_name(path: str) -> str:
    """A built-in job by its name (``part``), as the user gave it; any other job as its path."""
    return next((name for name in BUILTIN_JOBS if str(job_path(name)) == path), path)
