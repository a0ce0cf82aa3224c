"""Real PrusaSlicer for the slicer round trip: slice ringtune's test part with profiles.

``.ci/run`` installs Debian's ``prusa-slicer`` (2.5) as root; it slices without a display
(``--export-gcode``). :func:`prusaslicer` skips the test, with the reason, when it is missing or does
not run.
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

PART = Path(__file__).resolve().parent / "data" / "part"
STL = PART / "ringtune_part.stl"
BASE = PART / "prusaslicer_base.ini"
#: where the shipped part is placed on the 220 × 220 mm bed (its centre, mm)
CENTRE = "110,110"


def prusaslicer() -> tuple[str, str]:
    """(executable, version "X.Y.Z") of PrusaSlicer, or skip the test saying why."""
    exe = shutil.which("prusa-slicer")
    if exe is None:
        pytest.skip("prusa-slicer is not installed (.ci/run installs Debian's prusa-slicer as root)")
    try:
        out = subprocess.run([exe, "--help"], capture_output=True, text=True, timeout=60).stdout
    except (OSError, subprocess.SubprocessError) as exc:
        pytest.skip(f"prusa-slicer does not run: {exc}")
    m = re.search(r"PrusaSlicer-(\d+\.\d+\.\d+)", out)
    if m is None:
        pytest.skip("prusa-slicer --help names no version")
    return exe, m.group(1)


def slice_part(out: Path, *profiles: Path) -> Path:
    """Slice the test part with the base profile and then ``profiles`` loaded on top; the G-code."""
    exe, _ = prusaslicer()
    loads = [a for p in (BASE, *profiles) for a in ("--load", str(p))]
    res = subprocess.run([exe, *loads, "--center", CENTRE, "--export-gcode", str(STL), "-o", str(out)],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0 and out.is_file(), res.stderr[-2000:]
    return out
