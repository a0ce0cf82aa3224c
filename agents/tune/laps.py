"""How long each step of ``tune`` took: wall-clock seconds, for ``--json`` (``timings_s``) and the
benchmarks."""

from __future__ import annotations

import time


class Laps:
    """Wall-clock time of each step of ``tune`` (s): :meth:`lap` records the time since the last lap
    under a name; ``parts``: the steps after the study, filled by
    :func:`ringtune.agents.tune.refine.refine`."""

    def __init__(self, start: float):
        self.last = start
        self.times: dict[str, float] = {}
        self.parts: dict[str, float] = {}

    def lap(self, name: str) -> None:
        now = time.time()
        self.times[name] = now - self.last
        self.last = now

    def to_dict(self) -> dict:
        return {**{k: round(v, 3) for k, v in self.times.items()},
                "refine_parts": {k: round(v, 3) for k, v in self.parts.items()}}
