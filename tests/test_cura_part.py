"""The test part sliced by CuraEngine 4.13 (tests/data/part/part_cura.gcode, SOURCES.md): a whole
Cura job, its labels, and its own time estimate.

CuraEngine run alone writes ``;TIME:6666`` in the header whatever the model (Cura's window fills
its estimate in afterwards); its own estimate is the ``;TIME_ELAPSED:`` after the last layer.
Truth for the estimate read: planned with the limits CuraEngine estimated with (its definitions'
defaults: 4000 mm/s², classic jerk 20 mm/s, X/Y caps 9000 mm/s², no feedrate caps), ringtune's
planner lands within DESIGN's 3 % of it — and 72 % from the placeholder.
"""

from __future__ import annotations

import json
import re
from dataclasses import replace

import pytest

from ringtune.agents.cli.main import main
from ringtune.envs.printer import load_printer
from ringtune.shaping.config_plan import plan_with_config
from ringtune.shaping.features import feature_class
from ringtune.shaping.gcode import read_gcode
from ringtune.shaping.slicer import CURA_TIME_PLACEHOLDER, slicer_estimate

#: the limits CuraEngine 4.13's time estimate used for this job (fdmprinter.def.json's defaults the
#: engine run alone keeps: machine_acceleration 4000, machine_max_jerk_xy 20, machine_max_jerk_z 0.4,
#: machine_max_jerk_e 5, machine_max_acceleration_x/y 9000, _z 100, _e 10000, feedrates unbounded)
CURA_LIMITS = {"accel": 4000, "velocity": 1000, "junction": "jerk", "jerk": [20, 20, 0.4, 5],
               "max_accel": [9000, 9000, 100, 10000], "max_velocity": [0, 0, 0, 0]}


@pytest.fixture(scope="module")
def cura_part(data_dir):
    return data_dir / "part" / "part_cura.gcode"


def test_a_cura_engine_job_is_read_with_the_engines_own_estimate(cura_part):
    text = cura_part.read_text()
    assert ";TIME:6666\n" in text and "Cura_SteamEngine 4.13.0" in text
    last = float(re.findall(r";TIME_ELAPSED:([\d.]+)", text)[-1])
    assert slicer_estimate(cura_part) == last != CURA_TIME_PLACEHOLDER
    job = read_gcode(cura_part)
    assert {feature_class(f) for f in job.features} >= {"outer_wall", "inner_wall", "infill", "top_surface"}
    limits = replace(load_printer(None), limits_dict=CURA_LIMITS).limits
    planned = plan_with_config(job, limits, None).plan.print_time
    assert abs(planned / last - 1) < 0.03 and abs(planned / CURA_TIME_PLACEHOLDER - 1) > 0.5


def test_plan_compares_with_the_engines_estimate_not_the_placeholder(cura_part, capsys):
    assert main(["plan", str(cura_part), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["slicer_estimate_s"] == pytest.approx(1915.414508)
    assert res["vs_slicer"] == pytest.approx(res["print_time_s"] / 1915.414508 - 1)


def test_plan_names_the_class_each_of_curas_labels_is_judged_as(cura_part, capsys):
    """Cura's PrintFeatureType labels, each with the class its meaning gives (its walls, sparse
    fill, the skin of top and bottom faces alike, the skirt that is not the part)."""
    assert main(["plan", str(cura_part)]) == 0
    rows = {line.split()[0]: line.split()[1] for line in capsys.readouterr().out.splitlines()
            if line.startswith("    ") and line.strip().endswith("%")}
    cura = {"FILL": "infill", "SKIN": "top_surface", "WALL-OUTER": "outer_wall", "WALL-INNER": "inner_wall",
            "SKIRT": "support", "unknown": "other"}
    assert rows == cura
    assert main(["plan", str(cura_part), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["feature_classes"] == cura
