"""Feature classes from the labels real slicers write (tests/data/gcode, SOURCES.md there).

Truth: each slicer's own spelling of its features, read from the real files by the G-code reader,
and what each feature is on the part (an external perimeter is the outer wall a person sees, a
skirt is not the part)."""

from __future__ import annotations

from pathlib import Path

import pytest

from ringtune.shaping.features import (FEATURE_CLASSES, HIDDEN, VISIBLE, feature_class,
                                       normalise_label, nothing_seen_note, purge_note)
from ringtune.shaping.gcode import read_gcode
from ringtune.shaping.planner import MachineLimits
from ringtune.shaping.reading_notes import reading_notes

DATA = Path(__file__).parent / "data" / "gcode"


def _labels(path: Path) -> set[str]:
    """The raw labels of the moves a real file has (as the reader keeps them)."""
    job = read_gcode(path)
    return {job.features[i] for i in set(job.feature.tolist())}


def test_visible_and_hidden_split_the_classes():
    assert VISIBLE | HIDDEN == set(FEATURE_CLASSES)
    assert not VISIBLE & HIDDEN
    assert {"outer_wall", "top_surface", "bridge_overhang", "other"} == VISIBLE


def test_prusaslicer_labels_of_a_real_tower():
    labels = _labels(DATA / "ianalexis_ender3_marlin" / "ringing_tower.gcode")
    assert {"External perimeter", "Skirt/Brim", "Custom"} <= labels
    assert feature_class("External perimeter") == "outer_wall"
    assert feature_class("Skirt/Brim") == "support"
    assert feature_class("Custom") == "other"


def test_simplify3d_labels_of_a_real_tower():
    labels = _labels(DATA / "bassco_ender3" / "ringing_tower.gcode")
    assert {"outer perimeter", "skirt", "solid layer"} <= labels
    assert feature_class("outer perimeter") == "outer_wall"
    assert feature_class("skirt") == "support"
    # Simplify3D does not tell top from bottom layers: the top one is seen
    assert feature_class("solid layer") == "top_surface"


def test_cura_labels_of_a_real_job():
    labels = _labels(DATA / "fastlb_cura_um2" / "platte_klein_cut.gcode")
    assert {"SKIRT", "WALL-OUTER", "SKIN", "FILL"} <= labels
    assert [feature_class(x) for x in ("WALL-OUTER", "SKIN", "FILL", "SKIRT")] == \
        ["outer_wall", "top_surface", "infill", "support"]
    job = read_gcode(DATA / "fastlb_cura_um2" / "platte_klein_cut.gcode")
    seen = [feature_class(job.features[i]) in VISIBLE for i in job.feature[job.extruding]]
    assert any(seen) and not all(seen)        # walls and skin seen, infill and skirt hidden


def test_unlabelled_moves_count_as_visible():
    job = read_gcode("G90\nM83\nG1 X10 Y0 E1 F3000\n")
    assert job.features[job.feature[0]] == "unknown"
    assert feature_class("unknown") in VISIBLE
    assert feature_class("") == "other"


@pytest.mark.parametrize("label, cls", [
    ("WALL-OUTER", "outer_wall"), ("WALL-INNER", "inner_wall"), ("FILL", "infill"),
    ("SKIN", "top_surface"), ("SUPPORT-INTERFACE", "support"), ("SKIRT", "support"),
    ("Outer wall", "outer_wall"), ("Inner wall", "inner_wall"), ("Sparse infill", "infill"),
    ("Internal solid infill", "solid_infill"), ("Top surface", "top_surface"),
    ("Bottom surface", "solid_infill"), ("Overhang wall", "bridge_overhang"),
    ("Bridge", "bridge_overhang"), ("Internal Bridge", "solid_infill"),
    ("Perimeter", "inner_wall"), ("Internal infill", "infill"), ("Solid infill", "solid_infill"),
    ("Top solid infill", "top_surface"), ("Bridge infill", "bridge_overhang"),
    ("Overhang perimeter", "bridge_overhang"), ("Support material", "support"),
    ("Wipe tower", "support"), ("Gap fill", "other"), ("inner perimeter", "inner_wall"),
    ("infill", "infill"), ("something new", "other"),
])
def test_slicer_spellings(label, cls):
    assert feature_class(label) == cls
    assert cls in FEATURE_CLASSES


def test_normalise_label():
    assert normalise_label("  WALL-OUTER ") == "wall outer"
    assert normalise_label("Skirt/Brim") == "skirt brim"


def test_a_labelled_jobs_purge_line_is_said_not_judged(data_dir):
    """CuraEngine's slice of the part purges twice before its first label (the Creality start
    G-code's lines 25 and 27): said, with its label, count and line; a job without
    labels, or labelling only hidden features, or with nothing unlabelled, says nothing."""
    cura = read_gcode(data_dir / "part/part_cura.gcode")
    lines = (data_dir / "part/part_cura.gcode").read_text().splitlines()
    note = purge_note(cura)
    assert note.startswith("the job labels what a person sees, so its other extrusion (no label: 2 moves from line 25; mostly a purge line) is not")
    assert lines[24].startswith("G1") and " E" in lines[24] and lines[26].startswith("G1") and " E" in lines[26]
    assert note in reading_notes(cura, MachineLimits(), "klipper")
    zigzag = "".join(f"G1 X{20 + 40 * (i % 2)} Y{20 + 0.5 * i:.1f} E0.5 F9000\n" for i in range(20))
    for text in ("M83\n" + zigzag, "M83\n" + zigzag + ";TYPE:Internal infill\n" + zigzag,
                 "M83\n;TYPE:External perimeter\n" + zigzag):
        assert purge_note(read_gcode(text)) is None
    assert "(no label: 20 moves from line 2;" in purge_note(read_gcode("M83\n" + zigzag + ";TYPE:External perimeter\n" + zigzag))


def test_a_job_that_extrudes_nothing_seen_says_its_visible_measures_are_not_judged(data_dir):
    """An infill-only file (or support-only) reads 0 on every visible measure: tune and simulate say
    so (the reading notes) rather than let the zeros pass for quality. A job with any seen class, or
    with unlabelled extrusion only (seen), or extruding nothing, says nothing."""
    zigzag = "".join(f"G1 X{20 + 40 * (i % 2)} Y{20 + 0.5 * i:.1f} E0.5 F9000\n" for i in range(20))
    hidden = read_gcode("M83\n;TYPE:Internal infill\n" + zigzag + ";TYPE:Skirt\n" + zigzag)
    note = nothing_seen_note(hidden)
    assert note.startswith("the job labels none of its extrusion as seen (Internal infill, Skirt)")
    assert note in reading_notes(hidden, MachineLimits(), "klipper")
    for text in ("M83\n;TYPE:Internal infill\n" + zigzag + ";TYPE:External perimeter\n" + zigzag,
                 "M83\n" + zigzag, "G1 X10 Y10\nG1 X20 Y10\n"):
        assert nothing_seen_note(read_gcode(text)) is None
    assert nothing_seen_note(read_gcode(data_dir / "gcode/fastlb_cura_um2/platte_klein_cut.gcode")) is None
