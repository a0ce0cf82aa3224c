"""Klipper's (and Kalico's) dialect: ``SET_INPUT_SHAPER`` and the ``[input_shaper]`` section.

Syntax and ranges: ``shared/reference/firmware.md`` §1.5. Kalico's smoothers take
``SMOOTHER_FREQ_<axis>`` and no damping ratio. Klipper keeps nothing set by ``SET_INPUT_SHAPER``
across a restart: the config part (``printer.cfg``) is what persists it.
"""

from __future__ import annotations

from ringtune.hardware.export import Export
from ringtune.hardware.firmware_check import check_axis, fmt
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.firmware import FIRMWARES
from ringtune.shaping.smoothers import is_smoother


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


def klipper_export(config: TuneConfig, dialect: str) -> Export:
    """``SET_INPUT_SHAPER`` with every parameter on one line, and the ``[input_shaper]`` section."""
    fw = FIRMWARES[dialect]
    per_axis = _klipper_axes(config, fw)
    params, expected = _klipper_params(per_axis, fw)
    cfg = ["[input_shaper]"]
    for ax in ("x", "y"):
        cfg += _klipper_config_lines(ax, *per_axis[ax], fw)
    line = "SET_INPUT_SHAPER " + " ".join(params)
    return Export(dialect, [line], [], "\n".join(cfg) + "\n", fw.config_file, ["SET_INPUT_SHAPER"],
                  expected, dict.fromkeys(expected, 0),
                  [f"{fw.title} keeps nothing set by SET_INPUT_SHAPER across a restart (SAVE_CONFIG does "
                   "not save it either; only printer.cfg does): put the [input_shaper] section (export "
                   "--part config) in printer.cfg"])
