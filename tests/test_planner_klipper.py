"""The scv planner against a scalar transcription of Klipper's own look-ahead.

``klipper_time`` follows klippy/toolhead.py: ``Move.calc_junction`` (extruder instantaneous corner
velocity, junction deviation from square_corner_velocity, the centripetal half-move bound,
forward reachability, smoothed forward limit) and ``LookAheadQueue.flush`` (backward pass with
the "delayed" moves and the peak cruise of each smoothed hill), then trapezoid times per move.
It is a plain per-move Python loop, independent of the vectorised planner (DESIGN: print time
within 1 % of Klipper's own planner under Klipper's rules).
"""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest

from ringtune.shaping.config import TuneConfig
from ringtune.shaping.config_plan import plan_with_config
from ringtune.shaping.feature_settings import FeatureCommands
from ringtune.shaping.gcode import read_gcode
from ringtune.shaping.klipper_ignores import LONE_M204, klipper_ignored
from ringtune.shaping.planner import MachineLimits, plan
from ringtune.shaping.rewrite import rewrite_job


def klipper_time(start, end, feed, accel, scv, mcr, velocity=1e9):
    """Scalar port of Klipper's toolhead lookahead (calc_junction + flush) for xyz(+e) moves."""
    class M: pass
    moves = []
    jd = scv ** 2 * (math.sqrt(2) - 1) / accel
    for s, e, f in zip(start, end, feed):
        m = M()
        d = e - s
        m.d = math.sqrt(d[0]**2 + d[1]**2 + d[2]**2)
        m.kin = m.d > 0
        if not m.kin:
            m.d = abs(d[3])
        m.axes_r = d / m.d
        m.accel = accel
        v = min(f, velocity)
        m.max_cruise_v2 = v * v
        m.delta_v2 = 2 * m.d * accel
        m.smooth_delta_v2 = 2 * m.d * accel * (1 - mcr)
        m.max_start_v2 = 0.0
        m.max_smoothed_v2 = 0.0
        moves.append(m)
    for i in range(1, len(moves)):
        m, p = moves[i], moves[i - 1]
        if not m.kin or not p.kin:
            continue
        diff_r = m.axes_r[3] - p.axes_r[3]
        ext_v2 = (1.0 / abs(diff_r)) ** 2 if diff_r else math.inf
        mx = min(ext_v2, m.max_cruise_v2, p.max_cruise_v2, p.max_start_v2 + p.delta_v2)
        a, b = m.axes_r, p.axes_r
        cos = -(a[0]*b[0] + a[1]*b[1] + a[2]*b[2])
        sin_d2 = math.sqrt(max(0.5 * (1 - cos), 0))
        cos_d2 = math.sqrt(max(0.5 * (1 + cos), 0))
        om = 1 - sin_d2
        if om > 0 and cos_d2 > 0:
            R = sin_d2 / om
            q = 0.25 * sin_d2 / cos_d2
            mx = min(mx, R * jd * m.accel, R * jd * p.accel, m.delta_v2 * q, p.delta_v2 * q)
        m.max_start_v2 = mx
        m.max_smoothed_v2 = min(mx, p.max_smoothed_v2 + p.smooth_delta_v2)
    # flush (not lazy)
    res = [None] * len(moves)
    delayed = []
    next_end_v2 = next_smoothed_v2 = peak_cruise_v2 = 0.0
    for i in range(len(moves) - 1, -1, -1):
        m = moves[i]
        reachable_start_v2 = next_end_v2 + m.delta_v2
        start_v2 = min(m.max_start_v2, reachable_start_v2)
        reachable_smoothed_v2 = next_smoothed_v2 + m.smooth_delta_v2
        smoothed_v2 = min(m.max_smoothed_v2, reachable_smoothed_v2)
        if smoothed_v2 < reachable_smoothed_v2:
            if smoothed_v2 + m.smooth_delta_v2 > next_smoothed_v2 or delayed:
                peak_cruise_v2 = min(m.max_cruise_v2, (smoothed_v2 + reachable_smoothed_v2) * .5)
                if delayed:
                    mc_v2 = peak_cruise_v2
                    for (j, ms_v2, me_v2) in reversed(delayed):
                        mc_v2 = min(mc_v2, ms_v2)
                        res[j] = (min(ms_v2, mc_v2), mc_v2, min(me_v2, mc_v2))
                    del delayed[:]
            cruise_v2 = min((start_v2 + reachable_start_v2) * .5, m.max_cruise_v2, peak_cruise_v2)
            res[i] = (min(start_v2, cruise_v2), cruise_v2, min(next_end_v2, cruise_v2))
        else:
            delayed.append((i, start_v2, next_end_v2))
        next_end_v2 = start_v2
        next_smoothed_v2 = smoothed_v2
    total = 0.0
    for m, (s2, c2, e2) in zip(moves, res):
        s, c, e = math.sqrt(s2), math.sqrt(c2), math.sqrt(e2)
        ad = (c2 - s2) / (2 * m.accel)
        dd = (c2 - e2) / (2 * m.accel)
        cd = m.d - ad - dd
        t = (ad / ((s + c) * .5) if ad > 0 else 0) + (dd / ((e + c) * .5) if dd > 0 else 0) + (cd / c if c > 0 else 0)
        total += t
    return total


def _random_job(rng):
    n = int(rng.integers(2, 40))
    pts = rng.uniform(0, 50, (n, 2))
    if rng.uniform() < 0.4:                                   # short wiggly segments
        pts = np.cumsum(rng.uniform(-2, 2, (n, 2)), axis=0) + 50
    feeds = rng.choice([1200, 3000, 6000, 12000, 18000], n)
    lines = ["M83"] + [f"G1 X{x:.3f} Y{y:.3f} E{0.05 * rng.integers(0, 3):.3f} F{f}"
                       for (x, y), f in zip(pts, feeds)]
    return read_gcode("\n".join(lines) + "\n")


@pytest.mark.parametrize("mcr", [0.0, 0.5])
def test_print_time_equals_klippers_lookahead(mcr):
    rng = np.random.default_rng(7)
    for _ in range(60):
        job = _random_job(rng)
        if job.n_moves == 0:
            continue
        accel = float(rng.choice([500, 3000, 10000]))
        lim = MachineLimits(accel=accel, velocity=1e6, junction="scv", square_corner_velocity=5,
                            min_cruise_ratio=mcr)
        ref = klipper_time(job.start, job.end, job.feed, accel, 5.0, mcr)
        assert plan(job, lim).print_time == pytest.approx(ref, rel=1e-9)


def test_real_klipper_job_matches(data_dir):
    job = read_gcode(data_dir / "gcode/bassco_ender3/ringing_tower.gcode")
    # bassco's macro: SET_VELOCITY_LIMIT SQUARE_CORNER_VELOCITY=1 ACCEL=500 (see SOURCES.md)
    lim = MachineLimits(accel=500, velocity=1e6, junction="scv", square_corner_velocity=1,
                        min_cruise_ratio=0.5)
    ours = plan(job, lim).print_time
    ref = klipper_time(job.start, job.end, job.feed, 500.0, 1.0, 0.5)
    assert ours == pytest.approx(ref, rel=1e-9)
    # and it lands near what Simplify3D wrote (1 hour 4 minutes) with the printer's own settings
    assert abs(ours / 3840 - 1) < 0.05


#: what PrusaSlicer writes for Marlin 2 (machine limits in the start, M204 P per feature, M204 T
#: before travel) and a Marlin 1 frequency limit (M201 F)
MARLIN2_LINES = "M201 X500 Y400 F20 S50\nM203 X40 Y40\nM205 X8 Y8 J0.02\nM566 X600 Y600\n"


def _marlin2_job(seed: int = 3) -> str:
    rng = np.random.default_rng(seed)
    out, x, y, e = [MARLIN2_LINES], 0.0, 0.0, 0.0
    for i in range(40):
        if i % 8 == 0:
            out.append(f"M204 P{rng.choice([600, 900, 1200])}\n;TYPE:Perimeter")
        if i % 8 == 5:
            out.append(f"M204 T{rng.choice([700, 1500])}")
            x, y = rng.uniform(0, 100, 2)
            out.append(f"G1 X{x:.3f} Y{y:.3f} F9000")
            continue
        x, y = x + rng.uniform(-15, 15), y + rng.uniform(-15, 15)
        e += 0.5
        out.append(f"G1 X{x:.3f} Y{y:.3f} E{e:.4f} F{rng.choice([3000, 6000, 9000])}")
    return "\n".join(out) + "\n"


def test_klipper_acts_on_none_of_marlins_limit_lines_nor_on_a_lone_m204():
    # Klipper has no M201, M203, M205 or M566, and toolhead.py's cmd_M204 takes S, or P and T
    # together, answering a lone P or T with "Invalid M204 command": every move of such a job runs
    # at the printer's max_accel and velocity, as Klipper's own look-ahead (the port above) plans it
    job = read_gcode(_marlin2_job())
    lim = MachineLimits(accel=3000, velocity=1e6, junction="scv", square_corner_velocity=5, min_cruise_ratio=0.5)
    ref = klipper_time(job.start, job.end, job.feed, 3000.0, 5.0, 0.5)
    assert plan(job, lim).print_time == pytest.approx(ref, rel=1e-9)
    # the job's M201 F (Marlin's XY frequency limit) slows nothing there either
    configured = plan_with_config(job, lim)
    assert configured.freq_limit is None and configured.plan.print_time == pytest.approx(ref, rel=1e-9)
    # under Marlin's junction deviation the same lines rule: slower, and its frequency limit applies
    marlin = plan_with_config(job, MachineLimits(accel=3000, velocity=1e6, junction="jd"))
    assert marlin.freq_limit is not None and marlin.plan.print_time > 1.2 * ref
    # and the report names each ignored line
    ignored = klipper_ignored(job, lim)
    lone = [i + 1 for i, ln in enumerate(_marlin2_job().splitlines()) if ln.startswith("M204")]
    assert ignored == {"M201": [1], "M203": [2], "M205": [3], "M566": [4], LONE_M204: lone}
    assert klipper_ignored(job, dataclasses.replace(lim, junction="jd")) == {}     # Marlin acts on every one


@pytest.mark.parametrize("old", [False, True], ids=["Klipper since 2024", "Klipper before 2024"])
def test_a_line_whose_two_cruise_words_agree_loses_nothing_on_either_klipper(old):
    """ACCEL_TO_DECEL = ACCEL × (1 − MINIMUM_CRUISE_RATIO) is Klipper's own rule between the two words,
    so a line carrying both so (as ringtune rewrite writes it for Klippers of both ages) plans the same
    on either: the word a version does not read is not named. Alone (OrcaSlicer's ACCEL_TO_DECEL beside
    each ACCEL) or disagreeing, it is."""
    lim = MachineLimits(accel=3000, velocity=1e6, junction="scv", square_corner_velocity=5, min_cruise_ratio=0.5,
                        accel_to_decel=1500.0 if old else None)
    zigzag = "".join(f"G1 X{50 + 5 * (i % 2)} Y{10 + 0.4 * i:.1f} E0.2 F12000\n" for i in range(20))

    def named(line: str) -> dict:
        return klipper_ignored(read_gcode("M83\n" + line + "\n" + zigzag), lim)

    assert named("SET_VELOCITY_LIMIT ACCEL=4800 ACCEL_TO_DECEL=2400 MINIMUM_CRUISE_RATIO=0.5") == {}
    assert named("SET_VELOCITY_LIMIT ACCEL=10800 ACCEL_TO_DECEL=10800 MINIMUM_CRUISE_RATIO=0") == {}
    word = "MINIMUM_CRUISE_RATIO" if old else "ACCEL_TO_DECEL"
    assert named("SET_VELOCITY_LIMIT ACCEL=4800 ACCEL_TO_DECEL=3000 MINIMUM_CRUISE_RATIO=0.5") == {
        f"SET_VELOCITY_LIMIT {word}": [2]}
    alone = "SET_VELOCITY_LIMIT ACCEL=4800 ACCEL_TO_DECEL=3000" if not old else \
        "SET_VELOCITY_LIMIT ACCEL=4800 MINIMUM_CRUISE_RATIO=0.5"
    assert named(alone) == {f"SET_VELOCITY_LIMIT {word}": [2]}
    # what is in effect counts, not the line alone: the printer's ratio, or one an earlier line set
    # (ringtune rewrite writes the corner rule's words once where every group shares them)
    if not old:
        assert named("SET_VELOCITY_LIMIT ACCEL=4800 ACCEL_TO_DECEL=2400") == {}          # printer's 0.5
        assert named("SET_VELOCITY_LIMIT MINIMUM_CRUISE_RATIO=0.25\n"
                     "SET_VELOCITY_LIMIT ACCEL=4800 ACCEL_TO_DECEL=3600") == {}
        assert named("SET_VELOCITY_LIMIT MINIMUM_CRUISE_RATIO=0.25\n"
                     "SET_VELOCITY_LIMIT ACCEL=4800 ACCEL_TO_DECEL=2400") == {f"SET_VELOCITY_LIMIT {word}": [3]}
        assert named("M204 S6000\nSET_VELOCITY_LIMIT ACCEL_TO_DECEL=3000") == {}
    else:
        assert named("SET_VELOCITY_LIMIT ACCEL_TO_DECEL=2400\n"
                     "SET_VELOCITY_LIMIT ACCEL=4800 MINIMUM_CRUISE_RATIO=0.5") == {}
    both = read_gcode("M83\nSET_VELOCITY_LIMIT ACCEL=4800 ACCEL_TO_DECEL=2400 MINIMUM_CRUISE_RATIO=0.5\n" + zigzag)
    other = dataclasses.replace(lim, accel_to_decel=None if old else 1500.0)       # the other age
    assert plan(both, lim).print_time == pytest.approx(plan(both, other).print_time, rel=1e-12)


def test_klipper_takes_m204_s_and_p_with_t_and_kalicos_per_axis_accelerations():
    body = _marlin2_job().replace(MARLIN2_LINES, "")
    for line, accel in (("M204 S1000", 1000.0), ("M204 P1000 T1400", 1000.0),
                        ("SET_VELOCITY_LIMIT ACCEL=1000", 1000.0)):
        job = read_gcode(line + "\n" + "\n".join(ln for ln in body.splitlines() if not ln.startswith("M204")) + "\n")
        lim = MachineLimits(accel=3000, velocity=1e6, junction="scv", square_corner_velocity=5, min_cruise_ratio=0.5)
        assert plan(job, lim).print_time == pytest.approx(
            klipper_time(job.start, job.end, job.feed, accel, 5.0, 0.5), rel=1e-9), line
        assert klipper_ignored(job, lim) == {}
    # Kalico's limited kinematics: SET_VELOCITY_LIMIT X_ACCEL/Y_ACCEL cap the axes, as M201 X/Y does
    # on Marlin (the same per-axis rule)
    moves = "\n".join(ln for ln in body.splitlines() if not ln.startswith("M204")) + "\n"
    lim = MachineLimits(accel=3000, velocity=1e6, junction="scv", square_corner_velocity=5, min_cruise_ratio=0.5)
    capped = plan(read_gcode("SET_VELOCITY_LIMIT X_ACCEL=500 Y_ACCEL=400\n" + moves), lim).print_time
    same = plan(read_gcode(moves), dataclasses.replace(lim, max_accel=(500.0, 400.0, 0.0, 0.0))).print_time
    assert capped == pytest.approx(same, rel=1e-12) and capped > plan(read_gcode(moves), lim).print_time


def _velocity_limit_words(text: str) -> dict[str, float]:
    """The words of the file's SET_VELOCITY_LIMIT lines, the last value of each (read as text)."""
    return {k: float(v) for k, v in re.findall(r"\b(ACCEL|ACCEL_TO_DECEL|MINIMUM_CRUISE_RATIO)=([0-9.]+)", text)}


def test_rewritten_klipper_job_runs_as_planned_on_a_klipper_from_before_minimum_cruise_ratio():
    """A Klipper from before 2024 has no MINIMUM_CRUISE_RATIO: it keeps accel_to_decel in mm/s² (the
    config's, default half its max_accel) whatever ACCEL becomes, and caps each hill at
    min(accel_to_decel, ACCEL). The rewrite's ACCEL_TO_DECEL word makes that Klipper (scalar port
    at its values) and a current one (port at ACCEL and MINIMUM_CRUISE_RATIO) both run the
    rewritten zigzag in the time the planner gives it; without the word the old one is slower."""
    zigzag = "".join(f"G1 X{50 + 5 * (i % 2)} Y{10 + 0.4 * i:.1f} E0.2 F12000\n" for i in range(60))
    text = "M83\n;TYPE:Internal infill\n" + zigzag
    limits = MachineLimits(accel=3000, velocity=300, junction="scv", square_corner_velocity=5, min_cruise_ratio=0.5)
    cfg = TuneConfig(accel=3000.0, feature_accel={"infill": 9000.0}, feature_min_cruise_ratio={"infill": 0.1})
    out = "".join(rewrite_job(text.splitlines(keepends=True), "klipper", FeatureCommands.from_config(cfg, limits)))
    words = _velocity_limit_words(out)
    assert words["ACCEL"] == 9000 and words["MINIMUM_CRUISE_RATIO"] == 0.1
    job = read_gcode(out)
    planned = plan(job, limits).print_time
    s, e, f = job.start, job.end, job.feed
    current = klipper_time(s, e, f, 9000.0, 5.0, 0.1)
    old = klipper_time(s, e, f, 9000.0, 5.0, 1 - min(words["ACCEL_TO_DECEL"], 9000.0) / 9000.0)
    assert planned == pytest.approx(current, rel=1e-9) and planned == pytest.approx(old, rel=1e-9)
    without = klipper_time(s, e, f, 9000.0, 5.0, 1 - 1500.0 / 9000.0)   # its config's 3000 / 2
    assert without > 1.1 * old


ZIGZAG = "".join(f"G1 X{50 + 5 * (i % 2)} Y{10 + 0.4 * i:.1f} E0.2 F12000\n" for i in range(60))


@pytest.mark.parametrize("old", [False, True])
def test_accel_to_decel_of_a_job_counts_only_on_a_klipper_from_before_2024(old):
    """OrcaSlicer writes ``SET_VELOCITY_LIMIT ACCEL= ACCEL_TO_DECEL=`` (half of ACCEL by default). A
    current Klipper ignores the word: its minimum_cruise_ratio rules (port at 0 here). A Klipper
    from before 2024 (``accel_to_decel`` in the limits) takes it, and has no MINIMUM_CRUISE_RATIO:
    the port at 1 − 2500/5000. Each is named among what that Klipper does not act on."""
    job = read_gcode("M83\nSET_VELOCITY_LIMIT ACCEL=5000 ACCEL_TO_DECEL=2500\nSET_VELOCITY_LIMIT MINIMUM_CRUISE_RATIO=0\n"
                     + ZIGZAG)
    lim = MachineLimits(accel=3000, velocity=300, junction="scv", square_corner_velocity=5, min_cruise_ratio=0.5,
                        accel_to_decel=1500.0 if old else None)
    ref = klipper_time(job.start, job.end, job.feed, 5000.0, 5.0, 0.5 if old else 0.0)
    assert plan(job, lim).print_time == pytest.approx(ref, rel=1e-9)
    ignored = klipper_ignored(job, lim)
    assert ignored == {("SET_VELOCITY_LIMIT MINIMUM_CRUISE_RATIO" if old else "SET_VELOCITY_LIMIT ACCEL_TO_DECEL"):
                       [3 if old else 2]}


def test_an_old_klipper_keeps_its_accel_to_decel_where_the_configuration_sets_no_ratio():
    """On a Klipper from before 2024 with max_accel_to_decel 2000, a configuration at 6000 mm/s² runs
    the hills of a class it sets no minimum_cruise_ratio for at min(2000, 6000): with no ratio at all
    the rewrite writes no ACCEL_TO_DECEL (the printer's own stands), with a ratio for another class
    (outer walls) it writes the printer's own, 2000, where that class's would otherwise stay. Tune's
    plan, the rewritten file's and the scalar port agree. On a current Klipper with the same ratio at
    its max_accel (1 − 2000/4000 = 0.5) the ratio scales with ACCEL: 3000."""
    text = "M83\n;TYPE:Internal infill\n" + ZIGZAG
    job = read_gcode(text)
    for old, ratios, written, atd in ((True, {}, None, 2000.0), (True, {"outer_wall": 0.2}, 2000.0, 2000.0),
                                      (False, {"outer_wall": 0.2}, 3000.0, 3000.0), (False, {}, None, 3000.0)):
        lim = MachineLimits(accel=4000, velocity=300, junction="scv", square_corner_velocity=5, min_cruise_ratio=0.5,
                            accel_to_decel=2000.0 if old else None)
        cfg = TuneConfig(accel=6000.0, feature_accel={"infill": 6000.0}, feature_min_cruise_ratio=ratios)
        out = "".join(rewrite_job(text.splitlines(keepends=True), "klipper", FeatureCommands.from_config(cfg, lim)))
        assert _velocity_limit_words(out).get("ACCEL_TO_DECEL") == written
        ref = klipper_time(job.start, job.end, job.feed, 6000.0, 5.0, 1 - atd / 6000.0)
        assert plan_with_config(job, lim, cfg).plan.print_time == pytest.approx(ref, rel=1e-9)
        assert plan(read_gcode(out), lim).print_time == pytest.approx(ref, rel=1e-9)


def test_klipper_rests_only_where_it_has_the_command_and_waits_for_g4_p_alone():
    """Klipper has no M593 (unknown: the look-ahead runs on) and its G4 takes P alone
    (toolhead.py cmd_G4); Marlin stops at M593 and waits for S seconds."""
    moves = "G1 X10 Y0 E0.5 F6000\nG1 X20 Y0 E0.5\n"
    scv = MachineLimits(accel=3000, velocity=300, junction="scv", square_corner_velocity=5, min_cruise_ratio=0.5)
    jd = MachineLimits(accel=3000, velocity=300, junction="jd", junction_deviation=0.013, klipper_reading=False)
    plain = read_gcode("M83\n" + moves)
    shaped = read_gcode("M83\nG1 X10 Y0 E0.5 F6000\nM593 F40\nG1 X20 Y0 E0.5\n")
    waits = read_gcode("M83\nG1 X10 Y0 E0.5 F6000\nG4 S10\nG1 X20 Y0 E0.5\n")
    waits_p = read_gcode("M83\nG1 X10 Y0 E0.5 F6000\nG4 P500\nG1 X20 Y0 E0.5\n")
    ref = klipper_time(plain.start, plain.end, plain.feed, 3000.0, 5.0, 0.5)
    assert plan(shaped, scv).print_time == pytest.approx(ref, rel=1e-12)
    assert plan(shaped, jd).print_time > plan(plain, jd).print_time + 0.01       # Marlin comes to rest
    stopped = plan(waits_p, scv).print_time - 0.5                                # a rest, then 0.5 s
    assert plan(waits, scv).print_time == pytest.approx(stopped, rel=1e-12) and stopped > ref
    assert plan(waits, jd).print_time == pytest.approx(plan(waits_p, jd).print_time + 9.5, rel=1e-12)
    # both words: Marlin waits S (G4() reads S after P), Klipper P
    both = read_gcode("M83\nG1 X10 Y0 E0.5 F6000\nG4 P500 S2\nG1 X20 Y0 E0.5\n")
    assert plan(both, jd).print_time == pytest.approx(plan(waits_p, jd).print_time + 1.5, rel=1e-12)
    assert plan(both, scv).print_time == pytest.approx(plan(waits_p, scv).print_time, rel=1e-12)
