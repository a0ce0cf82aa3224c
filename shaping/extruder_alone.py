"""Klipper's limits on moves of the extruder alone (retractions and their restores): its
``[extruder] max_extrude_only_velocity`` and ``max_extrude_only_accel`` are their only limits
(``toolhead.py`` plans such a move unlimited, ``extruder.py`` ``check_move`` caps it), and an
extruding move has none on E. Unset, Klipper takes max_velocity and max_accel × 4·nozzle_diameter² /
the filament's cross-section (0.266 for a 0.4 mm nozzle and 1.75 mm filament). The printer
description carries them as ``[limits] extrude_only_velocity`` / ``extrude_only_accel``
(``ringtune printer from-klipper`` reads them; the E components of ``max_velocity`` / ``max_accel`` are
Marlin's and RRF's M203 E / M201 E, which Klipper has not); where it does not, the planner plans those moves at
the toolhead's acceleration and speed, and :func:`extruder_alone_note` says so."""

from __future__ import annotations

import math

import numpy as np


def filament_area(filament_diameter: float) -> float:
    """The filament's cross-section, mm², for its diameter (mm)."""
    return math.pi * (filament_diameter / 2.0) ** 2


def klipper_default_ratio(nozzle_diameter: float, filament_diameter: float) -> float:
    """Klipper's default extruder-alone limits over the toolhead's, and its default max_extrude_ratio:
    4·nozzle² (max_extrude_cross_section's default, mm²) / the filament's cross-section."""
    return 4.0 * nozzle_diameter ** 2 / filament_area(filament_diameter)


def e_capped(delta: np.ndarray) -> np.ndarray:
    """(n,) the moves (``delta``: (n, 4) x y z e, mm) Klipper's extruder limits bind (``extruder.py``
    ``check_move``): with E and no X/Y motion (a retraction, its restore, a Z move that extrudes),
    or with E backwards (a retraction while wiping)."""
    return (delta[:, 3] != 0) & (((delta[:, 0] == 0) & (delta[:, 1] == 0)) | (delta[:, 3] < 0))


def extruder_alone_note(job, limits) -> str | None:
    """Where ``job`` is read as Klipper reads it, has moves its extruder limits bind (:func:`e_capped`)
    and ``limits`` give none: that they are planned at the toolhead's acceleration and speed (None
    otherwise)."""
    if not limits.reads_like_klipper or limits.extrude_only_accel is not None:
        return None
    n = int(np.sum(e_capped(job.end - job.start)))
    if not n:
        return None
    return (f"the printer description gives no limits for moves of the extruder alone ([limits] extrude_only_accel "
            "and extrude_only_velocity: Klipper's [extruder] max_extrude_only_accel / _velocity, which `ringtune printer "
            f"from-klipper` reads): the job's {n} retractions, restores and wipes are planned at the toolhead's "
            f"acceleration and speed, where Klipper's defaults are {klipper_default_ratio(0.4, 1.75):.3f} × "
            "max_accel and max_velocity for a 0.4 mm nozzle and 1.75 mm filament, so they take longer there")
