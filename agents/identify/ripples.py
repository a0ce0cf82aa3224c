"""A printer description from what a person
measured on a calibration print (``ringtune testprint ringing``), without an accelerometer.

One mode per measured axis: from the ripple spacing and wall speed (seed 000; damping from the
ratio of successive ripple heights, else a typical printer's damping, said), or from the ringing-tower band
with the least ringing. The rest of the description (masses, motors, limits, the modes of an axis
not measured) comes from ``--base``; ``[measurement]`` records the source (``"ripples"`` or
``"tower"``) and the numbers measured.

"""

from __future__ import annotations

import hashlib
import math
import tomllib
from dataclasses import replace
from pathlib import Path

from ringtune.envs.printer import load_printer
from ringtune.envs.printer_model import AxisModel, Mode
from ringtune.envs.ripples import (TYPICAL_DAMPING, TYPICAL_DAMPING_SOURCE, damping_from_ratio, mode_from_ripples,
                                   parse_axis_values, tower_frequency)
from ringtune.shaping.calibration_prints import read_band_table
from ringtune.shaping.errors import RingtuneError


def _default_damping(args, out) -> tuple[float, str]:
    """A typical printer's damping (:data:`TYPICAL_DAMPING`, with its source), never a firmware's
    shaper setting: the same whichever firmware is named."""
    return TYPICAL_DAMPING, f"a typical printer's: {TYPICAL_DAMPING_SOURCE}"


def identify_modes(args, out) -> tuple[dict, dict, list]:
    """({axis: (freq Hz, damping, comment)}, measurement dict, files) from the options."""
    if args.ripples and args.tower_band:
        raise RingtuneError("give --ripples or --tower-band, not both", "--tower-band")
    if getattr(args, "files", None):
        raise RingtuneError("accelerometer files and --ripples/--tower-band are two ways; use one",
                            args.files[0])
    if args.ripples:
        return _ripple_modes(args, out)
    if args.tower_band:
        return _tower_modes(args, out)
    raise RingtuneError("give accelerometer files, --ripples X=MM,Y=MM --speed V, or --tower-band X=N,Y=N "
                        "--tower FILE", "identify")


def _ripple_inputs(args) -> tuple[dict, dict]:
    """(spacing mm, decay ratio) per axis from --ripples, --decay, checked with --speed and --tower."""
    if args.tower:
        raise RingtuneError("--tower goes with --tower-band", "--tower")
    if args.speed is None:
        raise RingtuneError("the ripples need the wall speed they were printed at", "--speed")
    if not (math.isfinite(args.speed) and args.speed > 0):
        raise RingtuneError(f"must be a positive wall speed in mm/s, not {args.speed:g}", "--speed")
    spacing = parse_axis_values(args.ripples, "--ripples")
    decay = parse_axis_values(args.decay, "--decay") if args.decay else {}
    for ax in decay:
        if ax not in spacing:
            raise RingtuneError(f"a decay for {ax.upper()} without its ripple spacing", "--decay")
    return spacing, decay


def _ripple_damping(args, out, ax: str, decay: dict, meas: dict) -> tuple[float, str]:
    """(damping ratio, how it was found) of axis ``ax``: from its measured decay, else the typical."""
    if ax in decay:
        meas["ripples"][f"decay_{ax}"] = decay[ax]
        return (damping_from_ratio(decay[ax], f"--decay {ax.upper()}"),
                f"ripple height ratio {decay[ax]:g} (logarithmic decrement)")
    z, how = _default_damping(args, out)
    out.note(f"{ax.upper()}: damping {z:g} is {how}, not measured (--decay {ax.upper()}=R to measure it)")
    return z, how


def _ripple_modes(args, out) -> tuple[dict, dict, list]:
    """:func:`identify_modes` from ripple spacings on a printed wall (f = speed / spacing)."""
    spacing, decay = _ripple_inputs(args)
    modes: dict = {}
    meas = {"source": "ripples", "ripples": {"speed": args.speed}}
    for ax, s in spacing.items():
        z, how = _ripple_damping(args, out, ax, decay, meas)
        m = mode_from_ripples(ax, s, args.speed, z, how, f"--ripples {ax.upper()}")
        meas["ripples"][f"spacing_{ax}"] = s
        modes[ax] = (m.freq, m.damping,
                     f"ripples {s:g} mm apart at {args.speed:g} mm/s: ringing at {m.damped_freq:.2f} Hz, "
                     f"natural {m.freq:.2f} Hz; damping {m.damping:.3f} from {how}")
    return modes, meas, []


def _tower_file(args) -> tuple[Path, bytes]:
    """The tower's G-code (path, bytes), checked with the options that do not go with a tower."""
    if not args.tower:
        raise RingtuneError("the band numbers need the tower's G-code (its band table)", "--tower")
    if args.speed or args.decay:
        raise RingtuneError("--speed and --decay go with --ripples", "--speed" if args.speed else "--decay")
    path = Path(args.tower)
    if path.is_dir():
        raise RingtuneError("is a directory, not the tower's G-code", f"--tower {args.tower}")
    if not path.is_file():
        raise RingtuneError("no such file", f"--tower {args.tower}")
    return path, path.read_bytes()


def _tower_modes(args, out) -> tuple[dict, dict, list]:
    """:func:`identify_modes` from the band of a shaper-frequency tower where the ringing is least."""
    path, data = _tower_file(args)
    bands = read_band_table(data.decode("utf-8", "replace"), f"--tower {args.tower}")
    numbers = parse_axis_values(args.tower_band, "--tower-band")
    modes: dict = {}
    files: list = []
    meas = {"source": "tower", "tower": {}}
    for ax, n in numbers.items():
        if n != int(n):
            raise RingtuneError(f"band {ax.upper()}={n:g} must be a whole number", "--tower-band")
        f, half = tower_frequency(bands, int(n), ax)
        z, how = _default_damping(args, out)
        out.note(f"{ax.upper()}: damping {z:g} is {how}; a tower does not measure damping")
        modes[ax] = (f, z, f"tower band {int(n)} ({bands[int(n) - 1][0]:g}-{bands[int(n) - 1][1]:g} mm) "
                           f"at {f:g} Hz, ±{half:.3g} Hz (half the band step); damping {z:g} from {how}")
        meas["tower"][f"band_{ax}"] = int(n)
        meas["tower"][f"freq_{ax}"] = f
        files.append({"name": path.name, "sha256": hashlib.sha256(data).hexdigest(), "axis": ax})
    return modes, meas, files


def printer_text(modes: dict, meas: dict, files: list, name: str, base: str | None, out) -> str:
    """The printer TOML: ``base`` with the measured axes' modes replaced, plus ``[measurement]``."""
    p = load_printer(base)
    unmeasured = ' and the modes of ' + ', '.join(a.upper() for a in 'xy' if a not in modes) if len(modes) < 2 else ''
    out.note(f"masses, motors, limits{unmeasured}: from {p.name}"
             + (" (--base to use your printer's)" if base is None else f" ({base})"))
    default_masses = _default_masses(base, p)
    if default_masses:
        out.note(f"masses {default_masses} are defaults (not in {base or 'the embedded printer'}): the motor load "
                 "and the acceleration headroom come from them (weigh them: [x] mass / [y] mass)")
    axes = {ax: AxisModel(p.axis(ax).mass, [Mode(round(f, 3), round(z, 4))]) for ax, (f, z, _) in modes.items()}
    new = replace(p, name=name, description=f"identified from {meas['source']} on a print; base {p.name}", **axes)
    if files:
        meas["files"] = files
    new.measurement = meas                  # written back as [measurement] with the TOML
    text = new.to_toml()
    head = [f"# identified without an accelerometer ({meas['source']}); base: {p.name}"]
    head += [f"# {ax.upper()}: {c}" for ax, (_, _, c) in sorted(modes.items())]
    if default_masses:
        head.append(f"# still defaults: masses {default_masses} (the base gives none); [x] mass / [y] mass "
                    "replace them")
    return "\n".join(head) + "\n" + text


def _default_masses(base: str | None, p) -> str:
    """"X 0.55 kg, Y 1.1 kg" for the axes whose mass the base description does not give (the
    loader's defaults), "" when it gives both."""
    if base is None or not Path(base).is_file():  # the embedded printers name their masses (and the
        return ""                                 # note before this one says they are not the user's)
    try:
        raw = tomllib.loads(Path(base).read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError):
        raw = {}
    missing = [ax for ax in "xy" if not isinstance(raw.get(ax), dict) or "mass" not in raw[ax]]
    return ", ".join(f"{ax.upper()} {p.axis(ax).mass:g} kg" for ax in missing)
