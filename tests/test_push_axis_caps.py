"""The acceleration a push claims is the one the printer runs: the per-axis caps the tuned
configuration was planned with are set before the acceleration (Marlin: ``M201 X Y`` before
``M204 P``; every move planned after M201 obeys it, planner.cpp's ``LIMIT_ACCEL``) and read back;
a configuration without them is not claimed as applied where the printer's own caps hold it lower.

The fake Marlin enforces M201 as Marlin's planner does (``tests/fake_printer.py``,
``MarlinCore.move_accel``) and starts with an Ender-3 V2's ``M201 X500 Y500``."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fake_printer import FakePrinter  # noqa: E402

from ringtune.hardware.dialects import export_config  # noqa: E402
from ringtune.hardware.push import push  # noqa: E402
from ringtune.hardware.push_status import APPLIED, NOT_APPLIED  # noqa: E402
from ringtune.shaping.config import TuneConfig  # noqa: E402

pytestmark = pytest.mark.timeout(60)

TUNED = dict(firmware="marlin", shaper_x="zv", shaper_y="zv", freq_x=45.5, freq_y=41.0, damping_x=0.07,
             damping_y=0.1, accel=5500.0)
MOVES = [(60.0, 0.0, 0.0), (0.0, 60.0, 0.0), (40.0, 40.0, 0.0), (50.0, 20.0, 2.0)]   # X, Y, diagonal, print


def test_an_exported_marlin_config_runs_at_the_tuned_acceleration_on_a_printer_enforcing_m201():
    cfg = TuneConfig(**TUNED, max_accel_x=5500.0, max_accel_y=5500.0)
    exp = export_config(cfg)
    assert exp.lines.index("M201 X5500 Y5500") < exp.lines.index("M204 P5500 T5500")
    assert {"M201", "M204"} <= set(exp.readback)
    with FakePrinter("marlin", transport="tcp") as fp:
        before = [fp.core.move_accel(*m) for m in MOVES]
        r = push(cfg, port=fp.url, timeout=2.0)
    assert before[0] == before[1] == 500.0           # the printer as it was: M201 held X and Y at 500
    status = {s.key: (s.status, s.reported) for s in r.settings}
    assert status["accel"] == (APPLIED, 5500.0) and status["travel_accel"] == (APPLIED, 5500.0)
    assert status["max_accel_x"] == (APPLIED, 5500.0) and status["max_accel_y"] == (APPLIED, 5500.0)
    assert r.ok
    # what the printer now does with each kind of move: the tuned acceleration
    for move in MOVES:
        assert fp.core.move_accel(*move) == 5500.0, move


def test_without_its_caps_the_acceleration_is_not_claimed_where_m201_holds_it_lower():
    cfg = TuneConfig(**TUNED)
    with FakePrinter("marlin", transport="tcp") as fp:
        r = push(cfg, port=fp.url, timeout=2.0)
        runs = fp.core.move_accel(60.0, 0.0)
    st = next(s for s in r.settings if s.key == "accel")
    assert runs == 500.0                                      # the fake printer's truth
    assert st.status == NOT_APPLIED and not r.ok
    assert "X 500, Y 500" in st.detail and "M201 X5500 Y5500" in st.detail
    assert "M201" in fp.executed                              # read back, not guessed


def test_rrf_sets_and_reads_back_its_m201_caps():
    cfg = TuneConfig(firmware="rrf", shaper_x="zvd", shaper_y="zvd", freq_x=40.0, freq_y=40.0, accel=6000.0,
                     max_accel_x=6000.0, max_accel_y=4500.0)
    with FakePrinter("rrf", transport="tcp") as fp:
        r = push(cfg, port=fp.url, timeout=2.0)
    assert r.ok and fp.core.max_accel["X"] == 6000.0 and fp.core.max_accel["Y"] == 4500.0
    assert {s.key: s.status for s in r.settings}["max_accel_y"] == APPLIED
    assert "M201 X6000 Y4500" in export_config(cfg).render_config()


def test_each_trial_carries_the_caps_its_firmware_would_run(tmp_path):
    """Marlin's M201 X/Y (set by G-code) are raised to the trial's acceleration; Kalico's
    max_x_accel/max_y_accel (the owner's, in printer.cfg) are kept as they are; a printer with no
    X/Y caps gives configurations without them."""
    from ringtune.agents.tune.space import config_from_params, default_space
    from ringtune.envs.printer import load_printer, printer_from_dict
    from ringtune.hardware.klipper_config import printer_facts_from_klipper

    modes = {"x": {"modes": [{"freq": 45.0, "damping": 0.07}]}, "y": {"modes": [{"freq": 38.0, "damping": 0.07}]}}
    marlin = printer_from_dict({"limits": {"accel": 500, "junction": "jd", "max_accel": [500, 500, 100, 5000]},
                                **modes})
    params = {"shaper_x": "zv", "shaper_y": "zv", "freq_x": 45.0, "freq_y": 40.0, "damping_x": 0.1,
              "damping_y": 0.1, "accel": 5500.0}
    cfg = config_from_params(params, default_space(marlin, "marlin"))
    assert (cfg.max_accel_x, cfg.max_accel_y) == (5500.0, 5500.0)
    low = config_from_params({**params, "accel": 400.0}, default_space(marlin, "marlin"))
    assert (low.max_accel_x, low.max_accel_y) == (500.0, 500.0)          # never lowered
    facts = printer_facts_from_klipper(Path(__file__).parent / "data" / "klipper_config" / "v24" / "printer.cfg")
    v24 = printer_from_dict({**facts.description, **modes, "current": {}})
    p = {**params, "shaper_x": "mzv", "shaper_y": "mzv", "accel": 20000.0}
    for fw in ("kalico", "klipper"):
        cfg = config_from_params(p, default_space(v24, fw))
        assert (cfg.max_accel_x, cfg.max_accel_y) == (10010.0, 4130.0)
    assert any("Klipper does not have" in n for n in export_config(cfg).notes)
    plain = config_from_params(p, default_space(load_printer(None), "klipper"))
    assert plain.axis_caps == (None, None)
