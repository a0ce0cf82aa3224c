"""The per-feature part of the search space (issue 22): an acceleration per group of feature
classes (:data:`ringtune.agents.tune.feature_groups.ACCEL_GROUPS`), the corner rule and Klipper's
minimum_cruise_ratio, for the job and for the corners nobody sees — within the firmware's limits
and each motor's reserve at that group's own speeds. One shaper configuration for the job
(firmwares shape per axis, not per feature). The study leaves them all to the walk from its choice
(:mod:`ringtune.agents.tune.hidden_raise`).

A hidden group (inner walls, infill, travel) is judged by what shows through, what the inner walls
push into the outer wall, extrusion where a person sees the material, and the constraints, and
most of its moves are never simulated; so its range stops where the weakest
motor keeps its reserve at the group's top speed, on the rigid machine
(:func:`ringtune.agents.tune.motor_bound.motor_accel_limit` with the reserve: the force asked, friction
included, at most (1 − reserve) of what the motor has at that speed). The visible group keeps the
space's ``accel`` range (judged by simulation, motor load included). Units: mm/s², mm/s, mm.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from ringtune.agents.tune.motor_bound import motor_accel_limit
from ringtune.agents.tune.feature_groups import ACCEL_GROUPS, CORNER_GROUPS, CORNER_WORDS, HIDDEN_CORNERS, SEEN_GROUPS
from ringtune.agents.tune.space import CORNER_UNIT, SearchSpace
from ringtune.agents.tune.hardware_cap import accel_ceiling, corner_ceiling, held_range, job_hardware
from ringtune.envs.planned_job import planned_job, resolve_job
from ringtune.shaping.config_plan import as_read_by, for_firmware
from ringtune.shaping.feature_settings import corner_value, effective_classes
from ringtune.shaping.features import FEATURE_CLASSES
from ringtune.shaping.firmware import FIRMWARES

#: ranges of the corner rule per junction rule: Klipper square_corner_velocity (mm/s), Marlin
#: junction deviation (mm), classic jerk / RRF M566 (mm/s)
CORNER_RANGE = {"scv": (2.0, 15.0), "jd": (0.005, 0.08), "jerk": (4.0, 20.0)}
#: Klipper's minimum_cruise_ratio searched from 0 (no smoothing) to its default 0.5
MCR_RANGE = (0.0, 0.5)
#: the corner rule of the classes whose corners nobody sees (:data:`HIDDEN_CORNERS`): up to twice the
#: visible walls' top — there only the show-through within the wall gap, extrusion and the motors'
#: reserve bound it, all judged on the simulated windows
HIDDEN_CORNER_RANGE = {k: (lo, 2.0 * hi) for k, (lo, hi) in CORNER_RANGE.items()}


def group_speeds(printer: Any, job: Any = None, firmware: str | None = None) -> dict[str, float]:
    """{group: top speed of its moves with X/Y motion, mm/s} for the groups the job has (planned
    at the printer's limits: the speed each move asks for after the velocity limits, the job's own
    as ``firmware`` reads them; None: as the printer's own does)."""
    _, parsed = resolve_job(job, for_firmware(printer.limits, as_read_by(firmware)))   # as the plan reads it
    moves = planned_job(printer, job, as_read_by(firmware)).plan.moves
    xy = np.hypot(*(moves.end - moves.start)[:, :2].T) > 0
    cls = effective_classes(parsed)
    out = {}
    for group, members in ACCEL_GROUPS.items():
        sel = xy & np.isin(cls, [FEATURE_CLASSES.index(c) for c in members])
        if sel.any():
            out[group] = float(moves.v_nominal[sel].max())
    return out


def feature_space(space: SearchSpace, printer: Any, job: Any = None, reserve: float = 0.2,
                  corner: bool = True, min_cruise_ratio: bool = True) -> SearchSpace:
    """``space`` with an acceleration range per group the job has (``visible`` stays ``accel``),
    the corner rule (``corner``) and, under Klipper's junction rule, minimum_cruise_ratio."""
    speeds = group_speeds(printer, job, space.firmware)
    lo = space.accel[0]
    hw, _model = job_hardware(printer, job, space.firmware)       # a firmware's compiled ceilings
    fw_hi = min(FIRMWARES[space.firmware].accel.hi, accel_ceiling(hw) or math.inf)
    groups, basis = [], {}
    for group, v in speeds.items():
        if group == "visible":
            basis[group] = {"top_speed_mm_s": v, "range": list(space.accel), "basis": space.accel_basis}
            continue
        limit, who = motor_accel_limit(printer, v, reserve=reserve)
        hi = max(lo, min(fw_hi, math.floor(limit / space.accel_step) * space.accel_step))
        groups.append((group, lo, float(hi)))
        basis[group] = {"top_speed_mm_s": v, "range": [lo, float(hi)],
                        "basis": f"the {who} keeps {reserve * 100:.0f} % of its force at {v:.0f} mm/s"}
    lim = printer.limits
    junction = lim.junction
    now = corner_value(lim)
    klipper = FIRMWARES[space.firmware].family == "klipper"
    sayable = junction != "scv" or klipper       # square_corner_velocity is Klipper's alone
    mcr = min_cruise_ratio and junction == "scv" and klipper
    behind = any(c in HIDDEN_CORNERS for g in speeds for c in ACCEL_GROUPS[g])
    top = corner_ceiling(hw, junction)
    return dataclasses.replace(
        space, feature_accel=tuple(groups), junction=junction,
        corner=held_range(CORNER_RANGE[junction], top) if (corner and sayable) else None,
        min_cruise_ratio=MCR_RANGE if mcr else None,
        hidden_corner=held_range(HIDDEN_CORNER_RANGE[junction], top) if (corner and sayable and behind) else None,
        hidden_min_cruise_ratio=MCR_RANGE if (mcr and behind) else None,
        feature_basis=basis, corner_now=float(now), mcr_now=float(lim.min_cruise_ratio))


def hidden_groups(printer: Any, job: Any = None) -> list[str]:
    """The groups nobody sees (not ``visible``, not :data:`SEEN_GROUPS`) that the job has moves of
    (travel included)."""
    return [g for g in group_speeds(printer, job) if g != "visible" and g not in SEEN_GROUPS]


def wanted(mode: str, space: SearchSpace, printer: Any, job: Any, job_sets_accel: bool,
           job_accel: str) -> tuple[bool, str]:
    """(search per feature, why) for ``--per-feature`` ``mode`` (``auto``, ``on``, ``off``):
    ``auto`` searches it when the acceleration is searched, the job has features nobody sees, and
    its own acceleration commands are not to be respected (they would be overruled)."""
    if mode == "off":
        return False, "--per-feature off"
    hidden = hidden_groups(printer, job)
    if not hidden:
        return False, "the job has no features apart from the visible ones (no labels, no travel)"
    if mode == "on":
        return True, "--per-feature on"
    if space.accel_fixed:
        return False, "the acceleration is not searched"
    if job_sets_accel and job_accel == "respect":
        return False, ("the job sets its own accelerations and --job-accel respect keeps them "
                       "(--job-accel replace searches them per feature, as re-slicing would; "
                       "--per-feature on overrules them too, the seen features' included, against the "
                       "print as sliced)")
    return True, f"the job has {', '.join(hidden)} apart from the visible features"


def feature_section(config, space: SearchSpace) -> tuple[list[str], dict]:
    """Summary lines and JSON of the chosen per-feature settings: each group's acceleration with
    its range and what bounds it, the corner rule, minimum_cruise_ratio."""
    basis = space.feature_basis or {}
    info = {"accel": {"visible": config.accel}, "ranges": dict(basis),
            "corner": config.corner, "junction": space.junction, "min_cruise_ratio": config.min_cruise_ratio,
            **{f"{what}_{name}": _group_value(table, CORNER_GROUPS[name])
               for name in CORNER_GROUPS for what, table in (("corner", config.feature_corner),
                                                             ("min_cruise_ratio", config.feature_min_cruise_ratio))},
            **{f"{name}_corner_classes": list(CORNER_GROUPS[name]) for name in CORNER_GROUPS}}
    lines = [f"  visible walls (outer walls, overhangs, unlabelled moves): {config.accel:.0f} mm/s² "
             f"(searched {space.accel[0]:.0f}–{space.accel[1]:.0f}; judged by ripple, corners, extrusion; unlabelled "
             "moves only where the job labels nothing visible, else they are a purge line)"]
    for group, lo, hi in space.feature_accel:
        a = config.feature_accel.get(ACCEL_GROUPS[group][0], config.accel)
        info["accel"][group] = a
        b = basis.get(group, {})
        lines.append(f"  {group.replace('_', ' ')} ({', '.join(ACCEL_GROUPS[group])}): {a:.0f} mm/s² "
                     f"(walked within {lo:.0f}–{hi:.0f}: {b.get('basis', '')})")
    rule = {"scv": "square_corner_velocity", "jd": "junction deviation", "jerk": "jerk"}
    unit = {j: f"{CORNER_UNIT[j]} {name}" for j, name in rule.items()}
    if config.corner is not None:
        lines.append(f"  corner rule: {config.corner:g} {unit.get(space.junction, '')}")
    if config.min_cruise_ratio is not None:
        lines.append(f"  minimum_cruise_ratio: {config.min_cruise_ratio:g}")
    for group in CORNER_GROUPS:
        why = CORNER_WORDS[group][2]
        for name, value, rng, u in (("corner rule", info[f"corner_{group}"], space.hidden_corner,
                                     unit.get(space.junction, "")),
                                    ("minimum_cruise_ratio", info[f"min_cruise_ratio_{group}"],
                                     space.hidden_min_cruise_ratio, "")):
            if value is not None:
                lines.append(f"  {name} of {', '.join(CORNER_GROUPS[group])} ({why}): {value:g}{' ' + u if u else ''}"
                             + (f" (walked within {rng[0]:g}–{rng[1]:g})" if rng else ""))
    return lines, info


def _group_value(table: dict, classes: tuple[str, ...]) -> float | None:
    """The value a per-class table gives ``classes`` (None: none set, or not one value)."""
    values = {table[c] for c in classes if c in table}
    return values.pop() if len(values) == 1 else None
