"""Klipper's ``calibrate_shaper`` choice, re-implemented from a PSD (the baseline users run today).

This is the rule in ``Klipper3d/klipper:klippy/extras/shaper_calibrate.py`` (see
``shared/reference/firmware.md`` §1.3), in two versions:

- ``"head"`` (current Klipper): shapers with the current formulas (flavour ``"klipper"``), the
  per-shaper choice accepts ``vibrs < 1.1·best + 0.0005``, and the cross-shaper choice has the later
  extras (a per-frequency result with both fewer vibrations and less smoothing wins; a ``zv`` pick
  is replaced by the first other shaper with 10 % fewer vibrations; ``max_vibrations``).
- ``"0.13"`` (tag v0.13.0 and the 2021–2023 releases whose output users recorded): the closed-form
  legacy shapers (flavour ``"klipper-legacy"``), ``vibrs < 1.1·best`` and the two original
  cross-shaper clauses.

Steps, per shaper in ``AUTOTUNE_SHAPERS`` order:

1. PSD normalisation (unless already normalised): ``psd /= f + 0.1``; low-frequency noise
   suppression — ``"exp"`` (psd × ``exp(1 − (10/(f+0.1))²)`` below 10 Hz; v0.13.0 and HEAD) or
   ``"zero"`` (psd = 0 below 5 Hz; the 2021–2023 releases — pass ``lowfreq="zero"``). Both give the
   recorded picks on the real files in ``tests/data/accel/klipper_psd``.
2. Test frequencies ``np.arange(min_freq, 150, 0.2)`` scanned from high to low; each shaper built at
   damping 0.1.
3. Remaining vibration (fraction 0..1), pessimised over test damping ratios 0.075, 0.1, 0.15:
   ``Σ max(H·psd − max(psd)/20, 0) / Σ max(psd − max(psd)/20, 0)`` with ``H`` the residual
   vibration of the shaper on a damped oscillator.
4. Smoothing (mm) at accel 5000 mm/s² and the square-corner velocity ``scv`` (mm/s); suggested
   ``max_accel`` (mm/s²) = the largest acceleration keeping smoothing ≤ 0.12 mm. Klipper bisects to
   1e-8; smoothing is affine in the acceleration, so this solves it exactly (same number to 1e-8).
5. ``score = smoothing · (vibrs^1.5 + 0.2·vibrs + 0.01)``; per shaper the lowest-score frequency
   whose vibrations are within 10 % of that shaper's best; across shapers a later shaper replaces the
   pick if its score is 20 % lower, or 5 % lower with 10 % less smoothing. With ``max_smoothing``
   (mm) the scan stops at the first frequency smoothing more than that, and the shaper's result is
   then the lowest-vibration frequency scanned so far (Klipper's early ``return best_res``).

Entry point: :func:`recommend_klipper`. Amplitudes and times come from
``ringtune.shaping.shapers.get_shaper`` (or an injected ``shaper_factory``); the shaper math
(residual vibration, smoothing, max_accel) from :mod:`ringtune.shaping.analysis` and the PSD
normalisation from :func:`ringtune.hardware.psd.normalize_to_frequencies`: this module holds only
Klipper's rule.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable, Sequence

import numpy as np

from ringtune.hardware.psd import normalize_to_frequencies
from ringtune.shaping.analysis import (SMOOTHING_ACCEL, TARGET_SMOOTHING, impulse_residual,
    max_accel_from_terms, smoothing_from_terms, smoothing_terms)
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.shapers import get_shaper

VERSIONS = ("head", "0.13")
VERSION_FLAVOR = {"head": "klipper", "0.13": "klipper-legacy"}
#: low-frequency noise suppression used by each version (see module docstring)
VERSION_LOWFREQ = {"head": "exp", "0.13": "exp"}

AUTOTUNE_SHAPERS = ("zv", "mzv", "ei", "2hump_ei", "3hump_ei")
#: shaper -> lowest test frequency, Hz (Klipper's ``min_freq``, "projected max_accel ~= 1500")
SHAPER_MIN_FREQ = {"zv": 21.0, "mzv": 23.0, "zvd": 29.0, "ei": 29.0, "2hump_ei": 39.0, "3hump_ei": 48.0}
TEST_DAMPING_RATIOS = (0.075, 0.1, 0.15)
DEFAULT_DAMPING_RATIO = 0.1
SHAPER_VIBRATION_REDUCTION = 20.0
MAX_FREQ = 200.0          # Hz, PSD bins used up to here (or the highest test frequency)
MAX_SHAPER_FREQ = 150.0   # Hz, test frequencies stop below this
FREQ_STEP = 0.2           # Hz

#: (name, freq Hz, damping) -> (amplitudes, times s); amplitudes need not be normalised
ShaperFactory = Callable[[str, float, float], tuple[np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class ShaperFit:
    """Klipper's fitted result for one shaper type.

    Attributes: name; freq (Hz); vibrs (remaining vibrations, fraction 0..1); smoothing (mm at
    5000 mm/s² and the scv used); score (Klipper's, dimensionless×mm); max_accel (mm/s², unrounded).
    """

    name: str
    freq: float
    vibrs: float
    smoothing: float
    score: float
    max_accel: float

    @property
    def max_accel_rounded(self) -> float:
        """The suggested max_accel as Klipper prints it: rounded to 100 mm/s²."""
        return float(round(self.max_accel / 100.0) * 100.0)

    def lines(self) -> list[str]:
        """The two console lines Klipper prints for this shaper."""
        return [
            "Fitted shaper '%s' frequency = %.1f Hz (vibrations = %.1f%%, smoothing ~= %.3f)"
            % (self.name, self.freq, self.vibrs * 100.0, self.smoothing),
            "To avoid too much smoothing with '%s', suggested max_accel <= %.0f mm/sec^2"
            % (self.name, self.max_accel_rounded),
        ]

    def to_dict(self) -> dict[str, Any]:
        return {"shaper": self.name, "freq": round(float(self.freq), 1), "vibrations_pct": 100.0 * self.vibrs,
                "smoothing": self.smoothing, "score": self.score, "max_accel": self.max_accel,
                "max_accel_rounded": self.max_accel_rounded}


@dataclass
class KlipperRecommendation:
    """The pick (``best``) and the per-shaper table (``shapers``, AUTOTUNE order)."""

    best: ShaperFit
    shapers: list[ShaperFit]
    version: str
    scv: float
    all_results: dict[str, list[ShaperFit]] = field(default_factory=dict, repr=False)

    def lines(self) -> list[str]:
        out = [line for s in self.shapers for line in s.lines()]
        out.append("Recommended shaper is %s @ %.1f Hz" % (self.best.name, self.best.freq))
        return out

    def to_dict(self) -> dict[str, Any]:
        return {"version": self.version, "scv": self.scv, "shaper": self.best.name,
                "freq": round(float(self.best.freq), 1), "max_accel": self.best.max_accel_rounded,
                "shapers": [s.to_dict() for s in self.shapers]}


# -- the pieces -----------------------------------------------------------------------------------

def remaining_vibrations(amps, times, freqs, psd, damping: float):
    """Klipper's ``_estimate_remaining_vibrations`` (fraction 0..1) for one test damping ratio:
    ``Σ max(H·psd − max(psd)/20, 0) / Σ max(psd − max(psd)/20, 0)``, ``H`` the shaper's residual
    (:func:`ringtune.shaping.analysis.impulse_residual`). A float for one shaper (``amps`` (n,)),
    an array for a stack of shapers (rows)."""
    vals = impulse_residual(amps, times, freqs, damping)
    thr = psd.max() / SHAPER_VIBRATION_REDUCTION
    out = np.maximum(vals * psd - thr, 0.0).sum(axis=-1) / np.maximum(psd - thr, 0.0).sum()
    return float(out) if np.ndim(out) == 0 else out


def default_shaper_factory(flavor: str) -> ShaperFactory:
    """Amplitudes and times from ``ringtune.shaping.shapers.get_shaper`` in ``flavor``."""
    def make(name: str, freq: float, damping: float) -> tuple[np.ndarray, np.ndarray]:
        s = get_shaper(name, float(freq), damping, flavor=flavor)
        return np.asarray(s.amplitudes, dtype=float), np.asarray(s.times, dtype=float)

    return make


# -- the rule -------------------------------------------------------------------------------------

@dataclass
class _Dataset:
    freqs: np.ndarray
    psd: np.ndarray        # normalised psd_sum


def _psd_columns(obj: Any, where: str) -> tuple[Any, Any, bool]:
    """(freqs, psd_sum, already normalised) of a PSD object (``.freqs``, ``.psd_sum``) or a pair."""
    if isinstance(obj, (tuple, list)) and len(obj) == 2:
        return obj[0], obj[1], False
    if hasattr(obj, "freqs") and hasattr(obj, "psd_sum"):
        return obj.freqs, obj.psd_sum, bool(getattr(obj, "normalized", False) or getattr(obj, "normalised", False))
    raise RingtuneError("expected a PSD (freqs, psd_sum) to fit shapers to", where)


def _as_dataset(obj: Any, lowfreq: str, where: str) -> _Dataset:
    """A PSD object (``.freqs``, ``.psd_sum``) or a ``(freqs, psd_sum)`` pair -> normalised dataset."""
    freqs, psd, normalised = _psd_columns(obj, where)
    freqs = np.asarray(freqs, dtype=float)
    psd = np.asarray(psd, dtype=float)
    if freqs.ndim != 1 or freqs.shape != psd.shape or freqs.size < 4:
        raise RingtuneError(f"PSD needs matching 1-D freqs and psd columns (got {freqs.shape}, {psd.shape})",
                            where)
    if not (np.all(np.isfinite(freqs)) and np.all(np.isfinite(psd))) or np.any(psd < 0):
        raise RingtuneError("PSD has non-finite or negative values", where)
    return _Dataset(freqs, psd if normalised else normalize_to_frequencies(freqs, psd, lowfreq))


def fit_shaper(name: str, datasets: Sequence[_Dataset], factory: ShaperFactory, *, version: str = "head",
               scv: float = 5.0, damping_ratio: float = DEFAULT_DAMPING_RATIO,
               test_damping_ratios: Sequence[float] = TEST_DAMPING_RATIOS,
               freq_range: tuple[float | None, float | None, float | None] = (None, None, None),
               max_freq: float | None = None, max_smoothing: float | None = None,
               max_vibrations: float | None = None) -> tuple[ShaperFit, list[ShaperFit]]:
    """Klipper's ``fit_shaper`` for one shaper type: (selected result, results high -> low freq)."""
    test_freqs = _test_frequencies(name, freq_range)
    max_freq = max(max_freq or MAX_FREQ, float(test_freqs.max()))
    cut = [(d.freqs[d.freqs <= max_freq], d.psd[d.freqs <= max_freq]) for d in datasets]
    freqs_desc = test_freqs[::-1]
    built = [factory(name, float(f), damping_ratio) for f in freqs_desc]
    amps = np.stack([np.asarray(b[0], dtype=float) for b in built])
    times = np.stack([np.asarray(b[1], dtype=float) for b in built])
    terms = smoothing_terms(amps, times, scv)
    smoothing = smoothing_from_terms(terms, SMOOTHING_ACCEL)
    keep = _smoothing_stop(smoothing, max_smoothing)     # None: all of them ([:None] is the whole array)
    freqs_desc, amps, times, smoothing = freqs_desc[:keep], amps[:keep], times[:keep], smoothing[:keep]
    terms = tuple(x[:keep] for x in terms)
    vibrs = _worst_vibrations(amps, times, cut, test_damping_ratios)
    scores = smoothing * (vibrs ** 1.5 + vibrs * 0.2 + 0.01)
    max_accels = max_accel_from_terms(terms, TARGET_SMOOTHING)
    results = [ShaperFit(name, float(freq), float(vibrs[i]), float(smoothing[i]), float(scores[i]),
                         float(max_accels[i])) for i, freq in enumerate(freqs_desc)]
    best = min(results, key=lambda r: r.vibrs)          # the first of the lowest, as Klipper's strict >
    if keep is not None:
        # Klipper's early exit (``return best_res``, every version): the lowest-vibration result of
        # the frequencies scanned so far, without the smoothing-saving selection below
        return best, results
    return _saving_smoothing(results, best, version, max_vibrations), results


def _worst_vibrations(amps, times, datasets, damping_ratios) -> np.ndarray:
    """Per candidate shaper, the largest remaining vibrations over the datasets and the tested
    damping ratios (HEAD's pessimisation; one dataset in 0.13's)."""
    vibrs = np.zeros(len(amps))
    for freqs, psd in datasets:
        for dr in damping_ratios:
            vibrs = np.maximum(vibrs, remaining_vibrations(amps, times, freqs, psd, dr))
    return vibrs


def _test_frequencies(name: str, freq_range) -> np.ndarray:
    """The frequencies Klipper tries for shaper ``name`` (Hz, rising): ``freq_range`` (start,
    end, step), each None for Klipper's default."""
    f_end = freq_range[1] or MAX_SHAPER_FREQ
    f_start = min(freq_range[0] or SHAPER_MIN_FREQ[_base(name)], f_end - 1e-7)
    return np.arange(f_start, f_end, freq_range[2] or FREQ_STEP)


def _smoothing_stop(smoothing: np.ndarray, max_smoothing: float | None) -> int | None:
    """How many results (high -> low frequency) Klipper scans under ``max_smoothing``, None when it
    scans them all: it stops once a result exists and the smoothing passes the bound."""
    if not max_smoothing:
        return None
    over = np.nonzero(smoothing[1:] > max_smoothing)[0]
    return int(over[0] + 1) if over.size else None


def _saving_smoothing(results: list[ShaperFit], best: ShaperFit, version: str,
                      max_vibrations: float | None) -> ShaperFit:
    """Klipper's selection from low to high frequency: a result with vibrations within 10 % of the
    best (HEAD: + 0.0005) and a better score (HEAD: or any, while the best breaks
    ``max_vibrations``)."""
    selected = best
    for res in results[::-1]:
        if version == "head":
            ok = res.vibrs < best.vibrs * 1.1 + 0.0005 and (
                res.score < selected.score or (max_vibrations is not None and best.vibrs > max_vibrations))
        else:
            ok = res.vibrs < best.vibrs * 1.1 and res.score < selected.score
        if ok:
            selected = res
    return selected


def recommend_klipper(psds: Any, version: str = "head", scv: float = 5.0, *,
                      shapers: Iterable[str] = AUTOTUNE_SHAPERS, damping_ratio: float | None = None,
                      test_damping_ratios: Sequence[float] | None = None,
                      freq_range: tuple[float | None, float | None, float | None] = (None, None, None),
                      max_freq: float | None = None, max_smoothing: float | None = None,
                      max_vibrations: float | None = None, lowfreq: str | None = None,
                      shaper_factory: ShaperFactory | None = None) -> KlipperRecommendation:
    """Klipper's ``find_best_shaper`` on one axis's PSD(s).

    Args:
        psds: a PSD (``.freqs`` Hz, ``.psd_sum``), a ``(freqs, psd_sum)`` pair, or a list of them
            (several measurements of one axis: HEAD pessimises over them; 0.13 averages them).
            Raw PSDs (as TEST_RESONANCES writes them) are normalised here; objects with
            ``normalized=True`` are not.
        version: ``"head"`` or ``"0.13"``.
        scv: square-corner velocity, mm/s (smoothing and max_accel).
        max_vibrations: fraction (HEAD only; Klipper's ``--max_vibrs_pcnt`` / 100).
        lowfreq: override the version's low-frequency suppression (``"zero"`` or ``"exp"``).
        shaper_factory: ``(name, freq, damping) -> (amps, times)``; default get_shaper in the
            version's flavour.
    """
    _check_rule(version, scv)
    datasets = _datasets(psds, version, lowfreq or VERSION_LOWFREQ[version])
    factory = shaper_factory or default_shaper_factory(VERSION_FLAVOR[version])
    names = [_check_shaper_name(n) for n in shapers]
    mv = max_vibrations if version == "head" else None
    kw = dict(version=version, scv=scv, damping_ratio=damping_ratio or DEFAULT_DAMPING_RATIO,
              test_damping_ratios=tuple(test_damping_ratios or TEST_DAMPING_RATIOS), freq_range=freq_range,
              max_freq=max_freq, max_smoothing=max_smoothing, max_vibrations=mv)
    fits = [(name, *fit_shaper(name, datasets, factory, **kw)) for name in names]
    best, table = _best_shaper(fits, version, mv)
    all_results = {name: results for name, _, results in fits}
    return KlipperRecommendation(best=best, shapers=table, version=version, scv=float(scv), all_results=all_results)


def _best_shaper(fits: list, version: str, max_vibrations: float | None) -> tuple[ShaperFit, list[ShaperFit]]:
    """(Klipper's pick, the table of each shaper's fit) from [(name, fit, results)], in order: a
    fit that is :func:`_better` replaces the best; HEAD then takes any result of that shaper with
    fewer vibrations and less smoothing, and never keeps ZV where another shaper vibrates 10 % less."""
    best: ShaperFit | None = None
    table: list[ShaperFit] = []
    for _, shaper, results in fits:
        if best is None or _better(shaper, best, version, max_vibrations):
            best = shaper
        if version == "head":
            best, shaper = _quieter_and_smoother(results, best, shaper)
        table.append(shaper)
    if version == "head" and best.name == "zv":
        best = next((s for s in table if s.name != "zv" and s.vibrs * 1.1 < best.vibrs), best)
    return best, table


def _quieter_and_smoother(results: list[ShaperFit], best: ShaperFit, shaper: ShaperFit) -> tuple[ShaperFit, ShaperFit]:
    """HEAD: (best, this shaper's entry) after taking, from low to high frequency, each result with
    fewer vibrations and less smoothing than the best so far."""
    for res in results[::-1]:
        if res.vibrs < best.vibrs and res.smoothing < best.smoothing:
            best = shaper = res
    return best, shaper


def _check_rule(version: str, scv) -> None:
    """A Klipper version there is, and a square-corner velocity ≥ 0 mm/s."""
    if version not in VERSIONS:
        raise RingtuneError(f"Klipper version must be one of {', '.join(VERSIONS)}, not {version!r}",
                            "version")
    if not (isinstance(scv, (int, float)) and math.isfinite(scv) and scv >= 0):
        raise RingtuneError(f"square-corner velocity must be ≥ 0 mm/s, not {scv!r}", "scv")


def _datasets(psds: Any, version: str, lowfreq: str) -> list[_Dataset]:
    """The normalised datasets of one axis (0.13: several averaged into one, as its add_data)."""
    items = list(psds) if isinstance(psds, list) else [psds]
    if not items:
        raise RingtuneError("no PSD given", "recommend_klipper")
    datasets = [_as_dataset(p, lowfreq, getattr(p, "source", None) or f"PSD {i + 1}") for i, p in enumerate(items)]
    if version == "0.13" and len(datasets) > 1:
        datasets = [_average(datasets)]
    return datasets


def _better(shaper: ShaperFit, best: ShaperFit, version: str, max_vibrations: float | None) -> bool:
    """Klipper's ``find_best_shaper`` comparison: a fifth better score, or 5 % better with 10 % less
    smoothing (HEAD: or fewer vibrations while the best breaks ``max_vibrations``)."""
    return (shaper.score * 1.2 < best.score
            or (shaper.score * 1.05 < best.score and shaper.smoothing * 1.1 < best.smoothing)
            or (version == "head" and max_vibrations is not None and best.vibrs > max_vibrations
                and shaper.vibrs < best.vibrs))


def _average(datasets: list[_Dataset]) -> _Dataset:
    """Old Klipper's ``add_data``: the mean PSD on the first dataset's bins (others interpolated)."""
    base = datasets[0]
    total = base.psd.copy()
    for d in datasets[1:]:
        total += np.interp(base.freqs, d.freqs, d.psd)
    return _Dataset(base.freqs, total / len(datasets))


_SHAPER_RE = re.compile(r"^\s*(\w+)\s*(\(.*\))?\s*$")


def _base(name: str) -> str:
    m = _SHAPER_RE.match(str(name))
    return m.group(1).lower() if m else str(name)


def _check_shaper_name(name: str) -> str:
    base = _base(name)
    if base not in SHAPER_MIN_FREQ:
        raise RingtuneError(f"unknown shaper {name!r}; Klipper's rule fits {', '.join(SHAPER_MIN_FREQ)}",
                            "shapers")
    return str(name).strip().lower() if _SHAPER_RE.match(str(name)).group(2) else base

