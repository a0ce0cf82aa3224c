"""The summary's front table reads at a glance: what every trial of a per-feature study shares (the
study samples the shapers and the visible walls' acceleration; the rest is the same on every trial)
is said once above the table, and only a row that sets otherwise (the walk's choice) says its own."""

from __future__ import annotations

from ringtune.agents.tune.pareto import Point
from ringtune.agents.tune.report import describe, front_table
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.feature_settings import per_feature_text, per_feature_words


def _point(accel: float, t: float, **kw) -> Point:
    cfg = TuneConfig(shaper_x="mzv", shaper_y="ei", freq_x=50.0, freq_y=40.0, accel=accel, corner=8.0,
                     min_cruise_ratio=0.5, feature_corner={"infill": 8.0, "travel": 8.0},
                     feature_min_cruise_ratio={"infill": 0.5, "travel": 0.5}, **kw)
    return Point(cfg, t, 1e-5, metrics={"ripple_mm": 1e-5})


def test_what_every_row_shares_per_feature_is_said_once_and_a_row_that_differs_says_its_own():
    rows = [_point(6000.0, 90.0), _point(5000.0, 91.0), _point(4000.0, 92.0)]
    walked = _point(4000.0, 85.0, feature_accel={"infill": 12000.0, "travel": 15000.0})
    text = front_table([walked, *rows], walked, "ripple_mm").splitlines()
    shared = per_feature_words(rows[0].config)
    assert shared and shared != per_feature_words(walked.config)
    assert per_feature_text(rows[0].config) == f" ({shared})"
    assert text[0] == f"  per feature, unless a row says otherwise: {shared}"
    body = text[2:]
    assert len(body) == 4 and sum(f"({shared})" in line for line in text) == 0
    assert body[0].startswith("  * ") and body[0].endswith(describe(walked.config))      # its own, whole
    for line, p in zip(body[1:], rows):
        assert line.endswith(describe(p.config, per_feature=False)) and "corner" not in line


def test_a_table_without_per_feature_settings_or_with_all_different_has_no_shared_line():
    plain = [Point(TuneConfig(accel=a), 90.0 + i, 1e-5, metrics={"ripple_mm": 1e-5})
             for i, a in enumerate((6000.0, 5000.0))]
    text = front_table(plain, plain[0], "ripple_mm").splitlines()
    assert "time s" in text[0] and len(text) == 3
    apart = [_point(4000.0, 85.0, feature_accel={"infill": a}) for a in (9000.0, 12000.0)]
    text = front_table(apart, apart[0], "ripple_mm").splitlines()
    assert "time s" in text[0] and all(line.endswith(describe(p.config)) for line, p in zip(text[1:], apart))
