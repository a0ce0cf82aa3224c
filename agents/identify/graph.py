"""The numbers of Klipper's shaper graph, per measured axis, and ringtune's choice beside them.

Klipper's ``calibrate_shaper.py -o`` draws, per resonance test: the spectrum (psd_x, psd_y, psd_z and
their sum, normalised to frequencies as its rule uses them), each autotuned shaper's remaining
vibration curve at the frequency the rule fitted for it, the recommended shaper's "after shaper"
spectrum, and a legend with each shaper's frequency, remaining vibrations, smoothing and max_accel.
:func:`shaper_graph` computes exactly those numbers with the rule of
:mod:`ringtune.agents.klipper.rule` (the function ``recommend`` and ``identify`` use, so the three
agree by construction), adds the modes ``identify`` fits to the same file, and, for a TuneConfig,
ringtune's choice judged by Klipper's own measure (remaining vibrations on this spectrum,
pessimised over the test dampings 0.075/0.1/0.15; smoothing at 5000 mm/s² and the scv; max_accel
for 0.12 mm smoothing). Drawing is :mod:`ringtune.agents.identify.graph_plot`.

Units: Hz, mm, mm/s², PSD in (mm/s²)²/Hz (normalised: divided by f + 0.1 Hz, as Klipper does).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ringtune.agents.identify.accelerometer import read_measurement
from ringtune.agents.klipper.rule import (TEST_DAMPING_RATIOS, ShaperFit, recommend_klipper,
                                          remaining_vibrations)
from ringtune.envs.identify import AxisFit
from ringtune.hardware.psd import normalize_to_frequencies
from ringtune.shaping.analysis import impulse_residual, max_accel, smoothing
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.shapers import canonical_name, get_shaper

#: Klipper's graph stops at its MAX_FREQ = 200 Hz; its sweep ends at 135 Hz
GRAPH_FMAX = 200.0


@dataclass
class ShaperCurve:
    """One shaper on the graph: Klipper's fit for it (or ringtune's choice), and its remaining
    vibration ratio per graph frequency (max over the test damping ratios)."""

    fit: ShaperFit
    residual: np.ndarray
    damping: float = 0.1
    flavor: str = "klipper"

    @property
    def label(self) -> str:
        """Klipper's legend text: ``name (freq Hz, vibr=…%, sm~=…, accel=…)``."""
        f = self.fit
        if f.name == "none":
            return "none (shaping off, vibr=100.0%)"
        return (f"{f.name} ({f.freq:.1f} Hz, vibr={100 * f.vibrs:.1f}%, sm~={f.smoothing:.2f}, "
                f"accel={self.max_accel_text})")

    @property
    def max_accel_text(self) -> str:
        """max_accel as Klipper prints it (rounded to 100 mm/s²), or "no limit" without shaping."""
        return f"{self.fit.max_accel_rounded:.0f}" if np.isfinite(self.fit.max_accel) else "no limit"

    def to_dict(self) -> dict:
        f = self.fit
        return {"shaper": f.name, "freq": round(float(f.freq), 1), "damping": self.damping,
                "flavor": self.flavor, "vibrations_pct": round(100.0 * f.vibrs, 1),
                "smoothing_mm": round(f.smoothing, 3),
                "max_accel": f.max_accel_rounded if np.isfinite(f.max_accel) else None,
                "score": f.score, "residual": self.residual}


@dataclass
class AxisGraph:
    """Everything one axis's panel shows."""

    axis: str
    sources: list[str]
    freqs: np.ndarray                       # Hz
    psd: dict[str, np.ndarray]              # "x", "y", "z", "sum": normalised PSD
    fitted: np.ndarray                      # the fitted modes' spectrum, normalised, on ``freqs``
    fit: AxisFit
    shapers: list[ShaperCurve]              # Klipper's table, AUTOTUNE order
    klipper: ShaperCurve                    # the rule's pick
    ringtune: ShaperCurve | None = None     # the TuneConfig's shaper on this axis
    scv: float = 5.0
    notes: list[str] = field(default_factory=list)

    @property
    def after_shaper(self) -> np.ndarray:
        """The sum spectrum times the pick's remaining vibration (Klipper's "After shaper")."""
        return self.psd["sum"] * self.klipper.residual

    def to_dict(self) -> dict:
        return {"axis": self.axis, "sources": self.sources, "scv": self.scv,
                "freqs_hz": self.freqs, "psd": self.psd, "fitted_psd": self.fitted,
                "modes": [{"freq": round(m.freq, 2), "damping": round(m.damping, 3), "share": round(m.share, 2)}
                          for m in self.fit.modes],
                "shapers": [s.to_dict() for s in self.shapers],
                "klipper": self.klipper.to_dict(), "ringtune": self.ringtune.to_dict() if self.ringtune else None,
                "after_shaper_psd": self.after_shaper, "notes": self.notes}


def _residual(amps, times, freqs: np.ndarray, dampings=TEST_DAMPING_RATIOS) -> np.ndarray:
    """Klipper's shaper curve on its graph: the worst remaining vibration ratio over the test dampings."""
    return np.max([impulse_residual(amps, times, freqs, z) for z in dampings], axis=0)


def _curve(fit: ShaperFit, freqs: np.ndarray) -> ShaperCurve:
    s = get_shaper(fit.name, fit.freq, 0.1, "klipper")
    return ShaperCurve(fit, _residual(s.amplitudes, s.times, freqs))


def _ringtune_curve(config: TuneConfig, axis: str, freqs: np.ndarray, psd: np.ndarray,
                    scv: float) -> ShaperCurve | None:
    """The TuneConfig's shaper on ``axis`` judged as Klipper judges its own candidates."""
    name, freq, damping = config.axis(axis)
    if canonical_name(name) in ("none", "daa"):
        flat = np.ones_like(freqs)
        return ShaperCurve(ShaperFit("none", 0.0, 1.0, 0.0, 0.0, float("inf")), flat, 0.0, config.flavor)
    s = get_shaper(name, freq, damping, config.flavor, where=f"config: shaper_{axis}")
    vibrs = max(remaining_vibrations(s.amplitudes, s.times, freqs, psd, z) for z in TEST_DAMPING_RATIOS)
    sm = smoothing(s, scv=scv)
    fit = ShaperFit(s.name, float(freq), float(vibrs), sm, sm * (vibrs ** 1.5 + 0.2 * vibrs + 0.01),
                    float(max_accel(s, scv)))
    return ShaperCurve(fit, _residual(s.amplitudes, s.times, freqs), float(s.damping), config.flavor)


def _normalised_columns(items: list, fmax: float) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Klipper's graph spectra: each column normalised to frequencies; several files of one axis
    are averaged on the first file's bins (what the graph of a combined run shows)."""
    base = items[0].freqs
    keep = base <= fmax
    cols: dict[str, np.ndarray] = {}
    for key in ("x", "y", "z", "sum"):
        arrays = [getattr(p, f"psd_{key}") for p in items]
        if any(a is None for a in arrays):
            continue
        total = sum(np.interp(base, p.freqs, normalize_to_frequencies(p.freqs, a)) for p, a in zip(items, arrays))
        cols[key] = (total / len(items))[keep]
    return base[keep], cols


def axis_graph(axis: str, items: list, fit: AxisFit, config: TuneConfig | None = None,
               scv: float = 5.0, fmax: float = GRAPH_FMAX) -> AxisGraph:
    """One axis's graph from its resonance spectra ``items`` (PSD objects) and the fit of them."""
    rec = recommend_klipper(list(items), "head", scv)
    freqs, cols = _normalised_columns(items, fmax)
    fitted = normalize_to_frequencies(freqs, np.interp(freqs, fit.x, fit.fitted, left=np.nan, right=np.nan))
    shapers = [_curve(s, freqs) for s in rec.shapers]
    pick = next((c for c in shapers if c.fit is rec.best), None) or _curve(rec.best, freqs)
    notes = []
    ringtune = None
    if config is not None:
        ringtune = _ringtune_curve(config, axis, freqs, cols["sum"], scv)
        if config.flavor != "klipper":
            notes.append(f"ringtune's choice uses {config.firmware}'s own shaper formulas "
                         f"({config.flavor}); Klipper's candidates use Klipper's")
    sources = sorted({str(p.source) for p in items})
    return AxisGraph(axis, sources, freqs, cols, fitted, fit, shapers, pick, ringtune, float(scv), notes)


def shaper_graph(paths: list[str | Path], config: TuneConfig | None = None, scv: float = 5.0,
                 axis: str | None = None) -> tuple[list[AxisGraph], list[str]]:
    """The graph of every measured axis (X first) from Klipper resonance files, and the warnings
    about the files (each naming its file)."""
    meas = read_measurement(paths, axis=axis)
    fits = meas.by_axis()
    graphs = [axis_graph(ax, meas.psds[ax], fits[ax], config, scv) for ax in ("x", "y") if ax in meas.psds]
    return graphs, list(meas.warnings)
