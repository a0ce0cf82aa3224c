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

from ringtune.shaping.config import TuneConfig
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


#: the line that sets Y's frequency, by firmware family: ``f`` Hz, ``grams`` g on the bed (Prusa;
#: Buddy refuses W ≤ 0), RepRapFirmware's one shaper for all axes (``shaper``, ``damping``)
_BAND_LINES = {"klipper": "SET_INPUT_SHAPER SHAPER_FREQ_Y={f}", "prusa": "M74 W{grams:.0f}",
               "marlin-ftm": "M493 Y A{f}", "marlin": "M593 Y F{f}", "rrf": 'M593 P"{shaper}" F{f} S{damping}'}


def band_commands(firmware: str, freq_y: float, grams: float, *, accel: float | None = None,
                  shaper: str = "mzv", damping: float = 0.1) -> list[str]:
    """The lines that set Y's shaper frequency ``freq_y`` (Hz) for a band with ``grams`` of print on
    the bed (Prusa: the mass itself) and, when given, the acceleration ``accel`` (mm/s²).
    ``shaper``/``damping``: the config's (RepRapFirmware re-states them: one shaper for all axes)."""
    if firmware not in FIRMWARES:
        raise RingtuneError(f"firmware must be one of {', '.join(FIRMWARES)}, not {firmware!r}", "firmware")
    fw = FIRMWARES[firmware]
    out = [_BAND_LINES[fw.family].format(f=_num(freq_y, min(fw.freq.decimals, 2)), grams=max(grams, 1.0),
                                         shaper=fw.native(shaper), damping=_num(damping, fw.damping.decimals))]
    if accel:
        out.append(f"SET_VELOCITY_LIMIT ACCEL={accel:.0f}" if fw.family == "klipper" else f"M204 P{accel:.0f}")
    return out


def prusa_weight_line(freq_y: float, schedule: list[dict]) -> str | None:
    """``M593 A<Hz> M<g>`` that puts Prusa's linear rule through (0 g, ``freq_y``) and the last
    entry of ``schedule`` (its ``freq_y`` at its ``mass_g``); None when Y does not fall there (A
    must be < 0) or the mass is under 1 g."""
    last = schedule[-1]
    delta, limit = last["freq_y"] - freq_y, last.get("mass_g", 0.0)
    return f"M593 A{delta:.2f} M{limit:.0f}" if delta < 0 and limit >= 1 else None


def schedule_inserts(layer_z: list[float], config: TuneConfig) -> dict[int, list[str]]:
    """{layer index: lines} of ``config.y_schedule`` for a job whose layers (in order) start at the
    heights ``layer_z`` (mm): each entry's lines at the first layer at or above its ``z_mm``, in
    ``config.firmware``'s form (:func:`band_commands`; Prusa also :func:`prusa_weight_line` first)."""
    sched = config.y_schedule or []
    fam = FIRMWARES[config.firmware].family
    out: dict[int, list[str]] = {}
    for i, e in enumerate(sched):
        layer = next((k for k, z in enumerate(layer_z) if z >= e["z_mm"] - 1e-6), None)
        if layer is None:
            raise RingtuneError(f"z_mm {e['z_mm']:g} is above the job's last layer ({max(layer_z):g} mm)",
                                f"config: y_schedule[{i}].z_mm")
        if fam == "prusa" and "mass_g" not in e:
            raise RingtuneError("Prusa's M74 W needs the mass on the bed: mass_g is missing",
                                f"config: y_schedule[{i}]")
        out.setdefault(layer, []).extend(band_commands(config.firmware, e["freq_y"], e.get("mass_g", 0.0),
                                                       accel=e.get("accel"), shaper=config.shaper_y,
                                                       damping=config.damping_y))
    if fam == "prusa" and sched:
        line = prusa_weight_line(config.freq_y, sched)
        if line:
            first = min(out)
            out[first].insert(0, line)
    return out
