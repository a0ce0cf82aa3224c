"""``ringtune shaper`` and ``ringtune response``: output, JSON keys, clean errors, plot."""

from __future__ import annotations

import json
import math

import pytest

from ringtune.agents.cli.main import main


def run_cli(capsys, *argv):
    code = main(list(argv))
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def test_shaper_json_reports_klipper_numbers(capsys):
    code, out, _ = run_cli(capsys, "shaper", "mzv", "--freq", "40", "--damping", "0.1", "--json")
    assert code == 0
    d = json.loads(out)
    assert d["flavor"] == "klipper" and d["centred"] is True and d["lag_s"] == 0.0
    assert d["amplitudes"] == pytest.approx([0.3651, 0.4075, 0.2274], abs=5e-5)
    assert d["smoothing_mm"] == pytest.approx(0.1273, abs=5e-5)
    assert round(d["max_accel"]) == 4713
    lo, hi = d["band90_hz"]
    assert lo < 40 < hi
    assert set(d) >= {"times_s", "duration_s", "band90_pct", "residual_at_freq", "centroid_s"}


def test_shaper_text_and_causal_lag(capsys):
    code, out, _ = run_cli(capsys, "shaper", "ei2", "--freq", "45", "--flavor", "rrf")
    assert code == 0
    assert "2hump_ei (rrf)" in out and "causal" in out and "90% band" in out
    code, out, _ = run_cli(capsys, "shaper", "zvd", "--freq", "40", "--damping", "0", "--flavor", "rrf", "--json")
    assert json.loads(out)["lag_s"] == pytest.approx(0.0125, abs=1e-6)     # ZVD: ¼·0 + ½·½T + ¼·T = T/2


def test_shaper_json_per_flavour_against_the_firmware_formulas(capsys):
    """firmware.md §2.1/§2.2: Marlin classic ZV at ζ 0.1: factor2 = floor(64.44056192 − 9.902008832
    − 0.0758095488 + 0.043073216) = 54 of 128, echo after 1/(2F) = 12.5 ms; Marlin FTM MZV at
    40 Hz ζ 0.1: N1 = LROUND(0.375/40/0.99499·1000) = 9 samples, A = [1, √2K, K²]/Σ with
    K = exp(−ζπ/df), centred by N0 = LROUND(−Σ A_i·N_i) = −7 samples."""
    def shaper_json(*argv):
        code, out, _ = run_cli(capsys, "shaper", *argv, "--json")
        assert code == 0
        return json.loads(out)

    m = shaper_json("zv", "--freq", "40", "--damping", "0.1", "--flavor", "marlin")
    assert m["amplitudes"] == [74 / 128, 54 / 128] and m["times_s"] == [0.0, 0.0125]
    assert m["centred"] is False and m["lag_s"] == pytest.approx(54 / 128 * 0.0125, rel=1e-12)
    assert m["centre_delay_s"] == 0.0
    f = shaper_json("mzv", "--freq", "40", "--damping", "0.1", "--flavor", "marlin-ftm")
    k = math.exp(-0.1 * math.pi / math.sqrt(0.99))
    assert f["amplitudes"] == pytest.approx([1 / (1 + 2 ** 0.5 * k + k * k), 2 ** 0.5 * k / (1 + 2 ** 0.5 * k + k * k),
                                             k * k / (1 + 2 ** 0.5 * k + k * k)], rel=1e-6)
    assert f["times_s"] == pytest.approx([0.0, 0.009, 0.018], abs=1e-15)
    assert f["centre_delay_s"] == pytest.approx(0.007, abs=1e-15)
    assert f["lag_s"] == pytest.approx(f["centroid_s"] - 0.007, abs=1e-15)
    r = shaper_json("mzv", "--freq", "40", "--damping", "0.1", "--flavor", "rrf")
    assert [round(a, 3) for a in r["amplitudes"]] == [0.227, 0.407, 0.365]     # M593's own report
    assert [round(t * 750_000) for t in r["times_s"]] == [0, 7066, 14132]
    p = shaper_json("mzv", "--freq", "40", "--damping", "0.1", "--flavor", "prusa")
    assert p["flavor"] == "klipper-legacy" and p["amplitudes"] == pytest.approx([0.3651, 0.4075, 0.2274], abs=5e-5)


@pytest.mark.parametrize("argv,needle", [
    (["shaper", "zv", "--freq", "40", "--flavor", "rrf"], "closest it offers is 'mzv'"),
    (["shaper", "custom(h=0.6:0.5)", "--freq", "40", "--flavor", "rrf"], "sum to less than 1"),
    (["shaper", "zv", "--freq", "-4"], "frequency"),
    (["shaper", "zv", "--freq", "40", "--flavor", "duet"], "--flavor"),
    (["response", "zv", "--freq", "40", "--plant-damping", "x"], "--plant-damping"),
])
def test_bad_input_is_one_line_and_exit_2(capsys, argv, needle):
    code, out, err = run_cli(capsys, *argv)
    assert code == 2 and out == ""
    assert needle in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err


def test_response_json_and_plot(capsys, tmp_path):
    png = tmp_path / "r.png"
    code, out, _ = run_cli(capsys, "response", "zv", "mzv", "ei", "--freq", "40", "--points", "200",
                           "--plot", str(png), "--json")
    assert code == 0
    d = json.loads(out)
    assert [s["name"] for s in d["shapers"]] == ["zv", "mzv", "ei"]
    assert len(d["freqs_hz"]) == 200 and len(d["shapers"][0]["residual"]) == 200
    assert d["plant_damping"] == [0.075, 0.1, 0.15]
    # the curve is the max over plant dampings: never 0 exactly, smallest near the design frequency
    res = d["shapers"][0]["residual"]
    i_min = min(range(len(res)), key=res.__getitem__)
    assert abs(d["freqs_hz"][i_min] - 40) < 2
    assert png.stat().st_size > 10_000 and png.read_bytes()[:4] == b"\x89PNG"


def test_response_plot_has_a_readable_percentage_axis(capsys, tmp_path, monkeypatch):
    """Without a PSD the residual curves own the only y axis: it must keep its 0–100 % ticks."""
    import matplotlib.figure

    saved = []
    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", lambda fig, *a, **k: saved.append(fig))
    code, _, _ = run_cli(capsys, "response", "zv", "--freq", "40", "--plot", str(tmp_path / "r.png"))
    assert code == 0 and len(saved) == 1
    ax = saved[0].axes[0]
    assert ax.get_ylabel() == "remaining vibration, %"
    assert len(ax.get_yticks()) >= 3 and max(ax.get_ylim()) >= 100


def test_response_with_klipper_psd(capsys, tmp_path, data_dir):
    csvs = sorted((data_dir / "accel" / "klipper_psd").rglob("resonances_*.csv"))
    if not csvs:
        pytest.skip("no Klipper resonances CSV in shared data")
    png = tmp_path / "psd.png"
    code, out, _ = run_cli(capsys, "response", "mzv", "--freq", "45", "--psd", str(csvs[0]), "--plot", str(png))
    assert code == 0 and png.exists() and "graph written" in out


def test_none_shaper_reports_valid_json_without_limits(capsys):
    code, out, _ = run_cli(capsys, "shaper", "none", "--freq", "40", "--json")
    assert code == 0
    d = json.loads(out, parse_constant=lambda c: pytest.fail(f"non-JSON constant {c}"))
    assert d["max_accel"] is None and d["band90_hz"] == [None, None] and d["smoothing_mm"] == 0.0
    code, out, _ = run_cli(capsys, "response", "none", "zv", "--freq", "40", "--json")
    d = json.loads(out, parse_constant=lambda c: pytest.fail(f"non-JSON constant {c}"))
    assert d["shapers"][0]["max_accel"] is None
