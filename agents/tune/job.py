"""What ``ringtune tune`` says about acceleration: the job's own acceleration commands, the print
times with them and without them, and which limit stops the chosen acceleration.

A sliced job often sets its own accelerations (Marlin ``M201``/``M204``, Klipper
``SET_VELOCITY_LIMIT``, per-feature ``M204``). With ``--job-accel respect`` they stand (the print as
sliced) and the tuned acceleration only rules where the job sets none — where it has no effect it
is not searched; with ``--job-accel replace`` the tuned acceleration replaces them (what
re-slicing at it, with the machine limits raised to it, would give). Print times here come from
the planner alone (no physics), through :func:`ringtune.envs.planned_job.planned_job`.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ringtune.agents.tune.pareto import DEFAULT_RESOLUTION, Point
from ringtune.agents.tune.motor_bound import defaults_note
from ringtune.envs.planned_job import job_accel_commands, planned_job, resolve_job
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.config_plan import as_read_by, for_firmware
from ringtune.shaping.features import FEATURE_CLASSES, LABELLED_VISIBLE, class_indices
from ringtune.shaping.reading_notes import reading_notes
from ringtune.shaping.layers import layer_starts

#: how the job's acceleration settings are written in G-code: command -> (setting, its word)
GCODE_WORDS = {"M201": (("max_accel_x", "X"), ("max_accel_y", "Y")),
               "M204": (("accel_print", "P"), ("accel_travel", "T"), ("accel_retract", "R")),
               "SET_VELOCITY_LIMIT": (("limited_accel_x", "X_ACCEL="), ("limited_accel_y", "Y_ACCEL="))}

@dataclass
class JobAccelFacts:
    """The job's own acceleration commands, as ``firmware`` reads them (None: as the printer's own
    does, ``[current] firmware``), and its top speed (mm/s)."""

    printer: Any
    job: Any
    firmware: str | None = None
    commands: dict = field(default_factory=dict)     # setting -> largest value set, mm/s²
    top_speed: float = 0.0
    cap: float | None = None                         # mm/s²: the largest acceleration the job lets any move have
    seen_low: float | None = None                    # mm/s²: the lowest its commands give a seen wall or surface
    #                                                  above the first layer (whose own the slicer sets for adhesion)

    @property
    def limits(self):
        """The printer's limits as the firmware reads a job (:func:`ringtune.shaping.config_plan.for_firmware`)."""
        return for_firmware(self.printer.limits, as_read_by(self.firmware))

    def time(self, config: TuneConfig, mode: str) -> float:
        """Planned time under ``mode``; ``respect`` is the job as sliced, so a per-feature
        configuration's own accelerations and corner rule are left out there."""
        if mode == "respect" and config.per_feature:
            config = config.without_per_feature()
        return planned_job(self.printer, self.job, config, job_accel=mode).print_time

    def accel_matters(self, space) -> bool:
        """Whether the acceleration changes the print time beyond the resolution under ``respect``
        over the space's range."""
        lo, hi = (TuneConfig(firmware=self.firmware or "klipper", accel=float(a)) for a in space.accel)
        t_lo, t_hi = self.time(lo, "respect"), self.time(hi, "respect")
        return abs(t_lo - t_hi) > DEFAULT_RESOLUTION.time_rel * max(t_lo, t_hi)

    def described(self) -> str:
        """The commands as G-code would write them (largest value of each), e.g.
        ``M201 X1500 Y1500, M204 P1500 T1500 R1000``; Klipper's own where no M204 word is set."""
        c = self.commands
        words = {cmd: "".join(f" {w}{c[k]:.0f}" for k, w in pairs if k in c) for cmd, pairs in GCODE_WORDS.items()}
        parts = [cmd + said for cmd, said in words.items() if said]
        if "accel_klipper" in c and not words["M204"]:
            parts.append(f"SET_VELOCITY_LIMIT ACCEL={c['accel_klipper']:.0f} (or M204 S)")
        return ", ".join(parts)

    def reading_notes(self) -> list[str]:
        """What the printer does otherwise than the job reads, and what the job leaves unjudged
        (:func:`ringtune.shaping.reading_notes.reading_notes`)."""
        return reading_notes(resolve_job(self.job)[1], self.limits, self.firmware)

    def notes(self, mode: str, space) -> list[str]:
        """What the job's own acceleration commands do under ``mode``; first, what the printer does
        otherwise than the job reads (:meth:`reading_notes`: the limit lines and macros under Klipper's
        reading, the firmware retractions)."""
        out = self.reading_notes()
        if not self.commands:
            return out
        head = f"the job sets its own accelerations ({self.described()}, mm/s²)" + (
            f": the file caps acceleration at {self.cap:.0f} mm/s²" if self.cap else "")
        if mode == "respect":
            tail = ("; --job-accel respect: they stand (the print as sliced)" +
                    ("; the acceleration has no effect and is not searched" if space.accel_fixed else "")
                    + ". --job-accel replace tunes the acceleration that re-slicing would use.")
        else:
            tail = "; --job-accel replace: the tuned acceleration replaces them (what re-slicing would give)."
        return out + [head + tail]


def job_accel_facts(printer, job, mode: str, firmware: str | None = None) -> JobAccelFacts:
    """The job's acceleration commands, its top speed (the largest speed a move asks for after the
    velocity limits, mm/s; under ``respect`` the job's own limits count; ``tune`` uses the printer's
    velocity limit instead when no job is given) and the acceleration cap those commands put on it
    (under ``respect``, planned at a very high machine acceleration). ``firmware``: the one tune
    writes for, whose reading of the job's commands counts (None: the printer's own)."""
    _, parsed = resolve_job(job, for_firmware(printer.limits, as_read_by(firmware)))   # as the plan reads it
    facts = JobAccelFacts(printer, job, firmware)
    facts.commands = job_accel_commands(parsed, facts.limits)
    pj = planned_job(printer, job, as_read_by(firmware))
    m = pj.plan.moves
    xy = np.hypot(*(m.end - m.start)[:, :2].T) > 0
    facts.top_speed = float(m.v_nominal[xy].max()) if xy.any() else float(printer.limits.velocity)
    if facts.commands:   # moves under one of the job's own acceleration commands, planned without a machine cap
        ruled = np.zeros(len(xy), bool)
        for k in facts.commands:
            ruled |= ~np.isnan(parsed.setting(k))
        far = planned_job(printer, job, TuneConfig(firmware=firmware or "klipper", accel=1e6),
                          job_accel="respect").plan.moves
        sel = xy & ruled
        facts.cap = float(far.accel[sel].max()) if sel.any() else None
        seen = sel & far.extruding & np.isin(class_indices(list(far.features))[far.feature],
                                             [FEATURE_CLASSES.index(c) for c in LABELLED_VISIBLE])
        starts = layer_starts(parsed)
        if len(starts) >= 2:
            seen[starts[0]:starts[1]] = False          # the first layer aside
        facts.seen_low = float(far.accel[seen].min()) if seen.any() else None
    return facts


def job_accel_section(facts: JobAccelFacts, mode: str, printer, job, chosen: TuneConfig) -> tuple[list[str], dict]:
    """Summary lines and JSON for the job's own accelerations: both print times of the chosen
    configuration (as sliced; with the job's accelerations replaced by the chosen one)."""
    info = {"mode": mode, "commands": dict(facts.commands), "cap_mm_s2": facts.cap, "searched": None,
            "print_time_as_sliced_s": None, "print_time_replaced_s": None, "replaced_accel": chosen.accel,
            "saved_s": None}
    if not facts.commands:
        return [], info
    sliced = facts.time(chosen, "respect")
    replaced = facts.time(chosen, "replace")
    saved = sliced - replaced
    info.update(print_time_as_sliced_s=sliced, print_time_replaced_s=replaced, saved_s=saved)
    lines = [f"The job sets its own accelerations ({facts.described()}, mm/s²)"
             + (f": the file caps acceleration at {facts.cap:.0f} mm/s²." if facts.cap else ".")]
    pct = 100.0 * saved / sliced if sliced else 0.0
    if mode == "respect":
        lines.append(f"--job-accel respect (the print as sliced): chosen configuration {sliced:.1f} s.")
        lines.append(f"With the job's accelerations replaced by {chosen.accel:.0f} mm/s² (re-slicing): {replaced:.1f} s, "
                     f"{saved:.1f} s ({pct:.1f} %) less — print time only, quality not judged at it here; "
                     "--job-accel replace tunes that acceleration.")
    else:
        lines.append(f"--job-accel replace: the chosen {chosen.accel:.0f} mm/s² replaces them: {replaced:.1f} s; "
                     f"as sliced (the job's own accelerations, same shaper): {sliced:.1f} s.")
        lines.append(f"Re-slicing at {chosen.accel:.0f} mm/s² (print and travel accelerations, and the machine "
                     f"limits M201 raised to it) would save {saved:.1f} s ({pct:.1f} %).")
    return lines, info


def accel_statement(chosen: Point, space, max_pe: float, reserve: float, points,
                    printer=None, binding: list[str] = (), measured: tuple[str, str] | None = None
                    ) -> tuple[list[str], dict]:
    """Which limit stops the chosen acceleration and how far it is from it: the motor reserve,
    the path-error bound, the range's edge (the motors' force, or ``--accel-range``), or none of
    them (then the choice of quality stops it). ``binding``: the firmware limits that hold some
    moves lower (:func:`ringtune.agents.tune.binding.binding_sentences`). With ``printer``: whether
    the motor bound rests on defaults. ``measured``: (sentence, what) of the measured stop
    (:mod:`ringtune.agents.tune.stop`), which then replaces the bounds' inference."""
    a = float(chosen.config.accel or 0.0)
    lo, hi = space.accel
    info = {"range": [lo, hi], "searched": not space.accel_fixed, "basis": space.accel_basis, "chosen": a,
            "stopped_by": None, "headroom": {}, "defaults": []}
    tail = list(binding)
    note = defaults_note(printer)
    if note:
        tail.append(note)
        info["defaults"] = list(printer.defaulted)
    if space.accel_fixed:
        info["stopped_by"] = "not searched"
        return [f"{a:.0f} mm/s², {space.accel_basis}."] + tail, info
    cands = _accel_bounds(chosen, space, max_pe, reserve, info["headroom"])
    name, ratio, text = max(cands, key=lambda c: c[1])
    lines = [f"Chosen {a:.0f} mm/s² (searched {lo:.0f}–{hi:.0f})."]
    if measured is not None:
        info["stopped_by"] = measured[1]
        lines.append(measured[0])
        ratio = 0.0                     # every bound's room is said below
    elif ratio >= 0.9:
        info["stopped_by"] = name
        lines.append(f"Stopped by the {name}: {text}.")
    else:
        info["stopped_by"] = "quality"
        lines.append("No bound is within 10 % of it: what stops it is quality — the faster front points have more "
                     "overshoot or path error than the choice allows.")
    lines += [f"  {LISTED_AS.get(n, '')}{t}" for n, r, t in cands if n != name or ratio < 0.9]
    return lines + _faster_trials(points, a) + tail, info


#: how a bound's line starts where the bounds are listed (the other bounds' words begin with their name)
LISTED_AS = {"range edge": "range edge: "}


def _accel_bounds(chosen: Point, space, max_pe: float, reserve: float, headroom: dict) -> list[tuple]:
    """[(bound, how near the choice is to it (1 = on it), in words)] for the motor reserve, the
    path-error bound and the range's edge; each one's free room goes into ``headroom``."""
    a = float(chosen.config.accel or 0.0)
    hi = space.accel[1]
    cands = []
    load = chosen.metrics.get("motor_load")
    if reserve > 0 and load:
        cap = 1.0 - reserve
        cands.append(("motor reserve", load / cap, f"motor load {load * 100:.0f} % of the force the motors have at "
                      f"their speed; the reserve allows {cap * 100:.0f} % ({_points((cap - load) * 100)} free)"))
        headroom["motor_load"] = cap - load
    pe = chosen.metrics.get("path_error_mm")
    if max_pe > 0 and pe is not None:
        cands.append(("path error", pe / max_pe, f"path error {pe * 1000:.1f} µm of the {max_pe * 1000:g} µm bound "
                      f"({(max_pe - pe) * 1000:.1f} µm free)"))
        headroom["path_error_mm"] = max_pe - pe
    cands.append(("range edge", a / hi, f"{hi:.0f} mm/s² ({space.accel_basis})"
                  + ("; the choice is on it" if hi - a < 0.5 else f", {hi - a:.0f} mm/s² above the choice")))
    headroom["accel_mm_s2"] = hi - a
    return cands


#: why a faster trial was not chosen, the first that applies: (in words, test)
HELD_BACK = (("lose steps", lambda p: p.step_loss), ("exceed the path-error bound", lambda p: p.too_rough),
             ("break the motor reserve", lambda p: p.overloaded))


def _faster_trials(points, a: float) -> list[str]:
    """What held back the trials at a higher acceleration than ``a`` mm/s², in one sentence (or none)."""
    faster = [p for p in points if (p.config.accel or 0) > a]
    why = Counter(next((words for words, test in HELD_BACK if test(p)), None) for p in faster)
    said = ", ".join(f"{why[words]} {words}" for words, _ in HELD_BACK if why[words])
    return [f"Of the {len(faster)} trials at a higher acceleration, {said}."] if said else []


def _points(pct: float) -> str:
    """``"1 point"``, ``"66 points"``: a number of percentage points, rounded, in words."""
    n = round(pct)
    return f"{n:.0f} point" + ("" if n == 1 else "s")
