"""The output folder of ``ringtune tune``: what a person opens after a study.

Files (all in ``out_dir``):

- ``README.txt``   — what each file is and which to open first;
- ``summary.txt``  — the chosen configuration, how it compares with Klipper's rule and with no
  shaping (by how much, in s and mm), and the Pareto front as a table;
- ``pareto.png``   — print time (s) against quality (mm): every trial, the front, the chosen point
  and the baselines marked;
- ``best.json``    — the chosen TuneConfig (for ``ringtune export``/``push``/``simulate``);
- ``apply.txt``    — the exact firmware lines that apply it (``hardware.dialects``);
- ``front.csv``, ``trials.csv`` — the front and every complete trial, one row each.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

from ringtune.agents.pareto import Point

QUALITY_LABEL = {"overshoot_mm": "overshoot", "path_error_mm": "path error"}


@dataclass
class Comparison:
    """How ``point`` compares with a baseline (positive = better than the baseline)."""

    baseline: str
    faster_s: float
    faster_pct: float
    better_mm: float
    better_pct: float
    dominates: bool

    def sentence(self, quality: str) -> str:
        word = QUALITY_LABEL.get(quality, quality)
        t = (f"{self.faster_s:.3f} s faster ({self.faster_pct:.1f} %)" if self.faster_s >= 0
             else f"{-self.faster_s:.3f} s slower ({-self.faster_pct:.1f} %)")
        q = (f"{self.better_mm * 1000:.1f} µm less {word} ({self.better_pct:.1f} %)" if self.better_mm >= 0
             else f"{-self.better_mm * 1000:.1f} µm more {word} ({-self.better_pct:.1f} %)")
        return f"{t}, {q}" + (" — dominates it" if self.dominates else "")


def compare(point: Point, base: Point) -> Comparison:
    dt = base.print_time_s - point.print_time_s
    dq = base.quality_mm - point.quality_mm
    return Comparison(base.label, dt, 100.0 * dt / base.print_time_s if base.print_time_s else 0.0,
                      dq, 100.0 * dq / base.quality_mm if base.quality_mm else 0.0, point.dominates(base))


def best_dominating(front: Sequence[Point], base: Point) -> Point | None:
    """The front point dominating ``base`` with the largest summed relative gain, or None."""
    dom = [p for p in front if p.dominates(base)]
    if not dom:
        return None

    def gain(p: Point) -> float:
        return ((base.print_time_s - p.print_time_s) / max(base.print_time_s, 1e-12)
                + (base.quality_mm - p.quality_mm) / max(base.quality_mm, 1e-12))

    return max(dom, key=gain)


def describe(cfg) -> str:
    """One line: shapers, F, S, frequency limit and acceleration of a TuneConfig."""
    def ax(a):
        name, f, z = cfg.axis(a)
        return f"{a.upper()} {name}" if name == "none" else f"{a.upper()} {name} @ {f:.1f} Hz"
    z = cfg.damping_x if cfg.shaper_x != "none" else cfg.damping_y
    parts = [ax("x"), ax("y")]
    if cfg.shaper_x != "none" or cfg.shaper_y != "none":
        parts.append(f"S {z:.3f}")
    parts.append("no freq limit" if cfg.freq_limit_hz <= 0 else
                 f"freq limit {cfg.freq_limit_hz:.1f} Hz ({cfg.freq_limit_method})")
    parts.append(f"accel {cfg.accel:.0f} mm/s²" if cfg.accel else "printer's accel")
    return ", ".join(parts)


def plot_front(path: Path, points: Sequence[Point], front: Sequence[Point], chosen: Point,
               baselines: dict[str, Point], quality: str, title: str) -> None:
    """Pareto front PNG: axes in s and mm, chosen point and baselines marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8.5, 6), dpi=120)
    feas = [p for p in points if p.feasible]
    bad = [p for p in points if p.step_loss]
    rough = [p for p in points if p.too_rough and not p.step_loss]
    if rough:
        ax.scatter([p.print_time_s for p in rough], [p.quality_mm for p in rough], s=12, marker="+",
                   c="tab:purple", alpha=0.5, label=f"path error over the bound ({len(rough)}, excluded)", zorder=1)
    if feas:
        ax.scatter([p.print_time_s for p in feas], [p.quality_mm for p in feas], s=10, c="0.75",
                   label=f"trials ({len(feas)})", zorder=1)
    if bad:
        ax.scatter([p.print_time_s for p in bad], [p.quality_mm for p in bad], s=14, marker="x", c="tab:red",
                   alpha=0.5, label=f"lost steps ({len(bad)}, excluded)", zorder=1)
    if front:
        ax.step([p.print_time_s for p in front], [p.quality_mm for p in front], where="post", c="tab:blue",
                lw=1.5, zorder=2)
        ax.scatter([p.print_time_s for p in front], [p.quality_mm for p in front], s=22, c="tab:blue",
                   label=f"Pareto front ({len(front)})", zorder=3)
    style = {"klipper": ("s", "tab:orange", "Klipper's rule"), "none": ("^", "black", "no shaping")}
    for key, p in baselines.items():
        m, c, lab = style.get(key, ("D", "tab:purple", key))
        ax.scatter([p.print_time_s], [p.quality_mm], s=90, marker=m, c=c, edgecolors="white", zorder=5,
                   label=f"{lab}: {p.print_time_s:.2f} s, {p.quality_mm * 1000:.1f} µm")
    ax.scatter([chosen.print_time_s], [chosen.quality_mm], s=260, marker="*", c="gold", edgecolors="black",
               zorder=6, label=f"chosen: {chosen.print_time_s:.2f} s, {chosen.quality_mm * 1000:.1f} µm")
    ax.set_xlabel("print time (s)")
    ax.set_ylabel(f"{QUALITY_LABEL.get(quality, quality)} (mm)")
    ax.set_title(title, fontsize=10)
    ax.grid(True, alpha=0.3)
    ys = [p.quality_mm for p in front] + [p.quality_mm for p in baselines.values()]
    if ys and min(ys) > 0 and max(ys) / min(ys) > 30:   # the no-shaping point would flatten the front
        ax.set_yscale("log")
        ys = []
    if ys and max(ys) > 0:
        ax.set_ylim(0, 1.15 * max(ys + [chosen.quality_mm]))
    ax.legend(fontsize=8, loc="upper right")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


_ROW_KEYS = ("print_time_s", "path_error_mm", "overshoot_mm", "ringing_mm", "peak_accel", "step_loss")


def _row(p: Point) -> dict[str, Any]:
    c = p.config
    row = {"label": p.label, "print_time_s": round(p.print_time_s, 4)}
    for k in _ROW_KEYS[1:]:
        v = p.metrics.get(k)
        row[k] = v if not isinstance(v, float) else round(v, 6)
    row.update({"shaper_x": c.shaper_x, "freq_x": c.freq_x, "shaper_y": c.shaper_y, "freq_y": c.freq_y,
                "damping": c.damping_x, "freq_limit_hz": c.freq_limit_hz,
                "freq_limit_method": c.freq_limit_method if c.freq_limit_hz > 0 else "off", "accel": c.accel})
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


def front_table(front: Sequence[Point], chosen: Point, quality: str) -> str:
    word = QUALITY_LABEL.get(quality, quality)
    pe = quality != "path_error_mm"
    lines = [f"  {'':2}{'time s':>8} {word + ' µm':>14}" + (f" {'path error µm':>14}" if pe else "")
             + "  configuration"]
    for p in front:
        mark = "*" if p is chosen else " "
        extra = f" {p.metrics.get('path_error_mm', float('nan')) * 1000:14.1f}" if pe else ""
        lines.append(f"  {mark:2}{p.print_time_s:8.3f} {p.quality_mm * 1000:14.1f}{extra}  {describe(p.config)}")
    return "\n".join(lines)


def write_report(out_dir: Path, *, points: Sequence[Point], front: Sequence[Point], chosen: Point,
                 baselines: dict[str, Point], quality: str, printer_name: str, job_name: str,
                 firmware: str, n_trials: int, storage: str, study_name: str, weight: float | None,
                 command: str = "ringtune tune", notes: Sequence[str] = (),
                 max_path_error_mm: float = 0.0) -> dict[str, Any]:
    """Write the output folder; returns the summary dict (also the CLI's --json)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    word = QUALITY_LABEL.get(quality, quality)
    how = f"minimises print time + {weight:g} s/mm × {word}" if weight is not None else \
        "the knee of the front: closest to the ideal corner with time scaled by the front's range and " \
        "quality by its range, at least 10 µm"

    best_cfg = chosen.config
    best_cfg.extra.update({"source": "ringtune tune", "printer": printer_name, "job": job_name,
                           "metrics": {k: chosen.metrics.get(k) for k in _ROW_KEYS if k in chosen.metrics},
                           "chosen_by": "weight" if weight is not None else "knee"})
    best_cfg.save(out_dir / "best.json")

    apply_text, apply_note = _apply_lines(best_cfg)
    (out_dir / "apply.txt").write_text(apply_text)

    comparisons = {k: compare(chosen, b) for k, b in baselines.items()}
    dominating = {}
    if "klipper" in baselines:
        d = best_dominating(front, baselines["klipper"])
        if d is not None:
            dominating["klipper"] = (d, compare(d, baselines["klipper"]))

    title = f"{printer_name} · {job_name} · {firmware} · {len(points)} trials"
    plot_front(out_dir / "pareto.png", points, front, chosen, baselines, quality, title)
    _write_csv(out_dir / "front.csv", front)
    _write_csv(out_dir / "trials.csv", sorted(points, key=lambda p: p.number if p.number is not None else -1))

    s = [f"ringtune tune — {title}", ""]
    s.append(f"CHOSEN ({how}):")
    s.append(f"  {describe(best_cfg)}")
    s.append(f"  print time {chosen.print_time_s:.3f} s, {word} {chosen.quality_mm * 1000:.1f} µm"
             + (f", path error {chosen.metrics['path_error_mm'] * 1000:.1f} µm"
                if quality != "path_error_mm" and "path_error_mm" in chosen.metrics else ""))
    s.append("")
    s.append("BASELINES (same printer, job and simulation):")
    names = {"klipper": "Klipper's rule (its shapers at its suggested max_accel)", "none": "no shaping"}
    for k, b in baselines.items():
        s.append(f"  {names.get(k, k)}: {describe(b.config)}")
        s.append(f"    print time {b.print_time_s:.3f} s, {word} {b.quality_mm * 1000:.1f} µm"
                 + (f", path error {b.metrics['path_error_mm'] * 1000:.1f} µm"
                    if quality != "path_error_mm" and "path_error_mm" in b.metrics else "")
                 + ("  (LOSES STEPS)" if b.step_loss else "")
                 + ("  (PATH ERROR OVER THE BOUND)" if b.too_rough else ""))
        s.append(f"    chosen vs this: {comparisons[k].sentence(quality)}")
    if "klipper" in baselines:
        if "klipper" in dominating:
            d, c = dominating["klipper"]
            s.append(f"  Best front point dominating Klipper's rule: {describe(d.config)}")
            s.append(f"    {c.sentence(quality)}")
        else:
            s.append("  No front point dominates Klipper's rule in this run (try more --trials).")
    s.append("")
    s.append(f"PARETO FRONT ({len(front)} of {len(points)} trials; * = chosen):")
    s.append(front_table(front, chosen, quality))
    s.append("")
    n_rough = sum(p.too_rough and not p.step_loss for p in points)
    n_lost = sum(p.step_loss for p in points)
    if max_path_error_mm > 0:
        s.append(f"Ruled out: {n_lost} trials that lose steps, {n_rough} whose path error (corner rounding, "
                 f"overshoot, ringing) exceeds {max_path_error_mm:g} mm (--max-path-error).")
    elif n_lost:
        s.append(f"Ruled out: {n_lost} trials that lose steps; path error is not bounded (--max-path-error 0).")
    s.extend(notes)
    s.append(f"Study '{study_name}' in {storage}; rerun the same command to resume or extend it (--trials).")
    if apply_note:
        s.append(apply_note)
    summary_text = "\n".join(s) + "\n"
    (out_dir / "summary.txt").write_text(summary_text)
    (out_dir / "README.txt").write_text(_readme(out_dir, best_cfg, firmware, storage, command))

    result = {
        "out": str(out_dir),
        "trials": len(points),
        "front_size": len(front),
        "quality": quality,
        "max_path_error_mm": max_path_error_mm,
        "chosen": {"config": best_cfg.to_dict(), "print_time_s": chosen.print_time_s, "quality_mm": chosen.quality_mm,
                   "chosen_by": "weight" if weight is not None else "knee"},
        "baselines": {k: {"config": b.config.to_dict(), "print_time_s": b.print_time_s, "quality_mm": b.quality_mm,
                          "step_loss": b.step_loss} for k, b in baselines.items()},
        "vs_baselines": {k: c.__dict__ for k, c in comparisons.items()},
        "dominates_klipper": None if "klipper" not in baselines else (
            None if "klipper" not in dominating else {
                "config": dominating["klipper"][0].config.to_dict(),
                "print_time_s": dominating["klipper"][0].print_time_s,
                "quality_mm": dominating["klipper"][0].quality_mm, **dominating["klipper"][1].__dict__}),
        "files": {k: str(out_dir / v) for k, v in (("readme", "README.txt"), ("summary", "summary.txt"),
                                                   ("plot", "pareto.png"), ("best", "best.json"),
                                                   ("apply", "apply.txt"), ("front", "front.csv"),
                                                   ("trials", "trials.csv"))},
    }
    return {"summary_text": summary_text, **result}


def _apply_lines(cfg) -> tuple[str, str]:
    try:
        from ringtune.hardware.dialects import export_config
    except ImportError:
        return ("# hardware.dialects is not available; run `ringtune export best.json` later\n",
                "apply.txt: firmware export was not available.")
    try:
        return export_config(cfg).render(), ""
    except Exception as exc:  # a firmware range refusal: say so instead of failing the study
        return (f"# could not export for {cfg.firmware}: {exc}\n", f"apply.txt: {exc}")


def _readme(out_dir: Path, cfg, firmware: str, storage: str, command: str) -> str:
    return f"""ringtune tune results — start here
=================================

1. summary.txt   The answer: the chosen input-shaping configuration, and how it compares with
                 Klipper's own rule and with no shaping on the same printer and job (seconds and
                 micrometres). Then the whole trade-off (the Pareto front) as a table.
2. pareto.png    The trade-off as a picture: print time (s) against quality (mm). Grey dots are
                 all trials, blue the best trade-offs, the gold star the chosen point, the orange
                 square Klipper's rule, the black triangle no shaping; red crosses lost steps and
                 purple plus signs left the path by more than --max-path-error (both ruled out).
                 Lower-left is better.
3. apply.txt     The exact {firmware} lines that put the chosen configuration on the printer.
                 Or: ringtune export {out_dir / 'best.json'} --firmware {firmware}
                     ringtune push {out_dir / 'best.json'} --port /dev/ttyUSB0 --firmware {firmware}
4. best.json     The chosen configuration (TuneConfig) for ringtune simulate / export / push.
5. front.csv, trials.csv   Every point of the front and every trial, for your own analysis.

To pick another point of the front: rerun with --weight W (seconds of print time you would
give for 1 mm less error; e.g. --weight 100). The study itself is kept in {storage}:
running the same command again ({command}) resumes it with nothing lost; --trials N extends it.
"""
