"""Arcs as Klipper cuts them: ``[gcode_arcs]`` splits an I/J arc into ``max(1, floor(travel / resolution))``
equal-angle segments (travel: the arc's length with its helical rise; klippy/extras/gcode_arcs.py
``planArc``, transcribed here on its own). On Klipper's reading a job's arcs are planned on those
segments — the junctions between 1 mm segments of a 3 mm circle hold the head far below the speed
0.01 mm chords allow — (Marlin's and RRF's own: tests/test_firmware_arcs.py)."""

from __future__ import annotations

import json
import math
from importlib import resources

import numpy as np
import pytest

from ringtune.agents.cli.main import main
from ringtune.envs.planned_job import resolve_job
from ringtune.envs.printer import load_printer
from ringtune.hardware.klipper_config import printer_facts_from_klipper
from ringtune.shaping import gcode
from ringtune.shaping.arcs import arc_resolution, arcs_note
from ringtune.shaping.config_plan import plan_with_config
from ringtune.shaping.firmware import job_reading
from ringtune.shaping.gcode import read_gcode
from ringtune.shaping.planner import MachineLimits

KLIPPER = MachineLimits(accel=5000.0, velocity=300.0, junction="scv", square_corner_velocity=5.0,
                        min_cruise_ratio=0.5, klipper_reading=True)
#: the embedded default printer's description (Klipper's reading)
EMBEDDED = (resources.files("ringtune.envs.data") / "ender3.toml").read_text()


def klipper_plan_arc(pos, target, offset, clockwise, resolution, e_total):
    """Klipper's planArc for the X/Y plane, absolute coordinates: the segment ends [x, y, z, e]."""
    r_p, r_q = -offset[0], -offset[1]
    cp, cq = pos[0] - r_p, pos[1] - r_q
    rt_a, rt_b = target[0] - cp, target[1] - cq
    travel = math.atan2(r_p * rt_b - r_q * rt_a, r_p * rt_a + r_q * rt_b)
    if travel < 0:
        travel += 2 * math.pi
    if clockwise:
        travel -= 2 * math.pi
    if travel == 0 and pos[0] == target[0] and pos[1] == target[1]:
        travel = 2 * math.pi
    linear = target[2] - pos[2]
    flat = math.hypot(r_p, r_q) * travel
    mm = math.hypot(flat, linear) if linear else abs(flat)
    segments = max(1.0, math.floor(mm / resolution))
    out = []
    for i in range(1, int(segments) + 1):
        th = i * travel / segments
        c, s = math.cos(th), math.sin(th)
        out.append([cp - offset[0] * c + offset[1] * s, cq - offset[0] * s - offset[1] * c,
                    pos[2] + i * linear / segments, pos[3] + i * e_total / segments])
    return out


@pytest.mark.parametrize("arc, res", [
    (("G3", (13, 10, 0.2), (-3, 0), 0.9), 1.0),        # a 3 mm full circle
    (("G2", (20, 10, 0.2), (3.5, 0), 0.5), 1.0),       # half a 3.5 mm circle, clockwise
    (("G3", (15, 20, 0.6), (-4, 6), 1.2), 0.5),        # a quarter of a 7.2 mm circle rising 0.4 mm (helical)
    (("G2", (13.2, 10.2, 0.2), (0.2, 0), 0.0), 1.0),    # shorter than one segment: one move
])
def test_the_reader_cuts_an_arc_into_klippers_segments(arc, res):
    cmd, (x, y, z), (i, j), e = arc
    start = [13.0, 10.0, 0.2, 0.0]
    text = f"G90\nM83\nG1 X13 Y10 Z0.2 F6000\n{cmd} X{x} Y{y} Z{z} I{i} J{j} E{e} F3000\n"
    job = read_gcode(text, arc_resolution=res)
    want = np.array(klipper_plan_arc(start, (x, y, z), (i, j), cmd == "G2", res, e))
    got = job.end[1:]
    assert len(got) == len(want) and job.arcs == (1, res, ())
    assert np.abs(got - want).max() < 1e-9


def _circles(r: float, v: float, n: int = 20) -> str:
    return f"G90\nM83\nG1 X{r} Y0 F{v * 60}\n" + f"G3 X{r} Y0 I{-r} J0 E1\n" * n


def _written_out(r: float, v: float, res: float, n: int = 20) -> str:
    """The same circles as Klipper's segments in G1 moves."""
    pts = klipper_plan_arc([r, 0.0, 0.0, 0.0], (r, 0.0, 0.0), (-r, 0.0), False, res, 1.0)
    return f"G90\nM83\nG1 X{r} Y0 F{v * 60}\n" + "".join(
        f"G1 X{p[0]:.9f} Y{p[1]:.9f} E{1 / len(pts):.9f}\n" for p in pts) * n


def test_klippers_reading_plans_the_arcs_on_its_segments_and_marlins_on_chords(tmp_path, capsys):
    """A 3 mm circle at 100 mm/s: Klipper's 1 mm segments take 30 % longer than 0.01 mm chords; a
    40 mm one hardly differs. The plan of the job as Klipper reads it is the plan of its segments
    written out."""
    for r, v in ((3.0, 100.0), (40.0, 200.0)):
        path = tmp_path / f"c{r:g}.gcode"
        path.write_text(_circles(r, v))
        klipper = plan_with_config(read_gcode(path, arc_resolution=1.0), KLIPPER).plan.print_time
        segments = plan_with_config(read_gcode(_written_out(r, v, 1.0)), KLIPPER).plan.print_time
        chords = plan_with_config(read_gcode(path), KLIPPER).plan.print_time
        assert klipper == pytest.approx(segments, rel=1e-9)
        assert (klipper / chords - 1 > 0.25) if r == 3.0 else (abs(klipper / chords - 1) < 0.01)
    printer = tmp_path / "p.toml"
    printer.write_text(EMBEDDED.replace("[limits]", "[limits]\narc_resolution = 0.5", 1))
    assert main(["plan", str(tmp_path / "c3.gcode"), "--printer", str(printer), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["arcs"] == 20 and "segments of 0.5 mm (the printer's [gcode_arcs] resolution)" in res["arcs_note"]
    assert res["print_time_s"] == pytest.approx(plan_with_config(
        read_gcode(_written_out(3.0, 100.0, 0.5)), load_printer(printer).limits).plan.print_time, rel=1e-9)
    assert main(["plan", str(tmp_path / "c3.gcode"), "--junction", "jerk", "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert "chords within 0.01 mm of the arc" in res["arcs_note"]


def test_the_arcs_klipper_refuses_are_named():
    """gcode_arcs.py: "G2/G3 does not support R moves", nor relative move mode; the note names them
    (they stay chords), and says nothing of them where the job has none."""
    text = ("G90\nM83\nG1 X10 Y10 F3000\nG2 X20 Y10 R5 E1\nG3 X30 Y10 I5 J0 E1\nG91\nG2 X10 Y0 I5 J0 E1\n")
    job = read_gcode(text, arc_resolution=1.0)
    assert job.arcs == (3, 1.0, (4, 7))
    note = arcs_note(job, KLIPPER)
    assert "Klipper refuses 2 of them (given by R or in relative mode; the first on line 4)" in note
    assert "refuses" not in arcs_note(read_gcode("G90\nG1 X3 Y0\nG3 X3 Y0 I-3 J0\n", arc_resolution=1.0), KLIPPER)


def test_from_klipper_reads_gcode_arcs(tmp_path):
    base = ("[printer]\nkinematics: cartesian\nmax_velocity: 300\nmax_accel: 3000\n"
            "[stepper_x]\nmicrosteps: 16\nrotation_distance: 40\n[stepper_y]\nmicrosteps: 16\nrotation_distance: 40\n")
    cfg = tmp_path / "printer.cfg"
    cfg.write_text(base + "[gcode_arcs]\nresolution: 0.2\n")
    assert printer_facts_from_klipper(cfg).description["limits"]["arc_resolution"] == 0.2
    cfg.write_text(base + "[gcode_arcs]\n")
    facts = printer_facts_from_klipper(cfg)
    assert facts.description["limits"]["arc_resolution"] == 1.0
    assert any("[gcode_arcs] resolution not set: Klipper's default 1 mm" in n for n in facts.notes)
    cfg.write_text(base)
    facts = printer_facts_from_klipper(cfg)
    assert "arc_resolution" not in facts.description["limits"]
    assert any(n.startswith("no [gcode_arcs]: a job's G2/G3 arcs are unknown commands") for n in facts.notes)


@pytest.mark.slow
def test_tune_on_a_job_with_arcs_writes_a_job_that_plans_as_it_judged(tmp_path, capsys):
    """Everything tune reads beside the plan (feature groups, binding limits, the rewritten job)
    cuts the arcs as the plan does: the run ends, and job.gcode plans at the time tune reports."""
    lines = ["G90", "M83", "G1 Z0.2 F600"]
    for layer in range(3):
        lines += [f";LAYER_CHANGE\nG1 Z{0.2 + 0.2 * layer:.1f} F600", ";TYPE:External perimeter",
                  "G1 X120 Y110 F9000", "G3 X120 Y110 I-10 J0 E2 F4800", ";TYPE:Internal infill"]
        lines += [f"G1 X{104 + 2 * k} Y{104 + 12 * (k % 2)} E0.3 F9000" for k in range(7)]
        lines += [";TYPE:External perimeter", "G1 X133 Y110 F9000", "G2 X133 Y110 I-3 J0 E0.6 F4800"]
    job = tmp_path / "arcs.gcode"
    job.write_text("\n".join(lines) + "\n")
    out = tmp_path / "out"
    assert main(["tune", "--gcode", str(job), "--trials", "3", "--workers", "1", "-o", str(out), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert "planned as Klipper's [gcode_arcs] cuts them" in (out / "summary.txt").read_text()
    assert res["job_gcode"]["print_time_s"] == pytest.approx(res["chosen"]["print_time_s"], rel=1e-4)


def test_a_job_without_arcs_is_read_once_whoever_cuts_arcs(tmp_path, monkeypatch):
    """The reader is asked once for a file without G2/G3 read as Klipper, Marlin and an unknown
    firmware cut arcs (the moves are the same: only the arcs' record names each reading); a file
    with arcs is read again for each cutting, since its moves differ."""
    calls = []
    real = gcode.read_gcode
    monkeypatch.setattr(gcode, "read_gcode", lambda *a, **k: calls.append(k.get("arc_resolution")) or real(*a, **k))
    readings = [MachineLimits(**job_reading(fw)) for fw in ("klipper", "marlin")] + [None]
    straight = tmp_path / "straight.gcode"
    straight.write_text("G90\nM82\nG1 X0 Y0 F6000\n" + "".join(f"G1 X{10 * (i % 2)} Y{i} E{i} F3000\n"
                                                             for i in range(1, 9)))
    jobs = [resolve_job(str(straight), lim)[1] for lim in readings]
    assert len(calls) == 1
    for job, lim in zip(jobs, readings):
        assert job.arcs == (0, arc_resolution(lim), ())
        assert np.array_equal(job.end, jobs[0].end) and job.line.tolist() == jobs[0].line.tolist()
    calls.clear()
    arcs = tmp_path / "arcs.gcode"
    arcs.write_text(_circles(3.0, 100.0))
    cut = [resolve_job(str(arcs), lim)[1] for lim in readings]
    assert len(calls) == 3 and len(cut[0].end) != len(cut[2].end)
