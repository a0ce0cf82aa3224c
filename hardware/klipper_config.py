"""The printer from a Klipper configuration: kinematics, limits, motors and the input shaper in use.

Two sources give the same facts:

- :func:`printer_facts_from_klipper` reads ``printer.cfg`` as Klipper does (includes, comments,
  SAVE_CONFIG block: :mod:`ringtune.hardware.klipper_cfgfile`);
- :func:`printer_facts_from_moonraker` asks a running printer, ``GET
  /printer/objects/query?configfile=config,settings``: ``settings`` holds the values as Klipper
  parsed them (its defaults included), ``config`` the raw text of what the files set, which tells a
  value the user wrote from one Klipper filled in.

What is taken (Klipper's option -> description key):

- ``[printer] kinematics`` -> ``kinematics`` (``cartesian``, ``corexy``, ``corexz``; Kalico's
  ``limited_*`` -> its base, with a note, ``[current] firmware = "kalico"`` and its caps below;
  anything else is refused);
- ``max_accel`` -> ``limits.accel``, ``max_velocity`` -> ``limits.velocity``,
  ``square_corner_velocity`` (default 5 mm/s), ``minimum_cruise_ratio`` -> ``limits.min_cruise_ratio``
  (default 0.5; from the old ``max_accel_to_decel``: ``1 − max_accel_to_decel / max_accel``, and
  that value itself as ``limits.accel_to_decel``: a Klipper from before 2024),
  ``max_z_velocity`` (and ``limited_*``'s ``max_x_velocity``/``max_y_velocity``) -> the per-axis
  speed caps ``limits.max_velocity`` (x, y, z, e; 0 = no cap) when they bind (under
  ``max_velocity``); ``max_z_accel`` and ``limited_*``'s ``max_x_accel``/``max_y_accel`` ->
  ``limits.max_accel`` whatever their value (a cap above today's max_accel still holds once the
  acceleration is raised; on ``limited_*`` an unset X/Y cap is Kalico's default, max_accel, as
  ``limited_*.py`` reads it), ``limited_corexy`` -> ``limits.axis_rule = "limited_corexy"`` (the
  belts' shares bind, not each axis's), ``scale_xy_accel`` -> ``limits.scale_xy_accel``;
- per motor (``stepper_x`` -> ``[x.motor]``, ``stepper_y`` -> ``[y.motor]``, one ``[motor]`` when
  both are the same): rotation distance, microsteps, run current and the named motor's constants,
  as :mod:`ringtune.hardware.klipper_motors` takes them;
- ``[firmware_retraction]`` -> ``limits.retract_length``, ``retract_speed``, ``unretract_extra_length``,
  ``unretract_speed`` (what a job's G10/G11 move; Klipper's defaults 0 mm, 20 mm/s, 0 mm, 10 mm/s
  where unset, each said; no section: ``retract_length = 0``, since G10/G11 then move nothing, said),
  and Kalico's ``z_hop_height`` -> ``retract_zlift``;
- ``[gcode_arcs] resolution`` -> ``limits.arc_resolution`` (Klipper's default 1 mm where unset, said;
  no section: G2/G3 move nothing there, said);
- ``[stepper_x]`` / ``[stepper_y]`` position_min (Klipper's default 0) and position_max ->
  ``limits.travel_x`` / ``travel_y`` ([min, max] mm: a move ending past them Klipper refuses);
- ``[input_shaper]`` -> ``[current]``: ``shaper_x``/``freq_x``/``damping_x`` (and y) as Klipper runs
  them (``shaper_type_x`` else ``shaper_type`` else Klipper's ``mzv``; damping 0.1 by default; a
  zero or missing frequency is ``"none"``), ``accel`` = ``max_accel``, ``firmware = "klipper"``.

Every default taken and every mapping made is a note; nothing is guessed silently.
"""

from __future__ import annotations

import re
from pathlib import Path

from ringtune.hardware.firmware_facts import KINEMATICS, FirmwareFacts, place_motors, to_number
from ringtune.hardware.klipper_cfgfile import read_klipper_cfg
from ringtune.hardware.klipper_motors import stepper_motor
from ringtune.hardware.klipper_source import KLIPPER_DEFAULTS, Source
from ringtune.hardware.moonraker import Moonraker
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.extruder_alone import filament_area, klipper_default_ratio

#: shapers Klipper 84104bb has (``klippy/extras/shaper_defs.py``), unparameterised names
KLIPPER_SHAPERS = ("zv", "mzv", "zvd", "ei", "2hump_ei", "3hump_ei")


def _kinematics(src: Source) -> str:
    kin = src.get("printer", "kinematics")
    if kin is None:
        raise RingtuneError("no kinematics: [printer] kinematics is missing", src.label)
    kin = str(kin).strip()
    if kin in KINEMATICS:
        return kin
    if kin.startswith("limited_") and kin[8:] in KINEMATICS:
        src.notes.append(f"{src.where('printer', 'kinematics')}: kinematics {kin} (Kalico's) is "
                         f"modelled as {kin[8:]}; its per-axis acceleration caps are applied as {kin} "
                         "applies them, and the firmware is Kalico")
        return kin[8:]
    raise RingtuneError(f"kinematics {kin!r} is not one the printer model has "
                        f"({', '.join(KINEMATICS)})", src.where("printer", "kinematics"))


def _limits(src: Source) -> dict:
    if src.name("printer") is None:
        raise RingtuneError("no [printer] section", src.label)
    accel = src.number("printer", "max_accel")
    velocity = src.number("printer", "max_velocity")
    for key, v in (("max_accel", accel), ("max_velocity", velocity)):
        if v is None:
            raise RingtuneError(f"[printer] {key} is missing (Klipper requires it)", src.label)
        if v <= 0:
            raise RingtuneError(f"must be > 0, not {v:g}", src.where("printer", key))
    limits = {"accel": accel, "velocity": velocity, "junction": "scv",
              "square_corner_velocity": src.number("printer", "square_corner_velocity",
                                                   KLIPPER_DEFAULTS["square_corner_velocity"], unit=" mm/s")}
    # only when written: an older Klipper's settings hold its default (max_accel / 2) unasked
    mad = src.number("printer", "max_accel_to_decel") if src.given_by_user("printer", "max_accel_to_decel") \
        else None
    if src.given_by_user("printer", "minimum_cruise_ratio") or mad is None:
        mcr = src.number("printer", "minimum_cruise_ratio", KLIPPER_DEFAULTS["minimum_cruise_ratio"])
        if mad is not None:
            src.notes.append(f"{src.where('printer', 'max_accel_to_decel')}: max_accel_to_decel is "
                             "ignored: minimum_cruise_ratio is set too")
    else:
        mcr = min(max(1.0 - mad / accel, 0.0), 0.99)
        limits["accel_to_decel"] = mad
        src.notes.append(f"{src.where('printer', 'max_accel_to_decel')}: a Klipper from before 2024 (no "
                         f"minimum_cruise_ratio): planned as it runs, {mad:g} mm/s² kept whatever ACCEL becomes "
                         f"([limits] accel_to_decel); its ratio at max_accel, 1 - {mad:g}/{accel:g} = {mcr:g}, is the "
                         "minimum_cruise_ratio tune starts from; `ringtune rewrite` writes ACCEL_TO_DECEL wherever a "
                         "configuration sets a ratio")
    if not 0 <= mcr < 1:
        raise RingtuneError(f"must be in [0, 1), not {mcr:g}", src.where("printer", "minimum_cruise_ratio"))
    limits["min_cruise_ratio"] = mcr
    _speed_caps(src, limits, velocity)
    _accel_caps(src, limits, accel)
    _extruder_caps(src, limits, accel, velocity)
    limits.update(_firmware_retraction(src))
    limits.update(_gcode_arcs(src))
    limits.update(_travel(src))
    return limits


def _travel(src: Source) -> dict:
    """``[stepper_x]`` / ``[stepper_y]`` position_min (Klipper's default 0) and position_max ->
    ``limits.travel_x`` / ``travel_y`` = [min, max] mm: where Klipper lets the toolhead go (a move
    ending past them is refused, "Move out of range"); none where position_max is not given."""
    out = {}
    for ax in "xy":
        sec = f"stepper_{ax}"
        top = src.number(sec, "position_max") if src.name(sec) is not None else None
        if top is None:
            continue
        low = src.get(sec, "position_min")
        low = 0.0 if low is None else to_number(low, src.where(sec, "position_min"))
        if not low < top:
            raise RingtuneError(f"position_max {top:g} must be above position_min {low:g}",
                                src.where(sec, "position_max"))
        out[f"travel_{ax}"] = [low, top]
    return out


def _gcode_arcs(src: Source) -> dict:
    """``[gcode_arcs] resolution`` -> ``limits.arc_resolution`` (mm; Klipper's default 1 mm where unset,
    said); no section: none, said (G2/G3 are then unknown commands to Klipper: nothing moves)."""
    if src.name("gcode_arcs") is None:
        src.notes.append("no [gcode_arcs]: a job's G2/G3 arcs are unknown commands to this printer and move nothing "
                         "(a job with arcs does not print as sliced; arcs are planned as Klipper's default 1 mm "
                         "segments)")
        return {}
    res = src.number("gcode_arcs", "resolution", KLIPPER_DEFAULTS["arc_resolution"], unit=" mm")
    if not res > 0:
        raise RingtuneError(f"must be > 0 mm, not {res:g}", src.where("gcode_arcs", "resolution"))
    return {"arc_resolution": res}


#: [firmware_retraction]'s options, as ``[limits]`` names them too: (Klipper's minimum, unit)
RETRACTION_OPTIONS = {"retract_length": (0.0, " mm"), "retract_speed": (1.0, " mm/s"),
                      "unretract_extra_length": (0.0, " mm"), "unretract_speed": (1.0, " mm/s")}


def _firmware_retraction(src: Source) -> dict:
    """``[firmware_retraction]`` -> what a job's G10/G11 move (Klipper's defaults where unset, each
    said); no section: a length of 0 (a G10 is then an unknown command to Klipper and moves nothing)."""
    if src.name("firmware_retraction") is None:
        src.notes.append("no [firmware_retraction]: a job's G10/G11 are unknown commands to this printer and move "
                         "nothing (limits.retract_length = 0)")
        return {"retract_length": 0.0}
    out = {k: src.number("firmware_retraction", k, KLIPPER_DEFAULTS[k], unit=unit)
           for k, (_low, unit) in RETRACTION_OPTIONS.items()}
    for k, v in out.items():
        if v < RETRACTION_OPTIONS[k][0]:
            low, unit = RETRACTION_OPTIONS[k]
            raise RingtuneError(f"must be ≥ {low:g}{unit} (Klipper's minimum), not {v:g}",
                                src.where("firmware_retraction", k))
    hop = src.number("firmware_retraction", "z_hop_height")     # Kalico's (limits.retract_zlift)
    return {**out, "retract_zlift": hop} if hop else out


def _speed_caps(src: Source, limits: dict, velocity: float) -> None:
    """Per-axis speed caps that bind (under max_velocity, which ringtune does not tune)."""
    caps = [0.0, 0.0, 0.0, 0.0]
    for i, ax in enumerate("xyz"):
        v = src.number("printer", f"max_{ax}_velocity")
        if v is None:
            continue
        if v < velocity:
            caps[i] = v
        else:
            src.notes.append(f"{src.where('printer', f'max_{ax}_velocity')}: max_{ax}_velocity {v:g} is not "
                             f"below max_velocity {velocity:g}, which limits every move: no speed cap of its "
                             f"own on {ax.upper()}")
    if any(caps):
        limits["max_velocity"] = caps


def _accel_caps(src: Source, limits: dict, accel: float) -> None:
    """Per-axis acceleration caps, kept whatever their value (module docstring)."""
    kin = str(src.get("printer", "kinematics")).strip()
    limited = kin.startswith("limited_")
    caps = [_accel_cap(src, ax, accel, kin if limited and ax != "z" else None) for ax in "xyz"] + [0.0]
    if any(caps):
        limits["max_accel"] = caps
    if kin == "limited_corexy":
        limits["axis_rule"] = "limited_corexy"
    scale = src.get("printer", "scale_xy_accel")
    if limited and str(scale).strip().lower() in ("true", "1", "yes"):       # str(None): "none"
        limits["scale_xy_accel"] = True


def _accel_cap(src: Source, ax: str, accel: float, limited: str | None) -> float:
    """max_<ax>_accel (0 = none); on a limited_* kinematics an unset X/Y cap is max_accel."""
    v = src.number("printer", f"max_{ax}_accel")
    if v is None and limited:
        src.notes.append(f"[printer] max_{ax}_accel not set: {limited}'s default, max_accel {accel:g} mm/s², "
                         f"caps {ax.upper()} even when the acceleration is raised at run time")
        return accel
    return 0.0 if v is None else v


def _extruder_caps(src: Source, limits: dict, accel: float, velocity: float) -> None:
    """``[extruder] max_extrude_only_velocity`` / ``max_extrude_only_accel`` -> ``limits.extrude_only_velocity``
    / ``extrude_only_accel``: what a move of the extruder alone (a retraction) runs at
    on Klipper; unset, Klipper's defaults (``kinematics/extruder.py``): max_velocity and max_accel ×
    4·nozzle_diameter² / the filament's cross-section, each said; and what its extruder refuses
    (``max_extrude_ratio``: max_extrude_cross_section, default 4·nozzle_diameter², over the
    filament's cross-section; ``nozzle_diameter``; ``extrude_only_distance``: max_extrude_only_distance,
    default 50 mm). No [extruder]: none."""
    sizes = _nozzle_and_filament(src)
    if sizes is None:
        return
    nozzle, filament = sizes
    ratio = klipper_default_ratio(nozzle, filament)
    for key, base in (("extrude_only_velocity", velocity), ("extrude_only_accel", accel)):
        cap = base * ratio
        limits[key] = _extruder_option(src, f"max_{key}", cap, f"{base:g} × {ratio:.4g} (4·nozzle_diameter² / the "
                                       f"filament's cross-section) = {cap:.4g}, what a retraction (the extruder "
                                       "alone) runs at")
    limits["nozzle_diameter"] = nozzle
    refused = "past which it refuses a move"
    limits["max_extrude_ratio"] = (_extruder_option(src, "max_extrude_cross_section", 4.0 * nozzle ** 2,
                                                    f"{4.0 * nozzle ** 2:.4g} mm², {refused}")
                                   / filament_area(filament))
    limits["extrude_only_distance"] = _extruder_option(src, "max_extrude_only_distance", 50.0, f"50 mm, {refused}")


def _extruder_option(src: Source, option: str, default: float, said: str) -> float:
    """The extruder's ``option`` as written, else Klipper's ``default``, said as ``said``."""
    if src.given_by_user("extruder", option):
        return src.number("extruder", option)
    src.notes.append(f"[extruder] {option} not set: Klipper's default, {said}")
    return default


def _nozzle_and_filament(src: Source) -> tuple[float, float] | None:
    """The [extruder]'s nozzle_diameter and filament_diameter (mm; None without an [extruder] giving
    both, which Klipper requires)."""
    if src.name("extruder") is None:
        return None
    nozzle, filament = src.number("extruder", "nozzle_diameter"), src.number("extruder", "filament_diameter")
    return (nozzle, filament) if nozzle and filament else None


def _shaping_unknown(src: Source) -> bool:
    """No [input_shaper] in what was read while parts could not be read: today's shaping is
    unknown (said in a note), not "none"."""
    if src.name("input_shaper") is not None or not src.unread:
        return False
    src.notes.append(f"no [input_shaper] in what could be read, and {', '.join(src.unread)} could not be "
                     "read: the input shaping the printer runs today is unknown ([current] not written; "
                     "give the missing files, or --moonraker to ask the running printer)")
    return True


def _current(src: Source, accel: float) -> dict | None:
    """``[current]``: the shaper the configuration sets; None (unknown) when it has no [input_shaper]
    but parts of it could not be read (one of them may hold it)."""
    if _shaping_unknown(src):
        return None
    kalico = str(src.get("printer", "kinematics")).strip().startswith("limited_")
    cur = {"source": src.label, "firmware": "kalico" if kalico else "klipper"}
    if src.name("input_shaper") is None:
        src.notes.append("no [input_shaper] section: the printer runs without input shaping today")
        cur.update(shaper_x="none", shaper_y="none", accel=accel)
        return cur
    for ax in "xy":
        freq = src.number("input_shaper", f"shaper_freq_{ax}")
        if not freq:
            src.notes.append(f"[input_shaper] shaper_freq_{ax} is {'0' if freq == 0 else 'not set'}: "
                             f"no shaping on {ax.upper()}")
            cur[f"shaper_{ax}"] = "none"
            continue
        if src.given_by_user("input_shaper", f"shaper_type_{ax}"):
            shaper = str(src.get("input_shaper", f"shaper_type_{ax}")).strip()
        elif src.given_by_user("input_shaper", "shaper_type"):
            shaper = str(src.get("input_shaper", "shaper_type")).strip()
        else:
            shaper = KLIPPER_DEFAULTS["shaper_type"]
            src.notes.append(f"[input_shaper] shaper_type_{ax} not set: Klipper's default {shaper}")
        if shaper.split("(")[0].strip().lower() not in KLIPPER_SHAPERS:
            src.notes.append(f"[input_shaper] {ax.upper()} shaper {shaper!r} is not one of Klipper's "
                             f"{', '.join(KLIPPER_SHAPERS)}; kept as written")
        damping = src.number("input_shaper", f"damping_ratio_{ax}", KLIPPER_DEFAULTS["damping_ratio"])
        cur.update({f"shaper_{ax}": shaper, f"freq_{ax}": freq, f"damping_{ax}": damping})
    cur["accel"] = accel
    return cur


def facts_from_sections(src: Source) -> FirmwareFacts:
    """The facts of a configuration already merged into sections (file or Moonraker)."""
    kin = _kinematics(src)
    limits = _limits(src)
    x = stepper_motor(src, "stepper_x")
    y = stepper_motor(src, "stepper_y")
    if kin == "corexz":
        zn = len(src.notes)
        z = stepper_motor(src, "stepper_z")
        del src.notes[zn:]
        if z != x:
            src.notes.append("corexz: motor B (stepper_z) differs from motor A (stepper_x); [x.motor] "
                             "describes stepper_x")
    named = {str(src.get(f"autotune_tmc {s}", "motor") or "").strip().lower()
             for s in ("stepper_x", "stepper_y")}
    for sec in src.sections:
        if sec.lower().startswith("motor_constants ") and sec.split(None, 1)[1].lower() not in named:
            src.notes.append(f"[{sec}] ({src.where(sec, 'resistance')}) is defined but neither stepper_x "
                             "nor stepper_y names it")
    description = {"kinematics": kin, "limits": limits}
    place_motors(description, x, y)
    current = _current(src, limits["accel"])
    if current is not None:
        description["current"] = current
    return FirmwareFacts(description, src.notes, src.label)


def printer_facts_from_klipper(path: str | Path) -> FirmwareFacts:
    """Facts from ``printer.cfg`` (and what it includes)."""
    cfg = read_klipper_cfg(path)
    notes = list(cfg.notes)
    used = re.compile(r"(printer|input_shaper|stepper_[xyz]|(tmc\w+|autotune_tmc)\s+stepper_[xyz]"
                      r"|motor_constants\s.*)", re.I)
    notes += [note for section, _, note in cfg.ignored_saved if used.fullmatch(section)]
    src = Source(cfg.sections, str(path), cfg.origin, None, notes, list(cfg.unread))
    return facts_from_sections(src)


def printer_facts_from_moonraker(url: str, api_key: str | None = None, timeout: float = 10.0) -> FirmwareFacts:
    """Facts from a running Klipper through Moonraker (``configfile`` object; see module docstring)."""
    mr = Moonraker(url, api_key=api_key, timeout=timeout)
    status = mr.query_objects({"configfile": ["config", "settings"]})
    cf = status.get("configfile") or {}
    raw, parsed = cf.get("config"), cf.get("settings")
    if not isinstance(raw, dict) or not isinstance(parsed, dict):
        raise RingtuneError("Moonraker's configfile object has no config/settings", mr.shown)
    sections = {name: dict(opts) for name, opts in raw.items() if isinstance(opts, dict)}
    given = {(name.lower(), opt.lower()) for name, opts in sections.items() for opt in opts}
    real = {name.lower(): name for name in sections}
    for name, opts in parsed.items():
        if isinstance(opts, dict):
            sections.setdefault(real.get(name.lower(), name), {}).update(opts)
    src = Source(sections, mr.shown, {}, given, [])
    return facts_from_sections(src)
