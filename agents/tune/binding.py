"""Which firmware limit binds an acceleration, measured: each limit removed from the planner in turn.

The chosen acceleration is not what every move runs at: a per-axis cap (Marlin/RRF ``M201 X Y``,
Kalico's ``max_x_accel``/``max_y_accel``), Marlin's retract acceleration (``M204 R``) or a travel
acceleration kept apart (``M204 T``) lowers some moves. For each such limit of the printer (and of
the configuration, whose caps replace the printer's), :func:`binding_limits` plans the job with it
and without it (the same planner, the same job, nothing else changed: a cap removed leaves those
moves at the configuration's acceleration; a retract or travel acceleration removed is raised to
it, since nothing else would bound those moves) and reports the moves it lowers and the print time
it costs; a limit that lowers no move does not bind and is not said.
:func:`binding_sentences` words them with the firmware's own names, for the summary.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ringtune.envs.planned_job import resolve_job
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.config_plan import for_firmware, plan_with_config, with_axis_caps
from ringtune.shaping.firmware import FIRMWARES
from ringtune.shaping.planner import MachineLimits

#: relative change of a move's acceleration below which a limit is said not to lower it
_TOL = 1e-9


@dataclass(frozen=True)
class Binding:
    """One limit that lowers some moves: its firmware name, value (mm/s²), the moves it lowers
    (count and what they are), and the print time (s) with it and with it removed."""

    name: str
    value: float
    what: str
    moves: int
    time_s: float
    time_without_s: float

    @property
    def cost_s(self) -> float:
        return self.time_s - self.time_without_s

    def sentence(self) -> str:
        pct = 100.0 * self.cost_s / self.time_without_s if self.time_without_s > 0 else 0.0
        return (f"{self.name} {self.value:.0f} mm/s² binds on {_counted(self.moves, self.what)}: the planner gives "
                f"{self.time_s:.2f} s with it and {self.time_without_s:.2f} s with it removed "
                f"({self.cost_s:+.2f} s, {pct:+.1f} %)")


def _counted(n: int, what: str) -> str:
    """``"2 moves with Z travel"``, ``"1 move with Z travel"``."""
    return f"{n} {what.replace('moves', 'move').replace('retractions', 'retraction') if n == 1 else what}"


#: the limits' own names per firmware family (``x``, ``y``, ``z``: the per-axis caps), Marlin's G-code where
#: the family has none of its own
_CAP_NAMES = {"klipper": {"x": "max_x_accel", "y": "max_y_accel", "z": "max_z_accel",
                          "retract": "retract acceleration", "travel": "travel acceleration"}}
_GCODE_CAP_NAMES = {"x": "M201 X", "y": "M201 Y", "z": "M201 Z", "retract": "M204 R", "travel": "M204 T"}


def cap_names(firmware: str) -> dict[str, str]:
    """The firmware's own names of the limits (``x``, ``y``: the per-axis caps; ``retract``,
    ``travel``): ``M201 X``/``M204 R`` on Marlin, ``max_x_accel`` on Kalico/Klipper, and so on."""
    return dict(_CAP_NAMES.get(FIRMWARES[firmware].family, _GCODE_CAP_NAMES))


def _variants(limits: MachineLimits) -> list[tuple[str, float, MachineLimits, str]]:
    """(key, its value mm/s², the limits with that limit removed, what it acts on) for every limit
    there is."""
    caps = tuple(limits.max_accel or ())
    out = [(ax, float(cap), replace(limits, max_accel=tuple(0.0 if j == i else c for j, c in enumerate(caps)),
                                    scale_xy_accel=False), f"moves with {ax.upper()} travel")
           for i, (ax, cap) in enumerate(zip("xyz", caps)) if cap > 0]
    if limits.reads_like_klipper:          # Klipper: one acceleration for every move
        return out
    roles = (("retract", "retract_accel", "retractions (E-only moves)"), ("travel", "travel_accel", "travel moves"))
    return out + [(key, float(getattr(limits, attr)), replace(limits, **{attr: limits.accel}), what)
                  for key, attr, what in roles if getattr(limits, attr) is not None]


def binding_limits(printer, job, config: TuneConfig, firmware: str | None = None,
                   job_accel: str | None = None) -> list[Binding]:
    """The limits that lower some move's acceleration when ``job`` runs on ``printer`` under
    ``config``, each with the print time with and without it (module docstring)."""
    limits = for_firmware(with_axis_caps(printer.limits, config), config)
    _, parsed = resolve_job(job, limits)
    if config.accel is not None:
        limits = replace(limits, accel=float(config.accel))
    plain = replace(config, max_accel_x=None, max_accel_y=None)     # its caps are in ``limits`` now
    base = plan_with_config(parsed, limits, plain, job_accel=job_accel).plan
    names = cap_names(firmware or config.firmware)
    out = []
    for key, value, without, what in _variants(limits):
        other = plan_with_config(parsed, without, plain, job_accel=job_accel).plan
        lowered = base.moves.accel < other.moves.accel * (1 - _TOL)
        if not lowered.any():
            continue
        out.append(Binding(names[key], value, what, int(np.sum(lowered)), float(base.print_time),
                           float(other.print_time)))
    return out


def binding_sentences(bindings: list[Binding], accel: float | None) -> list[str]:
    """Summary lines: each binding limit, or that none lowers any move below ``accel``."""
    if not bindings:
        return ([f"No per-axis cap, retract or travel acceleration lowers any move below {accel:.0f} mm/s²."]
                if accel is not None and math.isfinite(accel) else [])
    head = (f"Limits that hold some moves below {accel:.0f} mm/s² (each removed in turn from the planner, "
            "the same job):" if accel is not None else "Limits that hold some moves lower:")
    return [head] + [f"  {b.sentence()}" for b in bindings]
