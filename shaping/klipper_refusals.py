"""The moves Klipper refuses, where a job is read as Klipper reads it (it stops the print at the
first, with the error named): its extruder's ``check_move`` — a line extruding more filament per mm
of path than ``max_extrude_cross_section`` allows ("Move exceeds maximum extrusion"), a move of the
extruder alone longer than ``max_extrude_only_distance`` ("Extrude only move too long") — and its
kinematics' — a move ending past an axis's position_min / position_max ("Move out of range": the
check of each axis the move moves, ``kinematics/cartesian.py`` ``_check_endstops``; on X and Y, where
the printer description gives ``[limits] travel_x`` / ``travel_y``)."""

from __future__ import annotations

import numpy as np

from ringtune.shaping.extruder_alone import e_capped


def known_xy(job) -> np.ndarray:
    """(n, 2) where each move's X / Y end is where the firmware puts it: after a move in absolute
    mode that moves the axis, unless a G28 (the firmware at its endstop, the reader at 0) or a G92
    of the axis while its position was not known stands between (``Job.position_events``). A job's
    first moves before any such move are not known either (the head is where it was)."""
    n = len(job.line)
    out = np.zeros((n, 2), bool)
    events = sorted(getattr(job, "position_events", ()) or ())
    bounds = [0, *np.searchsorted(job.line, [line for line, _k, _a in events], side="left"), n]
    known, offset_known, absolute = [False, False], [True, True], True
    for s in range(len(bounds) - 1):
        if s:
            absolute = _after(events[s - 1], known, offset_known, absolute)
        for i in (0, 1):
            _segment(job, slice(bounds[s], bounds[s + 1]), i, known, offset_known, absolute, out)
    return out


def _home(known: list, offset_known: list, i: int) -> None:
    known[i], offset_known[i] = False, True


def _set(known: list, offset_known: list, i: int) -> None:
    offset_known[i] = known[i]


#: what a position event does to an axis it names: G28 homes it, G92 keeps its offset known only if
#: its position was
_ON_AXIS = {"home": _home, "set": _set}


def _after(event: tuple, known: list, offset_known: list, absolute: bool) -> bool:
    """Apply one position event; whether moves are absolute after it."""
    _line, kind, axes = event
    for i in axes:
        _ON_AXIS.get(kind, lambda *_: None)(known, offset_known, i)
    return {"abs": True, "rel": False}.get(kind, absolute)


def _segment(job, rows: slice, i: int, known: list, offset_known: list, absolute: bool, out: np.ndarray) -> None:
    """Fill ``out[rows, i]`` for moves between two position events; ``known[i]`` as it ends."""
    out[rows, i] = known[i]
    moving = np.flatnonzero(job.end[rows, i] != job.start[rows, i]) if absolute else ()
    if len(moving):
        out[rows.start + moving[0]:rows.stop, i] = known[i] = offset_known[i]


def out_of_range(job, limits) -> list[tuple[int, str, float, float]]:
    """(move index, ``out_of_range_x`` | ``out_of_range_y``, where the move ends, the bound it passes)
    of the moves of ``job`` that end past ``limits.travel_x`` / ``travel_y`` on an axis they move,
    where the end is known to be the firmware's (:func:`known_xy`: a G28 then relative moves
    would be counted from 0, not from the endstop)."""
    spans = [(i, ax, getattr(limits, f"travel_{ax}", None)) for i, ax in enumerate("xy")]
    spans = [(i, ax, span) for i, ax, span in spans if span is not None]
    known = known_xy(job) if spans else None
    out = []
    for i, ax, span in spans:
        end, moved = job.end[:, i], job.end[:, i] != job.start[:, i]
        for k in np.flatnonzero(known[:, i] & moved & ((end < span[0]) | (end > span[1]))):
            out.append((int(k), f"out_of_range_{ax}", float(end[k]), float(span[0] if end[k] < span[0] else span[1])))
    return out


def klipper_refusals(job, limits) -> list[dict]:
    """The moves of ``job`` Klipper refuses where it is read as Klipper reads it (module docstring;
    it stops the print at the first), one per move (its kinematics' check first, as Klipper runs
    them): ``{"line", "kind", "value", "limit"}`` with kind ``out_of_range_x`` / ``out_of_range_y``
    (where a move ends on that axis, mm, past ``limits.travel_x`` / ``travel_y``: the bound passed),
    ``too_wide`` (an extruding move's filament per mm of path over ``max_extrude_ratio``, unless it
    extrudes no more than ``nozzle_diameter`` × that ratio) or ``too_long`` (a move of the extruder
    alone, or backwards, over ``extrude_only_distance`` mm of filament); the extruder's where
    ``limits`` know it. Empty otherwise."""
    if not limits.reads_like_klipper:
        return []
    out = out_of_range(job, limits)
    if limits.max_extrude_ratio is not None:
        out += _extruder_refusals(job, limits)
    first: dict[int, tuple] = {}
    for i, kind, v, lim in sorted(out):
        first.setdefault(i, (kind, v, lim))
    return [{"line": int(job.line[i]), "kind": kind, "value": v, "limit": float(lim)}
            for i, (kind, v, lim) in first.items()]


def _extruder_refusals(job, limits) -> list[tuple[int, str, float, float]]:
    """(move index, ``too_wide`` | ``too_long``, value, limit) of the moves Klipper's extruder refuses."""
    d = job.end - job.start
    e = d[:, 3]
    xyz = np.sqrt(np.einsum("ij,ij->i", d[:, :3], d[:, :3]))
    alone = e_capped(d)
    rate = np.divide(e, xyz, out=np.zeros_like(e), where=xyz > 0)
    tiny = (limits.nozzle_diameter or 0.0) * limits.max_extrude_ratio
    wide = ~alone & (rate > limits.max_extrude_ratio) & (e > tiny)
    far = limits.extrude_only_distance if limits.extrude_only_distance is not None else np.inf
    long = alone & (np.abs(e) > far)
    out = [(i, "too_wide", float(rate[i]), limits.max_extrude_ratio) for i in np.flatnonzero(wide)]
    out += [(i, "too_long", float(abs(e[i])), far) for i in np.flatnonzero(long)]
    return out


def klipper_refusals_note(found: list[dict], shown: int = 3) -> str | None:
    """What :func:`klipper_refusals` ``found``, in words (the first ``shown`` named), None where it
    found none."""
    if not found:
        return None
    words = {"too_wide": lambda r: (f"line {r['line']} extrudes {r['value']:.3f} mm of filament per mm of path, past "
                                    f"the {r['limit']:.3f} its max_extrude_cross_section allows (\"Move exceeds "
                                    "maximum extrusion\")"),
             "too_long": lambda r: (f"line {r['line']} moves the extruder alone by {r['value']:.1f} mm, past its "
                                    f"max_extrude_only_distance {r['limit']:g} mm (\"Extrude only move too long\")")}
    for ax in "xy":
        words[f"out_of_range_{ax}"] = lambda r, ax=ax: (
            f"line {r['line']} moves {ax.upper()} to {r['value']:.3f} mm, past stepper_{ax}'s "
            f"position_{'min' if r['value'] < r['limit'] else 'max'} {r['limit']:g} mm (\"Move out of range\")")
    more = f"; {len(found) - shown} more" if len(found) > shown else ""
    return (f"Klipper refuses {len(found)} of the job's moves and stops the print at the first (its kinematics' "
            f"and extruder's checks): " + "; ".join(words[r["kind"]](r) for r in found[:shown]) + more
            + ". ringtune plans and judges the job as if Klipper ran on")
