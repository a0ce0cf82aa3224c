"""Layers of a parsed job and the filament mass laid down before each (units mm, kg).

Layers as the job rewriter inserts at them (:func:`layer_starts`): layer k is the k-th
height at which the job extrudes above every height before it, and begins right after the last
extrusion below it (its Z change and travel belong to it; layer 0 at the first move), which is
where a command for it is inserted. Deposited filament is the sum of E over extruding moves (E
rising while X/Y move: retractions and their priming do not count); its mass is length × π d²/4 ×
density.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.job import Job

#: the usual filament diameter, mm
FILAMENT_DIAMETER_MM = 1.75
#: PLA's density, g/cm³ (PETG ≈ 1.27, ABS ≈ 1.04, ASA ≈ 1.07)
FILAMENT_DENSITY_G_CM3 = 1.24


def layer_starts(job: Job) -> list[int]:
    """Move index where each layer starts: layer k is the k-th height (mm) at which the job
    extrudes above every height before it; it starts right after the last extruding move below it
    (so its Z move and travel belong to it). Layer 0 starts at the first move (or after a lower
    purge)."""
    ext = np.flatnonzero(job.extruding)
    if not len(ext):
        return []
    z = np.round(job.end[ext, 2], 4)
    new = np.concatenate(([True], z[1:] > np.maximum.accumulate(z)[:-1]))
    # each later layer starts after the extruding move before its first one
    return [0] + [int(ext[k - 1]) + 1 for k in np.searchsorted(ext, ext[new][1:])]

@dataclass
class Layer:
    """One layer: ``index`` (0-based), ``z`` (mm, its first extrusion's), ``first_move`` (move index
    where it begins),
    ``line`` (1-based source line of that move), ``mass_before`` (kg of filament laid before it),
    ``mass`` (kg laid in it), ``last_move`` (index of its last extruding move)."""

    index: int
    z: float
    first_move: int
    line: int
    mass_before: float
    mass: float
    last_move: int

    @property
    def mass_during(self) -> float:
        """kg on the bed halfway through the layer."""
        return self.mass_before + 0.5 * self.mass


def filament_mass_kg(length_mm, diameter_mm: float = FILAMENT_DIAMETER_MM,
                     density_g_cm3: float = FILAMENT_DENSITY_G_CM3):
    """kg of ``length_mm`` of filament of ``diameter_mm`` and ``density_g_cm3``."""
    if not (math.isfinite(diameter_mm) and 0.5 <= diameter_mm <= 5.0):
        raise RingtuneError(f"{diameter_mm:g} mm is not a filament diameter (0.5-5 mm: 1.75 or 2.85)",
                            "--filament-diameter")
    if not (math.isfinite(density_g_cm3) and 0.5 <= density_g_cm3 <= 5.0):
        raise RingtuneError(f"{density_g_cm3:g} g/cm³ is not a filament density (0.5-5 g/cm³: PLA 1.24)",
                            "--filament-density")
    area_mm2 = math.pi * diameter_mm ** 2 / 4.0
    return np.asarray(length_mm, float) * area_mm2 * density_g_cm3 * 1e-6    # mm³ · g/cm³ → kg


def job_layers(job: Job, diameter_mm: float = FILAMENT_DIAMETER_MM,
               density_g_cm3: float = FILAMENT_DENSITY_G_CM3) -> list[Layer]:
    """The job's layers in print order with the filament mass laid before and in each."""
    ext = np.flatnonzero(job.extruding)
    if not len(ext):
        raise RingtuneError("the job extrudes nothing: no layers, no mass on the bed", job.source)
    starts = layer_starts(job)
    de = filament_mass_kg(job.delta[ext, 3], diameter_mm, density_g_cm3)
    cum = np.concatenate([[0.0], np.cumsum(de)])
    # the extruding moves of layer k: from its start to the next layer's start
    bounds = list(np.searchsorted(ext, starts)) + [len(ext)]
    layers = []
    for k, (a, b) in enumerate(zip(bounds, bounds[1:])):
        layers.append(Layer(k, float(job.end[ext[a], 2]), int(starts[k]), int(job.line[starts[k]]),
                            float(cum[a]), float(cum[b] - cum[a]), int(ext[b - 1])))
    return layers


def job_slice(job: Job, first: int, stop: int) -> Job:
    """Moves ``first`` to ``stop`` − 1 of ``job`` as a job of their own (their settings, features,
    and the events and firmware retractions among them kept)."""
    if not 0 <= first < stop <= job.n_moves:
        raise RingtuneError(f"moves {first}..{stop} are outside the job's 0..{job.n_moves}", job.source)
    sl = slice(first, stop)
    events = [replace(e, move=e.move - first, time=None) for e in job.events if first <= e.move < stop]
    retractions = [replace(r, move=r.move - first) for r in job.fw_retractions if first <= r.move < stop]
    stop_before = job.stop_before[sl].copy()
    stop_before[0] = True
    return replace(job, line=job.line[sl], start=job.start[sl], end=job.end[sl], feed=job.feed[sl],
                   feature=job.feature[sl], settings=job.settings[sl], stop_before=stop_before,
                   dwell_before=job.dwell_before[sl], arc=job.arc[sl], events=events, dwell_after=0.0,
                   fw_retractions=retractions)
