"""Quality windows on a real sliced job are on the part (issue 22 item 6): a skirt, brim or support
(class ``support``) gets none while the part has corners or zigzags to judge; a job of nothing but
skirt is still judged. The classes come from the job's own labels (PrusaSlicer's ``;TYPE:``)."""

from __future__ import annotations

import numpy as np

from ringtune.envs.planned_job import planned_job
from ringtune.envs.printer import load_printer
from ringtune.shaping.features import feature_class
from ringtune.shaping.gcode import read_gcode


def test_a_prusaslicer_jobs_windows_are_on_the_part_not_its_skirt(data_dir):
    path = data_dir / "gcode/ianalexis_ender3_marlin/ringing_tower.gcode"
    job = read_gcode(path)
    labels = {feature_class(f) for f in job.features}
    assert "support" in labels and "outer_wall" in labels          # Skirt/Brim and External perimeter
    pj = planned_job(load_printer(None), path, None)
    shared = [w for w in pj.windows if not w.kind.startswith("seam")]
    assert len(shared) == 8
    # the seams too are the part's: its outer wall's entry and exit (the purge line before the
    # skirt, unlabelled, is not the part)
    assert sorted(w.kind for w in pj.windows if w.kind.startswith("seam")) == ["seam-in", "seam-out"]
    assert {w.feature for w in pj.windows} == {"outer_wall"}
    moves = pj.plan.moves
    by_line = dict(zip(moves.line.tolist(), moves.feature.tolist()))
    assert all(feature_class(moves.features[by_line[w.line]]) == "outer_wall" for w in pj.windows)


def test_a_job_of_skirt_alone_is_still_judged():
    square = "".join(f"G1 X{x} Y{y} E{i + 1} F6000\n" for i, (x, y) in
                     enumerate([(40, 0), (40, 40), (0, 40), (0, 0)] * 3))
    pj = planned_job(load_printer(None), ";TYPE:Skirt/Brim\nG1 X0 Y0 F6000\n" + square, None)
    assert pj.windows and {w.feature for w in pj.windows} == {"support"}
    assert np.all([w.t1 > w.t0 for w in pj.windows])
