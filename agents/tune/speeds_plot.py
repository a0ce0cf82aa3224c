"""Drawing vibration against speed (:mod:`ringtune.agents.tune.speeds`): the ripple of the typical
wall per direction against its speed, the bands to avoid shaded, and the OrcaSlicer keys. Every
text also goes into the PNG's ``Description`` chunk."""

from __future__ import annotations

from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt

from ringtune.agents.tune.speeds import BAND_LEVEL, DIRECTION_TEXT, SpeedAdvice
from ringtune.envs.figure import save_figure


def band_lines(a: SpeedAdvice) -> list[str]:
    """One line per band, worst first (also printed by the command)."""
    order = sorted(a.bands, key=lambda b: -b.peak_ripple)
    return [f"{b.direction}: {b.lo:g}-{b.hi:g} mm/s (worst {1000 * b.peak_ripple:.1f} µm at {b.peak_speed:g} mm/s)"
            for b in order]


def plot_speeds(a: SpeedAdvice, path: str | Path, printer_name: str = "") -> Path:
    """Ripple against speed per direction, bands shaded, on the left; the bands and OrcaSlicer's keys on the right."""
    matplotlib.use("Agg")
    fig, (ax, side) = plt.subplots(1, 2, figsize=(15, 6), gridspec_kw={"width_ratios": [2.5, 1.3]})
    colours = dict(zip(a.ripple, ("tab:blue", "tab:orange", "tab:green", "tab:red")))
    for k, r in a.ripple.items():
        ax.plot(a.speeds, 1000 * r, color=colours[k], lw=1.8, label=DIRECTION_TEXT[k])
    for b in a.bands:
        ax.axvspan(b.lo, b.hi, color=colours[b.direction], alpha=0.12)
    w = a.worst
    if w is not None:
        ax.annotate(f"worst: {w.peak_speed:g} mm/s", (w.peak_speed, 1000 * w.peak_ripple), xytext=(6, 6),
                    textcoords="offset points", fontsize=8)
    ax.set_xlabel("wall speed, mm/s")
    ax.set_ylabel("ripple across the wall, µm peak-to-peak (ripple_mm)")
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper right")
    ax.set_title(f"Vibration against speed{' — ' + printer_name if printer_name else ''}: a {a.wall_length:.1f} mm wall "
                 f"after a {a.corner_deg:.0f}° corner at {a.accel:g} mm/s²", fontsize=10)
    side.axis("off")
    orca = a.orcaslicer()
    text = [f"bands (shaded): ripple ≥ {BAND_LEVEL:.3f} (1/√2) of that direction's worst",
            *band_lines(a), "", "OrcaSlicer (printer settings, outer walls):",
            *([f"{k} = {v}" for k, v in orca.items()] or ["(no band)"]), "",
            "simulated: planner, shapers and the exact linear model", "(as ringtune simulate --backend lti)",
            *a.notes]
    side.text(0.0, 1.0, "\n".join(text), fontsize=8, va="top", transform=side.transAxes, wrap=True)
    fig.tight_layout()
    return save_figure(fig, path, "ringtune graph speeds")
