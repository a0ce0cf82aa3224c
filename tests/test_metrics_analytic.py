"""Metrics against nozzle paths built analytically with known error, overshoot and ringing."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy.integrate import quad

from ringtune.envs.metrics import Metrics
from ringtune.envs.path_geometry import path_legs
from ringtune.envs.window_metrics import compute_metrics
from ringtune.shaping.motion import Motion

RATE = 10_000.0  # Hz, synthetic sample rate


@dataclass
class FakeSim:
    t: np.ndarray
    nozzle: np.ndarray
    head_accel: np.ndarray
    step_loss: bool = False
    motor_force: np.ndarray | None = None
    motor_force_max: np.ndarray | None = None


def polyline_motion(points, durations, extruding=None) -> Motion:
    """Constant-velocity legs through ``points`` (x, y) taking ``durations`` s each."""
    pts = np.asarray(points, float)
    n = len(durations)
    t = np.concatenate([[0.0], np.cumsum(durations)])
    p = np.zeros((n, 4))
    v = np.zeros((n, 4))
    p[:, :2] = pts[:-1]
    v[:, :2] = (pts[1:] - pts[:-1]) / np.asarray(durations, float)[:, None]
    ext = np.ones(n, bool) if extruding is None else np.asarray(extruding, bool)
    return Motion(t, p, v, np.zeros((n, 4)), ext)


def sim_of(path: Motion, offset) -> FakeSim:
    t = np.arange(int(round(path.end_time * RATE)) + 1) / RATE
    noz = path.position(t)[:, :2] + offset(t)
    return FakeSim(t, noz, np.zeros((len(t), 2)))


def decaying(A, f, zeta):
    w = 2 * math.pi * f
    sigma, wd = zeta * w, w * math.sqrt(1 - zeta * zeta)
    return (lambda tau: np.where(tau >= 0, A * np.exp(-sigma * tau) * np.sin(wd * tau), 0.0)), sigma, wd


def first_peak(A, sigma, wd):
    tau = math.atan2(wd, sigma) / wd
    return A * math.exp(-sigma * tau) * math.sin(wd * tau)


def test_perpendicular_offset_on_straight_line_is_path_error():
    path = polyline_motion([(0, 0), (30, 0)], [0.3])
    sim = sim_of(path, lambda t: np.stack([0 * t, 0.17 * np.sin(2 * np.pi * 10 * t)], axis=1))
    m = compute_metrics(sim, path)
    assert m.path_error_mm == pytest.approx(0.17, rel=1e-6)
    assert m.overshoot_mm == 0.0 and m.ringing_mm == 0.0  # no corner on a single line


def test_lag_along_the_path_costs_nothing():
    path = polyline_motion([(0, 0), (20, 20)], [0.3])
    t = np.arange(3001) / RATE
    noz = path.position(t - 0.005)[:, :2]  # 5 ms behind, on the line
    m = compute_metrics(FakeSim(t, noz, np.zeros((len(t), 2))), path)
    assert m.path_error_mm < 1e-9


def test_lag_along_the_path_costs_nothing_at_corners_after_short_chords():
    """A slicer's arc: a corner split by a 0.15 mm chord (two 45° turns) at 90 mm/s; the nozzle runs
    on the path 10 ms behind the command. It is never off the path, so no corner is rounded or
    overshot — though the second corner's span, by time, reaches back to where the nozzle is still
    on the first leg (0.9 mm before a chord of 0.15 mm)."""
    c = 0.15 / math.sqrt(2.0)
    pts = [(0, 0), (20, 0), (20 + c, c), (20 + c, 20)]
    lengths = [20.0, 0.15, 20.0 - c]
    path = polyline_motion(pts, [d / 90.0 for d in lengths])
    t = np.arange(int(path.end_time * RATE) + 1) / RATE
    noz = path.position(np.maximum(t - 0.010, 0.0))[:, :2]
    m = compute_metrics(FakeSim(t, noz, np.zeros((len(t), 2))), path)
    assert m.path_error_mm < 1e-9
    assert m.corner_in_mm < 1e-9 and m.corner_out_mm < 1e-9


def test_corner_overshoot_and_wall_ringing_match_closed_forms():
    A, f, zeta, tc = 0.12, 40.0, 0.05, 0.1
    dx, sigma, wd = decaying(A, f, zeta)
    path = polyline_motion([(0, 0), (10, 0), (10, 30)], [tc, 0.3])
    sim = sim_of(path, lambda t: np.stack([dx(t - tc), 0 * t], axis=1))
    m = compute_metrics(sim, path)
    assert m.overshoot_mm == pytest.approx(first_peak(A, sigma, wd), rel=1e-3)

    def rms_truth(skip):
        a, b = skip, 0.3
        fn = lambda s: A * math.exp(-sigma * s) * math.sin(wd * s)  # noqa: E731
        mean = quad(fn, a, b, limit=400)[0] / (b - a)
        ms = quad(lambda s: fn(s) ** 2, a, b, limit=400)[0] / (b - a)
        return math.sqrt(ms - mean * mean)

    assert m.ringing_mm == pytest.approx(rms_truth(0.0), rel=5e-3)
    m2 = compute_metrics(sim, path, settle=0.02)
    assert m2.ringing_mm == pytest.approx(rms_truth(0.02), rel=5e-3)
    assert m2.ringing_mm < m.ringing_mm
    assert m.path_error_mm >= m.overshoot_mm


def test_a_wall_the_window_cuts_short_rings_only_with_a_tenth_of_a_second_measured():
    """Where the window's end cuts the wall after a corner, its ringing is the RMS over what is
    measured (closed form) if that is at least 0.1 s; a shorter stub holds the corner's transient,
    whose RMS exceeds the whole wall's and would grow as the window ends nearer the corner."""
    A, f, zeta, tc = 0.12, 40.0, 0.05, 0.1
    dx, sigma, wd = decaying(A, f, zeta)
    path = polyline_motion([(0, 0), (10, 0), (10, 30)], [tc, 0.3])
    sim = sim_of(path, lambda t: np.stack([dx(t - tc), 0 * t], axis=1))

    def cut(measured):        # the samples end `measured` s after the corner, the wall goes on
        keep = sim.t <= tc + measured + 1e-9
        return FakeSim(sim.t[keep], sim.nozzle[keep], sim.head_accel[keep])

    def rms_truth(b):
        fn = lambda s: A * math.exp(-sigma * s) * math.sin(wd * s)  # noqa: E731
        mean = quad(fn, 0.0, b, limit=400)[0] / b
        ms = quad(lambda s: fn(s) ** 2, 0.0, b, limit=400)[0] / b
        return math.sqrt(ms - mean * mean)

    for measured in (0.105, 0.15, 0.25):
        assert compute_metrics(cut(measured), path).ringing_mm == pytest.approx(rms_truth(measured), rel=5e-3)
    assert rms_truth(0.03) > 1.5 * rms_truth(0.3)
    for measured in (0.03, 0.095):
        assert compute_metrics(cut(measured), path).ringing_mm == 0.0
    assert compute_metrics(sim, path).ringing_mm == pytest.approx(rms_truth(0.3), rel=5e-3)


def test_inward_deviation_is_not_overshoot():
    A, f, zeta, tc = 0.12, 40.0, 0.05, 0.1
    dx, *_ = decaying(A, f, zeta)
    path = polyline_motion([(0, 0), (10, 0), (10, 30)], [tc, 0.3])
    # only the inward half-waves (x < corner x) remain
    sim = sim_of(path, lambda t: np.stack([np.minimum(dx(t - tc), 0.0), 0 * t], axis=1))
    assert compute_metrics(sim, path).overshoot_mm == 0.0


def test_reversal_overshoot_past_the_turning_point():
    A, f, zeta, tc = 0.3, 25.0, 0.08, 0.1
    dx, sigma, wd = decaying(A, f, zeta)
    # +x to the turning point, a 50 ms stop there, then back
    path = polyline_motion([(0, 0), (10, 0), (10, 0), (0, 0)], [tc, 0.05, 0.1])
    legs = path_legs(path)
    assert len(legs) == 2 and legs.turn_deg[1] == pytest.approx(180.0)
    off = lambda t: np.stack([np.where(t <= tc + 0.05, dx(t - tc), 0.0), 0 * t], axis=1)  # noqa: E731
    m = compute_metrics(sim_of(path, off), path)
    assert m.overshoot_mm == pytest.approx(first_peak(A, sigma, wd), rel=1e-3)


def test_adjacent_parallel_line_is_not_the_line_being_printed():
    # two 50 mm infill lines 0.4 mm apart; on the second, the nozzle strays 0.3 mm towards the first
    path = polyline_motion([(0, 0), (50, 0), (50, 0.4), (0, 0.4)], [0.5, 0.004, 0.5])
    bump = lambda t: np.stack([0 * t, -0.3 * np.exp(-(((t - 0.8) / 0.01) ** 2))], axis=1)  # noqa: E731
    m = compute_metrics(sim_of(path, bump), path)
    assert m.path_error_mm == pytest.approx(0.3, rel=1e-4)


def test_travel_moves_do_not_count():
    path = polyline_motion([(0, 0), (10, 0), (10, 10)], [0.1, 0.1], extruding=[True, False])
    far = lambda t: np.stack([np.where(t > 0.1, 5.0, 0.0), 0 * t], axis=1)  # noqa: E731
    assert compute_metrics(sim_of(path, far), path).path_error_mm < 1e-9


def test_peak_accel_and_step_loss():
    t = np.linspace(0, 0.1, 101)
    acc = np.zeros((101, 2))
    acc[40] = (3000.0, -4000.0)
    path = polyline_motion([(0, 0), (10, 0)], [0.1])
    noz = path.position(t)[:, :2]
    force = np.full((101, 2), 10.0)
    fmax = np.full((101, 2), 20.0)
    m = compute_metrics(FakeSim(t, noz, acc, False, force, fmax), path)
    assert m.peak_accel == pytest.approx(5000.0) and not m.step_loss
    force[70, 1] = -20.5
    assert compute_metrics(FakeSim(t, noz, acc, False, force, fmax), path).step_loss
    assert compute_metrics(FakeSim(t, noz, acc, True), path).step_loss


def test_worst_combines_windows():
    a = Metrics(path_error_mm=0.1, overshoot_mm=0.3, ringing_mm=0.01, peak_accel=10)
    b = Metrics(path_error_mm=0.2, overshoot_mm=0.1, ringing_mm=0.02, peak_accel=5, step_loss=True)
    w = Metrics.worst([a, b], print_time_s=12.0)
    assert (w.path_error_mm, w.overshoot_mm, w.ringing_mm, w.peak_accel, w.step_loss, w.print_time_s) == (
        0.2, 0.3, 0.02, 10, True, 12.0)


@settings(max_examples=15, deadline=None)
@given(st.floats(0, 2 * math.pi), st.floats(60, 150), st.floats(-50, 50), st.floats(-50, 50))
def test_metrics_do_not_depend_on_orientation_or_position(angle, turn, x0, y0):
    """Rotating and moving a corner with its ringing changes nothing."""
    A, f, zeta, tc = 0.1, 45.0, 0.06, 0.1
    dx, *_ = decaying(A, f, zeta)
    tr = math.radians(turn)
    base = [(0, 0), (10, 0), (10 + 30 * math.cos(tr), 30 * math.sin(tr))]
    # outward unit vector at the corner: bisector of d_in − d_out
    out = np.array([1 - math.cos(tr), -math.sin(tr)])
    out /= np.linalg.norm(out)
    # perpendicular to the outgoing wall, on the outer side
    perp = np.array([math.sin(tr), -math.cos(tr)])
    c, s = math.cos(angle), math.sin(angle)
    R = np.array([[c, -s], [s, c]])

    def run(rot, shift):
        pts = [tuple(rot @ np.array(p) + shift) for p in base]
        path = polyline_motion(pts, [tc, 0.3])
        return compute_metrics(sim_of(path, lambda t: np.outer(dx(t - tc), rot @ perp)), path)

    m0 = run(np.eye(2), np.zeros(2))
    m1 = run(R, np.array([x0, y0]))
    assert out @ perp > 0
    for key in ("path_error_mm", "overshoot_mm", "ringing_mm"):
        assert getattr(m1, key) == pytest.approx(getattr(m0, key), rel=1e-6, abs=1e-9)
    assert m0.overshoot_mm > 0.5 * A and m0.ringing_mm > 0
