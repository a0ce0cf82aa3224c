"""simulate's plots overlay Klipper's pick on the same axes, with units and a legend; the drawn
curves are the simulations' own samples (an independent evaluation of Klipper's pick)."""

from __future__ import annotations

import json
import re

import numpy as np
from PIL import Image

from ringtune.agents.cli.main import main
from ringtune.envs.evaluate import evaluate_judged
from ringtune.envs.printer import load_printer
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.features import FEATURE_CLASSES, HIDDEN


def _png(path) -> tuple[dict, str]:
    text = Image.open(path).text
    return {k: np.array(v) for k, v in json.loads(text["Data"]).items()}, text["Description"]


def _windows_xy(evs) -> list[np.ndarray]:
    """Every judged window's simulated nozzle x/y (mm), on every printer variant."""
    out = []
    for e in evs:
        for r, s in zip(e.runs, e.sims):
            t = np.asarray(s.t)
            keep = (t >= r.t0 + r.lag) & (t <= r.t1 + r.lag)
            out.append(np.round(np.asarray(s.nozzle)[keep, :2], 6))
    return out


def test_plots_overlay_klippers_pick_with_units(tmp_path, capsys):
    plots = tmp_path / "plots"
    assert main(["simulate", "--json", "--backend", "lti", "--shaper", "zv", "--freq", "40",
                 "--plot", str(plots)]) == 0
    res = json.loads(capsys.readouterr().out)
    rec = load_printer(None).measurement["klipper"]        # the default printer's recorded pick
    kcfg = TuneConfig(shaper_x=rec["shaper_x"], freq_x=round(rec["freq_x"], 1), shaper_y=rec["shaper_y"],
                      freq_y=round(rec["freq_y"], 1), accel=float(rec["max_accel"]))
    base = evaluate_judged([kcfg], None, None, backend="lti", freq_margin=res["freq_margin"])[0][1]
    mine = evaluate_judged([TuneConfig(shaper_x="zv", shaper_y="zv", freq_x=40.0, freq_y=40.0)], None, None,
                           backend="lti", freq_margin=res["freq_margin"], job_shapers=True)[0][1]

    data, text = _png(plots / "path.png")
    assert plots.joinpath("path.png").stat().st_size > 10_000
    assert any(w.shape == data["baseline_nozzle"].shape and np.allclose(w, data["baseline_nozzle"], atol=2e-6)
               for w in _windows_xy(base)), "the orange curve is a window of Klipper's pick"
    assert any(w.shape == data["nozzle"].shape and np.allclose(w, data["nozzle"], atol=2e-6)
               for w in _windows_xy(mine))
    assert "x (mm)" in text and "y (mm)" in text
    named = re.search(r"largest error [0-9.]+ mm at t = [0-9.]+ s, on the ([a-z ]+?)(: nobody sees it)?(\n|$)", text)
    assert named, text          # the feature the largest error is on
    cls = named.group(1).replace(" ", "_")
    assert cls in FEATURE_CLASSES and bool(named.group(2)) == (cls in HIDDEN)
    assert f"Klipper's pick from the resonance files ({kcfg.shaper_x} {kcfg.freq_x:.1f}" in text

    data, text = _png(plots / "ringing.png")
    assert len(data["baseline_nozzle"]) > 20 and len(data["nozzle"]) > 20
    assert "deviation across the wall (µm)" in text and "against Klipper's pick" in text
    assert "nozzle across the wall, Klipper's pick" in text
    # the wall's feature is named, and a hidden one said to be unseen (the worst ringing of a job
    # is often in its infill, which nobody sees)
    named = re.search(r"corner \(ms\), into the ([a-z ]+?)(: nobody sees it)?(\n|$)", text)
    assert named, text
    cls = named.group(1).replace(" ", "_")
    assert cls in FEATURE_CLASSES and bool(named.group(2)) == (cls in HIDDEN)

    data, text = _png(plots / "accel.png")
    assert "acceleration (mm/s²)" in text and "|head acceleration|, Klipper's pick" in text
    # the baseline's head acceleration reaches its own acceleration, not the configuration's
    assert data["baseline_head_accel"][:, 1].max() > 0.8 * kcfg.accel
