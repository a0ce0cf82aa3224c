"""CoreXY belts from Klipper's two diagonal resonance tests (``TEST_RESONANCES AXIS=1,1`` and
``AXIS=1,-1``): how alike the two belts are, and their stiffnesses for the printer description.

On a CoreXY a move along (1, 1) turns motor A (stepper_x) alone and one along (1, −1) motor B
(stepper_y) alone, so each test shakes the head mostly through one belt. What is compared:

- *similarity*: the cosine similarity of the two spectra (psd_xyz) over the swept band,
  ``Σ a·b / √(Σ a² · Σ b²)`` in %: 100 % when the spectra have the same shape whatever their scale;
  a belt that differs moves or reshapes its peaks and lowers it;
- *paired peaks*: the peaks of each spectrum (prominence ≥ 15 % of its highest), paired by nearest
  frequency within 10 % (at least 5 Hz), with the frequency difference (Hz, B − A) and the amplitude
  difference (% of the pair's mean, A − B); a peak with no partner is listed alone;
- *belt stiffnesses*: the printer model's two belts (:meth:`Printer.belt_stiffnesses`, their mean
  from the description) with the mismatch ``(k_A − k_B)/mean`` whose simulated diagonal tests
  (:func:`ringtune.envs.sim.resonance_test`) best match both measured spectra in shape and relative
  level (maximum likelihood with a Welch estimate's Gamma scatter, one common scale since both
  tests run at the same excitation), with its standard error from the curvature of that
  likelihood and the scatter left around the fit (model misfit counts as scatter). Belts whose stiffness
  differs by less than :data:`MATCHED` read as matched.

Units: Hz, N/m, PSD (mm/s²)²/Hz.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from scipy.optimize import minimize_scalar

from ringtune.agents.identify.accelerometer import sha256_of
from ringtune.envs.identify import find_peaks_psd
from ringtune.envs.printer_model import Printer
from ringtune.envs.sim import resonance_test
from ringtune.hardware.accel import axis_from_file_name, direction_from_file_name, read_resonances_csv
from ringtune.shaping.errors import RingtuneError

#: the two tests: belt A (motor A, stepper_x) is shaken by AXIS=1,1; belt B (stepper_y) by AXIS=1,-1
DIRECTIONS = {"a": (1.0, 1.0), "b": (1.0, -1.0)}
#: below this relative stiffness difference ((k_A − k_B)/mean), or two standard errors, the belts
#: read as matched
MATCHED = 0.02
#: Klipper's default sweep, Hz
SWEEP = (5.0, 135.0)
#: largest mismatch searched: a factor 3 between the belts' stiffnesses
MAX_MISMATCH = 1.0


@dataclass
class PeakPair:
    """A peak of belt A's spectrum and its partner in belt B's (None where it has none): Hz and PSD."""

    freq_a: float | None
    amp_a: float | None
    freq_b: float | None
    amp_b: float | None

    @property
    def freq_diff(self) -> float | None:
        """B − A, Hz."""
        return None if self.freq_a is None or self.freq_b is None else self.freq_b - self.freq_a

    @property
    def amp_diff_pct(self) -> float | None:
        """(A − B) as % of the pair's mean amplitude."""
        if self.amp_a is None or self.amp_b is None:
            return None
        return 200.0 * (self.amp_a - self.amp_b) / (self.amp_a + self.amp_b)

    def to_dict(self) -> dict:
        return {"freq_a": self.freq_a, "amp_a": self.amp_a, "freq_b": self.freq_b, "amp_b": self.amp_b,
                "freq_diff_hz": self.freq_diff, "amp_diff_pct": self.amp_diff_pct}


@dataclass
class BeltComparison:
    """What the two diagonal tests say about the belts (see the module docstring)."""

    sources: dict[str, str]
    freqs: dict[str, np.ndarray]
    psd: dict[str, np.ndarray]
    similarity: float                      # %, cosine similarity over the sweep
    pairs: list[PeakPair]
    mismatch: float | None = None          # (k_A − k_B)/mean; None without a printer model
    mismatch_error: float | None = None    # one standard error
    stiffness: tuple[float, float] | None = None   # N/m, belt A and belt B
    model: dict[str, np.ndarray] = field(default_factory=dict)   # fitted model spectra, scaled
    notes: list[str] = field(default_factory=list)

    @property
    def matched(self) -> bool | None:
        """The difference is under :data:`MATCHED` or under two standard errors (not resolved)."""
        if self.mismatch is None:
            return None
        return abs(self.mismatch) < max(MATCHED, 2.0 * self.mismatch_error)

    def meaning(self) -> str:
        """One paragraph for the person at the printer."""
        if self.mismatch is None:
            return (f"Spectra {self.similarity:.1f} % alike (100 %: the same shape). Without a model of the printer "
                    "(--printer, a CoreXY description) the difference is not turned into belt stiffnesses.")
        d = 100.0 * self.mismatch
        err = 100.0 * self.mismatch_error
        if self.matched:
            return (f"The belts read as matched: their stiffnesses differ by {abs(d):.1f} % (± {err:.1f} %, one "
                    f"standard error), under {max(100 * MATCHED, 2 * err):.1f} % (the larger of {100 * MATCHED:g} % and "
                    f"two standard errors). Spectra {self.similarity:.1f} % alike.")
        stiffer, softer = ("A", "B") if d > 0 else ("B", "A")
        return (f"Belt {stiffer} is {abs(d):.1f} % (± {err:.1f} %) stiffer than belt {softer}; spectra "
                f"{self.similarity:.1f} % alike. With belts of the same type and length the usual cause is "
                f"tension: belt {softer} is the looser one (or its path - idlers, teeth in mesh, a longer "
                "run - differs). Match the tensions and measure again; ringtune simulates the printer with "
                "the two stiffnesses it measured.")

    def to_dict(self) -> dict:
        return {"sources": self.sources, "similarity_pct": self.similarity,
                "similarity_definition": "cosine similarity of the two psd_xyz spectra over "
                                         f"{SWEEP[0]:g}-{SWEEP[1]:g} Hz: sum(a*b)/sqrt(sum(a^2)*sum(b^2))",
                "pairs": [p.to_dict() for p in self.pairs], "mismatch": self.mismatch,
                "mismatch_error": self.mismatch_error,
                "stiffness_a_n_m": self.stiffness[0] if self.stiffness else None,
                "stiffness_b_n_m": self.stiffness[1] if self.stiffness else None,
                "matched": self.matched, "meaning": self.meaning(),
                "freqs_hz": self.freqs, "psd": self.psd, "model_psd": self.model, "notes": self.notes}


def similarity(freqs_a, psd_a, freqs_b, psd_b, band: tuple[float, float] = SWEEP) -> float:
    """Cosine similarity (%) of two spectra over ``band`` (Hz), B interpolated on A's bins."""
    fa = np.asarray(freqs_a, float)
    sel = (fa >= band[0]) & (fa <= band[1])
    a = np.asarray(psd_a, float)[sel]
    b = np.interp(fa[sel], freqs_b, psd_b)
    return float(100.0 * np.dot(a, b) / math.sqrt(np.dot(a, a) * np.dot(b, b)))


def paired_peaks(freqs_a, psd_a, freqs_b, psd_b, band: tuple[float, float] = SWEEP) -> list[PeakPair]:
    """Peaks of each spectrum paired by nearest frequency (within 10 %, at least 5 Hz), by frequency."""
    def peaks(f, p):
        f, p = np.asarray(f, float), np.asarray(p, float)
        sel = (f >= band[0]) & (f <= band[1])
        return [(float(f[sel][i]), float(p[sel][i])) for i in find_peaks_psd(f[sel], p[sel], 6)]

    pa, pb = peaks(freqs_a, psd_a), peaks(freqs_b, psd_b)
    pairs, used = [], set()
    for fa, aa in sorted(pa, key=lambda x: -x[1]):          # the highest peaks choose first
        free = [(abs(fb - fa), j) for j, (fb, _) in enumerate(pb) if j not in used]
        near = min(free, default=None)
        if near and near[0] <= max(5.0, 0.1 * fa):
            used.add(near[1])
            pairs.append(PeakPair(fa, aa, *pb[near[1]]))
        else:
            pairs.append(PeakPair(fa, aa, None, None))
    pairs += [PeakPair(None, None, fb, ab) for j, (fb, ab) in enumerate(pb) if j not in used]
    return sorted(pairs, key=lambda p: p.freq_a if p.freq_a is not None else p.freq_b)


def _model_logs(printer: Printer, mismatch: float, freqs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    pr = replace(printer, belt_mismatch=float(mismatch))
    return {k: np.log(resonance_test(pr, DIRECTIONS[k], noise_floor=0.0, freqs=freqs[k])[1] + 1e-300)
            for k in DIRECTIONS}


def fit_mismatch(printer: Printer, freqs: dict[str, np.ndarray], psd: dict[str, np.ndarray],
                 band: tuple[float, float] = SWEEP) -> tuple[float, float, dict[str, np.ndarray]]:
    """(mismatch, its standard error, the fitted model spectra) of the belts whose simulated
    diagonal tests best match the measured ones (module docstring)."""
    if printer.kinematics != "corexy":
        raise RingtuneError(f"belt tests compare the two belts of a CoreXY; this printer is {printer.kinematics}",
                            "kinematics")
    base = _model_logs(printer, 0.0, freqs)
    sel = {k: (freqs[k] >= band[0]) & (freqs[k] <= band[1]) & (base[k] >= base[k].max() + math.log(0.02))
           & (psd[k] > 0) for k in DIRECTIONS}
    meas = {k: np.log(psd[k][sel[k]]) for k in DIRECTIONS}

    def residuals(model: dict[str, np.ndarray]) -> np.ndarray:
        """ln(measured / modelled) over the selected bins of both tests."""
        return np.concatenate([meas[k] - model[k][sel[k]] for k in DIRECTIONS])

    def ssr(mu: float) -> float:
        """Gamma (Welch) likelihood with the common scale at its optimum: n·ln mean(x/m) + Σ ln m."""
        r = residuals(_model_logs(printer, mu, freqs))
        return float(len(r) * math.log(np.mean(np.exp(r))) - r.sum())

    grid = np.linspace(-MAX_MISMATCH, MAX_MISMATCH, 41)
    i = int(np.argmin([ssr(m) for m in grid]))
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)]
    mu = float(minimize_scalar(ssr, bounds=(lo, hi), method="bounded", options={"xatol": 1e-5}).x)
    h = 0.01
    curv = (ssr(mu + h) - 2 * ssr(mu) + ssr(mu - h)) / (h * h)
    model = _model_logs(printer, mu, freqs)
    r = residuals(model)
    ratio = np.exp(r)
    shape = 1.0 / max(float(np.var(ratio / ratio.mean())), 1e-12)   # Gamma shape: scatter and misfit alike
    err = math.sqrt(1.0 / (shape * curv)) if curv > 0 else math.inf
    shift = np.mean(r)
    return mu, err, {k: np.exp(model[k] + shift) for k in DIRECTIONS}


def compare_belts(tests: dict[str, tuple[np.ndarray, np.ndarray, str]],
                  printer: Printer | None = None) -> BeltComparison:
    """The comparison of ``tests`` = ``{"a": (freqs, psd_xyz, source), "b": …}``; with a CoreXY
    ``printer`` the belts' stiffnesses too."""
    freqs = {k: np.asarray(tests[k][0], float) for k in DIRECTIONS}
    psd = {k: np.asarray(tests[k][1], float) for k in DIRECTIONS}
    out = BeltComparison({k: tests[k][2] for k in DIRECTIONS}, freqs, psd,
                         similarity(freqs["a"], psd["a"], freqs["b"], psd["b"]),
                         paired_peaks(freqs["a"], psd["a"], freqs["b"], psd["b"]))
    if printer is None:
        return out
    mu, err, out.model = fit_mismatch(printer, freqs, psd)
    out.mismatch, out.mismatch_error = mu, err
    if abs(mu) > 0.98 * MAX_MISMATCH:
        out.notes.append("the belts differ more than ringtune searches (a factor 3 in stiffness): check that the "
                         "files are the two diagonal tests of one printer")
    if printer.belt_stiffness is None:
        out.notes.append("the belts' mean stiffness is the model's default (half the stiffness of the softer axis's "
                         "first mode); the tests give their difference")
    out.stiffness = replace(printer, belt_mismatch=mu).belt_stiffnesses()
    return out


def _belt_keys(paths: list[str]) -> tuple[list[str], list[str]]:
    """Which belt each file tests ("a" for AXIS=1,1, "b" for AXIS=1,-1), from the names, and notes."""
    dirs = [direction_from_file_name(p) for p in paths]
    _refuse_not_diagonal(paths, dirs)
    if None in dirs:
        return ["a", "b"], [f"the file names do not say the test direction: {paths[0]} taken as AXIS=1,1 (belt A, "
                            f"stepper_x) and {paths[1]} as AXIS=1,-1 (belt B, stepper_y)"]
    keys = ["a" if d[0] * d[1] > 0 else "b" for d in dirs]
    if keys[0] == keys[1]:
        raise RingtuneError(f"both files are tests along the same diagonal ({', '.join(paths)})", "belts")
    return keys, []


def _refuse_not_diagonal(paths: list[str], dirs: list) -> None:
    """Refuse files whose names say an axis test or an axis direction, and the same test twice."""
    if any(d is not None and d[0] * d[1] == 0 for d in dirs):
        raise RingtuneError("not a diagonal test (the file name says an axis direction with a zero)", "belts")
    for p in paths:
        ax = axis_from_file_name(p)
        if ax is not None:
            raise RingtuneError(f"a test of the {ax.upper()} axis (its name says so), not a diagonal one: give the "
                                "AXIS=1,1 and AXIS=1,-1 tests (resonances_axis=1.000,1.000,… and "
                                "resonances_axis=1.000,-1.000,…)", str(p))
    if all(Path(p).is_file() for p in paths) and sha256_of(paths[0]) == sha256_of(paths[1]):   # the two tests
        raise RingtuneError(f"the same test twice ({paths[0]} and {paths[1]} hold the same data): give the AXIS=1,1 "
                            "and the AXIS=1,-1 test", "belts")


def read_belt_tests(paths: list[str]) -> tuple[dict[str, tuple[np.ndarray, np.ndarray, str]], list[str]]:
    """The two diagonal tests from Klipper resonance files -> ``{"a": (freqs, psd_xyz, path), "b": …}``
    and notes. The direction comes from each file's name (``resonances_axis=1.000,-1.000…``); when the
    names do not say, the first file is taken as AXIS=1,1 (belt A), said in the notes."""
    if len(paths) != 2:
        raise RingtuneError(f"expected two files (AXIS=1,1 and AXIS=1,-1), got {len(paths)}", "belts")
    keys, notes = _belt_keys(paths)
    tests = {}
    for key, path in zip(keys, paths):
        psd = read_resonances_csv(path)
        psd = psd[0] if isinstance(psd, list) else psd
        if psd.normalized:
            raise RingtuneError("a calibration file (already normalised); give the TEST_RESONANCES output", path)
        tests[key] = (psd.freqs, psd.psd_sum, str(path))
    return tests, notes


def belts_into_description(desc, printer: Printer, paths: list[str]) -> BeltComparison:
    """Measure the belts of the description being built (``desc``, an
    :class:`~ringtune.agents.identify.description.Description`, and ``printer``, what it loads as)
    and write ``[belts] mismatch`` with a comment on where it came from; the files go into
    ``[measurement] belt_files``."""
    if printer.kinematics != "corexy":
        raise RingtuneError(f"the belt tests compare a CoreXY's two belts, but the printer is {printer.kinematics} "
                            "(give --kinematics corexy, or a configuration that says corexy)", "--belts")
    tests, notes = read_belt_tests(paths)
    c = compare_belts(tests, printer)
    belts = dict(desc.data.get("belts", {}))
    belts["mismatch"] = float(f"{c.mismatch:.4f}")
    desc.data["belts"] = belts
    desc.comment("belts", f"mismatch (k_A - k_B)/mean = {100 * c.mismatch:+.1f} % ± {100 * c.mismatch_error:.1f} % "
                 f"from the diagonal tests {', '.join(Path(p).name for p in paths)}: belt A {c.stiffness[0]:.0f} N/m, "
                 f"belt B {c.stiffness[1]:.0f} N/m; spectra {c.similarity:.1f} % alike"
                 + (" (read as matched)" if c.matched else ""))
    measurement = desc.data.setdefault("measurement", {})
    measurement["belt_files"] = [{"name": str(tests[k][2]), "sha256": sha256_of(tests[k][2]),
                                  "test": "AXIS=1,1" if k == "a" else "AXIS=1,-1"} for k in DIRECTIONS]
    desc.notes.extend(notes + c.notes)
    return c
