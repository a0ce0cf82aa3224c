"""The whole job simulated (envs/whole_job.py): cut only where nothing is printed, the same figures
however it is cut, and never below what its quality windows, parts of it, measure."""

from __future__ import annotations

import numpy as np
import pytest

from ringtune.envs.evaluate import evaluate_many
from ringtune.envs.planned_job import planned_job, resolve_printer
from ringtune.envs.whole_job import LONGEST, lead_in, span_edges, whole_job_metrics
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError

VISIBLE_KEYS = ("ripple_mm", "corner_in_mm", "corner_out_mm", "extrusion_over_pct", "extrusion_under_pct")


def test_the_part_is_cut_only_where_nothing_is_printed():
    motion = planned_job(resolve_printer(None), "part", TuneConfig()).motion
    edges = span_edges(motion, 60.0)
    assert edges[0] == motion.start_time and edges[-1] == motion.end_time
    assert np.all(np.diff(edges) > 0) and len(edges) > 10
    inner = edges[1:-1]
    seg = np.searchsorted(motion.t, inner, side="right") - 1
    assert not motion.extruding[seg].any()                  # each cut inside a non-extruding move
    assert np.all(np.diff(edges)[:-1] >= 30.0)              # at least half a span apart


def test_the_lead_in_is_six_time_constants_of_the_slowest_mode():
    printer = resolve_printer(None)
    rates = [m.damping * m.omega for ax in "xy" for m in printer.effective_modes(ax)]
    assert lead_in(printer) == pytest.approx(6.0 / min(rates))


@pytest.mark.parametrize("accel", [4800.0, 8000.0])
def test_the_figures_do_not_depend_on_where_the_job_is_cut(accel):
    """The built-in print in pieces of about 1 s and in one piece: the same figures within 0.5 %
    (what remains is where the 5 kHz samples fall on a wall's ripple and a bead's extrusion; the
    corners are read between samples: 3 % before)."""
    cfg = TuneConfig(accel=accel)
    pieces, whole = (whole_job_metrics(cfg, span=s) for s in (1.0, 100.0))
    for k in VISIBLE_KEYS:
        assert getattr(pieces, k) == pytest.approx(getattr(whole, k), rel=0.005), k


@pytest.mark.parametrize("cfg", [TuneConfig(), TuneConfig(shaper_x="none", shaper_y="none", freq_x=0.0, freq_y=0.0),
                                 TuneConfig(accel=8000.0)], ids=["pick", "unshaped", "fast"])
def test_the_whole_job_measures_at_least_what_its_windows_do(cfg):
    """The windows are parts of the job: over all of it no visible measure is lower (within the
    2 kHz windows' own sampling of ripple and extrusion, 1 %), and the print time is the same plan's."""
    windows = evaluate_many([cfg], None, None, "lti")[0]
    whole = whole_job_metrics(cfg)
    assert whole.print_time_s == windows.print_time_s
    for k in VISIBLE_KEYS:
        assert getattr(whole, k) >= 0.99 * getattr(windows, k), k


def test_a_span_that_is_not_positive_is_refused():
    with pytest.raises(RingtuneError, match="span"):
        whole_job_metrics(TuneConfig(), span=0.0)


def vase_job(path) -> str:
    """A square vase: 20 turns of 40 mm walls printed without a pause (about 36 s)."""
    lines = ["G28", "G90", "M83", "G1 Z0.2 F600", "G1 X80 Y80 F6000", ";TYPE:External perimeter"]
    z = 0.2
    for _turn in range(20):
        for x, y in ((120, 80), (120, 120), (80, 120), (80, 80)):
            z += 0.05
            lines.append(f"G1 X{x} Y{y} Z{z:.3f} E1.6 F6000")
    lines.append("G1 X60 Y60 F9000")
    path.write_text("\n".join(lines) + "\n")
    return str(path)


def test_printing_without_pause_is_cut_inside_a_straight_line_with_the_same_figures(tmp_path):
    """A job printed without pause is cut inside its printing once it runs past LONGEST spans (so a
    vase's pieces, and their memory, stay bounded), in the middle of a straight line; the figures
    are those of the job simulated in one piece (to 1e-4: the lead-in's e^-6 of history)."""
    job = vase_job(tmp_path / "vase.gcode")
    motion = planned_job(resolve_printer(None), job, TuneConfig()).motion
    edges = span_edges(motion, 3.0)
    inner = edges[1:-1]
    seg = np.searchsorted(motion.t, inner, side="right") - 1
    printing = motion.extruding[seg]
    assert printing.sum() >= 8 and not printing[-1]              # the last cut: the travel off the vase
    assert np.all(np.diff(edges) <= LONGEST * 3.0 + 1e-9)
    at, dt = seg[printing], np.diff(motion.t)[seg[printing]]
    assert np.all(np.abs(inner[printing] - 0.5 * (motion.t[at] + motion.t[at + 1])) < 1e-9) and np.all(dt > 0.2)
    assert len(span_edges(motion, 100.0)) == 2                          # one piece
    cut, whole = (whole_job_metrics(TuneConfig(), None, job, span=s) for s in (3.0, 100.0))
    for k in VISIBLE_KEYS:
        assert getattr(cut, k) == pytest.approx(getattr(whole, k), rel=1e-4), k
