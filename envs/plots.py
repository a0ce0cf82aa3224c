"""Plots a person wants after a simulated print (matplotlib, Agg backend, PNG files).

- :func:`plot_path`: nozzle path against the commanded path, zoomed where the error is largest;
- :func:`plot_ringing`: the nozzle's deviation across the wall after the worst corner;
- :func:`plot_accel`: the toolhead accelerometer trace.

Each takes one simulated window (``SimResult``) and its unshaped commanded path (``Motion``) and
writes one PNG; :func:`plot_evaluation` picks the worst windows of an evaluation and writes all three.
A baseline (:class:`Overlay`: e.g. Klipper's pick, simulated on the same window of the same job) is
drawn on the same axes, so the plot shows the configuration against what it is compared with. The
plotted curves go into the PNG's ``Data`` text chunk as JSON ({series: [[x, y], …]} in the axes'
units), its title into ``Title``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt
import numpy as np

from ringtune.envs.windows import _trimmed
from ringtune.envs.figure import figure_texts
from ringtune.envs.path_geometry import path_legs
from ringtune.envs.variants import Variant
from ringtune.envs.window_metrics import compute_metrics
from ringtune.shaping.features import FEATURE_CLASSES, HIDDEN
from ringtune.shaping.motion import Motion


def _figure(nrows: int = 1, figsize=(7.5, 5.0)):
    matplotlib.use("Agg")
    fig, axes = plt.subplots(nrows, 1, figsize=figsize, squeeze=False)
    return plt, fig, axes[:, 0]


@dataclass
class Overlay:
    """A baseline drawn on the same axes: its simulated window (``sim``), that window's unshaped
    path, the causal lag (s) and how the legend names it."""

    label: str
    sim: object
    path: Motion
    lag: float = 0.0


def _save(plt, fig, out: Path, title: str = "", data: dict | None = None) -> Path:
    """Write the PNG; its title also goes into the file's ``Title`` text chunk and the plotted
    curves into ``Data`` (readable by tools and tests: what the picture says it shows)."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    meta = {"Title": title, "Description": "\n".join(figure_texts(fig))}
    if data:
        meta["Data"] = json.dumps({k: np.round(np.asarray(v, float), 6).tolist() for k, v in data.items()})
    fig.savefig(out, dpi=110, metadata=meta)
    plt.close(fig)
    return out


def _xy(a, b) -> np.ndarray:
    return np.column_stack([np.asarray(a, float), np.asarray(b, float)])


def plot_path(sim, path: Motion, out, *, lag: float = 0.0, title: str = "", baseline: Overlay | None = None,
              classes: np.ndarray | None = None) -> Path:
    """Nozzle vs commanded x/y path (mm), zoomed around the sample farthest from the path; the
    baseline's nozzle on the same window drawn over it. ``classes``: the feature class of each
    segment of ``path``: the legend names the feature the largest error is on."""
    m = compute_metrics(sim, path, lag=lag, classes=classes)
    where = m.details.get("path_error_at")
    plt, fig, (ax,) = _figure(figsize=(7.0, 6.0))
    t = np.asarray(sim.t)
    cmd_unshaped = path.position(t - lag)[:, :2]
    ax.plot(cmd_unshaped[:, 0], cmd_unshaped[:, 1], "k-", lw=2.5, alpha=0.35, label="G-code path (unshaped)")
    if getattr(sim, "commanded", None) is not None:
        cmd = np.asarray(sim.commanded)
        ax.plot(cmd[:, 0], cmd[:, 1], "b--", lw=1.0, label="shaped command")
    noz = np.asarray(sim.nozzle)
    ax.plot(noz[:, 0], noz[:, 1], "r-", lw=1.0, label="simulated nozzle (this configuration)")
    data = {"nozzle": noz[:, :2]}
    if baseline is not None:
        bn = np.asarray(baseline.sim.nozzle)
        ax.plot(bn[:, 0], bn[:, 1], "-", color="tab:orange", lw=1.0, label=f"simulated nozzle, {baseline.label}")
        data["baseline_nozzle"] = bn[:, :2]
    if where:
        x, y = where["x"], where["y"]
        r = max(4.0 * m.path_error_mm, 0.5)
        ax.set_xlim(x - r, x + r)
        ax.set_ylim(y - r, y + r)
        legs = path_legs(path, classes)
        k = int(np.argmin(np.maximum(legs.t_start - (where["t"] - lag), (where["t"] - lag) - legs.t_end)))
        ax.plot([x], [y], "o", mfc="none", mec="m", ms=12,
                label=f"largest error {m.path_error_mm:.3f} mm at t = {where['t']:.3f} s"
                f"{_feature_words(legs.cls[k], classes, 'on')}")
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    title = title or "Nozzle path against the commanded path (zoomed at the largest error)"
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=8, loc="best")
    ax.grid(alpha=0.3)
    return _save(plt, fig, out, title, data)


def _across(sim, path: Motion, lag: float, at_xy) -> tuple[np.ndarray, np.ndarray, object, int] | None:
    """(ms after the corner, µm across the wall) of the nozzle along the wall of ``path`` that
    starts nearest to ``at_xy`` (mm), with the legs and the wall's index; None without a wall."""
    legs = path_legs(path)
    if len(legs) < 2:
        return None
    k = int(np.argmin(np.linalg.norm(legs.start[:, :2] - np.asarray(at_xy)[:2], axis=1)))
    tc = legs.t_start[k]
    d = legs.direction[k]
    normal = np.array([-d[1], d[0]])
    t = np.asarray(sim.t) - lag
    sel = (t >= tc - 0.01) & (t <= legs.t_end[k])
    dev = (np.asarray(sim.nozzle)[sel, :2] - legs.start[k, :2]) @ normal
    return (t[sel] - tc) * 1e3, dev * 1e3, legs, k


def plot_ringing(sim, path: Motion, out, *, lag: float = 0.0, settle: float = 0.0,
                 anticipate: float = 0.0, title: str = "", baseline: Overlay | None = None,
                 classes: np.ndarray | None = None) -> Path:
    """Deviation across the wall (µm) after the corner with the worst ringing, against time (ms);
    the baseline's nozzle along the same wall (the wall of its path starting nearest the same
    corner) drawn over it. ``classes``: the feature class of each segment of ``path`` (the window's):
    the axis names the wall's feature, and says where nobody sees it."""
    m = compute_metrics(sim, path, lag=lag, settle=settle, anticipate=anticipate, classes=classes)
    legs = path_legs(path, classes)
    at = m.details.get("ringing_at") or m.details.get("overshoot_at")
    plt, fig, (ax,) = _figure(figsize=(8.0, 4.5))
    if at is None or len(legs) < 2:
        ax.text(0.5, 0.5, "no corner followed by a wall in this window", ha="center", va="center",
                transform=ax.transAxes)
        return _save(plt, fig, out)
    tc = at.get("t_corner", at.get("corner_t"))
    k = int(np.argmin(np.abs(legs.t_start - tc)))
    d = legs.direction[k]
    normal = np.array([-d[1], d[0]])
    t = np.asarray(sim.t) - lag
    sel = (t >= tc - 0.01) & (t <= legs.t_end[k])
    dev = (np.asarray(sim.nozzle)[sel, :2] - legs.start[k]) @ normal
    ax.plot((t[sel] - tc) * 1e3, dev * 1e3, "r-", lw=1.0, label="nozzle across the wall (this configuration)")
    data = {"nozzle": _xy((t[sel] - tc) * 1e3, dev * 1e3)}
    if getattr(sim, "commanded", None) is not None:
        cdev = (np.asarray(sim.commanded)[sel, :2] - legs.start[k]) @ normal
        ax.plot((t[sel] - tc) * 1e3, cdev * 1e3, "b--", lw=1.0, label="shaped command")
    base = _across(baseline.sim, baseline.path, baseline.lag, legs.start[k]) if baseline is not None else None
    if base is not None:
        ax.plot(base[0], base[1], "-", color="tab:orange", lw=1.0, label=f"nozzle across the wall, {baseline.label}")
        data["baseline_nozzle"] = _xy(base[0], base[1])
    ax.axhline(0, color="k", lw=0.8)
    if settle > 0:
        ax.axvline(settle * 1e3, color="g", ls=":", label="shaper finished turning")
    wall_end = (legs.t_end[k] - tc - anticipate) * 1e3
    if anticipate > 0:
        ax.axvline(wall_end, color="g", ls="--", label="shaper starts the next turn")
    ax.set_xlabel(f"time after the {legs.turn_deg[k]:.0f}° corner (ms){_feature_words(legs.cls[k], classes)}")
    ax.set_ylabel("deviation across the wall (µm)")
    title = title or (f"Ringing after a {legs.turn_deg[k]:.0f}° corner: RMS {m.ringing_mm * 1e3:.1f} µm; "
                      f"overshoot in this window {m.overshoot_mm * 1e3:.1f} µm")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    return _save(plt, fig, out, title, data)


def _feature_words(cls: int, classes, prep: str = "into") -> str:
    """``", into the infill: nobody sees it"``: the feature a place belongs to ("" without classes)."""
    if classes is None:
        return ""
    name = FEATURE_CLASSES[int(cls)]
    return f", {prep} the {name.replace('_', ' ')}" + (": nobody sees it" if name in HIDDEN else "")


def plot_accel(sim, out, *, title: str = "", t0: float = 0.0, baseline: Overlay | None = None,
               baseline_t0: float = 0.0) -> Path:
    """Toolhead accelerometer (x, y, z) and head acceleration magnitude, mm/s², against time (s)
    after ``t0`` (the quality window's start); the baseline's head acceleration on the same window
    (its own start ``baseline_t0``) over it."""
    plt, fig, axes = _figure(2, figsize=(8.0, 6.0))
    t = np.asarray(sim.t) - t0
    acc = getattr(sim, "accel_sensor", None)
    data = {}
    if acc is not None:
        acc = np.asarray(acc)
        for i, name in enumerate("xyz"[:acc.shape[1]]):
            axes[0].plot(t, acc[:, i], lw=0.8, color=("tab:blue", "tab:green", "0.5")[i], label=f"accelerometer {name}")
    axes[0].set_ylabel("acceleration (mm/s²)")
    title = title or "Toolhead accelerometer"
    axes[0].set_title(title, fontsize=9)
    axes[0].legend(fontsize=8)
    head = np.linalg.norm(np.asarray(sim.head_accel)[:, :2], axis=1)
    axes[1].plot(t, head, "k-", lw=0.8, label="|head acceleration| (this configuration)")
    data["head_accel"] = _xy(t, head)
    if baseline is not None:
        bt = np.asarray(baseline.sim.t) - baseline_t0
        bh = np.linalg.norm(np.asarray(baseline.sim.head_accel)[:, :2], axis=1)
        axes[1].plot(bt, bh, "-", color="tab:orange", lw=0.8, label=f"|head acceleration|, {baseline.label}")
        data["baseline_head_accel"] = _xy(bt, bh)
    axes[1].set_xlabel("time from the window's start (s)")
    axes[1].set_ylabel("acceleration (mm/s²)")
    axes[1].legend(fontsize=8)
    for ax in axes:
        ax.grid(alpha=0.3)
    return _save(plt, fig, out, title, data)


def _overlay(base, label: str, v: int, i: int) -> tuple[Overlay | None, float]:
    """The baseline's window ``i`` on variant ``v`` (and its start, s), or (None, 0) without one."""
    if not base or v >= len(base) or i >= len(base[v].runs):
        return None, 0.0
    r, s = base[v].runs[i], base[v].sims[i]
    return Overlay(label, _trimmed(s, r.t0 + r.lag, r.t1 + r.lag), r.path, r.lag), r.t0 + r.lag


def plot_evaluation(ev, out_dir, prefix: str = "", *, factors=None, judged: str = "", baseline=None,
                    baseline_label: str = "Klipper's pick") -> list[Path]:
    """Write path, ringing and accelerometer plots of an evaluation's worst windows to ``out_dir``.

    ``ev`` is a :class:`ringtune.envs.evaluate.Evaluation`, or a list of them: one per printer
    variant (``factors``: each one's :class:`ringtune.envs.variants.Variant`, as ``variant_factors`` gives them).
    Each plot shows the window and variant where its figure is worst, so its title states the
    figure the command reports for the job (``judged``: how it was judged, in words). ``baseline``:
    the Evaluations of a baseline configuration on the same job and variants (e.g. Klipper's pick),
    drawn on the same axes as ``baseline_label``. Returns the files written."""
    evs = list(ev) if isinstance(ev, (list, tuple)) else [ev]
    base = list(baseline) if isinstance(baseline, (list, tuple)) else ([baseline] if baseline is not None else [])
    factors = list(factors) if factors is not None else [Variant(1.0)] * len(evs)
    out_dir = Path(out_dir)
    if not evs or not evs[0].runs:
        return []
    how = f"\njudged: {judged}" if judged else ""
    vs = f"\nagainst {baseline_label.split(' (')[0]} (orange) on the same window" if base else ""

    def worst(key):
        """(variant, window) of the largest ``key``; the first variant on ties."""
        best, at = -np.inf, (0, 0)
        for v, e in enumerate(evs):
            for w, part in enumerate(e.metrics.details.get("windows", [])):
                if part[key] > best:
                    best, at = part[key], (v, w)
        return at

    def on(v):
        return f"\nshown on {factors[v].words()}" if len(evs) > 1 else ""

    files = []
    v, i = worst("path_error_mm")
    r, s = evs[v].runs[i], evs[v].sims[i]
    pe = evs[v].metrics.details["windows"][i]["path_error_mm"]
    files.append(plot_path(_trimmed(s, r.t0 + r.lag, r.t1 + r.lag), r.path, out_dir / f"{prefix}path.png",
                           lag=r.lag, title=f"Nozzle path at the job's largest path error, {pe * 1e3:.1f} µm"
                           f"{how}{on(v)}{vs}", baseline=_overlay(base, baseline_label, v, i)[0],
                           classes=r.classes))
    v, i = worst("ringing_mm")
    r, s = evs[v].runs[i], evs[v].sims[i]
    part = evs[v].metrics.details["windows"][i]
    job_os = max(e.metrics.overshoot_mm for e in evs)
    files.append(plot_ringing(_trimmed(s, r.t0 + r.lag, r.t1 + r.lag), r.path,
                              out_dir / f"{prefix}ringing.png", lag=r.lag, settle=r.settle,
                              anticipate=r.anticipate,
                              title=f"The job's worst ringing, RMS {part['ringing_mm'] * 1e3:.1f} µm\novershoot "
                              f"in this window {part['overshoot_mm'] * 1e3:.1f} µm (the job's worst "
                              f"{job_os * 1e3:.1f} µm){how}{on(v)}{vs}",
                              baseline=_overlay(base, baseline_label, v, i)[0], classes=r.classes))
    over, bt0 = _overlay(base, baseline_label, v, i)
    if over is not None:     # the whole simulated span, as for the configuration
        over.sim = base[v].sims[i]
    files.append(plot_accel(s, out_dir / f"{prefix}accel.png", t0=r.t0 + r.lag, baseline=over, baseline_t0=bt0,
                            title=f"Toolhead accelerometer in the window of the worst ringing{on(v)}{vs}"))
    return files
