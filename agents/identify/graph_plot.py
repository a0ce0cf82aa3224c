"""Drawing Klipper's shaper graph (:mod:`ringtune.agents.identify.graph`), one row per axis.

Left, as Klipper draws it: the normalised spectrum (X, Y, Z and their sum), the pick's "after
shaper" spectrum, and on the right-hand scale every candidate's remaining vibration ratio (dotted),
Klipper's pick (bold) and ringtune's choice (dashed, when a TuneConfig is given); the fitted modes
as a thin curve with their frequencies marked. Right: the table of the candidates (frequency,
remaining vibrations, smoothing, max_accel) with the picks named. Every text also goes into the
PNG's ``Description`` chunk (:func:`ringtune.envs.figure.save_figure`).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt

from ringtune.agents.identify.graph import AxisGraph, ShaperCurve
from ringtune.envs.figure import save_figure

#: column -> (label, colour, line width, alpha): the sum bold, the axes' columns thin and faint
_PSD_STYLE = {"x": ("X", "tab:red", 1, 0.6), "y": ("Y", "tab:green", 1, 0.6), "z": ("Z", "tab:blue", 1, 0.6),
              "sum": ("X+Y+Z", "tab:purple", 2, 1)}
TABLE_HEADER = ("shaper", "freq Hz", "vibr %", "smooth. mm", "max_accel", "pick")


def table_rows(g: AxisGraph) -> list[tuple[str, ...]]:
    """The table on the figure: one row per candidate, then ringtune's choice (when given)."""
    rows = []
    for c in g.shapers:
        rows.append(_row(c, "Klipper" if c is g.klipper else ""))
    if g.ringtune is not None:
        rows.append(_row(g.ringtune, "ringtune"))
    return rows


def _row(c: ShaperCurve, pick: str) -> tuple[str, ...]:
    f = c.fit
    if f.name == "none":
        return ("none", "-", "100.0", "0.000", "no limit", pick)
    return (f.name, f"{f.freq:.1f}", f"{100 * f.vibrs:.1f}", f"{f.smoothing:.3f}", c.max_accel_text, pick)


def _spectrum(ax, g: AxisGraph) -> None:
    for key, (label, colour, lw, alpha) in _PSD_STYLE.items():
        if key in g.psd:
            ax.plot(g.freqs, g.psd[key], color=colour, lw=lw, alpha=alpha, label=label)
    ax.plot(g.freqs, g.after_shaper, color="black", lw=1.2, ls="--",
            label=f"after {g.klipper.fit.name} (Klipper's pick)")
    ax.plot(g.freqs, g.fitted, color="grey", lw=1, label=f"fitted modes ({g.axis.upper()} column)")
    top = max(float(g.psd["sum"].max()), 1e-12)
    for m in g.fit.modes:
        ax.axvline(m.freq, color="grey", ls=":", lw=0.8)
        ax.annotate(f"{m.freq:.1f} Hz\nζ {m.damping:.3f}", (m.freq, top), fontsize=7, ha="left", va="top",
                    xytext=(2, 0), textcoords="offset points", color="dimgrey")
    ax.set_xlabel("frequency, Hz")
    ax.set_ylabel("power spectral density (normalised: / (f + 0.1 Hz))")
    ax.set_xlim(0, float(g.freqs[-1]))
    ax.set_ylim(bottom=0)
    ax.ticklabel_format(axis="y", style="scientific", scilimits=(0, 0))
    ax.grid(alpha=0.3)


def _curves(ax2, g: AxisGraph) -> None:
    for c in g.shapers:
        ls, lw = ("-", 2) if c is g.klipper else (":", 1.2)       # Klipper's pick bold
        ax2.plot(g.freqs, c.residual, ls=ls, lw=lw, label=c.label)
    if g.ringtune is not None:
        ax2.plot(g.freqs, g.ringtune.residual, ls="--", lw=2, color="black", label="ringtune: " + g.ringtune.label)
    ax2.set_ylabel("shaper vibration reduction (ratio)")
    ax2.set_ylim(0, 1.05)


def _table(ax, g: AxisGraph) -> None:
    ax.axis("off")
    rows = table_rows(g)
    tab = ax.table(cellText=rows, colLabels=TABLE_HEADER, loc="upper center", cellLoc="center")
    tab.auto_set_font_size(False)
    tab.set_fontsize(8)
    tab.scale(1.0, 1.4)
    ringtune = "" if g.ringtune is None else (
        f"\nringtune's choice: {g.ringtune.fit.name}" + (f" @ {g.ringtune.fit.freq:.1f} Hz, ζ {g.ringtune.damping:g}"
                                                         if g.ringtune.fit.name != "none" else ""))
    ax.text(0.0, 0.02, f"Klipper's pick: {g.klipper.fit.name} @ {g.klipper.fit.freq:.1f} Hz{ringtune}\n"
            f"vibr: remaining vibrations on this spectrum (Klipper's measure, worst of\n"
            f"damping 0.075/0.1/0.15); smoothing at 5000 mm/s², scv {g.scv:g} mm/s;\n"
            f"max_accel (mm/s²): smoothing ≤ 0.12 mm (rounded to 100, as Klipper prints)"
            + "".join(f"\n{n}" for n in g.notes), fontsize=7, va="bottom", transform=ax.transAxes)


def plot_shaper_graph(graphs: list[AxisGraph], path: str | Path) -> Path:
    """One row per axis: spectrum and shaper curves, and the table."""
    matplotlib.use("Agg")
    fig, axes = plt.subplots(len(graphs), 2, figsize=(16, 6.2 * len(graphs)), squeeze=False,
                             gridspec_kw={"width_ratios": [2.6, 1.4]})
    for (ax, tab_ax), g in zip(axes, graphs):
        _spectrum(ax, g)
        ax2 = ax.twinx()
        _curves(ax2, g)
        names = ", ".join(Path(s).name for s in g.sources)
        modes = ", ".join(f"{m.freq:.1f} Hz (ζ {m.damping:.3f}, share {m.share:.2f})" for m in g.fit.modes)
        ax.set_title(f"Axis {g.axis.upper()}: frequency response and shapers ({names})\nfitted modes: {modes}",
                     fontsize=10)
        h1, l1 = ax.get_legend_handles_labels()
        h2, l2 = ax2.get_legend_handles_labels()
        ax2.legend(h1 + h2, l1 + l2, loc="upper right", fontsize=7)
        _table(tab_ax, g)
    fig.tight_layout()
    title = "; ".join(f"{g.axis.upper()}: Klipper {g.klipper.fit.name} @ {g.klipper.fit.freq:.1f} Hz" for g in graphs)
    return save_figure(fig, path, "ringtune graph shapers — " + title)
