"""Shaper registry: firmware flavours, names, parameters, errors, and Klipper's worked numbers
(reference/firmware.md §1.6 — acceptance 4 of issue 2)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ringtune.shaping.analysis import max_accel, smoothing
from ringtune.shaping.custom import rrf_custom
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.shaper_formulas import marlin_factors, mzv_coeffs
from ringtune.shaping.shapers import FLAVORS, available_shapers, canonical_name, get_shaper, is_centred, max_damping

# firmware.md §1.6: f = 40 Hz, Klipper HEAD; A normalised, T in ms, smoothing at 5000/5, max_accel
KLIPPER_TABLE = [
    ("zv", 0.1, [0.5783, 0.4217], [0, 12.563], 0.1004, 6235),
    ("zv", 0.0, [0.5, 0.5], [0, 12.5], 0.0977, 6144),
    ("mzv", 0.1, [0.3651, 0.4075, 0.2274], [0, 9.422, 18.844], 0.1273, 4713),
    ("mzv", 0.0, [0.2929, 0.4142, 0.2929], [0, 9.375, 18.75], 0.1287, 4662),
    ("zvd", 0.1, [0.3344, 0.4877, 0.1778], [0, 12.563, 25.126], 0.1924, 3118),
    ("ei", 0.1, [0.3549, 0.4530, 0.1921], [0, 12.681, 25.126], 0.2059, 2914),
    ("ei", 0.0, [0.2622, 0.4756, 0.2622], [0, 12.498, 25.0], 0.2048, 2929),
    ("2hump_ei", 0.1, [0.2585, 0.3599, 0.2728, 0.1088], [0, 12.898, 25.205, 37.223], 0.3539, 1570),
    ("3hump_ei", 0.1, [0.2209, 0.2772, 0.2597, 0.1671, 0.0752], [0, 13.513, 25.701, 37.647, 49.573],
     0.5651, 874),
]


@pytest.mark.parametrize("name,z,amps,times_ms,smooth,maxacc", KLIPPER_TABLE)
def test_klipper_flavour_reproduces_firmware_md_worked_numbers(name, z, amps, times_ms, smooth, maxacc):
    s = get_shaper(name, 40.0, z, "klipper")
    np.testing.assert_allclose(s.amplitudes, amps, atol=5e-5)
    np.testing.assert_allclose(s.times * 1e3, times_ms, atol=5e-4)
    assert smoothing(s, 5000, 5) == pytest.approx(smooth, abs=5e-5)
    assert abs(max_accel(s, 5) - maxacc) <= 0.5          # table prints the bisection result to 1 mm/s²


def test_available_shapers_per_firmware():
    assert set(available_shapers("klipper")) == {"none", "zv", "mzv", "zvd", "ei", "2hump_ei", "3hump_ei"}
    assert set(available_shapers("rrf")) == {"none", "zvd", "zvdd", "zvddd", "mzv", "2hump_ei", "3hump_ei",
                                              "custom"}
    assert set(available_shapers("rrf35")) == set(available_shapers("rrf"))
    assert set(available_shapers("marlin")) == {"none", "zv"}
    assert set(available_shapers("marlin-ftm")) == {"none", "zv", "zvd", "zvdd", "zvddd", "ei", "2hump_ei",
                                                     "3hump_ei", "mzv"}
    assert set(available_shapers("kalico")) == {"none", "zv", "mzv", "zvd", "ei", "2hump_ei", "3hump_ei", "smooth_zv",
                                                 "smooth_mzv", "smooth_ei", "smooth_2hump_ei", "smooth_zvd_ei",
                                                 "smooth_si"}
    assert [is_centred(f) for f in FLAVORS] == [True, True, True, False, False, False, True]


@pytest.mark.parametrize("flavor,name,closest", [
    ("rrf", "zv", "mzv"), ("rrf", "ei", "zvd"), ("rrf35", "zv", "mzv"), ("klipper", "zvdd", "2hump_ei"),
    ("klipper", "zvddd", "3hump_ei"), ("marlin", "mzv", "zv"), ("marlin", "ei3", "zv"),
    ("klipper", "custom", "zvd"), ("klipper-legacy", "zvdd", "2hump_ei"),
])
def test_missing_shaper_names_the_closest_available(flavor, name, closest):
    with pytest.raises(RingtuneError) as err:
        get_shaper(name, 40.0, 0.1, flavor)
    assert f"closest it offers is {closest!r}" in str(err.value)
    assert flavor in str(err.value)


def test_aliases_and_case():
    for alias in ("ei2", "EI2", "2hei", "2hump_ei", "2HUMP-EI"):
        assert canonical_name(alias) == "2hump_ei"
    a = get_shaper("ei3", 45, 0.1, "rrf")
    b = get_shaper("3hump_ei", 45, 0.1, "rrf")
    np.testing.assert_array_equal(a.amplitudes, b.amplitudes)
    np.testing.assert_array_equal(a.times, b.times)


def test_none_shaper_is_identity_everywhere():
    for flavor in FLAVORS:
        s = get_shaper("none", 40, None, flavor)
        assert s.amplitudes.tolist() == [1.0] and s.times.tolist() == [0.0]


def test_default_damping_per_flavour():
    assert get_shaper("zv", 40, None, "klipper").damping == 0.1
    assert get_shaper("zv", 40, None, "marlin").damping == 0.15


def test_parameterised_mzv_default_equals_closed_form():
    """mzv(n=3, t=0.75) reproduces the legacy closed form; the generalised solver zeroes the
    vibration at 1 + k/tau (k = 0..n-2) design multiples."""
    a = get_shaper("mzv(n=3,t=0.75)", 40, 0.1)
    b = get_shaper("mzv", 40, 0.1, "klipper-legacy")
    np.testing.assert_allclose(a.amplitudes, b.amplitudes, atol=1e-12)
    np.testing.assert_allclose(a.times, b.times, atol=1e-15)
    for n, t in [(5, 1.1), (4, 1.0), (6, 1.0)]:
        coeffs = mzv_coeffs(n, t)
        tau = t * (n - 2) / (n - 2 * t - 1)
        T = np.arange(n) * t / (n - 1)
        for k in range(n - 1):
            w = 2 * math.pi * (1 + k / tau) * T
            assert abs(np.sum(coeffs * np.exp(1j * w))) < 1e-9
        assert coeffs.sum() == pytest.approx(1)


def test_mzv_defaults_and_limits_follow_klippers_get_mzv_shaper():
    """Klipper HEAD: t = tau = 0 (unset) means t = 0.75; tau wins over t; n <= 2t + 1 + 1e-7 is an
    error (the 1e-7 margin included)."""
    base = get_shaper("mzv(n=5,t=0.75)", 40, 0.1)
    for form in ("mzv(n=5)", "mzv(n=5,t=0)", "mzv(5)"):
        np.testing.assert_array_equal(get_shaper(form, 40, 0.1).times, base.times)
    tau = 1.1 * 3 / (5 - 2.2 - 1)
    np.testing.assert_allclose(get_shaper(f"mzv(n=5,t=0.5,tau={tau!r})", 40, 0.1).times,
                               get_shaper("mzv(n=5,t=1.1)", 40, 0.1).times, rtol=1e-12)
    get_shaper("mzv(n=3,t=0.9999)", 40, 0.1)
    with pytest.raises(RingtuneError, match="n > 2t"):
        get_shaper("mzv(n=3,t=0.99999996)", 40, 0.1)


def test_parameter_forms_and_their_errors():
    named = get_shaper("mzv(n=5,t=1.1)", 40, 0.1)
    positional = get_shaper("mzv(5, 1.1)", 40, 0.1)
    np.testing.assert_allclose(named.amplitudes, positional.amplitudes)
    assert named.n_impulses == 5 and named.name == "mzv(n=5,t=1.1)"
    tau_form = get_shaper("mzv(n=5,tau=%r)" % (1.1 * 3 / (5 - 2.2 - 1)), 40, 0.1)
    np.testing.assert_allclose(tau_form.times, named.times, rtol=1e-12)
    loose = get_shaper("ei(v_tol=0.1)", 40, 0.0)
    assert loose.amplitudes[0] > get_shaper("ei", 40, 0.0).amplitudes[0]
    with pytest.raises(RingtuneError, match="n >= 3"):
        get_shaper("mzv(n=3,t=1.0)", 40, 0.1)
    with pytest.raises(RingtuneError, match="not both"):
        get_shaper("mzv(5,t=1.1)", 40, 0.1)
    with pytest.raises(RingtuneError, match="no parameter"):
        get_shaper("zv(n=3)", 40, 0.1)
    with pytest.raises(RingtuneError, match="no parameter"):
        get_shaper("2hump_ei(v_tol=0.1)", 40, 0.1, "klipper")   # Klipper HEAD: no v_tol for 2/3-hump
    with pytest.raises(RingtuneError, match="cannot parse"):
        get_shaper("mzv(n=3", 40, 0.1)


@pytest.mark.parametrize("freq,damping", [(0, 0.1), (-3, 0.1), (float("nan"), 0.1), (40, -0.1), (40, 1.0),
                                          (40, float("inf"))])
def test_bad_frequency_or_damping_is_a_clear_error(freq, damping):
    with pytest.raises(RingtuneError):
        get_shaper("zvd", freq, damping, "rrf")


def test_klipper_max_damping_limits():
    assert max_damping("ei", "klipper") == 0.4
    assert max_damping("3hump_ei", "klipper") == 0.2
    with pytest.raises(RingtuneError, match=r"\[0, 0.3\]"):
        get_shaper("2hump_ei", 40, 0.35, "klipper")
    get_shaper("2hump_ei", 40, 0.35, "klipper-legacy")  # no limit before v0.13


def test_unknown_names():
    with pytest.raises(RingtuneError, match="unknown shaper"):
        get_shaper("foo", 40)
    with pytest.raises(RingtuneError, match="unknown shaper flavour"):
        get_shaper("zv", 40, flavor="grbl")


# -- firmware specifics ----------------------------------------------------------------------------
def test_marlin_classic_zv_weights_and_undamped_half_period():
    """factor2 = floor(poly(ζ)) approximates 128·K/(1+K) (1:7 fixed point); delay 1/(2F)."""
    for z in np.linspace(0.0, 0.9, 19):
        f1, f2 = marlin_factors(z)
        k = math.exp(-z * math.pi / math.sqrt(1 - z * z))
        assert f1 + f2 == 128
        assert abs(f2 - 128 * k / (1 + k)) < 1.5
    assert marlin_factors(0.0) == (64, 64) and marlin_factors(1.0) == (128, 0)
    s = get_shaper("zv", 35, 0.15, "marlin")
    assert s.amplitudes.tolist() == [79 / 128, 49 / 128]
    assert s.times[1] == pytest.approx(1 / 70)                 # not 1/(2·F·sqrt(1-ζ²))


def test_marlin_ftm_quantises_to_1ms_and_uses_its_own_mzv_damping():
    for name in available_shapers("marlin-ftm")[1:]:
        s = get_shaper(name, 37.0, 0.1, "marlin-ftm")
        np.testing.assert_allclose(s.times * 1000, np.round(s.times * 1000), atol=1e-9)
        assert s.centre_delay * 1000 == pytest.approx(round(s.centroid * 1000))
    m = get_shaper("mzv", 40, 0.1, "marlin-ftm")
    k = math.exp(-0.1 * math.pi / math.sqrt(0.99))
    np.testing.assert_allclose(m.amplitudes, np.array([1, math.sqrt(2) * k, k * k]) / (1 + math.sqrt(2) * k + k * k))
    # N1 = LROUND(0.375/f/df·1000) = LROUND(9.422) = 9 samples
    np.testing.assert_allclose(m.times, [0, 0.009, 0.018])


def test_rrf_delays_are_whole_step_clocks_and_ei2_uses_the_damped_period():
    s = get_shaper("ei2", 40, 0.1, "rrf")
    clocks = s.times * 750_000
    np.testing.assert_allclose(clocks, np.round(clocks), atol=1e-6)
    k = get_shaper("2hump_ei", 40, 0.1, "klipper")
    np.testing.assert_allclose(s.times, k.times / math.sqrt(1 - 0.01), rtol=2e-4)   # × t_d, not × 1/f
    # first three amplitudes are the raw 2hump_ei polynomials at ζ = 0.1, the last takes 1 − Σ
    z = 0.1
    first = 0.16054 + 0.76699 * z + 2.26560 * z ** 2 - 1.22750 * z ** 3
    assert s.amplitudes[0] == pytest.approx(first, rel=1e-12)
    assert s.amplitudes[3] == pytest.approx(1 - s.amplitudes[:3].sum(), rel=1e-12)


def _rrf36_reference(name, f, z):
    """firmware.md §3.2 (RRF 3.6-dev), transcribed directly: P = lrintf(750 kHz/(f·df)) whole
    clocks; zvd-family delays (i·P)/2 and MZV (3P)/8, 2·((3P)/8) by INTEGER division; MZV
    amplitudes [a3, a2, a1]/Σ (reversed against Klipper); last amplitude = 1 − Σ others."""
    df = math.sqrt(1 - z * z)
    P = round(750_000 / (f * df))
    k = math.exp(-z * math.pi / df)
    if name == "mzv":
        km = math.exp(-0.75 * z * math.pi / df)
        a1, a2, a3 = 1 - math.sqrt(2) / 2, (math.sqrt(2) - 1) * km, (1 - math.sqrt(2) / 2) * km * km
        c = [a3 / (a1 + a2 + a3), a2 / (a1 + a2 + a3)]
        d = [0, 3 * P // 8, 2 * (3 * P // 8)]
    else:
        n = {"zvd": 2, "zvdd": 3, "zvddd": 4}[name]
        c = [math.comb(n, i) * k ** i / (1 + k) ** n for i in range(n)]
        d = [i * P // 2 for i in range(n + 1)]
    return c + [1 - sum(c)], [x / 750_000 for x in d]


@pytest.mark.parametrize("name", ["mzv", "zvd", "zvdd", "zvddd"])
@pytest.mark.parametrize("f,z", [(40.0, 0.1), (750_000 / 18751, 0.0), (31.3, 0.05), (57.0, 0.2)])
def test_rrf36_matches_the_firmware_formulas(name, f, z):
    """f = 750000/18751 Hz makes P odd: (i·P)/2 and (3P)/8 truncate where rounding would not."""
    s = get_shaper(name, f, z, "rrf")
    a, t = _rrf36_reference(name, f, z)
    np.testing.assert_allclose(s.amplitudes, a, rtol=1e-12, atol=1e-15)
    np.testing.assert_array_equal(np.round(s.times * 750_000), np.round(np.array(t) * 750_000))
    np.testing.assert_allclose(s.times, t, rtol=0, atol=1e-15)


def test_rrf36_mzv_is_what_m593_reports():
    """M593 P"mzv" F40 S0.1 on RRF 3.6 reports "impulses 0.227 0.407 0.365 with delays (ms)
    0.00 9.42 18.84": 3P/8 = 7066 clocks (P = 18844), not Klipper's 0.375·t_d = 7066.67."""
    s = get_shaper("mzv", 40, 0.1, "rrf")
    assert [f"{a:.3f}" for a in s.amplitudes] == ["0.227", "0.407", "0.365"]
    assert [f"{t * 1e3:.2f}" for t in s.times] == ["0.00", "9.42", "18.84"]
    assert (s.times * 750_000).tolist() == pytest.approx([0, 7066, 14132], abs=1e-6)


def test_rrf35_durations_are_unrounded_float_multiples_of_the_damped_period():
    """RRF 3.4/3.5 keep P = StepClockRate/(f·df) and its durations as floats: times are exact
    multiples of t_d; the MZV coefficients are cumulative [a3, a2 + a3]/Σ (same reversed order)."""
    f, z = 40.0, 0.1
    td = 1 / (f * math.sqrt(1 - z * z))
    np.testing.assert_allclose(get_shaper("zvdd", f, z, "rrf35").times, [0, td / 2, td, 1.5 * td], rtol=1e-12)
    m = get_shaper("mzv", f, z, "rrf35")
    np.testing.assert_allclose(m.times, [0, 0.375 * td, 0.75 * td], rtol=1e-12)
    np.testing.assert_allclose(m.amplitudes, get_shaper("mzv", f, z, "rrf").amplitudes, rtol=1e-12)
    e = get_shaper("ei2", f, z, "rrf35")
    z2, z3 = z * z, z ** 3
    durations = [((0.49890) + (0.16270) * z + (-0.54262) * z2 + (6.16180) * z3) * td,
                 ((0.99748 - 0.49890) + (0.18382 - 0.16270) * z + (-1.58270 + 0.54262) * z2
                  + (8.17120 - 6.16180) * z3) * td,
                 ((1.49920 - 0.99748) + (-0.09297 - 0.18382) * z + (-0.28338 + 1.58270) * z2
                  + (1.85710 - 8.17120) * z3) * td]
    np.testing.assert_allclose(np.diff(e.times), durations, rtol=1e-12)
    cumulative = [0.16054 + 0.76699 * z + 2.26560 * z2 - 1.22750 * z3,
                  (0.16054 + 0.33911) + (0.76699 + 0.45081) * z + (2.26560 - 2.58080) * z2
                  + (-1.22750 + 1.73650) * z3]
    np.testing.assert_allclose(np.cumsum(e.amplitudes)[:2], cumulative, rtol=1e-12)


def test_rrf36_ei_delays_are_rounded_clocks_of_the_integer_period():
    z = 0.1
    P = round(750_000 / (40 * math.sqrt(1 - z * z)))
    rows = [[0.49890, 0.16270, -0.54262, 6.16180], [0.99748, 0.18382, -1.58270, 8.17120],
            [1.49920, -0.09297, -0.28338, 1.85710]]
    want = [0] + [round(sum(c * z ** i for i, c in enumerate(r)) * P) for r in rows]
    assert (get_shaper("ei2", 40, z, "rrf").times * 750_000).round().tolist() == want


# -- custom (RRF) -------------------------------------------------------------------------------
def test_custom_rrf36_individual_amplitudes_and_cumulative_delays():
    a, t = rrf_custom([0.2, 0.3], [0.01, 0.025], 40, 0.1, semantics="3.6")
    np.testing.assert_allclose(a, [0.2, 0.3, 0.5])
    np.testing.assert_allclose(t, [0, 0.01, 0.025])
    a, t = rrf_custom([0.4], None, 40, 0.0, semantics="3.6")
    np.testing.assert_allclose(t, [0, 0.0125])                      # default i·t_d/2


def test_custom_rrf35_cumulative_amplitudes_and_durations():
    """The M593 example of the RRF 3.4/3.5 docs: H0.4:0.7 T0.0135:0.0135."""
    s = get_shaper("custom(h=0.4:0.7,t=0.0135:0.0135)", 40, 0.1, "rrf35")
    np.testing.assert_allclose(s.amplitudes, [0.4, 0.3, 0.3])
    np.testing.assert_allclose(s.times, [0, 0.0135, 0.027])
    s36 = get_shaper("custom", 40, 0.1, "rrf", h=[0.4, 0.3], t=[0.0135, 0.027])
    np.testing.assert_allclose(s36.amplitudes, s.amplitudes)
    np.testing.assert_allclose(s36.times, s.times)


def test_custom_rrf36_delays_become_whole_step_clocks():
    """RRF 3.6 stores custom delays as lrintf(T·750 kHz) and defaults to (P·i)/2 clocks."""
    s = get_shaper("custom", 40, 0.1, "rrf", h=[0.3, 0.3], t=[0.0123457, 0.0240001])
    assert (s.times * 750_000).tolist() == pytest.approx([0, 9259, 18000], abs=1e-6)   # 9259.275, 18000.075
    f = 750_000 / 18751                                                 # P = 18751 clocks at ζ = 0
    d = get_shaper("custom", f, 0.0, "rrf", h=[0.3, 0.3])
    assert (d.times * 750_000).tolist() == pytest.approx([0, 9375, 18751], abs=1e-6)


@pytest.mark.parametrize("h,t,sem,msg", [
    ([0.5, 0.5], None, "3.6", "sum to less than 1"),
    ([0.6, 0.7], None, "3.6", "sum to less than 1"),
    ([0.1] * 5, None, "3.6", "at most 4"),
    ([0.1, 0.2], [0.02, 0.01], "3.6", "strictly increasing"),
    ([0.1, 0.2], [0.0, 0.01], "3.6", "strictly increasing"),
    ([0.1, 0.2], [0.01], "3.6", "as many values as H"),
    ([0.7, 0.4], None, "3.5", "increase strictly"),
    ([0.4, 1.0], None, "3.5", "below 1"),
    ([0.4, 0.7], [0.01, -0.01], "3.5", "durations must be > 0"),
    ([], None, "3.6", "needs H"),
    (None, None, "3.5", "needs H"),
])
def test_custom_is_validated_like_the_firmware(h, t, sem, msg):
    with pytest.raises(RingtuneError, match=msg) as err:
        rrf_custom(h, t, 40, 0.1, semantics=sem)
    assert "M593" in str(err.value)


def test_custom_only_where_the_firmware_has_it():
    with pytest.raises(RingtuneError, match="klipper has no 'custom'"):
        get_shaper("custom(h=0.5)", 40, 0.1, "klipper")


def test_mzv_parameter_validation_and_pulse_limits():
    with pytest.raises(RingtuneError, match="t > 0"):
        get_shaper("mzv(n=4,t=-0.5)", 40, 0.1)
    with pytest.raises(RingtuneError, match="integer n"):
        get_shaper("mzv(n=4.5,t=1.0)", 40, 0.1)
    get_shaper("mzv(n=10,t=1.5)", 40, 0.1)
    with pytest.raises(RingtuneError, match="at most 10"):
        get_shaper("mzv(n=11,t=1.5)", 40, 0.1)          # Klipper kin_shaper.c: 10 pulses at HEAD


def test_shapers_compare_by_value_and_hash():
    a = get_shaper("ei", np.float64(40.0), np.float32(0.1))
    b = get_shaper("ei", 40, float(np.float32(0.1)))
    assert a == b and hash(a) == hash(b) and len({a, b}) == 1
    assert a != get_shaper("ei", 41, 0.1)
    with pytest.raises(ValueError):
        a.amplitudes[0] = 1.0                             # read-only


def test_shapers_from_config():
    from ringtune.shaping.config import TuneConfig
    from ringtune.shaping.shapers import shapers_from_config

    cfg = TuneConfig(firmware="prusa", shaper_x="mzv", shaper_y="none", freq_x=50.7, freq_y=40.6,
                     damping_x=0.1, damping_y=0.1)
    shapers, centred = shapers_from_config(cfg)
    assert centred is True and shapers["y"] is None
    assert shapers["x"] == get_shaper("mzv", 50.7, 0.1, "klipper-legacy")
    bad = TuneConfig(firmware="rrf", shaper_x="zv", shaper_y="zvd")
    with pytest.raises(RingtuneError, match="shaper_x.*closest it offers is 'mzv'"):
        shapers_from_config(bad)


def test_an_integer_parameter_written_with_a_point_gives_the_same_shaper_on_a_cold_cache():
    """``mzv(5.0, 1.1)`` is Klipper's mzv(n=5, t=1.1): the same impulses whether or not ``mzv(5, …)``
    was computed before (the coefficients' cache takes 5.0 for 5 either way)."""
    from ringtune.shaping.shaper_formulas import mzv_coeffs
    from ringtune.shaping.shapers import get_shaper

    mzv_coeffs.cache_clear()
    dotted = get_shaper("mzv(5.0, 1.1)", 40.0, 0.1)
    mzv_coeffs.cache_clear()
    plain = get_shaper("mzv(5, 1.1)", 40.0, 0.1)
    assert len(dotted.amplitudes) == 5
    np.testing.assert_array_equal(dotted.amplitudes, plain.amplitudes)
    np.testing.assert_array_equal(dotted.times, plain.times)
