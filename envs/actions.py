"""The action encoding of the gymnasium environments: how a normalised action in [-1, 1]^n maps to a
:class:`~ringtune.shaping.config.TuneConfig` (:func:`decode_action`) and back (:func:`encode_config`),
absolute or anchored on the resonance peaks and a model acceleration (:class:`ActionSpec`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.shapers import max_damping


@dataclass(frozen=True)
class ActionSpec:
    """How a normalised action in [-1, 1]^n maps to a :class:`TuneConfig` (see :func:`decode_action`).

    Attributes:
        firmware: target firmware (decides the shaper flavour, centred or causal).
        shapers: shaper types the action chooses among (``"none"`` allowed).
        per_axis: separate type, F, S for X and Y (else one set shared by both axes).
        freq_range: Hz, shaper frequency range (log scale).
        damping_range: shaper damping ratio range (linear; clipped to what the shaper allows).
        freq_limit_max: Hz, top of the frequency-limit range; ``freq_limit_off`` Hz and below = off.
        tune_accel: whether the last action entry chooses the acceleration.
        accel_range: mm/s², acceleration range (log scale) when ``tune_accel``.
        freq_anchor: ``"absolute"`` (F on a log scale over ``freq_range``) or ``"peak"`` (F
            relative to the axis's resonance peak: ``f_peak·anchor_span^v``, v in [-1, 1]).
        anchor_span: with ``freq_anchor="peak"``, F covers ``[f_peak/span, f_peak·span]``.
        freq_limit_gate: the frequency limit is off for the lower half of its action entry and
            spans ``freq_limit_off``–``freq_limit_max`` Hz over the upper half (off unless chosen).
        accel_anchor: ``"absolute"`` (acceleration on a log scale over ``accel_range``) or
            ``"model"`` (relative to an anchor acceleration ``a_anchor·anchor_span^v``, v in [-1, 1];
            the env computes the anchor from the starting configuration's metrics, see
            :func:`model_accel`).
        accel_start: mm/s², the anchor before it is known (what the starting action decodes with).
    """

    firmware: str = "klipper"
    shapers: tuple[str, ...] = ("none", "zv", "mzv", "zvd", "ei", "2hump_ei", "3hump_ei")
    per_axis: bool = True
    freq_range: tuple[float, float] = (15.0, 150.0)
    damping_range: tuple[float, float] = (0.02, 0.25)
    freq_limit_max: float = 120.0
    freq_limit_off: float = 10.0
    tune_accel: bool = False
    accel_range: tuple[float, float] = (1000.0, 10000.0)
    freq_anchor: str = "absolute"
    anchor_span: float = 2.0
    freq_limit_gate: bool = False
    accel_anchor: str = "absolute"
    accel_start: float = 4000.0

    @property
    def size(self) -> int:
        return (6 if self.per_axis else 3) + 1 + (1 if self.tune_accel else 0)

    def labels(self) -> list[str]:
        axis = (["shaper_x", "freq_x", "damping_x", "shaper_y", "freq_y", "damping_y"] if self.per_axis
                else ["shaper", "freq", "damping"])
        return axis + ["freq_limit_hz"] + (["accel"] if self.tune_accel else [])


def _unit(u: float) -> float:
    """[-1, 1] -> [0, 1] (clipped)."""
    return (min(max(float(u), -1.0), 1.0) + 1.0) / 2.0


def _around(anchor: float, span: float, u: float, lo: float, hi: float) -> float:
    """``anchor·span^v`` with ``v = 2u − 1`` (``u`` in [0, 1]), clipped to [lo, hi]: a residual
    around a physical anchor, from ``anchor/span`` to ``anchor·span``."""
    return min(max(anchor * span ** (2.0 * u - 1.0), lo), hi)


def _unit_around(x: float, anchor: float, span: float) -> float:
    """The ``u`` for which :func:`_around` gives ``x`` (before clipping)."""
    return (math.log(x / anchor) / math.log(span) + 1.0) / 2.0


def _anchors(spec: ActionSpec, peaks) -> tuple[float, float] | None:
    """(X, Y) anchor frequencies in Hz for ``spec`` (None for absolute decoding); a shared
    setting anchors both axes at the geometric mean of the peaks."""
    if spec.freq_anchor == "absolute":
        return None
    if spec.freq_anchor != "peak":
        raise RingtuneError(f"freq_anchor must be 'absolute' or 'peak', not {spec.freq_anchor!r}", "freq_anchor")
    if peaks is None:
        raise RingtuneError("peak-relative actions need the resonance peaks (X, Y) in Hz", "peaks")
    fx, fy = (float(peaks[0]), float(peaks[1]))
    if not (fx > 0 and fy > 0):
        raise RingtuneError(f"resonance peaks must be > 0 Hz, not {peaks}", "peaks")
    return (fx, fy) if spec.per_axis else (math.sqrt(fx * fy),) * 2


def decode_action(action, spec: ActionSpec, peaks=None, accel_anchor: float | None = None) -> TuneConfig:
    """The configuration an action in [-1, 1]^spec.size stands for.

    Per axis (or shared) triple ``(type, F, S)``: type = ``spec.shapers[k]`` with ``k`` the index
    of the equal-width bin of [-1, 1] the value falls in; F = ``f_lo·(f_hi/f_lo)^u`` (log scale,
    ``u`` = value mapped to [0, 1]) or, with ``spec.freq_anchor == "peak"``, F =
    ``f_peak·span^v`` (``v`` the value in [-1, 1], ``f_peak`` the axis's entry of ``peaks`` (X, Y)
    in Hz, span = ``spec.anchor_span``), clipped to ``freq_range``; S = ``s_lo + u·(s_hi − s_lo)``,
    clipped to the shaper's largest allowed damping. Then frequency limit ``u·freq_limit_max`` Hz,
    off (0) at or below ``freq_limit_off`` (with ``freq_limit_gate``: off for ``u ≤ 1/2``, else
    ``off + (2u − 1)·(max − off)`` Hz); and, with ``tune_accel``, acceleration
    ``a_lo·(a_hi/a_lo)^u`` mm/s² (with ``spec.accel_anchor == "model"``: ``a·span^v`` clipped to
    ``accel_range``, ``a`` = ``accel_anchor`` mm/s², default ``spec.accel_start``). Values outside
    [-1, 1] are clipped.
    """
    a = np.asarray(action, dtype=float).ravel()
    if a.shape != (spec.size,):
        raise RingtuneError(f"action must have {spec.size} entries ({', '.join(spec.labels())}), "
                            f"not shape {np.shape(action)}", "action")
    flavor = TuneConfig(firmware=spec.firmware, shaper_x="none", shaper_y="none").flavor
    anchors = _anchors(spec, peaks)

    def triple(i, axis):
        k = min(int(_unit(a[i]) * len(spec.shapers)), len(spec.shapers) - 1)
        name = spec.shapers[k]
        f_lo, f_hi = spec.freq_range
        if anchors is None:
            freq = f_lo * (f_hi / f_lo) ** _unit(a[i + 1])
        else:
            freq = _around(anchors[axis], spec.anchor_span, _unit(a[i + 1]), f_lo, f_hi)
        s_lo, s_hi = spec.damping_range
        damping = s_lo + _unit(a[i + 2]) * (s_hi - s_lo)
        if name != "none":
            damping = min(damping, max_damping(name, flavor))
        return name, freq, damping

    x = triple(0, 0)
    y = triple(3, 1) if spec.per_axis else x
    j = 6 if spec.per_axis else 3
    if spec.freq_limit_gate:
        u = _unit(a[j])
        limit = 0.0 if u <= 0.5 else spec.freq_limit_off + (2.0 * u - 1.0) * (spec.freq_limit_max - spec.freq_limit_off)
    else:
        limit = _unit(a[j]) * spec.freq_limit_max
    accel = None
    if spec.tune_accel:
        lo, hi = spec.accel_range
        if spec.accel_anchor == "model":
            accel = _around(float(accel_anchor or spec.accel_start), spec.anchor_span, _unit(a[j + 1]), lo, hi)
        else:
            accel = lo * (hi / lo) ** _unit(a[j + 1])
    return TuneConfig(firmware=spec.firmware, shaper_x=x[0], freq_x=x[1], damping_x=x[2],
                      shaper_y=y[0], freq_y=y[1], damping_y=y[2],
                      freq_limit_hz=limit if limit > spec.freq_limit_off else 0.0, accel=accel)


def encode_config(config: TuneConfig, spec: ActionSpec, peaks=None, accel_anchor: float | None = None) -> np.ndarray:
    """The action (centre of the shaper's bin) that decodes to ``config`` (up to clipping);
    ``peaks`` (X, Y) Hz and ``accel_anchor`` mm/s² as for :func:`decode_action`."""
    anchors = _anchors(spec, peaks)

    def back(u):
        return 2.0 * min(max(u, 0.0), 1.0) - 1.0

    def triple(ax, i):
        name, freq, damping = config.axis(ax)
        k = spec.shapers.index(name) if name in spec.shapers else 0
        f_lo, f_hi = spec.freq_range
        s_lo, s_hi = spec.damping_range
        f = min(max(freq, f_lo), f_hi)
        if anchors is None:
            uf = math.log(f / f_lo) / math.log(f_hi / f_lo)
        else:
            uf = _unit_around(f, anchors[i], spec.anchor_span)
        return [back((k + 0.5) / len(spec.shapers)), back(uf), back((damping - s_lo) / (s_hi - s_lo))]

    out = triple("x", 0) + (triple("y", 1) if spec.per_axis else [])
    if config.freq_limit_hz <= 0:
        out.append(-1.0)
    elif spec.freq_limit_gate:
        lim = max(config.freq_limit_hz, spec.freq_limit_off)
        out.append(back((1.0 + (lim - spec.freq_limit_off) / (spec.freq_limit_max - spec.freq_limit_off)) / 2.0))
    else:
        out.append(back(config.freq_limit_hz / spec.freq_limit_max))
    if spec.tune_accel:
        lo, hi = spec.accel_range
        acc = min(max(config.accel or lo, lo), hi)
        if spec.accel_anchor == "model":
            out.append(back(_unit_around(acc, float(accel_anchor or spec.accel_start), spec.anchor_span)))
        else:
            out.append(back(math.log(acc / lo) / math.log(hi / lo)))
    return np.asarray(out, dtype=np.float32)
