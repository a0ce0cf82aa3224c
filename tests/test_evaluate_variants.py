"""One evaluation as tune judges it (the printer and its ±5 % twins) simulates every variant's
windows in one batch per integration step: the figures are exactly those of one call per variant."""

from __future__ import annotations

import pytest

from ringtune.envs.evaluate import evaluate_detailed, evaluate_judged
from ringtune.envs.windows import auto_settle
from ringtune.envs.metrics import worst_case
from ringtune.envs.printer import load_printer, printer_from_dict
from ringtune.envs.sim import auto_timestep
from ringtune.shaping.config import TuneConfig

CONFIGS = [TuneConfig(shaper_x="ei", shaper_y="mzv", freq_x=51.4, freq_y=46.6, accel=4800.0),
           TuneConfig(shaper_x="zv", shaper_y="2hump_ei", freq_x=38.0, freq_y=61.0, accel=8000.0)]


def _flat(d: dict, pre: str = "") -> dict:
    out = {}
    for k, v in d.items():
        out.update(_flat(v, f"{pre}{k}.") if isinstance(v, dict) else {pre + k: float(v)})
    return out


def _stiff_printer():
    """A printer whose 5 %-higher twin needs a finer integration step than itself (a lightly
    damped 100 Hz X mode: (ω·h)⁴/ζ crosses the step's error budget between 1.0× and 1.05×)."""
    d = load_printer(None).to_dict()
    d["x"] = {**d["x"], "modes": [{"freq": 100.0, "damping": 0.01}]}
    return printer_from_dict(d, "stiff")


@pytest.mark.parametrize("name", ["ender3", "voron24", "stiff"])
def test_batched_variants_give_the_figures_of_one_call_per_variant(name):
    printer = _stiff_printer() if name == "stiff" else load_printer(name)
    variants = [printer, printer.detuned(0.95, 0.75), printer.detuned(1.05, 0.75)]    # tune's twins
    if name == "stiff":
        assert len({auto_timestep(v) for v in variants}) == 2      # two batches, by step
    batched = evaluate_judged(CONFIGS, printer, None, freq_margin=0.05)
    settle = auto_settle(printer)
    apart = [evaluate_detailed(CONFIGS, v, None, settle=settle) for v in variants]
    for i, (m, evs) in enumerate(batched):
        want = worst_case(a[i].metrics for a in apart)
        got, ref = _flat(m.to_dict()), _flat(want.to_dict())
        assert got.keys() == ref.keys()
        assert max(abs(got[k] - ref[k]) for k in got) <= 1e-12
        for e, a in zip(evs, apart):
            assert e.metrics.to_dict() == a[i].metrics.to_dict()
