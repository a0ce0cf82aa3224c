"""Checks of a TuneConfig against a firmware's record before anything is built or sent.

One axis is checked exactly as ``ringtune shaper`` checks a shaper (name and aliases, parameters:
unknown ones, Klipper's mzv ``n >= 3``, the ``v_tol`` range; the shaper's damping limit) plus the
firmware's record (:data:`ringtune.shaping.firmware.FIRMWARES`): the shapers it has, its ranges and
the precision values are sent with. A value that would round to another one is refused, never
changed (:class:`ringtune.shaping.firmware.Span`). Every refusal is one line naming the config key
and the allowed range.
"""

from __future__ import annotations

from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.firmware import Firmware, Span
from ringtune.shaping.shapers import REGISTRY, parse_name

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


def named_params(name: str, flavor: str) -> tuple[str, dict]:
    """(base, parameters by name) of a shaper string, positional parameters named in the order
    the flavour's formula takes them (Klipper: ``mzv(5,1.1)`` is ``mzv(n=5,t=1.1)``)."""
    base, params = parse_name(name, f"shaper {name!r}")
    pos = params.pop("_positional", None)
    if pos:
        params.update(zip(REGISTRY[flavor][base][1], pos))
    return base, params


def check_available(name: str, dialect: str, where: str) -> str:
    """Canonical name if ``dialect`` has the shaper, else a refusal naming the nearest it has."""
    fw = Firmware.named(dialect, "--firmware")
    base, _ = canonical(name)
    have = fw.shapers
    if base in have:
        return base
    listed = ", ".join(fw.native(h) for h in have if h != "none")
    if base == "custom":
        raise RingtuneError(f"{fw.title} has no custom shaper (only RepRapFirmware takes impulse lists); "
                            f"it has {listed}", where)
    if base not in _NEAREST:
        raise RingtuneError(f"unknown shaper {name!r}; {fw.title} has {listed}", where)
    nearest = next(n for n in _NEAREST[base] if n in have)
    raise RingtuneError(f"{fw.title} has no {base!r} shaper (it has {listed}); the nearest it has is "
                        f"{fw.native(nearest)!r}", where)


def check_value(value: float, span: Span, what: str, unit: str, where: str, title: str) -> float:
    """``value`` as the firmware gets it; a refusal naming the allowed range when it is outside
    ``span`` or would round to another value at the firmware's precision."""
    why = f"; {span.why}" if span.why else ""
    shown = f"{what} {value:g}{unit and ' ' + unit}"
    if not span.contains(value):
        raise RingtuneError(f"{shown} is outside {title}'s range {span.text(unit)}{why}", where)
    if span.changes(value):
        raise RingtuneError(f"{shown} would be sent as "
                            f"{fmt(value, span.decimals)} (values go to {title} with {span.decimals} decimals, the "
                            f"precision read back); give a "
                            f"value in {span.text(unit)} at that precision", where)
    return span.sent(value)


def check_axis(config: TuneConfig, fw: Firmware, ax: str) -> tuple[str, dict, float, float]:
    """One axis of ``config`` checked exactly as ``ringtune shaper`` checks a shaper (name,
    parameters, damping limit of the shaper) plus ``fw``'s ranges and precision.

    Returns (base name, parameters by name, frequency Hz, damping) as they will be sent; "none"
    for an axis without shaping. Nothing is sent to a printer until every axis passed."""
    name, freq, damping = config.axis(ax)
    base = check_available(name, fw.name, f"config: shaper_{ax}")
    if base == "none":
        return "none", {}, 0.0, damping
    if base == "custom":      # impulses in seconds: checked by custom_impulses
        return base, named_params(name, fw.flavor)[1], freq, damping
    freq = check_value(freq, fw.freq, "frequency", "Hz", f"config: freq_{ax}", fw.title)
    zmax = fw.max_damping(base)
    span = fw.damping if zmax >= fw.damping.hi else Span(fw.damping.lo, zmax, fw.damping.decimals)
    damping = check_value(damping, span, f"damping ratio of {base}", "", f"config: damping_{ax}", fw.title)
    fw.check_shaper(name, freq, damping, f"config: shaper_{ax}")   # parameters, as `ringtune shaper`
    _, params = named_params(name, fw.flavor)
    return base, params, freq, damping
