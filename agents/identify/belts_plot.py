"""Drawing the CoreXY belt comparison (:mod:`ringtune.agents.identify.belts`): both diagonal
spectra overlaid (and the model fitted to them), the paired peaks marked, and a panel with the
similarity and its definition, the pairs' differences, the belts' stiffnesses and what it means.
Every text also goes into the PNG's ``Description`` chunk."""

from __future__ import annotations

import textwrap
from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt

from ringtune.agents.identify.belts import SWEEP, BeltComparison
from ringtune.envs.figure import save_figure

_STYLE = {"a": ("belt A (AXIS=1,1, motor A)", "tab:blue"), "b": ("belt B (AXIS=1,-1, motor B)", "tab:orange")}
PAIR_HEADER = ("peak A Hz", "peak B Hz", "B − A Hz", "amp. A − B %")


def pair_rows(c: BeltComparison) -> list[tuple[str, ...]]:
    """The pairs table as drawn: '-' where a peak has no partner."""
    def num(v, fmt):
        return "-" if v is None else format(v, fmt)

    return [(num(p.freq_a, ".1f"), num(p.freq_b, ".1f"), num(p.freq_diff, "+.1f"), num(p.amp_diff_pct, "+.0f"))
            for p in c.pairs]


def summary_lines(c: BeltComparison) -> list[str]:
    """The panel's text, one line each (also printed by the command)."""
    lines = [f"similarity: {c.similarity:.1f} %",
             f"  (cosine similarity of the two psd_xyz over {SWEEP[0]:g}-{SWEEP[1]:g} Hz:",
             "   Σ a·b / √(Σ a² · Σ b²); 100 % = same shape)"]
    if c.mismatch is not None:
        lines += [f"belt stiffness: A {c.stiffness[0]:.0f} N/m, B {c.stiffness[1]:.0f} N/m",
                  f"  (k_A − k_B)/mean = {100 * c.mismatch:+.1f} % ± {100 * c.mismatch_error:.1f} % "
                  "(model fitted to both tests)"]
    return lines


def plot_belts(c: BeltComparison, path: str | Path) -> Path:
    """Spectra on the left, the numbers on the right."""
    matplotlib.use("Agg")
    fig, (ax, side) = plt.subplots(1, 2, figsize=(15, 6.2), gridspec_kw={"width_ratios": [2.4, 1.6]})
    _spectra(ax, c)
    _numbers(side, c)
    fig.tight_layout()
    return save_figure(fig, path, f"ringtune graph belts — similarity {c.similarity:.1f} %")


def _spectra(ax, c: BeltComparison) -> None:
    """The two tests' spectra, the model fitted to them, and their peaks numbered by pair."""
    for k, (label, colour) in _STYLE.items():
        ax.plot(c.freqs[k], c.psd[k], color=colour, lw=1.8, label=f"{label}: {Path(c.sources[k]).name}")
        if k in c.model:
            ax.plot(c.freqs[k], c.model[k], color=colour, lw=1, ls="--", label=f"{label.split(' (')[0]}: model fit")
    for i, p in enumerate(c.pairs, 1):
        for f, a, k in ((p.freq_a, p.amp_a, "a"), (p.freq_b, p.amp_b, "b")):
            if f is not None:
                ax.plot([f], [a], "o", color=_STYLE[k][1], ms=6)
                ax.annotate(f"{i}{k.upper()} {f:.1f} Hz", (f, a), fontsize=7, xytext=(4, 4), textcoords="offset points")
    ax.set_xlim(0, SWEEP[1] + 10)
    ax.set_ylim(bottom=0)
    ax.set_xlabel("frequency, Hz")
    ax.set_ylabel("PSD of the head acceleration, (mm/s²)²/Hz (psd_xyz)")
    ax.ticklabel_format(axis="y", style="scientific", scilimits=(0, 0))
    ax.set_title(f"CoreXY belts: the two diagonal resonance tests (similarity {c.similarity:.1f} %)", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper right")


def _numbers(side, c: BeltComparison) -> None:
    """The peak pairs' table, the summary and what it means, with the notes."""
    side.axis("off")
    rows = pair_rows(c)
    if rows:
        tab = side.table(cellText=rows, colLabels=PAIR_HEADER, rowLabels=[str(i) for i in range(1, len(rows) + 1)],
                         loc="upper center", cellLoc="center")
        tab.auto_set_font_size(False)
        tab.set_fontsize(8)
    text = summary_lines(c) + [""] + textwrap.wrap(c.meaning(), 70) + [t for n in c.notes for t in textwrap.wrap(n, 70)]
    side.text(0.0, 0.0, "\n".join(text), fontsize=8, va="bottom", transform=side.transAxes)
