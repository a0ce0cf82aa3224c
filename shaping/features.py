"""Feature classes of a sliced job: which moves a person sees on the finished part.

Slicers label each stretch of a job with a comment (``;TYPE:External perimeter`` in PrusaSlicer and
SuperSlicer, ``;TYPE:Outer wall`` in OrcaSlicer, ``; FEATURE: Outer wall`` in Bambu Studio,
``;TYPE:WALL-OUTER`` in Cura, ``; feature outer perimeter`` in Simplify3D); the G-code reader keeps
the raw label per move (``Job.features``, ``"unknown"`` before the first label). This module maps a
raw label to one of :data:`FEATURE_CLASSES`:

- ``outer_wall``: external perimeters, outer walls, thin walls;
- ``inner_wall``: inner perimeters and walls;
- ``infill``: sparse infill;
- ``solid_infill``: internal solid infill, bottom surfaces, internal bridges;
- ``top_surface``: top solid infill, ironing; also the labels that do not tell top from bottom
  (Cura ``SKIN``, Simplify3D ``solid layer``): counted as seen, since their top layer is;
- ``bridge_overhang``: bridges over air and overhang perimeters;
- ``travel``: labels naming a travel (most slicers label none; non-extruding moves are travel
  whatever their label, which the judge decides from the moves, not here);
- ``support``: material that is not the part: support and its interface, skirt, brim, raft,
  wipe/prime towers, ooze shields;
- ``other``: unlabelled moves and labels that could be on the surface or are unknown (custom
  G-code, gap fill, PrusaSlicer ``Mixed``); gap fill stays here because PrusaSlicer gives it its
  ``default_acceleration``, as :mod:`ringtune.hardware.slicer_profile` exports ``other``.

:data:`VISIBLE` classes are judged by what a person sees (ripple, corners, extrusion);
:data:`HIDDEN` ones only by what shows through and by extrusion. Unlabelled and unknown moves run
at the visible walls' settings (a label we cannot read is not a licence to print it badly); in a
job that labels nothing visible they are judged as seen, in one that labels its visible features
they are not judged — there they are mostly a purge line — (:func:`seen_classes`), which
:func:`purge_note` says with their labels.
"""

from __future__ import annotations

import re

import numpy as np

FEATURE_CLASSES = ("outer_wall", "inner_wall", "infill", "solid_infill", "top_surface",
                   "bridge_overhang", "travel", "support", "other")
VISIBLE = frozenset({"outer_wall", "top_surface", "bridge_overhang", "other"})
HIDDEN = frozenset(FEATURE_CLASSES) - VISIBLE
#: the visible classes a slicer labels (``other`` is what has no label)
LABELLED_VISIBLE = VISIBLE - {"other"}


def seen_classes(present) -> frozenset:
    """The classes of the part a person sees among ``present`` (class names of a job's extrusion):
    :data:`VISIBLE`, but ``other`` only in a job that labels nothing visible — in a labelled job
    unlabelled extrusion is a purge line, not the part."""
    return LABELLED_VISIBLE if LABELLED_VISIBLE & set(present) else VISIBLE


def nothing_seen_note(job) -> str | None:
    """Where a parsed job (:class:`ringtune.shaping.job.Job`) extrudes only classes nobody sees (an
    infill-only test, a support-only file): one sentence saying so, with its labels; no visible
    measure is judged there (they all read 0). None otherwise, and for a job that extrudes nothing."""
    d = job.end - job.start
    extruding = (d[:, 3] > 0) & (np.hypot(d[:, 0], d[:, 1]) > 0)
    if not extruding.any():
        return None
    used = np.unique(job.feature[extruding])
    present = {feature_class(job.features[i]) for i in used}
    if seen_classes(present) & present:
        return None
    labels = ", ".join(sorted({str(job.features[i]) for i in used}))
    return (f"the job labels none of its extrusion as seen ({labels}): no visible measure (ripple, corners, "
            "extrusion) is judged, they all read 0, so only the bounds (motor reserve, path error, show-through) "
            "hold the acceleration")


def purge_note(job) -> str | None:
    """Where a parsed job labels what is seen and also extrudes moves of class ``other`` (no label,
    as before CuraEngine's first label, PrusaSlicer's ``Custom`` or ``Gap fill``, a label not known
    here): one sentence saying they are not judged as the part (:func:`seen_classes`) but run at the
    visible walls' settings, with their labels ("no label" for the parser's ``unknown``, index 0),
    count and first line. None otherwise."""
    d = job.end - job.start
    extruding = (d[:, 3] > 0) & (np.hypot(d[:, 0], d[:, 1]) > 0)
    used = np.unique(job.feature[extruding])
    cls = {int(i): feature_class(job.features[i]) for i in used}
    if "other" not in cls.values() or not LABELLED_VISIBLE & set(cls.values()):
        return None
    other = extruding & np.isin(job.feature, [i for i, c in cls.items() if c == "other"])
    labels = ", ".join(sorted({str(job.features[i]) if i else "no label" for i in np.unique(job.feature[other])}))
    return (f"the job labels what a person sees, so its other extrusion ({labels}: {int(other.sum())} moves from "
            f"line {int(job.line[other][0])}; mostly a purge line) is not judged as the part; it runs at the "
            "visible walls' settings")


#: normalised label (lower case, ``-``/``_``/``/`` as spaces, single spaces) -> class; the
#: spellings of PrusaSlicer/SuperSlicer, OrcaSlicer/Bambu Studio, Cura, Simplify3D and ideaMaker
_EXACT = {
    # PrusaSlicer / SuperSlicer (ExtrusionRole names)
    "external perimeter": "outer_wall", "perimeter": "inner_wall",
    "overhang perimeter": "bridge_overhang", "internal infill": "infill",
    "solid infill": "solid_infill", "top solid infill": "top_surface", "ironing": "top_surface",
    "bridge infill": "bridge_overhang", "internal bridge infill": "solid_infill",
    "thin wall": "outer_wall", "gap fill": "other", "skirt": "support", "brim": "support",
    "skirt brim": "support", "support material": "support",
    "support material interface": "support", "wipe tower": "support", "custom": "other",
    "mixed": "other", "milling": "other",
    # OrcaSlicer / Bambu Studio
    "outer wall": "outer_wall", "inner wall": "inner_wall", "overhang wall": "bridge_overhang",
    "sparse infill": "infill", "internal solid infill": "solid_infill",
    "top surface": "top_surface", "bottom surface": "solid_infill", "bridge": "bridge_overhang",
    "internal bridge": "solid_infill", "gap infill": "other", "support interface": "support",
    "support transition": "support", "prime tower": "support", "support": "support",
    "floating vertical shell": "outer_wall",
    # Cura (PrintFeatureType) and ideaMaker
    "wall outer": "outer_wall", "wall inner": "inner_wall", "skin": "top_surface", "fill": "infill",
    "support infill": "support", "support roof": "support", "support bottom": "support",
    "raft": "support", "move": "travel", "travel": "travel", "solid fill": "solid_infill",
    "sparse fill": "infill", "none": "other", "unknown": "other", "": "other",
    # Simplify3D
    "outer perimeter": "outer_wall", "inner perimeter": "inner_wall", "infill": "infill",
    "solid layer": "top_surface", "dense support": "support", "prime pillar": "support",
    "ooze shield": "support",
}

#: (pattern in a normalised label, class), tried in order when no exact spelling matches
_KEYWORDS = (
    ("support", "support"), ("skirt", "support"), ("brim", "support"), ("raft", "support"),
    ("wipe", "support"), ("prime", "support"), ("travel", "travel"),
    ("overhang", "bridge_overhang"), ("internal bridge", "solid_infill"),
    ("bridge", "bridge_overhang"), ("top", "top_surface"), ("ironing", "top_surface"),
    ("bottom", "solid_infill"), ("solid", "solid_infill"), ("infill", "infill"),
    ("outer", "outer_wall"), ("external", "outer_wall"), ("inner", "inner_wall"),
    ("internal perimeter", "inner_wall"), ("perimeter", "inner_wall"), ("wall", "inner_wall"),
)

_SEPARATORS = re.compile(r"[\s_/\-]+")


def normalise_label(label: str) -> str:
    """A raw feature label in the form the tables use: lower case, ``-``, ``_``, ``/`` and runs of
    spaces as single spaces (``WALL-OUTER`` -> ``wall outer``, ``Skirt/Brim`` -> ``skirt brim``)."""
    return _SEPARATORS.sub(" ", str(label)).strip().lower()


def feature_class(label: str) -> str:
    """The class of :data:`FEATURE_CLASSES` a slicer's raw feature label belongs to.

    Exact spellings of the slicers listed in the module docstring first, then keywords (an
    unknown slicer's ``Outer wall (overhang)`` is still an overhang); anything else is ``other``
    (seen)."""
    key = normalise_label(label)
    if key in _EXACT:
        return _EXACT[key]
    for word, cls in _KEYWORDS:
        if word in key:
            return cls
    return "other"


def class_indices(labels: list[str]) -> np.ndarray:
    """(len(labels),) index into :data:`FEATURE_CLASSES` of each raw label's class."""
    return np.array([FEATURE_CLASSES.index(feature_class(lab)) for lab in labels], np.int64)
