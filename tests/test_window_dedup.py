"""Windows that repeat another's motion are simulated once (envs/window_dedup.py).

The independent truth is the same computation with every window simulated and measured on its own:
the figures, every window's own and where each measure's worst is, must be the same (to the
rounding of the planner's absolute times), and the places of a repeated window must be its own.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import ringtune.envs.whole_job as whole_job
from ringtune.envs.planned_job import planned_job, resolve_printer
from ringtune.envs.window_dedup import distinct
from ringtune.envs.windows import auto_settle, corner_tail, window_runs
from ringtune.shaping.config import TuneConfig

PICK = TuneConfig(firmware="klipper", shaper_x="ei", shaper_y="mzv", freq_x=51.4, freq_y=46.6, damping_x=0.1,
                  damping_y=0.1, accel=4800.0, corner=5.0, min_cruise_ratio=0.5)
#: where the second square stands against the first, mm
OFFSET = (40.0, 25.0)


def _square(x0: float, y0: float, feed: float) -> str:
    """A travel to (x0, y0), then a 20 mm outer-wall square and a stroke of infill after it."""
    c = [(x0, y0), (x0 + 20, y0), (x0 + 20, y0 + 20), (x0, y0 + 20), (x0, y0)]
    walls = "\n".join(f"G1 X{x:g} Y{y:g} E{i + 1} F{feed:g}" for i, (x, y) in enumerate(c[1:]))
    return (f";TYPE:Travel\nG1 X{x0:g} Y{y0:g} F15000\n;TYPE:External perimeter\n{walls}\n"
            f";TYPE:Internal infill\nG1 X{x0 + 10:g} Y{y0 + 10:g} E6 F9000\nG92 E0\n")


def _job(tmp_path, last_feed: float) -> str:
    """Four squares, each ``OFFSET`` from the one before (so the travel into each but the first is the
    same), the last walled at ``last_feed`` mm/min, the others at 3000."""
    path = tmp_path / f"four_{last_feed:g}.gcode"
    path.write_text("G28\nG90\nM83\nG1 Z0.2 F600\nM82\n" + "".join(
        _square(20 + k * OFFSET[0], 20 + k * OFFSET[1], 3000 if k < 3 else last_feed) for k in range(4)))
    return str(path)


def _every_window_alone(monkeypatch) -> None:
    monkeypatch.setattr(whole_job, "distinct", lambda runs: (list(range(len(runs))), list(range(len(runs)))))


def _same(a, b, path: str = "") -> None:
    """``a`` and ``b`` (to_dict trees) equal, floats to 1e-6 relative (the planner's rounding of absolute times)."""
    if isinstance(a, dict):
        assert set(a) == set(b), path
        for k in a:
            _same(a[k], b[k], f"{path}/{k}")
    elif isinstance(a, list):
        assert len(a) == len(b), path
        for i, (u, v) in enumerate(zip(a, b)):
            _same(u, v, f"{path}[{i}]")
    elif isinstance(a, float):
        assert a == pytest.approx(b, rel=1e-6, abs=1e-7, nan_ok=True), path
    else:
        assert a == b, path


def test_a_square_repeated_elsewhere_is_simulated_once_and_measured_where_it_stands(tmp_path, monkeypatch):
    printer = resolve_printer(None)
    job = _job(tmp_path, 3000)
    pj = planned_job(printer, job, PICK)
    runs = window_runs(dataclasses.replace(pj, windows=whole_job.seam_windows(pj.plan)), PICK,
                       auto_settle(printer), corner_tail(printer))
    firsts, of = distinct(runs)
    # each square's entry and exit; every exit the same (its wall's end, then its infill); every
    # entry but the first (the travel from the square before)
    assert len(runs) == 8 and firsts == [0, 1, 2] and of == [0, 1, 2, 1, 2, 1, 2, 1]
    merged = whole_job.seam_metrics(PICK, printer, job).to_dict(details=True)
    _every_window_alone(monkeypatch)
    alone = whole_job.seam_metrics(PICK, printer, job).to_dict(details=True)
    _same(merged, alone)
    at = [w["details"]["outer_wall_at"]["corner_in_mm"] for w in merged["details"]["windows"]]
    windows = whole_job.seam_windows(pj.plan)
    for k in (4, 6):                                   # the third and fourth squares' entries, measured as the second's
        assert (at[k]["x"] - at[2]["x"], at[k]["y"] - at[2]["y"]) == pytest.approx(
            ((k // 2 - 1) * OFFSET[0], (k // 2 - 1) * OFFSET[1]))
        assert windows[k].t0 - 0.01 <= at[k]["t"] <= windows[k].t1 + 0.01
        x0, y0 = 20 + (k // 2) * OFFSET[0], 20 + (k // 2) * OFFSET[1]
        assert x0 - 0.1 <= at[k]["x"] <= x0 + 20.1 and y0 - 0.1 <= at[k]["y"] <= y0 + 20.1   # the nozzle, on its square


def test_a_square_printed_at_another_speed_is_simulated_on_its_own(tmp_path):
    printer = resolve_printer(None)
    pj = planned_job(printer, _job(tmp_path, 2400), PICK)
    runs = window_runs(dataclasses.replace(pj, windows=whole_job.seam_windows(pj.plan)), PICK,
                       auto_settle(printer), corner_tail(printer))
    firsts, of = distinct(runs)
    assert len(runs) == 8 and of[:6] == [0, 1, 2, 1, 2, 1] and of[6:] == [3, 4]     # the last square its own


@pytest.mark.slow
def test_the_parts_seams_are_the_same_figures_with_each_simulated_alone(monkeypatch):
    printer = resolve_printer(None)
    pj = planned_job(printer, "part", PICK)
    runs = window_runs(dataclasses.replace(pj, windows=whole_job.seam_windows(pj.plan)), PICK,
                       auto_settle(printer), corner_tail(printer))
    firsts, _of = distinct(runs)
    assert len(firsts) < 0.6 * len(runs)                 # its layers repeat: most seams are simulated once
    merged = whole_job.seam_metrics(PICK, printer, "part").to_dict(details=True)
    _every_window_alone(monkeypatch)
    alone = whole_job.seam_metrics(PICK, printer, "part").to_dict(details=True)
    assert np.isfinite(merged["corner_in_mm"]) and merged["corner_in_mm"] > 0
    _same(merged, alone)


def test_a_memo_measures_a_candidates_shared_windows_once_with_a_fresh_simulations_figures(monkeypatch):
    """The walk's candidates each change one feature group's moves: through a WindowMemo, the
    windows they share with the start (and with each other) on the same printer variant are not
    simulated again, and every figure, each window's and where it stands included, is what a fresh
    evaluation of each candidate alone gives (to the rounding the windows are compared at)."""
    import ringtune.envs.evaluate as evaluate
    from ringtune.envs.window_dedup import WindowMemo

    hidden = {"inner_wall": 4800.0, "infill": 4800.0, "support": 4800.0, "solid_infill": 4800.0, "travel": 4800.0}
    start = dataclasses.replace(PICK, feature_accel={"top_surface": 4800.0, **hidden})
    cands = [start, dataclasses.replace(start, feature_accel={**start.feature_accel, "infill": 12000.0, "support": 12000.0}),
             dataclasses.replace(start, feature_accel={**start.feature_accel, "travel": 10000.0}),
             dataclasses.replace(start, feature_corner={"infill": 30.0, "support": 30.0, "travel": 30.0})]
    fresh = [evaluate.evaluate_many([c], None, "part", freq_margin=0.05)[0] for c in cands]
    simulated = []
    real = evaluate._simulate_grouped
    monkeypatch.setattr(evaluate, "_simulate_grouped", lambda printers, motions, *a: (
        simulated.append(sum(map(len, motions))) or real(printers, motions, *a)))
    memo = WindowMemo()
    remembered = [evaluate.evaluate_many([c], None, "part", freq_margin=0.05, memo=memo)[0] for c in cands]
    for a, b in zip(fresh, remembered):
        _same(b.to_dict(details=True), a.to_dict(details=True))
    windows = len(fresh[0].details["variants"]) * len(evaluate.evaluate_variants([start], [resolve_printer(None)], "part",
                                                                               settle=0.1)[0][0].runs)
    assert simulated[0] == windows                        # the start: every window, on each variant
    assert all(0 < n < windows / 2 for n in simulated[1:]), (windows, simulated)   # a candidate: under half
    assert memo.hits > memo.misses / 2
    # on another printer nothing is taken from the memo: its own windows are simulated
    stiff = dataclasses.replace(resolve_printer(None), print_mass=0.2)
    evaluate.evaluate_many([start], stiff, "part", memo=memo)
    assert simulated[-1] == windows // 3
