"""One ``ringtune tune`` run between parsing and printing: the options checked
(:mod:`ringtune.agents.tune.request`), the search space for the printer and job, the study with its
baselines and warm start, the choice and the measured acceleration stop, the report folder and the
job rewritten with the choice. The command parses its options into a :class:`TuneRequest`, calls :func:`tune` and prints."""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from ringtune.agents.tune import feature_space, pareto, report, storage, study as tune_study, trial_screen
from ringtune.agents.tune.baselines import Baselines, baseline_configs, baselines_for, inside, warm_start
from ringtune.agents.tune.binding import binding_limits, binding_sentences
from ringtune.agents.tune.job import accel_statement, job_accel_facts, job_accel_section
from ringtune.agents.tune.job_write import job_written, start_job
from ringtune.agents.tune.motor_bound import top_speed_load_note
from ringtune.agents.tune.out_dir import check_out, remove_if_empty
from ringtune.agents.tune.choice import BASELINE_NAMES, pick, runners_up
from ringtune.agents.tune.hidden_raise import unseen_tops
from ringtune.agents.tune.laps import Laps
from ringtune.agents.tune.pareto import VISIBLE_KEYS
from ringtune.agents.tune.readme_text import readme_text
from ringtune.agents.tune.hardware_cap import held_to_ceiling
from ringtune.agents.tune.refine import refine
from ringtune.agents.tune.request import Limits, TuneRequest, check_request, shaping_min_freq
from ringtune.agents.tune.space import (CORNER_UNIT, default_space, freq_floor_note, params_from_config,
                                       unshaped_modes_note, walked_keys)
from ringtune.agents.tune.stop import Bounds
from ringtune.agents.tune.study_results import study_points
from ringtune.envs.planned_job import planned_job, resolve_printer, windows_sentence
from ringtune.envs.printer_model import unmeasured_note
from ringtune.envs.variants import TWIN_DAMPING
from ringtune.shaping.firmware import Firmware


@dataclass(frozen=True)
class Tuned:
    """A finished (or interrupted) run: the summary dict (``--json``), its text and whether Ctrl-C
    cut the study short."""

    result: dict
    text: str
    interrupted: bool


def tune(req: TuneRequest, note: Callable[[str], None] = lambda s: None, release: Callable[[], None] = lambda: None,
         progress: Callable | None = None) -> Tuned:
    """Run ``req``: the study (resumed when its storage holds one), the choice, the report folder.

    ``note``: where notes go; ``release``: called before the study runs long (notes go out live
    from then on); ``progress``: ``progress(quality, max_pe, reserve, space)`` gives an object with
    ``update(done, total, study)`` and ``close()``."""
    t_start = time.time()
    laps = Laps(t_start)
    if req.firmware is not None:
        Firmware.named(req.firmware, "--firmware")
    lim = check_request(req)
    out_dir = Path(req.out)
    check_out(out_dir)
    printer = resolve_printer(req.printer)
    fw = target_firmware(req.firmware, printer, note)
    if fw.junction_note(printer.limits.junction):
        note(f"ringtune tune: {fw.junction_note(printer.limits.junction)}")
    if unmeasured_note(printer):
        note(unmeasured_note(printer))
    quality = f"{req.quality}_mm"
    facts = job_accel_facts(printer, req.gcode, req.job_accel, fw.name)
    configs = None if req.no_baselines else baseline_configs(printer, fw.name, note=note)
    space, floor_note, why = _space(req, lim, fw.name, printer, facts, note, configs)
    laps.lap("setup_s")
    run_, settings, evaluator, bl, store = _study(req, lim, fw.name, printer, space, quality, out_dir, note,
                                                  release, progress, configs)
    laps.lap("study_s")
    baselines = bl.points
    points = study_points(run_.study, space, quality, lim.max_pe, lim.reserve, lim.max_st)
    unsplit = sum(not p.variants and not p.screened for p in points)
    if unsplit and any(b.variants for b in baselines.values()):
        note(f"ringtune tune: {unsplit} of the study's {len(points)} trials were stored without their figures on each "
             "printer variant (a study begun by an earlier ringtune): they are held to the baselines over the worst of "
             "the variants alone")
    front = pareto.pareto_front(points, also=_also(points, quality))
    choice = pick(front, baselines, lim.how, req.weight, candidates=points, why_none=unshaped_modes_note(printer, space))
    laps.lap("choice_s")
    if req.no_refine:
        stop = lift = ladder = None
        choice = dataclasses.replace(choice, sentence=(f"{choice.sentence}; taken as the study left it "
                                                       "(--no-refine: no shaper ladder, measured stop or walk "
                                                       "where nobody looks)"))
    else:
        bounds = Bounds(lim.max_pe, pareto.max_motor_load(lim.reserve), lim.max_st)
        choice, stop, lift, ladder = refine(choice, bl, evaluator, settings, printer, space, bounds, note,
                                            runners_up(choice, points, baselines), laps=laps.parts())
    laps.lap("refine_s")
    result, text, accel_json, ja_json = _report(req, lim, fw, printer, facts, space, quality, points, front, choice,
                                                (stop, lift, ladder), bl, settings, floor_note, why, out_dir, store, note)
    result.update({"stop": stop.to_dict() if stop else None,
                   "shaper_ladder": ladder.to_dict() if ladder else None, "hidden_raise": lift.to_dict() if lift else None,
                   "freq_margin": lim.margin, "refined": not req.no_refine,
                   "accel": accel_json, "job_accel": ja_json, "storage": store,
                   "study": req.study, "completed_now": run_.completed_now, "interrupted": run_.interrupted})
    laps.lap("report_s")
    result.update({"timings_s": laps.to_dict(), "elapsed_s": laps.last - t_start})
    lines = [text.rstrip("\n"), "", f"Results in {out_dir}/ — open {out_dir / 'README.txt'} first."]
    if run_.interrupted:
        lines.append(f"Interrupted after {run_.completed_before + run_.completed_now} complete trials; "
                     "run the same command again to resume.")
    return Tuned(result, "\n".join(lines), run_.interrupted)


def target_firmware(given: str | None, printer, note: Callable[[str], None] = lambda s: None,
                    who: str = "ringtune tune") -> Firmware:
    """The firmware ``tune`` (``who``: the command, for the note) writes for: ``given``
    (--firmware), else the one the printer description names in ``[current]`` (``printer
    from-klipper``/``from-marlin``/``from-rrf`` record it), else Klipper — the last two said in a
    note. ``printer``: None where there is no description (recommend from files)."""
    if given is not None:
        return Firmware.named(given, "--firmware")
    named = (getattr(printer, "current", None) or {}).get("firmware") if printer is not None else None
    if named:
        fw = Firmware.named(str(named), "[current] firmware")
        note(f"{who}: firmware {fw.name}, as the printer description's [current] names it (--firmware sets another)")
        return fw
    note(f"{who}: firmware klipper: " + ("the printer description names none ([current] firmware)"
                                                 if printer is not None else "no printer description names one")
         + "; --firmware sets it")
    return Firmware.named("klipper", "--firmware")


def _study(req: TuneRequest, lim: Limits, firmware: str, printer, space, quality: str, out_dir: Path,
           note: Callable[[str], None], release: Callable[[], None], progress: Callable | None,
           configs: Baselines | None):
    """(the study's run, its settings, evaluator, baselines (none with ``--no-baselines``), storage
    URL): the baselines (``configs``) evaluated, the search warm-started from Klipper's pick, the study
    run or resumed in ``out_dir`` (removed again when a failure leaves it empty and this run created it)."""
    created = not out_dir.exists()
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        store = req.storage or storage.default_storage(out_dir)
        settings = _settings(req, lim, firmware, quality, space, store)
        evaluator = tune_study.resolve_evaluator(settings.evaluator)
        bl = Baselines() if configs is None else baselines_for(printer, firmware, settings, evaluator, quality,
                                                                note=note, configs=configs)
        if "klipper" in bl.points:   # start the search from what users do today, and its neighbours
            settings.enqueue = _warm_points(bl, space)
            settings.screen_against = trial_screen.base_figures(bl.points["klipper"])
        tune_study.open_study(settings)   # a storage that cannot be opened fails here, its one line alone
        bar = progress(quality, lim.max_pe, lim.reserve, space) if progress else None
        release()                    # the study runs long: its notes and progress go out live
        try:
            run_ = tune_study.run_study(settings, req.workers, printer=printer, progress=bar and bar.update)
        finally:
            if bar:
                bar.close()
    except BaseException:
        if created:
            remove_if_empty(out_dir)
        raise
    return run_, settings, evaluator, bl, store


def _space(req: TuneRequest, lim: Limits, firmware: str, printer, facts, note: Callable[[str], None],
           configs: Baselines | None = None):
    """(search space, the firmware's frequency floor note or "", why per feature is searched)."""
    # no --gcode: the built-in print stands in for the user's, which may run up to the velocity limit
    min_freq = shaping_min_freq(req.shaping_min_freq)
    space = default_space(printer, firmware, accel=lim.accel_range, speed=facts.top_speed if req.gcode else None,
                          min_freq=min_freq)
    if lim.accel_range is None and configs is not None:
        space = _reaching_baselines(space, configs, note)
    space = held_to_ceiling(space, printer, req.gcode, note)
    floor_note = freq_floor_note(firmware, min_freq, space)
    if floor_note:
        note(f"ringtune tune: {floor_note}")
    # --per-feature on overrules the job's own commands (as job.gcode does): the acceleration is searched
    if (lim.accel_range is None and req.job_accel == "respect" and req.per_feature != "on" and facts.commands
            and not facts.accel_matters(space)):
        a = float(printer.limits.accel)
        space = dataclasses.replace(space, accel=(a, a), accel_basis="not searched: the job's own acceleration "
                                    "commands rule every move (--job-accel respect)")
    if req.per_feature == "on" and req.job_accel == "respect" and facts.seen_low and lim.accel_range is None:
        # the walls' acceleration reaches down to the job's own for what is seen (the baseline: as sliced)
        low = max(100.0, round(facts.seen_low, -2))
        if low < space.accel[0]:
            space = dataclasses.replace(space, accel=(low, space.accel[1]))
            note(f"ringtune tune: the walls' acceleration is searched from {low:.0f} mm/s², the lowest the job "
                 "gives what is seen, since --per-feature on overrules the job's own")
    for line in facts.notes(req.job_accel, space):
        note(f"ringtune tune: {line}")
    note(f"ringtune tune: {lim.st_source}")
    per_feature, why = feature_space.wanted(req.per_feature, space, printer, req.gcode, bool(facts.commands),
                                            req.job_accel)
    if per_feature:
        space = feature_space.feature_space(space, printer, req.gcode, lim.reserve)
    return space, floor_note, why


def _reaching_baselines(space, configs: Baselines, note: Callable[[str], None]):
    """``space`` with its acceleration range reaching down to the shaped baselines' (Klipper's pick,
    what the printer runs now), so that they, their neighbours and a walk from them per feature lie
    inside it (the range's own floor, 0.3× the printer's acceleration, can sit above Klipper's
    max_accel on a printer set fast); said in a note."""
    lows = {k: float(c.accel) for k, c in configs.configs.items()
            if k in ("klipper", "current") and c.accel and c.accel < space.accel[0]}
    if not lows:
        return space
    lo = max(100.0, math.floor(min(lows.values()) / space.accel_step) * space.accel_step)
    who = " and ".join(f"{BASELINE_NAMES.get(k, k)}'s {a:.0f}" for k, a in lows.items())
    note(f"ringtune tune: the acceleration is searched from {lo:.0f} mm/s² (not {space.accel[0]:.0f}, 0.3× the "
         f"printer's own): the range reaches down to {who} mm/s², so the search starts from {'them' if len(lows) > 1 else 'it'}")
    return dataclasses.replace(space, accel=(lo, space.accel[1]))


def _settings(req: TuneRequest, lim: Limits, firmware: str, quality: str, space, store: str):
    """The study's settings (what a resumed study must match)."""
    printer = req.printer
    if printer and Path(printer).exists():
        printer = str(Path(printer).resolve())
    return tune_study.StudySettings(
        storage=store, study_name=req.study, n_trials=req.trials, seed=req.seed, quality=quality, printer=printer,
        job=str(Path(req.gcode).resolve()) if req.gcode else None, firmware=firmware,
        backend=req.backend, evaluator=req.evaluator or tune_study.DEFAULT_EVALUATOR, space=space.to_dict(),
        max_path_error_mm=lim.max_pe, freq_margin=lim.margin, motor_reserve=lim.reserve, job_accel=req.job_accel,
        max_show_through_mm=lim.max_st)


def _warm_points(bl, space) -> list[dict]:
    """The study's first trials: Klipper's pick and its neighbours, what the printer runs now (when
    inside the space); no point twice (the walked per-feature parameters are not the study's)."""
    configs = warm_start(bl.points["klipper"].config, bl.fits, space)
    current = bl.points.get("current")
    if current is not None and inside(current.config, space):
        configs.append(current.config)
    walked = set(walked_keys(space))
    params = [{k: v for k, v in params_from_config(c, space).items() if k not in walked} for c in configs]
    unique: dict = {}
    for q in params:
        unique.setdefault(tuple(sorted(q.items())), q)
    return list(unique.values())


def _also(points, quality: str) -> tuple[str, ...]:
    """The figures the front is taken over besides print time and the quality objective: the other
    visible measures (the choice may make none worse), or path error for a custom evaluator's
    overshoot (a point with a little more overshoot and far less path error stays)."""
    keys = VISIBLE_KEYS if any("ripple_mm" in p.metrics for p in points) else ("path_error_mm",)
    return tuple(k for k in keys if k != quality)


def _report(req: TuneRequest, lim: Limits, fw: Firmware, printer, facts, space, quality: str, points, front,
            choice, stops, bl, settings, floor_note: str, why: str, out_dir: Path, store: str,
            note: Callable[[str], None]):
    """Write the report folder (and, with a job, the job with the choice written in): (summary dict,
    summary text, the ACCELERATION section's dict, the job's own accelerations' dict). ``stops``:
    (the measured stop, the raise where nobody looks, the shaper ladder), each or None."""
    stop, lift, ladder = stops
    chosen = choice.point
    accel_lines, accel_json = _accel_section(req, lim, fw.name, printer, space, points, chosen, stop)
    if ladder is not None and not space.accel_fixed:
        accel_lines.insert(1, f"  {ladder.sentence()}")
    ja_lines, ja_json = job_accel_section(facts, req.job_accel, printer, req.gcode, chosen.config)
    baseline_binding = {k: binding_limits(printer, req.gcode, b.config, fw.name, req.job_accel)
                        for k, b in bl.points.items()}
    pf_lines, pf_json = [], None
    if space.per_feature:
        pf_lines, pf_json = feature_space.feature_section(chosen.config, space)
        pf_json["why"] = why
        if lift is not None:
            pf_lines.append(f"  {lift.sentence()}")
            labels = {**{k: bl.labels.get(k, BASELINE_NAMES.get(k, k)) for k in bl.points},
                      "choice": "the choice before the walk"}
            unit = f" {CORNER_UNIT[space.junction]}" if space.junction in CORNER_UNIT else ""
            held = lift.held_lines(labels, unit) if lift.declined is None else []
            if held:
                pf_lines.append("  What holds each where it is (the next value the walk tried, measured as every "
                                "trial; µm and % the worst of the model and its twins unless said):")
                pf_lines += [f"    {line}" for line in held]
            ceiling = planned_job(printer, req.gcode, unseen_tops(chosen.config, space), job_accel=req.job_accel).print_time
            pf_lines.append(f"  {lift.ceiling_sentence(ceiling, space.hidden_min_cruise_ratio is not None)}")
            pf_json["ceiling_print_time_s"] = ceiling
            if lift.seams is not None:
                pf_lines.append(f"  {lift.seams.sentence()}")
                pf_json["seam_check"] = lift.seams.to_dict()
    ja_json["searched"] = not space.accel_fixed
    # the job with the choice written in, beside best.json: rewritten while the report is drawn
    job = start_job(req.gcode, out_dir, chosen.config, printer) if req.gcode else None
    result = report.write_report(
        out_dir, points=points, front=front, choice=choice, baselines=bl.points, quality=quality,
        printer_name=getattr(printer, "name", "printer"), job_name=Path(req.gcode).name if req.gcode else
        "built-in test print", firmware=fw.name, n_trials=req.trials, storage=store,
        study_name=req.study, command=req.command, max_path_error_mm=lim.max_pe, motor_reserve=lim.reserve,
        baseline_labels=bl.labels,
        sections=[(head, lines) for head, lines in (("ACCELERATION", accel_lines), ("PER FEATURE", pf_lines),
                                                    ("THE JOB'S OWN ACCELERATIONS", ja_lines)) if lines],
        notes=_notes(floor_note, lim.st_source, lim.margin, len(settings.enqueue)) + bl.notes
        + [f"The {n[4:]}." for n in (fw.junction_note(printer.limits.junction),) if n]
        + [f"{n[0].upper()}{n[1:]}." for n in (facts.reading_notes() if req.gcode else [])], export_firmware=fw.name,
        max_show_through_mm=lim.max_st, baseline_binding=baseline_binding,
        judged_on=windows_sentence(planned_job(printer, req.gcode, chosen.config, job_accel=req.job_accel)),
        best_extra={"job_accel": req.job_accel, "freq_margin": lim.margin, "motor_reserve": lim.reserve,
                    "max_path_error_mm": lim.max_pe,
                    "top_speed_mm_s": facts.top_speed if req.gcode else float(printer.limits.velocity),
                    **({"stop": stop.to_dict()} if stop else {})})
    text = result.pop("summary_text")
    result["per_feature"] = pf_json
    if job is not None:
        job_text = job_written(job(), req.gcode, out_dir, result, note)
        if result["files"]["job"]:         # summary.txt and README.txt name it too
            text += job_text
            with open(out_dir / "summary.txt", "a") as f:
                f.write(job_text.lstrip("\n") + "\n")
            (out_dir / "README.txt").write_text(readme_text(out_dir, fw.name, store, req.command, job=True,
                                                            per_feature=chosen.config.per_feature))
    for k, src in bl.sources.items():
        result["baselines"][k]["source"] = src
    return result, text, accel_json, ja_json


def _accel_section(req: TuneRequest, lim: Limits, firmware: str, printer, space, points, chosen, stop):
    """(lines, dict) of the report's ACCELERATION section: the chosen acceleration, what limits it
    (the measured stop, the firmware's binding limits) and, without a job, the load at top speed."""
    bindings = binding_limits(printer, req.gcode, chosen.config, firmware, req.job_accel)
    stopped = None
    if stop is not None and stop.kind != "not searched":
        stopped = (stop.sentence, stop.kind if stop.kind not in ("measure", "bound") else stop.key)
    lines, out = accel_statement(chosen, space, lim.max_pe, lim.reserve, points, printer,
                                 binding_sentences(bindings, chosen.config.accel), stopped)
    out["binding"] = [dataclasses.asdict(b) for b in bindings]
    if not req.gcode and chosen.config.accel:
        lines.append(top_speed_load_note(printer, chosen.config.accel, lim.reserve))
    return lines, out


def _notes(floor_note: str, st_source: str, margin: float, n_warm: int) -> list[str]:
    """The report's notes: the firmware's frequency floor, the show-through bound's source, the
    frequency margin, the warm start."""
    notes = [f"The {floor_note}."] if floor_note else []
    notes.append(st_source[0].upper() + st_source[1:] + ".")
    if margin:
        notes.append(f"Every figure is the worst of the printer as modelled and with all its resonances "
                     f"{margin * 100:g} % lower and higher and damping ratios ×{TWIN_DAMPING:g} (--freq-margin; `ringtune simulate --freq-margin "
                     f"{margin * 100:g}` gives the same figures).")
    else:
        notes.append("Every figure is on the exact model (--freq-margin 0).")
    if n_warm:
        notes.append("The search was warm-started from Klipper's recommendation" + (
            "." if n_warm == 1 else f" and {n_warm - 1} neighbour{'s' if n_warm > 2 else ''} of it (the rule's "
            "pick and robust shapers at its frequencies on the model's simulated test, higher accelerations)."))
    return notes
