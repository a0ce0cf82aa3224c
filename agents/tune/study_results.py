"""Reading a stored study: its complete trials as points judged against the bounds (those the study
was created with unless given), in the search space it ran with."""

from __future__ import annotations

from optuna.trial import TrialState

from ringtune.agents.tune.pareto import Point, judge_bounds, max_motor_load, variants_from_json
from ringtune.agents.tune.space import SearchSpace, config_from_params
from ringtune.agents.tune.study import StudySettings, load_space
from ringtune.agents.tune.trial_screen import SCREENED


def study_points(study, space: SearchSpace | None = None, quality: str | None = None,
                 max_path_error_mm: float | None = None, motor_reserve: float | None = None,
                 max_show_through_mm: float | None = None) -> list[Point]:
    """All complete trials as points, flagged ``step_loss``, ``too_rough`` (path error over
    ``max_path_error_mm``, mm), ``overloaded`` (motor load over 1 − ``motor_reserve``) or
    ``shows_through`` (show-through over ``max_show_through_mm``, mm); default bounds: those the
    study was created with; 0 = no bound. ``quality`` is not used: a point's quality is the
    study's second objective."""
    settings = study.user_attrs.get("settings", {})
    space = space if space is not None else _stored_space(study, settings)
    reserve = _or_stored(motor_reserve, settings, "motor_reserve")
    bounds = (_or_stored(max_path_error_mm, settings, "max_path_error_mm"), max_motor_load(reserve),
              _or_stored(max_show_through_mm, settings, "max_show_through_mm"))
    return [judge_bounds(_trial_point(t, space), *bounds)
            for t in study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,))]


def _stored_space(study, settings: dict) -> SearchSpace:
    """The search space a stored study was run with (from its settings where it recorded none)."""
    if "space" in study.user_attrs:
        return SearchSpace.from_dict(study.user_attrs["space"])
    return load_space(StudySettings(storage="", **{k: v for k, v in settings.items() if k != "storage"}))


def _or_stored(given: float | None, settings: dict, key: str) -> float:
    """``given``, else the stored study setting ``key`` (0 where it has none)."""
    return float(settings.get(key, 0.0) or 0.0) if given is None else given


def _trial_point(t, space: SearchSpace) -> Point:
    """A complete trial as a point not yet judged against the bounds."""
    metrics = dict(t.user_attrs.get("metrics", {}))
    return Point(config_from_params(t.params, space), float(t.values[0]), float(t.values[1]),
                 bool(metrics.get("step_loss", False)), metrics, f"trial {t.number}", t.number,
                 variants=variants_from_json(t.user_attrs.get("variants")), screened=t.user_attrs.get(SCREENED, ""))
