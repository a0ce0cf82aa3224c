"""evaluate / evaluate_many: batching, caching, determinism, and the physics behind the numbers."""

from __future__ import annotations

import pytest

import ringtune.envs.sim as sim
from ringtune.envs import evaluate as ev
from ringtune.envs.planned_job import planned_job
from ringtune.envs.windows import auto_settle
from ringtune.envs.printer import load_printer, printer_from_dict
from ringtune.shaping.config import TuneConfig

CONFIGS = [
    TuneConfig(shaper_x="none", shaper_y="none"),
    TuneConfig(shaper_x="mzv", shaper_y="ei", freq_x=45.0, freq_y=40.0),
    TuneConfig(firmware="rrf", shaper_x="zvd", shaper_y="zvd", freq_x=42.0, freq_y=42.0, freq_limit_hz=15.0),
    TuneConfig(shaper_x="zv", shaper_y="zv", freq_x=50.0, freq_y=50.0, accel=6000.0),
]


def test_evaluate_many_is_one_batch_and_equals_single_evaluations(monkeypatch):
    printer = load_printer(None)
    calls = []
    real = sim.simulate_batch

    def counting(*a, **k):
        calls.append(len(a[1]))
        return real(*a, **k)

    monkeypatch.setattr(ev, "simulate_batch", counting)    # the name evaluate calls (imported at its top)
    many = ev.evaluate_many(CONFIGS, printer, backend="lti")
    assert len(calls) == 1 and calls[0] == sum(len(planned_job(printer, None, c).windows) for c in CONFIGS)
    for cfg, m in zip(CONFIGS, many):
        one = ev.evaluate(cfg, printer, backend="lti")
        assert one.to_dict() == m.to_dict()  # deterministic and independent of batching


def test_plans_are_cached_per_limits_and_frequency_limit():
    printer = load_printer(None)
    a = planned_job(printer, None, CONFIGS[1])
    assert planned_job(printer, None, CONFIGS[0]) is a          # shaper changes share the plan
    limited = planned_job(printer, None, CONFIGS[2])
    faster = planned_job(printer, None, CONFIGS[3])
    assert limited is not a and faster is not a
    assert a.print_time > faster.print_time                         # higher accel
    # at 6000 mm/s² the zigzag's strokes reach speeds a 15 Hz limit cuts (at the printer's 3000
    # the built-in print's zigzag is acceleration-bound below 15 Hz already)
    fast_limited = planned_job(printer, None, TuneConfig(shaper_x="zv", shaper_y="zv", freq_x=50.0,
                                                            freq_y=50.0, accel=6000.0, freq_limit_hz=15.0))
    assert fast_limited.print_time > faster.print_time              # slower zigzags


def test_print_time_is_the_whole_job_and_quality_follows_the_physics():
    """Shaping at the true frequency of a one-mode printer removes most overshoot and ringing;
    shaping at half that frequency does much less; print time does not depend on the shaper."""
    printer = printer_from_dict({"name": "one-mode", "x": {"modes": [{"freq": 40.0, "damping": 0.05}]},
                                 "y": {"modes": [{"freq": 40.0, "damping": 0.05}]},
                                 "motor": {"slip": False}})   # one mode: no rotor stage
    off, on, wrong = ev.evaluate_many([
        TuneConfig(shaper_x="none", shaper_y="none"),
        TuneConfig(shaper_x="zvd", shaper_y="zvd", freq_x=40.0, freq_y=40.0, damping_x=0.05, damping_y=0.05),
        TuneConfig(shaper_x="zvd", shaper_y="zvd", freq_x=20.0, freq_y=20.0, damping_x=0.05, damping_y=0.05),
    ], printer, backend="lti")
    assert off.print_time_s == on.print_time_s == wrong.print_time_s
    assert on.print_time_s == pytest.approx(planned_job(printer, None, None).plan.print_time)
    assert on.overshoot_mm < 0.1 * off.overshoot_mm and on.ringing_mm < 0.1 * off.ringing_mm
    assert on.ripple_mm < 0.1 * off.ripple_mm and on.corner_out_mm < 0.1 * off.corner_out_mm
    assert wrong.ringing_mm > 3 * on.ringing_mm and wrong.ripple_mm > 3 * on.ripple_mm
    assert wrong.corner_in_mm > on.corner_in_mm > off.corner_in_mm   # a lower shaper rounds more
    assert on.peak_accel < off.peak_accel


def test_mujoco_and_exact_linear_backends_agree():
    cfg = CONFIGS[1]
    a = ev.evaluate(cfg, backend="lti")
    b = ev.evaluate(cfg, backend="mujoco", nthread=1)
    for key in ("path_error_mm", "overshoot_mm", "ringing_mm", "peak_accel"):
        assert getattr(b, key) == pytest.approx(getattr(a, key), rel=0.1, abs=1e-3)


def test_default_lead_in_is_long_enough():
    """With the automatic history before each window, a much longer history changes nothing
    that matters: the vibration left by earlier motion is simulated, not cut off."""
    printer = load_printer(None)
    assert 0.05 <= auto_settle(printer) <= 0.3
    cfg = TuneConfig(shaper_x="mzv", shaper_y="mzv", freq_x=45.0, freq_y=39.0)
    auto = ev.evaluate(cfg, printer, backend="lti")
    long = ev.evaluate(cfg, printer, backend="lti", settle=0.6)
    short = ev.evaluate(cfg, printer, backend="lti", settle=0.0)
    for key in ("path_error_mm", "overshoot_mm", "ringing_mm", "peak_accel", "ripple_mm", "corner_in_mm",
                "corner_out_mm", "show_through_mm", "extrusion_over_pct"):
        assert getattr(auto, key) == pytest.approx(getattr(long, key), rel=0.03), key
    # the built-in print's windows open on a quiet stretch (each starts before its corner or
    # zigzag), so even no history beyond the shaper's own duration changes little
    assert short.ripple_mm == pytest.approx(long.ripple_mm, rel=0.05)
