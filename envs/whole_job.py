"""A configuration's measures over the whole job, not only its quality windows (a check of them).

``tune`` judges quality on a few windows of the job (:mod:`ringtune.envs.windows`): its sharpest
corners, fastest zigzags and seams, chosen on the printer's own plan, each with at most
:data:`~ringtune.envs.windows.SETTLE_MAX` s of history. This simulates the whole job instead, in
pieces of about ``span`` s cut where nothing is printed (a job printed without pause for longer than
two spans inside a straight line too: :func:`span_edges`), each with a
lead-in of :data:`LEAD_TAUS` time constants of the printer's slowest-decaying mode (what the
machine still carries of earlier motion: e^−6, 0.25 %), and measures each as a window
(:func:`ringtune.envs.windows.metrics_of`); the job's figures are the worst over the pieces. With
the exact linear backend a 20-minute job takes about a minute.
"""

from __future__ import annotations

import numpy as np

from ringtune.envs.metrics import Metrics
from ringtune.envs.planned_job import PlannedJob, planned_job, resolve_printer
from ringtune.envs.sim import simulate_batch
from ringtune.envs.window_dedup import distinct, moved
from ringtune.envs.windows import auto_settle, corner_tail, slowest_tau, window_metrics, window_runs
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.seams import SEAM_ORDER, seam_candidates
from ringtune.shaping.testprints import Window

#: s of the job per simulated piece (about: cut where nothing is printed)
SPAN_S = 300.0
#: most spans a piece may hold before it is cut inside the printing (:func:`span_edges`)
LONGEST = 2.0
#: s of a seam's window (as the quality windows': the seam at a fifth of it)
SEAM_SPAN_S = 0.25
#: time constants 1/(ζω) of the slowest-decaying mode simulated before each piece
LEAD_TAUS = 6.0
#: Hz of the exact backend's samples (corners are measured between samples; from 2 to 20 kHz Klipper's
#: pick on the built-in print moves its corners by 0.2 %, its ripple by 0.7 %, its outer wall's
#: under-extrusion by 3.5 %: what is still read at the samples)
RATE_HZ = 5000.0


def lead_in(printer, taus: float = LEAD_TAUS) -> float:
    """s of history simulated before each piece: ``taus`` time constants of the printer's
    slowest-decaying mode (:func:`ringtune.envs.windows.slowest_tau`; no upper bound, unlike a
    quality window's: a lightly damped mode rings for seconds)."""
    return taus * slowest_tau(printer)


def span_edges(motion, span: float) -> np.ndarray:
    """Times (s) that cut ``motion`` into pieces of about ``span`` s, where nothing is printed:
    from each cut on, the middle of the non-extruding stretch (a travel, a retraction, a layer
    change) nearest a span later and at least half a span later. A job printed for longer than
    :data:`LONGEST` spans without such a stretch (a vase, a tower in one bead) is cut inside the
    printing too, at the middle of the longest segment between half a span and one and a half spans
    on (a straight line's cruise, no corner within half of it): a piece holds at most
    ``LONGEST · span`` s, so memory stays bounded however long the job prints without pause."""
    t = np.asarray(motion.t, float)
    mid = 0.5 * (t[:-1] + t[1:])
    idle = mid[~np.asarray(motion.extruding, bool)]
    edges = [motion.start_time]
    while True:
        e = edges[-1]
        later = idle[(idle >= e + 0.5 * span) & (idle < motion.end_time)]
        cut = float(later[np.argmin(np.abs(later - (e + span)))]) if len(later) else None
        if motion.end_time - e > LONGEST * span and (cut is None or cut > e + LONGEST * span):
            reach = np.flatnonzero((mid >= e + 0.5 * span) & (mid <= e + 1.5 * span))
            if len(reach):
                cut = float(mid[reach[np.argmax(np.diff(t)[reach])]])
        if cut is None:
            break
        edges.append(cut)
    return np.array([*edges, motion.end_time])


def whole_job_metrics(config: TuneConfig, printer=None, job=None, *, span: float = SPAN_S,
                      backend: str = "lti", job_accel: str | None = None) -> Metrics:
    """The job's metrics with all of it simulated (print time the planner's, s).

    Args:
        config: the configuration, as ``tune`` judges it (its shapers rule the whole job).
        printer: a ``Printer``, a TOML path or None (the embedded default).
        job: as :func:`ringtune.envs.evaluate.evaluate` takes it.
        span: s per simulated piece (:func:`span_edges`).
        backend: ``"lti"`` (exact linear, default; sampled at :data:`RATE_HZ`) or ``"mujoco"``.
        job_accel: as :func:`ringtune.envs.evaluate.evaluate`.
    """
    if not span > 0:
        raise RingtuneError(f"must be > 0 s, not {span}", "span")
    printer = resolve_printer(printer)
    pj = planned_job(printer, job, config, job_accel=job_accel)
    edges = span_edges(pj.motion, span)
    step = 1.0 / RATE_HZ if backend == "lti" else None
    parts = [_simulated(printer, pj, [Window(float(a), float(b), "span", 0.0)], config, lead_in(printer), backend, step)
             for a, b in zip(edges, edges[1:])]
    return Metrics.worst(parts, print_time_s=pj.print_time)


def _simulated(printer, pj: PlannedJob, windows: list[Window], config: TuneConfig, settle: float, backend: str,
               timestep: float | None = None) -> Metrics:
    """The metrics of ``windows`` of planned job ``pj``, each shaped with ``settle`` s of history
    and simulated from rest (:func:`ringtune.envs.windows.window_runs`, ``window_metrics``); on the
    exact linear model a window that repeats another's motion is simulated once
    (:mod:`ringtune.envs.window_dedup`)."""
    runs = window_runs(PlannedJob(pj.plan, windows), config, settle, corner_tail(printer))
    every = list(range(len(runs)))
    firsts, of = distinct(runs) if backend == "lti" else (every, every)    # lti: the same wherever the head is
    sims = simulate_batch(printer, [runs[i].shaped for i in firsts], backend=backend, initial="static",
                          timestep=timestep)
    own = [window_metrics(runs[i], sim) for i, sim in zip(firsts, sims)]
    return Metrics.worst([moved(own[k], runs[firsts[k]], run) for run, k in zip(runs, of)],
                         print_time_s=pj.print_time)


def outer_wall_worst(m: Metrics, key: str) -> dict | None:
    """Where the outer wall's worst ``key`` (``corner_in_mm`` or ``corner_out_mm``) of metrics
    ``m`` is — {value mm, t s (unshaped clock), x, y mm} — found in its windows (and the windows of
    its pieces, :func:`whole_job_metrics`); None where no window held the outer wall."""
    found = []

    def walk(details: dict) -> None:
        at = details.get("outer_wall_at", {}).get(key)
        if at is not None:
            found.append(at)
        for w in details.get("windows", ()):
            walk(w.get("details", {}))
    walk(m.details)
    return max(found, key=lambda at: at["value"]) if found else None


def seam_windows(plan, span: float = SEAM_SPAN_S) -> list[Window]:
    """A window on every seam of a visible class (a visible run's first and last move: where a
    travel, an inner wall or infill meets what is seen; :func:`ringtune.shaping.seams.seam_candidates`),
    in time order; overlapping ones merged into one."""
    cands = seam_candidates(plan, span)
    t0 = np.sort(np.concatenate([cands[side][0][np.isin(cands[side][3], SEAM_ORDER)]
                                 for side in ("seam-in", "seam-out")]))
    a = np.clip(t0, plan.start_time, plan.end_time)
    b = np.clip(t0 + span, plan.start_time, plan.end_time)
    a, b = a[b > a], b[b > a]
    if not len(a):
        return []
    reach = np.maximum.accumulate(b)
    first = np.concatenate([[True], a[1:] > reach[:-1]])         # starts after all before it end
    last = np.append(np.flatnonzero(first)[1:] - 1, len(a) - 1)
    return [Window(float(x), float(y), "seam", 0.0) for x, y in zip(a[first], reach[last])]


def seam_metrics(config: TuneConfig, printer=None, job=None, *, backend: str = "lti",
                 job_accel: str | None = None) -> Metrics:
    """The job's metrics on every seam of a visible class (:func:`seam_windows`), each simulated
    as a quality window is (its history :func:`ringtune.envs.windows.auto_settle`, samples at
    2 kHz): where settings per feature land on what is seen (the hop's deceleration rings into the
    wall's first millimetres; a shaper spreads the next move back over its last ones), every seam,
    where the quality windows hold a few."""
    printer = resolve_printer(printer)
    pj = planned_job(printer, job, config, job_accel=job_accel)
    return _simulated(printer, pj, seam_windows(pj.plan), config, auto_settle(printer), backend)
