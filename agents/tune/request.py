"""What ``ringtune tune`` is asked (:class:`TuneRequest`, as the command line gives it) and its
options checked against their ranges, in tables: a value out of range is refused in one line naming
the option (:func:`check_request`)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ringtune.agents.tune import pareto
from ringtune.envs.variants import DEFAULT_FREQ_MARGIN
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.wall_gap import show_through_bound


@dataclass(frozen=True)
class TuneRequest:
    """What ``tune`` is asked, as the command line gives it (percentages in %, lengths in mm;
    None: the default)."""

    printer: str | None = None
    gcode: str | None = None
    firmware: str | None = None          # None: the printer description's [current] firmware, else klipper
    trials: int = 200
    storage: str | None = None
    study: str = "ringtune"
    workers: int = 1
    seed: int = 0
    out: str = "ringtune-out"
    pick: str | None = None
    weight: float | None = None          # s per mm
    quality: str = "ripple"
    max_show_through: float | None = None
    max_path_error: float | None = None
    motor_reserve: float | None = None   # %
    freq_margin: float | None = None     # %
    shaping_min_freq: float | None = None   # Hz
    accel_range: str | None = None       # "LO,HI", mm/s²
    job_accel: str = "respect"
    per_feature: str = "auto"
    backend: str = "mujoco"
    evaluator: str | None = None
    no_baselines: bool = False
    no_refine: bool = False              # the study's choice as it left it: no ladder, stop or walk
    command: str = "ringtune tune"       # the command line that reproduces the run


@dataclass(frozen=True)
class Limits:
    """How the choice is made and the judgement's bounds: path error and show-through in mm, the
    frequency margin and motor reserve as fractions, the acceleration range in mm/s² (None: from
    the motors)."""

    how: str
    max_pe: float
    margin: float
    reserve: float
    max_st: float
    st_source: str             # where the show-through bound comes from, in words
    accel_range: tuple[float, float] | None


#: the run's size: (field, flag, default, scale of a given value, test, message); a value failing
#: its test is refused
_RUN_CHECKS = (
    ("trials", "--trials", None, 1, lambda v: v >= 1, "must be ≥ 1"),
    ("workers", "--workers", None, 1, lambda v: v >= 1, "must be ≥ 1"),
    ("weight", "--weight", None, 1, lambda v: v is None or v >= 0, "must be ≥ 0 (seconds per mm)"),
)

#: the judgement's bounds, as :data:`_RUN_CHECKS`; the show-through bound not given is the job's
#: own (:func:`ringtune.shaping.wall_gap.show_through_bound`)
_BOUNDS = (
    ("max_path_error", "--max-path-error", pareto.DEFAULT_MAX_PATH_ERROR_MM, 1.0, lambda v: v >= 0,
     "must be ≥ 0 (mm; 0 = no bound)"),
    ("freq_margin", "--freq-margin", DEFAULT_FREQ_MARGIN, 0.01, lambda v: 0 <= v < 0.5,
     "must be in [0, 50) per cent"),
    ("motor_reserve", "--motor-reserve", pareto.DEFAULT_MOTOR_RESERVE, 0.01, lambda v: 0 <= v < 1,
     "must be in [0, 100) per cent"),
    ("max_show_through", "--max-show-through", pareto.DEFAULT_MAX_SHOW_THROUGH_MM, 1.0, lambda v: v >= 0,
     "must be ≥ 0 (mm; 0 = no bound)"),
)


def check_request(req: TuneRequest) -> Limits:
    """The request's bounds and pick, refused in one line naming the option when out of range."""
    _checked(req, _RUN_CHECKS)
    how = req.pick or ("weight" if req.weight is not None else "fastest-at-baseline-quality")
    if how == "weight" and req.weight is None:
        raise RingtuneError("--pick weight needs --weight W (seconds per mm)", "--pick")
    bounds = _checked(req, _BOUNDS)
    max_st, st_source = show_through_bound(req.gcode, req.max_show_through, pareto.DEFAULT_MAX_SHOW_THROUGH_MM)
    accel_range = _accel_range(req.accel_range)
    if req.gcode and not Path(req.gcode).is_file():
        raise RingtuneError("no such G-code file", f"--gcode {req.gcode}")
    return Limits(how, bounds["max_path_error"], bounds["freq_margin"], bounds["motor_reserve"], max_st, st_source,
                   accel_range)


def _checked(req: TuneRequest, rows) -> dict:
    """{field: value} of ``rows`` (:data:`_RUN_CHECKS`, :data:`_BOUNDS`): the default where not
    given, else the given value scaled; refused in one line naming the flag when its test fails."""
    values = {}
    for name, flag, default, scale, ok, message in rows:
        given = getattr(req, name)
        values[name] = default if given is None else given * scale
        if not ok(values[name]):
            raise RingtuneError(message, flag)
    return values


def _accel_range(text: str | None) -> tuple[float, float] | None:
    if text is None:
        return None
    try:
        lo, hi = (float(v) for v in text.split(","))
    except ValueError:
        raise RingtuneError(f"must be LO,HI in mm/s² (e.g. 1000,8000), not {text!r}", "--accel-range") from None
    if not (0 < lo <= hi < 1e6):
        raise RingtuneError(f"must be 0 < LO ≤ HI (mm/s²), not {text!r}", "--accel-range")
    return (lo, hi)


def shaping_min_freq(value: float | None) -> float | None:
    if value is not None and not (0 < value <= 1000):
        raise RingtuneError(f"{value:g} Hz is not a frequency: give one in (0, 1000] Hz", "--shaping-min-freq")
    return value
