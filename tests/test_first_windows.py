"""A batch screened on a few windows first (agents/tune/first_windows.py) gives the verdicts of the
screen on every window, checked against that screen on real simulations of the built-in print."""

from __future__ import annotations

import dataclasses

import pytest

from ringtune.agents.tune.first_windows import PROBES, fails_anyway, nearness, ranked_windows, staged_failures
from ringtune.agents.tune.pareto import DEFAULT_RESOLUTION
from ringtune.agents.tune.stop import Bounds, evaluated, screen_failures
from ringtune.envs.evaluate import evaluate_many
from ringtune.envs.printer import load_printer
from ringtune.shaping.config import TuneConfig

BOUNDS = Bounds(max_path_error_mm=0.1, max_motor_load=0.8, max_show_through_mm=0.2)
#: the baseline: mzv at the default printer's resonances, 5000 mm/s²
BASE = TuneConfig(shaper_x="mzv", freq_x=45.5, shaper_y="mzv", freq_y=38.9, accel=5000.0)
#: candidates as the shaper ladder makes them: other shapers and frequencies, higher accelerations
#: (most worse than the baseline somewhere), and the baseline's own shaper lower (no worse)
CANDIDATES = [dataclasses.replace(BASE, shaper_x=s, shaper_y=s, freq_x=round(45.5 * k, 1), freq_y=round(38.9 * k, 1),
                                  accel=a)
              for s, k, a in [("zv", 1.0, 5500.0), ("ei", 1.1, 6000.0), ("mzv", 1.0, 4000.0), ("zvd", 1.2, 5500.0),
                              ("2hump_ei", 1.0, 7000.0), ("mzv", 1.16, 6000.0), ("ei", 1.0, 5000.0),
                              ("mzv", 1.0, 3000.0), ("zv", 1.24, 7000.0), ("mzv", 1.08, 5500.0),
                              ("3hump_ei", 1.2, 6000.0), ("zvd", 1.0, 4500.0)]]


class Screen:
    """The exact model's screen, counting the windows it simulates."""

    def __init__(self):
        self.windows = 0

    def __call__(self, configs):
        out = evaluate_many(configs, load_printer(None), None, freq_margin=0.0)
        self.windows += sum(len(m.details["windows"]) for m in out)
        return out

    def on_windows(self, configs, windows):
        self.windows += len(configs) * len(windows)
        return evaluate_many(configs, load_printer(None), None, freq_margin=0.0, windows=windows)


@pytest.fixture(scope="module")
def held():
    """(bases, the point to beat: the baseline itself made very slow, so only measures decide)."""
    base = evaluated([BASE], Screen(), BOUNDS, "")[0]
    return {"klipper": base}, dataclasses.replace(base, print_time_s=1e9)


def test_staged_verdicts_are_the_screens_on_every_window(held):
    """Same pass or fail per candidate as the screen on every window, the passing ones screened on
    every window; the failing ones found on fewer windows, and, where the probes pass, the batch
    screened on every window at once."""
    bases, beat = held
    full, staged = Screen(), Screen()
    want = screen_failures(CANDIDATES, full, bases, beat, BOUNDS, DEFAULT_RESOLUTION)
    got = staged_failures(CANDIDATES, staged, bases, beat, BOUNDS, DEFAULT_RESOLUTION)
    assert [f is None for f in got] == [f is None for f in want]
    assert 0 < sum(f is None for f in want) < len(want) - PROBES     # some pass, most fail
    assert staged.windows < full.windows
    passers = [c for c, f in zip(CANDIDATES, want) if f is None]     # probes that pass: no stages
    again = Screen()
    order = passers + [c for c in CANDIDATES if c not in passers]
    assert [f is None for f in staged_failures(order, again, bases, beat, BOUNDS, DEFAULT_RESOLUTION)] == \
        [f is None for f in screen_failures(order, Screen(), bases, beat, BOUNDS, DEFAULT_RESOLUTION)]
    assert again.windows == full.windows


def test_what_fails_on_one_window_fails_on_the_job(held):
    """Each candidate on each window alone: where it fails there (the 90th percentiles left out),
    it fails on the whole job, and there alone its nearness to failing is above 1; the windows
    ranked from the probes are every window, those where a probe fails first."""
    bases, beat = held
    screen = Screen()
    metrics = screen(CANDIDATES)
    whole = screen_failures(CANDIDATES, lambda _cs: metrics, bases, beat, BOUNDS, DEFAULT_RESOLUTION)
    n = len(metrics[0].details["windows"])
    alone = [evaluated(CANDIDATES, lambda cs: screen.on_windows(cs, [w]), BOUNDS, "") for w in range(n)]
    failing = {(w, i) for w in range(n) for i, p in enumerate(alone[w])
               if fails_anyway(p, bases, beat, BOUNDS, DEFAULT_RESOLUTION) is not None}
    assert failing and all(whole[i] is not None for _w, i in failing)
    near = {(w, i) for w in range(n) for i, p in enumerate(alone[w])
            if nearness(p, bases, BOUNDS, DEFAULT_RESOLUTION) > 1.0}
    assert near == failing
    ranked = ranked_windows(CANDIDATES[:PROBES], metrics[:PROBES], bases, BOUNDS, DEFAULT_RESOLUTION)
    probes_fail = {w for w, i in failing if i < PROBES}
    assert sorted(ranked) == list(range(n)) and set(ranked[:len(probes_fail)]) == probes_fail


def test_a_subset_of_windows_gives_those_windows_figures():
    """evaluate_many(windows=...) simulates only those windows: each alone has the figures the
    whole evaluation gives it (the same bits), and two together the larger of each figure."""
    cfg = CANDIDATES[1]
    whole = evaluate_many([cfg], load_printer(None), None)[0].details["windows"]
    for i in (0, len(whole) - 1):
        alone = evaluate_many([cfg], load_printer(None), None, windows=[i])[0].details["windows"]
        assert len(alone) == 1
        assert {k: v for k, v in alone[0].items() if k != "print_time_s"} == \
            {k: v for k, v in whole[i].items() if k != "print_time_s"}
    both = evaluate_many([cfg], load_printer(None), None, windows=[0, len(whole) - 1])[0]
    for k in ("ripple_mm", "corner_in_mm", "corner_out_mm", "extrusion_under_pct", "path_error_mm"):
        assert getattr(both, k) == max(whole[0][k], whole[-1][k])
