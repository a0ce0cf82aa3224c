"""``export --slicer``: the exported keys, put through a real PrusaSlicer, give the G-code tune planned.

Truth: PrusaSlicer (Debian's 2.5 in CI) slicing ringtune's test part with the base profile of the
shipped job and the exported profile on top. In its G-code every feature's ``M204`` must be the
acceleration the export says that feature gets, and the file as sliced must plan (the printer's own
limits, the file's own acceleration commands) within 1 % of what tune predicts for the
configuration on the shipped part and on that same file.
"""

from __future__ import annotations

import json
import re
import subprocess
from dataclasses import fields

import numpy as np
import pytest
from prusaslicer import prusaslicer, slice_part

from ringtune.agents.cli.main import main
from ringtune.envs.job_rewrite import rewrite_gcode_bytes
from ringtune.envs.planned_job import planned_job, resolve_printer
from ringtune.hardware.slicer_profile import KEYS, feature_accels, slicer_profile
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.features import FEATURE_CLASSES, feature_class
from ringtune.shaping.gcode import read_gcode

#: a per-feature choice: visible classes slow, hidden ones fast, every class different
PER_FEATURE = {"outer_wall": 2000, "inner_wall": 5000, "infill": 7000, "solid_infill": 6000,
               "top_surface": 2500, "bridge_overhang": 1500, "travel": 8000, "support": 4000, "other": 3500}
CONFIGS = {"one acceleration": {"firmware": "klipper", "accel": 5000},
           "per feature": {"firmware": "klipper", "accel": 3000, "feature_accel": PER_FEATURE}}


def _before_26(version: str) -> bool:
    return tuple(int(v) for v in version.split(".")[:2]) < (2, 6)


def _per_feature_planning() -> bool:
    return "feature_accel" in {f.name for f in fields(TuneConfig)}


def _accel_by_feature(job) -> dict[str, set]:
    """Feature class -> the accelerations (mm/s²) the file itself sets on its moves: extruding moves
    by their label's class, X/Y moves without extrusion as ``travel``; before the first command, none."""
    accel = job.setting("accel_klipper")
    xy = np.hypot(job.delta[:, 0], job.delta[:, 1]) > 0
    labels = np.array([feature_class(f) for f in job.features])[job.feature]
    cls = np.where(job.extruding, labels, "travel")
    out: dict[str, set] = {}
    for i in np.flatnonzero(xy & ~np.isnan(accel)):
        out.setdefault(str(cls[i]), set()).add(float(accel[i]))
    return out


@pytest.mark.parametrize("case", list(CONFIGS))
def test_prusaslicer_puts_the_exported_accelerations_in_and_the_file_plans_as_tune_predicted(case, tmp_path):
    exe, version = prusaslicer()
    if case == "per feature" and not _per_feature_planning():
        pytest.skip("per-feature planning (TuneConfig.feature_accel) is not in this tree yet")
    config = TuneConfig.from_dict(CONFIGS[case])
    profile = slicer_profile(config, "prusaslicer", version=version)
    ini = tmp_path / "tuned.ini"
    ini.write_text(profile.render())
    sliced = read_gcode(slice_part(tmp_path / "tuned.gcode", ini))
    found = _accel_by_feature(sliced)
    assert {"outer_wall", "inner_wall", "infill", "solid_infill", "top_surface", "bridge_overhang",
            "travel"} <= set(found)
    for cls, values in found.items():                      # one acceleration per class, the exported one
        if cls == "bridge_overhang" and _before_26(version):   # 2.5: overhang perimeters take perimeter_acceleration
            assert profile.effective[cls] in values and values <= {profile.effective[cls],
                                                                    profile.effective["inner_wall"]}
        else:
            assert values == {profile.effective[cls]}, cls
    printer = resolve_printer(None)
    as_sliced = planned_job(printer, sliced).print_time    # the file's own M204 lines, nothing replaced
    as_expressed = TuneConfig.from_dict({**CONFIGS[case], "feature_accel": profile.effective}
                                        if case == "per feature" else CONFIGS[case])
    for job in ("part", sliced):                           # tune's prediction, on the shipped part and on this file
        predicted = planned_job(printer, job, as_expressed).print_time
        assert predicted == pytest.approx(as_sliced, rel=0.01)
    if case == "per feature":                               # and the per-feature choice is a real change
        assert abs(as_sliced / planned_job(printer, "part", TuneConfig(accel=3000)).print_time - 1) > 0.01


def test_the_prusaslicer_25_keys_are_options_of_the_installed_prusaslicer():
    exe, version = prusaslicer()
    table = "prusaslicer-2.5" if _before_26(version) else "prusaslicer"
    listed = subprocess.run([exe, "--help-fff"], capture_output=True, text=True, timeout=60).stdout
    for key, _ in KEYS[table]:
        assert f"--{key.replace('_', '-')} " in listed, key


def test_a_key_governing_several_classes_takes_the_slowest_and_says_so():
    config = TuneConfig.from_dict(CONFIGS["per feature"])
    wanted = feature_accels(config)
    assert wanted == {c: float(PER_FEATURE[c]) for c in FEATURE_CLASSES}
    for slicer, version in (("prusaslicer", "2.5"), ("prusaslicer", None), ("orcaslicer", None), ("cura", None)):
        prof = slicer_profile(config, slicer, version=version)
        for key, classes in KEYS["prusaslicer-2.5" if version else slicer]:
            assert float(prof.settings[key]) == min(PER_FEATURE[c] for c in classes)
        slower = [c for c in FEATURE_CLASSES if prof.effective[c] < wanted[c]]
        assert all(any(n.startswith(f"{c}: ") for n in prof.notes) for c in slower)
        assert all(prof.effective[c] <= wanted[c] for c in FEATURE_CLASSES if c != "bridge_overhang" or slicer != "cura")
    p26 = slicer_profile(config, "prusaslicer")     # 2.6 and later: every class but other/support its own key
    assert p26.effective == {**wanted, "support": 3500.0}
    # a slicer's travel acceleration is every travel's: the seam's travel, judged at the wall's, is
    # said to differ (outer wall 2000 < travel 8000), for every firmware
    for fw in ("klipper", "marlin"):
        prof = slicer_profile(TuneConfig.from_dict({**CONFIGS["per feature"], "firmware": fw}), "prusaslicer")
        seam = [n for n in prof.notes if n.startswith("the seam's travel")]
        assert len(seam) == 1 and "outer_wall 2000" in seam[0] and "8000" in seam[0]
    slow_travel = TuneConfig.from_dict({**CONFIGS["per feature"], "feature_accel": {**PER_FEATURE, "travel": 1000}})
    assert not [n for n in slicer_profile(slow_travel, "prusaslicer").notes if n.startswith("the seam's travel")]


def test_export_slicer_version_and_a_bad_one(tmp_path, capsys):
    p = tmp_path / "c.json"
    p.write_text(json.dumps(CONFIGS["per feature"]))
    assert main(["export", str(p), "--slicer", "prusaslicer", "--slicer-version", "2.5", "--part", "slicer",
                 "--json"]) == 0
    d = json.loads(capsys.readouterr().out)["slicer"]
    assert d["settings"]["perimeter_acceleration"] == "2000" and "external_perimeter_acceleration" not in d["settings"]
    assert d["effective"]["inner_wall"] == 2000.0 and d["version"] == "2.5"
    assert main(["export", str(p), "--slicer", "prusaslicer", "--slicer-version", "two"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--slicer-version" in err


@pytest.mark.parametrize("config, says", [
    ({"firmware": "klipper"}, "no feature_accel"),
    ({"firmware": "klipper", "feature_accel": {"outer_wall": 2000}}, "leaves out (inner_wall"),
    ({"firmware": "klipper", "accel": 3000, "feature_accel": {"outerwall": 2000}}, "'outerwall' is not a feature class"),
])
def test_a_config_the_slicer_keys_cannot_come_from_is_one_line(config, says, tmp_path, capsys):
    p = tmp_path / "c.json"
    p.write_text(json.dumps(config))
    assert main(["export", str(p), "--slicer", "orcaslicer"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and says in err and str(p) in err and "Traceback" not in err


def test_the_profile_sets_a_gcode_flavour_whose_acceleration_lines_the_firmware_takes():
    # Klipper takes M204 S, or P and T together (toolhead.py cmd_M204); PrusaSlicer's marlin2 writes a
    # lone M204 P per feature and T for travel, its legacy marlin M204 S, its klipper (2.6+) and
    # OrcaSlicer's klipper SET_VELOCITY_LIMIT ACCEL (GCodeWriter::set_acceleration_internal)
    klipper = TuneConfig.from_dict(CONFIGS["per feature"])
    marlin = TuneConfig.from_dict({**CONFIGS["per feature"], "firmware": "marlin"})
    assert slicer_profile(klipper, "prusaslicer", version="2.5").settings["gcode_flavor"] == "marlin"
    assert slicer_profile(klipper, "prusaslicer").settings["gcode_flavor"] == "klipper"
    assert slicer_profile(klipper, "orcaslicer").settings["gcode_flavor"] == "klipper"
    for version in ("2.5", None):
        assert slicer_profile(marlin, "prusaslicer", version=version).settings["gcode_flavor"] == "marlin2"
    assert "gcode_flavor = marlin\n" in slicer_profile(klipper, "prusaslicer", version="2.5").render()


#: a Marlin 2 profile whose slicer writes its own acceleration per feature (M204 P before each)
MARLIN_OWN = ("gcode_flavor = marlin2\ndefault_acceleration = 3000\nperimeter_acceleration = 2000\n"
              "bridge_acceleration = 1000\nfirst_layer_acceleration = 1000\n")


def test_a_marlin_job_with_its_own_per_feature_accelerations_plans_and_rewrites_as_marlin_runs_it(tmp_path):
    """PrusaSlicer's Marlin 2 job sets M204 P per feature. Truth, read from the file's text alone:
    each extruding X/Y move runs at the last ``M204 P`` (or ``S``) before it — Marlin's print
    acceleration, whatever corner rule the embedded printer description gives (Klipper's scv, under
    which a lone M204 P would be ignored). Then --job-accel replace at one acceleration: the
    rewritten file plans to tune's figure for the configuration."""
    prusaslicer()
    ini = tmp_path / "own.ini"
    ini.write_text(MARLIN_OWN)
    path = slice_part(tmp_path / "own.gcode", ini)
    expected, now = [], None
    for line in path.read_text().splitlines():
        m = re.match(r"M204\b.*?\b[PS](\d+(?:\.\d*)?)", line)
        if m:
            now = float(m.group(1))
        elif re.match(r"G[01]\b", line) and " E" in line and (" X" in line or " Y" in line) and now is not None:
            if not re.search(r"\bE-", line):
                expected.append(now)
    printer = resolve_printer(None)
    plan = planned_job(printer, str(path), TuneConfig(firmware="marlin", accel=None)).plan
    m = plan.moves
    ext = m.extruding & (np.hypot(*(m.end - m.start)[:, :2].T) > 0)
    assert len(expected) == int(ext.sum()) and {1000.0, 2000.0, 3000.0} <= set(expected)
    assert m.accel[ext] == pytest.approx(expected, rel=1e-12)
    cfg = TuneConfig(firmware="marlin", accel=6000.0, extra={"job_accel": "replace"})
    done = rewrite_gcode_bytes(path.read_bytes(), cfg, printer, str(path))
    assert done.after_s == pytest.approx(done.config_s, rel=1e-9)
    assert done.config_s == pytest.approx(planned_job(printer, str(path), cfg).print_time, rel=1e-12)
