"""The added-mass method: a known mass ``dm`` (kg) fixed to what moves lowers every resonance of the
axis by ``s = sqrt(m/(m + dm))`` (same springs, same damping coefficients), which gives the moving
mass ``m`` and the stiffness.

:func:`frequency_scale` fits the factor ``s`` to whole resonance spectra (Klipper ``TEST_RESONANCES``
PSDs, the sweep model of :mod:`ringtune.envs.identify`) and states its standard error;
:func:`added_mass` turns two frequencies into mass and stiffness.

What makes the stated error hold up (checked over 40 seeded noisy pairs in the tests):

- one joint fit: the same modes for every unloaded spectrum, the same modes at ``s·freq`` with
  damping ``s·damping`` for every loaded one, a level, slope and noise floor per spectrum;
- the modes kept are the fewest the data support: starting from every mode either spectrum's own
  fit found, a mode is dropped while that lowers the Bayesian information criterion of the joint
  fit (``n·ln(RSS/n) + k·ln n`` on the log spectra, whose scatter is the same in every bin). A noise
  spike that one spectrum's fit took for a mode has no counterpart in the other spectrum; kept, it
  lets the fit follow the noise and the linearised error shrinks below the real scatter;
- the error is the sandwich covariance of the weighted least squares (the weights favour the
  peaks and are not inverse variances): ``inv(JᵀWJ)·JᵀW²J·inv(JᵀWJ)·σ²``, σ² from the unweighted
  residuals over ``n − k`` degrees of freedom.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import OptimizeResult, least_squares

from ringtune.envs.identify import PLAUSIBLE_DAMPING, AxisFit, psd_model, psd_model_jacobian, psd_weights
from ringtune.shaping.errors import RingtuneError

#: ln s is searched within these factors (a mass several times the moving one lowers f by ~0.3)
SCALE_RANGE = (0.3, 3.0)
#: starts of the factor besides the dominant modes' ratio: the cost has minima one mode apart
SCALE_STARTS = (0.6, 0.8, 1.0, 1.25)
#: evaluations per fit: a start that has not converged by then is in the wrong valley
MAX_EVALUATIONS = 300


@dataclass
class _Spectra:
    """The log spectra of one axis fitted together: bins ``f`` (Hz), ``logp`` (ln PSD), weights ``w``
    and whether each spectrum was measured with the added mass (``loaded``).

    Parameters ``x`` = ``[ln s, (ln C, p, ln b) per spectrum, (freq, damping, share) per mode]``."""

    f: list[np.ndarray]
    logp: list[np.ndarray]
    w: list[np.ndarray]
    loaded: list[bool]

    @classmethod
    def from_fits(cls, bases: list[AxisFit], loads: list[AxisFit]) -> "_Spectra":
        f, logp, w = [], [], []
        for fit in bases + loads:
            p = np.asarray(fit.y_measured, dtype=float)
            p = np.maximum(p, p.max() * 1e-9)
            f.append(np.asarray(fit.x_measured, dtype=float))
            logp.append(np.log(p))
            w.append(psd_weights(p))
        return cls(f, logp, w, [False] * len(bases) + [True] * len(loads))

    @property
    def first_mode(self) -> int:
        """Index in ``x`` of the first mode parameter."""
        return 1 + 3 * len(self.f)

    @property
    def bins(self) -> int:
        return sum(len(f) for f in self.f)

    def weights(self) -> np.ndarray:
        return np.concatenate(self.w)

    def spectrum_params(self, x: np.ndarray, i: int) -> np.ndarray:
        """The sweep-model parameters of spectrum ``i``: its own level, slope and floor, the modes
        scaled by ``s`` (frequency and damping) when it was loaded."""
        modes = x[self.first_mode:].reshape(-1, 3).copy()
        if self.loaded[i]:
            modes[:, :2] *= math.exp(x[0])
        return np.concatenate([x[1 + 3 * i:4 + 3 * i], modes.ravel()])

    def residuals(self, x: np.ndarray) -> np.ndarray:
        return np.concatenate([w * (np.log(psd_model(self.spectrum_params(x, i), f)) - lp)
                               for i, (f, lp, w) in enumerate(zip(self.f, self.logp, self.w))])

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        """d residuals / dx, from :func:`psd_model_jacobian` of each spectrum by the chain rule."""
        rows = []
        scale = math.exp(x[0])
        for i, (f, w) in enumerate(zip(self.f, self.w)):
            px = self.spectrum_params(x, i)
            d = psd_model_jacobian(px, f)
            out = np.zeros((len(f), x.size))
            out[:, 1 + 3 * i:4 + 3 * i] = d[:, :3]
            dm = d[:, 3:].copy()
            if self.loaded[i]:
                scaled = px[3:].reshape(-1, 3)
                out[:, 0] = d[:, 3::3] @ scaled[:, 0] + d[:, 4::3] @ scaled[:, 1]
                dm[:, 0::3] *= scale
                dm[:, 1::3] *= scale
            out[:, self.first_mode:] = dm
            rows.append(w[:, None] * out)
        return np.vstack(rows)


def _bounds(spectra: _Spectra, modes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = len(spectra.f)
    lo = [math.log(SCALE_RANGE[0])] + [-np.inf, -2.0, -np.inf] * n
    hi = [math.log(SCALE_RANGE[1])] + [np.inf, 6.0, np.inf] * n
    lo += [v for fn in modes[:, 0] for v in (0.5 * fn, PLAUSIBLE_DAMPING[0], 0.005)]
    hi += [v for fn in modes[:, 0] for v in (1.5 * fn, 0.5, 3.0)]
    return np.array(lo), np.array(hi)


def _typical_steps(spectra: _Spectra, x: np.ndarray) -> np.ndarray:
    """The solver's parameter scales: ln s 0.02, level and floor 0.5 (ln), slope 0.1, a mode's
    frequency 0.5 Hz, damping 0.01, share 0.1 (scales from the Jacobian break down when a mode's
    share reaches zero and its frequency and damping columns vanish)."""
    n_modes = (x.size - spectra.first_mode) // 3
    return np.array([0.02] + [0.5, 0.1, 0.5] * len(spectra.f) + [0.5, 0.01, 0.1] * n_modes)


def _fit(spectra: _Spectra, x: np.ndarray) -> OptimizeResult:
    """Weighted least squares from ``x`` (the modes may move half their frequency either way)."""
    lb, ub = _bounds(spectra, x[spectra.first_mode:].reshape(-1, 3))
    x = np.clip(x, lb + 1e-9, ub - 1e-9)
    return least_squares(spectra.residuals, x, jac=spectra.jacobian, bounds=(lb, ub),
                         x_scale=_typical_steps(spectra, x), max_nfev=MAX_EVALUATIONS)


def _start(spectra: _Spectra, origin: AxisFit, scale: float, from_loaded: bool) -> np.ndarray:
    """A start at factor ``scale`` with the modes of ``origin``'s own fit (brought back by
    ``1/scale`` if it is a loaded spectrum), each spectrum's level met at its median."""
    modes = origin.params[3:].reshape(-1, 3).copy()
    if from_loaded:
        modes[:, :2] /= scale
    x = np.concatenate([[math.log(scale)], np.tile(origin.params[:3], len(spectra.f)), modes.ravel()])
    for i, (f, lp) in enumerate(zip(spectra.f, spectra.logp)):
        x[1 + 3 * i] += float(np.median(lp - np.log(psd_model(spectra.spectrum_params(x, i), f))))
    return x


def _bic(spectra: _Spectra, sol: OptimizeResult) -> float:
    """Bayesian information criterion of a joint fit, from its unweighted log-spectrum residuals."""
    n = spectra.bins
    rss = float(np.sum((sol.fun / spectra.weights()) ** 2))
    return n * math.log(max(rss, 1e-300) / n) + sol.x.size * math.log(n)


def _without_mode(spectra: _Spectra, x: np.ndarray, i: int) -> np.ndarray:
    k = spectra.first_mode
    return np.concatenate([x[:k], np.delete(x[k:].reshape(-1, 3), i, axis=0).ravel()])


def _fewest_modes(spectra: _Spectra, sol: OptimizeResult) -> OptimizeResult:
    """Backward elimination: drop the mode whose removal lowers the BIC most, while one does."""
    score = _bic(spectra, sol)
    while (sol.x.size - spectra.first_mode) // 3 > 1:
        n_modes = (sol.x.size - spectra.first_mode) // 3
        trials = [_fit(spectra, _without_mode(spectra, sol.x, i)) for i in range(n_modes)]
        scores = [_bic(spectra, t) for t in trials]
        best = int(np.argmin(scores))
        if scores[best] >= score:
            break
        sol, score = trials[best], scores[best]
    return sol


def _standard_error(spectra: _Spectra, sol: OptimizeResult) -> float:
    """Standard error of ln s: sandwich covariance of the weighted fit, σ² from the unweighted
    residuals (the log spectrum's scatter is the same in every bin)."""
    w = spectra.weights()
    jw = spectra.jacobian(sol.x)                        # = W·J
    try:
        bread = np.linalg.pinv(jw.T @ jw)
    except np.linalg.LinAlgError:
        return float("nan")
    meat = (jw * w[:, None]).T @ (jw * w[:, None])
    sigma2 = float(np.sum((sol.fun / w) ** 2)) / max(sol.fun.size - sol.x.size, 1)
    return float(math.sqrt(max((bread @ meat @ bread)[0, 0] * sigma2, 0.0)))


def _dominant(fit: AxisFit) -> float:
    return max(fit.modes, key=lambda m: m.share).freq


def frequency_scale(base: AxisFit | list[AxisFit], loaded: AxisFit | list[AxisFit]) -> tuple[float, float]:
    """The factor ``s`` by which every resonance of an axis moved between spectrum fits of it (e.g.
    with a mass added), and its standard error (of ln s). ``base`` and ``loaded`` may each be several
    tests (repeats average the measurement noise: the error falls as 1/√N).

    Starts: the modes of the first base fit, or of the first loaded fit brought back by 1/s (the two
    fits may split close modes differently), the factor from their dominant modes and a grid; the
    lowest information criterion wins, then modes the joint data do not support are dropped (module
    docstring)."""
    bases = list(base) if isinstance(base, list) else [base]
    loads = list(loaded) if isinstance(loaded, list) else [loaded]
    if not bases or not loads or any(f.params is None for f in bases + loads):
        raise RingtuneError("needs spectrum fits of both measurements", bases[0].source if bases else "added_mass")
    spectra = _Spectra.from_fits(bases, loads)
    starts = sorted({_dominant(loads[0]) / _dominant(bases[0]), *SCALE_STARTS})
    sols = [_fit(spectra, _start(spectra, origin, s, origin is not bases[0]))
            for origin in (bases[0], loads[0]) for s in starts]
    best = _fewest_modes(spectra, min(sols, key=lambda sol: _bic(spectra, sol)))
    return float(math.exp(best.x[0])), _standard_error(spectra, best)


def added_mass(f0: float, f1: float, dm: float) -> tuple[float, float]:
    """Moving mass (kg) and stiffness (N/m) of a mode from the added-mass method: the same spring
    carries the moving mass ``m`` at ``f0`` (Hz) and ``m + dm`` (``dm`` kg fixed to it) at ``f1``, so
    ``(f0/f1)² = (m + dm)/m``: ``m = dm / ((f0/f1)² − 1)`` and ``k = m·(2π f0)²``."""
    if not (f0 > 0 and f1 > 0 and dm > 0):
        raise RingtuneError(f"need f0, f1 > 0 Hz and an added mass > 0 kg (got {f0}, {f1}, {dm})", "added_mass")
    ratio = (f0 / f1) ** 2 - 1.0
    if ratio <= 0:
        raise RingtuneError(f"the loaded frequency {f1:.2f} Hz is not below the unloaded {f0:.2f} Hz: the "
                            "added mass did not move with the axis, or the two tests differ", "added_mass")
    m = dm / ratio
    return m, m * (2.0 * math.pi * f0) ** 2
