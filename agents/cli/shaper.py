"""``ringtune shaper``: one shaper's impulses and what they cost and buy.

``--json`` keys (stable): ``name``, ``flavor``, ``freq`` (Hz), ``damping``, ``centred`` (bool),
``amplitudes`` (sum 1), ``times_s`` (first 0), ``duration_s``, ``lag_s`` (steady-state lag of the
shaped motion: Σ A_i·T_i when causal, 0 when centred), ``centroid_s``, ``centre_delay_s`` (the
delay a centring firmware subtracts from every impulse time: Σ A_i·T_i, Marlin FT_MOTION rounds
it to whole 1 ms samples, N0 = LROUND(−Σ A_i·N_i); 0 when causal), ``band90_hz`` [lo, hi]
(≥ 90 % vibration reduction for a plant of the shaper's own damping; nulls when there is none), ``band90_pct`` [lo, hi] relative to ``freq``,
``smoothing_mm`` (Klipper's definition at ``accel``/``scv``), ``max_accel`` (mm/s², Klipper's
smoothing ≤ 0.12 mm rule, unrounded; null when the shaper never smooths, e.g. ``none``), ``residual_at_freq`` (fraction left at ``freq``, plant damping
= ``damping``), ``accel``, ``scv``; for Kalico's continuous smoothers also ``kernel_coeffs`` (ascending
c_k of w(τ) = Σ c_k τ^k, τ in s, unit integral), ``smooth_time_s`` (its support) and ``offset_s``
(its centroid, by which Kalico shifts it); their ``amplitudes``/``times_s`` are the quadrature nodes
ringtune convolves with.
"""

from __future__ import annotations

import math

from ringtune.agents.cli.options import VALUES, flavor_name
from ringtune.shaping.analysis import summary
from ringtune.shaping.shapers import get_shaper, is_centred

NAME = "shaper"
DESCRIPTION = """\
Show an input shaper as a firmware would build it: its impulses (amplitude, time), how long it
lasts, how far the shaped motion lags the commanded one (causal firmwares: RRF, Marlin classic;
centred firmwares: Klipper, Prusa, Marlin FT_MOTION have none), the frequency band where it removes
at least 90 % of the ringing, and Klipper's smoothing estimate with the max accel that keeps
smoothing at or below 0.12 mm.

NAME is zv, mzv, zvd, zvdd, zvddd, ei, 2hump_ei (ei2), 3hump_ei (ei3), none or custom, or one of
Kalico's continuous smoothers (--flavor kalico): smooth_zv, smooth_mzv, smooth_ei, smooth_2hump_ei,
smooth_zvd_ei, smooth_si (a polynomial kernel, shown as such); Klipper's
parameterised forms work too: "mzv(n=5,t=1.1)", "ei(v_tol=0.1)"; RRF custom shapers take their
M593 lists: "custom(h=0.4:0.7,t=0.0135:0.0135)".
--flavor picks the firmware's formulas: klipper (default), klipper-legacy (also prusa), kalico, rrf (3.6),
rrf35 (3.4/3.5), marlin (classic ZV), marlin-ftm (M493); any firmware name (prusa, rrf34) gives
its formulas. A shaper the firmware lacks is an error
that names the closest one it has.

example:
  ringtune shaper mzv --freq 40 --damping 0.1
  ringtune shaper ei2 --freq 45 --flavor rrf --json
"""


def add_arguments(parser) -> None:
    parser.add_argument("name", metavar="NAME", help="shaper name, e.g. zv, mzv, ei, 'mzv(n=5,t=1.1)'")
    parser.add_argument("--freq", type=VALUES["freq"], required=True, help="shaper frequency, Hz")
    parser.add_argument("--damping", type=VALUES["damping_ratio"], default=None,
                        help="damping ratio (default: the firmware's default, e.g. 0.1 for Klipper)")
    parser.add_argument("--flavor", type=flavor_name, default="klipper",
                        help="firmware formulas: klipper, klipper-legacy, prusa, rrf, rrf35, marlin, marlin-ftm")
    parser.add_argument("--accel", type=VALUES["accel"], default=5000.0,
                        help="accel for the smoothing figure, mm/s² (5000)")
    parser.add_argument("--scv", type=VALUES["scv"], default=5.0, help="square corner velocity, mm/s (5)")


def finite_or_none(x: float) -> float | None:
    """JSON has no inf/NaN: report them as null."""
    return x if math.isfinite(x) else None


def band_text(lo: float, hi: float) -> str:
    return "none" if not (math.isfinite(lo) and math.isfinite(hi)) else f"{lo:.2f} – {hi:.2f} Hz"


def _impulses(shaper) -> tuple[list[str], dict]:
    """(lines, JSON keys) of the impulses, or of a smoother's kernel (a continuous weight, not
    impulses: ``kernel_coeffs``, ``smooth_time_s``, ``offset_s``)."""
    if hasattr(shaper, "coeffs"):
        terms = " ".join(f"{c:+.6g}·τ^{k}" for k, c in enumerate(shaper.coeffs))
        kernel = {"kernel_coeffs": list(shaper.coeffs), "smooth_time_s": shaper.smooth_time, "offset_s": shaper.offset}
        return [f"  continuous kernel w(τ) = {terms} (τ in s, unit integral)",
                f"  on [−{shaper.smooth_time * 500:.3f}, +{shaper.smooth_time * 500:.3f}] ms, centroid "
                f"{shaper.offset * 1e3:+.4f} ms (the firmware shifts the kernel by it); ringtune convolves with "
                f"its {int((shaper.amplitudes > 0).sum())}-node Gauss–Legendre quadrature"], kernel
    lines = ["  impulse   amplitude   time (ms)"]
    for i, (a, t) in enumerate(zip(shaper.amplitudes, shaper.times)):
        lines.append(f"  {i + 1:7d}   {a:9.4f}   {t * 1e3:9.3f}")
    return lines, {}


def run(args, out) -> int:
    flavor = args.flavor
    shaper = get_shaper(args.name, args.freq, args.damping, flavor, where=f"shaper {args.name!r}")
    centred = is_centred(flavor)
    info = summary(shaper, centred, args.accel, args.scv)
    result = {
        "name": shaper.name, "flavor": flavor, "freq": shaper.freq, "damping": shaper.damping,
        "centred": centred, "amplitudes": shaper.amplitudes.tolist(), "times_s": shaper.times.tolist(),
        "duration_s": info["duration_s"], "lag_s": info["lag_s"], "centroid_s": info["centroid_s"],
        "centre_delay_s": shaper.centre_delay if centred else 0.0,
        "band90_hz": info["band90_hz"], "band90_pct": info["band90_pct"],
        "smoothing_mm": info["smoothing_mm"], "max_accel": finite_or_none(info["max_accel"]),
        "residual_at_freq": info["residual_at_freq"], "accel": args.accel, "scv": args.scv,
    }
    impulse_lines, kernel = _impulses(shaper)
    result.update(kernel)
    lines = [f"{shaper.name} ({flavor}) at {shaper.freq:g} Hz, damping {shaper.damping:g}"] + impulse_lines
    lo, hi = info["band90_hz"]
    plo, phi = info["band90_pct"]
    lines += [
        f"  duration          {info['duration_s'] * 1e3:.3f} ms",
        f"  lag               {info['lag_s'] * 1e3:.3f} ms ({'centred' if centred else 'causal'})"
        + (f", impulses shifted by -{shaper.centre_delay * 1e3:.3f} ms" if centred else ""),
        f"  90% band          {band_text(lo, hi)}" + (f" ({plo:+.1f}% / {phi:+.1f}%)" if lo == lo else ""),
        f"  smoothing         {info['smoothing_mm']:.4f} mm at {args.accel:g} mm/s², scv {args.scv:g} mm/s",
        f"  max_accel         {info['max_accel']:.0f} mm/s² (smoothing <= 0.12 mm)"
        if info["max_accel"] != float("inf") else "  max_accel         no limit (no smoothing)",
        f"  residual at F     {100 * info['residual_at_freq']:.2f} %",
    ]
    out.emit(result, "\n".join(lines))
    return 0
