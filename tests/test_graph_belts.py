"""CoreXY belts from the two diagonal resonance tests: a simulated CoreXY whose belts differ by 10 %
in stiffness is recovered within 2 %, identical belts read as matched; the graph shows the JSON's
numbers; identify writes the difference into [belts] and the model tune simulates carries it."""

from __future__ import annotations

import json
import tomllib
from dataclasses import replace

import numpy as np
import pytest
from PIL import Image

from ringtune.agents.cli.main import main
from ringtune.agents.identify.belts import compare_belts, paired_peaks, similarity
from ringtune.envs.mujoco_model import linear_system
from ringtune.envs.printer import load_printer, printer_from_dict
from ringtune.envs.sim import resonance_test
from ringtune.hardware.accel import read_resonances_csv

#: a CoreXY whose two axes have the same modal mass and frequency: the belts carry both axes
COREXY = """
name = "corexy-test"
kinematics = "corexy"
[x]
mass = 0.7
modes = [{ freq = 55.0, damping = 0.06 }]
[y]
mass = 0.7
modes = [{ freq = 55.0, damping = 0.06 }]
"""
TEN_PERCENT = 2 * 0.1 / 2.1          # k_A = 1.1 k_B  ->  (k_A - k_B)/mean
#: Welch scatter of the simulated tests: ln-PSD standard deviation 0.2 per bin (Gamma, 50 degrees of
#: freedom), more than the bin-to-bin scatter of every real Klipper file in tests/data (checked below)
DOF = 50.0


def _printer():
    return printer_from_dict(tomllib.loads(COREXY), "corexy-test")


def _tests(printer, seed, dof=DOF):
    rng = np.random.default_rng(seed)
    return {k: (*resonance_test(printer, d, rng=rng, dof=dof), k) for k, d in (("a", (1, 1)), ("b", (1, -1)))}


def _log_scatter(psd):
    """Bin-to-bin scatter of ln PSD (second differences / √6): noise, not the curve's shape."""
    lc = np.log(psd)
    return float(np.std((lc[2:] - 2 * lc[1:-1] + lc[:-2]) / np.sqrt(6)))


def test_the_simulated_tests_scatter_more_than_the_real_files(data_dir):
    real = []
    for f in (data_dir / "accel/klipper_psd").glob("*/*.csv"):
        p = read_resonances_csv(f)
        sel = (p.freqs > 10) & (p.freqs < 120)
        real.append(_log_scatter(p.psd_sum[sel]))
    f, s = resonance_test(_printer(), (1, 1), rng=np.random.default_rng(0), dof=DOF)
    sel = (f > 10) & (f < 120)
    assert _log_scatter(s[sel]) > 1.5 * max(real)


@pytest.mark.parametrize("seed", range(8))
def test_belts_ten_percent_apart_are_recovered_within_two_percent(seed):
    p = _printer()
    truth = replace(p, belt_mismatch=TEN_PERCENT)
    ka, kb = truth.belt_stiffnesses()
    assert ka / kb == pytest.approx(1.1)
    c = compare_belts(_tests(truth, seed), p)
    assert c.stiffness[0] == pytest.approx(ka, rel=0.02)
    assert c.stiffness[1] == pytest.approx(kb, rel=0.02)
    assert not c.matched and "Belt A is" in c.meaning() and "belt B is the looser one" in c.meaning()


@pytest.mark.parametrize("seed", range(8))
def test_identical_belts_read_as_identical(seed):
    p = _printer()
    c = compare_belts(_tests(p, seed), p)
    assert c.matched and abs(c.mismatch) < 0.02
    assert c.meaning().startswith("The belts read as matched")
    ka, kb = c.stiffness
    assert abs(ka / kb - 1) < 0.02


def test_at_the_default_scatter_the_stated_error_covers_the_truth():
    """At the simulator's default (much noisier) scatter the estimate is looser, and says so."""
    p = _printer()
    truth = replace(p, belt_mismatch=TEN_PERCENT)
    for seed in range(6):
        c = compare_belts(_tests(truth, seed, dof=6.0), p)
        assert abs(c.mismatch - TEN_PERCENT) < 3 * c.mismatch_error
        assert c.mismatch_error > 0.015


def test_similarity_and_peaks_by_their_definition():
    f = np.linspace(5, 135, 84)
    a = np.exp(-((f - 50) / 4) ** 2) + 0.2 * np.exp(-((f - 90) / 3) ** 2)
    b = 3 * np.exp(-((f - 54) / 4) ** 2)
    assert similarity(f, a, f, 2 * a) == pytest.approx(100.0)
    assert similarity(f, a, f, b) == pytest.approx(100 * (a @ b) / np.sqrt((a @ a) * (b @ b)))
    pairs = paired_peaks(f, a, f, b)
    main_pair = next(p for p in pairs if p.freq_a is not None and p.freq_b is not None)
    assert main_pair.freq_diff == pytest.approx(4.0, abs=1.6)            # one bin
    assert main_pair.amp_diff_pct == pytest.approx(200 * (1 - 3) / 4, abs=15)
    assert any(p.freq_b is None and abs(p.freq_a - 90) < 2 for p in pairs)   # 90 Hz: A only


def _write(tmp_path, tests):
    paths = []
    for k, name in (("a", "1.000,1.000,0.000"), ("b", "1.000,-1.000,0.000")):
        f, s, _ = tests[k]
        path = tmp_path / f"resonances_axis={name}_belts.csv"
        rows = [f"{fi:.1f},{si / 2:.3e},{si / 2:.3e},{0.0:.3e},{si:.3e}" for fi, si in zip(f, s) if fi < 200]
        path.write_text("freq,psd_x,psd_y,psd_z,psd_xyz\n" + "\n".join(rows) + "\n")
        paths.append(str(path))
    return paths


def test_belt_graph_shows_the_json_numbers(capsys, tmp_path):
    p = _printer()
    printer_toml = tmp_path / "p.toml"
    printer_toml.write_text(COREXY)
    paths = _write(tmp_path, _tests(replace(p, belt_mismatch=TEN_PERCENT), 3))
    png = tmp_path / "belts.png"
    assert main(["graph", "belts", *paths[::-1], "--printer", str(printer_toml), "-o", str(png), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["sources"] == {"a": paths[0], "b": paths[1]}           # told apart by their names, not their order
    assert d["mismatch"] == pytest.approx(TEN_PERCENT, abs=0.02)
    im = Image.open(png)
    px = np.asarray(im.convert("RGB"), dtype=float)
    assert im.size[0] > 800 and 0.02 < (px.sum(axis=2) < 600).mean() < 0.6
    text = im.text["Description"]
    assert f"similarity: {d['similarity_pct']:.1f} %" in text
    assert f"belt stiffness: A {d['stiffness_a_n_m']:.0f} N/m, B {d['stiffness_b_n_m']:.0f} N/m" in text
    rows = [line.split("\t") for line in text.splitlines() if line.count("\t") == 4 and not line.startswith("\t")]
    assert len(rows) == len(d["pairs"])
    for cells, pair in zip(rows, d["pairs"]):
        assert cells[1] == ("-" if pair["freq_a"] is None else f"{pair['freq_a']:.1f}")
        assert cells[2] == ("-" if pair["freq_b"] is None else f"{pair['freq_b']:.1f}")


def test_identify_writes_the_belts_and_the_model_carries_them(capsys, tmp_path, data_dir):
    truth = replace(_printer(), belt_mismatch=TEN_PERCENT)
    paths = _write(tmp_path, _tests(truth, 5))
    x = str(data_dir / "accel/klipper_psd/bassco_voron_v24/resonances_x_20230306_224517.csv")
    y = str(data_dir / "accel/klipper_psd/bassco_voron_v24/resonances_y_20230306_224919.csv")
    out = tmp_path / "v.toml"
    assert main(["identify", x, y, "--kinematics", "corexy", "--belts", *paths, "-o", str(out), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    pr = load_printer(str(out))
    assert pr.belt_mismatch == pytest.approx(d["belts"]["mismatch"], abs=1e-4)
    ka, kb = pr.belt_stiffnesses()
    assert (ka, kb) == pytest.approx((d["belts"]["stiffness_a_n_m"], d["belts"]["stiffness_b_n_m"]), rel=1e-3)
    k = linear_system(pr).K                 # what simulate and tune integrate: the belts couple X and Y
    assert k[0, len(pr.effective_modes("x"))] == pytest.approx(ka - kb, rel=1e-6)
    assert "belt_files" in tomllib.loads(out.read_text())["measurement"]


def test_identify_refuses_belts_on_a_cartesian(capsys, tmp_path, data_dir):
    paths = _write(tmp_path, _tests(_printer(), 0))
    x = str(data_dir / "accel/klipper_psd/bassco_ender3/resonances_x_20210821_152037.csv")
    out = tmp_path / "e.toml"
    code = main(["identify", x, "--belts", *paths, "-o", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and "--belts" in err and "CoreXY" in err and "Traceback" not in err
    assert not out.exists()
