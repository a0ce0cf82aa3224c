"""An axis of a printer description (``[x]``, ``[y]``): its vibration modes and moving mass, given as
``modes`` (their shares checked, those left out filled), ``stiffness`` or a chain of ``masses`` +
``stiffnesses``. Units: kg, N/m, Hz (the description's form: :mod:`ringtune.envs.printer`)."""

from __future__ import annotations

import math

import numpy as np

from ringtune.envs.printer_defaults import DEFAULTS
from ringtune.envs.printer_model import AxisModel, Mode
from ringtune.envs.toml_checks import number, refuse_unknown
from ringtune.shaping.errors import RingtuneError

_AXIS_KEYS = {"mass", "modes", "stiffness", "masses", "stiffnesses", "damping", "motor"}
_MODE_KEYS = {"freq", "damping", "share", "mass_share"}


def _modes_from_chain(masses, stiffnesses, damping, where) -> tuple[list[Mode], float]:
    """Modes of a chain motor–k1–m1–k2–m2…, nozzle = last mass: (modes, total mass)."""
    m = np.asarray(masses, float)
    k = np.asarray(stiffnesses, float)
    n = len(m)
    K = np.zeros((n, n))
    for i in range(n):
        K[i, i] += k[i]
        if i + 1 < n:
            K[i, i] += k[i + 1]
            K[i, i + 1] = K[i + 1, i] = -k[i + 1]
    # symmetric form: M^-1/2 K M^-1/2
    s = 1.0 / np.sqrt(m)
    w2, psi = np.linalg.eigh(K * s[:, None] * s[None, :])
    phi = psi * s[:, None]                        # mass-normalised mode shapes (φᵀMφ = 1)
    gamma = phi.T @ m                              # participation factors Γ = φᵀ M 1
    share = phi[-1, :] * gamma                     # nozzle participation, Σ = 1
    mass_share = gamma ** 2 / m.sum()              # effective modal mass fraction, Σ = 1
    if np.any(w2 <= 0):
        raise RingtuneError("masses and stiffnesses give a non-positive mode", where)
    modes = [Mode(float(np.sqrt(w) / (2 * math.pi)), damping, float(sh), float(ms))
             for w, sh, ms in zip(w2, share, mass_share)]
    return modes, float(m.sum())


#: kg: what moves on a printer axis (a toolhead with its carriage, a bed, a gantry) weighs within this
MOVING_MASS_RANGE = (0.05, 30.0)


def check_moving_mass(kg: float, where: str) -> float:
    """``kg`` if it can be what moves on a printer axis (:data:`MOVING_MASS_RANGE`), else refused."""
    lo, hi = MOVING_MASS_RANGE
    if not lo <= kg <= hi:
        raise RingtuneError(f"{kg:g} kg ({1000 * kg:g} g) is outside what moves on a printer axis ({lo:g}-{hi:g} "
                            "kg: a toolhead with its carriage, a bed, a gantry); masses are in kg (600 g is 0.6)",
                            where)
    return kg


def _axis_mass(d: dict, axis: str, w: str) -> float:
    """The axis's moving mass (kg): given (and checked by :func:`check_moving_mass`) or the default."""
    mass = number(d, "mass", w, DEFAULTS[f"mass_{axis}"], lo=0.0, lo_open=True)
    return check_moving_mass(mass, f"{w}.mass") if "mass" in d else mass


def axis_from_dict(d: dict, axis: str, where: str) -> AxisModel:
    w = f"{where}: [{axis}]"
    refuse_unknown(d, _AXIS_KEYS, w)
    d = {k: v for k, v in d.items() if k != "motor"}
    mass = _axis_mass(d, axis, w)
    damping = number(d, "damping", w, DEFAULTS["damping"], lo=0.0, hi=0.95)
    given = [k for k in ("modes", "stiffness", "masses") if k in d]
    if len(given) != 1:
        raise RingtuneError("give exactly one of modes, stiffness, or masses + stiffnesses", w)
    if "modes" in d:
        return AxisModel(mass, _modes_from_list(d["modes"], damping, f"{w}.modes"))
    if "stiffness" in d:
        k = number(d, "stiffness", w, lo=0.0, lo_open=True)
        return AxisModel(mass, [Mode(math.sqrt(k / mass) / (2 * math.pi), damping, 1.0)])
    return _axis_from_chain(d, damping, w)


def _mode_from_dict(md, damping: float, mw: str) -> Mode:
    """One ``{freq, damping, share, mass_share}`` table; a mode without a share gets NaN (filled later)."""
    if not isinstance(md, dict):
        raise RingtuneError("each mode must be a table like { freq = 50, damping = 0.06 }", mw)
    refuse_unknown(md, _MODE_KEYS, mw)
    f = number(md, "freq", mw, lo=0.0, lo_open=True, hi=2000.0)
    z = number(md, "damping", mw, damping, lo=0.0, hi=0.95)
    # physical chains give higher modes small negative shares (nozzle against carriage)
    sh = number(md, "share", mw, math.nan, lo=-2.0, hi=2.0)
    if sh == 0.0:
        raise RingtuneError("share must not be 0 (drop the mode instead)", f"{mw}.share")
    ms = number(md, "mass_share", mw, lo=0.0, hi=1.0) if "mass_share" in md else None
    return Mode(f, z, sh, ms)


def _modes_from_list(raw, damping: float, w: str) -> list[Mode]:
    """An axis's ``modes``: each checked, the shares summing to 1 (modes without one split the rest)."""
    if not isinstance(raw, list) or not raw:
        raise RingtuneError("modes must be a non-empty list of {freq, damping, share}", w)
    modes = [_mode_from_dict(md, damping, f"{w}[{i}]") for i, md in enumerate(raw)]
    _fill_shares(modes, w)
    return modes


def _fill_shares(modes: list[Mode], w: str) -> None:
    """Check the given shares and split what they leave of 1 evenly over the modes without one."""
    free = [m for m in modes if math.isnan(m.share)]
    total = sum(m.share for m in modes if not math.isnan(m.share))
    off = total > 1.0 + 1e-6 if free else abs(total - 1.0) > 1e-3     # free modes take what is left
    if off:
        raise RingtuneError(f"mode shares sum to {total:g}; they must sum to 1 "
                            "(leave one out to let it take what is left)", w)
    if free and 1.0 - total <= 1e-9:
        raise RingtuneError("modes without a share get nothing: the given shares already sum to 1", w)
    for m in free:
        m.share = (1.0 - total) / len(free)


def _axis_from_chain(d: dict, damping: float, w: str) -> AxisModel:
    """An axis given as ``masses`` + ``stiffnesses`` (a chain whose last mass is the nozzle)."""
    ms, ks = d.get("masses"), d.get("stiffnesses")
    for key, v in (("masses", ms), ("stiffnesses", ks)):
        if not isinstance(v, list) or not v or not all(
                isinstance(x, (int, float)) and not isinstance(x, bool) and x > 0 for x in v):
            raise RingtuneError(f"{key} must be a non-empty list of positive numbers", f"{w}.{key}")
    if len(ms) != len(ks):
        raise RingtuneError(f"masses has {len(ms)} entries but stiffnesses has {len(ks)}", f"{w}.stiffnesses")
    if "mass" in d:
        raise RingtuneError("give either mass or masses, not both", f"{w}.mass")
    modes, total = _modes_from_chain(ms, ks, damping, w)
    return AxisModel(total, modes)
