"""Power spectral densities of accelerometer signals, computed as Klipper computes them.

:class:`PSD` is the spectrum the readers of :mod:`ringtune.hardware.accel` return and the
identification fits. :func:`klipper_psd` computes one from a raw capture exactly like Klipper's
``shaper_calibrate.calc_freq_response`` (Welch: Kaiser β=6 window of ``klipper_window_size`` samples,
50 % overlap, per-window mean removed); :func:`normalize_to_frequencies` is Klipper's
``normalize_to_frequencies`` (see ``shared/reference/firmware.md`` §1.3, §1.4).

Units: Hz, (mm/s²)²/Hz.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ringtune.hardware.raw_accel import RawAccel
from ringtune.shaping.errors import RingtuneError

#: Klipper's Welch window length, s (shaper_calibrate.WINDOW_T_SEC)
WINDOW_T_SEC = 0.5
#: Klipper's MIN_FREQ (normalize_to_frequencies damps below 2·MIN_FREQ)
KLIPPER_MIN_FREQ = 5.0


@dataclass
class PSD:
    """Power spectral density of an accelerometer signal, per frequency bin.

    Attributes:
        freqs: bin frequencies, Hz.
        psd_x, psd_y, psd_z: per-axis PSD, (mm/s²)²/Hz; None in the multi-dataset form.
        psd_sum: psd_x + psd_y + psd_z (Klipper's ``psd_xyz``).
        source: the file it came from ("" if computed in memory).
        name: dataset name (the axis for single files, the column name in multi-dataset files).
        normalized: True if already divided by (f + 0.1) as Klipper's ``normalize_to_frequencies``
            does (files with a shaper block are written normalised).
        shapers: shaper response columns of a calibration CSV, ``{"mzv(46.2)": values}``.
    """

    freqs: np.ndarray
    psd_x: np.ndarray | None
    psd_y: np.ndarray | None
    psd_z: np.ndarray | None
    psd_sum: np.ndarray
    source: str = ""
    name: str = ""
    normalized: bool = False
    shapers: dict[str, np.ndarray] = field(default_factory=dict)

    def axis(self, axis: str) -> np.ndarray:
        """PSD of ``"x"``, ``"y"``, ``"z"`` or ``"sum"``/``"xyz"``."""
        key = {"xyz": "sum", "all": "sum"}.get(axis, axis)
        arr = getattr(self, f"psd_{key}", None)
        if arr is None:
            raise RingtuneError(f"this PSD has no per-axis column {axis!r} (multi-dataset form)",
                                self.source or None)
        return arr

    def normalized_to_frequencies(self, lowfreq: str = "exp") -> "PSD":
        """Klipper's ``normalize_to_frequencies`` on every column (:func:`normalize_to_frequencies`).

        Returns self unchanged if :attr:`normalized` is already True.
        """
        if self.normalized:
            return self
        f = self.freqs

        def sc(a):
            return None if a is None else normalize_to_frequencies(f, a, lowfreq)

        return PSD(f.copy(), sc(self.psd_x), sc(self.psd_y), sc(self.psd_z), sc(self.psd_sum),
                   self.source, self.name, True, dict(self.shapers))


def normalize_to_frequencies(freqs: np.ndarray, psd: np.ndarray, lowfreq: str = "exp") -> np.ndarray:
    """Klipper's ``normalize_to_frequencies`` on one PSD column, (mm/s²)²/Hz -> a new array.

    ``psd / (f + 0.1)`` (a division, as Klipper writes it); then the low-frequency noise
    suppression: ``"exp"`` (v0.13.0 and HEAD) multiplies bins below 2·KLIPPER_MIN_FREQ = 10 Hz by
    ``exp(1 − (10/(f+0.1))²)``; ``"zero"`` (the 2021–2023 releases) zeroes bins below 5 Hz.
    """
    freqs = np.asarray(freqs, dtype=float)
    out = np.asarray(psd, dtype=float) / (freqs + 0.1)
    if lowfreq == "zero":
        out[freqs < KLIPPER_MIN_FREQ] = 0.0
    elif lowfreq == "exp":
        low = freqs < 2.0 * KLIPPER_MIN_FREQ
        out[low] *= np.exp(-((2.0 * KLIPPER_MIN_FREQ / (freqs[low] + 0.1)) ** 2) + 1.0)
    else:
        raise RingtuneError(f"low-frequency suppression must be 'zero' or 'exp', not {lowfreq!r}", "lowfreq")
    return out


# -- Klipper's PSD of a raw capture ---------------------------------------------------------------

def klipper_window_size(rate: float) -> int:
    """Klipper's Welch window length: ``1 << int(rate·0.5 − 1).bit_length()`` samples."""
    return 1 << int(rate * WINDOW_T_SEC - 1).bit_length()


def welch_psd(x: np.ndarray, fs: float, nfft: int) -> tuple[np.ndarray, np.ndarray]:
    """Welch PSD as Klipper's ``_psd``: Kaiser(β=6) window, 50 % overlap, per-window mean removed,
    scaled by 1/(Σw²·fs), one-sided (×2 except DC and Nyquist). Returns (freqs Hz, psd)."""
    window = np.kaiser(nfft, 6.0)
    scale = 1.0 / (window ** 2).sum()
    overlap = nfft // 2
    step = nfft - overlap
    n_windows = (x.shape[-1] - overlap) // step
    if n_windows < 1:
        raise RingtuneError(f"{x.shape[-1]} samples is not more than the {nfft}-sample window")
    x = np.ascontiguousarray(x, dtype=float)
    seg = np.lib.stride_tricks.as_strided(x, shape=(nfft, n_windows),
                                          strides=(x.strides[-1], step * x.strides[-1]),
                                          writeable=False)
    seg = window[:, None] * (seg - seg.mean(axis=0))
    spec = np.fft.rfft(seg, n=nfft, axis=0)
    power = (np.conjugate(spec) * spec).real * (scale / fs)
    power[1:-1, :] *= 2.0
    return np.fft.rfftfreq(nfft, 1.0 / fs), power.mean(axis=-1)


def _capture_rate_and_window(raw: RawAccel) -> tuple[float, int]:
    """(fs Hz, Klipper's window M) of a capture: fs = N / (t_last − t_first); refused as Klipper
    refuses it when N ≤ M."""
    n = len(raw.t)
    span = float(raw.t[-1] - raw.t[0])
    if n < 2 or span <= 0:
        raise RingtuneError("need at least two samples spanning some time", raw.source or None)
    fs = n / span
    m = klipper_window_size(fs)
    if n <= m:
        raise RingtuneError(f"{n} samples is not more than Klipper's {m}-sample analysis window "
                            f"(0.5 s at {fs:.0f} Hz); Klipper cannot compute a PSD from it",
                            raw.source or None)
    return fs, m


def klipper_psd(raw: RawAccel) -> PSD:
    """PSD of a raw capture computed exactly as Klipper's ``calc_freq_response``.

    fs = N / (t_last − t_first); window M = ``klipper_window_size(fs)``; Klipper refuses captures of
    N ≤ M samples, and so does this (RingtuneError). Axes not captured count as zero.
    """
    fs, m = _capture_rate_and_window(raw)
    spectra = {ax: welch_psd(getattr(raw, f"a{ax}"), fs, m) for ax in "xyz" if getattr(raw, f"a{ax}") is not None}
    if not spectra:
        raise RingtuneError("no axis captured", raw.source or None)
    freqs = spectra[list(spectra)[-1]][0]
    total = np.sum([p for _, p in spectra.values()], axis=0)
    zero = np.zeros_like(total)
    x, y, z = (spectra.get(ax, (freqs, zero))[1] for ax in "xyz")
    return PSD(freqs, x, y, z, total, raw.source, "", False)
