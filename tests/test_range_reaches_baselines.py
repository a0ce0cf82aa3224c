"""A printer set fast: the acceleration range's own floor (0.3× the printer's acceleration) above
Klipper's max_accel must not cost the guarantee that the choice is no worse than Klipper's pick.

Found on a Voron 0 description written from its printer.cfg (max_accel 25000 mm/s², the
Ender-3-class modes as defaults): the search ran from 7500 mm/s², Klipper's pick at 3900 lay
outside it, nothing the study tried matched its quality, and tune fell back to the knee of the
front, whose corners rounded 93.6 µm against the pick's 48.8 µm.
"""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import pytest

from ringtune.agents.cli.main import main
from ringtune.agents.tune.space import default_space
from ringtune.agents.tune.tuning import _reaching_baselines
from ringtune.envs.evaluate import evaluate_many
from ringtune.envs.printer import load_printer
from ringtune.envs.variants import variant_factors
from ringtune.envs.windows import auto_settle
from ringtune.shaping.config import TuneConfig

DATA = Path(__file__).parent / "data" / "klipper_config"
VISIBLE = ("ripple_mm", "ripple_p90_mm", "corner_in_mm", "corner_out_mm", "extrusion_over_pct", "extrusion_under_pct")


def _worse(key: str, mine: float, theirs: float) -> bool:
    """Worse beyond the resolution the summary states (1 µm or 5 %; 1 point or 5 % of extrusion)."""
    big = max(abs(mine), abs(theirs))
    tol = max(1.0, 0.05 * big) if key.endswith("_pct") else max(0.001, 0.05 * big)
    return mine - theirs > tol


def _voron0(tmp_path):
    """The Voron 0 description from its real printer.cfg (max_accel 25000 mm/s²; default modes)."""
    path = tmp_path / "v0.toml"
    assert main(["printer", "from-klipper", str(DATA / "v0" / "printer.cfg"), "-o", str(path)]) == 0
    return path


def test_the_range_reaches_down_to_the_baselines_acceleration(tmp_path, capsys):
    space = default_space(load_printer(str(_voron0(tmp_path))), "klipper")
    capsys.readouterr()
    assert space.accel[0] == 7500.0                   # 0.3 × 25000: the range's own floor
    configs = SimpleNamespace(configs={"klipper": TuneConfig(accel=3950.0), "current": TuneConfig(accel=25000.0),
                                       "none": TuneConfig(shaper_x="none", shaper_y="none", accel=50.0)})
    notes = []
    wide = _reaching_baselines(space, configs, notes.append)
    assert wide.accel == (3900.0, space.accel[1])     # to the step below; no shaping is no floor
    assert len(notes) == 1 and "reaches down to Klipper's rule's 3950 mm/s², so the search starts from it" in notes[0]
    configs.configs["klipper"] = TuneConfig(accel=7600.0)
    assert _reaching_baselines(space, configs, notes.append) is space and len(notes) == 1


@pytest.mark.slow
def test_a_printer_set_fast_gets_no_choice_worse_than_klippers_pick(tmp_path, capsys):
    path = _voron0(tmp_path)
    capsys.readouterr()
    assert main(["tune", "--json", "--workers", "1", "--seed", "0", "--trials", "30", "--printer", str(path),
                 "--out", str(tmp_path / "out")]) == 0
    captured = capsys.readouterr()
    res = json.loads(captured.out)
    klipper = TuneConfig.from_dict(res["baselines"]["klipper"]["config"])
    assert klipper.accel < 7500.0                            # the case: the pick below the old floor
    assert res["accel"]["range"][0] <= klipper.accel
    assert "the acceleration is searched from" in captured.err
    assert res["chosen"]["chosen_by"] == "fastest-at-baseline-quality" and "klipper" in res["chosen"]["held_to"]
    chosen = TuneConfig.from_dict(res["chosen"]["config"])
    printer = load_printer(str(path))
    # simulated again here, on each printer it was judged on, each alone
    for v in variant_factors(res["freq_margin"]):
        mine, theirs = evaluate_many([chosen, klipper], v.of(printer), None, settle=auto_settle(printer))
        for key in VISIBLE:
            assert not _worse(key, getattr(mine, key), getattr(theirs, key)), (v, key)
        assert mine.print_time_s <= theirs.print_time_s
