"""Kalico's input smoothers (``smooth_zv``, ``smooth_mzv``, ``smooth_ei``, ``smooth_2hump_ei``,
``smooth_zvd_ei``, ``smooth_si``): continuous kernels, not impulse trains.

Facts from Kalico's source (KalicoCrew/kalico 8b9f661, ``klippy/extras/shaper_defs.py``,
``input_shaper.py``, ``chelper/integrate.c``, ``kin_shaper.c``):

- each smoother is a polynomial ``w(τ) = Σ c_k τ^k`` on ``[−T_sm/2, T_sm/2]``, zero outside, with
  ``T_sm = k_sm / f`` (``f`` the configured ``smoother_freq``); the table's dimensionless
  coefficients ``a_k`` (for ``u = τ/T_sm``) give ``c_k = a_k / T_sm^(k+1)``, then normalised to unit
  integral over the support (``init_smoother``). The damping ratio is not used (``damping_ratio_unused``);
- the smoothed position is ``x_sm(t) = ∫ w(τ)·x(t + t_offs − τ) dτ`` with ``t_offs = ∫ τ·w(τ) dτ``
  (``get_smoother_offset``, ``range_integrate``): centred, no lag at constant speed;
- remaining vibration of a mode (ω, ζ), measured at the end of the kernel (the comment above
  ``get_zv_smoother``): ``V = |∫_0^T_sm e^{−ζωt}·e^{jω_d t}·w(T_sm/2 − t) dt|``.

ringtune carries a smoother as a :class:`~ringtune.shaping.shapers.Smoother` — a ``Shaper``
whose impulses (:func:`quadrature`) are the Gauss–Legendre quadrature of that convolution integral (``NODES`` nodes on
the support, weights ``W_j·w(τ_j)``, at causal times ``τ_j + T_sm/2``, plus two impulses of zero
weight at 0 and ``T_sm`` that pin the support's ends). For a smooth integrand (the kernel times a
polynomial, an exponential) the quadrature is exact to rounding: the remaining vibration, the
centroid and the variance computed from the impulses are the kernel's own, and the shaped motion
is exact wherever the kernel spans no change of acceleration; across one, each acceleration step
becomes a staircase of ``NODES`` steps instead of the kernel's smooth ramp (position error below
a micrometre: see the tests). Smoothing, whose 90° part integrates a kernel cut at its centre, is
computed from the polynomial exactly (:func:`smoother_smoothing_terms`).

Units: s, Hz, mm, mm/s, mm/s².
"""

from __future__ import annotations

import numpy as np
from numpy.polynomial import Polynomial

#: Kalico's table: name -> (dimensionless coefficients, highest power first, as in shaper_defs;
#: T_sm·f; min_freq Hz, "projected max_accel ~= 1000")
KALICO_SMOOTHERS: dict[str, tuple[tuple[float, ...], float, float]] = {
    "smooth_zv": ((-118.4265334338076, 5.861885495127615, 29.52796003014231, -1.465471373781904,
                   0.01966833207740377), 0.8025, 18.0),
    "smooth_mzv": ((-1906.717580206364, 125.8892756660212, 698.0200035767849, -37.75923018121473,
                    -62.18762409216703, 1.57172781617736, 1.713117990217123), 0.95625, 20.0),
    "smooth_ei": ((-1797.048868963208, 120.5310596109878, 669.6653197989012, -35.71975707450795,
                   -62.49388325512682, 1.396748042940248, 1.848276903900512), 1.06625, 21.0),
    "smooth_2hump_ei": ((-22525.88434486782, 2524.826047114184, 10554.22832043971, -1051.778387878068,
                         -1475.914693073253, 121.2177946817349, 57.95603221424528, -4.018706414213658,
                         0.8375784787864095), 1.14875, 21.5),
    "smooth_zvd_ei": ((-18835.07746719777, 1914.349309746547, 8786.608981369287, -807.3061869131075,
                       -1209.429748155012, 96.48879052981883, 43.1595785340444, -3.577268915175282,
                       1.083220648523371), 1.475, 26.0),
    "smooth_si": ((-6186.76006449789, 1206.747198930197, 2579.985143622855, -476.8554763069169,
                   -295.546608490564, 52.69679971161049, 4.234582468800491, -2.226157642004671,
                   1.267781046297883), 1.245, 21.5),
}
#: Gauss–Legendre nodes of the quadrature (exact for polynomials of degree 2·NODES − 1)
NODES = 64
_X, _W = np.polynomial.legendre.leggauss(NODES)


def is_smoother(name: str) -> bool:
    return name in KALICO_SMOOTHERS


def takes_damping(name: str) -> bool:
    """A shaper designed for a damping ratio S: not "none", not one of Kalico's smoothers."""
    return name != "none" and not is_smoother(name)


def unit_kernel(name: str) -> Polynomial:
    """Kalico's ``name`` as a polynomial in ``u = τ/T_sm`` on ``[−½, ½]``, scaled to unit integral."""
    table = KALICO_SMOOTHERS[name][0]
    w = Polynomial(np.asarray(table[::-1], float))          # ascending powers of u
    q = w.integ()
    return w / (q(0.5) - q(-0.5))


def kernel(name: str, freq: float) -> tuple[Polynomial, float, float]:
    """(w as a polynomial in τ seconds with unit integral, T_sm s, t_offs s) of Kalico's ``name`` at
    ``freq`` Hz: ``w(τ) = Σ a_k (τ/T_sm)^k / T_sm`` (``init_smoother``, then its normalisation)."""
    t_sm = KALICO_SMOOTHERS[name][1] / float(freq)
    a = unit_kernel(name).coef
    w = Polynomial(a / t_sm ** (np.arange(len(a)) + 1.0))
    q = (w * Polynomial([0.0, 1.0])).integ()
    return w, t_sm, float(q(0.5 * t_sm) - q(-0.5 * t_sm))


def quadrature(name: str, t_sm: float) -> tuple[np.ndarray, np.ndarray]:
    """(amplitudes, causal times s) of the Gauss–Legendre quadrature of ``name``'s kernel over its
    support ``T_sm``, with the two zero-weight end impulses at 0 and ``T_sm``; the amplitudes do
    not depend on ``T_sm`` (the kernel only scales in time)."""
    u = 0.5 * _X
    amps = np.concatenate([[0.0], 0.5 * _W * unit_kernel(name)(u), [0.0]])
    times = np.concatenate([[0.0], (u + 0.5) * t_sm, [t_sm]])
    return amps / amps.sum(), times          # Σ = 1 to rounding already; exactly 1 after


def smoother_smoothing_terms(coeffs, t_sm: float, offset: float, scv: float = 5.0) -> tuple[float, float, float]:
    """Klipper's smoothing terms (:func:`ringtune.shaping.analysis.smoothing_terms`) of the continuous
    kernel ``Σ coeffs_k τ^k`` (support ``T_sm``, centroid ``offset``), exactly: with ``u = τ − t_offs``,
    ``c90 = √2·scv·∫_{u≥0} w·u``, ``k90 = √2·½∫_{u≥0} w·u²``, ``k180 = ½∫ w·u²`` (mm per mm/s², mm)."""
    w = Polynomial(coeffs)
    h = 0.5 * t_sm
    shifted = w(Polynomial([offset, 1.0]))                   # w(u + t_offs)
    u = Polynomial([0.0, 1.0])
    lo, hi = -h - offset, h - offset

    def integral(p: Polynomial, a: float, b: float) -> float:
        q = p.integ()
        return float(q(b) - q(a))

    c90 = np.sqrt(2.0) * scv * integral(shifted * u, 0.0, hi)
    k90 = np.sqrt(2.0) * 0.5 * integral(shifted * u * u, 0.0, hi)
    k180 = 0.5 * integral(shifted * u * u, lo, hi)
    return float(c90), float(k90), float(k180)
