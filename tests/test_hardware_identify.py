"""Mode identification: analytic spectra and decays with known modes, and the real Ender 3 data."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ringtune.agents.identify.accelerometer import read_measurement
from ringtune.agents.identify.description import build_description, description_toml
from ringtune.envs.identify import identify_decay, identify_psd, plot_fits, transmissibility

ENDER3 = ("klipper_psd/bassco_ender3/resonances_x_20210821_152037.csv",
          "klipper_psd/bassco_ender3/resonances_y_20210630_230110.csv")


def _fits(paths, **kw):
    return read_measurement(paths, **kw).fits


def _toml(fits, **kw):
    return description_toml(build_description({f.axis: f for f in fits}, **kw))


def _local_maxima(f, p, rel, merge_hz=4.0):
    """Local maxima of at least rel·max; maxima closer than merge_hz keep only the highest."""
    i = np.flatnonzero((p[1:-1] > p[:-2]) & (p[1:-1] > p[2:])) + 1
    i = i[p[i] >= rel * p.max()]
    kept = []
    for k in sorted(i, key=lambda k: -p[k]):
        if all(abs(f[k] - f[j]) > merge_hz for j in kept):
            kept.append(k)
    return f[sorted(kept)]


def test_single_mode_transmissibility_is_the_textbook_one():
    f = np.linspace(1, 200, 50)
    r, z = f / 40.0, 0.07
    expect = (1 + 2j * z * r) / (1 - r * r + 2j * z * r)
    np.testing.assert_allclose(transmissibility(f, [(40.0, z, 1.0)]), expect)


def test_recovers_known_modes_from_a_synthetic_sweep_psd():
    rng = np.random.default_rng(7)
    f = np.arange(0, 200, 1.5625)                      # Klipper's bins at 3200 Hz, 2048-sample windows
    true = [(42.0, 0.06, 0.7), (75.0, 0.10, 0.3)]
    p = 3e3 * (f / 50) ** 2 * np.abs(transmissibility(f, true)) ** 2 + 50.0
    p *= np.exp(rng.normal(0, 0.05, f.size))
    fit = identify_psd(f, p, "x")
    got = sorted((m.freq, m.damping, m.share) for m in fit.modes)
    assert len(got) == 2
    for (fg, zg, sg), (ft, zt, st) in zip(got, true):
        assert fg == pytest.approx(ft, rel=0.01)
        assert zg == pytest.approx(zt, rel=0.2)
        assert sg == pytest.approx(st, abs=0.1)
    assert fit.r2 > 0.95


def test_half_power_damping_on_a_light_single_mode():
    f = np.arange(0, 200, 0.25)
    p = (f / 50) ** 2 * np.abs(transmissibility(f, [(50.0, 0.03, 1.0)])) ** 2
    fit = identify_psd(f, p, "x", damping="half-power", max_modes=1)
    assert fit.modes[0].damping == pytest.approx(0.03, rel=0.1)
    assert fit.modes[0].freq == pytest.approx(50.0, abs=0.2)


def test_damped_sinusoid_fit_recovers_a_free_decay():
    rng = np.random.default_rng(1)
    rate = 1390.0
    t = np.arange(1000) / rate
    a = np.zeros_like(t)
    kick = 20
    tt = t[kick:] - t[kick]
    w = 2 * math.pi * 59.0
    a[kick:] = 3000 * np.exp(-0.04 * w * tt) * np.cos(w * math.sqrt(1 - 0.04 ** 2) * tt)
    a += rng.normal(0, 20, t.size) + 9806.65 * 0.02
    fit = identify_decay(t, a, "x", "synthetic", rate, max_modes=1)
    assert fit.modes[0].freq == pytest.approx(59.0, rel=0.005)
    assert fit.modes[0].damping == pytest.approx(0.04, rel=0.1)
    assert fit.r2 > 0.9 and not fit.notes and not fit.warnings


def test_ender3_dominant_frequencies_within_1hz_of_the_psd_peaks(data_dir, tmp_path):
    paths = [data_dir / "accel" / p for p in ENDER3]
    fits = _fits(paths)
    assert [f.axis for f in fits] == ["x", "y"]
    for fit, path in zip(fits, paths):
        psd = __import__("ringtune.hardware.accel", fromlist=["x"]).read_resonances_csv(path)
        band = (psd.freqs >= 5) & (psd.freqs <= 135)
        col = psd.axis(fit.axis)[band]
        peaks = _local_maxima(psd.freqs[band], col, rel=0.5)    # the dominant peaks of the measured PSD
        assert len(peaks) >= 1
        for pk in peaks:
            nearest = min(fit.modes, key=lambda m: abs(m.freq - pk))
            assert abs(nearest.freq - pk) <= 1.0, (path.name, pk, nearest)
        # and the fitted spectrum peaks where the measured one does
        top = psd.freqs[band][np.argmax(col)]
        nearest = min(fit.modes, key=lambda m: abs(m.freq - top))
        assert abs(nearest.fitted_peak - top) <= 1.0, (path.name, top, nearest)
        assert fit.r2 > 0.9
    # measured peaks of these files (read off the CSVs): X 45.0 and 59.4 Hz, Y 39.0 Hz
    assert sorted(round(m.peak_freq, 1) for m in fits[0].modes) == [45.0, 59.4]
    out = tmp_path / "fit.png"
    plot_fits(fits, out)
    assert out.stat().st_size > 20000


def test_plot_shows_the_files_psd_against_the_fitted_spectrum(data_dir, tmp_path, monkeypatch):
    """What is drawn, not just that a PNG exists: per file, the measured curve is the file's own
    PSD column, and the fitted curve follows it and peaks where it does."""
    import matplotlib.figure

    from ringtune.hardware.accel import read_resonances_csv

    drawn = []
    save = matplotlib.figure.Figure.savefig
    monkeypatch.setattr(matplotlib.figure.Figure, "savefig",
                        lambda fig, *a, **k: (drawn.append(fig), save(fig, *a, **k))[1])
    paths = [data_dir / "accel" / p for p in ENDER3]
    fits = _fits(paths)
    plot_fits(fits, tmp_path / "fit.png")
    assert len(drawn) == 1 and (tmp_path / "fit.png").read_bytes()[:4] == b"\x89PNG"
    panels = drawn[0].axes
    assert len(panels) == 2
    for panel, path, fit, peaks in zip(panels, paths, fits, ([45.0, 59.4], [39.0])):
        lines = {ln.get_label(): ln for ln in panel.get_lines()}
        measured, fitted = lines["measured PSD"], lines["fitted modes"]
        psd = read_resonances_csv(path)
        col = psd.axis(fit.axis)
        fm, pm = measured.get_xdata(), measured.get_ydata()
        np.testing.assert_array_equal(pm, col[np.isin(psd.freqs, fm)])     # the file's numbers
        assert fm.min() <= 7 and fm.max() >= 130                            # the whole sweep
        ff, pf = fitted.get_xdata(), fitted.get_ydata()
        # the fitted curve follows the measured one (log scale) ...
        err = np.log10(np.interp(fm, ff, pf) / pm)
        assert np.median(np.abs(err)) < 0.15
        # ... and peaks where the measured one does
        for pk in peaks:
            near = (ff > pk - 4) & (ff < pk + 4)
            assert abs(ff[near][np.argmax(pf[near])] - pk) <= 1.0, (path.name, pk)


def test_printer_toml_round_trips_through_the_loader(data_dir, tmp_path):
    from ringtune.envs.printer import load_printer

    fits = _fits([data_dir / "accel" / p for p in ENDER3])
    text = _toml(fits, name="bassco-ender3")
    path = tmp_path / "p.toml"
    path.write_text(text)
    printer = load_printer(path)
    assert printer.name == "bassco-ender3"
    for ax, fit in zip(("x", "y"), fits):
        got = sorted((m.freq, m.damping, m.share) for m in printer.axis(ax).modes)
        want = sorted((m.freq, m.damping, m.share) for m in fit.modes)
        for g, w in zip(got, want):
            assert g == pytest.approx(w, rel=2e-3, abs=2e-3)
        assert sum(m.share for m in printer.axis(ax).modes) == pytest.approx(1.0)


def test_one_axis_takes_the_other_from_the_base_printer(data_dir, tmp_path):
    from ringtune.envs.printer import load_printer

    fits = _fits([data_dir / "accel" / ENDER3[0]])
    path = tmp_path / "p.toml"
    path.write_text(_toml(fits))
    p = load_printer(path)
    base = load_printer(None)
    assert [m.freq for m in p.y.modes] == pytest.approx([m.freq for m in base.y.modes], rel=1e-3)


def test_real_m956_captures_are_fitted_and_flagged(data_dir):
    paths = sorted((data_dir / "accel" / "rrf_m956").rglob("*.csv"))
    fits = _fits(paths)
    assert [f.axis for f in fits] == ["x", "y"] and all(f.kind == "decay" for f in fits)
    for fit in fits:
        assert all(5 <= m.freq <= 150 and 0 < m.damping <= 0.6 for m in fit.modes)
        assert sum(m.share for m in fit.modes) == pytest.approx(1.0)
    # these captures hold little clean ringing: the fit says so rather than pretending
    assert fits[0].r2 < 0.5 and any("noise" in n for n in fits[0].warnings)


def test_raw_klipper_sweep_capture_end_to_end(tmp_path):
    """A raw capture of a simulated sweep (one 50 Hz mode) -> Klipper's PSD -> fitted mode."""
    from scipy import signal

    fs, f0, f1, rate_hz = 1600.0, 20.0, 80.0, 6.0          # sweep 20 -> 80 Hz at 6 Hz/s
    t = np.arange(0, (f1 - f0) / rate_hz, 1 / fs)
    freq = f0 + rate_hz * t
    cmd = 60.0 * freq * np.sin(2 * np.pi * np.cumsum(freq) / fs)     # accel_per_hz = 60 mm/s²/Hz
    w, z = 2 * np.pi * 50.0, 0.05
    # absolute accel / commanded accel of a base-excited mode, discretised (bilinear)
    num, den = signal.zpk2tf(*signal.bilinear_zpk(*signal.tf2zpk([2 * z * w, w * w], [1, 2 * z * w, w * w]), fs))
    meas = signal.lfilter(num, den, cmd)
    rng = np.random.default_rng(0)
    path = tmp_path / "raw_data_x_20240101_000000.csv"
    with path.open("w") as fh:
        fh.write("#time,accel_x,accel_y,accel_z\n")
        noise = rng.normal(0, 5, (t.size, 3))
        np.savetxt(fh, np.column_stack([t, meas + noise[:, 0], noise[:, 1], 9806.65 + noise[:, 2]]),
                   fmt="%.6f", delimiter=",")
    fits = _fits([path], fmin=22, fmax=78, max_modes=1)
    assert fits[0].axis == "x" and fits[0].kind == "psd"
    assert fits[0].modes[0].freq == pytest.approx(50.0, abs=1.0)
