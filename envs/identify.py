"""Vibration modes fitted to accelerometer data given as arrays (reading the files is
:mod:`ringtune.agents.identify.accelerometer`; the printer description, :mod:`ringtune.agents.identify.description`).

Two kinds of measurement:

- a resonance sweep PSD (Klipper ``TEST_RESONANCES``): the toolhead's measured acceleration is the
  commanded one times the transmissibility of base-excited modes,
  ``T(f) = 1 + Σ sᵢ·rᵢ² / (1 − rᵢ² + 2jζᵢrᵢ)``, ``rᵢ = f/fᵢ`` (so a single mode of share 1 gives the
  classic ``(1 + 2jζr)/(1 − r² + 2jζr)``); Klipper's sweep commands ``accel_per_hz·f`` at every
  frequency for the same time, so the PSD is modelled as ``C·f^p·|T(f)|² + b`` (``p`` ≈ 2, ``b`` a
  noise floor) and fitted in log space to the band ``[fmin, fmax]``. Damping comes from that fit
  (``damping="fit"``) or from each peak's half-power width (``damping="half-power"``).
- a free-decay capture (RRF ``M956`` after a move): a sum of damped sinusoids
  ``Σ Aₖ·exp(−ζₖωₖt)·cos(ωₖ√(1−ζₖ²)t + φₖ) + c`` fitted by variable projection (amplitudes and phases
  linear, frequency and damping non-linear), started from the spectrum's peaks.

Shares are the modes' parts of the nozzle response, normalised to sum to 1 per axis. A spectrum fit
warns when the data stop short of the band, a mode sits at its edge, a damping ratio is implausible
or the fit is poor. The added-mass method (two spectra of one axis, with and without a known mass) is
:mod:`ringtune.envs.added_mass`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
from scipy.optimize import least_squares
from scipy.signal import find_peaks

from ringtune.shaping.errors import RingtuneError


@dataclass
class FittedMode:
    """A mode: natural frequency (Hz), damping ratio, share of the axis response, and the
    frequency of the measured peak it explains (Hz; None if it has none in the band)."""

    freq: float
    damping: float
    share: float
    peak_freq: float | None = None
    fitted_peak: float | None = None      # Hz: where the fitted spectrum peaks near this mode


@dataclass
class AxisFit:
    """The modes fitted to one measurement of one axis, and the curves to plot."""

    axis: str
    kind: str                    # "psd" or "decay"
    source: str
    modes: list[FittedMode]
    x: np.ndarray                # frequency (Hz) for psd, time (s) for decay
    measured: np.ndarray
    fitted: np.ndarray
    r2: float                    # coefficient of determination (log PSD for "psd")
    method: str = "fit"
    notes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)   # what makes the fit doubtful
    x_measured: np.ndarray | None = None   # the measured bins themselves (psd), for plots
    y_measured: np.ndarray | None = None
    params: np.ndarray | None = None       # psd: the fitted (ln C, p, ln b, (freq, damping, raw share)…)

    def to_dict(self) -> dict:
        return {"axis": self.axis, "kind": self.kind, "source": self.source, "method": self.method,
                "r2": self.r2, "notes": self.notes, "warnings": self.warnings,
                "modes": [{"freq": m.freq, "damping": m.damping, "share": m.share, "peak_freq": m.peak_freq,
                           "fitted_peak": m.fitted_peak} for m in self.modes]}


# -- PSD ------------------------------------------------------------------------------------------

def transmissibility(f: np.ndarray, modes: list[tuple[float, float, float]]) -> np.ndarray:
    """Complex ``T(f) = 1 + Σ s·r²/(1 − r² + 2jζr)`` for modes ``(freq Hz, damping, share)``."""
    t = np.ones_like(f, dtype=complex)
    for fn, z, s in modes:
        r = f / fn
        t += s * r * r / (1.0 - r * r + 2j * z * r)
    return t


def _half_power(f: np.ndarray, p: np.ndarray, i: int) -> float | None:
    """Damping ratio from the half-power width of the peak at index ``i`` (linear interpolation)."""
    half = p[i] / 2.0
    lo = i
    while lo > 0 and p[lo] > half:
        lo -= 1
    hi = i
    while hi < len(p) - 1 and p[hi] > half:
        hi += 1
    if p[lo] > half or p[hi] > half:
        return None
    f1 = f[lo] + (half - p[lo]) * (f[lo + 1] - f[lo]) / (p[lo + 1] - p[lo])
    f2 = f[hi - 1] + (p[hi - 1] - half) * (f[hi] - f[hi - 1]) / (p[hi - 1] - p[hi])
    return float((f2 - f1) / (2.0 * f[i]))


def find_peaks_psd(f: np.ndarray, p: np.ndarray, max_peaks: int = 3, rel: float = 0.15) -> list[int]:
    """Indices of the highest resonance peaks (prominence ≥ ``rel``·max), highest first."""
    idx, props = find_peaks(p, prominence=rel * p.max())
    order = np.argsort(p[idx])[::-1]
    return [int(idx[k]) for k in order[:max_peaks]]


def psd_model(x: np.ndarray, f: np.ndarray) -> np.ndarray:
    """The sweep PSD model ``C·(f/50)^p·|T(f)|² + b`` of parameters ``x = (ln C, p, ln b, (freq, damping,
    share)…)``."""
    m = np.asarray(x[3:]).reshape(-1, 3)
    lc, lb = np.clip(x[0], -700.0, 700.0), np.clip(x[2], -700.0, 700.0)    # trial steps may be wild
    return np.exp(lc) * (f / 50.0) ** x[1] * np.abs(transmissibility(f, [tuple(r) for r in m])) ** 2 + np.exp(lb)


def psd_model_jacobian(x: np.ndarray, f: np.ndarray) -> np.ndarray:
    """d ln M / dx of the sweep PSD model ``M`` (:func:`psd_model`) at parameters ``x``: one row per
    frequency ``f`` (Hz), one column per parameter (ln C, p, ln b, then freq, damping, share per mode).

    With ``A = C·(f/50)^p·|T|²`` and ``r = f/fₙ``, ``D = 1 − r² + 2jζr``: ``∂T/∂s = r²/D``,
    ``∂T/∂ζ = −2j·s·r³/D²``, ``∂T/∂fₙ = −2·s·r²·(1 + jζr)/(fₙ·D²)``, and
    ``∂|T|²/∂θ = 2·Re(conj(T)·∂T/∂θ)``."""
    m = np.asarray(x[3:]).reshape(-1, 3)
    lc, lb = np.clip(x[0], -700.0, 700.0), np.clip(x[2], -700.0, 700.0)
    t = transmissibility(f, [tuple(r) for r in m])
    t2 = np.abs(t) ** 2
    a = np.exp(lc) * (f / 50.0) ** x[1]
    total = a * t2 + np.exp(lb)
    cols = [a * t2, a * t2 * np.log(f / 50.0), np.full_like(f, np.exp(lb))]
    for fn, z, s in m:
        r = f / fn
        d = 1.0 - r * r + 2j * z * r
        for dt in (-2.0 * s * r * r * (1.0 + 1j * z * r) / (fn * d * d), -2j * s * r ** 3 / (d * d), r * r / d):
            cols.append(a * 2.0 * np.real(np.conj(t) * dt))
    return np.stack(cols, axis=1) / total[:, None]


def psd_weights(p: np.ndarray) -> np.ndarray:
    """Log-space residual weights, heavier at the resonances (the peaks are what a shaper must hit)."""
    return 1.0 + 3.0 * p / p.max()


def _usable_band(freqs, psd, fmin: float, fmax: float, where: str) -> tuple[np.ndarray, np.ndarray]:
    """(f Hz, psd) between ``fmin`` and ``fmax``, the psd floored at 1e-9 of its peak (its log is
    fitted); refused with fewer than 8 finite, positive bins."""
    band = (freqs >= fmin) & (freqs <= fmax)
    f, p = freqs[band], psd[band]
    if len(f) < 8 or not np.all(np.isfinite(p)) or p.max() <= 0:
        raise RingtuneError(f"too few usable bins between {fmin:g} and {fmax:g} Hz", where)
    return f, np.maximum(p, p.max() * 1e-9)


def _start_and_bounds(f, p, logp, peaks: list[int], z0: list[float], df: float) -> tuple[np.ndarray, list, list]:
    """(x0, lower, upper) of :func:`psd_model`'s parameters: C, exponent, background, then per peak
    frequency (±max(3 bins, 10 %)), damping and share (equal); C scaled so that the start meets
    the data at the highest peak."""
    fpk = f[peaks]
    x0 = [0.0, 2.0, math.log(p.min())]
    lo, hi = [-np.inf, -2.0, -np.inf], [np.inf, 6.0, np.inf]
    for k in range(len(peaks)):
        x0 += [fpk[k], z0[k], 1.0 / len(peaks)]
        lo += [fpk[k] - max(3 * df, 0.1 * fpk[k]), 0.005, 0.005]
        hi += [fpk[k] + max(3 * df, 0.1 * fpk[k]), 0.5, 3.0]
    x0 = np.array(x0, dtype=float)
    ipk = peaks[int(np.argmax(p[peaks]))]
    x0[0] = logp[ipk] - math.log(psd_model(x0, f[ipk:ipk + 1])[0] + 1e-300)
    return np.clip(x0, np.array(lo) + 1e-9, np.array(hi) - 1e-9), lo, hi


def _fitted_modes(x: np.ndarray, fpk, hp: list, damping: str, f) -> tuple[list, np.ndarray, np.ndarray]:
    """(modes, fine grid, model curve) from the fitted parameters: shares normalised, damping from the
    fit or the half-power points, each mode's peak on the fitted curve within 15 % of it."""
    m = x[3:].reshape(len(fpk), 3)
    total = sum(m[:, 2])
    out = []
    for k in range(len(fpk)):
        fn, z, s = m[k, 0], m[k, 1], m[k, 2]
        zz = z if damping == "fit" else (hp[k] if hp[k] is not None else z)
        out.append(FittedMode(float(fn), float(zz), float(s / total), float(fpk[k])))
    fine = np.linspace(f[0], f[-1], 2000)
    curve = psd_model(x, fine)
    for mode in out:
        near = np.abs(fine - mode.freq) <= 0.15 * mode.freq
        mode.fitted_peak = float(fine[near][np.argmax(curve[near])]) if near.any() else None
    return out, fine, curve


def identify_psd(freqs: np.ndarray, psd: np.ndarray, axis: str = "sum", source: str = "psd",
                 max_modes: int = 3, fmin: float = 5.0, fmax: float = 135.0,
                 damping: str = "fit") -> AxisFit:
    """Fit modes to one resonance spectrum: ``freqs`` (Hz) and ``psd`` ((mm/s²)²/Hz) of the axis
    ``axis`` ("x", "y" or "sum"), measured in ``source`` (named in errors and notes)."""
    if damping not in ("fit", "half-power"):
        raise RingtuneError("must be 'fit' or 'half-power'", "damping")
    freqs = np.asarray(freqs, dtype=float)
    where = source or "psd"
    f, p = _usable_band(freqs, np.asarray(psd, dtype=float), fmin, fmax, where)
    peaks = sorted(find_peaks_psd(f, p, max_modes) or [int(np.argmax(p))], key=lambda i: f[i])
    hp = [_half_power(f, p, i) for i in peaks]
    z0 = [min(max(h if h else 0.05, 0.01), 0.4) for h in hp]
    df = float(np.median(np.diff(f)))
    logp = np.log(p)
    weight = psd_weights(p)
    x0, lo, hi = _start_and_bounds(f, p, logp, peaks, z0, df)
    sol = least_squares(lambda x: weight * (np.log(psd_model(x, f)) - logp), x0,
                        jac=lambda x: weight[:, None] * psd_model_jacobian(x, f),
                        bounds=(lo, hi), x_scale="jac", max_nfev=4000)
    res = np.log(psd_model(sol.x, f)) - logp
    r2 = float(1.0 - (res ** 2).sum() / ((logp - logp.mean()) ** 2).sum())
    out, fine, curve = _fitted_modes(sol.x, f[peaks], hp, damping, f)
    fit = AxisFit(axis, "psd", where, out, fine, np.interp(fine, f, p), curve, r2, damping,
                  x_measured=f, y_measured=p, params=np.asarray(sol.x, dtype=float))
    if damping == "half-power" and any(h is None for h in hp):
        fit.notes.append("a peak had no half-power points in the band; its damping comes from the fit")
    fit.warnings += psd_fit_warnings(fit, freqs, fmin, fmax, df)
    return fit


#: below this r² a fit is reported as poor
POOR_R2 = 0.8
#: damping ratios outside this range are implausible for a printer's belt and frame modes
PLAUSIBLE_DAMPING = (0.02, 0.3)


def psd_fit_warnings(fit: AxisFit, freqs: np.ndarray, fmin: float, fmax: float, df: float) -> list[str]:
    """What makes a spectrum fit doubtful: data that stop short of the band asked for (``fmin`` to
    ``fmax`` Hz, by default Klipper's sweep), a mode at the edge of the data (seen from one side
    only), an implausible damping ratio, or a poor fit (r² < :data:`POOR_R2`)."""
    out = []
    lo, hi = float(np.min(freqs)), float(np.max(freqs))
    if hi < fmax - 2 * df:
        out.append(f"the data end at {hi:.1f} Hz, short of the {fmax:g} Hz the fit covers (Klipper's "
                   "sweep goes to 135 Hz): modes above are not seen")
    if lo > fmin + 2 * df:
        out.append(f"the data start at {lo:.1f} Hz, above the {fmin:g} Hz the fit covers")
    f_lo, f_hi = max(lo, fmin), min(hi, fmax)
    for m in fit.modes:
        if m.freq > f_hi - 3 * df or m.freq < f_lo + 3 * df:
            out.append(f"the mode at {m.freq:.1f} Hz sits at the edge of the data ({f_lo:.1f}-{f_hi:.1f} "
                       "Hz): its frequency and damping are extrapolated from one side of the peak")
        if not PLAUSIBLE_DAMPING[0] <= m.damping <= PLAUSIBLE_DAMPING[1]:
            out.append(f"damping {m.damping:.3f} of the mode at {m.freq:.1f} Hz is outside what printers "
                       f"show ({PLAUSIBLE_DAMPING[0]:g}-{PLAUSIBLE_DAMPING[1]:g}): check the measurement")
    if fit.r2 < POOR_R2:
        out.append(f"poor fit: the modes explain {100 * fit.r2:.0f} % of the log spectrum "
                   f"(r² {fit.r2:.3f} < {POOR_R2:g})")
    return out


# -- free decay -------------------------------------------------------------------------------------

def _decay_basis(t: np.ndarray, params: np.ndarray) -> np.ndarray:
    cols = [np.ones_like(t)]
    for fn, z in params.reshape(-1, 2):
        w = 2 * math.pi * fn
        env = np.exp(-z * w * t)
        wd = w * math.sqrt(max(1 - z * z, 1e-9))
        cols += [env * np.cos(wd * t), env * np.sin(wd * t)]
    return np.stack(cols, axis=1)


def _ringing(t, accel, rate: float | None, start: float | None, source: str) -> tuple:
    """(tt s from the start of the ringing, acceleration about its median there, sample rate Hz)."""
    a = np.asarray(accel, dtype=float)
    t = np.asarray(t, dtype=float) - t[0]
    rate = rate or (len(t) - 1) / t[-1]
    a = a - np.median(a)
    i0 = int(np.searchsorted(t, start)) if start is not None else int(np.argmax(np.abs(a[: len(a) // 2])))
    tt, yy = t[i0:] - t[i0], a[i0:]
    if len(tt) < 50:
        raise RingtuneError(f"only {len(tt)} samples after the start of the ringing", source or None)
    return tt, yy, rate


def _spectral_peaks(yy, rate: float, fmin: float, fmax: float, max_modes: int) -> list[float]:
    """The ``max_modes`` most prominent peak frequencies (Hz, ascending) of the ringing's spectrum
    between ``fmin`` and ``fmax`` (none prominent: the highest bin)."""
    nfft = 1 << (len(yy) * 8 - 1).bit_length()
    spec = np.abs(np.fft.rfft((yy - yy.mean()) * np.hanning(len(yy)), nfft))
    fr = np.fft.rfftfreq(nfft, 1 / rate)
    band = (fr >= fmin) & (fr <= fmax)
    idx, _ = find_peaks(spec[band], prominence=0.2 * spec[band].max())
    order = np.argsort(spec[band][idx])[::-1][:max_modes]
    return sorted(float(fr[band][idx[k]]) for k in order) or [float(fr[band][np.argmax(spec[band])])]


def _decay_warnings(r2: float, modes: list) -> list[str]:
    """A poor fit, or a mode that hardly decays (a steady vibration, not ringing)."""
    out = []
    if r2 < 0.5:
        out.append(f"the damped sinusoids explain only {100 * r2:.0f} % of the signal: the capture is "
                   "mostly noise or steady vibration, not clean ringing")
    out += [f"{m.freq:.1f} Hz hardly decays: a steady vibration (fan, motor) rather than ringing"
            for m in modes if m.damping < 0.003]
    return out


def _per_mode(freqs, damping: float) -> np.ndarray:
    """The decay fit's parameter vector [f₀, ζ, f₁, ζ, …]: each mode's frequency (Hz) with ``damping``."""
    return np.column_stack([freqs, np.full(len(freqs), damping)]).ravel()


def identify_decay(t: np.ndarray, accel: np.ndarray, axis: str, source: str = "capture",
                   rate: float | None = None, max_modes: int = 2, fmin: float = 5.0, fmax: float = 150.0,
                   start: float | None = None) -> AxisFit:
    """Fit damped sinusoids to one axis of a free-decay capture: times ``t`` (s), acceleration
    ``accel`` (mm/s²), sample ``rate`` (Hz; default from ``t``), measured in ``source``.

    The fit starts at ``start`` s, or by default at the largest acceleration (the end of the move's
    deceleration, where free ringing begins)."""
    tt, yy, rate = _ringing(t, accel, rate, start, source)
    fmax = min(fmax, 0.4 * rate)
    f0 = _spectral_peaks(yy, rate, fmin, fmax, max_modes)
    x0 = _per_mode(f0, 0.03)
    lo = _per_mode(np.maximum(fmin, np.multiply(f0, 0.8)), 0.0005)
    hi = _per_mode(np.minimum(fmax, np.multiply(f0, 1.2)), 0.6)

    def resid(x):
        B = _decay_basis(tt, x)
        c, *_ = np.linalg.lstsq(B, yy, rcond=None)
        return B @ c - yy

    sol = least_squares(resid, x0, bounds=(lo, hi), x_scale="jac", max_nfev=3000)
    B = _decay_basis(tt, sol.x)
    c, *_ = np.linalg.lstsq(B, yy, rcond=None)
    fitted = B @ c
    r2 = float(1 - ((fitted - yy) ** 2).sum() / ((yy - yy.mean()) ** 2).sum())
    modes, disp = [], []
    for k, (fn, z) in enumerate(sol.x.reshape(-1, 2)):
        amp = math.hypot(c[1 + 2 * k], c[2 + 2 * k])           # mm/s² at the start of the ringing
        disp.append(amp / (2 * math.pi * fn) ** 2)              # displacement amplitude, mm
        modes.append(FittedMode(float(fn), float(z), 0.0, f0[k]))
    tot = sum(disp) or 1.0
    for m, d in zip(modes, disp):
        m.share = float(d / tot)
    fit = AxisFit(axis, "decay", source, modes, tt, yy, fitted, r2, "damped-sinusoid")
    fit.warnings += _decay_warnings(r2, modes)
    return fit


def plot_fits(fits: list[AxisFit], path: str | Path) -> None:
    """Measured against fitted: spectra (log scale) and decays, one panel per fit."""
    matplotlib.use("Agg")
    fig, axes = plt.subplots(len(fits), 1, figsize=(9, 3.6 * len(fits)), squeeze=False)
    for ax, fit in zip(axes[:, 0], fits):
        title = f"{Path(fit.source).name}: axis {fit.axis.upper()} ({fit.kind} fit, r² = {fit.r2:.3f})"
        if fit.kind == "psd":
            xm = fit.x if fit.x_measured is None else fit.x_measured
            ym = fit.measured if fit.y_measured is None else fit.y_measured
            ax.semilogy(xm, ym, "o-", ms=3, lw=1, label="measured PSD")
            ax.semilogy(fit.x, fit.fitted, "-", lw=2, label="fitted modes")
            ax.set_xlabel("frequency (Hz)")
            ax.set_ylabel("PSD ((mm/s²)²/Hz)")
            for m in fit.modes:
                ax.axvline(m.freq, color="grey", ls=":", lw=1)
        else:
            ax.plot(fit.x, fit.measured / 1000, lw=1, label="measured acceleration")
            ax.plot(fit.x, fit.fitted / 1000, lw=1.5, label="fitted damped sinusoids")
            ax.set_xlabel("time after the start of ringing (s)")
            ax.set_ylabel("acceleration (m/s²)")
        label = ", ".join(f"{m.freq:.1f} Hz ζ={m.damping:.3f} share {m.share:.2f}" for m in fit.modes)
        ax.set_title(title + "\n" + label, fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
