"""The measured stop (agents/tune/stop.py), with an evaluator whose verdicts are known in advance:
it climbs the acceleration in 5 % steps while nothing a person sees gets worse, names what stops
it, and sheds a frequency limit that only costs time — one the study's match carried, which slows
zigzags more the higher the acceleration climbs."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from ringtune.agents.tune.pareto import point_from_metrics
from ringtune.agents.tune.refine import declined_if_same_time
from ringtune.agents.tune.shaper_ladder import Ladder
from ringtune.agents.tune.space import default_space
from ringtune.agents.tune.stop import MIN_STEP_SAVING, Bounds, measured_stop, next_accels
from ringtune.envs.printer import load_printer
from ringtune.shaping.config import TuneConfig

RIPPLE_TOP = 7000.0         # mm/s²: above it the walls ripple more
LIMIT_COST = 0.01           # s per mm/s² above 5000 that a frequency limit adds (zigzags slowed)
BOUNDS = Bounds(max_path_error_mm=0.1, max_motor_load=0.8, max_show_through_mm=0.2)


def _metrics(cfg: TuneConfig):
    """Print time falls with the acceleration; a frequency limit costs LIMIT_COST per mm/s² above
    5000 and changes nothing seen; the ripple is worse above RIPPLE_TOP."""
    a = float(cfg.accel)
    t = 1000.0 + 1e6 / a + (LIMIT_COST * max(a - 5000.0, 0.0) if cfg.freq_limit_hz > 0 else 0.0)
    return SimpleNamespace(print_time_s=t, step_loss=False, path_error_mm=0.05, overshoot_mm=0.03, ringing_mm=0.01,
                           peak_accel=a, motor_load=0.5, ripple_mm=0.08 if a > RIPPLE_TOP else 0.05,
                           ripple_p90_mm=0.04, corner_in_mm=0.03, corner_out_mm=0.02, extrusion_over_pct=8.0,
                           extrusion_under_pct=8.0, e_lag_mm=0.05, show_through_mm=0.01)


@pytest.fixture(scope="module")
def space():
    return default_space(load_printer(None), "klipper")


def _stop(space, limit_hz: float):
    cfg = TuneConfig(shaper_x="mzv", shaper_y="mzv", freq_x=54.2, freq_y=42.7, damping_x=0.15, damping_y=0.15,
                     accel=5000.0, freq_limit_hz=limit_hz, freq_limit_method="nophead")
    start = point_from_metrics(cfg, _metrics(cfg), max_path_error_mm=0.1, max_motor_load=0.8, max_show_through_mm=0.2)
    return measured_stop(start, {"klipper": start}, lambda cs: [_metrics(c) for c in cs], space, BOUNDS,
                         labels={"klipper": "Klipper's rule"})


def _highest_step_within(space) -> float:
    """The 5 % ladder from 5000 mm/s², worked out here: its last rung within RIPPLE_TOP."""
    a, top = 5000.0, 5000.0
    while True:
        nxt = next_accels(a, space.accel[1], space.accel_step, n=1)
        if not nxt or nxt[0] > RIPPLE_TOP:
            return top
        a = top = nxt[0]


def test_the_stop_climbs_to_the_last_step_nothing_seen_gets_worse_and_names_the_ripple(space):
    stop = _stop(space, 0.0)
    assert stop.point.config.accel == _highest_step_within(space) and stop.kind == "measure"
    assert stop.key == "ripple_mm" and (stop.value, stop.base_value) == (0.08, 0.05)
    assert stop.accel > RIPPLE_TOP and "ripple 80.0 µm > 50.0 µm of Klipper's rule" in stop.sentence


def test_a_frequency_limit_that_only_costs_time_is_shed(space):
    """From a choice with a frequency limit: the same acceleration as without one, and no limit —
    at that acceleration the limit costs LIMIT_COST × (a − 5000) s and changes nothing seen."""
    stop = _stop(space, 18.0)
    top = _highest_step_within(space)
    assert stop.point.config.accel == top and stop.point.config.freq_limit_hz == 0.0
    assert stop.point.print_time_s == pytest.approx(1000.0 + 1e6 / top)


@pytest.mark.parametrize("c", [1e3, 1e6])
def test_a_step_that_buys_under_the_least_saving_is_not_taken(space, c):
    """A job whose print time is 1000 s + c/a: with c = 1e3 (its speeds bound it) the first 5 %
    step saves c/a·(1 − a/a′) ≈ 0.01 s, under MIN_STEP_SAVING (0.05 %, 0.5 s) of the print time, so
    the stop stays at 5000 mm/s² and says print time stops it; with c = 1e6 every step saves ~10 s
    and it climbs to the ripple's top as before."""
    def metrics(cfg):
        return SimpleNamespace(**{**vars(_metrics(cfg)), "print_time_s": 1000.0 + c / float(cfg.accel)})

    cfg = TuneConfig(shaper_x="mzv", shaper_y="mzv", freq_x=54.2, freq_y=42.7, accel=5000.0)
    start = point_from_metrics(cfg, metrics(cfg), max_path_error_mm=0.1, max_motor_load=0.8, max_show_through_mm=0.2)
    stop = measured_stop(start, {"klipper": start}, lambda cs: [metrics(x) for x in cs], space, BOUNDS,
                         labels={"klipper": "Klipper's rule"})
    nxt = next_accels(5000.0, space.accel[1], space.accel_step, n=1)[0]
    saving = c / 5000.0 - c / nxt
    if saving < MIN_STEP_SAVING * start.print_time_s:
        assert c == 1e3 and not stop.moved and stop.kind == "time" and stop.accel == nxt
        assert "print time falls by less than 0.05 %" in stop.sentence
    else:
        assert c == 1e6 and stop.point.config.accel == _highest_step_within(space) and stop.kind == "measure"


@pytest.mark.parametrize("c, taken", [(7e4, False), (1e6, True)])
def test_a_ladder_and_stop_that_end_no_faster_by_the_resolution_are_not_taken(space, c, taken):
    """A job whose print time is 1000 s + c/a. With c = 70 000 the 5 % steps from 5500 mm/s² save
    about c·0.05/a ≈ 0.5–0.6 s each, at least MIN_STEP_SAVING (0.05 %), so the stop climbs; but from
    the study's choice at 5000 the whole climb saves c·(1/5000 − 1/a_end) < 4 s, under the 0.5 %
    (5.07 s) the summary calls the same time: the study's choice stays, and the stop and the ladder
    (which had moved to 5500 mm/s²) keep where they ended as ``declined``. With c = 1e6 the climb
    saves ~57 s: taken."""
    def metrics(cfg):
        m = _metrics(cfg)
        m.print_time_s = 1000.0 + c / float(cfg.accel)
        m.motor_load = float(cfg.accel) / 10000.0
        return m

    def point(accel):
        cfg = TuneConfig(shaper_x="mzv", shaper_y="mzv", freq_x=54.2, freq_y=42.7, damping_x=0.15, damping_y=0.15,
                         accel=accel)
        return point_from_metrics(cfg, metrics(cfg), max_path_error_mm=0.1, max_motor_load=0.8,
                                  max_show_through_mm=0.2)

    before, rung = point(5000.0), point(5500.0)
    ladder = Ladder(rung, before, tried=[("mzv @ 54.2 Hz", 5500.0)], evaluations=1, offered=1, first_rung=5500.0)
    stop = measured_stop(rung, {"klipper": before}, lambda cs: [metrics(x) for x in cs], space, BOUNDS,
                         labels={"klipper": "Klipper's rule"})
    end = stop.point
    assert stop.moved and end.config.accel > 5500.0
    saved = before.print_time_s - end.print_time_s
    assert (saved < 0.005 * before.print_time_s) == (not taken)
    ladder2, stop2 = declined_if_same_time(before, ladder, stop)
    if taken:
        assert (ladder2, stop2) == (ladder, stop) and stop2.declined is None and ladder2.declined is None
        return
    assert stop2.point is before and not stop2.moved and stop2.declined is end and stop2.kind == "same time"
    assert ladder2.point is before and not ladder2.moved and ladder2.declined is rung
    assert stop2.sentence == (
        f"Not raised: the shaper ladder and the measured stop ended at {end.config.accel:.0f} mm/s² "
        f"({end.print_time_s:.3f} s from {before.print_time_s:.3f} s), a saving under the 0.5 % that counts as "
        f"faster, for motor load {end.config.accel / 100:.0f} % against 50 %: kept at 5000 mm/s², as the study chose. "
        + stop.sentence.replace("What stops it at", "What stopped the climb at"))
    assert f"What stopped the climb at {end.config.accel:.0f} mm/s²" in stop2.sentence
    assert "not taken" in ladder2.sentence() and "5500 mm/s²" in ladder2.sentence()
    d = stop2.to_dict()
    assert d["moved"] is False and d["declined_accel"] == end.config.accel
    assert d["declined_print_time_s"] == pytest.approx(end.print_time_s)
    assert ladder2.to_dict()["declined_config"]["accel"] == 5500.0
