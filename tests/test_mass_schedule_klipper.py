"""The schedule's lines against the real thing: Klipper 84104bb (session fixture ``real_klipper``,
tests/real_klipper.py). Truth is Klipper itself: every band's lines, as ``schedule -o`` writes them
(with their comment), answered ``ok``, no "Unknown command", no "!!", and Klipper's own
``SET_INPUT_SHAPER`` / ``SET_VELOCITY_LIMIT`` reports giving the last band's frequency and
acceleration."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

from ringtune.agents.tune.mass_schedule import mass_schedule  # noqa: E402
from ringtune.shaping.config import TuneConfig  # noqa: E402
from ringtune.shaping.solid_block import solid_block  # noqa: E402

pytestmark = [pytest.mark.timeout(600), pytest.mark.slow]


def test_klipper_takes_every_band_line_and_reports_the_last_band(real_klipper, tmp_path):
    path = tmp_path / "block.gcode"
    path.write_text(solid_block(size_mm=60.0, height_mm=90.0, layer_mm=0.6)[0])
    s = mass_schedule(TuneConfig(freq_x=45.5, freq_y=38.9, accel=3000), None, path)
    lines = [c for b in s.bands for c in b.commands]
    assert len(s.bands) > 5 and any(ln.startswith("SET_VELOCITY_LIMIT") for ln in lines)
    state = lambda: dict(re.findall(r"(\w+_[xy]|max_accel):\s*(\S+)",             # noqa: E731
                                    real_klipper.send("SET_INPUT_SHAPER", "SET_VELOCITY_LIMIT")))
    before = state()
    try:
        _check_bands(real_klipper, s, lines, state)
    finally:      # the Klipper fixture is shared by the session: leave it as it was found
        real_klipper.send(f"SET_VELOCITY_LIMIT ACCEL={before['max_accel']}",
                          "SET_INPUT_SHAPER " + " ".join(f"{k.upper()}={v}" for k, v in before.items()
                                                        if k.startswith(("shaper_freq", "damping_ratio"))))
    assert state() == before


def _check_bands(real_klipper, s, lines, state):
    transcript = real_klipper.send(*[f"{ln} ; ringtune mass schedule" for ln in lines])
    replies = [ln for ln in transcript.splitlines() if ln.startswith("< ")]
    assert len([r for r in replies if r == "< ok"]) == len(lines), transcript
    assert "Unknown command" not in transcript and "!!" not in transcript, transcript
    report = state()
    last = s.bands[-1]
    assert float(report["shaper_freq_y"]) == pytest.approx(last.freq_y)
    assert float(report["max_accel"]) == pytest.approx(last.accel)
