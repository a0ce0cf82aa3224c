"""TuneConfig: the configuration ``tune`` and ``recommend`` write and ``simulate``, ``export`` and
``push`` read (JSON). Extra keys (provenance, metrics) are kept in ``extra`` and written back."""

from __future__ import annotations

import difflib
import json
import math
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any

from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.features import FEATURE_CLASSES
from ringtune.shaping.firmware import FIRMWARES
from ringtune.shaping.textfile import read_text_file

FREQ_LIMIT_METHODS = ("nophead", "sections", "marlin")

#: range of each scalar setting: key -> (lo, hi, unit, may be None)
_RANGES = {
    "freq_limit_hz": (0.0, 1000.0, "Hz", False),
    "min_speed_factor": (0.01, 1.0, "", False),
    "accel": (1.0, 1e6, "mm/s²", True),
    "max_accel_x": (1.0, 1e6, "mm/s²", True),
    "max_accel_y": (1.0, 1e6, "mm/s²", True),
    "corner": (0.0, 1000.0, "", True),
    "min_cruise_ratio": (0.0, 0.99, "", True),
}

#: per-class tables ({feature class: value}) and the range of their values
_PER_CLASS = {"feature_accel": (1.0, 1e6, "mm/s²", False), "feature_corner": _RANGES["corner"],
              "feature_min_cruise_ratio": _RANGES["min_cruise_ratio"]}

#: keys read from JSON as floats
_NUMBER_KEYS = ("freq_x", "freq_y", "damping_x", "damping_y", "freq_limit_hz", "min_speed_factor", "accel",
                "max_accel_x", "max_accel_y", "corner", "min_cruise_ratio")


@dataclass
class TuneConfig:
    """One tuning configuration.

    Attributes:
        firmware: target firmware, a key of :data:`ringtune.shaping.firmware.FIRMWARES` (read
            case-insensitively: ``"Klipper"`` is stored as ``"klipper"``).
        shaper_x, shaper_y: shaper names (``"none"`` turns shaping off on that axis).
        freq_x, freq_y: shaper frequencies, Hz.
        damping_x, damping_y: shaper damping ratios (dimensionless).
        freq_limit_hz: infill direction-change frequency limit, Hz (0 = off).
        min_speed_factor: lowest fraction of the commanded speed the limit may slow to.
        freq_limit_method: ``nophead`` (whole path), ``sections`` (only the fast part), ``marlin``.
        accel: printing acceleration, mm/s² (None = the printer's own).
        max_accel_x, max_accel_y: the per-axis acceleration caps this configuration runs with,
            mm/s² (Marlin/RRF ``M201 X Y``, Kalico ``max_x_accel``/``max_y_accel``; None = the
            printer's own, unchanged). ``export`` and ``push`` set and read them back before the
            acceleration; written to JSON only when set.
        feature_accel: acceleration per feature class of the job, mm/s² (class of
            :data:`ringtune.shaping.features.FEATURE_CLASSES` -> value; a class absent takes
            ``accel``); planned move by move (:mod:`ringtune.shaping.feature_settings`) and written
            into the job at each feature change (:mod:`ringtune.shaping.rewrite`). Empty = one
            acceleration for the whole job.
        corner: the firmware's corner rule value for the whole job, in the printer's own rule:
            Klipper ``square_corner_velocity`` mm/s, Marlin junction deviation mm (``M205 J``) or
            classic jerk mm/s (``M205 X Y``), RepRapFirmware ``M566`` jerk mm/s (None = the
            printer's / the job's own).
        min_cruise_ratio: Klipper's ``minimum_cruise_ratio`` in [0, 1) (None = the printer's).
        feature_corner, feature_min_cruise_ratio: the corner rule value (unit as ``corner``) and
            Klipper's minimum_cruise_ratio per feature class (class -> value; a class absent takes
            ``corner`` / ``min_cruise_ratio``, or the printer's own); planned and written into the
            job like ``feature_accel``. Empty = one value for the whole job.
        y_schedule: a bed slinger's Y shaper frequency by printed height, ``[{"z_mm": mm,
            "freq_y": Hz, "accel": mm/s², "mass_g": g}, ...]`` in rising ``z_mm`` (``accel`` and
            ``mass_g``, the mass on the bed it was chosen for, optional): from the layer at ``z_mm``
            on, Y runs at ``freq_y`` (the print's mass lowers the bed's modes); None = one frequency
            for the whole job. Written to JSON only when set.
        extra: any other keys (provenance, metrics), carried through unchanged.
    """

    firmware: str = "klipper"
    shaper_x: str = "mzv"
    shaper_y: str = "mzv"
    freq_x: float = 40.0
    freq_y: float = 40.0
    damping_x: float = 0.1
    damping_y: float = 0.1
    freq_limit_hz: float = 0.0
    min_speed_factor: float = 0.3
    freq_limit_method: str = "sections"
    accel: float | None = None
    max_accel_x: float | None = None
    max_accel_y: float | None = None
    feature_accel: dict[str, float] = field(default_factory=dict)
    corner: float | None = None
    min_cruise_ratio: float | None = None
    feature_corner: dict[str, float] = field(default_factory=dict)
    feature_min_cruise_ratio: dict[str, float] = field(default_factory=dict)
    y_schedule: list[dict[str, float]] | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.validate()

    @property
    def flavor(self) -> str:
        """Shaper formula flavour of the target firmware (see ``ringtune.shaping.shapers``)."""
        return FIRMWARES[self.firmware].flavor

    def axis(self, axis: str) -> tuple[str, float, float]:
        """(shaper name, frequency Hz, damping ratio) for axis ``"x"`` or ``"y"``."""
        return getattr(self, f"shaper_{axis}"), getattr(self, f"freq_{axis}"), getattr(self, f"damping_{axis}")

    @property
    def daa_freq(self) -> float | None:
        """Ringing frequency (Hz) of RepRapFirmware ≤ 3.3's Dynamic Acceleration Adjustment when
        either axis's shaper is ``"daa"`` (any case, as RRF lower-cases ``M593 P``), else None.

        DAA is one setting for the whole machine (``M593 P"daa" F…``): it stretches every move's
        acceleration phases to whole ringing periods, whichever axes the move drives, so a
        ``"daa"`` on X or on Y means the same machine-wide DAA at that axis's frequency. DAA works in
        the planner; such a config is planned with it and not input-shaped (see
        :func:`ringtune.shaping.shapers.shapers_from_config`)."""
        axes = [ax for ax in ("x", "y") if _is_daa(getattr(self, f"shaper_{ax}"))]
        return float(getattr(self, f"freq_{axes[0]}")) if axes else None

    def validate(self, where: str = "config") -> None:
        firmware = self.firmware.strip().lower() if isinstance(self.firmware, str) else self.firmware
        if firmware not in FIRMWARES:
            raise RingtuneError(f"firmware must be one of {', '.join(FIRMWARES)}, not {self.firmware!r}",
                                f"{where}: firmware")
        self.firmware = firmware
        for ax in ("x", "y"):
            self._validate_axis(ax, where)
        if _is_daa(self.shaper_x) and _is_daa(self.shaper_y) and self.freq_x != self.freq_y:
            raise RingtuneError(f"DAA has one frequency for the whole machine (M593 F), but freq_x is "
                                f"{self.freq_x:g} Hz and freq_y {self.freq_y:g} Hz", f"{where}: freq_y")
        self._check_ranges(where, "freq_limit_hz", "min_speed_factor")
        if self.freq_limit_method not in FREQ_LIMIT_METHODS:
            raise RingtuneError(f"must be one of {', '.join(FREQ_LIMIT_METHODS)}",
                                f"{where}: freq_limit_method")
        self._check_ranges(where, "accel", "max_accel_x", "max_accel_y")
        if self.y_schedule is not None:
            self.y_schedule = _checked_schedule(self.y_schedule, f"{where}: y_schedule")
        self._validate_features(where)

    def _validate_axis(self, ax: str, where: str) -> None:
        name, freq, damping = self.axis(ax)
        if not isinstance(name, str) or not name:
            raise RingtuneError("shaper name must be a non-empty string", f"{where}: shaper_{ax}")
        _finite(freq, f"{where}: freq_{ax}", lo=0.0, hi=1000.0, unit="Hz")
        _finite(damping, f"{where}: damping_{ax}", lo=0.0, hi=0.99)
        if name != "none" and freq <= 0:
            raise RingtuneError(f"{freq:g} Hz is outside (0, 1000] Hz while shaper_{ax} is {name!r} "
                                f"(shaper_{ax} = \"none\" turns shaping off)", f"{where}: freq_{ax}")

    def _check_ranges(self, where: str, *keys: str) -> None:
        """Each of ``keys`` within its :data:`_RANGES` row (an optional key may be None)."""
        for key in keys:
            lo, hi, unit, optional = _RANGES[key]
            value = getattr(self, key)
            if not (optional and value is None):
                _finite(value, f"{where}: {key}", lo=lo, hi=hi, unit=unit)

    def _validate_features(self, where: str) -> None:
        for key, (lo, hi, unit, _opt) in _PER_CLASS.items():
            table = getattr(self, key)
            if not isinstance(table, dict):
                raise RingtuneError(f"must be an object {{feature class: {unit or 'value'}}}", f"{where}: {key}")
            for cls, value in table.items():
                if cls not in FEATURE_CLASSES:
                    raise RingtuneError(f"{cls!r} is not a feature class (one of {', '.join(FEATURE_CLASSES)})",
                                        f"{where}: {key}")
                _finite(value, f"{where}: {key}.{cls}", lo=lo, hi=hi, unit=unit)
        self._check_ranges(where, "corner", "min_cruise_ratio")

    def without_per_feature(self) -> "TuneConfig":
        """This configuration without what it sets per feature or as the corner rule (what a job's
        own commands, or a rewritten job's, set instead)."""
        return replace(self, feature_accel={}, feature_corner={}, feature_min_cruise_ratio={}, corner=None,
                       min_cruise_ratio=None)

    @property
    def per_feature(self) -> bool:
        """Whether the configuration sets anything per feature or the corner rule (planned move by
        move, written into the job by the rewriter)."""
        return (any(getattr(self, k) for k in _PER_CLASS) or self.corner is not None
                or self.min_cruise_ratio is not None)

    # -- JSON ------------------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        extra = d.pop("extra")
        for key in ("max_accel_x", "max_accel_y", "corner", "min_cruise_ratio", "y_schedule"):   # only when
            if d[key] is None:                                                                # set: older files stay
                del d[key]
        for key in _PER_CLASS:
            if not d[key]:
                del d[key]
        d.update(extra)
        return d

    def key(self) -> str:
        """A string equal for equal configurations (their JSON, keys sorted): for caches."""
        return json.dumps(self.to_dict(), sort_keys=True)

    @property
    def axis_caps(self) -> tuple[float | None, float | None]:
        """(X, Y) per-axis acceleration caps this configuration runs with, mm/s² (None: the printer's)."""
        return self.max_accel_x, self.max_accel_y

    @classmethod
    def from_dict(cls, data: dict[str, Any], where: str = "config") -> "TuneConfig":
        if not isinstance(data, dict):
            raise RingtuneError("a TuneConfig must be a JSON object", where)
        known = {f.name for f in fields(cls)} - {"extra"}
        kwargs: dict[str, Any] = {}
        extra: dict[str, Any] = {}
        for k, v in data.items():
            (kwargs if k in known else extra)[k] = v
        for k in _NUMBER_KEYS:
            if kwargs.get(k) is not None:
                kwargs[k] = _number(kwargs[k], f"{where}: {k}")
        for key in _PER_CLASS:
            table = kwargs.get(key)
            if isinstance(table, dict):
                kwargs[key] = {str(c): _number(v, f"{where}: {key}.{c}") for c, v in table.items()}
            elif table is None:          # null, as absent: one value for the whole job
                kwargs[key] = {}
        try:
            cfg = cls(**kwargs, extra=extra)
        except RingtuneError as exc:
            raise exc.relocated("config", where) from None
        return cfg

    def likely_typos(self) -> list[str]:
        """Extra keys that look like a misspelt known key (``freqq_y`` for ``freq_y``): kept, as
        extra keys are, but the known key then silently takes its default; worth a warning."""
        known = [f.name for f in fields(self) if f.name != "extra"]
        out = []
        for k in self.extra:
            close = difflib.get_close_matches(str(k), known, n=1, cutoff=0.8)
            if close:
                out.append(f"unknown key {k!r} kept as an extra key; did you mean {close[0]!r}?")
        return out

    @classmethod
    def load(cls, path: str | Path) -> "TuneConfig":
        path = Path(path)
        text = read_text_file(path, "TuneConfig JSON")
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise RingtuneError(f"not valid JSON: {exc.msg}", f"{path}:{exc.lineno}") from None
        return cls.from_dict(data, where=str(path))

    def save(self, path: str | Path) -> None:
        Path(path).write_text(json.dumps(self.to_dict(), indent=2) + "\n")


def _number(value: Any, where: str) -> float:
    """``value`` as a float; a bool or a non-number is an error at ``where``."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise RingtuneError(f"must be a number, not {value!r}", where)
    return float(value)


def _finite(value: Any, where: str, lo: float, hi: float, unit: str = "") -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise RingtuneError(f"must be a finite number, not {value!r}", where)
    if not lo <= value <= hi:
        unit = unit and " " + unit
        raise RingtuneError(f"{value}{unit} is out of range [{lo:g}, {hi:g}]{unit}", where)


#: keys of one y_schedule entry: required, optional
_SCHEDULE_KEYS = (("z_mm", "freq_y"), ("accel", "mass_g"))


def _checked_schedule(entries: Any, where: str) -> list[dict[str, float]]:
    """``y_schedule`` as a list of {z_mm, freq_y[, accel, mass_g]} floats in strictly rising z_mm."""
    if not isinstance(entries, list):
        raise RingtuneError("must be a list of {z_mm, freq_y[, accel]} objects", where)
    out, last = [], -math.inf
    for i, e in enumerate(entries):
        w = f"{where}[{i}]"
        if not isinstance(e, dict):
            raise RingtuneError("must be an object {z_mm, freq_y[, accel]}", w)
        unknown = set(e) - set(_SCHEDULE_KEYS[0]) - set(_SCHEDULE_KEYS[1])
        if unknown:
            raise RingtuneError(f"unknown key {sorted(unknown)[0]!r} (keys: z_mm, freq_y, accel, mass_g)", w)
        for k in _SCHEDULE_KEYS[0]:
            if k not in e:
                raise RingtuneError(f"{k} is missing", w)
        _finite(e["z_mm"], f"{w}.z_mm", lo=0.0, hi=10000.0, unit="mm")
        _finite(e["freq_y"], f"{w}.freq_y", lo=1.0, hi=1000.0, unit="Hz")
        if e["z_mm"] <= last:
            raise RingtuneError(f"z_mm {e['z_mm']} does not rise above the previous {last}", f"{w}.z_mm")
        last = e["z_mm"]
        d = {"z_mm": float(e["z_mm"]), "freq_y": float(e["freq_y"])}
        if e.get("accel") is not None:
            _finite(e["accel"], f"{w}.accel", lo=1.0, hi=1e6, unit="mm/s²")
            d["accel"] = float(e["accel"])
        if e.get("mass_g") is not None:
            _finite(e["mass_g"], f"{w}.mass_g", lo=0.0, hi=1e6, unit="g")
            d["mass_g"] = float(e["mass_g"])
        out.append(d)
    return out


def _is_daa(name: Any) -> bool:
    return isinstance(name, str) and name.strip().lower() == "daa"
