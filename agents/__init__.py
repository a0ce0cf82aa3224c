"""Who decides: the Optuna study, PPO, baselines (Klipper's rule, grid), reports, plots, the CLI.

Importing it (the ``ringtune`` command does, before anything imports numpy) sets numpy's OpenBLAS to
one thread unless the environment already says how many (``OPENBLAS_NUM_THREADS``): the matrices
here are small (a few modes against a window's samples), OpenBLAS's extra threads spin against the
study's workers and the forked checks, which already take every core. Measured on 2 cores: the
seams of two copies of the part for two configurations at once 4.5 → 2.2 s; the test suite 8 min 30 s
→ 7 min 47 s.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

__version__ = "0.1.0"
