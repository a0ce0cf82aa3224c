"""Does an identified printer give back what it was fitted to? Klipper's rule on the model's simulated
resonance test against Klipper's rule on the measured files.

The simulated test is the model's expected spectrum (:func:`ringtune.envs.sim.resonance_test` without
noise): it depends on no seed. The two picks agree when the shaper is the same and the frequencies
differ by at most :data:`PICK_TOLERANCE`. When they do not, the warning names the axis, both picks,
the difference, and what explains it:

- Klipper's rule reads ``psd_xyz``, the sum of the accelerometer's three columns; the model holds
  the axis's own modes (fitted to its own column). The share of what the rule weighs (bins above a
  twentieth of the peak of the normalised spectrum, Klipper's vibration threshold) that lies off
  the axis's column is said;
- where the spectrum the rule weighs peaks, measured and simulated (normalised as Klipper does);
- the fitted modes explain r² of the axis's log spectrum (a few modes cannot follow every hump).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ringtune.agents.klipper.baseline import klipper_rule_on_simulated_test
from ringtune.agents.klipper.rule import SHAPER_VIBRATION_REDUCTION
from ringtune.envs.identify import AxisFit
from ringtune.envs.printer_model import Printer
from ringtune.envs.sim import resonance_test
from ringtune.hardware.psd import PSD, normalize_to_frequencies

#: the model's pick counts as the files' within this relative frequency difference
PICK_TOLERANCE = 0.03


@dataclass(frozen=True)
class PickComparison:
    """Klipper's pick on one axis from the files (``files``) and from the model's simulated test
    (``model``), each ``(shaper, freq Hz)``; ``off_axis``: fraction of what the rule weighs that is
    off the axis's own column (None when the files have no per-axis columns); ``r2`` of the fit."""

    axis: str
    files: tuple[str, float]
    model: tuple[str, float]
    off_axis: float | None
    r2: float | None
    peaks: tuple[float, float] | None = None      # Hz: where the weighed spectrum peaks, files and model

    @property
    def difference(self) -> float:
        """Relative frequency difference, model against files."""
        return self.model[1] / self.files[1] - 1.0 if self.files[1] else float("inf")

    def agrees(self) -> bool:
        return self.model[0] == self.files[0] and abs(self.difference) <= PICK_TOLERANCE

    def warning(self) -> str:
        """One sentence: which axis differs, by how much, and why."""
        ax = self.axis.upper()
        what = "the same shaper" if self.model[0] == self.files[0] else "another shaper"
        why = []
        if self.off_axis is not None and self.off_axis >= 0.1:
            why.append(f"Klipper's rule reads all three accelerometer columns (psd_xyz) and {100 * self.off_axis:.0f} % "
                       f"of what it weighs is off the {ax} column, which the model ({ax}'s own modes) does not have")
        if self.peaks and abs(self.peaks[1] / self.peaks[0] - 1.0) > PICK_TOLERANCE:
            why.append(f"the spectrum the rule weighs peaks at {self.peaks[0]:.1f} Hz in the files and at "
                       f"{self.peaks[1]:.1f} Hz in the model")
        if self.r2 is not None:
            why.append(f"the fitted modes explain {100 * self.r2:.0f} % of psd_{self.axis}'s log spectrum "
                       f"(r² {self.r2:.3f}): a few modes do not follow every hump")
        return (f"{ax}: Klipper's rule on the model's simulated resonance test picks {self.model[0]} @ "
                f"{self.model[1]:.1f} Hz, on the files {self.files[0]} @ {self.files[1]:.1f} Hz ({what}, "
                f"{100 * self.difference:+.1f} %): " + "; ".join(why) + ". tune compares against the pick "
                "from the files ([measurement.klipper]); the physics runs on the fitted modes")


def off_axis_share(psds: list[PSD], axis: str) -> float | None:
    """Fraction of Klipper's weighed spectrum (normalised ``psd_xyz`` above a twentieth of its peak)
    that is not in the ``axis`` column, over every file of the axis; None without per-axis columns."""
    total = own = 0.0
    for psd in psds:
        if psd.psd_x is None or psd.normalized:
            return None
        whole = normalize_to_frequencies(psd.freqs, psd.psd_sum, "exp")
        column = normalize_to_frequencies(psd.freqs, psd.axis(axis), "exp")
        weighed = whole > whole.max() / SHAPER_VIBRATION_REDUCTION
        total += float(np.sum(whole[weighed]))
        own += float(np.sum(column[weighed]))
    return 1.0 - own / total if total > 0 else None


def weighed_peak(freqs: np.ndarray, psd: np.ndarray) -> float:
    """Frequency (Hz) where the spectrum Klipper's rule weighs (normalised as Klipper does) peaks."""
    return float(freqs[int(np.argmax(normalize_to_frequencies(freqs, psd, "exp")))])


def compare_picks(printer: Printer, record: dict, psds: dict[str, list[PSD]],
                  fits: dict[str, AxisFit]) -> list[PickComparison]:
    """Klipper's pick from the files (``record``: ``[measurement.klipper]``) against the pick on the
    model's simulated test, for each axis the record has (``psds``, ``fits``: the files' spectra and
    mode fits by axis)."""
    axes = [ax for ax in ("x", "y") if record.get(f"shaper_{ax}") and record.get(f"freq_{ax}")]
    if not axes:
        return []
    _, fields = klipper_rule_on_simulated_test(printer, "klipper", str(record.get("version") or "head"))
    out = []
    for ax in axes:
        fit = fits.get(ax)
        measured = psds.get(ax, [])
        out.append(PickComparison(ax, (str(record[f"shaper_{ax}"]), float(record[f"freq_{ax}"])),
                                  (str(fields[f"shaper_{ax}"]), float(fields[f"freq_{ax}"])),
                                  off_axis_share(measured, ax), fit.r2 if fit else None,
                                  _weighed_peaks(printer, ax, measured)))
    return out


def _weighed_peaks(printer: Printer, ax: str, measured: list[PSD]) -> tuple[float, float] | None:
    """(files, model): where the spectrum Klipper's rule weighs peaks on axis ``ax``, Hz; None
    without a raw spectrum of the axis."""
    if not measured or measured[0].normalized:
        return None
    return weighed_peak(measured[0].freqs, measured[0].psd_sum), weighed_peak(*resonance_test(printer, ax))


def pick_warnings(printer: Printer, record: dict, psds: dict[str, list[PSD]],
                  fits: dict[str, AxisFit]) -> list[str]:
    """The warnings of :func:`compare_picks` for the axes where the picks do not agree."""
    return [c.warning() for c in compare_picks(printer, record, psds, fits) if not c.agrees()]
