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

import math
from dataclasses import dataclass, field

from ringtune.hardware.firmware_check import canonical, check_available, check_axis, check_value, fmt
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.custom import rrf_custom
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.firmware import FIRMWARES, Firmware, Span
from ringtune.shaping.smoothers import is_smoother

_FTM_MODE = {"none": 0, "zv": 1, "zvd": 2, "zvdd": 3, "zvddd": 4, "ei": 5, "2hump_ei": 6, "3hump_ei": 7,
             "mzv": 8}
_PRUSA_TYPE = {"zv": 0, "zvd": 1, "mzv": 2, "ei": 3, "2hump_ei": 4, "3hump_ei": 5}
#: said wherever an acceleration is applied: the slicer has the last word
SLICER_OVERRIDES = ("a sliced file's own acceleration commands (M204, SET_VELOCITY_LIMIT, written by the "
                    "slicer from its printer profile) override this acceleration while it prints: put the "
                    "same value in the slicer (ringtune export --slicer prusaslicer|orcaslicer|cura) or "
                    "rewrite a sliced file with ringtune limit FILE.gcode --accel A")


@dataclass
class Export:
    """What to send, save and expect for one firmware.

    Attributes:
        firmware: firmware name (a key of :data:`ringtune.shaping.firmware.FIRMWARES`).
        lines: G-code lines that apply the config now, in order.
        save_lines: lines that persist it on the printer (``M500``, ``M593 W``); empty if the
            firmware cannot save it from G-code.
        config_text: text for the firmware's config file (``printer.cfg`` section, ``config.g``
            lines), or None.
        config_target: where ``config_text`` belongs (e.g. ``"printer.cfg"``, ``"config.g"``).
        readback: commands whose reply reports the applied settings.
        expected: setting -> intended value, as :mod:`ringtune.hardware.readback` reports them:
            ``"x.type"``, ``"x.freq"``, ``"x.damping"`` (RRF: ``"all.*"``), ``"accel"``.
        setting_lines: setting -> index in ``lines`` of the line that sets it.
        notes: remarks for the user (e.g. no frequency limit in this firmware, and what to run).
    """

    firmware: str
    lines: list[str]
    save_lines: list[str] = field(default_factory=list)
    config_text: str | None = None
    config_target: str | None = None
    readback: list[str] = field(default_factory=list)
    expected: dict[str, object] = field(default_factory=dict)
    setting_lines: dict[str, int] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    @property
    def record(self) -> Firmware:
        return FIRMWARES[self.firmware]

    def render_commands(self) -> str:
        """The command part: the firmware's comment syntax and G-code lines only, so the whole text
        can be sent to the printer as a file (Klipper reads ``;`` comments, not ``#``)."""
        c = self.record.comment
        out = [f"{c} ringtune export for {self.record.title}"]
        out += [f"{c} note: {n}" for n in self.notes]
        out += self.lines
        if self.save_lines:
            out.append(f"{c} to keep it after a restart:")
            out += self.save_lines
        if self.config_text:
            out.append(f"{c} the {self.config_target} part is written separately (export --part config)")
        return "\n".join(out) + "\n"

    def render_config(self) -> str | None:
        """The config-file part (``printer.cfg`` section, ``config.g`` lines), or None."""
        if not self.config_text:
            return None
        c = "#" if self.config_target == "printer.cfg" else self.record.comment
        head = (f"{c} ringtune export for {self.record.title}: put this in {self.config_target}"
                + (" (it replaces an existing [input_shaper] section)" if self.config_target == "printer.cfg"
                   else ""))
        return head + "\n" + self.config_text.rstrip("\n") + "\n"

    def render(self) -> str:
        """Both parts, the config part after a comment line saying where it belongs."""
        cfg = self.render_config()
        return self.render_commands() + ("" if cfg is None else "\n" + cfg)


def export_config(config: TuneConfig, firmware: str | None = None, accel: bool = True) -> Export:
    """The lines that put ``config`` on ``firmware`` (default: ``config.firmware``); ``accel``
    False leaves the printer's acceleration alone."""
    fw = Firmware.named(firmware or config.firmware, "--firmware")
    build = {"klipper": _klipper, "rrf": _rrf, "marlin": _marlin, "marlin-ftm": _marlin_ftm,
             "prusa": _prusa}[fw.family]
    exp = build(config, fw.name)
    _freq_limit(config, fw, exp)
    _accel(config, fw, exp, accel)
    return exp


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
                     f"this config was tuned at; {SLICER_OVERRIDES}")
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
    if fw.family == "rrf" and exp.config_text:
        exp.config_text += line + "\n"
    exp.notes.append(f"the per-axis acceleration caps become {text} mm/s² ({line}), as this config was "
                     "planned: each axis's share of a move's acceleration stays under its cap")


def _no_axis_caps(fw: Firmware, exp: Export, text: str) -> None:
    fork = "; Kalico's limited_* kinematics do (--firmware kalico)" if fw.family == "klipper" else ""
    exp.notes.append(f"this config was planned with per-axis acceleration caps ({text} mm/s²), which "
                     f"{fw.title} does not have{fork}")


def _axis_caps_line(fw: Firmware, sent: dict[str, float]) -> str:
    """The record's command for the caps given (``M201 X.. Y..``; an axis not given is left out)."""
    words = [w for w in fw.axis_accel_set.split()
             if not any("{" + ax + "}" in w for ax in "xy" if ax not in sent)]
    return " ".join(words).format(**{ax: fmt(v, fw.axis_accel.decimals) for ax, v in sent.items()})


def _accel_persistence(config: TuneConfig, fw: Firmware, exp: Export, a: float) -> None:
    """Where the acceleration (and the caps) stay after a restart, from the firmware record."""
    caps = config.axis_caps != (None, None) and bool(fw.axis_accel_set)
    if fw.family == "klipper":
        _klipper_printer_section(fw, exp, a, caps)
    elif fw.family == "rrf" and exp.config_text:
        exp.config_text += exp.lines[-1] + "\n"
    elif fw.family in ("marlin", "marlin-ftm"):
        exp.notes.append("M500 stores M201 and M204" if caps else
                         "Marlin also caps each axis at its M201 X/Y maximum (push reads it back and says "
                         "when it holds the acceleration lower); M500 stores M204")
    elif fw.family == "prusa":
        exp.notes.append("M593 W stores the shaper, not M204" + (" or M201" if caps else "")
                         + ": the acceleration lasts until restart")


def _klipper_printer_section(fw: Firmware, exp: Export, a: float, caps: bool) -> None:
    """Klipper/Kalico: the [printer] keys that keep the acceleration (and Kalico's caps), as
    comment lines of the config part (it replaces [input_shaper] only)."""
    keys = [fw.axis_accel_config.format(ax=k[-1]) for k in exp.expected
            if k.startswith("max_accel_") and caps and fw.axis_accel_config]
    exp.notes.append(f"SET_VELOCITY_LIMIT lasts until restart: {', '.join(['max_accel', *keys])} in "
                     "printer.cfg's [printer] section keeps it")
    if exp.config_text:
        exp.config_text += f"# and in the [printer] section: max_accel: {fmt(a, fw.accel.decimals)}\n"
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
    if fw.freq_limit and config.freq_limit_method == "marlin":
        f = check_value(hz, Span(0.0, 100.0, 2, lo_open=True), "frequency limit F", "Hz", "config: freq_limit_hz",
                        "Marlin M201 F")
        pct = check_value(config.min_speed_factor * 100, Span(1.0, 100.0, 0), "minimum speed S", "%",
                          "config: min_speed_factor", "Marlin M201 S")
        exp.setting_lines["limit"] = len(exp.lines)
        exp.lines.append(f"M201 F{fmt(f, 2)} S{fmt(pct, 0)}")
        exp.notes.append("M201 F/S needs XY_FREQUENCY_LIMIT compiled in (older Marlin uses G<min%> "
                         "instead of S)")
        return
    if fw.freq_limit:
        exp.notes.append(f"this config's frequency limit was tuned with the '{config.freq_limit_method}' "
                         f"method, which Marlin's M201 F does not run, so no M201 F is sent: apply it to "
                         f"the G-code instead: {limit_command(config)}")
        return
    exp.notes.append(f"{fw.title} has no XY frequency limit; apply it to the G-code instead: "
                     f"{limit_command(config)}")


# -- Klipper ---------------------------------------------------------------------------------------

def _klipper_value(v) -> str:
    """A shaper parameter as Klipper parses it (``[\\d.]+``; int without a point)."""
    if isinstance(v, int) or float(v) == int(v) and abs(v) < 1e9:
        return str(int(v))
    return fmt(float(v), 9)


def _freq_key(name: str | None, ax: str) -> str:
    """Kalico's smoothers take ``smoother_freq_<ax>``; every shaper ``shaper_freq_<ax>``."""
    return f"smoother_freq_{ax}" if name and is_smoother(name) else f"shaper_freq_{ax}"


def _freq_params(name: str | None, freq: float, ax: str, fw) -> list[str]:
    """``SHAPER_FREQ_X=…`` (``SMOOTHER_FREQ_X=…`` for a smoother); an axis turned off on Kalico gets
    both at 0 (a smoother there reads only SMOOTHER_FREQ)."""
    out = [f"{_freq_key(name, ax).upper()}={fmt(freq, fw.freq.decimals)}"]
    if name is None and fw.flavor == "kalico":
        out.append(f"SMOOTHER_FREQ_{ax.upper()}=0")
    return out


def _klipper_config_lines(ax: str, name: str | None, freq: float, damping: float, fw) -> list[str]:
    """The ``[input_shaper]`` lines of one axis (a smoother has no damping ratio)."""
    if not name:
        return [f"shaper_freq_{ax}: 0"]
    lines = [f"shaper_type_{ax}: {name}", f"{_freq_key(name, ax)}: {fmt(freq, fw.freq.decimals)}"]
    if not is_smoother(name):
        lines.append(f"damping_ratio_{ax}: {fmt(damping, fw.damping.decimals)}")
    return lines


def _klipper_axes(config: TuneConfig, fw) -> dict:
    """{axis: (shaper name with its parameters or None, freq Hz, damping)} as Klipper is told them."""
    per_axis = {}
    for ax in ("x", "y"):
        base, p, freq, damping = check_axis(config, fw, ax)
        if base == "none":
            per_axis[ax] = (None, 0.0, damping)
            continue
        name = base + ("(" + ",".join(f"{k}={_klipper_value(v)}" for k, v in p.items()) + ")" if p else "")
        per_axis[ax] = (name, freq, damping)
    return per_axis


def _klipper_params(per_axis: dict, fw) -> tuple[list[str], dict]:
    """SET_INPUT_SHAPER's parameters in Klipper's order (frequencies, damping ratios of shapers that
    have one, types) and the values read back for each."""
    params: list[str] = []
    expected: dict[str, object] = {}
    for ax, (name, freq, _) in per_axis.items():
        params += _freq_params(name, freq, ax, fw)
        expected[f"{ax}.freq"] = freq
    for ax, (name, _, damping) in per_axis.items():
        if name and not is_smoother(name):
            params.append(f"DAMPING_RATIO_{ax.upper()}={fmt(damping, fw.damping.decimals)}")
            expected[f"{ax}.damping"] = damping
    for ax, (name, _, _) in per_axis.items():
        if name:
            params.append(f"SHAPER_TYPE_{ax.upper()}={name}")
            expected[f"{ax}.type"] = name
    return params, expected


def _klipper(config: TuneConfig, dialect: str) -> Export:
    fw = FIRMWARES[dialect]
    per_axis = _klipper_axes(config, fw)
    params, expected = _klipper_params(per_axis, fw)
    cfg = ["[input_shaper]"]
    for ax in ("x", "y"):
        cfg += _klipper_config_lines(ax, *per_axis[ax], fw)
    line = "SET_INPUT_SHAPER " + " ".join(params)
    exp = Export(dialect, [line], [], "\n".join(cfg) + "\n", fw.config_file, ["SET_INPUT_SHAPER"],
                 expected, {k: 0 for k in expected},
                 [f"{fw.title} keeps nothing set by SET_INPUT_SHAPER across a restart (SAVE_CONFIG does "
                  "not save it either; only printer.cfg does): put the [input_shaper] section (export "
                  "--part config) in printer.cfg"])
    _rounding_notes(config, exp)
    return exp


# -- RepRapFirmware ---------------------------------------------------------------------------------

def _rrf(config: TuneConfig, dialect: str) -> Export:
    fw = FIRMWARES[dialect]
    title = fw.title
    sx, fx, dx = config.axis("x")
    sy, fy, dy = config.axis("y")
    bx = check_available(sx, dialect, "config: shaper_x")
    by = check_available(sy, dialect, "config: shaper_y")
    same = bx == by and (bx in ("none", "custom") or (math.isclose(fx, fy) and math.isclose(dx, dy)))
    if not same:
        raise RingtuneError(f"{title} applies one shaper to all axes, but X is {sx} {fx:g} Hz ζ={dx:g} "
                            f"and Y is {sy} {fy:g} Hz ζ={dy:g}; give both axes the same shaper", "config")
    for ax in ("x", "y"):
        check_axis(config, fw, ax)
    expected: dict[str, object] = {"all.type": fw.native(bx)}
    if bx == "none":
        line = 'M593 P"none"'
    elif bx == "custom":
        line = 'M593 P"custom" ' + _rrf_custom(config, dialect)
    else:
        f, z = fw.freq.sent(fx), fw.damping.sent(dx)
        line = f'M593 P"{fw.native(bx)}" F{fmt(f, fw.freq.decimals)} S{fmt(z, fw.damping.decimals)}'
        expected.update({"all.freq": f, "all.damping": z})
    if dialect != "rrf" and bx != "none":
        line += _rrf_l(config, dialect)
    exp = Export(dialect, [line], [], line + "\n", fw.config_file, ["M593"], expected,
                 {k: 0 for k in expected},
                 [f"{title} cannot save M593 (M500 does not store it): add the config.g part "
                  "(export --part config) to config.g"])
    _rounding_notes(config, exp)
    return exp


def _rrf_l(config: TuneConfig, dialect: str) -> str:
    if dialect == "rrf35" and "reduction_limit" in config.extra:
        val = float(config.extra["reduction_limit"])
        val = check_value(val, Span(0.01, 1.0, 3), "reduction limit L", "", "config: reduction_limit",
                          "RepRapFirmware 3.5")
        return f" L{fmt(val, 3)}"
    if dialect == "rrf34" and "min_accel" in config.extra:
        val = float(config.extra["min_accel"])
        val = check_value(val, Span(1.0, 1e6, 1), "minimum acceleration L", "mm/s²", "config: min_accel",
                          "RepRapFirmware 3.4")
        return f" L{fmt(val, 1)}"
    return ""


def custom_impulses(config: TuneConfig, axis: str = "x") -> tuple[list[float], list[float]]:
    """(amplitudes, times s) of the config's custom shaper on ``axis``, validated: first time 0,
    times strictly increasing, amplitudes positive summing to 1, 2..5 impulses (RRF takes at most
    4 H values)."""
    where = "config: custom"
    name, freq, damping = config.axis(axis)
    _, params = canonical(name)
    if params:
        semantics = "3.6" if config.firmware == "rrf" else "3.5"
        amps, times = rrf_custom(params.get("h"), params.get("t"), freq, damping,
                                 semantics, where=f"config: shaper_{axis} {name!r}")
        return [float(a) for a in amps], [float(t) for t in times]
    amps, times = _spec_impulses(config.extra.get("custom"), where)
    _check_impulses(amps, times, where)
    return amps, times


def _spec_impulses(spec, where: str) -> tuple[list[float], list[float]]:
    """The config's ``"custom": {"amplitudes": [...], "times": [...]}`` as two lists of numbers."""
    if not isinstance(spec, dict) or "amplitudes" not in spec or "times" not in spec:
        raise RingtuneError('a custom shaper needs "custom": {"amplitudes": [...], "times": [...]} in '
                            "the config", where)
    try:
        return [float(a) for a in spec["amplitudes"]], [float(t) for t in spec["times"]]
    except (TypeError, ValueError):
        raise RingtuneError("amplitudes and times must be lists of numbers", where) from None


#: what RepRapFirmware's custom impulses must satisfy: (refused when, message, where suffix), in order
_IMPULSE_RULES = (
    (lambda a, t: len(a) != len(t), lambda a, t: f"{len(a)} amplitudes but {len(t)} times", ""),
    (lambda a, t: not 2 <= len(a) <= 5,
     lambda a, t: f"RepRapFirmware takes 2 to 5 impulses (at most 4 H values), not {len(a)}", ""),
    (lambda a, t: any(not math.isfinite(x) or x <= 0 for x in a), lambda a, t: "amplitudes must be positive",
     ".amplitudes"),
    (lambda a, t: not math.isclose(sum(a), 1.0, abs_tol=1e-6), lambda a, t: f"amplitudes must sum to 1, not {sum(a):g}",
     ".amplitudes"),
    (lambda a, t: t[0] != 0 or any(y <= x for x, y in zip(t, t[1:])),
     lambda a, t: "times must start at 0 and strictly increase", ".times"),
    (lambda a, t: t[-1] > 0.5, lambda a, t: f"last impulse at {t[-1]:g} s: times are in seconds", ".times"),
)


def _check_impulses(amps: list[float], times: list[float], where: str) -> None:
    """Refuse impulses that break one of :data:`_IMPULSE_RULES` (the first that applies)."""
    for broken, message, suffix in _IMPULSE_RULES:
        if broken(amps, times):
            raise RingtuneError(message(amps, times), where + suffix)


def _rrf_custom(config: TuneConfig, dialect: str) -> str:
    amps, times = custom_impulses(config, "x")
    amps_y, times_y = custom_impulses(config, "y")
    if len(amps_y) != len(amps) or not all(math.isclose(a, b, abs_tol=1e-9) for a, b in
                                           zip(amps + times, amps_y + times_y)):
        raise RingtuneError(f"{FIRMWARES[dialect].title} applies one shaper to all axes, but the custom "
                            f"shapers of X and Y differ; give both axes the same impulses", "config")
    if dialect == "rrf":    # 3.6: individual amplitudes except the last; cumulative delays
        h = amps[:-1]
        if sum(h) >= 1:  # pragma: no cover - guarded by positive amplitudes summing to 1
            raise RingtuneError("H must sum to less than 1", "config: custom")
        t = times[1:]
    else:                   # 3.4/3.5: cumulative amplitudes except the last; durations between impulses
        h = [sum(amps[:i + 1]) for i in range(len(amps) - 1)]
        t = [b - a for a, b in zip(times, times[1:])]
    return "H" + ":".join(fmt(v, 4) for v in h) + " T" + ":".join(fmt(v, 6) for v in t)


# -- Marlin -----------------------------------------------------------------------------------------

def _marlin(config: TuneConfig, dialect: str) -> Export:
    fw = FIRMWARES[dialect]
    lines, expected, where_line = [], {}, {}
    for ax in ("x", "y"):
        base, params, freq, damping = check_axis(config, fw, ax)
        if base == "none":
            lines.append(f"M593 {ax.upper()} F0")
            expected[f"{ax}.freq"] = 0.0
        else:
            lines.append(f"M593 {ax.upper()} F{fmt(freq, fw.freq.decimals)} D{fmt(damping, fw.damping.decimals)}")
            expected.update({f"{ax}.freq": freq, f"{ax}.damping": damping})
        for k in expected:
            where_line.setdefault(k, len(lines) - 1)
    exp = Export(dialect, lines, list(fw.save), None, None, ["M593"], expected, where_line,
                 ["Marlin's minimum F depends on the board (the echo delay must fit its timer)"])
    low = [f"{ax.upper()} {fmt(config.axis(ax)[1], 2)} Hz" for ax in "xy"
           if config.axis(ax)[0] != "none" and 0 < config.axis(ax)[1] < fw.build_min_freq]
    if low:
        exp.notes.append(f"{', '.join(low)} is below {fw.build_min_freq:g} Hz, {fw.build_min_freq_why}: "
                         f"build with SHAPING_MIN_FREQ at or below it (Configuration_adv.h), or tune with "
                         f"--shaping-min-freq your build's value")
    _rounding_notes(config, exp)
    return exp


def _vtol(params: dict, where: str, title: str) -> float | None:
    """The EI vibration tolerance (the only shaper parameter Marlin FT_MOTION and Prusa take)."""
    if not params:
        return None
    return check_value(float(params["v_tol"]), Span(0.001, 1.0, 3), "vibration tolerance v_tol", "", where, title)


def _marlin_ftm(config: TuneConfig, dialect: str) -> Export:
    fw = FIRMWARES[dialect]
    lines, expected, where_line = ["M493 S1"], {}, {}
    for ax in ("x", "y"):
        base, params, freq, damping = check_axis(config, fw, ax)
        line = f"M493 {ax.upper()} C{_FTM_MODE[base]}"
        expected[f"{ax}.mode"] = _FTM_MODE[base]
        if base != "none":
            line += f" A{fmt(freq, fw.freq.decimals)} I{fmt(damping, fw.damping.decimals)}"
            expected.update({f"{ax}.freq": freq, f"{ax}.damping": damping})
            vtol = _vtol(params, f"config: shaper_{ax}", fw.title)
            if vtol is not None:
                line += f" Q{fmt(vtol, 3)}"
                expected[f"{ax}.vtol"] = vtol
        lines.append(line)
        for k in expected:
            where_line.setdefault(k, len(lines) - 1)
    notes = ["M493 S1 turns FT_MOTION on"]
    if any(v > 0.25 for k, v in expected.items() if k.endswith(".damping")):
        notes.append("some FT_MOTION builds cap damping I at FTM_MAX_DAMPENING 0.25")
    exp = Export(dialect, lines, list(fw.save), None, None, ["M493"], expected, where_line, notes)
    _rounding_notes(config, exp)
    return exp


# -- Prusa Buddy ------------------------------------------------------------------------------------

def _prusa(config: TuneConfig, dialect: str) -> Export:
    fw = FIRMWARES[dialect]
    lines, expected, where_line = [], {}, {}
    for ax in ("x", "y"):
        base, params, freq, damping = check_axis(config, fw, ax)
        if base == "none":
            lines.append(f"M593 {ax.upper()} F0")
            expected[f"{ax}.type"] = "none"
        else:
            line = (f"M593 {ax.upper()} T{_PRUSA_TYPE[base]} F{fmt(freq, fw.freq.decimals)} "
                    f"D{fmt(damping, fw.damping.decimals)}")
            vtol = _vtol(params, f"config: shaper_{ax}", fw.title)
            if vtol is not None:
                line += f" R{fmt(1 / vtol, 3)}"
            lines.append(line)
            expected.update({f"{ax}.type": base, f"{ax}.freq": freq, f"{ax}.damping": damping})
        for k in expected:
            where_line.setdefault(k, len(lines) - 1)
    exp = Export(dialect, lines, list(fw.save), None, None, ["M593"], expected, where_line,
                 ["Prusa keeps M593 settings only after M593 W (written to EEPROM)"])
    _rounding_notes(config, exp)
    return exp
