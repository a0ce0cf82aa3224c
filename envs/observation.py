"""The observation's parts from resonance tests (simulated, or measured when a policy is applied to a
real printer): the binned spectrum (:func:`spectrum_features`), the dominant resonance of each axis
(:func:`spectrum_peaks`) and its position on a log scale (:func:`peak_features`)."""

from __future__ import annotations

import math

import numpy as np

from ringtune.shaping.errors import RingtuneError


def log_position(x, lo: float, hi: float):
    """Where ``x`` sits on a log scale from ``lo`` (−1) to ``hi`` (+1); numbers or arrays."""
    return 2.0 * np.log(np.asarray(x, float) / lo) / math.log(hi / lo) - 1.0


def _axis_spectra(spectra: dict) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """[(axis, freqs Hz, psd)] of X then Y from ``{"x": (freqs, psd), "y": …}``; a missing axis takes
    the other's."""
    if not spectra:
        raise RingtuneError("needs at least one resonance spectrum (x or y)", "psd")
    return [(axis, *(np.asarray(col, float) for col in spectra.get(axis) or spectra.get(other)))
            for axis, other in (("x", "y"), ("y", "x"))]


def spectrum_features(spectra: dict, n_bins: int = 24,
                      spectrum_range: tuple[float, float] = (10.0, 160.0)) -> np.ndarray:
    """The observation's spectrum part from resonance-test PSDs ``{"x": (freqs Hz, psd), "y": …}``
    (simulated here, measured when a policy is applied to a real printer).

    Mean PSD per bin of ``n_bins`` equal bins over ``spectrum_range`` Hz, X then Y,
    ``1 + log10(psd / max)/3`` clipped to [-1, 1] (X and Y share the max). A missing axis takes
    the other's spectrum. Returns float32 (2·n_bins,)."""
    edges = np.linspace(spectrum_range[0], spectrum_range[1], n_bins + 1)
    binned = []
    for axis, freqs, psd in _axis_spectra(spectra):
        if freqs.shape != psd.shape or freqs.ndim != 1:
            raise RingtuneError(f"frequency and PSD columns differ in shape ({freqs.shape} vs {psd.shape})",
                                f"psd {axis}")
        idx = np.digitize(freqs, edges) - 1
        ok = (idx >= 0) & (idx < n_bins)
        total = np.bincount(idx[ok], weights=psd[ok], minlength=n_bins)
        count = np.bincount(idx[ok], minlength=n_bins)
        binned.append(total / np.maximum(count, 1))
    b = np.concatenate(binned)
    b = np.log10(np.maximum(b, 1e-300) / max(b.max(), 1e-300))
    return np.clip(1.0 + b / 3.0, -1.0, 1.0).astype(np.float32)


def spectrum_peaks(spectra: dict, spectrum_range: tuple[float, float] = (10.0, 160.0)) -> tuple[float, float]:
    """(X, Y) Hz: the dominant resonance of each axis's resonance-test PSD (``{"x": (freqs Hz,
    psd), …}``, simulated or measured): the maximum of ``psd/f`` smoothed over 3 neighbouring
    bins, searched within ``spectrum_range``. A missing axis takes the other's.

    Why ``psd/f``: Klipper's sweep commands an acceleration amplitude ∝ f, so the PSD is
    ∝ f²·|T(f)|² (T the transmissibility); the raw maximum drifts to the top of the sweep when a
    mode sits above it, ``psd/f²`` = |T|² is lifted at low f by the sensor noise; ``psd/f`` picks
    the resonance on the simulated printers and on the real files (e.g. the Ender-3's 45 Hz X
    mode rather than its 58 Hz hump)."""
    out = []
    for axis, freqs, psd in _axis_spectra(spectra):
        ok = (freqs >= spectrum_range[0]) & (freqs <= spectrum_range[1]) & np.isfinite(psd)
        if not ok.any():
            raise RingtuneError(f"no PSD bins within {spectrum_range[0]:g}-{spectrum_range[1]:g} Hz", f"psd {axis}")
        f, p = freqs[ok], psd[ok] / np.maximum(freqs[ok], 1e-9)
        if p.size >= 3:
            p = np.convolve(p, np.ones(3) / 3.0, mode="same")
        out.append(_refine_peak(f, psd[ok] / np.maximum(f, 1e-9), int(np.argmax(p))))
    return out[0], out[1]


def _refine_peak(f: np.ndarray, p: np.ndarray, k: int) -> float:
    """Hz: the peak near bin ``k`` of ``p`` between the bins: the vertex of the parabola through
    the largest unsmoothed bin (``k`` or a neighbour) and its two neighbours in log p, on a uniform
    grid (a PSD's resolution is fs/nperseg, e.g. 1.56 Hz: 3 % of a 50 Hz resonance, enough to
    matter for a shaper on it). Falls back to the bin's frequency at the edges or off-grid."""
    lo, hi = max(k - 1, 0), min(k + 2, p.size)
    j = lo + int(np.argmax(p[lo:hi]))
    if j < 1 or j > p.size - 2 or np.any(p[j - 1:j + 2] <= 0):
        return float(f[k])
    df = f[j + 1] - f[j]
    if not (df > 0 and abs((f[j] - f[j - 1]) - df) <= 1e-6 * df):
        return float(f[j])
    a, b, c = np.log(p[j - 1:j + 2])
    den = a - 2.0 * b + c
    shift = 0.5 * (a - c) / den if den < 0 else 0.0
    return float(f[j] + float(np.clip(shift, -0.5, 0.5)) * df)


def peak_features(peaks, spectrum_range: tuple[float, float] = (10.0, 160.0)) -> np.ndarray:
    """The observation's peak part: ``2·ln(f/lo)/ln(hi/lo) − 1`` per axis (X, Y), float32 in [-1, 1]."""
    lo, hi = spectrum_range
    return log_position(np.clip(np.asarray(peaks, float), lo, hi), lo, hi).astype(np.float32)
