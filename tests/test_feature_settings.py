"""The per-move settings a per-feature configuration puts in force (issue 22), checked move by move
against a plain loop: every move of the built-in part and of three slicers' files gets its own row
of settings — the job's own, with the configuration's values over them — and no two rows are alike
without cause."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ringtune.envs.planned_job import resolve_job
from ringtune.envs.printer import load_printer
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.feature_settings import FeatureCommands, move_settings, with_feature_settings
from ringtune.shaping.job import SETTING_KEYS

JOBS = ["part", "gcode/ianalexis_ender3_marlin/ringing_tower.gcode", "gcode/bassco_ender3/ringing_tower.gcode",
        "gcode/fastlb_cura_um2/platte_klein_cut.gcode"]
CONFIG = dict(firmware="klipper", shaper_x="mzv", shaper_y="mzv", freq_x=50.0, freq_y=40.0, accel=6000.0,
              feature_accel={"top_surface": 6500.0, "inner_wall": 7000.0, "infill": 12000.0, "support": 12000.0,
                             "solid_infill": 8000.0, "travel": 10000.0},
              corner=5.0, min_cruise_ratio=0.5, feature_corner={"infill": 12.0, "travel": 12.0},
              feature_min_cruise_ratio={"infill": 0.0, "travel": 0.0})


@pytest.mark.parametrize("name", JOBS)
@pytest.mark.parametrize("junction,firmware", [("scv", "klipper"), ("jd", "marlin"), ("jerk", "rrf")])
def test_every_move_carries_the_jobs_settings_with_the_configurations_over_them(name, junction, firmware, data_dir):
    _key, job = resolve_job(name if name == "part" else str(data_dir / name))
    limits = dataclasses.replace(load_printer(None).limits, junction=junction)
    fc = FeatureCommands.from_config(TuneConfig(**{**CONFIG, "firmware": firmware}), limits)
    values = move_settings(job, fc)
    out = with_feature_settings(job, fc)
    assert values and out.n_moves == job.n_moves
    table, own = np.asarray(out.settings_table, float), np.asarray(job.settings_table, float)
    rows = set()
    for i in range(job.n_moves):          # the plain loop: the job's row, the configuration's values over it
        want = own[job.settings[i]].copy()
        for k, v in values.items():
            want[SETTING_KEYS.index(k)] = v[i]
        got = table[out.settings[i]]
        assert np.array_equal(got, want, equal_nan=True), (name, i)
        rows.add((int(job.settings[i]), tuple(np.nan_to_num([v[i] for v in values.values()], nan=-1.0))))
    assert len(table) == len(rows)        # one row per distinct (job's row, values) pair, none unused
    assert set(np.unique(out.settings)) == set(range(len(table)))


def test_a_job_changed_since_gets_its_own_classes():
    """The classes are worked out once per job object: another job (a copy with other labels) is
    not given the first one's."""
    _key, job = resolve_job("part")
    fc = FeatureCommands.from_config(TuneConfig(**CONFIG), load_printer(None).limits)
    first = move_settings(job, fc)["accel_klipper"]
    relabelled = dataclasses.replace(job, features=["Sparse infill"] * len(job.features))
    again = move_settings(relabelled, fc)["accel_klipper"]
    extruding = (np.hypot(job.delta[:, 0], job.delta[:, 1]) > 0) & (job.delta[:, 3] > 0)
    assert np.all(again[extruding] == CONFIG["feature_accel"]["infill"])
    assert not np.all(first[extruding] == CONFIG["feature_accel"]["infill"])
