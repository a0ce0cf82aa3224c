"""Speeds to avoid: at which wall speeds the printer model rings most, for a job's typical walls.

A wall's ripple comes from the corner before it: the move into the corner brakes across the wall's
direction, and that braking rings the modes of the axis across the wall. How much depends on the
speed: the braking lasts ``(v − v_corner)/a``, and a ramp of about half a period of a mode
(``v ≈ v_corner + a/(2f)``, then 3/2, 5/2 … periods, each weaker with damping) leaves the most
ringing, a ramp of whole periods the least. So the ripple against speed has peaks, and their
places depend on the acceleration, the corner rule, the modes and, on short walls, the wall's length.

:func:`speed_advice` measures this on the printer model rather than by formula: for each wall
direction (along X and along Y; on a CoreXY also along the two diagonals, each driven by one belt)
it builds the job's typical wall — its length-weighted median length, entered through its median
corner angle — at each speed of a grid, and runs it through the same pipeline ``simulate`` uses
(planner with the printer's limits and the configuration's acceleration, the configuration's
shapers, the exact linear model: ``evaluate(..., backend="lti")``), reading the ripple as
``ripple_mm`` (peak-to-peak of the nozzle's deviation across the wall, what calipers see). A
*band* is a run of speeds whose
ripple is at least :data:`BAND_LEVEL` (1/√2, the half-power level) of that direction's worst.

OrcaSlicer's resonance avoidance takes one band for outer walls (keys ``resonance_avoidance``,
``min_resonance_avoidance_speed``, ``max_resonance_avoidance_speed``, mm/s): the band of the worst
ripple over all directions goes there; every band is also given as advice.

Units: mm, mm/s, mm/s², degrees.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ringtune.envs.evaluate import evaluate
from ringtune.envs.planned_job import resolve_job
from ringtune.envs.printer_model import Printer
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.features import feature_class

#: a band: speeds whose ripple is at least this fraction of the direction's worst (half power)
BAND_LEVEL = 1.0 / math.sqrt(2.0)
#: a direction change at least this large (degrees) ends a straight wall
CORNER_DEG = 30.0
#: without a job: a 40 mm square's walls
DEFAULT_WALL = (40.0, 90.0)
#: directions of the walls tried: name -> unit vector (CoreXY adds the belts' diagonals)
DIRECTIONS = {"x": (1.0, 0.0), "y": (0.0, 1.0)}
DIAGONALS = {"a": (math.sqrt(0.5), math.sqrt(0.5)), "b": (math.sqrt(0.5), -math.sqrt(0.5))}
DIRECTION_TEXT = {"x": "walls along X (ripple across them: Y's modes)",
                  "y": "walls along Y (ripple across them: X's modes)",
                  "a": "walls along (1,1) (motor A's belt alone)", "b": "walls along (1,-1) (motor B's belt alone)"}


@dataclass
class Band:
    """Speeds lo..hi (mm/s) where walls of ``direction`` ripple most; the worst at ``peak_speed``."""

    direction: str
    lo: float
    hi: float
    peak_speed: float
    peak_ripple: float          # mm, peak-to-peak across the wall

    def to_dict(self) -> dict:
        return {"direction": self.direction, "lo": self.lo, "hi": self.hi, "peak_speed": self.peak_speed,
                "peak_ripple_mm": self.peak_ripple}


@dataclass
class SpeedAdvice:
    """Ripple against speed per wall direction, the bands, and where they came from."""

    speeds: np.ndarray                       # mm/s
    ripple: dict[str, np.ndarray]            # direction -> mm per speed
    bands: list[Band]
    wall_length: float                       # mm
    corner_deg: float
    accel: float                             # mm/s²
    notes: list[str] = field(default_factory=list)

    @property
    def worst(self) -> Band | None:
        return max(self.bands, key=lambda b: b.peak_ripple, default=None)

    def orcaslicer(self) -> dict:
        """OrcaSlicer's resonance-avoidance keys for the worst band ({} without one)."""
        w = self.worst
        if w is None:
            return {}
        return {"resonance_avoidance": "1", "min_resonance_avoidance_speed": f"{w.lo:g}",
                "max_resonance_avoidance_speed": f"{w.hi:g}"}

    def to_dict(self) -> dict:
        return {"speeds_mm_s": self.speeds, "ripple_mm": self.ripple, "bands": [b.to_dict() for b in self.bands],
                "wall_length_mm": self.wall_length, "corner_deg": self.corner_deg, "accel": self.accel,
                "band_level": BAND_LEVEL, "orcaslicer": self.orcaslicer(), "notes": self.notes}


def _runs(job) -> list[tuple[float, float]]:
    """(length mm, corner angle before it, degrees) of every straight wall of the job's outer walls
    (:func:`ringtune.shaping.features.feature_class`; all extruding moves when the job labels
    none) that follows a corner: a wall runs on through
    direction changes under :data:`CORNER_DEG` and ends at a corner or where the walls stop."""
    ext = job.extruding
    named = np.array([feature_class(job.features[f]) == "outer_wall" for f in job.feature], dtype=bool)
    sel = ext & named if (ext & named).any() else ext
    d = job.delta[:, :2]
    length = np.hypot(d[:, 0], d[:, 1])
    idx = np.flatnonzero(sel & (length > 1e-9))
    if len(idx) < 2:
        return []
    u = d[idx] / length[idx, None]
    contiguous = np.diff(idx) == 1
    turn = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", u[:-1], u[1:]), -1.0, 1.0)))
    corner = contiguous & (turn >= CORNER_DEG)
    starts = np.r_[True, ~contiguous | corner]
    group_len = np.bincount(np.cumsum(starts) - 1, weights=length[idx])
    at_corner = np.r_[False, corner][starts]
    angle = np.r_[0.0, turn][starts]
    return [(float(group_len[g]), float(angle[g])) for g in np.flatnonzero(at_corner)]


def typical_wall(job) -> tuple[float, float, int]:
    """(length-weighted median wall length mm, median corner angle degrees, walls counted)."""
    walls = _runs(job)
    if not walls:
        return (*DEFAULT_WALL, 0)
    lengths = np.array([w[0] for w in walls])
    order = np.argsort(lengths)
    cum = np.cumsum(lengths[order])
    median_len = float(lengths[order][np.searchsorted(cum, 0.5 * cum[-1])])
    return median_len, float(np.median([w[1] for w in walls])), len(walls)


def wall_gcode(direction, length: float, corner_deg: float, speed: float) -> str:
    """G-code of one wall of ``length`` mm along ``direction``, entered by an equally long extruding
    move through a corner of ``corner_deg`` degrees, left by a travel, at ``speed`` mm/s. Only the
    wall is labelled an outer wall (the entry an inner one, nobody sees), so its ripple is the job's:
    the entry runs along another direction, whose ripple belongs to that direction's curve."""
    d = np.asarray(direction, float)
    th = math.radians(corner_deg)
    u = np.array([d[0] * math.cos(-th) - d[1] * math.sin(-th), d[0] * math.sin(-th) + d[1] * math.cos(-th)])
    p0 = np.array([150.0, 150.0]) - length * u
    p2 = np.array([150.0, 150.0]) + length * d
    p3 = p2 + length * d
    f = speed * 60.0
    return "\n".join(["G90", "M82", "G92 E0", f"G0 X{p0[0]:.4f} Y{p0[1]:.4f} F{f:.1f}", ";TYPE:Inner wall",
                      f"G1 X150 Y150 E1 F{f:.1f}", ";TYPE:Outer wall", f"G1 X{p2[0]:.4f} Y{p2[1]:.4f} E2",
                      f"G0 X{p3[0]:.4f} Y{p3[1]:.4f}"])


def ripple_against_speed(printer: Printer, config: TuneConfig, direction, length: float, corner_deg: float,
                         speeds: np.ndarray) -> np.ndarray:
    """Ripple (mm, ``ripple_mm``: peak-to-peak across the wall) of the typical wall along
    ``direction`` at each speed (mm/s)."""
    return np.array([evaluate(config, printer, wall_gcode(direction, length, corner_deg, v), backend="lti").ripple_mm
                     for v in speeds])


def find_bands(direction: str, speeds: np.ndarray, ripple: np.ndarray, level: float = BAND_LEVEL) -> list[Band]:
    """Runs of speeds where ``ripple`` ≥ ``level`` × its maximum, widened half a step each side."""
    top = float(ripple.max()) if len(ripple) else 0.0
    if top <= 0:
        return []
    step = float(np.median(np.diff(speeds))) if len(speeds) > 1 else 0.0
    edges = np.flatnonzero(np.diff(np.r_[0, (ripple >= level * top).astype(int), 0]))   # run starts, ends + 1
    bands = []
    for i, end in zip(edges[::2], edges[1::2]):
        k = i + int(np.argmax(ripple[i:end]))
        bands.append(Band(direction, max(float(speeds[i]) - step / 2, 0.0), float(speeds[end - 1]) + step / 2,
                          float(speeds[k]), float(ripple[k])))
    return bands


def _wall_of(job) -> tuple[float, float, list[str]]:
    """The typical wall of ``job`` (None: a 40 mm square's) and the note saying where it came from."""
    if job is None:
        return (*DEFAULT_WALL, [f"no job given: walls of {DEFAULT_WALL[0]:g} mm after {DEFAULT_WALL[1]:g}° corners "
                                "(a 40 mm square)"])
    length, corner, n = typical_wall(resolve_job(job)[1])
    if not n:
        return (*DEFAULT_WALL, ["the job has no wall after a corner: a 40 mm square's walls"])
    return length, corner, [f"the job's typical wall: {length:.1f} mm (length-weighted median of {n} walls) after a "
                            f"{corner:.0f}° corner"]


def speed_advice(printer: Printer, job=None, config: TuneConfig | None = None, step: float = 5.0,
                 v_min: float = 10.0) -> SpeedAdvice:
    """Ripple against wall speed per direction and the bands to avoid (module docstring).

    ``job``: G-code path or text (None: a 40 mm square's walls, said in the notes); ``config``: the
    shaping and acceleration printed with (None: shaping off at the printer's acceleration, said)."""
    if not step > 0 or not 0 < v_min < printer.limits.velocity:
        raise RingtuneError(f"need a step > 0 and 0 < lowest speed < {printer.limits.velocity:g} mm/s", "speeds")
    length, corner, notes = _wall_of(job)
    if config is None:
        config = TuneConfig(firmware="klipper", shaper_x="none", shaper_y="none", accel=None)
        notes.append("no configuration given: shaping off, the printer's own acceleration")
    accel = float(config.accel or printer.limits.accel)
    speeds = np.arange(v_min, printer.limits.velocity + 1e-9, step)
    directions = dict(DIRECTIONS, **(DIAGONALS if printer.kinematics == "corexy" else {}))
    ripple = {k: ripple_against_speed(printer, config, d, length, corner, speeds) for k, d in directions.items()}
    bands = [b for k in directions for b in find_bands(k, speeds, ripple[k])]
    return SpeedAdvice(speeds, ripple, bands, length, corner, accel, notes)

