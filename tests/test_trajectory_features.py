"""`plan --trajectory` labels each sample with the feature of the move X/Y are on, as the job names
it: on a real sliced file, the samples labelled as outer wall lie on the file's outer-wall moves
(read from the G-code text here, independently of ringtune's reader)."""

from __future__ import annotations

import csv
import json
import re

import numpy as np
import pytest

from ringtune.agents.cli.main import main

CURA = "gcode/fastlb_cura_um2/platte_klein_cut.gcode"          # Cura 5.0: ;TYPE:WALL-OUTER, SKIN, FILL
PRUSA = "gcode/ianalexis_ender3_marlin/ringing_tower.gcode"    # PrusaSlicer 2.9: ;TYPE:External perimeter


def _segments(path, label: str) -> np.ndarray:
    """(n, 4) x0, y0, x1, y1 of the G0/G1 moves in X/Y under ``;TYPE:label`` (absolute positioning,
    as both files use)."""
    kind, x, y, out = None, 0.0, 0.0, []
    for line in path.read_text().splitlines():
        if line.startswith(";TYPE:"):
            kind = line[6:].strip()
            continue
        code = line.split(";")[0]
        if not re.match(r"G[01]\b", code):
            continue
        words = dict((w[0], float(w[1:])) for w in code.split()[1:] if w[0] in "XY")
        nx, ny = words.get("X", x), words.get("Y", y)
        if kind == label and (nx, ny) != (x, y):
            out.append((x, y, nx, ny))
        x, y = nx, ny
    return np.array(out)


def _distance(pts: np.ndarray, segs: np.ndarray) -> np.ndarray:
    """Each point's distance (mm) from the nearest of ``segs`` (in chunks of points)."""
    a, b = segs[None, :, :2], segs[None, :, 2:]
    d = b - a
    out = []
    for chunk in np.array_split(pts, max(1, len(pts) // 20)):
        p = chunk[:, None]
        u = np.clip(np.sum((p - a) * d, axis=2) / np.maximum(np.sum(d * d, axis=2), 1e-12), 0, 1)
        out.append(np.min(np.linalg.norm(p - (a + u[..., None] * d), axis=2), axis=1))
    return np.concatenate(out)


def _some(mask: np.ndarray, n: int = 400) -> np.ndarray:
    """Up to ``n`` indices where ``mask`` holds, spread evenly (deterministic)."""
    idx = np.flatnonzero(mask)
    return idx[np.linspace(0, len(idx) - 1, min(n, len(idx))).astype(int)] if len(idx) else idx


def _read(traj):
    with open(traj) as f:
        rows = list(csv.reader(f))
    assert rows[0] == ["t", "x", "y", "z", "e", "feature"]
    xy = np.array([[float(r[1]), float(r[2])] for r in rows[1:]])
    return xy, np.array([r[5] for r in rows[1:]])


@pytest.mark.parametrize("rel,label,rate", [(CURA, "WALL-OUTER", "500"), (PRUSA, "External perimeter", "20")])
def test_outer_wall_samples_lie_on_the_outer_wall_moves(data_dir, tmp_path, capsys, rel, label, rate):
    job = data_dir / rel
    traj = tmp_path / "t.csv"
    assert main(["plan", str(job), "--trajectory", str(traj), "--rate", rate]) == 0
    capsys.readouterr()
    xy, feature = _read(traj)
    wall = _segments(job, label)
    on = feature == label
    assert on.sum() > 50
    assert _distance(xy[_some(on)], wall).max() < 1e-5          # the planned path: exactly on them
    # the other features' samples are not all on the wall: the column tells them apart
    others = xy[_some((feature != label) & (feature != ""))]
    assert len(others) and _distance(others, wall).max() > 1.0


def test_causal_shaper_labels_follow_the_delayed_axes(data_dir, tmp_path, capsys):
    """Marlin's classic ZV delays X/Y by ΣAᵢTᵢ: the labels follow the delayed X/Y, so the outer-wall
    samples stay on the outer wall within the shaper's smoothing (not a lag's travel away)."""
    job = data_dir / CURA
    cfg = tmp_path / "c.json"
    cfg.write_text(json.dumps({"firmware": "marlin", "shaper_x": "zv", "shaper_y": "zv",
                               "freq_x": 40, "freq_y": 40, "damping_x": 0.1, "damping_y": 0.1}))
    traj = tmp_path / "t.csv"
    assert main(["plan", str(job), "--config", str(cfg), "--trajectory", str(traj), "--rate", "500"]) == 0
    capsys.readouterr()
    xy, feature = _read(traj)
    on = feature == "WALL-OUTER"
    assert on.sum() > 50
    assert _distance(xy[on], _segments(job, "WALL-OUTER")).max() < 0.3
