"""Plots a person wants after a simulated print (matplotlib, Agg backend, PNG files).

- :func:`plot_path`: nozzle path against the commanded path, zoomed where the error is largest;
- :func:`plot_ringing`: the nozzle's deviation across the wall after the worst corner;
- :func:`plot_accel`: the toolhead accelerometer trace.

Each takes one simulated window (``SimResult``) and its unshaped commanded path (``Motion``) and
writes one PNG; :func:`plot_evaluation` picks the worst windows of an evaluation and writes all three.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt
import numpy as np

from ringtune.envs.evaluate import _trimmed
from ringtune.envs.metrics import compute_metrics
from ringtune.envs.path_geometry import path_legs
from ringtune.shaping.motion import Motion


def _figure(nrows: int = 1, figsize=(7.5, 5.0)):
    matplotlib.use("Agg")
    fig, axes = plt.subplots(nrows, 1, figsize=figsize, squeeze=False)
    return plt, fig, axes[:, 0]


def _save(plt, fig, out: Path, title: str = "") -> Path:
    """Write the PNG; its title also goes into the file's ``Title`` text chunk (readable by tools
    and tests: what the picture says it shows)."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(out, dpi=110, metadata={"Title": title} if title else None)
    plt.close(fig)
    return out


def plot_path(sim, path: Motion, out, *, lag: float = 0.0, title: str = "") -> Path:
    """Nozzle vs commanded x/y path, zoomed around the sample farthest from the path."""
    m = compute_metrics(sim, path, lag=lag)
    where = m.details.get("path_error_at")
    plt, fig, (ax,) = _figure(figsize=(7.0, 6.0))
    t = np.asarray(sim.t)
    cmd_unshaped = path.position(t - lag)[:, :2]
    ax.plot(cmd_unshaped[:, 0], cmd_unshaped[:, 1], "k-", lw=2.5, alpha=0.35, label="G-code path (unshaped)")
    if getattr(sim, "commanded", None) is not None:
        cmd = np.asarray(sim.commanded)
        ax.plot(cmd[:, 0], cmd[:, 1], "b--", lw=1.0, label="shaped command")
    noz = np.asarray(sim.nozzle)
    ax.plot(noz[:, 0], noz[:, 1], "r-", lw=1.0, label="simulated nozzle")
    if where:
        x, y = where["x"], where["y"]
        r = max(4.0 * m.path_error_mm, 0.5)
        ax.set_xlim(x - r, x + r)
        ax.set_ylim(y - r, y + r)
        ax.plot([x], [y], "o", mfc="none", mec="m", ms=12,
                label=f"largest error {m.path_error_mm:.3f} mm at t = {where['t']:.3f} s")
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    title = title or "Nozzle path against the commanded path (zoomed at the largest error)"
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=8, loc="best")
    ax.grid(alpha=0.3)
    return _save(plt, fig, out, title)


def plot_ringing(sim, path: Motion, out, *, lag: float = 0.0, settle: float = 0.0,
                 anticipate: float = 0.0, title: str = "") -> Path:
    """Deviation across the wall after the corner with the worst ringing, against time (ms)."""
    m = compute_metrics(sim, path, lag=lag, settle=settle, anticipate=anticipate)
    legs = path_legs(path)
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
    ax.plot((t[sel] - tc) * 1e3, dev * 1e3, "r-", lw=1.0, label="nozzle across the wall")
    if getattr(sim, "commanded", None) is not None:
        cdev = (np.asarray(sim.commanded)[sel, :2] - legs.start[k]) @ normal
        ax.plot((t[sel] - tc) * 1e3, cdev * 1e3, "b--", lw=1.0, label="shaped command")
    ax.axhline(0, color="k", lw=0.8)
    if settle > 0:
        ax.axvline(settle * 1e3, color="g", ls=":", label="shaper finished turning")
    wall_end = (legs.t_end[k] - tc - anticipate) * 1e3
    if anticipate > 0:
        ax.axvline(wall_end, color="g", ls="--", label="shaper starts the next turn")
    ax.set_xlabel(f"time after the {legs.turn_deg[k]:.0f}° corner (ms)")
    ax.set_ylabel("deviation across the wall (µm)")
    title = title or (f"Ringing after a {legs.turn_deg[k]:.0f}° corner: RMS {m.ringing_mm * 1e3:.1f} µm; "
                      f"overshoot in this window {m.overshoot_mm * 1e3:.1f} µm")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    return _save(plt, fig, out, title)


def plot_accel(sim, out, *, title: str = "") -> Path:
    """Toolhead accelerometer (x, y, z) and commanded head acceleration magnitude, mm/s² vs s."""
    plt, fig, axes = _figure(2, figsize=(8.0, 6.0))
    t = np.asarray(sim.t)
    acc = getattr(sim, "accel_sensor", None)
    if acc is not None:
        acc = np.asarray(acc)
        for i, name in enumerate("xyz"[:acc.shape[1]]):
            axes[0].plot(t, acc[:, i], lw=0.8, label=f"accelerometer {name}")
    axes[0].set_ylabel("acceleration (mm/s²)")          # the unit every text of ringtune uses
    title = title or "Toolhead accelerometer"
    axes[0].set_title(title, fontsize=9)
    axes[0].legend(fontsize=8)
    head = np.linalg.norm(np.asarray(sim.head_accel)[:, :2], axis=1)
    axes[1].plot(t, head, "k-", lw=0.8, label="|head acceleration|")
    axes[1].set_xlabel("time (s)")
    axes[1].set_ylabel("acceleration (mm/s²)")
    axes[1].legend(fontsize=8)
    for ax in axes:
        ax.grid(alpha=0.3)
    return _save(plt, fig, out, title)


def _variant_name(factor: float) -> str:
    return "the printer as modelled" if factor == 1.0 else \
        f"the printer with its resonances {abs(factor - 1) * 100:g} % {'lower' if factor < 1 else 'higher'}"


def plot_evaluation(ev, out_dir, prefix: str = "", *, factors=None, judged: str = "") -> list[Path]:
    """Write path, ringing and accelerometer plots of an evaluation's worst windows to ``out_dir``.

    ``ev`` is a :class:`ringtune.envs.evaluate.Evaluation`, or a list of them: one per printer
    variant (``factors``: each variant's resonance factor, as ``evaluate_judged`` returns them).
    Each plot shows the window and variant where its figure is worst, so its title states the
    figure the command reports for the job (``judged``: how it was judged, in words). Returns the
    files written."""
    evs = list(ev) if isinstance(ev, (list, tuple)) else [ev]
    factors = list(factors) if factors is not None else [1.0] * len(evs)
    out_dir = Path(out_dir)
    if not evs or not evs[0].runs:
        return []
    how = f"\njudged: {judged}" if judged else ""

    def worst(key):
        """(variant, window) of the largest ``key``; the first variant on ties."""
        best, at = -np.inf, (0, 0)
        for v, e in enumerate(evs):
            for w, part in enumerate(e.metrics.details.get("windows", [])):
                if part[key] > best:
                    best, at = part[key], (v, w)
        return at

    def on(v):
        return f"\nshown on {_variant_name(factors[v])}" if len(evs) > 1 else ""

    files = []
    v, i = worst("path_error_mm")
    r, s = evs[v].runs[i], evs[v].sims[i]
    pe = evs[v].metrics.details["windows"][i]["path_error_mm"]
    files.append(plot_path(_trimmed(s, r.t0 + r.lag, r.t1 + r.lag), r.path, out_dir / f"{prefix}path.png",
                           lag=r.lag, title=f"Nozzle path at the job's largest path error, {pe * 1e3:.1f} µm"
                           f"{how}{on(v)}"))
    v, i = worst("ringing_mm")
    r, s = evs[v].runs[i], evs[v].sims[i]
    part = evs[v].metrics.details["windows"][i]
    job_os = max(e.metrics.overshoot_mm for e in evs)
    files.append(plot_ringing(_trimmed(s, r.t0 + r.lag, r.t1 + r.lag), r.path,
                              out_dir / f"{prefix}ringing.png", lag=r.lag, settle=r.settle,
                              anticipate=r.anticipate,
                              title=f"The job's worst ringing, RMS {part['ringing_mm'] * 1e3:.1f} µm\novershoot "
                              f"in this window {part['overshoot_mm'] * 1e3:.1f} µm (the job's worst "
                              f"{job_os * 1e3:.1f} µm){how}{on(v)}"))
    files.append(plot_accel(s, out_dir / f"{prefix}accel.png",
                            title=f"Toolhead accelerometer in the window of the worst ringing{on(v)}"))
    return files
