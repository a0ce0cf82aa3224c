"""``pareto.png`` of ``ringtune tune``: print time against each quality figure, every point drawn.

Two panels share the print-time axis: the quality objective (overshoot or path error) and the path
error with its bound. Every trial is drawn, the ruled-out ones too (lost steps, path error over the
bound, motor load over the reserve); a point beyond a panel's scale is drawn as an arrow at the edge
it lies beyond, with a count, so that the legend's counts and the picture agree. Baselines that
break a bound are drawn with a red edge and say so in the legend. The legend sits below each panel
(it covers no point), with file paths cut to their names; a ring "dominates X" takes X's colour.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Sequence

import matplotlib
import matplotlib.pyplot as plt
import numpy as np

from ringtune.agents.tune.pareto import Point, pareto_front

LABEL = {"overshoot_mm": "overshoot", "path_error_mm": "path error"}
STYLE = {"klipper": ("s", "tab:orange"), "current": ("D", "tab:green"), "none": ("^", "black")}


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
    if key == quality:
        return p.quality_mm
    v = p.metrics.get(key)
    return float("nan") if v is None else float(v)


def _limits(vals: np.ndarray, log: bool) -> tuple[float, float]:
    vals = vals[np.isfinite(vals)]
    if not len(vals):
        return (0.0, 1.0)
    lo, hi = float(vals.min()), float(vals.max())
    if log:
        lo = max(lo, 1e-6)
        return lo / 1.5, hi * 1.5
    pad = 0.08 * max(hi - lo, 1e-9)
    return (0.0 if lo >= 0 and lo < 0.5 * hi else lo - pad), hi + pad


def plot_front(path: Path, points: Sequence[Point], front: Sequence[Point], chosen: Point,
               baselines: dict[str, Point], quality: str, title: str, *, max_path_error_mm: float = 0.0,
               baseline_labels: dict[str, str] | None = None, marked: dict[str, Point] | None = None) -> dict:
    """Write the PNG; returns {panel key: {"above_scale": n, "below_scale": n, "right_of_scale": n,
    "left_of_scale": n, "legend": [labels], "legend_over_points": bool, "rings": {label: colour}}}
    (what was drawn as arrows, the legend, whether it overlaps the panel's plotting area, the rings).
    ``marked``: {label: point} drawn ringed (e.g. "dominates Klipper's rule")."""
    matplotlib.use("Agg")
    baseline_labels = baseline_labels or {}
    keys = [quality] + (["path_error_mm"] if quality != "path_error_mm" else [])
    fig, axes = plt.subplots(1, len(keys), figsize=(7.5 * len(keys), 6), dpi=110, squeeze=False)
    # the scale: what matters (front, baselines, chosen, feasible trials), not far-off rejects
    core = list(front) + list(baselines.values()) + [chosen]
    t_core = np.array([p.print_time_s for p in core] + [p.print_time_s for p in points if p.feasible])
    t_lo, t_hi = _limits(t_core, False)
    arrows = {}
    groups = [("trials", [p for p in points if p.feasible and p not in front], dict(s=10, c="0.7", marker="o")),
              ("lost steps, excluded", [p for p in points if p.step_loss],
               dict(s=16, c="tab:red", marker="x", alpha=0.6)),
              ("path error over the bound, excluded", [p for p in points if p.too_rough and not p.step_loss],
               dict(s=16, c="tab:purple", marker="+", alpha=0.6)),
              ("motor load over the reserve, excluded",
               [p for p in points if p.overloaded and not p.too_rough and not p.step_loss],
               dict(s=16, c="tab:brown", marker="1", alpha=0.7))]
    for ax, key in zip(axes[0], keys):
        y_core = np.array([_value(p, key, quality) for p in core])
        log = bool(np.nanmin(y_core) > 0 and np.nanmax(y_core) / np.nanmin(y_core) > 30)
        y_lo, y_hi = _limits(np.concatenate([y_core, [max_path_error_mm]] if key == "path_error_mm"
                                            and max_path_error_mm > 0 else [y_core]), log)
        counts = {"above_scale": 0, "below_scale": 0, "right_of_scale": 0, "left_of_scale": 0}
        for label, pts, style in groups:
            if not pts:
                continue
            t = np.array([p.print_time_s for p in pts])
            y = np.array([_value(p, key, quality) for p in pts])
            inside = (t >= t_lo) & (t <= t_hi) & (y >= y_lo) & (y <= y_hi)
            ax.scatter(t[inside], y[inside], label=f"{label} ({len(pts)})", zorder=1, **style)
            for name, sel, xy, marker in (
                    ("above_scale", y > y_hi, lambda tt, yy: (np.clip(tt, t_lo, t_hi), np.full_like(yy, y_hi)), "^"),
                    ("below_scale", y < y_lo, lambda tt, yy: (np.clip(tt, t_lo, t_hi), np.full_like(yy, y_lo)), "v"),
                    ("right_of_scale", (y >= y_lo) & (y <= y_hi) & (t > t_hi),
                     lambda tt, yy: (np.full_like(tt, t_hi), yy), ">"),
                    ("left_of_scale", (y >= y_lo) & (y <= y_hi) & (t < t_lo),
                     lambda tt, yy: (np.full_like(tt, t_lo), yy), "<")):
                if sel.any():
                    counts[name] += int(sel.sum())
                    xx, yy = xy(t[sel], y[sel])
                    ax.scatter(xx, yy, marker=marker, s=30, c=style["c"], alpha=0.8, zorder=1, clip_on=False)
        notes = [f"{n} {where.replace('_', ' ')} (arrows)" for where, n in counts.items() if n]
        if notes:
            ax.text(0.01, 0.99, "; ".join(notes), transform=ax.transAxes, va="top", fontsize=8, color="0.3")
        arrows[key] = counts
        if front:
            if key == quality:     # the staircase of print time against this figure alone
                stair = pareto_front(front)
                ax.step([p.print_time_s for p in stair], [p.quality_mm for p in stair], where="post",
                        c="tab:blue", lw=1.2, zorder=2)
            ax.scatter([p.print_time_s for p in front], [_value(p, key, quality) for p in front], s=22,
                       c="tab:blue", label=f"Pareto front ({len(front)})", zorder=3)
        if key == "path_error_mm" and max_path_error_mm > 0:
            ax.axhline(max_path_error_mm, c="tab:purple", ls="--", lw=1,
                       label=f"path-error bound {max_path_error_mm * 1000:g} µm")
        for bkey, p in baselines.items():
            m, c = STYLE.get(bkey, ("P", "tab:cyan"))
            broke = [w for w, flag in (("loses steps", p.step_loss), ("path error over the bound", p.too_rough),
                                       ("motor load over the reserve", p.overloaded)) if flag]
            lab = short_label(baseline_labels.get(bkey, bkey))
            ax.scatter([p.print_time_s], [np.clip(_value(p, key, quality), y_lo, y_hi)], s=90, marker=m, c=c,
                       edgecolors="red" if broke else "white", linewidths=2 if broke else 1, zorder=5,
                       label=f"{lab}: {p.print_time_s:.2f} s, {_value(p, key, quality) * 1000:.1f} µm"
                       + (f" — BREAKS A BOUND ({', '.join(broke)})" if broke else ""))
        counts["rings"] = {}
        for i, (lab, p) in enumerate((marked or {}).items()):     # rings of different sizes: both show
            colour = counts["rings"][short_label(lab)] = _ring_colour(lab, baseline_labels, i)
            ax.scatter([p.print_time_s], [_value(p, key, quality)], s=180 + 120 * i, facecolors="none",
                       edgecolors=colour, linewidths=1.8, zorder=4, label=short_label(lab))
        ax.scatter([chosen.print_time_s], [_value(chosen, key, quality)], s=260, marker="*", c="gold",
                   edgecolors="black", zorder=6,
                   label=f"chosen: {chosen.print_time_s:.2f} s, {_value(chosen, key, quality) * 1000:.1f} µm")
        ax.set_xlim(t_lo, t_hi)
        if log:
            ax.set_yscale("log")
        ax.set_ylim(y_lo, y_hi)
        ax.set_xlabel("print time (s)")
        ax.set_ylabel(f"{LABEL.get(key, key)} (mm)")
        ax.grid(True, alpha=0.3)
        # below the panel, not over the points
        leg = ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(0.0, -0.16), borderaxespad=0.0)
        counts["legend"] = [t.get_text() for t in leg.get_texts()]
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.canvas.draw()
    for ax, key in zip(axes[0], keys):     # whether a legend overlaps its panel's plotting area
        arrows[key]["legend_over_points"] = bool(ax.get_legend().get_window_extent().overlaps(ax.get_window_extent()))
    fig.savefig(path, bbox_inches="tight")
    plt.close(fig)
    return arrows
