"""evaluate() honours every knob of a TuneConfig: acceleration over the job's own M204, and DAA."""

from __future__ import annotations

import ringtune.envs.planned_job as pjm
from ringtune.envs.evaluate import evaluate
from ringtune.envs.planned_job import clear_cache, planned_job, resolve_printer
from ringtune.shaping import planner
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.gcode import read_gcode

GCODE = """\
M204 S500
G1 X0 Y0 F6000
G1 X40 Y0 E1 F6000
G1 X40 Y40 E2
G1 X0 Y40 E3
G1 X0 Y0 E4
"""


def test_config_accel_overrides_the_jobs_own_m204():
    clear_cache()
    printer = resolve_printer(None)
    own = evaluate(TuneConfig(shaper_x="none", shaper_y="none"), printer, GCODE, backend="lti")
    fast = evaluate(TuneConfig(shaper_x="none", shaper_y="none", accel=3000.0), printer, GCODE,
                    backend="lti")
    expected = planner.plan(read_gcode(GCODE), printer.limits, accel=3000.0).print_time
    assert fast.print_time_s == expected
    assert fast.print_time_s < own.print_time_s  # M204 S500 no longer rules


def test_daa_is_planned_not_shaped():
    """RRF ≤ 3.3's DAA retimes acceleration phases in the planner: the job gets slower, and the
    ringing it leaves is lower than with no compensation at all, window by window: where it changes
    the motion the wall rings less, and nowhere more. (The job's worst window may be one DAA leaves
    alone, a corner taken at the jerk speed with no acceleration phase to retime.)"""
    clear_cache()
    printer = resolve_printer(None)
    freq = printer.effective_modes("x")[0].freq
    none = TuneConfig(firmware="rrf", shaper_x="none", shaper_y="none")
    daa = TuneConfig(firmware="rrf", shaper_x="daa", shaper_y="daa", freq_x=freq, freq_y=freq)
    m_none, m_daa = evaluate(none, printer, backend="lti"), evaluate(daa, printer, backend="lti")
    pj = planned_job(printer, None, daa)
    assert pj.plan.print_time == m_daa.print_time_s
    assert m_daa.print_time_s > m_none.print_time_s
    ring_none, ring_daa = ([w["ringing_mm"] for w in m.details["windows"]] for m in (m_none, m_daa))
    assert len(ring_none) == len(ring_daa) >= 4
    assert all(d <= n + 1e-9 for d, n in zip(ring_daa, ring_none))
    assert sum(d < 0.9 * n for d, n in zip(ring_daa, ring_none)) >= 2
    assert m_daa.ringing_mm <= m_none.ringing_mm + 1e-9


def test_the_plan_cache_holds_a_bounded_number_of_bytes(monkeypatch):
    """A plan of a long job is tens of MB: the cache of planned jobs keeps the newest within its byte
    budget (a 1.5-hour job's tune held 3 GB with a count alone), and what it keeps is reused."""
    clear_cache()
    printer = resolve_printer(None)
    first = planned_job(printer, "part", TuneConfig(accel=3000.0))
    size = pjm._nbytes(first)
    motion = first.plan.motion
    assert size >= sum(getattr(motion, k).nbytes for k in ("t", "p", "v", "a")) > 1_000_000
    monkeypatch.setattr(pjm, "_CACHE_BYTES", int(2.5 * size))
    plans = [first] + [planned_job(printer, "part", TuneConfig(accel=a)) for a in (3100.0, 3200.0, 3300.0)]
    held = [v for v in pjm._PLANS.values() if pjm._nbytes(v)]
    assert held == plans[-2:]                       # two plans fit in 2.5 plans' bytes: the newest two
    assert planned_job(printer, "part", TuneConfig(accel=3300.0)) is plans[-1]
    assert planned_job(printer, "part", TuneConfig(accel=3000.0)) is not first
    clear_cache()
