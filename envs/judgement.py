"""The PPO environment's cost of a configuration: ``tune``'s judgement as one number.

``tune`` chooses the fastest configuration with no visible measure worse than the baseline's at a
stated resolution, within its constraints (no lost steps, the motors' force reserve, the path-error
bound). As a cost, on one printer and job (all from :class:`ringtune.envs.metrics.Metrics`, the
measures named there):

    cost = w_time · T / T0
         + w_worse · Σ_k ln(1 + max(0, m_k − b_k − tol_k) / max(b_k, tol_k))      k in JUDGED_KEYS
         + P · step_loss + P · max(0, load − (1 − reserve)) / reserve
         + P · max(0, path_error − bound) / bound

with ``T`` the print time (s), ``T0`` the print time of the job at the printer's own acceleration,
``m_k`` and ``b_k`` a measure of the configuration and of the baseline (:func:`baseline_config`:
MZV on each axis's resonance peak at the printer's own acceleration, Klipper's usual pick) on the
same printer, ``tol_k = max(distance_mm, distance_rel · max(m_k, b_k))`` the resolution below which
two figures are the same (``agents.tune.pareto.Resolution``'s), ``P`` the step-loss penalty. A
configuration no worse than the baseline in every judged measure pays only its print time;
each measure worse than the baseline's costs the logarithm of one plus its relative excess (as the
relative excess while it is small; a measure 100 times the baseline's, on a printer whose baseline
barely ripples, costs 4.6 rather than 99, so that one such printer does not drown the others in a
mean or in the policy's reward scale). The defaults equal ``tune``'s (``tests/test_ppo_judgement.py``
checks that they do).

*Example*: T/T0 = 0.9, the baseline's ripple 5 µm, the configuration's 7 µm (tolerance
max(1 µm, 0.35 µm) = 1 µm), every other measure no worse, nothing violated: cost = 0.9 + 5 · ln(1 +
(7 − 5 − 1)/5) = 0.9 + 5 · ln 1.2 = 1.81.
"""

from __future__ import annotations

import math

from ringtune.envs.metrics import EXTRUSION_KEYS, SEEN_KEYS, Metrics, by_variant
from ringtune.shaping.config import TuneConfig

#: the measures judged against the baseline: what a person sees on visible features, the
#: extruder's timing, and what hidden features push into the walls
JUDGED_KEYS = SEEN_KEYS + EXTRUSION_KEYS + ("show_through_mm",)
#: the resolution (mm and fraction) and constraints (fraction of the motors' force, mm) of the judgement
JUDGEMENT = {"distance_mm": 0.001, "distance_rel": 0.05, "pct_abs": 1.0, "motor_reserve": 0.2, "max_path_error_mm": 0.1}
#: reward weights: the print-time ratio and the summed relative excess over the baseline
DEFAULT_WEIGHTS = {"time": 1.0, "worse": 5.0}
#: the baseline's damping ratio
BASELINE_DAMPING = 0.1


def baseline_config(peaks, firmware: str, accel: float) -> TuneConfig:
    """MZV on each axis's resonance peak (``peaks`` (X, Y) Hz) at ``accel`` mm/s²: the baseline a
    configuration is judged against."""
    return TuneConfig(firmware=firmware, shaper_x="mzv", shaper_y="mzv", freq_x=float(peaks[0]),
                      freq_y=float(peaks[1]), damping_x=BASELINE_DAMPING, damping_y=BASELINE_DAMPING,
                      accel=float(accel))


def tolerance(key: str, a: float, b: float, judgement: dict = JUDGEMENT) -> float:
    """Below this two figures of measure ``key`` are the same: max(distance_mm, distance_rel · the
    larger) for distances (mm), max(pct_abs, distance_rel · the larger) for extrusion (``*_pct``, %)."""
    floor = judgement["pct_abs"] if key.endswith("_pct") else judgement["distance_mm"]
    return max(floor, judgement["distance_rel"] * max(abs(a), abs(b)))


def worse_by(m: Metrics, base: Metrics | None, judgement: dict = JUDGEMENT) -> dict[str, float]:
    """{measure: relative excess over the baseline beyond the resolution} for the judged measures
    where ``m`` is worse (empty when nothing is, or without a baseline). Where both were judged on
    the same printer variants (:func:`ringtune.envs.metrics.worst_case` names them), the largest
    excess over their worst and on each variant, as ``tune`` judges (a measure worse on one variant
    is worse)."""
    out = {}
    if base is None:
        return out
    pairs = [(m.to_dict(), base.to_dict())] + _variant_pairs(m, base)
    for k in JUDGED_KEYS:
        excess = []
        for mine, theirs in pairs:
            a, b = float(mine[k]), float(theirs[k])
            tol = tolerance(k, a, b, judgement)
            if a - b > tol:
                excess.append((a - b - tol) / max(b, tol))
        if excess:
            out[k] = max(excess)
    return out


def _variant_pairs(m: Metrics, base: Metrics) -> list[tuple[dict, dict]]:
    """(m's, base's) metrics on each printer variant both were judged on (:func:`by_variant`)."""
    theirs = by_variant(base)
    return [(d, theirs[v]) for v, d in by_variant(m).items() if v in theirs]


def violations(m: Metrics, penalty: float, judgement: dict = JUDGEMENT) -> float:
    """The constraints' cost: ``penalty`` for lost steps, and ``penalty`` × the relative excess of
    the motor load over 1 − reserve (in units of the reserve) and of the path error over its bound."""
    reserve = judgement["motor_reserve"]
    bound = judgement["max_path_error_mm"]
    cost = penalty if m.step_loss else 0.0
    if reserve > 0:
        cost += penalty * max(0.0, float(m.motor_load) - (1.0 - reserve)) / reserve
    if bound > 0:
        cost += penalty * max(0.0, float(m.path_error_mm) - bound) / bound
    return cost


def judged_cost(m: Metrics, base: Metrics | None, t0: float, weights: dict, penalty: float,
                judgement: dict = JUDGEMENT) -> float:
    """The cost above (``t0`` s; ``weights`` keys time and worse)."""
    worse = sum(math.log1p(x) for x in worse_by(m, base, judgement).values())
    return weights["time"] * float(m.print_time_s) / t0 + weights["worse"] * worse + violations(m, penalty, judgement)
