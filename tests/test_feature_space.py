"""The per-feature search space (issue 22): each hidden group's acceleration range stops where the
weakest motor keeps its reserve at that group's own top speed — checked against the rigid-body force
balance F = m·a + F_friction ≤ (1 − reserve)·F_max(v) computed here for a cartesian axis — so a weak
motor on the same frame gets lower hidden-feature accelerations than a strong one; parameters and
configurations map both ways; the corner rule is searched only where the firmware can say it."""

from __future__ import annotations

import json

import pytest

from ringtune.agents.tune.feature_space import feature_space, group_speeds, hidden_groups, wanted
from ringtune.agents.tune.feature_groups import ACCEL_GROUPS
from ringtune.agents.tune.space import (SearchSpace, config_from_params, default_space, params_from_config,
                                        suggest_params, walked_keys)
from ringtune.envs.printer import load_printer, printer_from_dict
from ringtune.shaping.config import TuneConfig

BASE = load_printer(None)


def _with_motor(force: float):
    d = BASE.to_dict()
    d["motor"] = {"force": force, "corner_speed": 150.0, "rotor_mass": 0.13, "friction": 1.0, "steps_per_mm": 80.0}
    d.pop("measurement", None)
    return printer_from_dict(d)


def _rigid_limit(printer, speed: float, reserve: float) -> float:
    """Largest a (mm/s²) with (m + m_rotor)·a + friction ≤ (1 − reserve)·F(v) on the heavier
    (bed) axis of a cartesian printer: the motor's force table at the belt speed."""
    mo = printer.motor_for("y")
    force = (1 - reserve) * float(mo.max_force(speed))          # N the reserve leaves
    mass = max(printer.moving_mass("x"), printer.moving_mass("y")) + mo.rotor_mass
    return (force - mo.friction) / mass * 1e3


def test_hidden_ranges_are_the_motor_reserve_at_each_groups_speed():
    space = feature_space(default_space(BASE, "klipper"), BASE, None, reserve=0.2)
    speeds = group_speeds(BASE, None)
    groups = {g for g, *_ in space.feature_accel}
    assert groups == set(hidden_groups(BASE, None)) == {"hidden_walls", "infill", "travel"}
    for group, lo, hi in space.feature_accel:
        assert lo == space.accel[0]
        want = _rigid_limit(BASE, speeds[group], 0.2)
        assert want - 100 < hi <= want + 1, group          # rounded down to the 100 mm/s² step
    # travel is the fastest group: its range is the lowest
    ranges = {g: hi for g, _lo, hi in space.feature_accel}
    assert ranges["travel"] < ranges["infill"]


def test_a_weak_motor_gets_lower_hidden_accelerations_than_a_strong_one():
    weak, strong = _with_motor(18.0), _with_motor(45.0)
    tops = {}
    for name, p in (("weak", weak), ("strong", strong)):
        space = feature_space(default_space(p, "klipper"), p, None, reserve=0.2)
        tops[name] = {g: hi for g, _lo, hi in space.feature_accel}
        # a point of the study (no group sampled) runs every group at the visible walls' acceleration,
        # within the group's range
        for accel in (3000.0, 20_000.0):
            cfg = config_from_params({"shaper_x": "mzv", "shaper_y": "mzv", "freq_x": 45.0, "freq_y": 40.0,
                                      "freq_limit": "off", "accel": accel}, space)
            for g, hi in tops[name].items():
                assert cfg.feature_accel[ACCEL_GROUPS[g][0]] == min(accel, hi)
    for g in tops["weak"]:
        assert tops["weak"][g] < tops["strong"][g]


def test_parameters_and_configs_map_both_ways_and_the_space_survives_json():
    space = feature_space(default_space(BASE, "klipper"), BASE, None)
    assert SearchSpace.from_dict(json.loads(json.dumps(space.to_dict()))) == space
    params = {"shaper_x": "ei", "shaper_y": "mzv", "freq_x": 51.4, "freq_y": 46.6, "damping_x": 0.1,
              "damping_y": 0.1, "freq_limit": "off", "accel": 5000.0, "accel_hidden_walls": 8000.0,
              "accel_infill": 9000.0, "accel_travel": 7000.0, "corner": 7.5, "min_cruise_ratio": 0.2,
              "corner_hidden": 21.0, "min_cruise_ratio_hidden": 0.0}
    cfg = config_from_params(params, space)
    assert cfg.feature_accel == {"inner_wall": 8000.0, "infill": 9000.0, "support": 9000.0, "travel": 7000.0}
    assert (cfg.corner, cfg.min_cruise_ratio) == (7.5, 0.2)
    # the corners nobody sees (the built-in print has no solid infill: solid infill's own corner
    # rule, walked apart, is not in its space)
    assert cfg.feature_corner == dict.fromkeys(("infill", "support", "travel"), 21.0)
    assert cfg.feature_min_cruise_ratio == dict.fromkeys(("infill", "support", "travel"), 0.0)
    assert TuneConfig.from_dict(json.loads(json.dumps(cfg.to_dict()))) == cfg
    assert params_from_config(cfg, space) == params
    # a configuration without per-feature values runs the printer's own corner and ratio
    plain = params_from_config(TuneConfig(shaper_x="ei", shaper_y="mzv", freq_x=51.4, freq_y=46.6, accel=5000.0),
                               space)
    assert plain["corner"] == BASE.limits.square_corner_velocity
    assert plain["min_cruise_ratio"] == BASE.limits.min_cruise_ratio
    assert plain["accel_infill"] == 5000.0


@pytest.mark.parametrize("firmware,corner,mcr", [("klipper", True, True), ("marlin", False, False)])
def test_the_corner_rule_is_searched_where_the_firmware_can_say_it(firmware, corner, mcr):
    """The default printer plans corners with Klipper's square_corner_velocity: Marlin has no
    command for it, so its corner is not searched there (nor minimum_cruise_ratio)."""
    space = feature_space(default_space(BASE, firmware), BASE, None)
    assert (space.corner is not None, space.min_cruise_ratio is not None) == (corner, mcr)


def test_auto_searches_per_feature_only_where_it_can_matter(data_dir):
    space = default_space(BASE, "klipper")
    assert wanted("auto", space, BASE, None, False, "respect")[0]
    assert not wanted("off", space, BASE, None, False, "respect")[0]
    assert not wanted("auto", space, BASE, None, True, "respect")[0]      # the job's own accelerations stand
    assert wanted("on", space, BASE, None, True, "respect")[0]
    fixed = SearchSpace.from_dict({**space.to_dict(), "accel": (3000.0, 3000.0)})
    assert not wanted("auto", fixed, BASE, None, False, "replace")[0]
    # a job with one visible feature and no travel has nothing apart from the visible walls
    one = ";TYPE:External perimeter\nG1 X0 Y0 F6000\nG1 X20 Y0 E1\nG1 X20 Y20 E2\n"
    assert hidden_groups(BASE, one) == [] and not wanted("on", space, BASE, one, False, "replace")[0]


def test_the_study_samples_no_walked_parameter():
    """The study samples what a single-acceleration study samples (shapers, the visible walls'
    acceleration); the group accelerations and the corner rules are the walk's (a FixedTrial
    refuses any parameter it is not given)."""
    import optuna

    space = feature_space(default_space(BASE, "klipper"), BASE, None)
    walked = set(walked_keys(space))
    assert walked == {f"accel_{g}" for g, _lo, _hi in space.feature_accel} | {
        "corner", "min_cruise_ratio", "corner_hidden", "min_cruise_ratio_hidden"}
    # a job with solid infill walks its corners apart (their extrusion is judged as seen)
    part = set(walked_keys(feature_space(default_space(BASE, "klipper"), BASE, "part")))
    assert part - walked == {"accel_solid_infill", "accel_top_surface", "corner_solid", "min_cruise_ratio_solid"}
    given = {"shaper_x": "zv", "shaper_y": "zv", "freq_x": 45.0, "freq_y": 40.0, "damping_x": 0.1, "damping_y": 0.1,
             "freq_limit": "off", "accel": 4000.0}
    p = suggest_params(optuna.trial.FixedTrial(given), space)
    assert not walked & set(p)
    part_space = feature_space(default_space(BASE, "klipper"), BASE, "part")
    params = {**given, **{f"accel_{g}": 5000.0 for g, _lo, _hi in part_space.feature_accel}, "corner": 5.0,
              "min_cruise_ratio": 0.5, "corner_hidden": 21.0, "min_cruise_ratio_hidden": 0.0, "corner_solid": 9.0,
              "min_cruise_ratio_solid": 0.5}
    cfg = config_from_params(params, part_space)
    assert cfg.feature_corner == {"infill": 21.0, "support": 21.0, "travel": 21.0, "solid_infill": 9.0}
    assert cfg.feature_min_cruise_ratio == {"infill": 0.0, "support": 0.0, "travel": 0.0, "solid_infill": 0.5}
    assert params_from_config(cfg, part_space) == params
