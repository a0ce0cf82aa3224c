"""The output folder of ``ringtune tune``: what a person opens after a study.

Files (all in ``out_dir``):

- ``README.txt``   — what each file is and which to open first;
- ``summary.txt``  — the chosen configuration and why, how it compares with each baseline (Klipper's
  rule, what the printer runs now, no shaping: every visible measure — ripple, corners, extrusion —
  with both values and the verdict better / same / worse at the resolution of
  :class:`ringtune.agents.tune.pareto.Resolution`, :mod:`ringtune.agents.tune.versus`), what stops
  the acceleration (measured, :mod:`ringtune.agents.tune.stop`), the job's own accelerations, and
  the Pareto front as a table;
- ``pareto.png``   — print time (s) against overshoot and against path error (mm): every trial
  (ruled-out ones too; off-scale ones as counted arrows), the front, the chosen point, the
  baselines (marked when they break a bound) and the point dominating a baseline
  (:mod:`ringtune.agents.tune.pareto_plot`);
- ``best.json``    — the chosen TuneConfig (for ``ringtune export``/``push``/``simulate``);
- ``apply.txt``    — the exact firmware lines that apply it (``hardware.dialects``);
- ``front.csv``, ``trials.csv`` — the front and every complete trial, one row each.
"""

from __future__ import annotations

import csv
import dataclasses
from collections import Counter
from pathlib import Path
from typing import Any, Sequence

from ringtune.agents.tune import trial_screen
from ringtune.agents.tune.choice import BASELINE_NAMES, Choice
from ringtune.agents.tune.pareto import (DEFAULT_RESOLUTION, METRIC_KEYS, VISIBLE_KEYS, Point, Resolution, broken_bounds,
                                         shown)
from ringtune.agents.tune.pareto_plot import plot_front
from ringtune.agents.tune.readme_text import readme_text
from ringtune.agents.tune.versus import QUALITY_LABEL, best_dominating, compare, table as versus_table, versus_all
from ringtune.hardware.dialects import export_config, limit_command
from ringtune.shaping.feature_settings import per_feature_text, per_feature_words
from ringtune.shaping.firmware import Firmware
from ringtune.shaping.smoothers import takes_damping


def describe(cfg, per_feature: bool = True) -> str:
    """One line: shapers, F, S (per axis where the axes' differ), frequency limit, acceleration and
    the per-axis caps the configuration carries of a TuneConfig; then, with ``per_feature``, what it
    sets per feature (:func:`ringtune.shaping.feature_settings.per_feature_text`)."""
    shaped = [a for a in "xy" if takes_damping(cfg.axis(a)[0])]
    dampings = {cfg.axis(a)[2] for a in shaped}
    per_axis_s = len(dampings) > 1

    def ax(a):
        name, f, z = cfg.axis(a)
        if name == "none":
            return f"{a.upper()} {name}"
        return f"{a.upper()} {name} @ {f:.1f} Hz" + (f" S {z:.3f}" if per_axis_s * (a in shaped) else "")
    parts = [ax("x"), ax("y")]
    if len(dampings) == 1:     # one S for both shaped axes
        parts.append(f"S {cfg.axis(shaped[0])[2]:.3f}")
    parts.append("no freq limit" if cfg.freq_limit_hz <= 0 else
                 f"freq limit {cfg.freq_limit_hz:.1f} Hz ({cfg.freq_limit_method})")
    caps = ", ".join(f"{a.upper()} {c:.0f}" for a, c in zip("xy", cfg.axis_caps) if c is not None)
    parts.append((f"accel {cfg.accel:.0f} mm/s²" if cfg.accel else "printer's accel")
                 + (f" (axis caps {caps})" if caps else "") + (per_feature_text(cfg) if per_feature else ""))
    return ", ".join(parts)


def _row(p: Point) -> dict[str, Any]:
    c = p.config
    row = {"label": p.label, "print_time_s": round(p.print_time_s, 4)}
    for k in METRIC_KEYS[1:]:
        v = p.metrics.get(k)
        row[k] = v if not isinstance(v, float) else round(v, 6)
    row.update({"shaper_x": c.shaper_x, "freq_x": c.freq_x, "shaper_y": c.shaper_y, "freq_y": c.freq_y,
                "damping_x": c.damping_x, "damping_y": c.damping_y, "freq_limit_hz": c.freq_limit_hz,
                "freq_limit_method": c.freq_limit_method if c.freq_limit_hz > 0 else "off", "accel": c.accel,
                # the twins can only make a figure worse: a trial settled without them has lower bounds
                "judged_on": f"the model alone ({p.screened}): lower bounds" if p.screened else
                "the model and its twins" if p.variants else "one printer"})
    return row


def _write_csv(path: Path, points: Sequence[Point]) -> None:
    rows = [_row(p) for p in points]
    if not rows:
        path.write_text("")
        return
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


#: the front table's column heads of the visible measures (a quality objective's: its label in µm)
_COLUMNS = {"ripple_mm": "ripple µm", "ripple_p90_mm": "p90 µm", "corner_in_mm": "in µm", "corner_out_mm": "out µm",
            "extrusion_over_pct": "over%", "extrusion_under_pct": "under%"}


def front_table(front: Sequence[Point], chosen: Point, quality: str) -> str:
    """The front as text: time, then the visible measures the points have (µm, %), then the
    configuration. What most rows set per feature (the study samples the shapers and the visible
    walls' acceleration; the rest is the same on every trial) is said once above the table, and
    only a row that sets otherwise says its own."""
    keys = [k for k in VISIBLE_KEYS if k in (front[0].metrics if front else {})] or \
        list(dict.fromkeys((quality, "path_error_mm")))
    head = "".join(f" {_COLUMNS.get(k, QUALITY_LABEL.get(k, k) + ' µm'):>12}" for k in keys)
    texts = [per_feature_words(p.config) for p in front]
    common, count = Counter(texts).most_common(1)[0] if texts else ("", 0)
    common = common if count > 1 else ""
    lines = [f"  per feature, unless a row says otherwise: {common}"] if common else []
    lines.append(f"  {'':2}{'time s':>8}{head}  configuration")
    for p, text in zip(front, texts):
        mark = "*" if p is chosen else " "
        vals = "".join(f" {_num(p, k):>12}" for k in keys)
        lines.append(f"  {mark:2}{p.print_time_s:8.3f}{vals}  {describe(p.config, per_feature=text != common)}")
    return "\n".join(lines)


def _num(p: Point, k: str) -> str:
    v = p.value(k)
    if v is None:
        return "—"
    return f"{v:.2f}" if k.endswith("_pct") else f"{v * 1000:.1f}"


def write_report(out_dir: Path, *, points: Sequence[Point], front: Sequence[Point], choice: Choice,
                 baselines: dict[str, Point], quality: str, printer_name: str, job_name: str,
                 firmware: str, n_trials: int, storage: str, study_name: str,
                 command: str = "ringtune tune", notes: Sequence[str] = (), max_path_error_mm: float = 0.0,
                 motor_reserve: float = 0.0, resolution: Resolution = DEFAULT_RESOLUTION,
                 baseline_labels: dict[str, str] | None = None, sections: Sequence[tuple[str, list[str]]] = (),
                 export_firmware: str | None = None, best_extra: dict | None = None,
                 max_show_through_mm: float = 0.0, baseline_binding: dict[str, list] | None = None,
                 judged_on: str = "") -> dict[str, Any]:
    """Write the output folder; returns the summary dict (also the CLI's --json).

    ``baseline_labels``: how each baseline is named (e.g. "Klipper's rule on a simulated resonance
    test"); ``sections``: (title, lines) blocks printed after the baselines (the acceleration's
    limit, the job's own accelerations); ``export_firmware``: the dialect apply.txt is written in
    (default ``firmware``); ``best_extra``: more keys for best.json's extra; ``judged_on``: where the
    measures are taken (:func:`ringtune.envs.planned_job.windows_sentence`), under the table."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    chosen = choice.point
    labels = _labels(baselines, baseline_labels or {})
    binding = baseline_binding or {}
    dialect = export_firmware or firmware

    best_cfg = chosen.config
    vs = versus_all(chosen, baselines, resolution)
    _save_best(out_dir, choice, vs, {"source": "ringtune tune", "printer": printer_name, "job": job_name},
               best_extra or {})

    apply_text, apply_notes = _apply_lines(best_cfg, dialect)
    (out_dir / "apply.txt").write_text(apply_text)

    comparisons = {k: compare(chosen, b, resolution) for k, b in baselines.items()}
    dominating = _dominating(front, baselines, resolution)

    title = f"{printer_name} · {job_name} · {firmware} · {len(points)} trials"
    marked = {f"dominates {labels[k]} (at the resolution)": d for k, (d, _c) in dominating.items()}
    drawn = plot_front(out_dir / "pareto.png", points, front, chosen, baselines, quality, title,
                       max_path_error_mm=max_path_error_mm, baseline_labels=labels, marked=marked)
    arrows = {k: {w: n for w, n in v.items() if w != "legend"} for k, v in drawn.items()}
    _write_csv(out_dir / "front.csv", front)
    _write_csv(out_dir / "trials.csv", sorted(points, key=lambda p: p.number if p.number is not None else -1))

    s = [f"ringtune tune — {title}", "", f"CHOSEN ({choice.sentence}):", f"  {describe(best_cfg)}",
         "  " + _figures(chosen, quality)]
    rewrite, rewrite_lines = _job_rewrite(best_cfg, dialect)
    s += rewrite_lines
    s += ["", "BASELINES (same printer, job and simulation):"]
    s += _baseline_lines(baselines, labels, comparisons, dominating, quality, resolution, binding)
    if baselines and "ripple_mm" in chosen.metrics:
        s += ["", "WHAT A PERSON SEES (the chosen configuration against each baseline, same simulation):"]
        s.extend(versus_table(chosen, baselines, labels, resolution))
        if judged_on:
            s.append(f"  ({judged_on}.)")
    for head, lines in sections:
        s += ["", f"{head}:"] + [f"  {line}" for line in lines]
    s += ["", _front_head(chosen, quality, len(front), len(points)), front_table(front, chosen, quality), ""]
    s.append("Ruled out: " + "; ".join(_ruled_out(points, max_path_error_mm, motor_reserve, max_show_through_mm))
             + ". All are drawn in pareto.png.")
    s.extend(notes)
    s.append(f"Study '{study_name}' in {storage}; rerun the same command to resume or extend it (--trials).")
    s.extend(apply_notes)
    summary_text = "\n".join(s) + "\n"
    (out_dir / "summary.txt").write_text(summary_text)
    (out_dir / "README.txt").write_text(readme_text(out_dir, dialect, storage, command))

    result = {
        "out": str(out_dir),
        "trials": len(points),
        "front_size": len(front),
        # trials whose twins were not simulated (agents/tune/trial_screen.py), by why
        "settled_on_model": trial_screen.settled_counts(points),
        "quality": quality,
        "max_path_error_mm": max_path_error_mm,
        "motor_reserve": motor_reserve,
        "max_show_through_mm": max_show_through_mm,
        "resolution": dataclasses.asdict(resolution),
        "chosen": _chosen_dict(choice, rewrite),
        "baselines": {k: _baseline_dict(b, labels[k], binding.get(k, [])) for k, b in baselines.items()},
        "vs_baselines": {k: c.to_dict() for k, c in comparisons.items()},
        "versus": vs,
        "judged_on": judged_on,
        "dominates_klipper": _dominating_dict(dominating, "klipper"),
        "dominates_current": _dominating_dict(dominating, "current"),
        "plot_arrows": arrows,
        "files": {k: str(out_dir / v) for k, v in _FILES},
    }
    return {"summary_text": summary_text, **result}


def _labels(baselines: dict[str, Point], given: dict[str, str]) -> dict[str, str]:
    """How each baseline is named: as ``given``, else its short name."""
    return {k: given.get(k, BASELINE_NAMES.get(k, k)) for k in baselines}


def _front_head(chosen: Point, quality: str, n_front: int, n_points: int) -> str:
    """The PARETO FRONT heading: what the front is taken over, how many trials it holds."""
    dims = ("print time and every visible measure" if "ripple_mm" in chosen.metrics else
            "print time and " + QUALITY_LABEL.get(quality, quality) + ("" if quality == "path_error_mm" else ", path error"))
    return f"PARETO FRONT over {dims} ({n_front} of {n_points} trials; * = chosen):"


#: the report folder's files: --json ``files`` key, file name
_FILES = (("readme", "README.txt"), ("summary", "summary.txt"), ("plot", "pareto.png"), ("best", "best.json"),
          ("apply", "apply.txt"), ("front", "front.csv"), ("trials", "trials.csv"))


def _save_best(out_dir: Path, choice: Choice, vs: dict, where: dict, extra: dict) -> None:
    """best.json: the chosen configuration with where it comes from (``where``), its figures, how it
    was chosen and its verdicts against each baseline, and ``extra``'s keys."""
    cfg = choice.point.config
    cfg.extra.update({**where, "metrics": _measures(choice.point, METRIC_KEYS),
                      "chosen_by": choice.by, "against": choice.baseline,
                      "versus": {k: {m: v["verdict"] for m, v in d.items()} for k, d in vs.items()}, **extra})
    cfg.save(out_dir / "best.json")


def _dominating(front: Sequence[Point], baselines: dict[str, Point], res: Resolution) -> dict:
    """{klipper|current: (the best front point dominating that baseline, its comparison)}, for the
    baselines some front point dominates."""
    out = {}
    for k in ("klipper", "current"):
        d = best_dominating(front, baselines[k], res) if k in baselines else None
        if d is not None:
            out[k] = (d, compare(d, baselines[k], res))
    return out


#: a broken bound (:func:`ringtune.agents.tune.pareto.broken_bounds`' words) -> its key in --json
_BREAK_KEYS = {"loses steps": "step_loss", "path error over the bound": "max_path_error",
               "motor load over the reserve": "motor_reserve", "show-through over the bound": "max_show_through",
               "judged on the model alone": "screened"}


def _baseline_lines(baselines: dict[str, Point], labels: dict[str, str], comparisons: dict, dominating: dict,
                    quality: str, res: Resolution, binding: dict[str, list]) -> list[str]:
    """The summary's BASELINES section: each baseline, its figures and bounds broken, the firmware
    limits that bind it (``binding``: {key: [BindingLimit]}), the chosen point against it, and the
    best front point dominating Klipper's or the current one."""
    s = []
    for k, b in baselines.items():
        s.append(f"  {labels[k]}: {describe(b.config)}")
        s.append("    " + _figures(b, quality) + "".join(f"  ({words.upper()})" for words in broken_bounds(b)))
        s.extend(f"    {x.sentence()}" for x in binding.get(k, []))
        s.append(f"    chosen vs this: {comparisons[k].sentence(quality)}")
    for k in ("klipper", "current"):
        if k not in baselines or comparisons[k].dominates:
            continue                    # the chosen point itself dominates it (said above)
        if k in dominating:
            d, c = dominating[k]
            s += [f"  Best front point dominating {labels[k]}: {describe(d.config)}", f"    {c.sentence(quality)}"]
        else:
            s.append(f"  No front point dominates {labels[k]} in this run (try more --trials).")
    s.append(f"  (\"the same\", \"dominates\": {res.describe()}.)")
    return s


def _ruled_out(points: Sequence[Point], max_pe: float, reserve: float, max_st: float) -> list[str]:
    """What the bounds ruled out, counted (each trial under the first bound it breaks), or that a
    bound is off."""
    n = Counter(broken_bounds(p)[0] for p in points if not p.feasible)
    bounded = ((max_pe, f"{n['path error over the bound']} whose path error (corner rounding, overshoot, ringing) "
                f"exceeds {max_pe:g} mm (--max-path-error)", "path error not bounded (--max-path-error 0)"),
               (reserve, f"{n['motor load over the reserve']} that ask a motor for more than "
                f"{(1 - reserve) * 100:.0f} % of its force (--motor-reserve)",
                "motor load not bounded (--motor-reserve 0)"),
               (max_st, f"{n['show-through over the bound']} whose hidden features reach the outer wall by more "
                f"than {max_st * 1000:g} µm (--max-show-through)", "show-through not bounded (--max-show-through 0)"))
    return ([f"{n['loses steps']} trials that lose steps"] + [on if bound > 0 else off for bound, on, off in bounded]
            + _settled(points))


def _settled(points: Sequence[Point]) -> list[str]:
    """The trials settled on the model alone (:mod:`ringtune.agents.tune.trial_screen`), in words
    (none: [])."""
    settled = trial_screen.settled_counts(points)
    beaten, over = settled.get(trial_screen.BEATEN, 0), settled.get(trial_screen.OVER_A_BOUND, 0)
    if beaten:
        return [f"{beaten} beaten on the printer as modelled by a trial judged on it and its twins, and worse "
                "than Klipper's pick there on a visible measure: their twins, which can only make a figure "
                "worse, were not simulated" + (f" (nor those of {over} counted above, which broke a bound on "
                "the model alone)" if over else "")]
    if over:
        return [f"the twins of {over} counted above, which broke a bound on the printer as modelled, were not "
                "simulated (they can only make a figure worse)"]
    return []


def _measures(p: Point, keys: Sequence[str] = METRIC_KEYS[1:]) -> dict:
    """The figures of ``keys`` ``p`` has (default: all but print time)."""
    return {k: p.metrics[k] for k in keys if k in p.metrics}


def _chosen_dict(choice: Choice, rewrite: str | None) -> dict:
    """--json ``chosen``: the configuration, its figures, how and against what it was chosen."""
    p = choice.point
    return {"config": p.config.to_dict(), "print_time_s": p.print_time_s, "quality_mm": p.quality_mm,
            "path_error_mm": p.metrics.get("path_error_mm"), "overshoot_mm": p.metrics.get("overshoot_mm"),
            "motor_load": p.metrics.get("motor_load"), "measures": _measures(p), "chosen_by": choice.by,
            "against": choice.baseline, "held_to": list(choice.held_to), "why": choice.sentence,
            "rewrite_jobs": rewrite}


def _baseline_dict(b: Point, label: str, binding: list) -> dict:
    """--json ``baselines.<key>``: the configuration, its figures, the bounds it breaks and the
    firmware limits that bind it."""
    return {"config": b.config.to_dict(), "print_time_s": b.print_time_s, "quality_mm": b.quality_mm,
            "path_error_mm": b.metrics.get("path_error_mm"), "overshoot_mm": b.metrics.get("overshoot_mm"),
            "motor_load": b.metrics.get("motor_load"), "step_loss": b.step_loss, "measures": _measures(b),
            "breaks": [_BREAK_KEYS[words] for words in broken_bounds(b)],
            "binding": [dataclasses.asdict(x) for x in binding], "label": label}


def _dominating_dict(dominating: dict, k: str) -> dict | None:
    """--json ``dominates_<k>``: the best front point dominating baseline ``k`` and how, or None."""
    if k not in dominating:
        return None
    d, c = dominating[k]
    return {"config": d.config.to_dict(), "print_time_s": d.print_time_s, "quality_mm": d.quality_mm, **c.to_dict()}


def _figures(p: Point, quality: str) -> str:
    """print time, the visible measures (or the quality figure and path error of a custom
    evaluator), show-through and motor load of a point, one line."""
    out = f"print time {p.print_time_s:.3f} s"
    if "ripple_mm" in p.metrics:
        m = p.metrics
        out += (f", ripple {shown('ripple_mm', m['ripple_mm'])} (p90 {shown('ripple_mm', m.get('ripple_p90_mm', 0.0))})"
                f", corners in {shown('corner_in_mm', m.get('corner_in_mm', 0.0))} / out "
                f"{shown('corner_out_mm', m.get('corner_out_mm', 0.0))}, extrusion +{m.get('extrusion_over_pct', 0.0):.1f} "
                f"/ −{m.get('extrusion_under_pct', 0.0):.1f} %, show-through {shown('ripple_mm', m.get('show_through_mm', 0.0))}")
    else:
        out += f", {QUALITY_LABEL.get(quality, quality)} {p.quality_mm * 1000:.1f} µm"
        if quality != "path_error_mm" and "path_error_mm" in p.metrics:
            out += f", path error {p.metrics['path_error_mm'] * 1000:.1f} µm"
    if p.metrics.get("motor_load"):
        out += f", motor load {p.metrics['motor_load'] * 100:.0f} %"
    return out


def _job_rewrite(cfg, dialect: str | None = None) -> tuple[str | None, list[str]]:
    """(the ``ringtune limit`` command, the summary's line saying so) when the chosen frequency
    limit cannot be set on the firmware and every job must be rewritten with it (no limit of the
    firmware's own, or Marlin's ``M201 F`` with another method than Marlin's); (None, []) otherwise."""
    if cfg.freq_limit_hz <= 0:
        return None, []
    fw = Firmware.named(dialect or cfg.firmware)
    if fw.freq_limit and cfg.freq_limit_method == "marlin":
        return None, []
    cmd = limit_command(cfg)
    why = (f"{fw.title} has no frequency limit of its own" if not fw.freq_limit else
           f"{fw.title}'s M201 F runs Marlin's method, not '{cfg.freq_limit_method}'")
    return cmd, [f"  The {cfg.freq_limit_hz:g} Hz frequency limit is not a printer setting ({why}): rewrite every "
                 f"job with `{cmd}` before printing it."]


def _apply_lines(cfg, dialect: str | None = None) -> tuple[str, list[str]]:
    """apply.txt's text, and the summary's notes on it: none, or why the firmware refused it."""
    try:
        return export_config(cfg, dialect).render(), []
    except Exception as exc:  # a firmware range refusal: say so instead of failing the study
        return (f"# could not export for {dialect or cfg.firmware}: {exc}\n", [f"apply.txt: {exc}"])
