"""How each shaper's print time and quality respond to one factor (the sweep behind ``ringtune study``).

Factors: ``freq-error`` (the shaper frequency off by a fraction of its tuned value), ``mass`` (print
mass on the bed, kg; the shapers stay tuned for the empty bed) and ``accel`` (printing acceleration,
mm/s²). Each shaper starts tuned as Klipper's rule tunes it on the printer's simulated resonance
test (a shaper outside Klipper's list: the axis's strongest mode); every value of the factor is
then evaluated with :func:`ringtune.envs.evaluate.evaluate_many` (print time over the whole job,
quality from physics on its quality windows).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import matplotlib
import matplotlib.pyplot as plt
import numpy as np

from ringtune.agents.klipper.baseline import klipper_rule_on_simulated_test
from ringtune.agents.tune.pareto import words
from ringtune.agents.tune.space import checked_shapers
from ringtune.envs.evaluate import evaluate_many
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.firmware import FIRMWARES
from ringtune.shaping.shapers import available_shapers

#: factor -> (label, unit, default values (lo, hi, n) or None: from the printer)
FACTORS = {"freq-error": ("shaper frequency error", "fraction", (-0.3, 0.3, 13)),
           "mass": ("print mass on the bed", "kg", (0.0, 1.0, 6)),
           "accel": ("acceleration", "mm/s²", None)}
#: how a factor's unit is shown on the plot's axis: unit -> (scale, shown unit)
_AXIS_UNITS = {"fraction": (100, "%")}


@dataclass
class ShaperSweep:
    """One shaper across the factor's values: tuned frequencies (Hz), print time (s), quality (mm)
    and whether steps were lost, one entry per value."""

    freq_x: float
    freq_y: float
    print_time_s: list[float] = field(default_factory=list)
    quality_mm: list[float] = field(default_factory=list)
    step_loss: list[bool] = field(default_factory=list)


def offered_shapers(firmware: str, shapers: list[str] | None = None) -> list[str]:
    """The shapers to compare: ``shapers`` (checked against the firmware's) or all it offers but
    ``custom``."""
    if firmware not in FIRMWARES:
        raise RingtuneError(f"must be one of {', '.join(FIRMWARES)}, not {firmware!r}", "firmware")
    offered = [s for s in available_shapers(FIRMWARES[firmware].flavor) if s != "custom"]
    return checked_shapers(firmware, [s.strip().lower() for s in shapers] if shapers else offered, offered)


def factor_values(factor: str, printer: Any, values: list[float] | None = None) -> list[float]:
    """The values to sweep: ``values`` (checked) or the factor's default range (accel: 0.3–2.5× the
    printer's own acceleration, rounded to 100 mm/s²)."""
    if factor not in FACTORS:
        raise RingtuneError(f"must be one of {', '.join(FACTORS)}, not {factor!r}", "factor")
    if values is not None:
        vals = [float(v) for v in values]
    elif factor == "accel":
        a0 = float(printer.limits.accel)
        vals = [round(float(a), -2) for a in np.linspace(0.3 * a0, 2.5 * a0, 8)]
    else:
        lo, hi, n = FACTORS[factor][2]
        vals = [round(float(v), 4) for v in np.linspace(lo, hi, n)]
    if not vals:
        raise RingtuneError("no values", "values")
    refused, must = _VALUE_RULES[factor]
    if any(refused(v) for v in vals):
        raise RingtuneError(must, "values")
    return vals


#: factor -> (a value it refuses, what the values must be)
_VALUE_RULES = {
    "freq-error": (lambda v: v <= -0.9, "frequency errors must be > -0.9 (fractions, e.g. -0.2 for 20 % low)"),
    "mass": (lambda v: v < 0, "print mass must be ≥ 0 kg"),
    "accel": (lambda v: v <= 0, "accelerations must be > 0 mm/s²"),
}


def tuned_frequencies(printer: Any, firmware: str, shapers: list[str],
                      note: Callable[[str], None] = lambda message: None) -> dict[str, dict[str, float]]:
    """{shaper: {"x": Hz, "y": Hz}}: Klipper's per-shaper fit on the printer's simulated resonance
    test where it has one, else the axis's strongest mode (said through ``note``); one frequency for
    both axes on firmwares with one shaper for all axes."""
    try:
        fits, _ = klipper_rule_on_simulated_test(printer, firmware, "head")
    except (ImportError, RingtuneError) as exc:
        note(f"Klipper's fit unavailable ({exc}); shapers tuned to the main mode")
        fits = {}
    fitted = {ax: {f.name: f.freq for f in fit.shapers} for ax, fit in fits.items()}
    main = {ax: max(getattr(printer, ax).modes, key=lambda m: m.share or 0).freq for ax in ("x", "y")}
    y = "x" if FIRMWARES[firmware].one_shaper else "y"          # one shaper for all axes: Y runs X's
    return {s: {"x": round(fitted.get("x", {}).get(s, main["x"]), 1), "y": round(fitted.get(y, {}).get(s, main[y]), 1)}
            for s in shapers}


def sweep(printer: Any, job: Any, firmware: str, factor: str, values: list[float],
          tuned: dict[str, dict[str, float]], quality: str = "overshoot_mm",
          backend: str = "mujoco", freq_margin: float = 0.0) -> dict[str, ShaperSweep]:
    """Evaluate every shaper of ``tuned`` at every value of ``factor`` on ``printer`` and ``job``
    (a G-code path or None for the built-in test print); ``quality`` is a Metrics field in mm;
    ``freq_margin``: judged as ``evaluate_many`` judges with it (fraction; 0 = the exact model)."""
    results = {s: ShaperSweep(f["x"], f["y"]) for s, f in tuned.items()}
    for v in values:
        scale = 1 + v if factor == "freq-error" else 1.0      # the shapers' frequencies off by v
        acc = float(v) if factor == "accel" else None
        pr = dataclasses.replace(printer, print_mass=float(v)) if factor == "mass" else printer
        configs = [TuneConfig(firmware=firmware, shaper_x=s, shaper_y=s,
                              freq_x=0.0 if s == "none" else round(f["x"] * scale, 2),
                              freq_y=0.0 if s == "none" else round(f["y"] * scale, 2), accel=acc)
                   for s, f in tuned.items()]
        for s, m in zip(tuned, evaluate_many(configs, pr, job, backend=backend, freq_margin=freq_margin)):
            results[s].print_time_s.append(float(m.print_time_s))
            results[s].quality_mm.append(float(getattr(m, quality)))
            results[s].step_loss.append(bool(m.step_loss))
    return results


def write_csv(path: str | Path, factor: str, values: list[float], results: dict[str, ShaperSweep],
              quality: str) -> None:
    """One row per shaper and value: factor, shaper, freq_x, freq_y, print_time_s, quality, step_loss."""
    with open(path, "w") as f:
        f.write(f"{factor},shaper,freq_x,freq_y,print_time_s,{quality},step_loss\n")
        for s, r in results.items():
            for i, v in enumerate(values):
                f.write(f"{v:g},{s},{r.freq_x},{r.freq_y},{r.print_time_s[i]:.4f},"
                        f"{r.quality_mm[i]:.6f},{int(r.step_loss[i])}\n")


def plot_sweep(path: str | Path, factor: str, values: list[float], results: dict[str, ShaperSweep],
               quality: str, title: str) -> None:
    """Two panels against the factor (print time, quality), one line per shaper; red x = lost steps."""
    matplotlib.use("Agg")
    label, unit, _ = FACTORS[factor]
    scale, shown = _AXIS_UNITS.get(unit, (1, unit))
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(8, 7.5), dpi=120, sharex=True)
    xs = [scale * v for v in values]
    for s, r in results.items():
        ls = "--" if s == "none" else "-"
        a1.plot(xs, r.print_time_s, ls, marker="o", ms=3, label=s)
        a2.plot(xs, r.quality_mm, ls, marker="o", ms=3, label=s)
        bad = np.flatnonzero(r.step_loss)
        if bad.size:
            a2.scatter(np.take(xs, bad), np.take(r.quality_mm, bad), marker="x", c="red", zorder=5)
    a1.set_ylabel("print time (s)")
    a2.set_ylabel(f"{words(quality)[0]} (mm)")
    a2.set_xlabel(f"{label} ({shown})")
    for a in (a1, a2):
        a.grid(True, alpha=0.3)
    a1.legend(fontsize=8, ncol=4)
    a1.set_title(f"{label}: {title}\n(red x = lost steps)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
