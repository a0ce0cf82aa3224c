"""Acceptance 5: on random paths the planned motion respects every limit at every segment.

The junction limits are recomputed here by straightforward scalar transcriptions of the firmware
rules (Klipper toolhead.py calc_junction, Marlin planner.cpp junction deviation, PrusaSlicer's
classic-jerk estimator), independent of the vectorised planner.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ringtune.shaping.gcode import read_gcode
from ringtune.shaping.planner import MachineLimits, plan

TOL = 1e-6
AMAX = (20000.0, 5000.0, 100.0, 5000.0)     # per-axis accel caps x, y, z, e (mm/s²)
VMAX = (250.0, 250.0, 10.0, 60.0)           # per-axis speed caps x, y, z, e (mm/s)


def _unit(d):
    xyz = math.sqrt(d[0] ** 2 + d[1] ** 2 + d[2] ** 2)
    length = xyz if xyz > 0 else abs(d[3])
    return [x / length for x in d], length, xyz == 0


def ref_scv(prev, cur, lim):
    (up, dp, ep, Ap), (uc, dc, ec, Ac) = prev, cur
    if ep or ec:
        return 0.0
    v2 = math.inf
    diff_r = abs(uc[3] - up[3])
    if diff_r:
        v2 = (1.0 / diff_r) ** 2
    cos_j = -(uc[0] * up[0] + uc[1] * up[1] + uc[2] * up[2])
    sin_d2 = math.sqrt(max(0.5 * (1 - cos_j), 0))
    cos_d2 = math.sqrt(max(0.5 * (1 + cos_j), 0))
    if 1 - sin_d2 > 0 and cos_d2 > 0:
        r = sin_d2 / (1 - sin_d2)
        jd = lim.square_corner_velocity ** 2 * (math.sqrt(2) - 1)
        q = 0.25 * sin_d2 / cos_d2
        v2 = min(v2, r * jd, 2 * Ac * dc * q, 2 * Ap * dp * q)
    return v2


def ref_jd(prev, cur, lim):
    (up, _, ep, _), (uc, dc, ec, Ac) = prev, cur
    # Marlin normalises over X, Y, Z and E together (an E-only move: ±E)
    vp = [x / math.sqrt(sum(y * y for y in up)) for x in up]
    vc = [x / math.sqrt(sum(y * y for y in uc)) for x in uc]
    cos_t = -sum(a * b for a, b in zip(vp, vc))
    if cos_t > 0.999999:
        return 0.05 ** 2
    cos_t = max(cos_t, -0.999999)
    s = math.sqrt(0.5 * (1 - cos_t))
    ju = [b - a for a, b in zip(vp, vc)]
    norm = math.sqrt(sum(x * x for x in ju))
    a_j = Ac
    for a in range(4):
        if norm > 0 and ju[a] != 0:
            a_j = min(a_j, lim.max_accel[a] / abs(ju[a] / norm))
    v2 = a_j * lim.junction_deviation * s / (1 - s)
    if dc < 1 and cos_t < -0.7071067812:
        v2 = min(v2, dc * a_j / marlin_turn_ref(-cos_t))
    return v2


def marlin_turn_ref(t):
    """Marlin's junction_theta for junction_cos_theta = −t: π/2 − its MinMax asin polynomial (planner.cpp)."""
    asin = 0.032843707 + t * (-1.451838349 + t * (29.66153956 + t * (-131.1123477 + t * (
        262.8130562 + t * (-242.7199627 + t * 84.31466202)))))
    return math.pi / 2 - asin


def ref_jerk(prev, cur, lim, vp_nom, vc_nom):
    (up, _, _, _), (uc, _, _, _) = prev, cur
    jerk = lim.jerk

    def safe(u, v):
        s = v
        for a in range(4):
            if abs(u[a]) * v > jerk[a]:
                s = min(s, jerk[a])
        return s

    safe_p, safe_c = safe(up, vp_nom), safe(uc, vc_nom)
    prev_larger = vp_nom > vc_nom
    smaller = vc_nom / vp_nom if prev_larger else vp_nom / vc_nom
    vj = vc_nom if prev_larger else vp_nom
    v_factor, limited = 1.0, False
    for a in range(4):
        v_exit, v_entry = up[a] * vp_nom, uc[a] * vc_nom
        if prev_larger:
            v_exit *= smaller
        if limited:
            v_exit *= v_factor
            v_entry *= v_factor
        if v_exit > v_entry:
            j = (v_exit - v_entry) if (v_entry > 0 or v_exit < 0) else max(v_exit, -v_entry)
        else:
            j = (v_entry - v_exit) if (v_entry < 0 or v_exit > 0) else max(-v_exit, v_entry)
        if j > jerk[a]:
            v_factor *= jerk[a] / j
            limited = True
    if limited:
        vj *= v_factor
    if safe_p > 0.99 * vj and safe_c > 0.99 * vj:
        vj = safe_c
    return vj ** 2, safe_p, safe_c


points = st.lists(
    st.tuples(st.floats(0, 60), st.floats(0, 60), st.sampled_from([0.0, 0.0, 0.0, 0.3]),
              st.sampled_from([0.0, 0.05, 0.5, -0.5]), st.sampled_from([600, 3000, 6000, 12000, 30000])),
    min_size=2, max_size=25)


def _gcode(pts):
    lines = ["G90", "M83"]
    for x, y, dz, e, f in pts:
        lines.append(f"G1 X{x:.3f} Y{y:.3f} Z{1 + dz:.3f} E{e:.4f} F{f}")
    lines.append("G1 E-0.8 F2400")
    return "\n".join(lines) + "\n"


@settings(max_examples=150, deadline=None)
@given(pts=points, junction=st.sampled_from(["scv", "jd", "jerk"]),
       accel=st.sampled_from([500.0, 3000.0, 10000.0]), daa=st.sampled_from([None, None, 35.0]),
       mcr=st.sampled_from([0.0, 0.5]))
def test_planned_motion_respects_every_limit(pts, junction, accel, daa, mcr):
    job = read_gcode(_gcode(pts))
    if job.n_moves == 0:
        return
    lim = MachineLimits(accel=accel, velocity=250, junction=junction, square_corner_velocity=5,
                        junction_deviation=0.02, jerk=(8, 8, 0.4, 5), min_cruise_ratio=mcr,
                        max_velocity=VMAX, max_accel=AMAX)
    p = plan(job, lim, daa_freq=daa)
    m, mo = p.moves, p.motion
    n = len(m)
    # -- expected per-move speed and acceleration caps --
    # Klipper (scv) has no M201/M203 E: the E caps do not apply there (its extruder's own limits,
    # extrude_only_*, are not given here: a move of the extruder alone runs as any other)
    klipper = junction == "scv"
    units = [_unit(list(job.end[i] - job.start[i])) for i in range(n)]
    caps_v, caps_a = [], []
    for i, (u, d, eonly) in enumerate(units):
        v = min(job.feed[i], 250.0)
        a_cap = accel
        for a, (vcap, acap) in enumerate(zip(VMAX, AMAX)):
            if abs(u[a]) > 0 and not (klipper and a == 3):
                v = min(v, vcap / abs(u[a]))
                a_cap = min(a_cap, acap / abs(u[a]))
        caps_v.append(v)
        caps_a.append(a_cap)
    caps_v, caps_a = np.array(caps_v), np.array(caps_a)
    e_bound = np.full(n, not klipper)
    np.testing.assert_allclose(m.v_nominal, caps_v, rtol=1e-12)
    # -- every segment: speed <= nominal, |acceleration| <= limit, per-axis speed caps --
    seg_move = mo.move
    moving = seg_move >= 0
    dt = np.diff(mo.t)
    assert np.all(dt > 0)
    v_end = mo.v + mo.a * dt[:, None]
    for vel in (mo.v, v_end):
        path_speed = np.where(np.linalg.norm(vel[:, :3], axis=1) > 0, np.linalg.norm(vel[:, :3], axis=1),
                              np.abs(vel[:, 3]))
        assert np.all(path_speed[moving] <= caps_v[seg_move[moving]] * (1 + TOL) + TOL)
        for a, cap in enumerate(VMAX):
            rows = moving & e_bound[seg_move] if a == 3 else slice(None)
            assert np.all(np.abs(vel[rows, a]) <= cap * (1 + TOL) + TOL)
    for a, cap in enumerate(AMAX):
        rows = moving & e_bound[seg_move] if a == 3 else slice(None)
        assert np.all(np.abs(mo.a[rows, a]) <= cap * (1 + TOL))
    acc_mag = np.where(np.linalg.norm(mo.a[:, :3], axis=1) > 0, np.linalg.norm(mo.a[:, :3], axis=1),
                       np.abs(mo.a[:, 3]))
    assert np.all(acc_mag[moving] <= caps_a[seg_move[moving]] * (1 + TOL))
    # -- the motion follows the moves exactly --
    np.testing.assert_allclose(mo.position(m.t_start), m.start, atol=1e-6)
    np.testing.assert_allclose(mo.position(m.t_start + m.duration), m.end, atol=1e-6)
    p_end = mo.p + mo.v * dt[:, None] + 0.5 * mo.a * dt[:, None] ** 2
    same = seg_move[1:] == seg_move[:-1]
    np.testing.assert_allclose(p_end[:-1][same], mo.p[1:][same], atol=1e-6)
    np.testing.assert_allclose(v_end[:-1][same], mo.v[1:][same], atol=1e-6)
    # -- each move's profile is reachable with its acceleration --
    assert np.all(m.v_entry <= m.v_cruise * (1 + TOL) + TOL)
    assert np.all(m.v_exit <= m.v_cruise * (1 + TOL) + TOL)
    assert np.all(m.v_cruise <= m.v_nominal * (1 + TOL) + TOL)
    # -- junctions: one speed on both sides, within the firmware rule --
    np.testing.assert_allclose(m.v_exit[:-1], m.v_entry[1:], rtol=1e-9, atol=1e-9)
    safes = []
    for i in range(1, n):
        prev = (*units[i - 1], caps_a[i - 1])
        cur = (*units[i], caps_a[i])
        if junction == "scv":
            v2 = ref_scv(prev, cur, lim)
        elif junction == "jd":
            v2 = ref_jd(prev, cur, lim)
        else:
            v2, sp, sc = ref_jerk(prev, cur, lim, caps_v[i - 1], caps_v[i])
            safes.append((sp, sc))
        v2 = min(v2, caps_v[i - 1] ** 2, caps_v[i] ** 2)
        assert m.v_entry[i] ** 2 <= v2 * (1 + TOL) + TOL, (i, junction, m.v_entry[i] ** 2, v2)
    # start and end of the job: from and to rest (classic jerk: a jump of at most the safe speed)
    if junction == "jerk":
        if safes:
            assert m.v_entry[0] <= safes[0][0] + TOL
            assert m.v_exit[-1] <= safes[-1][1] + TOL
    else:
        assert m.v_entry[0] == 0 and m.v_exit[-1] == 0
    if daa:
        # RRF DAA: an adjusted phase lasts one or two ringing periods, unless the move became a
        # single accelerate-only / decelerate-only phase spanning the whole move
        period = 1 / daa
        for i in range(n):
            for a_used, dv, single in ((m.accel[i], m.v_cruise[i] - m.v_entry[i], m.v_cruise[i] <= m.v_exit[i] + 1e-9),
                                       (m.decel[i], m.v_cruise[i] - m.v_exit[i], m.v_cruise[i] <= m.v_entry[i] + 1e-9)):
                assert a_used <= caps_a[i] * (1 + TOL)
                if abs(a_used - caps_a[i]) <= 1e-9 * caps_a[i] or dv <= 1e-9:
                    continue
                t = dv / a_used
                assert (min(abs(t - period), abs(t - 2 * period)) < 1e-7
                        or (single and abs(m.duration[i] - t) < 1e-7)), (i, t, period)


@pytest.mark.parametrize("junction", ["scv", "jd", "jerk"])
def test_planner_is_time_optimal_on_a_straight_split_line(junction):
    """Splitting a straight line into pieces must not change the plan (look-ahead is global)."""
    lim = MachineLimits(accel=2000, junction=junction, jerk=(8, 8, 0.4, 5), min_cruise_ratio=0.0)
    one = plan(read_gcode("G1 X100 F6000\n"), lim)
    many = plan(read_gcode("".join(f"G1 X{x} F6000\n" for x in range(5, 101, 5))), lim)
    assert many.print_time == pytest.approx(one.print_time, rel=1e-9)
