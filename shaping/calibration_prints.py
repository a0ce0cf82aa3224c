"""Calibration prints for printers without an accelerometer (units mm, mm/s, mm/s², Hz).

- :func:`ringing_tower`: a single-wall square tower printed at one constant wall speed with sharp
  90° corners, in height bands that each carry their own shaper lines (or shaping off, to measure
  ripples: seed 000). The walls along Y show the ringing of X, the walls along X that of Y. The
  band table and what to measure are written as comments; :func:`read_band_table` reads the table
  back (``ringtune identify --tower-band``).
- :func:`accel_ladder`: a check of an acceleration on the machine: rungs of fast travel moves at
  rising accelerations, each starting and ending at one reference point and followed by two short
  marks (a dash along Y at the same X for every rung, a dash along X at the same Y): a dash out of
  line means the motors skipped steps on that rung.

The firmware's own lines (shaper settings, acceleration commands) are made by the caller
(``hardware.dialects`` for shapers) or by :func:`accel_lines`; this module writes geometry and
comments only.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.firmware import Firmware

C = ";"   # comment character every firmware here accepts (Klipper too)


@dataclass(frozen=True)
class Extrusion:
    """Line geometry: nozzle and line width (mm), layer height (mm), filament diameter (mm)."""

    nozzle: float = 0.4
    layer: float = 0.2
    filament: float = 1.75
    width: float | None = None     # default 1.125 × nozzle

    def validate(self) -> None:
        for name, lo, hi in (("nozzle", 0.1, 2.0), ("layer", 0.04, 1.0), ("filament", 1.0, 3.5)):
            v = getattr(self, name)
            if not (math.isfinite(v) and lo <= v <= hi):
                raise RingtuneError(f"must be {lo:g} to {hi:g} mm, not {v:g}", f"--{name}")
        if self.layer > 0.8 * self.nozzle:
            raise RingtuneError(f"a {self.layer:g} mm layer is too thick for a {self.nozzle:g} mm nozzle "
                                "(at most 80 % of it)", "--layer")

    @property
    def line_width(self) -> float:
        return self.width if self.width else 1.125 * self.nozzle

    @property
    def e_per_mm(self) -> float:
        """mm of filament per mm of line: line cross-section / filament cross-section."""
        return self.line_width * self.layer / (math.pi * (self.filament / 2.0) ** 2)


@dataclass
class Band:
    """A height band of the ringing tower: number (1 = lowest), heights (mm, the band holds the
    layers with ``z0 < z <= z1``), shaper frequency per axis (Hz, 0 = shaping off), the shaper's
    name and damping, and the firmware lines that set it."""

    number: int
    z0: float
    z1: float
    freq_x: float
    freq_y: float
    shaper: str
    damping: float
    lines: list[str] = field(default_factory=list)

    def table_line(self) -> str:
        def f(v):
            return f"{v:.2f} Hz" if v > 0 else "off"
        what = f" ({self.shaper}, damping {self.damping:g})" if self.shaper != "none" else " (shaping off)"
        return (f"{C} ringtune band {self.number}: z {self.z0:.2f}-{self.z1:.2f} mm: "
                f"X {f(self.freq_x)}, Y {f(self.freq_y)}{what}")


_BAND = re.compile(r"^\s*;\s*ringtune band (\d+): z ([\d.]+)-([\d.]+) mm: X (off|[\d.]+ Hz), "
                   r"Y (off|[\d.]+ Hz)")


def read_band_table(text: str, where: str = "tower") -> list[tuple[float, float, dict]]:
    """The band table of a ringing tower written by :func:`ringing_tower`: [(z0, z1, {"x": Hz,
    "y": Hz})] in band order (0 Hz = shaping off)."""
    rows = {}
    for line in text.splitlines():
        m = _BAND.match(line)
        if m:
            hz = [0.0 if g == "off" else float(g.split()[0]) for g in (m.group(4), m.group(5))]
            rows[int(m.group(1))] = (float(m.group(2)), float(m.group(3)), {"x": hz[0], "y": hz[1]})
    if not rows:
        raise RingtuneError("no band table (lines '; ringtune band N: ...'): not a ringing tower written "
                            "by ringtune testprint ringing", where)
    if sorted(rows) != list(range(1, len(rows) + 1)):
        raise RingtuneError(f"the band table is incomplete (bands {sorted(rows)})", where)
    return [rows[k] for k in sorted(rows)]


# -- acceleration commands per firmware ------------------------------------------------------------
def accel_lines(firmware: str, accel: float, axis_maxima: bool = True) -> list[str]:
    """The lines that make ``firmware`` print and travel at ``accel`` mm/s²: its own command from
    :mod:`ringtune.shaping.firmware` (``SET_VELOCITY_LIMIT ACCEL=``, ``M204 P T``: the ladder's fast
    moves are travel moves); Marlin, Prusa, RepRapFirmware (``M201 X Y``) and Kalico's limited_* kinematics
    (``SET_VELOCITY_LIMIT X_ACCEL= Y_ACCEL=``) also cap each axis, so those caps are raised first
    when ``axis_maxima``."""
    fw = Firmware.named(firmware, "--firmware")
    a = f"{accel:.0f}"
    caps = [fw.axis_accel_set.format(x=a, y=a)] if axis_maxima and fw.axis_accel_set else []
    return caps + [fw.accel_set.format(a=a)]


def accel_syntax(firmware: str) -> str:
    """How :func:`accel_lines` sets the acceleration on ``firmware``, for comments."""
    lines = accel_lines(firmware, 987654321)
    text = " + ".join(ln.replace("987654321", "<a>") for ln in lines)
    return text + (" (axis maxima, then print and travel)" if len(lines) > 1 else "")


# -- the ringing tower ------------------------------------------------------------------------------
@dataclass(frozen=True)
class TowerGeometry:
    """Where and how the tower is printed: front-left corner (mm), side (mm), wall speed (mm/s),
    first-layer speed (mm/s), travel speed (mm/s)."""

    x0: float = 80.0
    y0: float = 80.0
    side: float = 60.0
    speed: float = 100.0
    first_layer_speed: float = 25.0
    travel_speed: float = 150.0


def _e(ext: Extrusion, x0, y0, x1, y1) -> str:
    return f"{ext.e_per_mm * math.hypot(x1 - x0, y1 - y0):.5f}"


def start_lines(hotend: float, bed: float, accel: list[str]) -> list[str]:
    """Heat, home, absolute XYZ with relative E, then the acceleration lines."""
    return [f"M140 S{bed:.0f}", f"M104 S{hotend:.0f}", "G28", "G90", "M83", f"M190 S{bed:.0f}",
            f"M109 S{hotend:.0f}", *accel]


def end_lines(z: float) -> list[str]:
    return ["G1 E-1 F2400", f"G1 Z{z + 10:.2f} F600", "M104 S0", "M140 S0", "M84"]


def _prime_and_brim(g: TowerGeometry, ext: Extrusion) -> list[str]:
    """A prime line in front of the tower, then a 3-loop brim around the first layer (the travel from
    the homed corner runs 2 mm up, clear of bed clips and an unlevel bed's high side)."""
    x0, y0, s, z = g.x0, g.y0, g.side, ext.layer
    out = [f"G1 Z{z + 2:.3f} F600", f"G1 X{x0:.3f} Y{y0 - 12:.3f} F{g.travel_speed * 60:.0f}",
           f"G1 Z{z:.3f} F600",
           f"G1 X{x0 + s:.3f} Y{y0 - 12:.3f} E{_e(ext, x0, 0, x0 + s, 0)} F{g.first_layer_speed * 60:.0f}"]
    for k in (3, 2, 1):
        d = k * ext.line_width
        pts = [(x0 - d, y0 - d), (x0 + s + d, y0 - d), (x0 + s + d, y0 + s + d), (x0 - d, y0 + s + d),
               (x0 - d, y0 - d)]
        out.append(f"G1 X{pts[0][0]:.3f} Y{pts[0][1]:.3f} F{g.travel_speed * 60:.0f}")
        out.append(f"G1 F{g.first_layer_speed * 60:.0f}")
        out += [f"G1 X{bx:.3f} Y{by:.3f} E{_e(ext, ax, ay, bx, by)}" for (ax, ay), (bx, by) in zip(pts, pts[1:])]
    out.append(f"G1 X{x0:.3f} Y{y0:.3f} F{g.travel_speed * 60:.0f}")
    return out


def _layer(i: int, band: Band, first_of_band: bool, g: TowerGeometry, ext: Extrusion) -> list[str]:
    """Layer ``i`` (from 0): its comment, the band's lines before its first layer, then the
    counter-clockwise square from the front-left corner."""
    z = (i + 1) * ext.layer
    out = [f"{C} layer {i + 1}, z {z:.3f} mm, band {band.number}"]
    if first_of_band:
        out += [f"{C} band {band.number} starts", *band.lines]
    out += [f"G1 Z{z:.3f} F600", f"G1 F{(g.first_layer_speed if i == 0 else g.speed) * 60:.0f}"]
    corners = [(g.x0, g.y0), (g.x0 + g.side, g.y0), (g.x0 + g.side, g.y0 + g.side), (g.x0, g.y0 + g.side),
               (g.x0, g.y0)]
    out += [f"G1 X{qx:.3f} Y{qy:.3f} E{_e(ext, px, py, qx, qy)}" for (px, py), (qx, qy) in zip(corners, corners[1:])]
    return out


def _comments(lines: list[str]) -> list[str]:
    """``lines`` as G-code comments (an empty line as a bare ``;``)."""
    return [f"{C} {h}" if h else C for h in lines]


def ringing_tower(bands: list[Band], geometry: TowerGeometry, ext: Extrusion, *, header: list[str],
                  start: list[str], end_note: list[str]) -> str:
    """G-code of the ringing tower: ``header`` comments, the band table, ``start`` lines, a prime
    line and a 3-loop brim, then every layer (counter-clockwise square, seam at the front-left
    corner) with each band's lines just before its first layer."""
    ext.validate()
    if not bands:
        raise RingtuneError("a tower needs at least one band", "--bands")
    out = _comments(header)
    out += [C, f"{C} band table (band 1 is the lowest; frequencies of the shaper each band is printed with):"]
    out += [b.table_line() for b in bands]
    out += [C] + start
    # band 1 holds the first layer, prime line and brim included
    out += [f"{C} band {bands[0].number} starts", *bands[0].lines]
    out += _prime_and_brim(geometry, ext)
    n_layers = int(round(bands[-1].z1 / ext.layer))
    band_iter = iter(bands)
    band = next(band_iter)
    for i in range(n_layers):
        first_of_band = False
        while (i + 1) * ext.layer > band.z1 + 1e-9:
            band = next(band_iter)
            first_of_band = True
        out += _layer(i, band, first_of_band, geometry, ext)
    out += end_lines(n_layers * ext.layer if n_layers else ext.layer)
    out += [f"{C} {h}" for h in end_note]
    return "\n".join(out) + "\n"


def tower_bands(f0: float, f1: float, n: int, band_height: float, layer: float) -> list[tuple[int, float, float, float]]:
    """(number, z0, z1, frequency) of ``n`` bands from ``f0`` to ``f1`` Hz (evenly spaced), each
    ``band_height`` mm (rounded to whole layers)."""
    if n < 1 or n > 50:
        raise RingtuneError(f"the number of bands must be 1 to 50, not {n}", "--bands")
    if not (math.isfinite(f0) and math.isfinite(f1) and 0 < f0 and (f0 < f1 or (n == 1 and f0 == f1))):
        raise RingtuneError(f"need 0 < F0 < F1, not {f0:g}:{f1:g}", "--bands")
    layers = max(1, int(round(band_height / layer)))
    h = layers * layer
    step = (f1 - f0) / (n - 1) if n > 1 else 0.0
    return [(k + 1, k * h, (k + 1) * h, f0 + k * step) for k in range(n)]


# -- the acceleration ladder -------------------------------------------------------------------------
@dataclass(frozen=True)
class LadderGeometry:
    """Reference point (mm), reach of the fast moves around it (mm), their speed (mm/s), the
    repetitions of the pattern per rung, the hop height (mm) of fast moves and the mark speed."""

    cx: float = 110.0
    cy: float = 110.0
    reach: float = 40.0
    speed: float = 200.0
    reps: int = 3
    hop: float = 2.0
    mark_speed: float = 20.0
    mark_length: float = 4.0
    mark_pitch: float = 6.0


def ladder_marks(g: LadderGeometry, k: int) -> tuple[tuple, tuple]:
    """The two dashes of rung ``k`` (0 = reference, before any fast move): (start, end) of the dash
    along Y at x = cx (its X tells whether X lost steps) and of the dash along X at y = cy."""
    a = g.mark_pitch * (k + 1)
    along_y = ((g.cx, g.cy + a), (g.cx, g.cy + a + g.mark_length))
    along_x = ((g.cx + a, g.cy), (g.cx + a + g.mark_length, g.cy))
    return along_y, along_x


def _fast_pattern(g: LadderGeometry) -> list[tuple[float, float]]:
    """Points of one repetition, from and back to the reference point: X, Y and both diagonals
    (on CoreXY the diagonals load one motor alone)."""
    cx, cy, r = g.cx, g.cy, g.reach
    pts = []
    for dx, dy in ((1, 0), (0, 1), (1, 1), (1, -1)):
        pts += [(cx + r * dx, cy + r * dy), (cx - r * dx, cy - r * dy), (cx, cy)]
    return pts


def accel_ladder(accels: list[float], firmware: str, g: LadderGeometry, ext: Extrusion, *,
                 header: list[str], start: list[str], safe_accel: float, shaper_lines: list[str],
                 restore: list[str], end_note: list[str]) -> str:
    """G-code of the acceleration ladder. Reference marks first (at ``safe_accel``); then per rung:
    its acceleration, ``reps`` × the fast pattern at ``g.speed`` starting and ending at the
    reference point, ``safe_accel`` again, and the rung's two marks (drawn slowly, returning to the
    reference point). Rungs are delimited by ``; rung K start`` / ``; rung K end`` comments;
    ``restore`` lines come last (the starting acceleration again)."""
    ext.validate()
    if g.reps < 1:
        raise RingtuneError("at least one repetition per rung", "--reps")
    out = _comments(header) + [C] + start + shaper_lines
    z, zh = ext.layer, ext.layer + g.hop
    travel = f"F{g.speed * 60:.0f}"

    def marks(k: int) -> list[str]:
        lines = []
        for (ax, ay), (bx, by) in ladder_marks(g, k):
            lines += [f"G1 X{ax:.3f} Y{ay:.3f} F{g.mark_speed * 3 * 60:.0f}", f"G1 Z{z:.3f} F600",
                      "G1 E1 F2400",
                      f"G1 X{bx:.3f} Y{by:.3f} E{_e(ext, ax, ay, bx, by)} F{g.mark_speed * 60:.0f}",
                      "G1 E-1 F2400", f"G1 Z{zh:.3f} F600"]
        lines.append(f"G1 X{g.cx:.3f} Y{g.cy:.3f} F{g.mark_speed * 3 * 60:.0f}")
        return lines

    out += [f"G1 Z{zh:.3f} F600", f"G1 X{g.cx:.3f} Y{g.cy:.3f} F{g.mark_speed * 3 * 60:.0f}",
            f"{C} reference marks (rung 0) at {safe_accel:.0f} mm/s²"]
    out += accel_lines(firmware, safe_accel) + ["G1 E-1 F2400"] + marks(0)
    for k, a in enumerate(accels, 1):
        out.append(f"{C} rung {k} start: {a:.0f} mm/s²")
        out += accel_lines(firmware, a)
        for _ in range(g.reps):
            out += [f"G1 X{x:.3f} Y{y:.3f} {travel}" for x, y in _fast_pattern(g)]
        out += accel_lines(firmware, safe_accel)
        out += marks(k)
        out.append(f"{C} rung {k} end")
    out += ["G1 E1 F2400"] + end_lines(z) + restore
    out += [f"{C} {h}" for h in end_note]
    return "\n".join(out) + "\n"
