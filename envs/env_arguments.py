"""The checks of :class:`ringtune.envs.env.TuneEnv`'s arguments: the shapers it chooses among, the
anchors of its F and acceleration entries, a dictionary over its defaults (reward weights,
judgement) and the starting action; every refusal is one line naming the argument."""

from __future__ import annotations

import numpy as np

from ringtune.envs.actions import ActionSpec
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.shapers import available_shapers


def checked_shapers(firmware: str, shapers) -> tuple[str, ...]:
    """The shapers the policy chooses from: ``shapers`` (default: every one the firmware offers but
    custom), refused when the firmware lacks one."""
    flavor = TuneConfig(firmware=firmware, shaper_x="none", shaper_y="none").flavor
    have = [s for s in available_shapers(flavor) if s != "custom"]
    shapers = tuple(have) if shapers is None else tuple(shapers)
    bad = [s for s in shapers if s not in have]
    if bad:
        raise RingtuneError(f"{firmware} offers no {', '.join(bad)} (available: {', '.join(have)})", "shapers")
    return shapers


def check_anchors(freq_anchor: str, accel_anchor: str, metrics_of_start: bool) -> None:
    """Refuse an unknown anchor, or the model anchor without a simulated start (tune_accel and
    observe_metrics) to take it from."""
    if freq_anchor not in ("absolute", "peak"):
        raise RingtuneError(f"must be 'absolute' or 'peak', not {freq_anchor!r}", "freq_anchor")
    if accel_anchor not in ("absolute", "model"):
        raise RingtuneError(f"must be 'absolute' or 'model', not {accel_anchor!r}", "accel_anchor")
    if accel_anchor == "model" and not metrics_of_start:
        raise RingtuneError("'model' needs tune_accel and observe_metrics (the anchor comes from the "
                            "starting configuration's metrics)", "accel_anchor")


def over_defaults(given: dict | None, defaults: dict, what: str, where: str) -> dict:
    """``defaults`` with ``given``'s values over them; a key ``defaults`` lacks is refused."""
    merged = {**defaults, **(given or {})}
    unknown = sorted(set(merged) - set(defaults))
    if unknown:
        raise RingtuneError(f"unknown {what} {unknown}; known: {sorted(defaults)}", where)
    return merged


def checked_start_action(start_action, spec: ActionSpec) -> np.ndarray:
    """The starting action clipped to [-1, 1], one entry per action of ``spec``."""
    action = np.clip(np.asarray(start_action, dtype=np.float32).ravel(), -1.0, 1.0)
    if action.shape != (spec.size,):
        raise RingtuneError(f"must have {spec.size} entries ({', '.join(spec.labels())}), "
                            f"not {np.size(start_action)}", "start_action")
    return action
