"""A Y shaper frequency per layer band in each firmware's own G-code (Hz, g, mm/s²); the job
rewriter (:func:`ringtune.shaping.rewrite.rewrite_job`, ``layer_inserts``) puts them at layer changes.

- Klipper, Kalico: ``SET_INPUT_SHAPER SHAPER_FREQ_Y=<Hz>`` (the rest of the shaper stays).
- Marlin classic: ``M593 Y F<Hz>``; FT_MOTION: ``M493 Y A<Hz>``.
- Prusa Buddy: ``M74 W<g>``, the mass on the bed; the firmware moves Y itself by its own linear
  rule (``M74.cpp``, ``get_weight_adjusted_frequency``): ``f = F + A·min(W/M, 1)`` from Y's F, with
  ``M593 A<Hz> M<g>`` (A < 0; it changes no axis), by default A = −20 Hz, M = 800 g
  (``input_shaper_config.hpp``; XL and iX: A = 0).
- RepRapFirmware: one shaper for every axis, ``M593 P"<type>" F<Hz> S<ζ>``: moving it for Y moves
  X's too.

An acceleration, where the band has one, follows with the firmware's own command.
"""

from __future__ import annotations

from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.firmware import FIRMWARES

#: Prusa Buddy's default Y weight adjustment (frequency delta Hz, mass limit g), all but XL and iX
PRUSA_WEIGHT_ADJUST = (-20.0, 800.0)
#: the comment every inserted line carries, so the lines can be found (and removed)
TAG = "; ringtune mass schedule"


def _num(v: float, decimals: int) -> str:
    s = f"{v:.{decimals}f}"
    return s.rstrip("0").rstrip(".") if "." in s else s


def prusa_weight_frequency(f0: float, grams: float, delta: float = PRUSA_WEIGHT_ADJUST[0],
                           limit: float = PRUSA_WEIGHT_ADJUST[1]) -> float:
    """Hz Prusa Buddy sets on Y after ``M74 W<grams>`` from its Y frequency ``f0``: linear from f0
    at 0 g to f0 + delta at ``limit`` g, held there beyond (``limit`` 0: f0)."""
    if limit <= 0:
        return f0
    return f0 + delta * min(max(grams, 0.0) / limit, 1.0)


def band_commands(firmware: str, freq_y: float, grams: float, *, accel: float | None = None,
                  shaper: str = "mzv", damping: float = 0.1) -> list[str]:
    """The lines that set Y's shaper frequency ``freq_y`` (Hz) for a band with ``grams`` of print on
    the bed (Prusa: the mass itself) and, when given, the acceleration ``accel`` (mm/s²).
    ``shaper``/``damping``: the config's (RepRapFirmware re-states them: one shaper for all axes)."""
    if firmware not in FIRMWARES:
        raise RingtuneError(f"firmware must be one of {', '.join(FIRMWARES)}, not {firmware!r}", "firmware")
    fw = FIRMWARES[firmware]
    f = _num(freq_y, min(fw.freq.decimals, 2))
    if fw.family == "klipper":
        out = [f"SET_INPUT_SHAPER SHAPER_FREQ_Y={f}"]
    elif fw.family == "prusa":
        out = [f"M74 W{max(grams, 1.0):.0f}"]      # Buddy refuses W ≤ 0
    elif fw.family == "marlin-ftm":
        out = [f"M493 Y A{f}"]
    elif fw.family == "marlin":
        out = [f"M593 Y F{f}"]
    else:                      # RepRapFirmware: one shaper, all axes
        native = dict(fw.native_names).get(shaper, shaper)
        out = [f'M593 P"{native}" F{f} S{_num(damping, fw.damping.decimals)}']
    if accel:
        out.append(f"SET_VELOCITY_LIMIT ACCEL={accel:.0f}" if fw.family == "klipper" else f"M204 P{accel:.0f}")
    return out
