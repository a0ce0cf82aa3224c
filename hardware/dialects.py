"""Firmware dialects: a :class:`TuneConfig` as each firmware's own G-code and config lines.

Syntax and ranges follow ``shared/reference/firmware.md`` (§1.5 Klipper, §2 Marlin, §3 RRF, §4 Prusa):

==============  ==============================================================  ==================
dialect         runtime lines                                                    frequency limit
==============  ==============================================================  ==================
``klipper``     ``SET_INPUT_SHAPER SHAPER_FREQ_X= ... SHAPER_TYPE_Y=``          none (ringtune limit)
``rrf``         RRF 3.6: ``M593 P"mzv" F40 S0.1``; custom ``H`` individual       none (ringtune limit)
                amplitudes, ``T`` cumulative delays (s)
``rrf35``       RRF 3.5: custom ``H`` cumulative amplitudes, ``T`` durations;   none (ringtune limit)
                ``L`` = reduction limit (fraction)
``rrf34``       as rrf35 but ``L`` = minimum acceleration (mm/s²)               none (ringtune limit)
``marlin``      ``M593 X F40 D0.15`` (ZV only)                                   ``M201 F<Hz> S<%>``
``marlin-ftm``  ``M493 S1`` + ``M493 X C<mode> A<Hz> I<zeta> [Q<vtol>]``        ``M201 F<Hz> S<%>``
``prusa``       ``M593 X T<type> F<Hz> D<zeta> [R<red.>]``; ``M593 W`` saves      none (ringtune limit)
==============  ==============================================================  ==================

Marlin's ``M201 F S`` is sent only for a config tuned with Marlin's own algorithm (method
``marlin``); another method's limit goes to the G-code with ``ringtune limit`` and no M201 F is sent.
The config's acceleration is applied with the firmware's own command (Klipper
``SET_VELOCITY_LIMIT ACCEL=``, Marlin/Prusa/RRF ``M204 P``) and read back.

Before any line is built, every value is checked exactly as ``ringtune shaper`` checks a shaper
(name, parameters, the shaper's damping limit) plus the firmware's ranges and precision from its
record (:data:`ringtune.shaping.firmware.FIRMWARES`): a value that would round to another one is
refused, never changed.

RRF applies one shaper to every axis, so an RRF config must give X and Y the same shaper. A custom
RRF shaper is ``shaper_x = "custom"`` with ``extra["custom"] = {"amplitudes": [A1..An] (sum 1),
"times": [0, T2..Tn] (s)}``; it is converted to the H/T meaning of the chosen RRF version.
"""

from __future__ import annotations

import dataclasses

from ringtune.hardware.dialect_klipper import klipper_export
from ringtune.hardware.dialect_marlin import marlin_export, marlin_ftm_export, prusa_export
from ringtune.hardware.dialect_rrf import rrf_export
from ringtune.hardware.export import Export
from ringtune.hardware.firmware_check import canonical, check_value, fmt
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.feature_settings import corner_words
from ringtune.shaping.firmware import Firmware, Span
from ringtune.shaping.prusa_limits import PRUSA_HARDWARE_LIMITS, STEALTH_ACCEL

#: firmware family -> the builder of its lines (one module per family's dialect)
_BUILDERS = {"klipper": klipper_export, "rrf": rrf_export, "marlin": marlin_export,
             "marlin-ftm": marlin_ftm_export, "prusa": prusa_export}
#: said wherever an acceleration is applied: the slicer has the last word
SLICER_OVERRIDES = ("a sliced file's own acceleration commands (M204, SET_VELOCITY_LIMIT, written by the "
                    "slicer from its printer profile) override this acceleration while it prints: put the "
                    "same value in the slicer (ringtune export --slicer prusaslicer|orcaslicer|cura) or "
                    "rewrite a sliced file with ringtune limit FILE.gcode --accel A")

#: said where a configuration sets accelerations or corner rules per feature: a firmware holds one
PER_FEATURE = ("this configuration sets accelerations (or corner rules) per feature, which a firmware cannot "
               "hold: these lines carry the visible walls' {a} mm/s², and the per-feature settings belong in the "
               "job: print the job tune wrote with them (job.gcode, from tune --gcode), write them into any sliced "
               "job with ringtune rewrite JOB --config CONFIG -o OUT, or re-slice with ringtune export CONFIG "
               "--slicer prusaslicer|orcaslicer|cura; with these lines alone the job prints at the visible walls' "
               "acceleration everywhere")


def export_config(config: TuneConfig, firmware: str | None = None, accel: bool = True) -> Export:
    """The lines that put ``config`` on ``firmware`` (default: ``config.firmware``); ``accel``
    False leaves the printer's acceleration (and Klipper's corner rule) alone."""
    fw = Firmware.named(firmware or config.firmware, "--firmware")
    exp = _BUILDERS[fw.family](config, fw.name)
    carried = accel and _carries_corner(config, fw)
    if config.per_feature:
        exp.notes.insert(0, PER_FEATURE.format(a=fmt(config.accel or 0, 0)) + _corner_not_carried(config, carried))
    _rounding_notes(config, exp)
    _freq_limit(config, fw, exp)
    _accel(config, fw, exp, accel)
    _klipper_corner(config, fw, exp, carried)
    if accel:
        _hardware_ceiling(config, fw, exp)
    return exp


def _hardware_ceiling(config: TuneConfig, fw: Firmware, exp: Export) -> None:
    """On Prusa-Firmware-Buddy: where the config asks more than a model's compiled ceiling
    (:mod:`ringtune.shaping.prusa_limits`), which no file names here, that it runs at the ceiling there."""
    if fw.name != "prusa":
        return
    asked = max([config.accel or 0.0, *config.feature_accel.values(), *(c or 0.0 for c in config.axis_caps)])
    limits = {m: (h["normal"].max_accel[0], h["stealth"].max_accel[0]) for m, h in PRUSA_HARDWARE_LIMITS.items()}
    if asked <= STEALTH_ACCEL:
        return
    known = "; ".join(f"{m} {n:.0f}, in stealth mode {st:.0f}" for m, (n, st) in limits.items())
    lower = [m for m, (n, _st) in limits.items() if n < asked]
    where = (f"on the {' and the '.join(lower)}, and on any of them in stealth mode," if lower
             else "in stealth mode")
    exp.notes.append(f"this config asks for up to {asked:.0f} mm/s², and Prusa-Firmware-Buddy holds M201 X/Y to its "
                     f"model's hardware limit whatever a line asks ({known} mm/s²): {where} the printer runs at "
                     "its limit, slower than this config was planned (tune --gcode on a job naming its model, "
                     "M862.3, plans with it)")


def _carries_corner(config: TuneConfig, fw: Firmware) -> bool:
    """Whether the lines set the visible walls' corner rule the configuration was tuned with: on
    Klipper and Kalico (``SET_VELOCITY_LIMIT SQUARE_CORNER_VELOCITY= MINIMUM_CRUISE_RATIO=``), for a
    configuration tuned for one of them (its ``corner`` is then a square_corner_velocity, mm/s)."""
    tuned_for = Firmware.named(config.firmware, "config: firmware").junctions
    given = bool(corner_words(config.corner, config.min_cruise_ratio))
    return (fw.family, tuned_for) == ("klipper", ("scv",)) and given


#: Klipper's SET_VELOCITY_LIMIT words of the corner rule: (word, config field, expected key and
#: [printer] key, unit, range)
_KLIPPER_CORNER = (("SQUARE_CORNER_VELOCITY", "corner", "square_corner_velocity", "mm/s",
                    Span(0.0, 1000.0, 6, why="Klipper takes any SQUARE_CORNER_VELOCITY >= 0; ringtune's "
                                              "bound on a corner value")),
                   ("MINIMUM_CRUISE_RATIO", "min_cruise_ratio", "minimum_cruise_ratio", "",
                    Span(0.0, 0.999999, 6, why="Klipper takes 0 <= MINIMUM_CRUISE_RATIO < 1")))


def _klipper_corner_values(config: TuneConfig, fw: Firmware) -> list[tuple]:
    """[(word, key, unit, value as sent, its text)] of the corner settings the configuration gives."""
    out = []
    for word, name, key, unit, span in _KLIPPER_CORNER:
        value = getattr(config, name)
        if value is not None:
            v = check_value(value, span, key, unit, f"config: {name}", fw.title)
            out.append((word, key, unit, v, fmt(v, span.decimals)))
    return out


def _klipper_corner(config: TuneConfig, fw: Firmware, exp: Export, carried: bool) -> None:
    """Where ``carried``: the visible walls' corner rule as Klipper's own command, read back with the
    acceleration's report, and the [printer] keys that keep it (comment lines of the config part)."""
    if not carried:
        return
    values = _klipper_corner_values(config, fw)
    exp.setting_lines.update({key: len(exp.lines) for _, key, _, _, _ in values})
    exp.expected.update({key: v for _, key, _, v, _ in values})
    exp.lines.append("SET_VELOCITY_LIMIT " + " ".join(f"{word}={text}" for word, _, _, _, text in values))
    _read_back(exp, fw.accel_report)
    keys = "".join(f"#   {key}: {text}\n" for _, key, _, _, text in values)
    exp.config_text = _printer_section(exp.config_text) + keys
    exp.notes.append(_corner_note(values))


#: the comment of Klipper's config part that opens the [printer] keys to set (the part replaces
#: [input_shaper] only)
_PRINTER_KEYS = "# and in the [printer] section:"


def _printer_section(config_text: str) -> str:
    """Klipper's config part, ending in the comment that opens the [printer] keys to set."""
    return config_text if _PRINTER_KEYS in config_text else config_text + _PRINTER_KEYS + "\n"


def _corner_note(values: list[tuple]) -> str:
    """What the corner rule becomes, and what keeps it after a restart."""
    said = " and ".join(f"{key} {text}{unit and ' ' + unit}" for _, key, unit, _, text in values)
    keys = " and ".join(key for _, key, _, _, _ in values)
    return (f"the corner rule becomes {said}, the visible walls' own this config was tuned with; "
            f"SET_VELOCITY_LIMIT lasts until restart: {keys} in printer.cfg's [printer] section keep it")


def _corner_not_carried(config: TuneConfig, carried: bool) -> str:
    """The PER_FEATURE note's tail where the configuration was tuned with a corner rule for the visible
    walls (``corner``, ``min_cruise_ratio``), which these lines do not set: "" where it has none or
    they set it (``carried``)."""
    words = [] if carried else corner_words(config.corner, config.min_cruise_ratio)
    if not words:
        return ""
    return (f"; nor do they set the visible walls' corner rule it was tuned with ({'; '.join(words)}, "
            "in the printer's corner rule's unit): set it on the printer as well, or print the job")


def limit_command(config: TuneConfig) -> str:
    """The ``ringtune limit`` command that applies the config's frequency limit to G-code instead:
    its limit (Hz), its method and its minimum speed factor, so the G-code gets the limit that was
    tuned (the command's own defaults may differ)."""
    return (f"ringtune limit FILE.gcode --freq-limit {fmt(config.freq_limit_hz, 2)} "
            f"--method {config.freq_limit_method} --min-speed-factor {fmt(config.min_speed_factor, 3)} "
            "-o FILE-limited.gcode")


def _accel(config: TuneConfig, fw: Firmware, exp: Export, apply: bool) -> None:
    """The config's per-axis caps, then its printing acceleration, as the firmware's own commands,
    read back afterwards (the caps first: Marlin applies M201 to every move planned after it)."""
    if config.accel is None and config.axis_caps == (None, None):
        return
    if not apply:
        exp.notes.append(f"the config's acceleration {fmt(config.accel or 0, 0)} mm/s² and axis caps are not "
                         "applied (--no-accel): the printer keeps its own")
        return
    _axis_caps(config, fw, exp)
    if config.accel is None:
        return
    a = check_value(config.accel, fw.accel, "acceleration", "mm/s²", "config: accel", fw.title)
    exp.setting_lines["accel"] = len(exp.lines)
    exp.lines.append(fw.accel_set.format(a=fmt(a, fw.accel.decimals)))
    exp.expected["accel"] = a
    if "travel" in fw.accel_roles:
        exp.setting_lines["travel_accel"] = exp.setting_lines["accel"]
        exp.expected["travel_accel"] = a
    _read_back(exp, fw.accel_report)
    if fw.axis_accel_report and config.axis_caps == (None, None):
        _read_back(exp, fw.axis_accel_report)     # push says whether the printer's caps hold it lower
    exp.notes.append(f"the printing acceleration becomes {fmt(a, fw.accel.decimals)} mm/s², the value "
                     f"this config was tuned at" + ("" if config.per_feature else f"; {SLICER_OVERRIDES}"))
    _accel_persistence(config, fw, exp, a)


def _read_back(exp: Export, command: str) -> None:
    if command not in exp.readback:
        exp.readback.append(command)


def _axis_caps(config: TuneConfig, fw: Firmware, exp: Export) -> None:
    """The X/Y caps the config runs with (``max_accel_x``/``y``), set before the acceleration."""
    caps = {ax: c for ax, c in zip("xy", config.axis_caps) if c is not None}
    if not caps:
        return
    text = ", ".join(f"{ax.upper()} {fmt(c, 0)}" for ax, c in caps.items())
    if not fw.axis_accel_set:
        _no_axis_caps(fw, exp, text)
        return
    sent = {ax: check_value(c, fw.axis_accel, f"{ax.upper()} acceleration cap", "mm/s²",
                            f"config: max_accel_{ax}", fw.title) for ax, c in caps.items()}
    line = _axis_caps_line(fw, sent)
    for ax, v in sent.items():
        exp.setting_lines[f"max_accel_{ax}"] = len(exp.lines)
        exp.expected[f"max_accel_{ax}"] = v
    exp.lines.append(line)
    _read_back(exp, fw.axis_accel_report)
    if fw.family == "rrf":                    # config.g: the M201 line after M593
        exp.config_text += line + "\n"
    exp.notes.append(f"the per-axis acceleration caps become {text} mm/s² ({line}), as this config was "
                     "planned: each axis's share of a move's acceleration stays under its cap")


def _no_axis_caps(fw: Firmware, exp: Export, text: str) -> None:
    fork = "; Kalico's limited_* kinematics do (--firmware kalico)" if fw.family == "klipper" else ""
    exp.notes.append(f"this config was planned with per-axis acceleration caps ({text} mm/s²), which "
                     f"{fw.title} does not have{fork}")


def _axis_caps_line(fw: Firmware, sent: dict[str, float]) -> str:
    """The record's command for the caps given (``M201 X.. Y..``; an axis not given is left out)."""
    unsent = set("xy") - set(sent)
    words = [w for w in fw.axis_accel_set.split() if not any("{" + ax + "}" in w for ax in unsent)]
    return " ".join(words).format(**{ax: fmt(v, fw.axis_accel.decimals) for ax, v in sent.items()})


#: Marlin and Prusa: what their save command keeps of the acceleration (without, with axis caps)
_ACCEL_KEPT = {
    "marlin": ("Marlin also caps each axis at its M201 X/Y maximum (push reads it back and says when it holds "
               "the acceleration lower); M500 stores M204", "M500 stores M201 and M204"),
    "prusa": ("M593 W stores the shaper, not M204: the acceleration lasts until restart",
              "M593 W stores the shaper, not M204 or M201: the acceleration lasts until restart"),
}
_ACCEL_KEPT["marlin-ftm"] = _ACCEL_KEPT["marlin"]


def _accel_persistence(config: TuneConfig, fw: Firmware, exp: Export, a: float) -> None:
    """Where the acceleration (and the caps) stay after a restart, from the firmware record."""
    if fw.family == "klipper":
        _klipper_printer_section(fw, exp, a)
    elif fw.family == "rrf":                  # config.g: the M204 line after M593 (and M201)
        exp.config_text += exp.lines[-1] + "\n"
    else:
        caps = config.axis_caps != (None, None) and bool(fw.axis_accel_set)
        exp.notes.append(_ACCEL_KEPT[fw.family][caps])


def _klipper_printer_section(fw: Firmware, exp: Export, a: float) -> None:
    """Klipper/Kalico: the [printer] keys that keep the acceleration (and Kalico's caps, when the
    config sets them), as comment lines of the config part (it replaces [input_shaper] only)."""
    keys = [fw.axis_accel_config.format(ax=k[-1]) for k in exp.expected
            if k.startswith("max_accel_") and fw.axis_accel_config]
    exp.notes.append(f"SET_VELOCITY_LIMIT lasts until restart: {', '.join(['max_accel', *keys])} in "
                     "printer.cfg's [printer] section keeps it")
    exp.config_text += f"{_PRINTER_KEYS} max_accel: {fmt(a, fw.accel.decimals)}\n"
    exp.config_text += "".join(f"#   {key}: {fmt(exp.expected['max_accel_' + key[4]], fw.axis_accel.decimals)}\n"
                               for key in keys)


def _rounding_notes(config: TuneConfig, exp: Export) -> None:
    """Say where a value goes out rounded to the firmware's precision (within the tolerance)."""
    fw = exp.record
    for key, span in (("freq_x", fw.freq), ("freq_y", fw.freq), ("damping_x", fw.damping),
                      ("damping_y", fw.damping)):
        ax = key[-1]
        if canonical(config.axis(ax)[0])[0] in ("none", "custom"):
            continue
        value = getattr(config, key)
        if span.sent(value) != value:
            exp.notes.append(f"{key} {value:g} is sent as {fmt(value, span.decimals)} (values go to "
                             f"{fw.title} with {span.decimals} decimals, the precision read back)")


def _freq_limit(config: TuneConfig, fw: Firmware, exp: Export) -> None:
    """Marlin's own limit (``M201 F S``) only for a config tuned with Marlin's algorithm; every
    other limit goes to the G-code with ``ringtune limit`` (never both: the printer would apply
    another algorithm than the one tuned)."""
    hz = config.freq_limit_hz
    if hz <= 0:
        return
    if not fw.freq_limit:
        exp.notes.append(f"{fw.title} has no XY frequency limit; apply it to the G-code instead: "
                         f"{limit_command(config)}")
        return
    if config.freq_limit_method != "marlin":
        exp.notes.append(f"this config's frequency limit was tuned with the '{config.freq_limit_method}' "
                         f"method, which Marlin's M201 F does not run, so no M201 F is sent: apply it to "
                         f"the G-code instead: {limit_command(config)}")
        return
    f = check_value(hz, Span(0.0, 100.0, 2, lo_open=True), "frequency limit F", "Hz", "config: freq_limit_hz",
                    "Marlin M201 F")
    pct = check_value(config.min_speed_factor * 100, Span(1.0, 100.0, 0), "minimum speed S", "%",
                      "config: min_speed_factor", "Marlin M201 S")
    exp.setting_lines["limit"] = len(exp.lines)
    exp.lines.append(f"M201 F{fmt(f, 2)} S{fmt(pct, 0)}")
    exp.notes.append("M201 F/S needs XY_FREQUENCY_LIMIT compiled in (older Marlin uses G<min%> "
                     "instead of S)")


def shaper_commands(config: TuneConfig, firmware: str | None = None) -> list[str]:
    """The G-code lines that set ``config``'s shaper alone on ``firmware`` (default
    ``config.firmware``): :func:`export_config`'s, without its frequency limit and acceleration
    (the job rewriter writes them in place of a job's own shaper command)."""
    return export_config(dataclasses.replace(config, freq_limit_hz=0.0), firmware, accel=False).lines
