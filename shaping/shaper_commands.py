"""Each firmware's shaper command applied to the shaping it leaves in force (Hz, damping ratio).

The settings are a dict of the shaping fields of a :class:`~ringtune.shaping.config.TuneConfig`
(:func:`settings_of`) plus what Klipper keeps of an axis that is off (``kept_x``, ``kept_y``: its
type); :func:`apply_command` changes them as the firmware does:

- Klipper ``SET_INPUT_SHAPER``: ``SHAPER_TYPE[_X|_Y]``, ``SHAPER_FREQ_X|Y`` (0 = off),
  ``DAMPING_RATIO_X|Y``; an axis turned off keeps its type, so a later ``SHAPER_FREQ_X=50`` alone
  turns it on again with it (Klipper's InputShaperParams); where shaping starts off, the type is
  Klipper's default, ``mzv`` (the command exists only with an ``[input_shaper]`` section, whose
  ``shaper_type`` defaults to it);
- Marlin ``M593 [X] [Y] F D`` (classic ZV; no axis letter: both; ``F0`` = off; a ``D`` outside 0–1
  or a negative ``F`` is skipped, the rest applies); Prusa ``M593 ... T F D`` (``T`` the type index; an axis turned
  off keeps nothing: the next change turns it on from Buddy's defaults, :func:`_prusa_m593`);
  RepRapFirmware ``M593 P"type" F S`` (one shaper for all axes, ``P"none"`` = off; without P the
  type stays, so a Marlin job's ``M593 F15`` sets its frequency,
  and an F outside its range — ``F0`` among them — fails the command, which changes nothing);
- Marlin FT_MOTION ``M493 [X] [Y] C A I`` (``C`` the mode, 0 = off; ``S0`` turns FT_MOTION off and
  ``S1`` on again with the shapers it had; A and I set only an axis that shapes).

What a command stores for an axis that is off (its damping, a type; not on Prusa, which keeps
nothing of it) applies once the axis is on again.
"""

from __future__ import annotations

import math

from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.firmware import FIRMWARES
from ringtune.shaping.gcode_commands import number_or_none

_FTM_MODES = ("none", "zv", "zvd", "zvdd", "zvddd", "ei", "2hump_ei", "3hump_ei", "mzv")
#: Prusa-Firmware-Buddy's M593 T (input_shaper::Type, first zv to last ei_3hump; another T is skipped)
_PRUSA_TYPES = ("zv", "zvd", "mzv", "ei", "2hump_ei", "3hump_ei")
_RRF_NAMES = {"ei2": "2hump_ei", "ei3": "3hump_ei"}
#: the settings a shaper command changes
SHAPING = ("shaper_x", "shaper_y", "freq_x", "freq_y", "damping_x", "damping_y")


def _indexed(table: tuple, v) -> str | None:
    """``table[int(v)]`` for a numeric ``v`` inside the table, else None."""
    i = number_or_none(v)
    return table[int(i)] if i is not None and 0 <= int(i) < len(table) else None


def _set_axis(cfg: dict, ax: str, shaper: str | None, freq: float | None, damping: float | None) -> None:
    """Apply one axis's change: frequency 0 or shaper ``none`` turns it off (a damping, or a
    frequency beside ``none``, is kept for when it is on again, as the firmwares keep them)."""
    if damping is not None:
        cfg[f"damping_{ax}"] = damping
    if freq is not None and freq > 0:
        cfg[f"freq_{ax}"] = freq
    if freq is not None and freq <= 0 or shaper == "none":
        cfg[f"shaper_{ax}"] = "none"
    elif shaper is not None:
        cfg[f"shaper_{ax}"] = shaper


#: Klipper's shaper_type where the [input_shaper] section names none
KLIPPER_DEFAULT_TYPE = "mzv"


def _klipper_freq(cfg: dict, ax: str, p: dict) -> float:
    """Hz an axis runs at after a SET_INPUT_SHAPER: as given, else as it was (0 where off)."""
    freq = number_or_none(p.get(f"SHAPER_FREQ_{ax.upper()}"))
    if freq is not None and freq < 0:
        raise RingtuneError(f"SHAPER_FREQ_{ax.upper()}={freq:g}: Klipper takes a frequency of at least 0 Hz, refuses "
                            "the line and stops the print there")
    if freq is not None:
        return freq
    return 0.0 if cfg[f"shaper_{ax}"] == "none" else cfg[f"freq_{ax}"]


def _klipper(cfg: dict, p: dict, _fw) -> None:
    """Klipper's SET_INPUT_SHAPER: each axis's type (``kept_<ax>``: the one it keeps while off),
    frequency (0: off) and damping, each as given or as it was."""
    for ax in "xy":
        kind = p.get("SHAPER_TYPE", p.get(f"SHAPER_TYPE_{ax.upper()}"))
        kept = str(kind).lower() if kind is not None else cfg[f"kept_{ax}"]
        if kept == "none":
            raise RingtuneError(f"Klipper has no shaper type {kind!r}: it answers \"Unsupported shaper type\" and "
                                "stops the print there (SHAPER_FREQ_X=0 / SHAPER_FREQ_Y=0 turn shaping off)")
        freq = _klipper_freq(cfg, ax, p)
        damping = number_or_none(p.get(f"DAMPING_RATIO_{ax.upper()}"))
        if damping is not None:
            cfg[f"damping_{ax}"] = damping
        cfg[f"kept_{ax}"] = kept
        if freq <= 0:
            cfg[f"shaper_{ax}"] = "none"
        else:
            cfg[f"shaper_{ax}"], cfg[f"freq_{ax}"] = kept, freq


def _axes(p: dict) -> str:
    named = "".join(ax for ax in "xy" if ax.upper() in p)
    return named or "xy"


#: the words of Marlin's M593 and the range outside which it skips each ("?Zeta (D) value out of
#: range", "?Frequency (F) must be greater than …"), setting the rest of the command (M593.cpp)
_MARLIN_M593_RANGES = {"D": (0.0, 1.0), "F": (0.0, math.inf)}


def _marlin_m593(cfg: dict, p: dict, _fw) -> None:
    """Marlin's M593 (classic ZV), without the words it skips (:data:`_MARLIN_M593_RANGES`)."""
    p = {k: v for k, v in p.items() if k not in _MARLIN_M593_RANGES or _within(v, *_MARLIN_M593_RANGES[k]) is not None}
    freq, damping = number_or_none(p.get("F")), number_or_none(p.get("D"))
    for ax in _axes(p):
        _set_axis(cfg, ax, "zv" if freq and cfg[f"shaper_{ax}"] == "none" else None, freq, damping)


#: Prusa-Firmware-Buddy's ``axis_x_default`` / ``axis_y_default`` (input_shaper_config.hpp: MZV at
#: 50.7 and 40.6 Hz, damping 0.1): what an axis that is off starts from when an M593 changes it
PRUSA_AXIS_DEFAULTS = {"x": ("mzv", 50.7, 0.1), "y": ("mzv", 40.6, 0.1)}


def _prusa_m593(cfg: dict, p: dict, fw) -> None:
    """Prusa-Firmware-Buddy's M593 (M593.cpp): a D outside 0–1, a negative F, a T outside its types or
    an R not above 0 is skipped; F0 turns the axis off; any other change of an axis (D, F, T, R) turns
    it on from where it is, or, where it is off, from Buddy's defaults (:data:`PRUSA_AXIS_DEFAULTS`:
    it keeps nothing of an axis it turned off), the frequency clamped to ``fw.freq`` (10–100 Hz)."""
    d, f = _within(p.get("D"), 0.0, 1.0), _within(p.get("F"), 0.0, math.inf)
    kind, r = _indexed(_PRUSA_TYPES, p.get("T")), _within(p.get("R"), 1e-300, math.inf)
    if all(v is None for v in (d, f, kind, r)):
        return
    for ax in _axes(p):
        if f == 0.0:
            cfg[f"shaper_{ax}"] = "none"
            continue
        base = PRUSA_AXIS_DEFAULTS[ax] if cfg[f"shaper_{ax}"] == "none" else axis_of(cfg, ax)
        cfg[f"shaper_{ax}"], cfg[f"damping_{ax}"] = _or(kind, base[0]), _or(d, base[2])
        cfg[f"freq_{ax}"] = min(max(_or(f, base[1]), fw.freq.lo), fw.freq.hi)


def _within(word, lo: float, hi: float) -> float | None:
    """A command word's number where it lies in [lo, hi], else None (absent, or one the firmware skips)."""
    v = number_or_none(word)
    return v if v is not None and lo <= v <= hi else None


def _or(value, default):
    """``value``, or ``default`` where it is None."""
    return default if value is None else value


def _m493(cfg: dict, p: dict, fw) -> None:
    """Marlin FT_MOTION's M493 (M493.cpp @00317b4): S0 / S1 turn fixed-time motion off and on again,
    its shapers kept (``ftm_on``, ``ftm``); a C outside its modes fails the rest of the command; A and
    I set an axis that shapes (after the command's C), within ``fw.freq`` and ``fw.damping``, else
    are skipped; the axes named, else X and Y."""
    if "S" in p:
        cfg["ftm_on"] = number_or_none(p["S"]) != 0          # Marlin's value_bool: S alone is on
    mode = _indexed(_FTM_MODES, p.get("C"))
    if mode is not None or number_or_none(p.get("C")) is None:
        a, i = _within(p.get("A"), fw.freq.lo, fw.freq.hi), _within(p.get("I"), fw.damping.lo, fw.damping.hi)
        for ax in _axes(p):
            was_mode, was_freq, was_zeta = cfg["ftm"][ax]
            now = _or(mode, was_mode)
            a_ax, i_ax = (a, i) if now != "none" else (None, None)
            cfg["ftm"] = {**cfg["ftm"], ax: (now, _or(a_ax, was_freq), _or(i_ax, was_zeta))}
    _ftm_in_force(cfg)


def _ftm_in_force(cfg: dict) -> None:
    """The shaping FT_MOTION's settings put in force: each axis's mode while it is on, else none."""
    for ax in "xy":
        mode, freq, zeta = cfg["ftm"][ax]
        if cfg["ftm_on"] and mode != "none":
            cfg[f"shaper_{ax}"], cfg[f"freq_{ax}"], cfg[f"damping_{ax}"] = mode, freq, zeta
        else:
            cfg[f"shaper_{ax}"] = "none"


def _rrf_m593(cfg: dict, p: dict, fw) -> None:
    """RepRapFirmware's M593, one shaper for all axes: P its type (none given, as in a Marlin job's
    ``M593 F30``: the type stays), F and S its frequency and damping; an F outside the firmware's
    range (``fw.freq``; F0, Marlin's "off", among them) fails the whole command, which then changes
    nothing (AxisShaper::Configure's limited F)."""
    freq, damping = number_or_none(p.get("F")), number_or_none(p.get("S"))
    if freq is not None and not fw.freq.contains(freq):
        return
    name = str(p.get("P", "")).strip().lower().replace("-", "").replace("_", "") or None
    for ax in "xy":
        _set_axis(cfg, ax, _RRF_NAMES.get(name, name), freq, damping)


#: (command, firmware family) -> its reader, ``reader(settings, params, firmware record)``: the
#: commands each family acts on (:data:`ringtune.shaping.job_shapers.ACTED_ON` is read from it)
READERS = {("SET_INPUT_SHAPER", "klipper"): _klipper, ("M593", "marlin"): _marlin_m593,
           ("M593", "prusa"): _prusa_m593, ("M593", "rrf"): _rrf_m593, ("M493", "marlin-ftm"): _m493}


def settings_of(config: TuneConfig) -> dict:
    """The shaping fields of ``config`` as a command changes them, with the type each axis keeps
    while off (``kept_x``, ``kept_y``: its own, or Klipper's default where it is off) and FT_MOTION's
    state (``ftm_on``; ``ftm``: {axis: (mode, Hz, zeta)} kept while it is off)."""
    d = {k: getattr(config, k) for k in SHAPING}
    for ax in "xy":
        d[f"kept_{ax}"] = KLIPPER_DEFAULT_TYPE if d[f"shaper_{ax}"] == "none" else d[f"shaper_{ax}"]
    d["ftm_on"], d["ftm"] = True, {ax: config.axis(ax) for ax in "xy"}
    return d


def shaping_of(d: dict) -> dict:
    """``d`` without what only a command reads (the kept types, FT_MOTION's state)."""
    return {k: d[k] for k in SHAPING}


def apply_command(command: str, cfg: dict, params: dict, firmware: str) -> None:
    """Apply one shaper command to ``cfg`` (:func:`settings_of`) as ``firmware`` reads it."""
    fw = FIRMWARES[firmware]
    READERS[(command, fw.family)](cfg, params, fw)


def axis_of(d: dict, ax: str) -> tuple:
    """What shapes axis ``ax`` in settings ``d``: its shaper, frequency and damping, or off."""
    return ("none",) if d[f"shaper_{ax}"] == "none" else (d[f"shaper_{ax}"], d[f"freq_{ax}"], d[f"damping_{ax}"])
