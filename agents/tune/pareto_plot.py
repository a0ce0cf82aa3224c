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
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import matplotlib
import matplotlib.pyplot as plt
import numpy as np

from ringtune.agents.tune.pareto import Point, broken_bounds

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


#: the trials drawn as groups: (the group: "trials" off the front, or a ruled-out trial's first broken
#: bound in :func:`ringtune.agents.tune.pareto.broken_bounds`' words; legend label; marker style).
#: Trials over the show-through bound alone are not drawn.
_GROUPS = (("trials", "trials", dict(s=10, c="0.7", marker="o")),
           ("loses steps", "lost steps, excluded", dict(s=16, c="tab:red", marker="x", alpha=0.6)),
           ("path error over the bound", "path error over the bound, excluded",
            dict(s=16, c="tab:purple", marker="+", alpha=0.6)),
           ("motor load over the reserve", "motor load over the reserve, excluded",
            dict(s=16, c="tab:brown", marker="1", alpha=0.7)),
           ("judged on the model alone", "beaten on the model alone (twins not simulated)",
            dict(s=8, c="0.82", marker=".")))


def _groups(points: Sequence[Point], front: Sequence[Point]) -> list:
    """(label, points, style) of each of :data:`_GROUPS`."""
    ids = {id(p) for p in front}
    group = [(broken_bounds(p) or ["front" if id(p) in ids else "trials"])[0] for p in points]
    return [(label, [p for p, g in zip(points, group) if g == key], style) for key, label, style in _GROUPS]


def _scatter_clipped(ax, t, y, box, style, counts, label=None):
    """Points inside ``box`` (t_lo, t_hi, y_lo, y_hi) as they are; the others as arrows at the edge
    they lie beyond (counted in ``counts``): their values clipped into the box."""
    t_lo, t_hi, y_lo, y_hi = box
    ok = np.isfinite(y)
    inside = ok & (t >= t_lo) & (t <= t_hi) & (y >= y_lo) & (y <= y_hi)
    ax.scatter(t[inside], y[inside], label=label, zorder=1, **style)
    in_y = (y >= y_lo) & (y <= y_hi)
    for name, marker, s in (("above_scale", "^", ok & (y > y_hi)), ("below_scale", "v", ok & (y < y_lo)),
                            ("right_of_scale", ">", ok & in_y & (t > t_hi)),
                            ("left_of_scale", "<", ok & in_y & (t < t_lo))):
        if s.any():
            counts[name] += int(s.sum())
            ax.scatter(np.clip(t[s], t_lo, t_hi), np.clip(y[s], y_lo, y_hi), marker=marker, s=30, c=style["c"],
                       alpha=0.8, zorder=1, clip_on=False)


@dataclass(frozen=True)
class _Scene:
    """What every panel draws: every trial, the front, the chosen point, the baselines by key and
    their labels, the ringed points ({label: point}), the quality objective's key, the path-error
    bound (mm; 0 = none); ``scaled``: the points the scales are fitted to (the front, the
    baselines, the chosen point and every feasible trial) and ``t_box``: the print-time range drawn (s)."""

    points: list
    front: list
    chosen: Point
    baselines: dict
    labels: dict
    marked: dict
    quality: str
    max_path_error_mm: float
    scaled: list
    t_box: tuple


def _panel(ax, key, name, unit, factor, scene: _Scene, full_legend: bool) -> dict:
    """Draw one measure against print time; returns its counts, legend and drawn series."""
    def y(p: Point) -> float:
        return _value(p, key, scene.quality) * factor

    counts = {"above_scale": 0, "below_scale": 0, "right_of_scale": 0, "left_of_scale": 0}
    scaled = [y(p) for p in scene.scaled]
    if not np.isfinite(scaled).any():
        return {**counts, **_missing(ax, name, unit, scene.t_box), "series": {}}
    bound = scene.max_path_error_mm * factor if key == "path_error_mm" and scene.max_path_error_mm > 0 else np.nan
    box = (*scene.t_box, *_limits(np.array(scaled + [bound], float)))    # no bound: NaN, left out
    _trials(ax, scene, y, box, counts, full_legend)
    series = {"front": _front(ax, scene.front, [y(p) for p in scene.front])} if scene.front else {}
    if np.isfinite(bound):
        ax.axhline(bound, c="tab:purple", ls="--", lw=1,
                   label=f"path-error bound {scene.max_path_error_mm * 1000:g} µm")
    for bkey, p in scene.baselines.items():
        _baseline(ax, bkey, p, y(p), box[2:], unit, scene.labels, full_legend, series)
    rings = _rings(ax, scene.marked, scene.labels, y)
    _chosen(ax, scene.chosen, y(scene.chosen), unit, full_legend, series)
    legend = _finish(ax, counts, f"{name} ({unit})" if full_legend else unit, full_legend, box)
    return {**counts, "missing": False, "legend": legend, "rings": rings, "series": series}


def _trials(ax, scene: _Scene, y, box, counts: dict, full_legend: bool) -> None:
    """Every trial off the front and every ruled-out one (:func:`_groups`) at its value ``y(point)``,
    those beyond ``box`` as arrows counted in ``counts``; labelled with their numbers when ``full_legend``."""
    for label, pts, style in _groups(scene.points, scene.front):
        if pts:
            _scatter_clipped(ax, np.array([p.print_time_s for p in pts]), np.array([y(p) for p in pts]), box,
                             style, counts, f"{label} ({len(pts)})" if full_legend else None)


def _missing(ax, name: str, unit: str, t_box) -> dict:
    """A panel whose measure no point recorded: says so."""
    ax.text(0.5, 0.5, f"{name}:\nnot recorded for these trials",
            ha="center", va="center", transform=ax.transAxes, fontsize=8, color="0.3")
    ax.set_title(f"{name} ({unit})", fontsize=8)
    ax.set_xlim(t_box[0], t_box[1])
    return {"missing": True, "legend": [], "rings": {}}


def _baseline(ax, bkey: str, p: Point, y: float, y_box, unit: str, labels: dict, full_legend: bool,
              series: dict) -> None:
    """One baseline's marker (edged red when it breaks a bound other than show-through, the legend
    naming them) and label; a baseline without the measure is not drawn."""
    if not np.isfinite(y):
        return
    m, c = STYLE.get(bkey, ("P", "tab:cyan"))
    broke = [w for w in broken_bounds(p) if w != "show-through over the bound"]
    lab = f"{short_label(labels.get(bkey, bkey))}: {p.print_time_s:.2f} s, {y:.1f} {unit}"
    edge, width = ("white", 1)
    if broke:
        lab, edge, width = f"{lab} — BREAKS A BOUND ({', '.join(broke)})", "red", 2
    y_lo, y_hi = y_box
    ax.scatter([p.print_time_s], [np.clip(y, y_lo, y_hi)], s=90, marker=m, c=c, zorder=5, label=lab,
               edgecolors=edge, linewidths=width)
    series[f"baseline:{bkey}"] = [[p.print_time_s, y]]
    ax.annotate(SHORT.get(bkey, bkey) + ("" if full_legend else f" {y:.1f}"),
                (p.print_time_s, float(np.clip(y, y_lo, y_hi))), fontsize=7,
                xytext=(6, -9), textcoords="offset points", color=c)


def _front(ax, front: Sequence[Point], ys: list[float]) -> list:
    """The front's points (``ys``: their values), drawn; [[time, value], ...] as drawn."""
    art = ax.scatter([p.print_time_s for p in front], ys, s=22, c="tab:blue", zorder=3,
                     label=f"Pareto front ({len(front)})")
    return np.asarray(art.get_offsets(), float).tolist()


def _rings(ax, marked: dict, labels: dict, value) -> dict:
    """Rings around the ``marked`` points ({label: point}; ``value(point)``: its y), of different
    sizes so that both show on one point; {short label: colour}."""
    rings = {}
    for i, (lab, p) in enumerate(marked.items()):
        colour = rings[short_label(lab)] = _ring_colour(lab, labels, i)
        ax.scatter([p.print_time_s], [value(p)], s=180 + 120 * i, facecolors="none",
                   edgecolors=colour, linewidths=1.8, zorder=4, label=short_label(lab))
    return rings


def _chosen(ax, chosen: Point, y: float, unit: str, full_legend: bool, series: dict) -> None:
    """The chosen point: a gold star, labelled."""
    ax.scatter([chosen.print_time_s], [y], s=260, marker="*", c="gold", edgecolors="black", zorder=6,
               label=f"chosen: {chosen.print_time_s:.2f} s, {y:.1f} {unit}")
    series["chosen"] = [[chosen.print_time_s, y]]
    ax.annotate("chosen" + ("" if full_legend else f" {y:.1f}"), (chosen.print_time_s, y), fontsize=7, xytext=(7, 5),
                textcoords="offset points")


def _finish(ax, counts: dict, ylabel: str, full_legend: bool, box) -> list[str]:
    """A panel's off-scale note, limits, axis label and grid; its legend (below the panel, not over
    the points) when ``full_legend``, as the texts drawn."""
    notes = [f"{n} {where.replace('_', ' ')} (arrows)" for where, n in counts.items() if n]
    if notes:       # top right: the front falls from the top left, where the fast (chosen) points are labelled
        ax.text(0.99, 0.99, "; ".join(notes), transform=ax.transAxes, ha="right", va="top", fontsize=7, color="0.3")
    ax.set_xlim(box[0], box[1])
    ax.set_ylim(box[2], box[3])
    ax.set_ylabel(ylabel, fontsize=10 if full_legend else 8)
    ax.grid(True, alpha=0.3)
    if not full_legend:
        return []
    leg = ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(0.0, -0.07), borderaxespad=0.0)
    return [t.get_text() for t in leg.get_texts()]


def _main_measure(scene: _Scene) -> tuple[tuple, str]:
    """The large panel's measure (as a row of :data:`MEASURES`): the ripple, or the quality
    objective when no point carries it, with a note saying so ("" with the ripple)."""
    if any(np.isfinite(_value(p, "ripple_mm", scene.quality)) for p in scene.scaled + scene.points):
        return MAIN, ""
    word, unit, factor = QUALITY.get(scene.quality, (scene.quality, "µm", 1000.0))
    return (scene.quality, word, unit, factor), f"ripple not recorded for these trials: {word} shown instead"


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
    scaled = list(front) + list(baselines.values()) + [chosen] + [p for p in points if p.feasible]
    scene = _Scene(points, list(front), chosen, baselines, baseline_labels or {}, marked or {}, quality,
                   max_path_error_mm, scaled, _limits(np.array([p.print_time_s for p in scaled])))
    main, note = _main_measure(scene)
    fig = plt.figure(figsize=(16, 10), dpi=110)
    grid = fig.add_gridspec(3, 4)
    ax_main = fig.add_subplot(grid[:, :2])
    drawn = {main[0]: _panel(ax_main, *main, scene, True)}
    ax_main.set_xlabel("print time (s)")
    if note:
        ax_main.text(0.01, 0.02, note, transform=ax_main.transAxes, fontsize=8, color="tab:red")
    small = [m for m in MEASURES if m[0] != main[0]][:6]
    for i, m in enumerate(small):
        ax = fig.add_subplot(grid[i // 2, 2 + i % 2], sharex=ax_main)
        drawn[m[0]] = _panel(ax, *m, scene, False)
        ax.set_title(f"{m[1]} ({m[2]})", fontsize=8)
        ax.tick_params(labelsize=7)
        if i >= len(small) - 2:
            ax.set_xlabel("print time (s)", fontsize=8)
    fig.suptitle(f"{title}\nprint time against wall ripple; every measure of the same points, lower is better; "
                 "baselines and the chosen point marked on each", fontsize=10)
    fig.tight_layout()
    spec = {m[0]: m for m in (main, *small)}
    data = {k: {"unit": spec[k][2], "scale": spec[k][3], **v.pop("series")} for k, v in drawn.items()}
    fig.savefig(path, metadata={"Title": title, "Data": json.dumps(data)}, bbox_inches="tight")
    leg = ax_main.get_legend()      # whether it overlaps any panel's plotting area, as savefig drew them
    over = bool(leg is not None and any(leg.get_window_extent().overlaps(a.get_window_extent()) for a in fig.axes))
    for v in drawn.values():
        v["legend_over_points"] = over
    plt.close(fig)
    return drawn
