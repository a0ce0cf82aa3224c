"""Kalico's smooth shapers against numbers computed here from Kalico's own source formulas
(KalicoCrew/kalico 8b9f661: klippy/extras/shaper_defs.py, input_shaper.py, chelper/integrate.c),
independently of ringtune's module: the kernel and its normalisation, the centring offset, the
remaining vibration (shaper_defs' V_c/V_s integrals, by adaptive quadrature), the smoothing, the
shaped motion (the convolution integral, by adaptive quadrature), a simulated mode's ringing, and
the Kalico record's commands."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad

from ringtune.envs.lti import response
from ringtune.envs.mujoco_model import linear_system
from ringtune.envs.printer import printer_from_dict
from ringtune.hardware.dialects import export_config
from ringtune.hardware.readback import parse_report
from ringtune.shaping.analysis import residual_vibration, smoothing
from ringtune.shaping.apply import shape_motion
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.firmware import FIRMWARES
from ringtune.shaping.motion import Motion
from ringtune.shaping.shapers import available_shapers, get_shaper

# shaper_defs.py (8b9f661): get_<x>_smoother coefficient lists (highest power first) and T_sm·f
SOURCE = {
    "smooth_zv": ([-118.4265334338076, 5.861885495127615, 29.52796003014231, -1.465471373781904,
                   0.01966833207740377], 0.8025),
    "smooth_mzv": ([-1906.717580206364, 125.8892756660212, 698.0200035767849, -37.75923018121473,
                    -62.18762409216703, 1.57172781617736, 1.713117990217123], 0.95625),
    "smooth_ei": ([-1797.048868963208, 120.5310596109878, 669.6653197989012, -35.71975707450795,
                   -62.49388325512682, 1.396748042940248, 1.848276903900512], 1.06625),
    "smooth_2hump_ei": ([-22525.88434486782, 2524.826047114184, 10554.22832043971, -1051.778387878068,
                         -1475.914693073253, 121.2177946817349, 57.95603221424528, -4.018706414213658,
                         0.8375784787864095], 1.14875),
    "smooth_si": ([-6186.76006449789, 1206.747198930197, 2579.985143622855, -476.8554763069169,
                   -295.546608490564, 52.69679971161049, 4.234582468800491, -2.226157642004671,
                   1.267781046297883], 1.245),
    "smooth_zvd_ei": ([-18835.07746719777, 1914.349309746547, 8786.608981369287, -807.3061869131075,
                       -1209.429748155012, 96.48879052981883, 43.1595785340444, -3.577268915175282,
                       1.083220648523371], 1.475),
}
NAMES = sorted(SOURCE)
FREQ = 37.3


def source_kernel(name: str, freq: float):
    """Kalico's path: init_smoother(normalize_coeffs=False) reverses the list; integrate.c's
    init_smoother divides a[i] by t_sm^(i+1), then by the kernel's integral over [-hst, hst];
    t_offs is get_smoother_offset(C, t_sm, normalized=False). Returns (w(τ), t_sm, hst, t_offs)."""
    coeffs, k = SOURCE[name]
    t_sm = k / freq
    a = list(reversed(coeffs))
    c = [a[i] / t_sm ** (i + 1) for i in range(len(a))]
    hst = 0.5 * t_sm
    norm = sum(ci * (hst ** (i + 1) - (-hst) ** (i + 1)) / (i + 1) for i, ci in enumerate(c))
    c = [ci / norm for ci in c]
    int_t0 = sum(ci / (2 ** i * (i + 1)) for i, ci in enumerate(a) if not i & 1)
    int_t1 = sum(ci / (2 ** (i + 1) * (i + 2)) for i, ci in enumerate(a) if i & 1) * t_sm
    return (lambda tau: sum(ci * tau ** i for i, ci in enumerate(c))), t_sm, hst, int_t1 / int_t0


def test_the_kalico_record_offers_its_smoothers():
    assert set(NAMES) <= set(available_shapers("kalico")) and FIRMWARES["kalico"].flavor == "kalico"
    assert not any(n.startswith("smooth_") for n in available_shapers("klipper"))


@pytest.mark.parametrize("name", NAMES)
def test_kernel_support_and_centring_are_kalicos(name):
    w, t_sm, hst, t_offs = source_kernel(name, FREQ)
    s = get_shaper(name, FREQ, None, "kalico")
    assert s.duration == pytest.approx(t_sm, abs=1e-15) and s.offset == pytest.approx(t_offs, abs=1e-12)
    mine = np.polynomial.Polynomial(s.coeffs)
    for tau in np.linspace(-hst, hst, 41):
        assert mine(tau) == pytest.approx(w(tau), rel=1e-6, abs=1e-6 * abs(w(0.3 * hst)))
    # integrate.c's t_offs is ∫ τ w: the same number as shaper_defs' closed form
    assert quad(lambda t: t * w(t), -hst, hst, epsabs=1e-15)[0] == pytest.approx(t_offs, abs=1e-10)
    assert s.centroid == pytest.approx(hst + t_offs, abs=1e-12)       # centred on it: no lag


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("f_plant,zeta", [(FREQ, 0.1), (0.8 * FREQ, 0.05), (1.7 * FREQ, 0.0), (3.1 * FREQ, 0.15)])
def test_remaining_vibration_is_shaper_defs_integral(name, f_plant, zeta):
    """V = |∫_0^T_sm e^{−ζωt}(cos, sin)(ω_d t)·w(T_sm/2 − t) dt| (the comment above get_zv_smoother)."""
    w, t_sm, hst, _ = source_kernel(name, FREQ)
    om = 2 * math.pi * f_plant
    od = om * math.sqrt(1 - zeta ** 2)
    vc = quad(lambda t: math.exp(-zeta * om * t) * math.cos(od * t) * w(hst - t), 0, t_sm, epsabs=1e-13, limit=200)[0]
    vs = quad(lambda t: math.exp(-zeta * om * t) * math.sin(od * t) * w(hst - t), 0, t_sm, epsabs=1e-13, limit=200)[0]
    s = get_shaper(name, FREQ, None, "kalico")
    assert float(residual_vibration(s, [f_plant], zeta)[0]) == pytest.approx(math.hypot(vc, vs), abs=1e-6)


@pytest.mark.parametrize("name", NAMES)
def test_smoothing_is_the_kernels_own(name):
    """Klipper's smoothing (90° corner at scv, 180° reversal) of the continuous kernel about its
    centroid: √2·∫_{u≥0} w·(scv + a/2·u)·u and a/2·∫ w·u², by adaptive quadrature."""
    w, t_sm, hst, t_offs = source_kernel(name, FREQ)
    accel, scv = 5000.0, 5.0
    o90 = math.sqrt(2) * quad(lambda t: w(t) * (scv + 0.5 * accel * (t - t_offs)) * (t - t_offs), t_offs, hst,
                              epsabs=1e-14)[0]
    o180 = 0.5 * accel * quad(lambda t: w(t) * (t - t_offs) ** 2, -hst, hst, epsabs=1e-14)[0]
    assert smoothing(get_shaper(name, FREQ, None, "kalico"), accel, scv) == pytest.approx(max(o90, o180), rel=1e-6)


def _trapezoid() -> Motion:
    """0 -> 100 mm/s at 4000 mm/s², 60 mm/s² cruise, brake to rest, along x."""
    ta, tc = 0.025, 0.05
    t = np.array([0.0, ta, ta + tc, 2 * ta + tc])
    v = np.array([0.0, 100.0, 100.0])
    a = np.array([4000.0, 0.0, -4000.0])
    p = np.array([0.0, 1.25, 6.25])
    z = np.zeros(3)
    return Motion(t, np.stack([p, z, z, z], 1), np.stack([v, z, z, z], 1), np.stack([a, z, z, z], 1))


@pytest.mark.parametrize("name", ["smooth_zv", "smooth_mzv", "smooth_si"])
def test_shaped_motion_is_kalicos_convolution(name):
    """x_sm(t) = ∫ w(τ)·x(t + t_offs − τ) dτ (range_integrate), against shape_motion."""
    w, t_sm, hst, t_offs = source_kernel(name, 60.0)
    mo = _trapezoid()
    shaped = shape_motion(mo, {"x": get_shaper(name, 60.0, None, "kalico")}, centred=True)
    times = np.linspace(-0.02, 0.12, 57)
    breaks = list(mo.t)
    for t in times:
        pts = [b for b in (t + t_offs - np.array(breaks)) if -hst < b < hst]
        x = quad(lambda tau: w(tau) * mo.position(np.array([t + t_offs - tau]))[0, 0], -hst, hst,
                 points=pts or None, epsabs=1e-12, limit=200)[0]
        assert shaped.position(np.array([t]))[0, 0] == pytest.approx(x, abs=1e-6)      # mm


def _ringing_amplitude(t, q, zeta, freq):
    """Amplitude (referred to t = 0) of the damped oscillation in q(t): least squares on
    e^{−ζωt}·(cos, sin)(ω_d t) and a constant."""
    om = 2 * math.pi * freq
    od = om * math.sqrt(1 - zeta ** 2)
    decay = np.exp(-zeta * om * t)
    basis = np.stack([decay * np.cos(od * t), decay * np.sin(od * t), np.ones_like(t)], axis=1)
    c = np.linalg.lstsq(basis, q, rcond=None)[0]
    return math.hypot(c[0], c[1])


@pytest.mark.parametrize("name", ["smooth_mzv", "smooth_ei", "smooth_zvd_ei"])
def test_a_simulated_mode_rings_as_the_remaining_vibration_says(name):
    """One mode (rigid motor), lightly damped: after an acceleration step has passed through the
    smoother, the mode rings at V times its unshaped amplitude, V the remaining vibration."""
    zeta = 0.02
    printer = printer_from_dict({"name": "one", "kinematics": "cartesian", "motor": {"slip": False},
                                 "x": {"mass": 0.5, "modes": [{"freq": 40.0, "damping": zeta}]},
                                 "y": {"mass": 0.5, "modes": [{"freq": 40.0, "damping": zeta}]}}, "one")
    step = Motion(np.array([0.0, 0.4]), np.zeros((1, 4)), np.zeros((1, 4)), np.array([[1000.0, 0, 0, 0]]))
    s = get_shaper(name, 45.0, zeta, "kalico")
    sysm = linear_system(printer)
    t = np.linspace(0.1, 0.3, 4001)
    amp = []
    for m in (step, shape_motion(step, {"x": s}, centred=True)):
        q, _ = response(sysm, m, np.concatenate([[m.start_time], t]))
        amp.append(_ringing_amplitude(t, q[1:, 0], zeta, 40.0))
    last = s.duration - s.centre_delay              # the kernel's end, on the centred clock
    measured = amp[1] / amp[0] * math.exp(-zeta * 2 * math.pi * 40.0 * last)
    assert measured == pytest.approx(float(residual_vibration(s, [40.0], zeta)[0]), rel=1e-3)


def test_kalicos_commands_for_a_smoother():
    cfg = TuneConfig(firmware="kalico", shaper_x="smooth_mzv", freq_x=45.0, shaper_y="ei", freq_y=40.0,
                     damping_y=0.08)
    e = export_config(cfg, "kalico")
    line = e.lines[0]
    assert "SHAPER_TYPE_X=smooth_mzv" in line and "SMOOTHER_FREQ_X=45" in line
    assert "DAMPING_RATIO_X" not in line and "SHAPER_FREQ_Y=40" in line and "DAMPING_RATIO_Y=0.08" in line
    # input_shaper.py's status of a smoother: shaper_type_x:<type> smoother_freq_x:%.3f
    got = parse_report("kalico", "// shaper_type_x:smooth_mzv smoother_freq_x:45.000 "
                                 "shaper_type_y:ei shaper_freq_y:40.000 damping_ratio_y:0.080000")
    assert got["x.type"].value == "smooth_mzv" and float(got["x.freq"].value) == 45.0
    assert float(got["y.damping"].value) == pytest.approx(0.08)
