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

RRF applies one shaper to every axis, so an RRF config must give X and Y the same shaper. A custom
RRF shaper is ``shaper_x = "custom"`` with ``extra["custom"] = {"amplitudes": [A1..An] (sum 1),
"times": [0, T2..Tn] (s)}``; it is converted to the H/T meaning of the chosen RRF version.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.shapers import parse_name

DIALECTS = ("klipper", "rrf", "rrf35", "rrf34", "marlin", "marlin-ftm", "prusa")

FIRMWARE_TITLE = {
    "klipper": "Klipper", "rrf": "RepRapFirmware 3.6", "rrf35": "RepRapFirmware 3.5",
    "rrf34": "RepRapFirmware 3.4", "marlin": "Marlin (classic input shaping)",
    "marlin-ftm": "Marlin FT_MOTION", "prusa": "Prusa-Firmware-Buddy",
}

#: shapers each dialect has (canonical names; "none" = shaping off)
AVAILABLE = {
    "klipper": ("none", "zv", "mzv", "zvd", "ei", "2hump_ei", "3hump_ei"),
    "rrf": ("none", "zvd", "zvdd", "zvddd", "mzv", "2hump_ei", "3hump_ei", "custom"),
    "rrf35": ("none", "zvd", "zvdd", "zvddd", "mzv", "2hump_ei", "3hump_ei", "custom"),
    "rrf34": ("none", "zvd", "zvdd", "zvddd", "mzv", "2hump_ei", "3hump_ei", "custom"),
    "marlin": ("none", "zv"),
    "marlin-ftm": ("none", "zv", "zvd", "zvdd", "zvddd", "ei", "2hump_ei", "3hump_ei", "mzv"),
    "prusa": ("none", "zv", "zvd", "mzv", "ei", "2hump_ei", "3hump_ei"),
}

#: for a missing shaper, the ones most like it (similar duration and band), best first
_NEAREST = {
    "zv": ("zv", "mzv", "zvd", "ei"),
    "mzv": ("mzv", "zv", "zvd", "ei"),
    "zvd": ("zvd", "mzv", "ei", "zvdd", "zv"),
    "ei": ("ei", "zvd", "mzv", "2hump_ei", "zvdd", "zv"),
    "zvdd": ("zvdd", "2hump_ei", "zvd", "ei", "zvddd", "zv"),
    "zvddd": ("zvddd", "3hump_ei", "zvdd", "2hump_ei", "zvd", "zv"),
    "2hump_ei": ("2hump_ei", "zvdd", "ei", "3hump_ei", "zvd", "zv"),
    "3hump_ei": ("3hump_ei", "zvddd", "2hump_ei", "zvdd", "ei", "zv"),
}
_FTM_MODE = {"none": 0, "zv": 1, "zvd": 2, "zvdd": 3, "zvddd": 4, "ei": 5, "2hump_ei": 6, "3hump_ei": 7,
             "mzv": 8}
_PRUSA_TYPE = {"zv": 0, "zvd": 1, "mzv": 2, "ei": 3, "2hump_ei": 4, "3hump_ei": 5}
#: Klipper HEAD max_damping_ratio per shaper (firmware.md §1.1)
_KLIPPER_MAX_DAMPING = {"zv": 0.99, "mzv": 0.99, "zvd": 0.99, "ei": 0.4, "2hump_ei": 0.3, "3hump_ei": 0.2}
#: RRF 3.4/3.5 minimum frequency on Duet 3: StepClockRate / (2·65535) = 750 kHz / 131070
RRF35_MIN_FREQ = 750000.0 / 131070.0


@dataclass
class Export:
    """What to send, save and expect for one firmware.

    Attributes:
        firmware: dialect name (:data:`DIALECTS`).
        lines: G-code lines that apply the config now, in order.
        save_lines: lines that persist it on the printer (``M500``, ``M593 W``); empty if the
            firmware cannot save it from G-code.
        config_text: text for the firmware's config file (``printer.cfg`` section, ``config.g``
            lines), or None.
        config_target: where ``config_text`` belongs (e.g. ``"printer.cfg"``, ``"config.g"``).
        readback: commands whose reply reports the applied settings.
        expected: setting -> intended value, as :mod:`ringtune.hardware.readback` reports them:
            ``"x.type"``, ``"x.freq"``, ``"x.damping"`` (RRF: ``"all.*"``).
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

    def render(self) -> str:
        """The export file: commented, ready to paste or send."""
        c = "#" if self.firmware == "klipper" else ";"
        out = [f"{c} ringtune export for {FIRMWARE_TITLE[self.firmware]}"]
        out += [f"{c} {n}" for n in self.notes]
        out += self.lines
        if self.save_lines:
            out.append(f"{c} to keep it after a restart:")
            out += self.save_lines
        if self.config_text:
            out.append(f"{c} for {self.config_target}:" if self.firmware != "klipper"
                       else f"{c} printer.cfg section (replaces an existing [input_shaper]):")
            out.append(self.config_text.rstrip("\n"))
        return "\n".join(out) + "\n"


def fmt(value: float, decimals: int = 3) -> str:
    """A number as short as it can be at ``decimals`` places: 40.0 -> '40', 0.15 -> '0.15'."""
    s = f"{value:.{decimals}f}"
    if "." in s:                      # trailing zeros of the fraction only: 4000 stays 4000
        s = s.rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def canonical(name: str) -> tuple[str, dict]:
    """(base name, parameters) of a shaper string: ``"MZV(n=5,t=1.1)"`` -> ``("mzv", {"n": 5, "t": 1.1})``.

    Uses :func:`ringtune.shaping.shapers.parse_name` (Klipper's syntax; aliases such as ``ei2``)."""
    base, params = parse_name(name, f"shaper {name!r}")
    if "_positional" in params:
        pos = params.pop("_positional")
        params.update({str(i): v for i, v in enumerate(pos)})
    return base, params


def check_available(name: str, dialect: str, where: str) -> str:
    """Canonical name if ``dialect`` has the shaper, else a refusal naming the nearest it has."""
    base, _ = canonical(name)
    have = AVAILABLE[dialect]
    if base in have:
        return base
    title = FIRMWARE_TITLE[dialect]
    native = _rrf_name if dialect.startswith("rrf") else (lambda n: n)
    listed = ", ".join(native(h) for h in have if h != "none")
    if base == "custom":
        raise RingtuneError(f"{title} has no custom shaper (only RepRapFirmware takes impulse lists); "
                            f"it has {listed}", where)
    if base not in _NEAREST:
        raise RingtuneError(f"unknown shaper {name!r}; {title} has {listed}", where)
    nearest = next(n for n in _NEAREST[base] if n in have)
    raise RingtuneError(f"{title} has no {base!r} shaper (it has {listed}); the nearest it has is "
                        f"{native(nearest)!r}", where)


def _range(value: float, lo: float, hi: float, what: str, where: str, title: str,
           lo_open: bool = False) -> None:
    if not math.isfinite(value) or value < lo or value > hi or (lo_open and value <= lo):
        raise RingtuneError(f"{what} {value:g} is outside {title}'s range "
                            f"{'(' if lo_open else '['}{lo:g}, {hi:g}]", where)


def export_config(config: TuneConfig, firmware: str | None = None) -> Export:
    """The lines that put ``config`` on ``firmware`` (default: ``config.firmware``)."""
    dialect = firmware or config.firmware
    if dialect not in DIALECTS:
        raise RingtuneError(f"firmware must be one of {', '.join(DIALECTS)}, not {dialect!r}", "--firmware")
    build = {"klipper": _klipper, "rrf": _rrf, "rrf35": _rrf, "rrf34": _rrf, "marlin": _marlin,
             "marlin-ftm": _marlin_ftm, "prusa": _prusa}[dialect]
    exp = build(config, dialect)
    _freq_limit(config, dialect, exp)
    _accel_note(config, exp)
    return exp


def limit_command(config: TuneConfig) -> str:
    """The ``ringtune limit`` command that applies the config's frequency limit to G-code instead:
    its limit (Hz), its method and its minimum speed factor, so the G-code gets the limit that was
    tuned (the command's own defaults may differ)."""
    return (f"ringtune limit FILE.gcode --freq-limit {fmt(config.freq_limit_hz, 2)} "
            f"--method {config.freq_limit_method} --min-speed-factor {fmt(config.min_speed_factor, 3)} "
            "-o FILE-limited.gcode")


def _accel_note(config: TuneConfig, exp: Export) -> None:
    """A config tuned at its own acceleration says so: no dialect line here sets it."""
    if config.accel is not None:
        exp.notes.append(f"this config was tuned at an acceleration of {fmt(config.accel, 0)} mm/s², "
                         "which these lines do not set: print with that acceleration (printer or "
                         "slicer setting) to get the simulated result")


def _freq_limit(config: TuneConfig, dialect: str, exp: Export) -> None:
    hz = config.freq_limit_hz
    if hz <= 0:
        return
    title = FIRMWARE_TITLE[dialect]
    if dialect in ("marlin", "marlin-ftm"):
        _range(hz, 0, 100, "frequency limit F", "config: freq_limit_hz", "Marlin M201 F", lo_open=True)
        pct = round(config.min_speed_factor * 100)
        _range(pct, 1, 100, "minimum speed S (%)", "config: min_speed_factor", "Marlin M201 S")
        exp.setting_lines["limit"] = len(exp.lines)
        exp.lines.append(f"M201 F{fmt(hz, 2)} S{pct}")
        exp.notes.append("M201 F/S needs XY_FREQUENCY_LIMIT compiled in (older Marlin uses G<min%> "
                         "instead of S)")
        if config.freq_limit_method != "marlin":
            exp.notes.append(f"M201 F S applies Marlin's own limit (method 'marlin'); this config was "
                             f"tuned with the '{config.freq_limit_method}' method: for exactly that, "
                             f"leave M201 out and run {limit_command(config)}")
        return
    exp.notes.append(f"{title} has no XY frequency limit; apply it to the G-code instead: "
                     f"{limit_command(config)}")


# -- Klipper ---------------------------------------------------------------------------------------

def _klipper(config: TuneConfig, dialect: str) -> Export:
    params, cfg = [], ["[input_shaper]"]
    expected: dict[str, object] = {}
    per_axis = {}
    for ax in ("x", "y"):
        name, freq, damping = config.axis(ax)
        where = f"config: shaper_{ax}"
        base = check_available(name, dialect, where)
        if base == "none":
            per_axis[ax] = (None, 0.0, damping)
            continue
        _, p = canonical(name)
        if p and base not in ("mzv", "ei"):
            raise RingtuneError(f"Klipper takes parameters only for mzv and ei, not {base!r}", where)
        _range(freq, 0, 1000, "frequency", f"config: freq_{ax}", "Klipper", lo_open=True)
        _range(damping, 0, _KLIPPER_MAX_DAMPING[base], f"damping ratio of {base}", f"config: damping_{ax}",
               "Klipper")
        per_axis[ax] = (name.strip().lower().replace(" ", ""), freq, damping)
    for ax in ("x", "y"):
        name, freq, _ = per_axis[ax]
        params.append(f"SHAPER_FREQ_{ax.upper()}={fmt(freq)}")
        expected[f"{ax}.freq"] = round(freq, 3)
    for ax in ("x", "y"):
        name, _, damping = per_axis[ax]
        if name:
            params.append(f"DAMPING_RATIO_{ax.upper()}={fmt(damping, 6)}")
            expected[f"{ax}.damping"] = round(damping, 6)
    for ax in ("x", "y"):
        name, _, _ = per_axis[ax]
        if name:
            params.append(f"SHAPER_TYPE_{ax.upper()}={name}")
            expected[f"{ax}.type"] = name
    for ax in ("x", "y"):
        name, freq, damping = per_axis[ax]
        if name:
            cfg += [f"shaper_type_{ax}: {name}", f"shaper_freq_{ax}: {fmt(freq)}",
                    f"damping_ratio_{ax}: {fmt(damping, 6)}"]
        else:
            cfg.append(f"shaper_freq_{ax}: 0")
    line = "SET_INPUT_SHAPER " + " ".join(params)
    return Export(dialect, [line], [], "\n".join(cfg) + "\n", "printer.cfg", ["SET_INPUT_SHAPER"],
                  expected, {k: 0 for k in expected},
                  ["SET_INPUT_SHAPER lasts until restart; SAVE_CONFIG would not keep damping_ratio, so "
                   "put the [input_shaper] section below in printer.cfg"])


# -- RepRapFirmware ---------------------------------------------------------------------------------

def _rrf(config: TuneConfig, dialect: str) -> Export:
    title = FIRMWARE_TITLE[dialect]
    sx, fx, dx = config.axis("x")
    sy, fy, dy = config.axis("y")
    bx = check_available(sx, dialect, "config: shaper_x")
    by = check_available(sy, dialect, "config: shaper_y")
    same = bx == by and (bx in ("none", "custom") or (math.isclose(fx, fy) and math.isclose(dx, dy)))
    if not same:
        raise RingtuneError(f"{title} applies one shaper to all axes, but X is {sx} {fx:g} Hz ζ={dx:g} "
                            f"and Y is {sy} {fy:g} Hz ζ={dy:g}; give both axes the same shaper", "config")
    for ax, name in (("x", sx), ("y", sy)):
        if canonical(name)[1] and bx != "custom":
            raise RingtuneError(f"{title} takes no shaper parameters", f"config: shaper_{ax}")
    expected: dict[str, object] = {"all.type": _rrf_name(bx)}
    if bx == "none":
        line = 'M593 P"none"'
    elif bx == "custom":
        line = 'M593 P"custom" ' + _rrf_custom(config, dialect)
    else:
        lo = 4.0 if dialect == "rrf" else RRF35_MIN_FREQ
        _range(fx, lo, 1000, "frequency F", "config: freq_x", title + (" (Duet 3)" if dialect != "rrf" else ""))
        _range(dx, 0, 0.99, "damping S", "config: damping_x", title)
        line = f'M593 P"{_rrf_name(bx)}" F{fmt(fx, 2)} S{fmt(dx, 3)}'
        expected.update({"all.freq": round(fx, 2), "all.damping": round(dx, 3)})
    if dialect != "rrf" and bx != "none":
        line += _rrf_l(config, dialect)
    return Export(dialect, [line], [], line + "\n", "config.g", ["M593"], expected,
                  {k: 0 for k in expected},
                  [f"{title} cannot save M593 (M500 does not store it): add the line to config.g"])


def _rrf_name(base: str) -> str:
    return {"2hump_ei": "ei2", "3hump_ei": "ei3"}.get(base, base)


def _rrf_l(config: TuneConfig, dialect: str) -> str:
    if dialect == "rrf35" and "reduction_limit" in config.extra:
        val = float(config.extra["reduction_limit"])
        _range(val, 0.01, 1.0, "reduction limit L", "config: reduction_limit", "RepRapFirmware 3.5")
        return f" L{fmt(val, 3)}"
    if dialect == "rrf34" and "min_accel" in config.extra:
        val = float(config.extra["min_accel"])
        _range(val, 1.0, 1e6, "minimum acceleration L", "config: min_accel", "RepRapFirmware 3.4")
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
        from ringtune.shaping.custom import rrf_custom

        semantics = "3.6" if config.firmware == "rrf" else "3.5"
        amps, times = rrf_custom(params.get("h"), params.get("t"), freq, damping,
                                 semantics, where=f"config: shaper_{axis} {name!r}")
        return [float(a) for a in amps], [float(t) for t in times]
    spec = config.extra.get("custom")
    if not isinstance(spec, dict) or "amplitudes" not in spec or "times" not in spec:
        raise RingtuneError('a custom shaper needs "custom": {"amplitudes": [...], "times": [...]} in '
                            "the config", where)
    try:
        amps = [float(a) for a in spec["amplitudes"]]
        times = [float(t) for t in spec["times"]]
    except (TypeError, ValueError):
        raise RingtuneError("amplitudes and times must be lists of numbers", where) from None
    if len(amps) != len(times):
        raise RingtuneError(f"{len(amps)} amplitudes but {len(times)} times", where)
    if not 2 <= len(amps) <= 5:
        raise RingtuneError(f"RepRapFirmware takes 2 to 5 impulses (at most 4 H values), not {len(amps)}",
                            where)
    if any(not math.isfinite(a) or a <= 0 for a in amps):
        raise RingtuneError("amplitudes must be positive", where + ".amplitudes")
    if not math.isclose(sum(amps), 1.0, abs_tol=1e-6):
        raise RingtuneError(f"amplitudes must sum to 1, not {sum(amps):g}", where + ".amplitudes")
    if times[0] != 0 or any(b <= a for a, b in zip(times, times[1:])):
        raise RingtuneError("times must start at 0 and strictly increase", where + ".times")
    if times[-1] > 0.5:
        raise RingtuneError(f"last impulse at {times[-1]:g} s: times are in seconds", where + ".times")
    return amps, times


def _rrf_custom(config: TuneConfig, dialect: str) -> str:
    amps, times = custom_impulses(config, "x")
    amps_y, times_y = custom_impulses(config, "y")
    if len(amps_y) != len(amps) or not all(math.isclose(a, b, abs_tol=1e-9) for a, b in
                                           zip(amps + times, amps_y + times_y)):
        raise RingtuneError(f"{FIRMWARE_TITLE[dialect]} applies one shaper to all axes, but the custom "
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
    lines, expected, where_line = [], {}, {}
    for ax in ("x", "y"):
        name, freq, damping = config.axis(ax)
        base = check_available(name, dialect, f"config: shaper_{ax}")
        if canonical(name)[1]:
            raise RingtuneError("Marlin's ZV takes no parameters", f"config: shaper_{ax}")
        if base == "none":
            lines.append(f"M593 {ax.upper()} F0")
            expected[f"{ax}.freq"] = 0.0
        else:
            _range(freq, 0, 1000, "frequency F", f"config: freq_{ax}", "Marlin", lo_open=True)
            _range(damping, 0, 1, "damping D", f"config: damping_{ax}", "Marlin")
            lines.append(f"M593 {ax.upper()} F{fmt(freq, 2)} D{fmt(damping, 3)}")
            expected.update({f"{ax}.freq": round(freq, 2), f"{ax}.damping": round(damping, 3)})
        for k in expected:
            where_line.setdefault(k, len(lines) - 1)
    return Export(dialect, lines, ["M500"], None, None, ["M593"], expected, where_line,
                  ["Marlin's minimum F depends on the board (the echo delay must fit its timer)"])


def _marlin_ftm(config: TuneConfig, dialect: str) -> Export:
    lines, expected, where_line = ["M493 S1"], {}, {}
    for ax in ("x", "y"):
        name, freq, damping = config.axis(ax)
        where = f"config: shaper_{ax}"
        base = check_available(name, dialect, where)
        _, params = canonical(name)
        line = f"M493 {ax.upper()} C{_FTM_MODE[base]}"
        expected[f"{ax}.mode"] = _FTM_MODE[base]
        if base != "none":
            _range(freq, 10, 500, "base frequency A", f"config: freq_{ax}", "Marlin FT_MOTION "
                   "(FTM_MIN_SHAPE_FREQ..FTM_FS/2)")
            _range(damping, 0.01, 1.0, "damping I", f"config: damping_{ax}", "Marlin FT_MOTION")
            line += f" A{fmt(freq, 2)} I{fmt(damping, 3)}"
            expected.update({f"{ax}.freq": round(freq, 2), f"{ax}.damping": round(damping, 3)})
            if params:
                if base != "ei" or set(params) - {"v_tol", "0"}:
                    raise RingtuneError("Marlin FT_MOTION takes only ei(v_tol=...)", where)
                vtol = next(iter(params.values()))
                _range(vtol, 0, 1, "vibration tolerance Q", where, "Marlin FT_MOTION")
                line += f" Q{fmt(vtol, 3)}"
                expected[f"{ax}.vtol"] = round(vtol, 3)
        lines.append(line)
        for k in expected:
            where_line.setdefault(k, len(lines) - 1)
    notes = ["M493 S1 turns FT_MOTION on"]
    if any(v > 0.25 for k, v in expected.items() if k.endswith(".damping")):
        notes.append("some FT_MOTION builds cap damping I at FTM_MAX_DAMPENING 0.25")
    return Export(dialect, lines, ["M500"], None, None, ["M493"], expected, where_line, notes)


# -- Prusa Buddy ------------------------------------------------------------------------------------

def _prusa(config: TuneConfig, dialect: str) -> Export:
    lines, expected, where_line = [], {}, {}
    for ax in ("x", "y"):
        name, freq, damping = config.axis(ax)
        where = f"config: shaper_{ax}"
        base = check_available(name, dialect, where)
        _, params = canonical(name)
        if base == "none":
            lines.append(f"M593 {ax.upper()} F0")
            expected[f"{ax}.type"] = "none"
        else:
            _range(freq, 10, 100, "frequency F", f"config: freq_{ax}", "Prusa-Firmware-Buddy (it clamps "
                   "to 10-100 Hz)")
            _range(damping, 0, 0.99, "damping D", f"config: damping_{ax}", "Prusa-Firmware-Buddy")
            line = f"M593 {ax.upper()} T{_PRUSA_TYPE[base]} F{fmt(freq, 2)} D{fmt(damping, 3)}"
            if params:
                if base != "ei" or set(params) - {"v_tol", "0"}:
                    raise RingtuneError("Prusa takes only ei(v_tol=...) (as R = 1/v_tol)", where)
                vtol = next(iter(params.values()))
                _range(vtol, 1e-3, 1, "vibration tolerance", where, "Prusa-Firmware-Buddy", lo_open=True)
                line += f" R{fmt(1 / vtol, 3)}"
            lines.append(line)
            expected.update({f"{ax}.type": base, f"{ax}.freq": round(freq, 2),
                             f"{ax}.damping": round(damping, 3)})
        for k in expected:
            where_line.setdefault(k, len(lines) - 1)
    return Export(dialect, lines, ["M593 W"], None, None, ["M593"], expected, where_line,
                  ["Prusa keeps M593 settings only after M593 W (written to EEPROM)"])
