"""How long each step of ``tune`` took: wall-clock seconds, for ``--json`` (``timings_s``) and the
benchmarks."""

from __future__ import annotations

import time


class Laps:
    """Wall-clock time of each step of ``tune`` (s): :meth:`lap` records the time since the last lap
    under a name; :meth:`parts` starts the laps of the steps inside one (the steps after the study,
    :func:`ringtune.agents.tune.refine.refine`)."""

    def __init__(self, start: float | None = None):
        self.last = time.time() if start is None else start
        self.times: dict[str, float] = {}
        self.inner: Laps | None = None

    def lap(self, name: str) -> None:
        now = time.time()
        self.times[name] = now - self.last
        self.last = now

    def parts(self) -> "Laps":
        """Laps from now, reported as ``refine_parts``."""
        self.inner = Laps()
        return self.inner

    def to_dict(self) -> dict:
        inner = self.inner.times if self.inner is not None else {}
        return {**{k: round(v, 3) for k, v in self.times.items()},
                "refine_parts": {k: round(v, 3) for k, v in inner.items()}}
