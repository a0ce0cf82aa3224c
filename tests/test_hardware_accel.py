"""Accelerometer readers against the real files and against independent truth (scipy's Welch)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy import signal

from ringtune.hardware.accel import axis_from_file_name, read_accel, read_raw_accel, read_resonances_csv
from ringtune.hardware.psd import PSD, klipper_psd, klipper_window_size
from ringtune.hardware.raw_accel import G_MM_S2, RawAccel
from ringtune.shaping.errors import RingtuneError


def _files(data_dir: Path, sub: str) -> list[Path]:
    files = sorted((data_dir / "accel" / sub).rglob("*.csv"))
    assert files, f"no files under {sub}"
    return files


def test_every_klipper_psd_file_parses(data_dir):
    files = _files(data_dir, "klipper_psd")
    assert len(files) == 10
    for path in files:
        psd = read_resonances_csv(path)
        assert isinstance(psd, PSD)
        lines = [ln for ln in path.read_text().splitlines()[1:] if ln.strip()]
        assert len(psd.freqs) == len(lines)
        first = [float(v) for v in lines[0].split(",")]
        assert psd.freqs[0] == first[0] and psd.psd_x[0] == first[1] and psd.psd_sum[0] == first[4]
        # psd_xyz is the sum of the three axes (to the file's 4 significant digits)
        np.testing.assert_allclose(psd.psd_x + psd.psd_y + psd.psd_z, psd.psd_sum, rtol=2e-3)
        assert psd.name == path.name.split("_")[1] and not psd.normalized
        assert read_accel(path).freqs.shape == psd.freqs.shape


def test_bassco_ender3_peaks(data_dir):
    x = read_resonances_csv(data_dir / "accel/klipper_psd/bassco_ender3/resonances_x_20210821_152037.csv")
    y = read_resonances_csv(data_dir / "accel/klipper_psd/bassco_ender3/resonances_y_20210630_230110.csv")
    sweep = x.freqs < 135  # Klipper's default sweep ends at 135 Hz
    top2 = x.freqs[sweep][np.argsort(x.psd_x[sweep])[::-1][:2]]
    assert sorted(top2) == pytest.approx([45.0, 59.4])
    assert x.freqs[sweep][np.argmax(x.psd_sum[sweep])] == pytest.approx(59.4)
    sweep = y.freqs < 135
    assert y.freqs[sweep][np.argmax(y.psd_y[sweep])] == pytest.approx(39.0)


def test_every_m956_file_parses(data_dir):
    for path in _files(data_dir, "rrf_m956"):
        raw = read_raw_accel(path)
        assert raw.fmt == "m956" and len(raw.t) == 1000
        lines = path.read_text().splitlines()
        rate = float(lines[-1].split()[1].rstrip(","))
        assert raw.rate == rate and raw.overflows == 0
        np.testing.assert_allclose(raw.t[1] - raw.t[0], 1.0 / rate)
        row = [float(v) for v in lines[1].split(",")]
        assert raw.ax[0] == pytest.approx(row[1] * 9806.65)
        assert raw.az[0] == pytest.approx(row[3] * G_MM_S2)
        # 1000 samples is not more than Klipper's 1024-sample window: Klipper refuses, so do we
        with pytest.raises(RingtuneError, match="1024-sample"):
            klipper_psd(raw)


def test_klipper_window_size():
    assert klipper_window_size(3200) == 2048      # ADXL345 at 3200 Hz: 0.5 s -> 1600 -> 2048
    assert klipper_window_size(1387) == 1024
    assert klipper_window_size(400) == 256


def _write_raw(path: Path, t, a):
    with path.open("w") as f:
        f.write("#time,accel_x,accel_y,accel_z\n")
        for row in zip(t, *a):
            f.write("%.6f,%.6f,%.6f,%.6f\n" % row)


def test_klipper_psd_matches_scipy_welch_and_parseval(tmp_path):
    rng = np.random.default_rng(3)
    fs, n = 3200.0, 9000
    t = np.arange(n) / fs
    ax = 1000 * np.sin(2 * np.pi * 50 * t) + rng.normal(0, 10, n)
    ay = 300 * np.sin(2 * np.pi * 80 * t) + 50
    az = rng.normal(0, 20, n) + 9806.65
    p = tmp_path / "raw_data_x_20240101_000000.csv"
    _write_raw(p, t, (ax, ay, az))
    raw = read_accel(p)
    assert isinstance(raw, RawAccel)
    psd = klipper_psd(raw)
    fs_k = n / (raw.t[-1] - raw.t[0])
    m = klipper_window_size(fs_k)
    for col, ours in ((raw.ax, psd.psd_x), (raw.ay, psd.psd_y), (raw.az, psd.psd_z)):
        f_ref, p_ref = signal.welch(col, fs=fs_k, window=np.kaiser(m, 6.0), nperseg=m, noverlap=m // 2,
                                    detrend="constant", scaling="density")
        np.testing.assert_allclose(psd.freqs, f_ref)
        np.testing.assert_allclose(ours, p_ref, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(psd.psd_sum, psd.psd_x + psd.psd_y + psd.psd_z)
    # Parseval: power of a sinusoid of amplitude A is A^2/2
    df = psd.freqs[1]
    band = (psd.freqs > 40) & (psd.freqs < 60)
    assert psd.psd_x[band].sum() * df == pytest.approx(1000 ** 2 / 2, rel=0.02)
    assert psd.freqs[np.argmax(psd.psd_y)] == pytest.approx(80, abs=df)


def test_multi_dataset_and_shaper_block(tmp_path):
    p = tmp_path / "multi.csv"
    p.write_text('freq,"run, one",run2,shapers:,zv(34.4),mzv(40.0)\n'
                 "5.0,1.000e+01,2.000e+01,,0.500,0.400\n"
                 "6.6,1.500e+01,2.500e+01,,0.450,0.350\n")
    out = read_resonances_csv(p)
    assert isinstance(out, list) and [d.name for d in out] == ["run, one", "run2"]
    np.testing.assert_allclose(out[1].psd_sum, [20.0, 25.0])
    assert out[0].psd_x is None and out[0].normalized
    np.testing.assert_allclose(out[0].shapers["mzv(40.0)"], [0.4, 0.35])
    # old Klipper calibration_data form: shaper columns straight after psd_xyz
    q = tmp_path / "calibration_data_x_20230306.csv"
    q.write_text("freq,psd_x,psd_y,psd_z,psd_xyz,zv(34.4),ei(51.2)\n"
                 "5.0,1.0e+00,2.0e+00,3.0e+00,6.0e+00,0.900,0.800\n"
                 "6.6,1.0e+00,2.0e+00,3.0e+00,6.0e+00,0.910,0.810\n")
    c = read_resonances_csv(q)
    assert c.normalized and list(c.shapers) == ["zv(34.4)", "ei(51.2)"] and c.name == "x"
    assert c.normalized_to_frequencies() is c


def test_normalize_to_frequencies():
    f = np.array([0.0, 5.0, 10.0, 50.0])
    one = np.ones(4)
    p = PSD(f, one, one, one, 3 * one).normalized_to_frequencies()
    expect = 3 / (f + 0.1)
    expect[:2] *= np.exp(1 - (10 / (f[:2] + 0.1)) ** 2)
    np.testing.assert_allclose(p.psd_sum, expect)


@pytest.mark.parametrize("text, line, msg", [
    ("freq,psd_x,psd_y,psd_z,psd_xyz\n5.0,1,2,3,6\n6.0,1,2,3\n", 3, "expected 5"),
    ("freq,psd_x,psd_y,psd_z,psd_xyz\n5.0,1,2,3,6\n6.0,1,x2,3,6\n", 3, "not a number"),
    ("freq,psd_x,psd_y,psd_z,psd_xyz\n5.0,1,2,3,6\n4.0,1,2,3,6\n", 3, "increase"),
    ("Sample,X,Y\n0,0.1,0.2\n1,0.1,0.2\n", 3, "trailer"),
    ("Sample,X,Y\n0,0.1,0.2\n1,0.1\nRate 1000, overflows 0\n", 3, "expected 3"),
    ("Sample,X,Q\n0,0.1,0.2\n", 1, "header"),
    ("#time,accel_x,accel_y,accel_z\n0.0,1,2,3\n0.1,1,2\n", 3, "expected 4"),
    ("#time,accel_x,accel_y,accel_z\n0.0,1,2,3\n0.1,1,nan,3\n", 3, "finite"),
    ("hello,world\n", 1, "unrecognised"),
])
def test_malformed_files_name_file_and_line(tmp_path, text, line, msg):
    p = tmp_path / "bad.csv"
    p.write_text(text)
    with pytest.raises(RingtuneError, match=msg) as exc:
        read_accel(p)
    assert f"{p}:{line}" in str(exc.value)


def test_missing_file(tmp_path):
    with pytest.raises(RingtuneError, match="no such file"):
        read_accel(tmp_path / "nope.csv")


# -- the axis from the file name: one function (hardware.accel.axis_from_file_name) ------------------

def test_axis_from_file_name_on_the_real_files(data_dir):
    """Every real file's axis is the one its SOURCES.md entry states (Klipper: the name Klipper
    wrote; RRF: the X54-161 / Y71-214 moves of Duet's plugin names)."""
    files = sorted((data_dir / "accel").rglob("*.csv"))
    assert len(files) >= 12
    for f in files:
        if f.name.startswith("resonances_"):
            expect = f.name.split("_")[1]
        else:
            expect = {"1-T0-X54-161-0-none.csv": "x", "1-T0-Y71-214-0-none.csv": "y"}[f.name]
        assert axis_from_file_name(f) == expect, f.name


@pytest.mark.parametrize("name, axis", [
    ("resonances_x_20210821_152037.csv", "x"),            # Klipper TEST_RESONANCES
    ("calibration_data_y_20230306.csv", "y"),              # SHAPER_CALIBRATE
    ("raw_data_x_adxl345_20230306.csv", "x"),              # OUTPUT=raw_data
    ("resonances_z_20251004.csv", "z"),                    # Klipper HEAD's Z axis
    ("Resonances_X_20210821.CSV", "x"),                    # renamed by a user: case does not matter
    ("ender3_resonances_y_20210630.csv", "y"),             # a prefix the user added
    ("resonances_axis=1.000,-1.000_20240101.csv", None),   # a diagonal test names no single axis
    ("myresonances_x_1.csv", None),                        # not Klipper's word
    ("adxl345-20240101_120000.csv", None),                 # ACCELEROMETER_MEASURE: no axis in the name
    ("1-T0-X54-161-0-none.csv", "x"),                      # Duet's Input Shaping plugin
])
def test_axis_from_file_name(name, axis):
    assert axis_from_file_name(Path("/somewhere") / name) == axis
