"""Issue 21, acceptance 3: the search and the choice judge what a person sees.

- On the default printer and on a printer built from ripple measurements (X 44 Hz, Marlin: the
  Ender-3 V2 case of the issue), 200 seeded trials never choose, as "same quality", a configuration
  with more ripple or worse corners than Klipper's pick: the choice and Klipper's pick are simulated
  again in a fresh ``evaluate_many`` call (not read back from the study) and compared with the
  resolution written out here (1 µm or 5 % for distances, 1 point or 5 % for extrusion).
- The Voron 2.4 from its real resonance files and printer.cfg: the reported stop is the measure (or
  bound) that really stops it — the choice re-simulated one acceleration step higher shows that
  measure worse than the baseline's (or that bound broken).
The 200-trial runs take about a minute each on two shared cores (marked slow).
"""

from __future__ import annotations

import json

import pytest

from ringtune.agents.cli.main import main
from ringtune.agents.tune.stop import MIN_STEP_SAVING, next_accels
from ringtune.agents.tune.wider import WIDER
from ringtune.envs.evaluate import evaluate_many
from ringtune.envs.variants import variant_factors
from ringtune.envs.windows import auto_settle
from ringtune.envs.printer import load_printer
from ringtune.envs.planned_job import planned_job
from ringtune.shaping.config import TuneConfig

SEEN = ("ripple_mm", "ripple_p90_mm", "corner_in_mm", "corner_out_mm")


def _worse(key: str, mine: float, theirs: float) -> bool:
    """Worse beyond the resolution the summary states, written out independently of pareto.Resolution."""
    big = max(abs(mine), abs(theirs))
    tol = max(1.0, 0.05 * big) if key.endswith("_pct") else max(0.001, 0.05 * big)
    return mine - theirs > tol


def _tune(args, capsys) -> dict:
    assert main(["tune", "--json", "--workers", "1", "--seed", "0", *args]) == 0
    return json.loads(capsys.readouterr().out)


def _check_same_quality(res: dict, printer, job=None) -> None:
    chosen = TuneConfig.from_dict(res["chosen"]["config"])
    klipper = TuneConfig.from_dict(res["baselines"]["klipper"]["config"])
    mine, theirs = evaluate_many([chosen, klipper], printer, job, freq_margin=res["freq_margin"])
    assert res["chosen"]["chosen_by"] == "fastest-at-baseline-quality" and "klipper" in res["chosen"]["held_to"]
    for key in SEEN + ("extrusion_over_pct", "extrusion_under_pct"):
        assert not _worse(key, getattr(mine, key), getattr(theirs, key)), (
            key, getattr(mine, key), getattr(theirs, key))
    assert mine.print_time_s <= theirs.print_time_s
    assert not mine.step_loss and mine.motor_load <= 1 - res["motor_reserve"]
    # and on each printer it was judged on, simulated on its own (not only over their worst)
    for v in variant_factors(res["freq_margin"]):
        mine_v, theirs_v = evaluate_many([chosen, klipper], v.of(printer), job, settle=auto_settle(printer))
        for key in SEEN + ("extrusion_over_pct", "extrusion_under_pct"):
            assert not _worse(key, getattr(mine_v, key), getattr(theirs_v, key)), (v, key)
        for key, value in mine_v.features.get("outer_wall", {}).items():
            if key in ("ripple_mm", "corner_in_mm", "corner_out_mm", "extrusion_over_pct", "extrusion_under_pct"):
                assert not _worse(key, value, theirs_v.features["outer_wall"][key]), (v, "outer_wall", key)
    # what the report says is what a fresh simulation gives
    for key in SEEN:
        assert res["versus"]["klipper"][key]["value"] == pytest.approx(getattr(mine, key), rel=1e-9, abs=1e-12)
        assert res["versus"]["klipper"][key]["baseline"] == pytest.approx(getattr(theirs, key), rel=1e-9, abs=1e-12)


@pytest.mark.slow
def test_200_trials_on_the_default_printer_never_choose_more_ripple_or_worse_corners(tmp_path, capsys):
    res = _tune(["--out", str(tmp_path / "out"), "--trials", "200"], capsys)
    printer = load_printer(None)
    _check_same_quality(res, printer)
    # the study's choice here is Klipper's pick itself (its figures, tied); the ladder, the stop and
    # the walk step from it only where a step also holds on the wider printers (agents/tune/wider.py):
    # so the choice is no worse there either, each printer simulated on its own
    chosen = TuneConfig.from_dict(res["chosen"]["config"])
    klipper = TuneConfig.from_dict(res["baselines"]["klipper"]["config"])
    for v in WIDER:
        mine, theirs = evaluate_many([chosen, klipper], v.of(printer), None, settle=auto_settle(printer))
        for key in SEEN + ("extrusion_over_pct", "extrusion_under_pct"):
            assert not _worse(key, getattr(mine, key), getattr(theirs, key)), (v, key)
        for key, value in mine.features["outer_wall"].items():
            if key in ("ripple_mm", "corner_in_mm", "corner_out_mm", "extrusion_over_pct", "extrusion_under_pct"):
                assert not _worse(key, value, theirs.features["outer_wall"][key]), (v, "outer_wall", key)
    summary = (tmp_path / "out" / "summary.txt").read_text()
    assert "WHAT A PERSON SEES" in summary and "What stops it at" in summary
    # where the measures are taken, under the table: the chosen plan's windows, counted here
    pj = planned_job(printer, None, chosen)
    kinds = [w.kind for w in pj.windows]
    span = sum(w.t1 - w.t0 for w in pj.windows)
    assert res["judged_on"] in summary and res["judged_on"].startswith(
        f"measures: the worst over the job's {len(kinds)} quality windows, {span:.1f} s of its {pj.print_time:.1f} s")
    assert f"{kinds.count('corner')} sharpest corner" in res["judged_on"]
    assert f"{sum(k.startswith('seam') for k in kinds)} seam" in res["judged_on"]
    best = json.loads((tmp_path / "out" / "best.json").read_text())
    assert best["stop"] == res["stop"] and best["versus"]["klipper"]["ripple_mm"] == \
        res["versus"]["klipper"]["ripple_mm"]["verdict"]
    for name in ("front.csv", "trials.csv"):
        header = (tmp_path / "out" / name).read_text().splitlines()[0].split(",")
        assert {*SEEN, "extrusion_over_pct", "extrusion_under_pct", "e_lag_mm", "show_through_mm"} <= set(header)


@pytest.mark.slow
def test_200_trials_on_a_printer_from_ripples_never_choose_more_ripple_or_worse_corners(tmp_path, capsys):
    toml = tmp_path / "v2.toml"     # X 44 Hz from ripples 2.27 mm apart at 100 mm/s (the Ender-3 V2)
    assert main(["identify", "--ripples", "X=2.27,Y=2.4", "--speed", "100", "-o", str(toml)]) == 0
    capsys.readouterr()
    printer = load_printer(str(toml))
    assert printer.x.modes[0].freq == pytest.approx(44.4, abs=0.1)
    res = _tune(["--printer", str(toml), "--firmware", "marlin", "--out", str(tmp_path / "out"), "--trials", "200"],
                capsys)
    _check_same_quality(res, printer)


@pytest.fixture(scope="module")
def v24_printer(tmp_path_factory, data_dir):
    d = tmp_path_factory.mktemp("v24")
    files = sorted((data_dir / "accel/klipper_psd/bassco_voron_v24").glob("*.csv"))
    toml = d / "v24.toml"
    assert main(["identify", *map(str, files), "--klipper-config",
                 str(data_dir / "klipper_config/v24/printer.cfg"), "-o", str(toml)]) == 0
    return toml


@pytest.mark.slow
def test_voron_reported_stop_is_the_measure_that_stops_it(v24_printer, tmp_path, capsys):
    capsys.readouterr()
    res = _tune(["--printer", str(v24_printer), "--out", str(tmp_path / "out"), "--trials", "60"], capsys)
    stop = res["stop"]
    assert stop is not None and stop["kind"] in ("measure", "bound", "ceiling", "time", "same time")
    chosen = TuneConfig.from_dict(res["chosen"]["config"])
    summary = (tmp_path / "out" / "summary.txt").read_text()
    assert stop["sentence"] in summary and res["accel"]["stopped_by"] in (stop["key"], stop["kind"])
    if stop["kind"] == "same time":
        # the ladder and the stop climbed, but ended less than 0.5 % faster than the study's choice:
        # the choice keeps its acceleration; where they ended is said, with both print times
        t0, t1 = stop["baseline_value"], stop["value"]
        assert stop["declined_accel"] > chosen.accel == stop["from_accel"] == stop["to_accel"]
        assert 0 < t0 - t1 < 0.005 * t0 and stop["declined_print_time_s"] == t1 and not stop["moved"]
        assert f"({t1:.3f} s from {t0:.3f} s)" in stop["sentence"]
        end = TuneConfig.from_dict(stop["config"])           # where they ended, re-simulated here
        assert end.accel == stop["declined_accel"]
        (m,) = evaluate_many([end], load_printer(str(v24_printer)), None, freq_margin=res["freq_margin"])
        assert m.print_time_s == pytest.approx(t1, rel=1e-9)
        return
    if stop["kind"] == "ceiling":
        assert next_accels(chosen.accel, res["accel"]["range"][1], 100.0) == []
        return
    # the next step up, re-simulated independently from its configuration
    step = TuneConfig.from_dict(stop["config"])
    assert step.accel == next_accels(chosen.accel, 1e9, 100.0, 1)[0]
    same = ("shaper_x", "shaper_y", "freq_x", "freq_y", "damping_x", "damping_y", "freq_limit_hz")
    assert [getattr(step, k) for k in same] == [getattr(chosen, k) for k in same]
    assert stop["baseline"] in res["chosen"]["held_to"] if stop["kind"] == "measure" else stop["baseline"] is None
    base = TuneConfig.from_dict(res["baselines"][stop["baseline"] or res["chosen"]["against"]]["config"])
    printer = load_printer(str(v24_printer))
    up, mine, theirs = evaluate_many([step, chosen, base], printer, None, freq_margin=res["freq_margin"])
    key = stop["key"]
    if stop["kind"] == "measure":      # a job's figure, or one class's own ("outer_wall:ripple_mm")
        def val(m):
            cls, _, k = key.rpartition(":")
            return m.features[cls][k] if cls else getattr(m, k)
        if stop["variant"] is not None:
            # worse on one printer variant: that variant simulated on its own, no margin (with the
            # lead-in the judgement gives every variant: the printer's own)
            twin = printer.detuned(*stop["variant"])
            up_v, mine_v, theirs_v = evaluate_many([step, chosen, base], twin, None, settle=auto_settle(printer))
            assert _worse(key, val(up_v), val(theirs_v))
            if tuple(stop["variant"]) in {(v.freq, v.damping) for v in variant_factors(res["freq_margin"])}:
                assert not _worse(key, val(mine_v), val(theirs_v))
            else:         # a printer of the stop's wider check: the choice may already be worse there
                assert tuple(stop["variant"]) in {(v.freq, v.damping) for v in WIDER}
            assert val(up_v) == pytest.approx(stop["value"], rel=1e-9)
            assert val(theirs_v) == pytest.approx(stop["baseline_value"], rel=1e-9)
        else:
            assert _worse(key, val(up), val(theirs))          # the stopping measure got worse
            assert val(up) == pytest.approx(stop["value"], rel=1e-9)
        assert not _worse(key, val(mine), val(theirs))    # and was not at the choice, over the variants
    elif stop["kind"] == "bound":
        bound = {"motor_load": up.motor_load > 1 - res["motor_reserve"], "step_loss": up.step_loss,
                 "show_through_mm": up.show_through_mm > res["max_show_through_mm"],
                 "path_error_mm": up.path_error_mm > res["max_path_error_mm"]}[key]
        assert bound
    else:                                  # print time falls by less than the least saving a step must buy
        assert up.print_time_s >= mine.print_time_s * (1 - MIN_STEP_SAVING)


def test_simulate_shows_every_visible_measure_against_klippers_pick(capsys):
    """simulate --json: each visible measure of the configuration against Klipper's pick, both values
    from fresh simulations, and the verdict from the resolution written out here."""
    assert main(["simulate", "--json", "--shaper", "zv", "--freq", "40", "--accel", "6000"]) == 0
    res = json.loads(capsys.readouterr().out)
    printer = load_printer(None)
    klipper = TuneConfig.from_dict(res["baselines"]["klipper"]["config"])
    mine, theirs = evaluate_many([TuneConfig.from_dict(res["config"]), klipper], printer, None,
                                 freq_margin=res["freq_margin"])
    vs = res["versus"]["klipper"]
    measures = ("ripple_mm", "corner_in_mm", "corner_out_mm", "extrusion_over_pct", "extrusion_under_pct")
    assert set(vs) == {"print_time_s", *SEEN, "extrusion_over_pct", "extrusion_under_pct",
                       *(f"outer_wall:{k}" for k in measures)}

    def val(d, key):                # a job's figure, or the outer wall's own, from a metrics dict
        cls, _, k = key.rpartition(":")
        return d["features"][cls][k] if cls else d[key]
    mine_d, theirs_d = mine.to_dict(), theirs.to_dict()
    for key, v in vs.items():
        assert v["value"] == pytest.approx(val(mine_d, key), rel=1e-9, abs=1e-12)
        assert v["baseline"] == pytest.approx(val(theirs_d, key), rel=1e-9, abs=1e-12)
        if key != "print_time_s":
            # worse over the worst of the printer and its twins, or on any one of them
            pairs = [(mine_d, theirs_d)] + list(zip(mine.details["variants"], theirs.details["variants"]))
            worse_on = [i for i, (a, b) in enumerate(pairs) if _worse(key, val(a, key), val(b, key))]
            expect = ("worse" if worse_on else
                      "better" if _worse(key, v["baseline"], v["value"]) else "same")
            assert v["verdict"] == expect, key
            assert ("on" in v) == (bool(worse_on) and worse_on[0] > 0 and 0 not in worse_on), key
    assert "none" in res["versus"] and res["baselines"]["none"]["config"]["shaper_x"] == "none"


def test_the_choice_is_held_to_every_baseline_at_once_not_a_chain_of_sames():
    """What the printer runs now 4 % more ripple than Klipper's pick (the same at 5 %), a point 4 %
    more than that (the same as the printer's, 8 % more than Klipper's): not "same quality"."""
    from ringtune.agents.tune.choice import pick
    from ringtune.agents.tune.pareto import Point

    def pt(t, ripple, label):
        m = {k: 0.02 for k in SEEN} | {"ripple_mm": ripple, "extrusion_over_pct": 5.0, "extrusion_under_pct": 5.0}
        return Point(TuneConfig(accel=1000), t, ripple, False, m, label)

    klipper, current = pt(10.0, 0.100, "klipper"), pt(10.0, 0.104, "current")
    chained, honest = pt(8.0, 0.108, "chained"), pt(9.0, 0.101, "honest")
    c = pick([chained, honest], {"klipper": klipper, "current": current, "none": pt(12.0, 0.5, "none")})
    assert c.point is honest and set(c.held_to) == {"klipper", "current"}
    c = pick([chained], {"klipper": klipper, "current": current})
    # nothing the study tried is "same quality" as both: a baseline itself (the better of the two
    # equally fast ones), never the knee, which ripples 8 % more than Klipper's pick
    assert c.point is klipper and c.by == "fastest-at-baseline-quality" and set(c.held_to) == {"klipper", "current"}
    assert "Klipper's rule itself, at 1000 mm/s²" in c.sentence
    c = pick([chained], {"none": pt(12.0, 0.5, "none")}, candidates=[chained])
    assert c.point is chained   # held to no shaping only, the study's point is faster and no worse
    assert pick([chained], {}).by == "knee"      # no baseline at all: the knee, said as such
