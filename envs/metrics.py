"""The print-quality record of a simulated print (:class:`Metrics`) and how records combine: the
windows of one job into the job's (:meth:`Metrics.worst`), a configuration's results on several
printer variants into the worst case (:func:`worst_case`, :func:`by_variant`).

What each measure is and how one window's are computed: :mod:`ringtune.envs.window_metrics`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Iterable, Sequence

import numpy as np

from ringtune.envs.visible import p90
from ringtune.shaping.features import VISIBLE

#: the measures kept per feature class (``Metrics.features[class]``)
FEATURE_KEYS = ("ripple_mm", "ripple_p90_mm", "corner_in_mm", "corner_out_mm", "show_through_mm",
                "extrusion_over_pct", "extrusion_under_pct", "e_lag_mm", "path_error_mm")
#: what a person sees on the visible features (all: smaller is better)
SEEN_KEYS = ("ripple_mm", "ripple_p90_mm", "corner_in_mm", "corner_out_mm")
#: the extruder's timing measures (per class; the job's over
#: :data:`ringtune.envs.window_metrics.EXTRUSION_SEEN`)
EXTRUSION_KEYS = ("extrusion_over_pct", "extrusion_under_pct", "e_lag_mm")


@dataclass
class Metrics:
    """Print time and quality of one configuration on one job (definitions:
    :mod:`ringtune.envs.window_metrics`).

    Attributes:
        print_time_s: planned print time of the whole job, s.
        path_error_mm: largest nozzle distance from the extrusion path while extruding, mm.
        overshoot_mm: largest outward excursion past the path after a corner or reversal, mm.
        ringing_mm: worst RMS oscillation across a straight wall after a direction change, mm.
        peak_accel: largest head acceleration magnitude, mm/s².
        step_loss: whether a motor was asked for more force than it has at that speed.
        motor_load: largest fraction of the force a motor has at its speed that it was asked for
            (``max |force| / max_force(speed)``; 1 is the edge of step loss; 0 if not simulated;
            the evaluator takes in the whole planned job's, rigid machine).
        details: diagnostics (per-window values, where the worst error occurred); not part of
            the stable ``to_dict()`` keys unless asked for.
        ripple_mm: worst visible wall's peak-to-peak deviation across the wall, mm.
        ripple_p90_mm: 90th percentile of the visible walls' ripple, mm.
        corner_in_mm: worst inward deviation at visible corners (rounding), mm.
        corner_out_mm: worst outward deviation at visible corners (overshoot), mm.
        extrusion_over_pct: worst over-extrusion over 1 mm of path, %.
        extrusion_under_pct: worst under-extrusion over 1 mm of path, %.
        e_lag_mm: largest distance along the path between the extruder and the nozzle, mm.
        show_through_mm: hidden features' worst excursion towards the walls, mm.
        features: the measures per feature class present, ``{class: {key: value}}``.
        extrusion_if_synced: the extrusion measures with the firmware's E synchronisation on,
            where it has one off by default (else empty).
    """

    print_time_s: float = float("nan")
    path_error_mm: float = 0.0
    overshoot_mm: float = 0.0
    ringing_mm: float = 0.0
    peak_accel: float = 0.0
    step_loss: bool = False
    motor_load: float = 0.0
    details: dict[str, Any] = field(default_factory=dict)
    ripple_mm: float = 0.0
    ripple_p90_mm: float = 0.0
    corner_in_mm: float = 0.0
    corner_out_mm: float = 0.0
    extrusion_over_pct: float = 0.0
    extrusion_under_pct: float = 0.0
    e_lag_mm: float = 0.0
    show_through_mm: float = 0.0
    features: dict[str, dict[str, float]] = field(default_factory=dict)
    extrusion_if_synced: dict[str, float] = field(default_factory=dict)

    QUALITY_KEYS = ("path_error_mm", "overshoot_mm", "ringing_mm")
    #: every scalar measure, in ``to_dict()`` order after ``print_time_s``
    SCALAR_KEYS = ("path_error_mm", "overshoot_mm", "ringing_mm", "peak_accel", "motor_load",
                   "ripple_mm", "ripple_p90_mm", "corner_in_mm", "corner_out_mm",
                   "extrusion_over_pct", "extrusion_under_pct", "e_lag_mm", "show_through_mm")

    def to_dict(self, details: bool = False) -> dict[str, Any]:
        d: dict[str, Any] = {"print_time_s": float(self.print_time_s)}
        d.update({k: float(getattr(self, k)) for k in self.SCALAR_KEYS})
        d["step_loss"] = bool(self.step_loss)
        d["features"] = {c: {k: float(v) for k, v in m.items()} for c, m in self.features.items()}
        d["extrusion_if_synced"] = {k: float(v) for k, v in self.extrusion_if_synced.items()}
        if details:
            d["details"] = self.details
        return d

    @staticmethod
    def worst(parts: Iterable["Metrics"], print_time_s: float = float("nan")) -> "Metrics":
        """Combine per-window metrics: the max of every measure, any step loss; the ripple's 90th
        percentile over the walls of all windows (kept in ``details["ripple_walls"]``) of the classes
        the first part judged as seen (``details["seen_classes"]``; :data:`VISIBLE` if it says none)."""
        parts = list(parts)
        if not parts:
            return Metrics(print_time_s=print_time_s)
        out = _combined(parts, print_time_s)
        seen = parts[0].details.get("seen_classes", sorted(VISIBLE))
        walls_all = [w for p in parts for w in p.details.get("ripple_walls", [])]
        if walls_all and all("ripple_walls" in p.details for p in parts):
            p90_from_walls(out, walls_all, seen)
        out.details = {"windows": [p.to_dict(details=True) for p in parts], "ripple_walls": walls_all,
                       "seen_classes": seen}
        return out


def _combined(parts: list[Metrics], print_time_s: float) -> Metrics:
    """The max of every scalar and per-feature measure of ``parts``, any step loss."""
    out = Metrics(print_time_s=print_time_s, step_loss=any(p.step_loss for p in parts),
                  **{k: max(getattr(p, k) for p in parts) for k in Metrics.SCALAR_KEYS})
    for p in parts:
        for cls, vals in p.features.items():
            mine = out.features.setdefault(cls, dict.fromkeys(FEATURE_KEYS, 0.0))
            for k, v in vals.items():
                mine[k] = max(mine.get(k, 0.0), v)
        for k, v in p.extrusion_if_synced.items():
            out.extrusion_if_synced[k] = max(out.extrusion_if_synced.get(k, 0.0), v)
    return out


def p90_from_walls(out: Metrics, walls_all: list, seen: Iterable[str] = VISIBLE) -> None:
    """Set the 90th percentiles of ``out`` from [class, ripple] pairs: per class, and at the top
    level over the classes in ``seen`` (the job's seen classes)."""
    seen = set(seen)
    by_class: dict[str, list[float]] = {}
    for cls, ripple in walls_all:
        by_class.setdefault(cls, []).append(ripple)
    out.ripple_p90_mm = p90(np.array([r for c, rs in by_class.items() if c in seen for r in rs]))
    for cls, vals in out.features.items():
        vals["ripple_p90_mm"] = p90(np.array(by_class.get(cls, [])))


def worst_case(results: Iterable[Metrics], variants: Sequence | None = None) -> Metrics:
    """One :class:`Metrics` for a configuration judged on several variants of a printer: the
    first's print time (the planner does not see resonances), the largest of every measure (the
    90th percentiles included, per printer), and step loss if any variant lost steps.
    ``details["variants"]``: each variant's own metrics (``to_dict``), with ``"variant"``: its
    (frequency factor, damping factor) where ``variants`` (:class:`ringtune.envs.variants.Variant`,
    in the order of ``results``) names them — a comparison variant by variant needs them."""
    results = list(results)
    worst = _combined(results, results[0].print_time_s)
    worst.details = {"variants": [m.to_dict() for m in results]}
    if variants is not None:
        for d, v in zip(worst.details["variants"], variants, strict=True):
            d["variant"] = [float(v.freq), float(v.damping)]
    return worst


def by_variant(m: Metrics) -> dict[tuple[float, float], dict[str, Any]]:
    """A :func:`worst_case` object's own metrics on each printer variant (``to_dict``), by the
    variant's (frequency factor, damping factor); {} where it was judged on one printer or its
    variants are not named."""
    out = {}
    for d in (getattr(m, "details", None) or {}).get("variants", ()):
        if "variant" not in d:
            return {}
        out[(float(d["variant"][0]), float(d["variant"][1]))] = d
    return out

