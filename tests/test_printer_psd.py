"""The embedded printers against the real measurements their modes were read from, and the
simulated resonance test (Klipper TEST_RESONANCES-like PSD)."""

from __future__ import annotations

import numpy as np
import pytest

from ringtune.envs.printer import load_printer, printer_from_dict
from ringtune.envs.sim import resonance_test

FILES = {
    ("ender3", "x"): "bassco_ender3/resonances_x_20210821_152037.csv",
    ("ender3", "y"): "bassco_ender3/resonances_y_20210630_230110.csv",
    ("voron24", "x"): "bassco_voron_v24/resonances_x_20230306_224517.csv",
    ("voron24", "y"): "bassco_voron_v24/resonances_y_20230306_224919.csv",
}


@pytest.mark.parametrize("printer,axis", list(FILES))
def test_embedded_modes_reproduce_the_measured_psd(data_dir, printer, axis):
    d = np.genfromtxt(data_dir / "accel" / "klipper_psd" / FILES[(printer, axis)], delimiter=",", names=True)
    fm, pm = d["freq"], d[f"psd_{axis}"]
    f, p = resonance_test(load_printer(printer), axis)
    band = (fm >= 20) & (fm <= 130)
    sim = np.interp(fm[band], f, p)
    meas = pm[band]
    # main peak within two bins
    assert abs(fm[band][np.argmax(sim)] - fm[band][np.argmax(meas)]) <= 2 * (fm[1] - fm[0]) + 1e-9
    # the shape agrees (correlation of the spectra in the sweep band)
    assert np.corrcoef(sim, meas)[0, 1] > 0.9


def test_resonance_test_of_one_mode_follows_the_excitation_model():
    """One mode: PSD = (60 f)²|T(f)|²/(2·130) + floor on Klipper's bins, with the textbook base
    transmissibility T = (2ζωs + ω²)/(s² + 2ζωs + ω²); peak at the mode."""
    p = printer_from_dict({"x": {"modes": [{"freq": 60.0, "damping": 0.08}]}, "y": {"modes": [{"freq": 40}]}})
    f, psd = resonance_test(p, "x")
    assert f[1] - f[0] == pytest.approx(3200 / 2048)
    assert f[-1] <= 200.0 < f[-1] + f[1]
    s, w, z = 2j * np.pi * f, 2 * np.pi * 60.0, 0.08
    T = (2 * z * w * s + w * w) / (s * s + 2 * z * w * s + w * w)
    inside = (f >= 5) & (f <= 135)
    expect = np.where(inside, (60.0 * f) ** 2 * np.abs(T) ** 2 / (2 * 130.0), 0.0) + 50.0
    np.testing.assert_allclose(psd, expect, rtol=1e-9)
    assert abs(f[np.argmax(psd)] - 60.0) < 2.0
    assert np.all(psd[f > 140] == 50.0)


def test_resonance_test_noise_is_seeded():
    p = load_printer(None)
    a = resonance_test(p, "y", rng=np.random.default_rng(7))[1]
    b = resonance_test(p, "y", rng=np.random.default_rng(7))[1]
    c = resonance_test(p, "y", rng=np.random.default_rng(8))[1]
    clean = resonance_test(p, "y")[1]
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    assert 0.7 < a.sum() / clean.sum() < 1.3


def test_corexy_resonance_test_sees_the_y_mode():
    f, p = resonance_test(load_printer("voron24"), "y")
    assert abs(f[np.argmax(p)] - 41.9) < 2.0
