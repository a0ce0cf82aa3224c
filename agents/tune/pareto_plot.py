"""``pareto.png`` of ``ringtune tune``: print time against the wall ripple, the other measures beside it.

The large panel plots print time (s) against the ripple a person sees on the visible walls (µm,
``ripple_mm``); small panels sharing the print-time axis show the other measures of the same
points: corner rounding and overshoot at visible corners (µm), over- and under-extrusion (%), what
hidden features push into the walls (µm) and the path error with its bound (µm). Every trial is
drawn, the ruled-out ones too (lost steps, path error over the bound, motor load over the
reserve); a point beyond a panel's scale is drawn as an arrow at the edge it lies beyond, with a
count. The baselines (Klipper's pick, what the printer runs now, no shaping) and the chosen point
are marked and labelled on every panel, with their values. A measure the trials do not carry (a
study from before it existed) gets a panel that says so; without ripple the large panel shows the
study's quality objective and says so. The legend sits below the large panel (it covers no point),
with file paths cut to their names; a ring "dominates X" takes X's colour.

The plotted values are written into the PNG's ``Data`` text chunk as JSON (``{panel key: {"unit",
"scale", series: [[print time s, value in the unit], …]}}``, read from the drawn artists), so a
test or tool can compare the picture with ``front.csv`` without reading pixels.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Sequence

import matplotlib
import matplotlib.pyplot as plt
import numpy as np

from ringtune.agents.tune.pareto import Point

#: the small panels: (metrics key, label, unit, factor from the stored unit to the drawn one)
MEASURES = (("corner_in_mm", "corner rounding (visible corners)", "µm", 1000.0),
            ("corner_out_mm", "corner overshoot (visible corners)", "µm", 1000.0),
            ("extrusion_over_pct", "over-extrusion", "%", 1.0),
            ("extrusion_under_pct", "under-extrusion", "%", 1.0),
            ("show_through_mm", "show-through of hidden features", "µm", 1000.0),
            ("path_error_mm", "path error", "µm", 1000.0))
MAIN = ("ripple_mm", "wall ripple, peak-to-peak (visible walls)", "µm", 1000.0)
QUALITY = {"overshoot_mm": ("overshoot", "µm", 1000.0), "path_error_mm": ("path error", "µm", 1000.0)}
STYLE = {"klipper": ("s", "tab:orange"), "current": ("D", "tab:green"), "none": ("^", "black")}
SHORT = {"klipper": "Klipper", "current": "now", "none": "none"}


def short_label(text: str) -> str:
    """A legend label with every path in parentheses cut to its file name (``(…/v24/printer.cfg)`` ->
    ``(printer.cfg)``): the summary names the full path; the legend must not cover the points."""
    return re.sub(r"\(([^()]*[/\\])([^()/\\]+)\)", r"(\2)", text)


def _ring_colour(label: str, baseline_labels: dict[str, str], i: int) -> str:
    """A ring ("dominates …") in the colour of the baseline it names, else one of its own."""
    for bkey, lab in baseline_labels.items():
        if lab and lab in label:
            return STYLE.get(bkey, ("P", "tab:cyan"))[1]
    return ("tab:pink", "tab:olive", "tab:cyan")[i % 3]


def _value(p: Point, key: str, quality: str) -> float:
    v = p.metrics.get(key)
    if v is None and key == quality:
        return p.quality_mm
    return float("nan") if v is None else float(v)


def _limits(vals: np.ndarray) -> tuple[float, float]:
    vals = vals[np.isfinite(vals)]
    if not len(vals):
        return (0.0, 1.0)
    lo, hi = float(vals.min()), float(vals.max())
    pad = 0.08 * max(hi - lo, 1e-9, 0.02 * abs(hi))
    return (0.0 if 0 <= lo < 0.5 * hi else lo - pad), hi + pad


def _groups(points: Sequence[Point], front: Sequence[Point]) -> list:
    ids = {id(p) for p in front}
    return [("trials", [p for p in points if p.feasible and id(p) not in ids], dict(s=10, c="0.7", marker="o")),
            ("lost steps, excluded", [p for p in points if p.step_loss], dict(s=16, c="tab:red", marker="x", alpha=0.6)),
            ("path error over the bound, excluded", [p for p in points if p.too_rough and not p.step_loss],
             dict(s=16, c="tab:purple", marker="+", alpha=0.6)),
            ("motor load over the reserve, excluded",
             [p for p in points if p.overloaded and not p.too_rough and not p.step_loss],
             dict(s=16, c="tab:brown", marker="1", alpha=0.7))]


_EDGES = (("above_scale", "^"), ("below_scale", "v"), ("right_of_scale", ">"), ("left_of_scale", "<"))


def _scatter_clipped(ax, t, y, box, style, counts, label=None):
    """Points inside ``box`` (t_lo, t_hi, y_lo, y_hi) as they are; the others as arrows at the edge
    they lie beyond (counted in ``counts``)."""
    t_lo, t_hi, y_lo, y_hi = box
    ok = np.isfinite(y)
    inside = ok & (t >= t_lo) & (t <= t_hi) & (y >= y_lo) & (y <= y_hi)
    ax.scatter(t[inside], y[inside], label=label, zorder=1, **style)
    in_y = (y >= y_lo) & (y <= y_hi)
    sel = {"above_scale": ok & (y > y_hi), "below_scale": ok & (y < y_lo),
           "right_of_scale": ok & in_y & (t > t_hi), "left_of_scale": ok & in_y & (t < t_lo)}
    for name, marker in _EDGES:
        s = sel[name]
        if not s.any():
            continue
        counts[name] += int(s.sum())
        if name in ("above_scale", "below_scale"):
            xx, yy = np.clip(t[s], t_lo, t_hi), np.full(int(s.sum()), y_hi if name == "above_scale" else y_lo)
        else:
            xx, yy = np.full(int(s.sum()), t_hi if name == "right_of_scale" else t_lo), y[s]
        ax.scatter(xx, yy, marker=marker, s=30, c=style["c"], alpha=0.8, zorder=1, clip_on=False)


def _panel(ax, key, name, unit, factor, ctx, full_legend: bool) -> dict:
    """Draw one measure against print time; returns its counts, legend and drawn series."""
    points, front, chosen, baselines, quality, labels, marked, bound, t_box = ctx
    counts = {"above_scale": 0, "below_scale": 0, "right_of_scale": 0, "left_of_scale": 0}
    ys = {id(p): _value(p, key, quality) * factor for p in points + list(front) + list(baselines.values()) + [chosen]}
    core = [ys[id(p)] for p in list(front) + list(baselines.values()) + [chosen]]
    core += [ys[id(p)] for p in points if p.feasible]
    series: dict = {}
    if not np.isfinite(core).any():
        ax.text(0.5, 0.5, f"{name}:\nnot recorded for these trials",
                ha="center", va="center", transform=ax.transAxes, fontsize=8, color="0.3")
        ax.set_title(f"{name} ({unit})", fontsize=8)
        ax.set_xlim(t_box[0], t_box[1])
        return {**counts, "missing": True, "legend": [], "rings": {}, "series": series}
    extra = [bound * factor] if key == "path_error_mm" and bound > 0 else []
    y_lo, y_hi = _limits(np.array(core + extra, float))
    box = (t_box[0], t_box[1], y_lo, y_hi)
    for label, pts, style in _groups(points, front):
        if pts:
            _scatter_clipped(ax, np.array([p.print_time_s for p in pts]), np.array([ys[id(p)] for p in pts]), box,
                             style, counts, f"{label} ({len(pts)})" if full_legend else None)
    if front:
        ft = [p.print_time_s for p in front]
        fy = [ys[id(p)] for p in front]
        art = ax.scatter(ft, fy, s=22, c="tab:blue", zorder=3, label=f"Pareto front ({len(front)})")
        series["front"] = np.asarray(art.get_offsets(), float).tolist()
    if key == "path_error_mm" and bound > 0:
        ax.axhline(bound * factor, c="tab:purple", ls="--", lw=1, label=f"path-error bound {bound * 1000:g} µm")
    for bkey, p in baselines.items():
        m, c = STYLE.get(bkey, ("P", "tab:cyan"))
        broke = [w for w, flag in (("loses steps", p.step_loss), ("path error over the bound", p.too_rough),
                                   ("motor load over the reserve", p.overloaded)) if flag]
        y = ys[id(p)]
        txt = f"{y:.1f} {unit}" if np.isfinite(y) else "not measured"
        lab = (f"{short_label(labels.get(bkey, bkey))}: {p.print_time_s:.2f} s, {txt}"
               + (f" — BREAKS A BOUND ({', '.join(broke)})" if broke else ""))
        if np.isfinite(y):
            art = ax.scatter([p.print_time_s], [np.clip(y, y_lo, y_hi)], s=90, marker=m, c=c, zorder=5, label=lab,
                             edgecolors="red" if broke else "white", linewidths=2 if broke else 1)
            series[f"baseline:{bkey}"] = [[p.print_time_s, y]]
            ax.annotate(SHORT.get(bkey, bkey) + ("" if full_legend else f" {y:.1f}"),
                        (p.print_time_s, float(np.clip(y, y_lo, y_hi))), fontsize=7,
                        xytext=(6, -9), textcoords="offset points", color=c)
    rings = {}
    for i, (lab, p) in enumerate((marked or {}).items()):     # rings of different sizes: both show
        colour = rings[short_label(lab)] = _ring_colour(lab, labels, i)
        ax.scatter([p.print_time_s], [_value(p, key, quality) * factor], s=180 + 120 * i, facecolors="none",
                   edgecolors=colour, linewidths=1.8, zorder=4, label=short_label(lab))
    y = ys[id(chosen)]
    ax.scatter([chosen.print_time_s], [y], s=260, marker="*", c="gold", edgecolors="black", zorder=6,
               label=f"chosen: {chosen.print_time_s:.2f} s, {y:.1f} {unit}")
    series["chosen"] = [[chosen.print_time_s, y]]
    ax.annotate("chosen" + ("" if full_legend else f" {y:.1f}"), (chosen.print_time_s, y), fontsize=7, xytext=(7, 5),
                textcoords="offset points")
    notes = [f"{n} {where.replace('_', ' ')} (arrows)" for where, n in counts.items() if n]
    if notes:
        ax.text(0.01, 0.99, "; ".join(notes), transform=ax.transAxes, va="top", fontsize=7, color="0.3")
    ax.set_xlim(t_box[0], t_box[1])
    ax.set_ylim(y_lo, y_hi)
    ax.set_ylabel(f"{name} ({unit})" if full_legend else unit, fontsize=10 if full_legend else 8)
    ax.grid(True, alpha=0.3)
    legend = []
    if full_legend:       # below the panel, not over the points
        leg = ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(0.0, -0.07), borderaxespad=0.0)
        legend = [t.get_text() for t in leg.get_texts()]
    return {**counts, "missing": False, "legend": legend, "rings": rings, "series": series}


def plot_front(path: Path, points: Sequence[Point], front: Sequence[Point], chosen: Point,
               baselines: dict[str, Point], quality: str, title: str, *, max_path_error_mm: float = 0.0,
               baseline_labels: dict[str, str] | None = None, marked: dict[str, Point] | None = None) -> dict:
    """Write the PNG; returns {panel key: {"above_scale": n, "below_scale": n, "right_of_scale": n,
    "left_of_scale": n, "missing": bool, "legend": [labels], "legend_over_points": bool, "rings":
    {label: colour}}} (what was drawn as arrows, whether the trials lack the measure, the legend (the
    large panel's; the small panels label their marks in place), whether it overlaps a plotting
    area, the rings). The first key is the large panel's (ripple, or
    the quality objective when the trials carry no ripple). ``marked``: {label: point} drawn
    ringed (e.g. "dominates Klipper's rule")."""
    matplotlib.use("Agg")
    points = list(points)
    core = list(front) + list(baselines.values()) + [chosen]
    t_lo, t_hi = _limits(np.array([p.print_time_s for p in core] + [p.print_time_s for p in points if p.feasible]))
    ctx = (points, list(front), chosen, baselines, quality, baseline_labels or {}, marked,
           max_path_error_mm, (t_lo, t_hi))
    main = MAIN
    has_ripple = any(np.isfinite(_value(p, "ripple_mm", quality)) for p in core + points)
    note = ""
    if not has_ripple:
        word, unit, factor = QUALITY.get(quality, (quality, "µm", 1000.0))
        main = (quality, word, unit, factor)
        note = f"ripple not recorded for these trials: {word} shown instead"
    fig = plt.figure(figsize=(16, 10), dpi=110)
    grid = fig.add_gridspec(3, 4)
    ax_main = fig.add_subplot(grid[:, :2])
    drawn = {main[0]: _panel(ax_main, *main, ctx, True)}
    ax_main.set_xlabel("print time (s)")
    if note:
        ax_main.text(0.01, 0.02, note, transform=ax_main.transAxes, fontsize=8, color="tab:red")
    small = [m for m in MEASURES if m[0] != main[0]][:6]
    for i, m in enumerate(small):
        ax = fig.add_subplot(grid[i // 2, 2 + i % 2], sharex=ax_main)
        drawn[m[0]] = _panel(ax, *m, ctx, False)
        ax.set_title(f"{m[1]} ({m[2]})", fontsize=8)
        ax.tick_params(labelsize=7)
        if i >= len(small) - 2:
            ax.set_xlabel("print time (s)", fontsize=8)
    fig.suptitle(f"{title}\nprint time against wall ripple; every measure of the same points, lower is better; "
                 "baselines and the chosen point marked on each", fontsize=10)
    fig.tight_layout()
    fig.canvas.draw()
    leg = ax_main.get_legend()
    boxes = [a.get_window_extent() for a in fig.axes]
    for v in drawn.values():      # whether the legend overlaps any panel's plotting area
        v["legend_over_points"] = bool(leg is not None and any(leg.get_window_extent().overlaps(b) for b in boxes))
    data = {k: {"unit": dict((m[0], m[2]) for m in (main, *small))[k],
                "scale": dict((m[0], m[3]) for m in (main, *small))[k], **v.pop("series")} for k, v in drawn.items()}
    fig.savefig(path, metadata={"Title": title, "Data": json.dumps(data)}, bbox_inches="tight")
    plt.close(fig)
    return drawn
