"""Issue 25: a model gives back what it was fitted to. Klipper's rule on the identified model's
simulated resonance test lands where it lands on the real files (same shaper, frequency within 3 %),
or identify's warning says which axis differs and by how much; the embedded printers record
Klipper's pick from the real files they were fitted to, so tune's baseline on them is that pick; a
simulated test, where one is still needed, does not move with the study's seed."""

from __future__ import annotations

import json
import os
import tomllib
from pathlib import Path

import pytest

from ringtune.agents.cli.main import main
from ringtune.agents.identify.accelerometer import klipper_record, read_measurement, sha256_of
from ringtune.agents.klipper.rule import recommend_klipper
from ringtune.envs.printer import load_printer
from ringtune.envs.sim import resonance_test

TESTS = Path(__file__).resolve().parent
SETS = sorted(p.name for p in (TESTS / "data/accel/klipper_psd").iterdir() if p.is_dir())


@pytest.fixture
def fake_evaluator(monkeypatch):
    monkeypatch.syspath_prepend(str(TESTS))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(TESTS), os.environ.get("PYTHONPATH", "")]))
    return "study_objective:evaluate"


@pytest.mark.parametrize("name", SETS)
def test_klippers_rule_on_the_identified_model_lands_on_the_files_pick_or_identify_says_by_how_much(
        name, data_dir, tmp_path, capsys):
    files = sorted((data_dir / "accel/klipper_psd" / name).glob("*.csv"))
    out = tmp_path / "p.toml"
    assert main(["identify", *map(str, files), "-o", str(out), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    record = tomllib.loads(out.read_text())["measurement"]["klipper"]
    printer = load_printer(out)
    for ax in ("x", "y"):
        if f"shaper_{ax}" not in record:
            continue
        # the rule, run here on the model's expected spectrum (no noise: no seed)
        model = recommend_klipper(resonance_test(printer, ax), "head", record["scv"]).best
        files_pick = (record[f"shaper_{ax}"], record[f"freq_{ax}"])
        diff = round(model.freq, 1) / files_pick[1] - 1
        said = [w for w in res["warnings"] if w.startswith(f"{ax.upper()}: Klipper's rule on the model's")]
        if model.name == files_pick[0] and abs(diff) <= 0.03:
            assert not said, said
        else:
            assert len(said) == 1, res["warnings"]
            assert f"{model.name} @ {model.freq:.1f} Hz" in said[0]
            assert f"{files_pick[0]} @ {files_pick[1]:.1f} Hz" in said[0] and f"{100 * diff:+.1f} %" in said[0]
            assert "[measurement.klipper]" in said[0]
            assert said[0] in out.read_text()                  # the TOML says it too


@pytest.mark.parametrize("embedded, folder", [("ender3", "bassco_ender3"), ("voron24", "bassco_voron_v24")])
def test_the_embedded_printers_record_klippers_pick_from_the_files_they_were_fitted_to(embedded, folder, data_dir):
    files = sorted((data_dir / "accel/klipper_psd" / folder).glob("*.csv"))
    meas = load_printer(embedded).measurement
    assert [Path(f["name"]).name for f in meas["files"]] == [f.name for f in files]
    assert [f["sha256"] for f in meas["files"]] == [sha256_of(f) for f in files]
    assert meas["klipper"] == klipper_record(read_measurement(files).psds, 5.0)


def test_tune_on_the_default_printer_compares_against_the_files_pick(tmp_path, capsys, fake_evaluator):
    assert main(["tune", "--json", "--out", str(tmp_path / "o"), "--trials", "3", "--evaluator",
                 fake_evaluator]) == 0
    k = json.loads(capsys.readouterr().out)["baselines"]["klipper"]
    assert k["source"] == "measurement" and "the resonance files the model was fitted to" in k["label"]
    c = k["config"]
    assert (c["shaper_x"], c["freq_x"], c["shaper_y"], c["freq_y"], c["accel"]) == ("ei", 51.4, "mzv", 46.6, 4800.0)


@pytest.mark.slow
def test_the_simulated_baseline_does_not_move_with_the_studys_seed(tmp_path, capsys, fake_evaluator):
    toml = tmp_path / "p.toml"
    toml.write_text('name = "m"\n[x]\nmodes = [{ freq = 47.0, damping = 0.08 }]\n'
                    '[y]\nmodes = [{ freq = 38.0, damping = 0.1, share = 0.7 }, { freq = 52.0, damping = 0.1 }]\n')
    seen = []
    for seed in ("0", "1", "7"):
        assert main(["tune", "--json", "--printer", str(toml), "--out", str(tmp_path / seed), "--trials", "3",
                     "--seed", seed, "--evaluator", fake_evaluator]) == 0
        k = json.loads(capsys.readouterr().out)["baselines"]["klipper"]
        assert k["source"] == "simulated resonance test"
        seen.append(k["config"])
    assert seen[0] == seen[1] == seen[2]


def test_the_typical_damping_ripples_assume_is_the_median_of_the_real_tests(data_dir):
    """identify --ripples/--tower-band without --decay assume TYPICAL_DAMPING: the median damping of
    the dominant mode (largest share) fitted to every real Klipper resonance test in tests/data."""
    from statistics import median

    from ringtune.envs.ripples import TYPICAL_DAMPING

    dampings = []
    for name in SETS:
        fits = read_measurement(sorted((data_dir / "accel/klipper_psd" / name).glob("*.csv"))).by_axis()
        dampings += [max(f.modes, key=lambda m: m.share).damping for f in fits.values()]
    assert len(dampings) == 10 and round(median(dampings), 2) == TYPICAL_DAMPING
