"""What a person sees, each measure against an independent computation (issue 21 acceptance):

- ripple: a single-mode printer stops X into a corner and runs a wall along Y; the nozzle's
  deviation across the wall is the closed-form free decay of the mode after the acceleration
  step (the physics backends are checked against that closed form in test_physics_accuracy);
- corner rounding: a 90° corner shaped by each shaper, on a stiff machine, against the deepest
  cut of the shaped command computed here from the impulses by brute force;
- show-through and per-feature: hidden features are judged only by what reaches the walls (and
  their extrusion); the path-error bound counts visible samples only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from ringtune.envs.metrics import FEATURE_KEYS, Metrics
from ringtune.envs.printer import printer_from_dict
from ringtune.envs.sim import simulate
from ringtune.envs.window_metrics import compute_metrics
from ringtune.shaping.apply import shape_motion
from ringtune.shaping.features import FEATURE_CLASSES
from ringtune.shaping.motion import Motion
from ringtune.shaping.shapers import get_shaper

RATE = 200_000.0  # Hz, samples of the stiff (commanded) nozzle (kinks of the shaped path are sharp)


@dataclass
class StiffSim:
    """A nozzle that is exactly where the (shaped) command is: a stiff machine."""

    t: np.ndarray
    nozzle: np.ndarray
    head_accel: np.ndarray
    step_loss: bool = False


def stiff(shaped: Motion, rate: float = RATE) -> StiffSim:
    t = np.arange(shaped.t[0], shaped.t[-1], 1.0 / rate)
    return StiffSim(t, shaped.position(t)[:, :2], np.zeros((len(t), 2)))


def free_decay(tau, a, freq, z):
    """Relative deflection after a commanded acceleration step ``a`` at τ = 0 from rest
    (mm): −(a/ω²)(1 − e^(−ζωτ)(cos ω_dτ + ζ/√(1−ζ²) sin ω_dτ)), 0 before."""
    w = 2 * math.pi * freq
    wd = w * math.sqrt(1 - z * z)
    tau = np.asarray(tau, float)
    e = np.exp(-z * w * np.maximum(tau, 0.0))
    q = -(a / w ** 2) * (1 - e * (np.cos(wd * tau) + z / math.sqrt(1 - z * z) * np.sin(wd * tau)))
    return np.where(tau >= 0, q, 0.0)


def corner_motion(v: float, a: float, cruise: float = 0.1, wall: float = 0.15) -> tuple[Motion, float, float]:
    """X at v, decelerates at a to rest at the corner (t_c); then Y accelerates at a to v and
    cruises along the wall, and stops. Returns (motion, t_c, t_end)."""
    td = v / a
    t = np.cumsum([0.0, cruise, td, td, wall, td])
    acc = np.array([[0, 0], [-a, 0], [0, a], [0, 0], [0, -a]], float)
    acc4 = np.hstack([acc, np.zeros((5, 1)), np.zeros((5, 1))])
    mo = Motion.from_constant_accel(t, acc4, p0=[0.0, 0.0, 0.2, 0.0], v0=[v, 0.0, 0.0, 0.0],
                                    extruding=np.ones(5, bool))
    return mo, float(t[2]), float(t[-1])


@pytest.mark.parametrize("backend, tol", [("lti", 0.005), ("mujoco", 0.02)])
@pytest.mark.parametrize("freq, z", [(40.0, 0.05), (62.0, 0.1)])
def test_ripple_of_one_mode_after_an_acceleration_step_is_the_free_decay(backend, tol, freq, z):
    v, a = 100.0, 5000.0
    printer = printer_from_dict({"x": {"modes": [{"freq": freq, "damping": z}]},
                                 "y": {"modes": [{"freq": 0.8 * freq, "damping": z}]},
                                 "motor": {"slip": False}})
    mo, tc, t_end = corner_motion(v, a)
    sim = simulate(printer, mo, backend=backend, initial="static")
    m = compute_metrics(sim, mo, corner_tail=0.0)
    # the wall along Y is measured from the corner to its end: X's deviation is the response to
    # the deceleration step −a at t_c − v/a and the step back to 0 at t_c
    tau = np.linspace(tc, t_end, 200_001)
    q = free_decay(tau - (tc - v / a), -a, freq, z) + free_decay(tau - tc, a, freq, z)
    expected = q.max() - q.min()
    assert m.ripple_mm == pytest.approx(expected, rel=tol)
    assert m.ripple_mm > 0.5 * a / (2 * math.pi * freq) ** 2     # a real ripple, not noise
    assert m.ripple_p90_mm <= m.ripple_mm


def test_ripple_worked_example_of_the_docstring():
    """metrics docstring: a/ω² = 0.079 mm at 5000 mm/s², 40 Hz; 0.147 mm peak-to-peak over 0.1 s
    (the deceleration lasts long enough for the mode to settle at a/ω² before the corner)."""
    a, f, z = 5000.0, 40.0, 0.05
    w = 2 * math.pi * f
    q0 = a / w ** 2
    assert q0 == pytest.approx(0.0792, abs=5e-4)
    assert q0 * (1 + math.exp(-z * math.pi / math.sqrt(1 - z * z))) == pytest.approx(0.147, abs=1e-3)


def _deepest_cut(points: np.ndarray, corner: np.ndarray, d_in: np.ndarray, d_out: np.ndarray) -> float:
    """Largest distance inside a corner (apex ``corner``, legs along −d_in and +d_out) of points,
    by brute force: the distance to the nearer leg of the points on the inner side of both legs."""
    rel = points - corner
    n_in = np.array([-d_in[1], d_in[0]])
    n_out = np.array([-d_out[1], d_out[0]])
    side = np.sign(d_in[0] * d_out[1] - d_in[1] * d_out[0])   # +1: left turn, the inside is on the left
    inner = (side * rel @ n_in > 0) & (side * rel @ n_out > 0)
    along_in = rel @ d_in          # ≤ 0 on the incoming leg
    along_out = rel @ d_out        # ≥ 0 on the outgoing leg
    dist_in = np.where(along_in <= 0, np.abs(rel @ n_in), np.hypot(along_in, rel @ n_in))
    dist_out = np.where(along_out >= 0, np.abs(rel @ n_out), np.hypot(along_out, rel @ n_out))
    return float(np.max(np.where(inner, np.minimum(dist_in, dist_out), 0.0)))


def _l_path(v: float, leg: float, through: bool) -> Motion:
    """A 90° left corner at (leg, 0): constant speed through it (``through``) or rest to rest
    with 20000 mm/s² (a stop at the corner)."""
    if through:
        t = np.array([0.0, leg / v, 2 * leg / v])
        p = np.array([[0.0, 0.0, 0.2, 0.0], [leg, 0.0, 0.2, 0.0]])
        vel = np.array([[v, 0.0, 0.0, 0.0], [0.0, v, 0.0, 0.0]])
        return Motion(t, p, vel, np.zeros((2, 4)), np.ones(2, bool))
    a = 20000.0
    td = v / a
    cr = (leg - v * td) / v
    t = np.cumsum([0.0, td, cr, td, td, cr, td])
    acc = np.array([[a, 0], [0, 0], [-a, 0], [0, a], [0, 0], [0, -a]], float)
    acc4 = np.hstack([acc, np.zeros((6, 2))])
    return Motion.from_constant_accel(t, acc4, p0=[0.0, 0.0, 0.2, 0.0], extruding=np.ones(6, bool))


@pytest.mark.parametrize("flavor, name", [("klipper", "zv"), ("klipper", "mzv"), ("klipper", "ei"),
                                          ("klipper", "2hump_ei"), ("rrf", "zvd"), ("marlin", "zv")])
@pytest.mark.parametrize("through", [True, False])
def test_corner_rounding_is_the_shaped_commands_own_cut(flavor, name, through):
    shaper = get_shaper(name, 45.0, 0.1, flavor)
    centred = flavor == "klipper"
    mo = _l_path(100.0, 20.0, through)
    shaped = shape_motion(mo, {"x": shaper, "y": shaper}, centred)
    sim = stiff(shaped)
    lag = 0.0 if centred else shaper.centroid
    settle = shaper.duration - (shaper.centre_delay if centred else 0.0)
    anticipate = shaper.centre_delay if centred else 0.0
    m = compute_metrics(sim, mo, lag=lag, settle=settle, anticipate=anticipate, corner_tail=0.0)
    # independent: the shaped command Σ A_i x(t − s_i), from the impulses, on a fine grid
    shifts = shaper.times - (shaper.centre_delay if centred else 0.0)
    t = np.arange(-0.05, mo.end_time + 0.05, 1e-6)
    pts = sum(A * mo.position(t - s)[:, :2] for A, s in zip(shaper.amplitudes, shifts))
    cut = _deepest_cut(pts, np.array([20.0, 0.0]), np.array([1.0, 0.0]), np.array([0.0, 1.0]))
    assert cut > 1e-3
    assert m.corner_in_mm == pytest.approx(cut, rel=2e-3, abs=2e-5)
    assert m.corner_out_mm < 1e-6            # a stiff shaped command never leaves the corner outward


@pytest.mark.parametrize("name, through", [("mzv", True), ("ei", True), ("mzv", False), ("ei", False)])
def test_corner_rounding_between_samples_does_not_depend_on_their_phase(name, through):
    """At the quality windows' 2 kHz the deepest cut falls between samples (the distance to the
    nearer leg has a kink there): measured on the chord between them, the rounding is the shaped
    command's own (brute force at 1 MHz) within 0.2 % whatever the samples' phase, where the
    nearest sample alone reads up to 5 % short."""
    shaper = get_shaper(name, 45.0, 0.1, "klipper")
    mo = _l_path(100.0, 20.0, through)
    shaped = shape_motion(mo, {"x": shaper, "y": shaper}, True)
    shifts = shaper.times - shaper.centre_delay
    t = np.arange(-0.05, mo.end_time + 0.05, 1e-6)
    pts = sum(A * mo.position(t - s)[:, :2] for A, s in zip(shaper.amplitudes, shifts))
    cut = _deepest_cut(pts, np.array([20.0, 0.0]), np.array([1.0, 0.0]), np.array([0.0, 1.0]))
    for phase in np.linspace(0.0, 1.0, 13)[:-1]:
        ts = np.arange(shaped.t[0] + phase / 2000.0, shaped.t[-1], 1 / 2000.0)
        sim = StiffSim(ts, shaped.position(ts)[:, :2], np.zeros((len(ts), 2)))
        m = compute_metrics(sim, mo, settle=shaper.duration - shaper.centre_delay,
                            anticipate=shaper.centre_delay, corner_tail=0.0)
        assert m.corner_in_mm == pytest.approx(cut, rel=2e-3)


@pytest.mark.parametrize("phase", [0.0, 0.2, 0.5, 0.9])
def test_what_a_travel_leaves_counts_from_the_instant_the_wall_starts(phase):
    """A travel along +X stops (5000 mm/s²) where a wall along +Y starts from rest (90°); the
    nozzle is off the travel's line outward by A·e^(−s/τ) (s from the wall's start): at the start
    it is A from both legs, past the corner, and the wall closes in on it at once. The outward
    figure is that instant's A whatever the 2 kHz samples' phase (within the nozzle's curvature
    over a sample, 1 %); the first sample after it, up to 0.5 ms later, reads A·e^(−s/τ) − a·s²/2,
    down to 87 % of it."""
    a, amp, tau = 5000.0, 0.02, 0.005
    td = 100.0 / a
    t = np.cumsum([0.0, td, 0.1, td, td, 0.1, td])
    acc = np.hstack([np.array([[a, 0], [0, 0], [-a, 0], [0, a], [0, 0], [0, -a]], float), np.zeros((6, 2))])
    mo = Motion.from_constant_accel(t, acc, p0=[0.0, 0.0, 0.2, 0.0], extruding=np.arange(6) >= 3)
    ts = np.arange(phase / 2000.0, mo.end_time, 1 / 2000.0)
    off = amp * np.exp(-(ts - t[3]) / tau)
    nozzle = mo.position(ts)[:, :2] - np.column_stack([np.zeros_like(ts), off])
    sim = StiffSim(ts, nozzle, np.zeros((len(ts), 2)))
    m = compute_metrics(sim, mo, classes=_classes(mo, ["travel"] * 3 + ["outer_wall"] * 3))
    assert m.features["outer_wall"]["corner_out_mm"] == pytest.approx(amp, rel=0.01)


def test_corner_worked_example_of_the_docstring():
    """ZV with no damping at 50 Hz (two halves 10 ms apart, centred), 100 mm/s through a 90°
    corner, stiff: the command cuts the corner by v·Δt/4 = 0.25 mm."""
    zv = get_shaper("zv", 50.0, 0.0, "klipper")
    mo = _l_path(100.0, 20.0, through=True)
    shaped = shape_motion(mo, {"x": zv, "y": zv}, centred=True)
    m = compute_metrics(stiff(shaped), mo, settle=zv.duration - zv.centre_delay,
                        anticipate=zv.centre_delay, corner_tail=0.0)
    assert m.corner_in_mm == pytest.approx(0.25, rel=1e-3)


def _classes(mo: Motion, names: list[str]) -> np.ndarray:
    return np.array([FEATURE_CLASSES.index(n) for n in names])


def test_hidden_features_count_only_through_show_through():
    """The same oscillating nozzle on a corner: labelled outer wall it is ripple and corner; labelled
    infill, only what it pushes outward at the turn (show-through) and by its wall offset."""
    mo, tc, t_end = corner_motion(100.0, 5000.0)
    printer = printer_from_dict({"x": {"modes": [{"freq": 40.0, "damping": 0.05}]},
                                 "y": {"modes": [{"freq": 32.0, "damping": 0.05}]}, "motor": {"slip": False}})
    sim = simulate(printer, mo, backend="lti", initial="static")
    seen = compute_metrics(sim, mo, classes=_classes(mo, ["outer_wall"] * mo.n_segments))
    hidden = compute_metrics(sim, mo, classes=_classes(mo, ["infill"] * mo.n_segments))
    assert seen.ripple_mm > 0.1 and seen.corner_out_mm > 0.05
    assert hidden.ripple_mm == 0 and hidden.corner_out_mm == 0 and hidden.corner_in_mm == 0
    assert seen.show_through_mm == 0
    # infill's reach towards the walls: its outward overshoot at the turn, or its largest offset
    # from a straight stretch (here the wall after the corner), whichever is larger
    assert hidden.show_through_mm == pytest.approx(max(seen.corner_out_mm, hidden.features["infill"]["show_through_mm"]))
    assert hidden.show_through_mm >= seen.corner_out_mm
    assert set(hidden.features) == {"infill"} and set(seen.features) == {"outer_wall"}
    assert set(seen.features["outer_wall"]) == set(FEATURE_KEYS)
    assert hidden.features["infill"]["ripple_mm"] == pytest.approx(seen.ripple_mm)
    # the path-error bound is on what is seen: hidden samples keep their own figure only
    assert seen.path_error_mm > 0.1 and hidden.path_error_mm == 0
    assert hidden.features["infill"]["path_error_mm"] == pytest.approx(seen.path_error_mm)


def test_unlabelled_extrusion_in_a_labelled_job_is_measured_but_not_judged():
    """The oscillating corner as unlabelled extrusion (``other``): in a job that labels nothing
    visible it is what a person sees; in one that labels its outer walls it is a purge line, kept
    per class (the same figures) but out of the job's ripple, corners, path error and extrusion."""
    from ringtune.shaping.features import LABELLED_VISIBLE, VISIBLE
    mo, tc, t_end = corner_motion(100.0, 5000.0)
    printer = printer_from_dict({"x": {"modes": [{"freq": 40.0, "damping": 0.05}]},
                                 "y": {"modes": [{"freq": 32.0, "damping": 0.05}]}, "motor": {"slip": False}})
    sim = simulate(printer, mo, backend="lti", initial="static")
    other = _classes(mo, ["other"] * mo.n_segments)
    alone = compute_metrics(sim, mo, classes=other, seen_classes=VISIBLE)
    purge = compute_metrics(sim, mo, classes=other, seen_classes=LABELLED_VISIBLE)
    assert alone.ripple_mm > 0.1 and alone.corner_out_mm > 0.05 and alone.path_error_mm > 0.1
    assert alone.ripple_mm == compute_metrics(sim, mo, classes=other).ripple_mm     # None: VISIBLE
    assert purge.ripple_mm == purge.corner_out_mm == purge.corner_in_mm == purge.path_error_mm == 0
    assert purge.ripple_p90_mm == 0 and purge.show_through_mm == 0     # not hidden either
    assert purge.features["other"] == pytest.approx(alone.features["other"])
    assert Metrics.worst([purge]).ripple_p90_mm == 0 and alone.ripple_p90_mm > 0.1
    assert Metrics.worst([purge]).details["seen_classes"] == sorted(LABELLED_VISIBLE, key=FEATURE_CLASSES.index)


def test_worst_combines_windows_and_recomputes_the_percentile():
    a = Metrics(ripple_mm=0.01, details={"ripple_walls": [["outer_wall", 0.01], ["infill", 0.5]]},
                features={"outer_wall": dict.fromkeys(FEATURE_KEYS, 0.01)})
    b = Metrics(ripple_mm=0.03, details={"ripple_walls": [["outer_wall", 0.03], ["outer_wall", 0.02]]},
                features={"outer_wall": dict.fromkeys(FEATURE_KEYS, 0.03)})
    w = Metrics.worst([a, b], print_time_s=3.0)
    assert w.ripple_mm == 0.03 and w.print_time_s == 3.0
    assert w.ripple_p90_mm == pytest.approx(np.percentile([0.01, 0.03, 0.02], 90))   # infill is hidden
    assert w.features["outer_wall"]["ripple_p90_mm"] == pytest.approx(np.percentile([0.01, 0.03, 0.02], 90))
    d = w.to_dict()
    assert d["features"]["outer_wall"]["corner_in_mm"] == 0.03


def test_the_jobs_labels_decide_what_is_seen_on_the_built_in_print():
    """evaluate on the built-in print: its three labelled classes are judged; the job's ripple and
    corners are the outer wall's, its show-through the hidden features' worst, its extrusion the
    worst of all; without its labels everything is seen (and nothing is hidden)."""
    from ringtune.envs import evaluate as ev
    from ringtune.shaping.config import TuneConfig
    from ringtune.shaping.testprints import builtin_test_gcode

    cfg = TuneConfig(shaper_x="zv", shaper_y="zv", freq_x=40.0, freq_y=40.0, accel=6000.0)
    m = ev.evaluate(cfg, None, None, backend="lti")
    assert set(m.features) == {"outer_wall", "inner_wall", "infill"}
    f = m.features
    for key in ("ripple_mm", "corner_in_mm", "corner_out_mm"):
        assert getattr(m, key) == f["outer_wall"][key]
    assert m.show_through_mm == max(f["inner_wall"]["show_through_mm"], f["infill"]["show_through_mm"]) > 0
    assert f["outer_wall"]["show_through_mm"] == 0
    for key in ("extrusion_over_pct", "extrusion_under_pct", "e_lag_mm"):
        assert getattr(m, key) == max(v[key] for v in f.values())
    unlabelled = "\n".join(line for line in builtin_test_gcode().splitlines() if not line.startswith(";TYPE:"))
    u = ev.evaluate(cfg, None, unlabelled + "\n", backend="lti")
    assert set(u.features) == {"other"} and u.show_through_mm == 0
    assert u.ripple_mm == u.features["other"]["ripple_mm"] > 0
