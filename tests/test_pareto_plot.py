"""pareto.png: print time against the wall ripple, the other measures beside it; what is drawn is
what the study measured (front.csv of the same run, or the evaluations themselves)."""

from __future__ import annotations

import csv
import json

import numpy as np
from PIL import Image

from ringtune.agents.cli.main import main
from ringtune.agents.tune.pareto import Point, pareto_front
from ringtune.agents.tune.pareto_plot import MEASURES, plot_front
from ringtune.envs.evaluate import evaluate_many
from ringtune.shaping.config import TuneConfig


def _data(png) -> dict:
    """The plotted series the PNG carries (its ``Data`` text chunk)."""
    return json.loads(Image.open(png).text["Data"])


def test_pareto_png_plots_the_values_of_front_csv(tmp_path, capsys):
    """A real 6-trial study: every panel whose measure is a column of front.csv shows exactly the
    front's rows (print time, value in the panel's unit); the PNG is a real picture."""
    out = tmp_path / "out"
    assert main(["tune", "--trials", "6", "--seed", "3", "--out", str(out), "--no-refine"]) == 0
    capsys.readouterr()
    png = out / "pareto.png"
    assert png.read_bytes()[:4] == b"\x89PNG" and png.stat().st_size > 20_000
    with open(out / "front.csv") as f:
        rows = list(csv.DictReader(f))
    assert rows
    data = _data(png)
    compared = 0
    for key, panel in data.items():
        if key not in rows[0]:
            continue
        want = sorted((float(r["print_time_s"]), float(r[key]) * panel["scale"]) for r in rows)
        got = sorted(map(tuple, panel["front"]))
        assert len(got) == len(want), key
        # front.csv rounds time to 0.1 ms and distances to 1 nm (0.001 µm)
        np.testing.assert_allclose(np.array(got), np.array(want), atol=2e-3, err_msg=key)
        compared += 1
    assert compared >= 2          # the large panel and the path error at least


def _points():
    """Real evaluations on the built-in print (the default printer): a few shapers and accelerations."""
    cfgs = [TuneConfig(shaper_x=s, shaper_y=s, freq_x=f, freq_y=f * 0.9, accel=a)
            for s, f, a in (("mzv", 48.0, 4000), ("ei", 52.0, 6000), ("zv", 45.0, 8000), ("2hump_ei", 60.0, 3000))]
    ms = evaluate_many(cfgs, None, None)
    pts = [Point(c, m.print_time_s, m.overshoot_mm, m.step_loss,
                 {k: v for k, v in m.to_dict().items() if not isinstance(v, dict)}, f"trial {i}", i)
           for i, (c, m) in enumerate(zip(cfgs, ms))]
    return pts, ms


def test_ripple_is_the_large_panel_and_every_measure_is_the_evaluated_one(tmp_path):
    pts, ms = _points()
    front = pareto_front(pts, also=("ripple_mm",))
    klipper = Point(TuneConfig(), 9.0, 0.004, metrics={**pts[0].metrics, "print_time_s": 9.0}, label="klipper")
    drawn = plot_front(tmp_path / "p.png", pts, front, front[0], {"klipper": klipper}, "overshoot_mm", "t",
                       max_path_error_mm=0.1, baseline_labels={"klipper": "Klipper's pick"})
    assert list(drawn)[0] == "ripple_mm"
    assert set(drawn) == {"ripple_mm", *(k for k, *_ in MEASURES)}
    assert not any(p["missing"] for p in drawn.values())
    data = _data(tmp_path / "p.png")
    by_time = {round(m.print_time_s, 9): m for m in ms}
    for key, panel in data.items():
        for t, y in panel["front"]:
            assert abs(y - getattr(by_time[round(t, 9)], key) * panel["scale"]) < 1e-9, key
        assert panel["chosen"] == [[front[0].print_time_s, front[0].metrics[key] * panel["scale"]]]
        assert panel["baseline:klipper"][0][0] == 9.0
    assert data["ripple_mm"]["unit"] == "µm" and data["extrusion_over_pct"]["unit"] == "%"
    legend = drawn["ripple_mm"]["legend"]
    assert any(t.startswith("Klipper's pick: 9.00 s, ") and t.endswith(" µm") for t in legend)
    assert any(t.startswith("chosen: ") for t in legend)


def test_a_measure_the_trials_lack_is_said_on_the_plot(tmp_path):
    """Trials from a study that recorded only overshoot and path error: the large panel shows the
    quality objective and every other panel says its measure is not recorded."""
    pts = [Point(TuneConfig(), 5.0 + i, 0.01 - 0.002 * i, metrics={"overshoot_mm": 0.01 - 0.002 * i,
                                                                    "path_error_mm": 0.05}) for i in range(3)]
    drawn = plot_front(tmp_path / "p.png", pts, pts, pts[1], {}, "overshoot_mm", "t")
    assert list(drawn)[0] == "overshoot_mm"
    assert not drawn["path_error_mm"]["missing"]
    assert all(drawn[k]["missing"] for k in ("corner_in_mm", "corner_out_mm", "extrusion_over_pct",
                                             "extrusion_under_pct", "show_through_mm"))
    assert [y for _t, y in _data(tmp_path / "p.png")["overshoot_mm"]["front"]] == [10.0, 8.0, 6.0]
