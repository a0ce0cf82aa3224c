"""Built-in jobs by name, for ``--gcode NAME`` (and ``ringtune plan NAME``): G-code files shipped in
``ringtune.shaping.data``.

- ``part``: ringtune's test part (tests/data/part: straight 50 mm walls, a half-cylinder end, two
  holes, a shelf overhanging 8 mm; 60 × 28 × 20 mm) sliced once by PrusaSlicer 2.5 for the embedded
  Ender-3-class printer, features labelled; about 20 minutes as planned (SOURCES in tests/data/part).

A name here means the built-in job even when a file of that name exists in the working folder
(write ``./part`` for such a file).
"""

from __future__ import annotations

import os
from pathlib import Path

#: name -> file in shaping/data
BUILTIN_JOBS = {"part": "part.gcode"}
DATA = Path(__file__).resolve().parent / "data"


def job_path(job):
    """``job`` itself, unless it is the name of a built-in job (:data:`BUILTIN_JOBS`): then the
    path of that job's file (str)."""
    if isinstance(job, (str, os.PathLike)) and str(job) in BUILTIN_JOBS:
        return str(DATA / BUILTIN_JOBS[str(job)])
    return job
