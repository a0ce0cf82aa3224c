"""The study simulates a trial's detuned twins only where they can count
(agents/tune/trial_screen.py). Checked against the full judgement: every trial settled on the model
alone is judged again on the printer and its twins, and then it breaks a bound, or it is off the
front and worse than Klipper's pick; the front and the default choice are the same with those full
judgements as without them."""

from __future__ import annotations

import json

import pytest

from ringtune.agents.tune import trial_screen
from ringtune.agents.tune.baselines import baselines_for
from ringtune.agents.tune.choice import pick
from ringtune.agents.tune.pareto import VISIBLE_KEYS, max_motor_load, no_worse, pareto_front, point_from_metrics
from ringtune.agents.tune.report import _ruled_out
from ringtune.agents.tune.study import StudySettings, run_study
from ringtune.agents.tune.study_results import study_points
from ringtune.envs.evaluate import evaluate_many
from ringtune.envs.planned_job import resolve_printer

MARGIN = 0.05
ALSO = tuple(k for k in VISIBLE_KEYS if k != "ripple_mm")


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    """A 40-trial study of the built-in print as ``tune`` runs it (Klipper's pick as the screen's
    base), and its baselines."""
    printer = resolve_printer(None)
    path = tmp_path_factory.mktemp("screen") / "study.journal"
    settings = StudySettings(storage=f"journal:{path}", n_trials=40, seed=3, freq_margin=MARGIN)
    bl = baselines_for(printer, "klipper", settings, evaluate_many, "ripple_mm")
    settings.screen_against = trial_screen.base_figures(bl.points["klipper"])
    assert settings.screen_against, "Klipper's pick is feasible and judged on its twins"
    points = study_points(run_study(settings, printer=printer).study)
    return printer, settings, bl.points, points


def _full(printer, settings, points):
    """``points`` judged as the study judges without the screen: the printer and both twins."""
    ms = evaluate_many([p.config for p in points], printer, None, freq_margin=MARGIN)
    return [point_from_metrics(p.config, m, "ripple_mm", label=p.label, number=p.number,
                               max_path_error_mm=settings.max_path_error_mm,
                               max_motor_load=max_motor_load(settings.motor_reserve),
                               max_show_through_mm=settings.max_show_through_mm) for p, m in zip(points, ms)]


@pytest.mark.slow
def test_each_settled_trial_is_what_its_full_judgement_says(study):
    printer, settings, bases, points = study
    settled = [p for p in points if p.screened]
    kinds = {p.screened for p in settled}
    assert kinds == {trial_screen.OVER_A_BOUND, trial_screen.BEATEN}, "both kinds occur in this study"
    assert all(not p.feasible for p in settled), "read back, a settled trial is never a candidate"
    for p, full in zip(settled, _full(printer, settings, settled)):
        assert full.print_time_s == pytest.approx(p.print_time_s, rel=1e-12)
        for k in VISIBLE_KEYS:                   # the model's figures are lower bounds of the judged ones
            assert full.metrics[k] >= p.metrics[k] - 1e-12
        if p.screened == trial_screen.OVER_A_BOUND:
            assert not full.feasible
        else:
            assert not no_worse(full, bases["klipper"]), "worse than Klipper's pick, judged in full"
            assert any(q.dominates(full) or _beats(q, full) for q in points if q.feasible and not q.screened)


def _beats(q, p) -> bool:
    """q no worse than p on print time and every visible measure, better on one."""
    keys = ("print_time_s", *VISIBLE_KEYS)
    a, b = [q.value(k) for k in keys], [p.value(k) for k in keys]
    return all(x <= y for x, y in zip(a, b)) and any(x < y for x, y in zip(a, b))


def test_the_front_and_the_choice_are_those_of_the_full_judgement(study):
    printer, settings, bases, points = study
    settled = [p for p in points if p.screened]
    judged = [p for p in points if not p.screened]
    full = _full(printer, settings, settled)
    front = pareto_front(points, also=ALSO)
    front_full = pareto_front(judged + full, also=ALSO)
    assert [p.number for p in front] == [p.number for p in front_full]
    assert all(not p.screened for p in front)
    chosen = pick(front, bases, candidates=points)
    chosen_full = pick(front_full, bases, candidates=judged + full)
    assert chosen.point.number == chosen_full.point.number and chosen.sentence == chosen_full.sentence


def test_judged_trials_carry_every_variant_and_the_report_counts_the_settled(study):
    _printer, settings, _bases, points = study
    for p in points:
        if not p.screened:
            assert [f for f, _ in p.variants] == [(1.0, 1.0), (1 - MARGIN, 0.75), (1 + MARGIN, 0.75)]
    beaten = sum(p.screened == trial_screen.BEATEN for p in points)
    over = sum(p.screened == trial_screen.OVER_A_BOUND for p in points)
    line = "; ".join(_ruled_out(points, settings.max_path_error_mm, settings.motor_reserve,
                                settings.max_show_through_mm))
    assert f"{beaten} beaten on the printer as modelled" in line
    assert f"nor those of {over} counted above" in line


@pytest.mark.slow
def test_tune_counts_the_settled_trials_and_does_not_call_them_old(tmp_path, capsys):
    """A settled trial has no figures per variant, as a trial of a study begun by an earlier
    ringtune had none: tune must not say that of it."""
    from ringtune.agents.cli.main import main
    assert main(["tune", "--trials", "16", "--workers", "1", "--seed", "0", "--out", str(tmp_path / "out"),
                 "--per-feature", "off", "--no-refine"]) == 0
    out, err = capsys.readouterr()
    settled = [p for p in study_points_of(tmp_path / "out") if p.screened]
    assert settled, "this run settles some trials on the model alone"
    assert main(["tune", "--trials", "16", "--workers", "1", "--seed", "0", "--out", str(tmp_path / "out"),
                 "--per-feature", "off", "--no-refine", "--json"]) == 0      # resumed: nothing left to run, the same report
    counts = json.loads(capsys.readouterr()[0])["settled_on_model"]
    assert counts == {k: sum(p.screened == k for p in settled) for k in {p.screened for p in settled}}
    beaten = sum(p.screened == trial_screen.BEATEN for p in settled)
    over = sum(p.screened == trial_screen.OVER_A_BOUND for p in settled)
    assert (f"{beaten} beaten on the printer as modelled" in out) == (beaten > 0)
    assert (f"nor those of {over} counted above" if beaten else f"the twins of {over} counted above") in out
    assert "stored without their figures" not in err
    rows = (tmp_path / "out" / "trials.csv").read_text().splitlines()
    assert sum("the model alone (" in r for r in rows[1:]) == len(settled)


def study_points_of(out_dir):
    """The points of the study ``tune`` left in ``out_dir``."""
    import optuna
    from ringtune.agents.tune.storage import default_storage, make_storage
    return study_points(optuna.load_study(study_name="ringtune", storage=make_storage(default_storage(out_dir))))
