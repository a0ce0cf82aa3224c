"""The extruder as each firmware commands it under input shaping (seed 002; mm of filament, s).

Input shaping moves X and Y later than the planner asked by the shaper's centroid ΣAᵢTᵢ (causal
shapers) or by nothing on average (time-centred ones); what the extruder does meanwhile is the
firmware's choice, recorded per firmware in :class:`ringtune.shaping.firmware.Firmware`
(``e_timing``, ``xy_delay``, with sources):

- ``shaped``: the extruder gets the same impulses as X/Y (RepRapFirmware 3.5+);
- ``delayed``: the extruder is delayed by the shaped axes' lag (Marlin FT_MOTION with
  ``FTM_SHAPER_E`` and axis synchronisation);
- ``neither``: the extruder runs on the planner's clock; it is in step with the nozzle on average
  only where X/Y are time-centred (Klipper, Prusa), and ahead by the lag where they are delayed
  (Marlin classic ZV, Marlin FT_MOTION as built by default).

:func:`extruder_command` gives that command on the clock of
:func:`ringtune.shaping.apply.shape_motion`'s output (centred or causal as the flavour's shapers
are applied), so it can be compared sample by sample with the simulated nozzle.
"""

from __future__ import annotations

import numpy as np

from ringtune.shaping.apply import shape_motion
from ringtune.shaping.firmware import FIRMWARES, Firmware
from ringtune.shaping.motion import Motion
from ringtune.shaping.shapers import Shaper, shapers_from_config

E_TIMINGS = ("shaped", "delayed", "neither")
#: each timing in words, for reports
E_TIMING_WORDS = {"shaped": "the extruder shaped with X/Y", "delayed": "the extruder delayed with X/Y",
                  "neither": "the extruder neither shaped nor delayed"}
XY_DELAYS = ("centred", "causal", "largest")


def extruder_motion(raw: Motion) -> Motion:
    """The extruder column of ``raw`` as a one-column motion (same segments, mm and mm/s)."""
    return Motion(raw.t, raw.p[:, 3:4], raw.v[:, 3:4], raw.a[:, 3:4], raw.extruding, raw.move)


def shaped_axes_lag(shapers: dict[str, Shaper | None], centred: bool) -> float:
    """s: the largest delay a shaped axis takes from its shaper (its centroid ΣAᵢTᵢ; what a
    centring firmware removes: :attr:`Shaper.centre_delay`); 0 without shaping."""
    active = [s for s in shapers.values() if s is not None]
    return max(((s.centre_delay if centred else s.centroid) for s in active), default=0.0)


def extruder_shift(shapers: dict[str, Shaper | None], centred: bool, firmware: Firmware,
                   timing: str) -> float:
    """s by which the planner's extruder is delayed on the simulated clock for ``timing`` other
    than ``shaped`` (negative: the extruder runs ahead).

    The simulated X/Y are delayed by 0 (``centred``) or by each axis's centroid (causal); the
    firmware delays its X/Y by 0 (``xy_delay`` ``centred``), by each axis's centroid (``causal``)
    or all by the largest centroid (``largest``, Marlin FT_MOTION's axis synchronisation); its
    extruder by that delay (``delayed``) or not at all (``neither``)."""
    lag = shaped_axes_lag(shapers, centred)
    sim_xy = 0.0 if centred else lag
    fw_xy = 0.0 if firmware.xy_delay == "centred" else lag
    e_delay = fw_xy if timing == "delayed" else 0.0
    return e_delay - (fw_xy - sim_xy)


def extruder_command(raw: Motion, shapers: dict[str, Shaper | None], centred: bool, firmware: Firmware,
                     timing: str | None = None) -> Motion:
    """The extruder as ``firmware`` commands it (one column, mm of filament) when the X/Y of
    ``raw`` are shaped by ``shape_motion(raw, shapers, centred)``; on that output's clock.

    ``timing``: one of :data:`E_TIMINGS` (default the firmware's own ``e_timing``). ``shaped``
    follows the shaped X/Y along the path: each move's filament is split by its direction into an
    X share (u_x²) and a Y share (u_y²), shaped with that axis's shaper (the same where the
    firmware has one shaper for all axes, as RepRapFirmware; Kalico's ``enabled_extruders``
    projects the shaped X/Y motion onto the extruder, which this is)."""
    timing = timing or firmware.e_timing
    if timing not in E_TIMINGS:
        raise ValueError(f"E timing must be one of {E_TIMINGS}, not {timing!r}")
    e = extruder_motion(raw)
    if not any(shapers.get(ax) is not None for ax in ("x", "y")):
        return e
    if timing == "shaped":
        both = shape_motion(_split_by_direction(raw), {"x": shapers.get("x"), "y": shapers.get("y")}, centred)
        return Motion(both.t, both.p.sum(axis=1), both.v.sum(axis=1), both.a.sum(axis=1), both.extruding, both.move)
    shift = extruder_shift(shapers, centred, firmware, timing)
    return e.shifted(shift) if shift else e


def _split_by_direction(raw: Motion) -> Motion:
    """Two-column motion (X share, Y share) of the extruder: each segment's filament times u_x² and
    u_y² (u its X/Y direction; a segment without X/Y motion counts as X), the X share starting at
    the extruder's position; their sum is the extruder."""
    xy = np.where(np.abs(raw.v[:, :2]).sum(axis=1, keepdims=True) > 0, raw.v[:, :2], raw.a[:, :2])
    norm = np.hypot(xy[:, 0], xy[:, 1])
    wx = np.where(norm > 0, (xy[:, 0] / np.maximum(norm, 1e-300)) ** 2, 1.0)
    w = np.stack([wx, 1.0 - wx], axis=1)
    dt = raw.dt[:, None]
    de = raw.v[:, 3:4] * dt + 0.5 * raw.a[:, 3:4] * dt * dt
    p = np.cumsum(np.concatenate([np.zeros((1, 2)), de * w]), axis=0)[:-1]
    p[:, 0] += raw.p[0, 3]
    return Motion(raw.t, p, raw.v[:, 3:4] * w, raw.a[:, 3:4] * w, raw.extruding, raw.move)


def firmware_trajectory(motion: Motion, config, rate: float) -> tuple[np.ndarray, np.ndarray]:
    """(t, [x, y, z, e]) sampled at ``rate`` Hz as ``config``'s firmware commands them: X/Y
    shaped by its shapers (centred or causal as the firmware applies them), E by the firmware's
    own timing (:func:`extruder_command`); ``config`` None: the planned motion as it is.
    Over the span of the shaped X/Y (the extruder holds its position outside its own)."""
    if config is None:
        return motion.sample(rate)
    shapers, centred = shapers_from_config(config)
    if not any(s is not None for s in shapers.values()):
        return motion.sample(rate)
    shaped = shape_motion(motion, shapers, centred)
    t, pos = shaped.sample(rate)
    e = extruder_command(motion, shapers, centred, FIRMWARES[config.firmware])
    pos = pos[:, :4].copy()
    pos[:, 3] = e.position(t)[:, 0]
    return t, pos


def sample_features(plan, config, t: np.ndarray) -> list[str]:
    """The feature label (as the job names it, e.g. ``External perimeter``, ``WALL-OUTER``;
    ``""`` outside any move) of the move the commanded X/Y of :func:`firmware_trajectory` are on at
    each time ``t`` (s): the planned move at ``t``, or at ``t`` minus the causal shapers' lag where
    the firmware delays X/Y by their centroid ΣAᵢTᵢ (time-centred shapers: no lag)."""
    lag = 0.0
    if config is not None:
        shapers, centred = shapers_from_config(config)
        lag = 0.0 if centred else shaped_axes_lag(shapers, centred)
    motion, moves = plan.motion, plan.moves
    tu = np.asarray(t, float) - lag
    move = motion.move[motion.segment_index(tu)]
    inside = (tu >= motion.t[0]) & (tu <= motion.t[-1]) & (move >= 0)
    labels = np.array(list(moves.features) + [""], dtype=object)
    idx = np.where(inside, moves.feature[np.clip(move, 0, None)], len(moves.features))
    return labels[idx].tolist()
