"""A cheap, deterministic stand-in for envs.evaluate used by the study-machinery tests.

It keeps the physics out of tests about storage, resume, workers and reproducibility. Print time
falls with acceleration and rises with a frequency limit; overshoot is Klipper's residual
vibration of each axis's shaper on that axis's modes, scaled by the static deflection a/ω² of the
acceleration; more than 6000 mm/s² loses steps. ``RINGTUNE_TEST_SLEEP`` (s) slows each call so that
a test can interrupt a run mid-trial; ``RINGTUNE_TEST_HANG_AT=k`` makes the k-th call of a process
touch the file ``RINGTUNE_TEST_HANG_FILE`` and then hang (a certain mid-trial interruption);
``RINGTUNE_TEST_SLOW_PARITY=0|1`` makes a process whose id has that parity sleep 0.03 s on every
call (of two workers started together, one: a test shifts which one lags behind).
"""

from __future__ import annotations

import math
import os
import time
from types import SimpleNamespace

import numpy as np

_CALLS = [0]
MODES = {"x": [(45.5, 0.069, 0.41), (58.1, 0.112, 0.59)], "y": [(38.9, 0.127, 0.725), (51.3, 0.108, 0.275)]}


def evaluate(configs, printer=None, job=None, **kw):
    from ringtune.shaping.analysis import residual_vibration
    from ringtune.shaping.shapers import get_shaper

    delay = float(os.environ.get("RINGTUNE_TEST_SLEEP", "0") or 0)
    hang_at = int(os.environ.get("RINGTUNE_TEST_HANG_AT", "0") or 0)
    out = []
    for c in configs:
        _CALLS[0] += 1
        if hang_at and _CALLS[0] == hang_at:
            with open(os.environ["RINGTUNE_TEST_HANG_FILE"], "w") as f:
                f.write(str(os.getpid()))
            while True:
                time.sleep(0.05)
        if delay:
            time.sleep(delay)
        parity = os.environ.get("RINGTUNE_TEST_SLOW_PARITY", "")
        if parity and os.getpid() % 2 == int(parity):
            time.sleep(0.03)
        a = float(c.accel or 3000.0)
        t = 60.0 + 40.0 * math.sqrt(1000.0 / a)
        if c.freq_limit_hz > 0:
            t += 200.0 / c.freq_limit_hz
        over = 0.0
        for ax in ("x", "y"):
            name, f, z = c.axis(ax)
            for fm, zm, share in MODES[ax]:
                if name == "none":
                    r = 1.0
                else:
                    s = get_shaper(name, f, z, flavor=c.flavor)
                    r = float(residual_vibration(s, np.array([fm]), zm)[0])
                    t += 0.002 * s.duration * 1000.0
                over += share * r * a / (2 * math.pi * fm) ** 2
        out.append(SimpleNamespace(print_time_s=t, path_error_mm=over * 1.3, overshoot_mm=over, ringing_mm=over / 2,
                                   peak_accel=a, step_loss=a > 6000.0))
    return out
