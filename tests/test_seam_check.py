"""The seam check after the walk (agents/tune/seam_check.py) against the whole job simulated.

The first two layers of the part as CuraEngine slices it (inner walls printed just before the outer
wall, G0 hops between stretches of wall). The independent truth is the whole job simulated by the
exact linear model (envs/whole_job.py: every second, 5 kHz, six time constants of history), which
the check's seams-only simulation must agree with, and what it takes back must hold there.
"""

from __future__ import annotations

from dataclasses import replace

import pytest

from ringtune.agents.tune.pareto import Point, metrics_dict
from ringtune.agents.tune.seam_check import check_seams, seam_failure, taken_back
from ringtune.agents.tune.stop import Bounds, evaluated
from ringtune.envs.evaluate import evaluate_many
from ringtune.envs.metrics import Metrics
from ringtune.envs.planned_job import resolve_printer
from ringtune.envs.whole_job import whole_job_metrics
from ringtune.shaping.config import TuneConfig

PICK = TuneConfig(firmware="klipper", shaper_x="ei", shaper_y="mzv", freq_x=51.4, freq_y=46.6, damping_x=0.1,
                  damping_y=0.1, accel=4800.0, corner=5.0, min_cruise_ratio=0.5)
START = replace(PICK, feature_accel={"top_surface": 4800.0, "inner_wall": 4800.0, "infill": 4800.0,
                                     "support": 4800.0})
WALKED = replace(START, feature_accel={**START.feature_accel, "infill": 12400.0, "support": 12400.0,
                                       "travel": 10800.0},
                 feature_corner={"infill": 30.0, "support": 30.0, "travel": 30.0},
                 feature_min_cruise_ratio={"infill": 0.0, "support": 0.0, "travel": 0.0})


def test_what_meets_the_seams_is_taken_back_alone_then_all_together():
    steps = taken_back(replace(WALKED, feature_accel={**WALKED.feature_accel, "inner_wall": 6000.0}), START)
    words = [w for w, _c in steps]
    assert words == ["travel's acceleration", "travel's corner rule", "the inner walls' acceleration",
                     "travel's acceleration, travel's corner rule, the inner walls' acceleration", "the walk"]
    accel, corner, inner, together, last = (c for _w, c in steps)
    assert "travel" not in accel.feature_accel and accel.feature_corner == WALKED.feature_corner
    assert accel.feature_accel["inner_wall"] == 6000.0 and accel.feature_accel["infill"] == 12400.0
    assert corner.feature_accel["travel"] == 10800.0 and corner.feature_corner == {"infill": 30.0, "support": 30.0}
    assert corner.feature_min_cruise_ratio == {"infill": 0.0, "support": 0.0}
    assert inner.feature_accel == {**WALKED.feature_accel, "inner_wall": 4800.0}
    assert together.feature_accel == {**START.feature_accel, "infill": 12400.0, "support": 12400.0}
    assert together.feature_corner == {"infill": 30.0, "support": 30.0}
    assert last == START
    assert [w for w, _c in taken_back(START, START)] == ["the walk"]


def test_a_seam_measure_is_worse_only_beyond_the_resolution():
    base = Metrics(print_time_s=1.0, corner_out_mm=0.030)
    base.features = {"outer_wall": {"corner_out_mm": 0.0298}}
    same = Metrics(print_time_s=1.0, corner_out_mm=0.031)            # within 1 µm / 5 %
    same.features = {"outer_wall": {"corner_out_mm": 0.0310}}
    assert seam_failure(same, base) is None
    worse = Metrics(print_time_s=1.0, corner_out_mm=0.031)
    worse.features = {"outer_wall": {"corner_out_mm": 0.0400}}
    why = seam_failure(worse, base)
    assert (why.kind, why.key, why.value, why.limit) == ("measure", "outer_wall:corner_out_mm", 0.04, 0.0298)


@pytest.mark.slow
def test_the_check_finds_what_the_whole_job_shows_and_takes_back_what_holds_there(data_dir, tmp_path):
    """Inner walls raised to 12,000 mm/s² besides: printed just before the outer wall, they make the
    seams worse; taken back alone, the travel and infill raises stay."""
    lines = (data_dir / "part" / "part_cura.gcode").read_text().splitlines(keepends=True)
    job = str(tmp_path / "two_layers.gcode")
    (tmp_path / "two_layers.gcode").write_text("".join(lines[:lines.index(";LAYER:2\n")]))
    printer = resolve_printer(None)
    walked = replace(WALKED, feature_accel={**WALKED.feature_accel, "inner_wall": 12000.0})
    whole_start, whole_walked = (whole_job_metrics(c, printer, job) for c in (START, walked))
    assert seam_failure(whole_walked, whole_start) is not None          # the whole job: something seen is worse

    def evaluate(configs):
        return evaluate_many(configs, printer, job)

    bounds = Bounds()
    start, end = evaluated([START, walked], evaluate, bounds, "")
    check = check_seams(start, end, {"choice": start}, evaluate, bounds, printer, job)
    assert check.failure is not None and isinstance(check.point, Point)
    assert check.taken_back == ["the inner walls' acceleration"]
    kept = check.point.config
    assert kept.feature_accel["travel"] == 10800.0 and kept.feature_accel["infill"] == 12400.0
    # what it kept holds over the whole job too, and is faster than the start
    assert seam_failure(whole_job_metrics(kept, printer, job), whole_start) is None
    assert check.point.print_time_s < start.print_time_s
    assert "Every seam of what a person sees" in check.sentence() and "back as before the walk" in check.sentence()
    # the outer wall's worst over the seams, said beside the quality windows': the seams are part of
    # the whole job, so no seam is worse than the whole job's worst (within the history each is
    # simulated with), and the windows' figure is what the walk's end was judged by
    whole = metrics_dict(whole_walked)
    assert set(check.worst) == {"outer_wall:ripple_mm", "outer_wall:corner_in_mm", "outer_wall:corner_out_mm"}
    for key, got in check.worst.items():
        assert got["walk_end"] <= whole[key] * 1.05 + 0.001, key
        assert got["windows"] == end.metrics[key]
    ripple = check.worst["outer_wall:ripple_mm"]
    assert "The outer wall, worst over those seams" in check.sentence()
    assert f"ripple {ripple['walk_end'] * 1000:.1f} / {ripple['walk_start'] * 1000:.1f} / " in check.sentence()
    assert check.to_dict()["outer_wall_worst_mm"] == check.worst
