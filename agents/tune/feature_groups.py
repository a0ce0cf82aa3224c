"""The feature groups of the per-feature search: which feature classes share an acceleration, and
which share a corner rule, and in what spirit each is judged (``tune``'s walk where nobody looks,
:mod:`ringtune.agents.tune.hidden_raise`; the classes: :mod:`ringtune.shaping.features`)."""

from __future__ import annotations

#: acceleration groups of feature classes searched apart (``visible``: the config's ``accel``); top
#: surfaces have their own, judged as seen; internal solid infill its own, hidden (a top surface's
#: judgement does not hold it back); support goes with the infill
ACCEL_GROUPS = {"visible": ("outer_wall", "bridge_overhang", "other"), "top_surface": ("top_surface",),
                "hidden_walls": ("inner_wall",), "infill": ("infill", "support"),
                "solid_infill": ("solid_infill",), "travel": ("travel",)}
#: groups apart from ``visible`` that a person sees: walked last (:mod:`ringtune.agents.tune.hidden_raise`)
SEEN_GROUPS = ("top_surface",)
#: groups that lie against what is seen (inner walls abut the outer wall: what they push into it is
#: judged, :data:`ringtune.agents.tune.pareto.CLASS_KEYS`); walked after those nobody sees
ABUTTING_GROUPS = ("hidden_walls",)
#: classes whose corners nobody sees, in two groups, each with its own corner rule and
#: minimum_cruise_ratio searched apart from the visible walls' (inner walls abut the outer wall:
#: they keep the job-wide ones): ``hidden``, sparse infill and support behind the perimeters and
#: travel, which prints nothing; ``solid``, solid infill, whose corners are as hidden but whose
#: extrusion is judged as seen (it lies under the top surface and forms the bottom:
#: :data:`ringtune.envs.window_metrics.EXTRUSION_SEEN`), so that its extrusion does not hold the
#: others' corner rule down (on the built-in part it held all four at 9 mm/s; apart, the others
#: reach 30)
CORNER_GROUPS = {"hidden": ("infill", "support", "travel"), "solid": ("solid_infill",)}
#: each corner group in words: whose corners they are and whose rule (the walk's lines), and how
#: they are judged (the summary's per-feature section)
CORNER_WORDS = {"hidden": ("the corners nobody sees", "their", "corners nobody sees"),
                "solid": ("solid infill", "solid infill's", "corners nobody sees; its extrusion judged as seen")}
#: every class whose corners nobody sees
HIDDEN_CORNERS = tuple(c for classes in CORNER_GROUPS.values() for c in classes)


def corner_groups(space) -> list[str]:
    """The groups of :data:`CORNER_GROUPS` the job has classes of (from the acceleration groups of
    ``space``, a :class:`ringtune.agents.tune.space.SearchSpace`)."""
    present = {c for g, _lo, _hi in space.feature_accel for c in ACCEL_GROUPS[g]}
    return [name for name, classes in CORNER_GROUPS.items() if present & set(classes)]
