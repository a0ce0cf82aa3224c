"""``ringtune simulate``'s configuration from its options: a TuneConfig JSON (--config), the
per-axis options (--shaper, --freq, --damping as ``V`` or ``X,Y``) and one option per other
TuneConfig key, each value checked in the option's own units and a bad one refused naming the
option; without any, what the printer runs now (its ``[current]`` section), else no shaping.
"""

from __future__ import annotations

from ringtune.agents.cli.common import load_config
from ringtune.agents.cli.options import Value
from ringtune.agents.tune.baselines import current_config
from ringtune.agents.tune.pareto import DEFAULT_MAX_PATH_ERROR_MM, DEFAULT_MOTOR_RESERVE
from ringtune.envs.variants import DEFAULT_FREQ_MARGIN
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.firmware import FIRMWARES
from ringtune.shaping.shapers import default_damping, shapers_from_config

#: option -> (the range its values must lie in, the refusal of a value outside it). The options'
#: values are checked in their own units, named by option (TuneConfig's own check would name its
#: keys: ``options: freq_x: -40.0 is out of range``).
_RANGES = {
    "--max-accel": (Value("an acceleration cap", "mm/s²", 1.0, 1e6, low_closed=True),
                    "{:g} is not an acceleration cap: give mm/s² > 0"),
    "--min-speed-factor": (Value("a speed factor", "", 0.01, 1.0, low_closed=True),
                           "{:g} is not a speed factor: give one in [0.01, 1]"),
    "--freq": (Value("a shaper frequency", "Hz", 0.0, 1000.0, low_closed=True),
               "{:g} Hz is not a shaper frequency: give one in (0, 1000] Hz"),
    "--damping": (Value("a damping ratio", "", 0.0, 0.99, low_closed=True),
                  "{:g} is not a damping ratio: give one in [0, 0.99] (e.g. 0.1)"),
    "--freq-limit": (Value("a frequency limit", "Hz", 0.0, 1000.0, low_closed=True),
                     "{:g} Hz is not a frequency limit: give one in [0, 1000] Hz (0 = off)"),
    "--accel": (Value("a printing acceleration", "mm/s²", 0.0, 1e6),
                "{:g} mm/s² is not a printing acceleration: give one in (0, 1e6] mm/s²"),
}

#: TuneConfig key -> the option that sets it
_KEY_FLAG = {"freq_x": "--freq", "freq_y": "--freq", "damping_x": "--damping", "damping_y": "--damping",
             "shaper_x": "--shaper", "shaper_y": "--shaper", "firmware": "--firmware",
             "freq_limit_hz": "--freq-limit", "accel": "--accel", "max_accel_x": "--max-accel",
             "max_accel_y": "--max-accel", "freq_limit_method": "--freq-limit-method",
             "min_speed_factor": "--min-speed-factor", "feature_accel": "--feature-accel", "corner": "--corner",
             "min_cruise_ratio": "--min-cruise-ratio"}


def build_config(args, out=None, printer=None):
    """The TuneConfig from --config and/or the individual options (options override the file);
    without either, what ``printer`` runs now (``[current]``), else no shaping."""
    cfg, notes = _start(args, out, printer)     # the notes are said once the options are known to be good
    shaper = _pair(args.shaper, "--shaper")
    freq = _pair(args.freq, "--freq", float)
    damping = _pair(args.damping, "--damping", float)
    if shaper and not args.config:     # shapers given alone: they need a frequency, and take a damping
        if not freq and any(s != "none" for s in shaper):
            raise RingtuneError("a shaper needs a frequency", "--freq")
        if not damping:
            _default_damping(cfg)
    for key, pair in (("shaper", shaper), ("freq", freq), ("damping", damping)):
        if pair:
            cfg[f"{key}_x"], cfg[f"{key}_y"] = pair
    _other_keys(cfg, args)
    _check_ranges({"--freq": freq, "--damping": damping, "--freq-limit": (args.freq_limit,),
                   "--accel": (args.accel,)})
    config = _named_config(cfg, args, shaper)
    if out is not None:
        out.note(*notes)
    return config


def freq_margin(args, config=None) -> float:
    """--freq-margin PCT as a fraction; default: the margin the configuration was tuned with
    (``freq_margin`` in a best.json from tune), else tune's default."""
    if args is not None and args.freq_margin is not None:
        if not 0 <= args.freq_margin < 50:
            raise RingtuneError(f"must be a percentage in [0, 50), not {args.freq_margin:g}", "--freq-margin")
        return args.freq_margin / 100.0
    return _recorded(config, "freq_margin", 0.5, DEFAULT_FREQ_MARGIN)


def motor_reserve(config=None) -> float:
    """The motor reserve (fraction) the baselines are judged with: the one the configuration was
    tuned with (``motor_reserve`` in a best.json from tune), else tune's default."""
    return _recorded(config, "motor_reserve", 1.0, DEFAULT_MOTOR_RESERVE)


def max_path_error(config=None) -> float:
    """The path-error bound (mm) the baselines are judged with: the one the configuration was tuned
    with (``max_path_error_mm`` in a best.json from tune), else tune's default."""
    return _recorded(config, "max_path_error_mm", float("inf"), DEFAULT_MAX_PATH_ERROR_MM)


def _recorded(config, key: str, below: float, default: float) -> float:
    """The number tune recorded as ``key`` in the configuration's extras (a best.json) where it lies
    in [0, ``below``), else ``default``."""
    value = (config.extra or {}).get(key) if config is not None else None
    return float(value) if type(value) in (int, float) and 0 <= value < below else default    # a number, not a bool


def _pair(text: str | None, option: str, read=str) -> tuple | None:
    """``V`` or ``X,Y`` -> (x, y), each read by ``read``; None when the option is not given."""
    if text is None:
        return None
    parts = [p.strip() for p in str(text).split(",")]
    if len(parts) == 1:
        parts = parts * 2
    if len(parts) != 2 or not all(parts):
        raise RingtuneError("give one value or two separated by a comma (X,Y)", option)
    try:
        return tuple(read(p) for p in parts)
    except ValueError:
        raise RingtuneError(f"not a number: {text!r}", option) from None


def _check_ranges(values: dict) -> None:
    """Refuse the first value out of its option's range (:data:`_RANGES`); None values are not given."""
    for option, given in values.items():
        in_range, refusal = _RANGES[option]
        bad = [v for v in given or () if v is not None and not in_range.holds(v)]
        if bad:
            raise RingtuneError(refusal.format(bad[0]), option)


def _start(args, out, printer) -> tuple[dict, list[str]]:
    """(config dict the options then override, notes): --config's, else (no shaper option) what the
    printer runs now, else no shaping; with --firmware's firmware."""
    notes: list[str] = []
    if args.config:
        cfg = load_config(args.config, out).to_dict()
    elif all(v is None for v in (args.shaper, args.freq, args.damping)):     # no shaper option
        cfg, notes = _base_config(args, printer)
    else:
        cfg = {"shaper_x": "none", "shaper_y": "none"}
    if args.firmware:
        cfg["firmware"] = args.firmware
    return cfg, notes


def _base_config(args, printer) -> tuple[dict, list[str]]:
    """What is simulated when neither --config nor --shaper/--freq/--damping says: what the printer
    runs now (its ``[current]`` section), else no shaping; and the notes that say so."""
    notes: list[str] = []
    if printer is not None and printer.current:
        cur = printer.current
        cfg, why = current_config(printer, args.firmware or str(cur.get("firmware") or "klipper"))
        if cfg is not None:
            notes.append(f"no --config: simulating what the printer runs now, from [current] "
                         f"({cur.get('source') or printer.name})")
            d = cfg.to_dict()
            d.pop("extra", None)
            d["job_accel"] = "respect"    # the printer runs the job's own acceleration commands
            return d, notes
        notes.append(why)
    notes.append("no --config or --shaper: simulating with input shaping off (give --config best.json or "
                 "--shaper S --freq F to simulate a configuration)")
    return {"shaper_x": "none", "shaper_y": "none"}, notes


def _default_damping(cfg: dict) -> None:
    """Shapers given without --damping take their firmware's default damping ratio."""
    record = FIRMWARES.get(str(cfg.get("firmware", "klipper")).lower())
    if record is not None:  # an unknown firmware is reported by TuneConfig below
        cfg["damping_x"] = cfg["damping_y"] = default_damping(record.flavor)


def _other_keys(cfg: dict, args) -> None:
    """The TuneConfig keys without a per-axis option of their own: frequency limit, acceleration,
    caps, limit method and speed factor, the job-acceleration mode (an extra key of tune's best.json)."""
    caps = _pair(args.max_accel, "--max-accel", float) or (None, None)
    _check_ranges({"--max-accel": caps, "--min-speed-factor": (args.min_speed_factor,)})
    given = {"freq_limit_hz": args.freq_limit, "accel": args.accel, "max_accel_x": caps[0],
             "max_accel_y": caps[1], "freq_limit_method": args.freq_limit_method,
             "min_speed_factor": args.min_speed_factor, "job_accel": args.job_accel,
             "feature_accel": _feature_accel(args.feature_accel), "corner": args.corner,
             "min_cruise_ratio": args.min_cruise_ratio}
    cfg.update({k: v for k, v in given.items() if v is not None})


def _feature_accel(text: str | None) -> dict | None:
    """``CLASS=A,CLASS=A`` -> {class: mm/s²} (the classes are checked by TuneConfig)."""
    if text is None:
        return None
    out = {}
    for part in text.split(","):
        name, eq, value = part.partition("=")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            eq = ""
        if not eq:
            raise RingtuneError(f"{part!r} is not CLASS=mm/s² (e.g. infill=10000)", "--feature-accel")
    return out


def _named_config(cfg: dict, args, shaper) -> TuneConfig:
    """The TuneConfig of ``cfg``; a bad value is refused naming the option that gave it (or the
    file), and shapers the firmware does not offer naming --shaper (or the file)."""
    where = args.config or "options"
    try:
        config = TuneConfig.from_dict(cfg, where)
    except RingtuneError as exc:   # a value an option gave: name the option, not the config key
        flag = _KEY_FLAG.get((exc.where or "").rpartition(": ")[2].partition(".")[0], "")
        if getattr(args, flag[2:].replace("-", "_"), None) is not None:     # the option was given
            raise RingtuneError(exc.bare, flag) from None
        raise
    try:  # the firmware must offer the shapers: say which option (or file) asked for them
        shapers_from_config(config)
    except RingtuneError as exc:
        if shaper:
            raise RingtuneError(exc.bare, "--shaper") from None
        raise exc.relocated("config", where) from None
    return config
