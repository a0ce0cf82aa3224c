"""The mass schedule in words (``ringtune schedule``): filament and print mass, the bands, and the
last band simulated at the fixed and at the scheduled frequency (µm, s)."""

from __future__ import annotations

from ringtune.agents.tune.mass_schedule import MassSchedule
from ringtune.shaping.firmware import FIRMWARES


def schedule_summary(s: MassSchedule) -> str:
    """The schedule in words: filament, bands, the last band fixed against scheduled, notes."""
    src = s.filament_source
    lines = [f"print mass {s.total_kg * 1e3:.0f} g over {len(s.layers)} layers (filament {s.diameter_mm:g} mm "
             f"({src['diameter_mm']}), {s.density_g_cm3:g} g/cm³ ({src['density_g_cm3']}); --filament-diameter, "
             "--filament-density); Y's dominant mode "
             f"{s.empty_mode_hz:.1f} Hz with the bed as described, {s.final_mode_hz:.1f} Hz on the last layer; "
             f"tuned freq_y {s.config.freq_y:g} Hz"]
    if not s.needed:
        lines.append(f"the mode moves {(1 - s.final_mode_hz / s.empty_mode_hz) * 100:.1f} % over this job, less than "
                     f"the band step ({s.step * 100:g} %): the tuned frequency holds, nothing is inserted")
    else:
        lines.extend(_band_table(s))
        if s.ripple:
            lines.extend(_last_band_table(s.ripple))
    lines.extend(f"note: {n}" for n in s.notes)
    return "\n".join(lines)


def _band_table(s: MassSchedule) -> list[str]:
    prusa = FIRMWARES[s.config.firmware].family == "prusa"
    acc = any(b.accel for b in s.bands)
    lines = [f"{len(s.bands)} bands (a new one where the model's Y mode has moved {s.step * 100:g} %):",
             "  from z mm  layers     mass g  Y mode Hz  freq_y Hz" + ("  accel" if acc else "")
             + ("  Prusa sets Hz  (its defaults)" if prusa else "")]
    for b in s.bands:
        lines.append(f"  {b.z_mm:9.2f}  {b.first_layer:>3}-{b.last_layer:<4} {b.mass_kg * 1e3:8.0f}  "
                     f"{b.mode_hz:9.2f}  {b.freq_y:9.2f}" + (f"  {b.accel or 0:5.0f}" if acc else "")
                     + (f"  {b.prusa_hz:12.2f}  {b.prusa_default_hz:13.2f}" if prusa else ""))
    lines.append(f"  inserted at each band's first layer: {' / '.join(s.bands[-1].commands)} (last band)")
    return lines


def _last_band_table(r: dict) -> list[str]:
    lines = [f"last band (layers {r['first_layer']}-{r['last_layer']}, z {r['z_mm']:.2f}-{r['z_top_mm']:.2f} mm, "
             f"{r['mass_g']:.0f} g on the bed, Y mode {r['mode_hz']:.1f} Hz) simulated on the exact model; "
             "ripple = worst visible wall's peak-to-peak across it, corner in = rounding, out = overshoot, "
             "all against the commanded path:",
             "                         freq_y Hz  accel  ripple µm  corner in µm  corner out µm   time s"]
    for key, label in (("fixed", "fixed"), ("scheduled", "scheduled"), ("prusa_default_rule", "Prusa's default rule")):
        if key in r:
            v = r[key]
            lines.append(f"  {label:<22} {v['freq_y']:9.2f}  {v['accel'] or 0:5.0f}  {v['ripple_mm'] * 1e3:9.1f}  "
                         f"{v['corner_in_mm'] * 1e3:12.1f}  {v['corner_out_mm'] * 1e3:13.1f}  {v['print_time_s']:7.1f}")
    fx, sc = r["fixed"]["ripple_mm"], r["scheduled"]["ripple_mm"]
    if sc > 0:
        lines.append(f"  ripple fixed / scheduled: {fx / sc:.2f}")
    return lines
