"""RepRapFirmware's dialect: ``M593 P"<type>" F<Hz> S<damping>`` and custom impulse shapers.

Syntax and ranges: ``shared/reference/firmware.md`` §3. RRF applies one shaper to every axis, so
X and Y must have the same one. RRF cannot save M593 (``M500`` does not store it): the line goes
to ``config.g``. Versions differ:

- ``rrf`` (3.6): custom ``H`` individual amplitudes, ``T`` cumulative delays (s);
- ``rrf35`` (3.5): custom ``H`` cumulative amplitudes, ``T`` durations; ``L`` = reduction limit
  (fraction, the config's ``extra["reduction_limit"]``);
- ``rrf34`` (3.4): as 3.5 but ``L`` = minimum acceleration (mm/s², ``extra["min_accel"]``).

A custom shaper is ``shaper_x = "custom"`` with ``extra["custom"] = {"amplitudes": [A1..An]
(sum 1), "times": [0, T2..Tn] (s)}`` (or ``custom(h=…,t=…)`` parameters in the config's
version's H/T meaning); it is converted to the H/T meaning of the chosen version.
"""

from __future__ import annotations

import math
from itertools import accumulate

from ringtune.hardware.export import Export
from ringtune.hardware.firmware_check import canonical, check_available, check_axis, check_value, fmt
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.custom import rrf_custom
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.firmware import FIRMWARES, Firmware, Span

#: version -> (the config's extra key, its range, what it is, unit, firmware) of M593's ``L``
_L_WORD = {"rrf35": ("reduction_limit", Span(0.01, 1.0, 3), "reduction limit L", "", "RepRapFirmware 3.5"),
           "rrf34": ("min_accel", Span(1.0, 1e6, 1), "minimum acceleration L", "mm/s²", "RepRapFirmware 3.4")}


def rrf_export(config: TuneConfig, dialect: str) -> Export:
    """The one ``M593`` line (also the ``config.g`` part) for both axes."""
    fw = FIRMWARES[dialect]
    base = _one_shaper(config, fw)
    expected: dict[str, object] = {"all.type": fw.native(base)}
    if base == "none":
        line = 'M593 P"none"'
    elif base == "custom":
        line = 'M593 P"custom" ' + _rrf_custom(config, dialect) + _rrf_l(config, dialect)
    else:
        _, fx, dx = config.axis("x")
        f, z = fw.freq.sent(fx), fw.damping.sent(dx)
        line = (f'M593 P"{fw.native(base)}" F{fmt(f, fw.freq.decimals)} S{fmt(z, fw.damping.decimals)}'
                + _rrf_l(config, dialect))
        expected.update({"all.freq": f, "all.damping": z})
    return Export(dialect, [line], [], line + "\n", fw.config_file, ["M593"], expected,
                  dict.fromkeys(expected, 0),
                  [f"{fw.title} cannot save M593 (M500 does not store it): add the config.g part "
                   "(export --part config) to config.g"])


def _one_shaper(config: TuneConfig, fw: Firmware) -> str:
    """The base name of the shaper X and Y share, each axis checked; refused when they differ."""
    sx, fx, dx = config.axis("x")
    sy, fy, dy = config.axis("y")
    bx = check_available(sx, fw.name, "config: shaper_x")
    by = check_available(sy, fw.name, "config: shaper_y")
    same_values = bx in ("none", "custom") or (math.isclose(fx, fy) and math.isclose(dx, dy))
    if bx != by or not same_values:
        raise RingtuneError(f"{fw.title} applies one shaper to all axes, but X is {sx} {fx:g} Hz ζ={dx:g} "
                            f"and Y is {sy} {fy:g} Hz ζ={dy:g}; give both axes the same shaper", "config")
    for ax in ("x", "y"):
        check_axis(config, fw, ax)
    return bx


def _rrf_l(config: TuneConfig, dialect: str) -> str:
    """`` L<value>`` of RRF 3.5/3.4 when the config gives it (:data:`_L_WORD`), else ``""``."""
    rule = _L_WORD.get(dialect)
    if rule is None or rule[0] not in config.extra:
        return ""
    key, span, what, unit, title = rule
    val = check_value(float(config.extra[key]), span, what, unit, f"config: {key}", title)
    return f" L{fmt(val, span.decimals)}"


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
    if not isinstance(spec, dict) or not {"amplitudes", "times"} <= spec.keys():
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
    """``H… T…`` of the custom shaper X and Y share, in ``dialect``'s meaning of H and T."""
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
        h = list(accumulate(amps))[:-1]
        t = [b - a for a, b in zip(times, times[1:])]
    return "H" + ":".join(fmt(v, 4) for v in h) + " T" + ":".join(fmt(v, 6) for v in t)
