"""The baselines ``ringtune tune`` compares against, evaluated exactly like every trial.

- ``klipper`` — Klipper's rule. When the printer description records Klipper's recommendation from
  the user's own resonance files (``[measurement.klipper]``, written by ``ringtune identify``:
  ``shaper_x``, ``freq_x``, ``shaper_y``, ``freq_y``, ``max_accel``), it is that recommendation;
  otherwise the rule (:mod:`ringtune.agents.klipper.baseline`) on the model's simulated resonance
  test, and its label says so. Where the motors cannot follow it at its max_accel (step loss, or
  over the reserve) or its corners past the path-error bound, it is judged at the highest
  acceleration found within the bounds (:func:`lowered_pick`), and its label and a note say so.
- ``current`` — what the printer runs now (``[current]``: shaper, frequency and damping per axis and
  the acceleration, from its firmware configuration), when known.
- ``none`` — no shaping at the printer's own acceleration.

Each is judged by every visible measure (ripple, corners, extrusion) and the bounds, like every
trial; the default choice is held to the best of them (:func:`ringtune.agents.tune.choice.reference_baselines`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Callable

from ringtune.agents.klipper import baseline as klipper_baseline
from ringtune.agents.klipper.rule import DEFAULT_DAMPING_RATIO
from ringtune.agents.tune import study as tune_study
from ringtune.agents.tune.pareto import Point, max_motor_load, point_from_metrics
from ringtune.agents.tune.space import printer_axis_caps
from ringtune.envs.printer_model import Printer
from ringtune.hardware.firmware_check import check_available
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.firmware import FIRMWARES
from ringtune.shaping.shapers import parse_name, shapers_from_config

SIMULATED = "on a simulated resonance test of the model"
#: whose files [measurement.klipper] came from, unless [measurement] says (``origin``, e.g. an embedded printer's)
FROM_FILES = "your resonance files"


@dataclass
class Baselines:
    """Evaluated baselines (``points``), how each is named (``labels``), where each comes from
    (``sources``: "measurement" | "simulated resonance test" | "[current]" | "no shaping") and
    Klipper's per-axis fits when the rule ran here (for the warm start)."""

    points: dict[str, Point] = field(default_factory=dict)
    configs: dict[str, TuneConfig] = field(default_factory=dict)
    labels: dict[str, str] = field(default_factory=dict)
    sources: dict[str, str] = field(default_factory=dict)
    fits: dict = field(default_factory=dict)
    #: sentences for the summary on how a baseline was taken (Klipper's pick lowered into the bounds)
    notes: list[str] = field(default_factory=list)

    def add(self, key: str, config: TuneConfig, label: str, source: str) -> None:
        """One baseline's configuration, name and source (not evaluated)."""
        self.configs[key] = config
        self.labels[key] = label
        self.sources[key] = source


def recorded_klipper(printer: Printer, firmware: str) -> tuple[TuneConfig | None, str]:
    """Klipper's recommendation recorded from the resonance files, as a TuneConfig (or None, and
    why not)."""
    rec = printer.measurement.get("klipper")
    if not isinstance(rec, dict) or not rec:
        return None, "the printer description records no Klipper recommendation ([measurement.klipper])"
    try:
        fields = {"firmware": firmware}
        for ax in ("x", "y"):
            name = str(rec.get(f"shaper_{ax}") or "none").lower()
            fields[f"shaper_{ax}"] = name
            fields[f"freq_{ax}"] = round(float(rec.get(f"freq_{ax}") or 0.0), 1) if name != "none" else 0.0
            fields[f"damping_{ax}"] = DEFAULT_DAMPING_RATIO
        cfg = _checked(fields, rec.get("max_accel"), printer, "[measurement.klipper]",
                       "Klipper's calibrate_shaper rule on the resonance files (recorded by ringtune identify)")
        shapers_from_config(cfg)          # Klipper's shapers may not be the firmware's (Marlin: zv only)
        _runs_on(cfg, firmware, "[measurement.klipper]", "the files' picks differ per axis")
    except (TypeError, ValueError, RingtuneError) as exc:
        return None, f"[measurement.klipper] cannot be used for {firmware}: {exc}"
    return cfg, ""


def _checked(fields: dict[str, Any], accel: Any, printer: Printer, where: str, source: str) -> TuneConfig:
    """The TuneConfig of a recorded baseline's ``fields`` at ``accel`` mm/s² (none: the printer's own),
    validated as ``where`` says, its ``source`` in ``extra``."""
    cfg = TuneConfig(**fields, accel=float(accel) if accel else float(printer.limits.accel), extra={"source": source})
    cfg.validate(where)
    return cfg


def _model_fits(printer: Printer, firmware: str) -> dict:
    """Klipper's per-axis fits on the model's simulated resonance test ({} when it cannot run)."""
    try:
        return klipper_baseline.klipper_rule_on_simulated_test(printer, firmware, "head")[0]
    except (ImportError, RingtuneError):
        return {}


def _runs_on(cfg: TuneConfig, firmware: str, where: str, differ: str) -> None:
    """Refuse a recorded configuration (``where``) ``firmware`` cannot run: a shaper it lacks, or two
    axes' shapers on a firmware with one shaper for all axes (``differ`` says how they differ; for
    Klipper's pick, its rule is then aimed at that one shaper instead)."""
    for ax in ("x", "y"):
        check_available(cfg.axis(ax)[0], firmware, f"shaper_{ax}")
    if FIRMWARES[firmware].one_shaper and cfg.axis("x")[:2] != cfg.axis("y")[:2]:
        raise RingtuneError(f"{firmware} runs one shaper for all axes, {differ}", where)


def current_config(printer: Printer, firmware: str) -> tuple[TuneConfig | None, str]:
    """What the printer runs now (``[current]``) as a TuneConfig for ``firmware`` (or None, and why)."""
    cur = printer.current
    if not cur:
        return None, ""
    try:
        fields: dict[str, Any] = {"firmware": firmware}
        for ax in ("x", "y"):
            raw = cur.get(f"shaper_{ax}", cur.get("shaper"))
            freq = cur.get(f"freq_{ax}", cur.get("freq"))
            name = parse_name(str(raw))[0] if raw and freq else "none"
            fields[f"shaper_{ax}"] = name
            fields[f"freq_{ax}"] = float(freq) if name != "none" else 0.0
            z = cur.get(f"damping_{ax}", cur.get("damping"))
            fields[f"damping_{ax}"] = float(z) if z is not None else DEFAULT_DAMPING_RATIO
        cfg = _checked(fields, cur.get("accel"), printer, "[current]",
                       f"what the printer runs now ({cur.get('source') or '[current]'})")
        # a printer described from another firmware's config (Klipper's ei, per axis) may run
        # shapers this one lacks: nothing to compare with on it
        _runs_on(cfg, firmware, "[current]", "the printer runs a different shaper per axis now")
    except (TypeError, ValueError, RingtuneError) as exc:
        return None, f"what the printer runs now ([current]) cannot be compared on {firmware}: {exc}"
    return cfg, ""


def baseline_configs(printer: Printer, firmware: str, *, note: Callable[[str], None] = lambda s: None) -> Baselines:
    """Klipper's rule, what the printer runs now (when known) and no shaping as configurations, with
    their labels and sources (not evaluated: ``points`` is empty). Klipper's rule on a simulated test
    uses the model's expected spectrum: it does not depend on any seed."""
    out = Baselines()
    _klipper_baseline(printer, firmware, out, note)
    if "klipper" in out.configs:
        out.configs["klipper"] = with_raised_caps(out.configs["klipper"], printer, firmware)
    ccfg, why = current_config(printer, firmware)
    if ccfg is not None:
        src = printer.current.get("source")
        out.add("current", ccfg, "what the printer runs now" + (f" ({src})" if src else ""), "[current]")
    elif why:
        note(f"ringtune tune: {why}")
    out.add("none", TuneConfig(firmware=firmware, shaper_x="none", shaper_y="none", freq_x=0.0, freq_y=0.0,
                               accel=float(printer.limits.accel), extra={"source": "no shaping"}),
            "no shaping", "no shaping")
    return out


def with_raised_caps(cfg: TuneConfig, printer: Printer, firmware: str) -> TuneConfig:
    """``cfg`` as ``firmware`` runs its acceleration: where the firmware sets its X/Y caps by G-code
    (``M201 X Y``: Marlin, Prusa, RepRapFirmware), raised to it, as every trial's are and as
    ``export`` sends them — Klipper's max_accel behind a stored 500 mm/s² cap would be judged at
    500; elsewhere as it is."""
    caps, raise_caps = printer_axis_caps(printer, firmware)
    if not caps or not raise_caps or cfg.accel is None:
        return cfg
    raised = {f"max_accel_{ax}": max(c, float(cfg.accel)) for ax, c in zip("xy", caps) if c > 0}
    return dataclasses.replace(cfg, **raised)


def _klipper_baseline(printer: Printer, firmware: str, out: Baselines, note: Callable[[str], None]) -> None:
    """Klipper's rule into ``out``: its recommendation recorded from the resonance files, else the
    rule on the model's simulated resonance test (``note`` says why a recorded one is not used, or
    that the rule could not run)."""
    kcfg, why = recorded_klipper(printer, firmware)
    if kcfg is not None:
        rec = printer.measurement.get("klipper", {})
        version = f" (Klipper {rec['version']})" if rec.get("version") else ""
        out.add("klipper", kcfg, f"Klipper's rule from {printer.measurement.get('origin') or FROM_FILES}{version}",
                "measurement")
        out.fits = _model_fits(printer, firmware)      # the model's own frequencies, for the warm start
        return
    try:
        out.fits, fields = klipper_baseline.klipper_rule_on_simulated_test(printer, firmware, "head")
        if fields.get("accel") is None:
            fields["accel"] = float(printer.limits.accel)
        source = "Klipper's calibrate_shaper rule (HEAD) " + SIMULATED
        out.add("klipper", TuneConfig(**fields, extra={"source": source}), f"Klipper's rule {SIMULATED}",
                "simulated resonance test")
        if printer.measurement.get("klipper"):
            note(f"ringtune tune: {why}; Klipper's rule is computed {SIMULATED} instead")
    except (ImportError, RingtuneError) as exc:
        note(f"ringtune tune: Klipper's-rule baseline skipped: {exc}")


def baselines_for(printer: Printer, firmware: str, settings, evaluator: Callable, quality: str, *,
                  note: Callable[[str], None] = lambda s: None, configs: Baselines | None = None) -> Baselines:
    """:func:`baseline_configs` (or ``configs``, what it gave already) evaluated with the study's
    evaluator, bounds and frequency margin (``settings``: a StudySettings)."""
    out = configs if configs is not None else baseline_configs(printer, firmware, note=note)

    def judged(cfgs: dict[str, TuneConfig]) -> dict[str, Point]:
        metrics = evaluator(list(cfgs.values()), printer, settings.job, **tune_study.evaluator_kwargs(settings))
        return {key: point_from_metrics(cfg, m, quality, label=key, max_path_error_mm=settings.max_path_error_mm,
                                        max_motor_load=max_motor_load(settings.motor_reserve),
                                        max_show_through_mm=getattr(settings, "max_show_through_mm", 0.0))
                for (key, cfg), m in zip(cfgs.items(), metrics)}

    out.points = judged(out.configs)
    _within_bounds(out, judged, bound_limits(max_motor_load(settings.motor_reserve), settings.max_path_error_mm),
                   note)
    return out


#: evaluations spent at most lowering Klipper's pick into the bounds
LOWER_TRIES = 6
#: mm/s²: the grid its acceleration is lowered on (the study's step)
LOWER_STEP = 100.0
#: the bounds that fall with the acceleration, as (metrics key, words for its figure)
LOWERED_BOUNDS = (("motor_load", "motor load"), ("path_error_mm", "path error"))


def bound_limits(max_load: float, max_path_error_mm: float) -> dict[str, float]:
    """{metrics key: bound} of :data:`LOWERED_BOUNDS` (0 = none); the motors' own edge (load 1) where
    no reserve is kept."""
    return {"motor_load": max_load or 1.0, "path_error_mm": max_path_error_mm}


def bound_ratio(values, step_loss: bool, limits: dict[str, float]) -> float:
    """The largest figure over its bound of ``limits`` (``values``: metrics key -> figure); above 1
    where one is broken or the motors lose steps."""
    r = max((float(values.get(k) or 0.0) / b for k, b in limits.items() if b > 0), default=0.0)
    return max(r, 1.0 + 1e-6) if step_loss else r


def accel_within_bounds(accel: float, ratio: float, judge_at: Callable[[float], tuple[float, bool]]) -> float | None:
    """The highest acceleration found (mm/s², on :data:`LOWER_STEP`, below ``accel``, where a
    configuration's :func:`bound_ratio` is ``ratio`` > 1) at which ``judge_at(a)`` — (its ratio there,
    whether it keeps every bound) — says it does; None where no try gets there (a job whose own
    accelerations rule). The first try scales ``accel`` by 1 / ``ratio`` (force and smoothing grow
    with the acceleration); the next ones solve the line through the last two tries (a part that
    does not grow), kept between the highest try within the bounds and the lowest over them (else
    halfway); at most :data:`LOWER_TRIES` evaluations."""
    tried, lo, hi = [(float(accel), float(ratio))], None, float(accel)
    for _ in range(LOWER_TRIES):
        (a1, r1), (a0, r0) = tried[-1], tried[-2] if len(tried) > 1 else (0.0, 0.0)
        slope = (r1 - r0) / (a1 - a0)           # ratio per mm/s²
        aim = a1 + (1.0 - r1) / slope if slope > 0 else 0.95 * a1
        if lo is not None:                      # bracketed: inside (lo, hi), else halfway
            aim = aim if lo < aim < hi else (lo + hi) / 2
        a = min(aim, hi - LOWER_STEP) // LOWER_STEP * LOWER_STEP
        if a < LOWER_STEP or (lo is not None and a <= lo):
            break
        r, ok = judge_at(float(a))
        tried.append((a, r))
        lo, hi = (float(a), hi) if ok else (lo, float(a))
    return lo


def lowered_words(accel: float, before: tuple, lowered: float, after, limits: dict[str, float]) -> str:
    """The sentence saying Klipper's pick is judged at ``lowered`` mm/s², not its max_accel ``accel``;
    ``before``: (its figures there, whether it lost steps); ``after``: the figures at ``lowered``."""
    values, lost = before
    broke = ["loses steps"] if lost else []
    broke += [f"has {name} {_fig(key, values)} ({_fig(key, limits)} allowed)" for key, name in LOWERED_BOUNDS
              if limits.get(key, 0) > 0 and float(values.get(key) or 0.0) > limits[key]]
    kept = ", ".join(f"{name} {_fig(key, after)}" for key, name in LOWERED_BOUNDS if limits.get(key, 0) > 0)
    return (f"Klipper's rule's max_accel {accel:.0f} mm/s² is a ceiling set by smoothing alone; there its pick "
            f"{' and '.join(broke)}, so it is judged at {lowered:.0f} mm/s², the highest found within the bounds "
            f"({kept})")


def _fig(key: str, values) -> str:
    v = float(values.get(key) or 0.0)
    return f"{v:.0%}" if key == "motor_load" else f"{v * 1000:.1f} µm"


def lowered_label(label: str, accel: float) -> str:
    """Klipper's pick's ``label`` where it is judged below its max_accel, at ``accel`` mm/s²."""
    return f"{label} at {accel:.0f} mm/s² (within the bounds)"


def lowered_pick(accel: float, before: tuple[dict, bool], judge_at: Callable[[float], tuple[dict, bool, bool]],
                 limits: dict[str, float]) -> tuple[float, str] | None:
    """Klipper's pick at its max_accel ``accel`` with ``before`` (its figures there, whether it lost
    steps): where that breaks a bound of ``limits``, (the acceleration :func:`accel_within_bounds`
    finds, the sentence saying so); None where it keeps them or no acceleration gets it within
    them. ``judge_at(a)``: (the figures at ``a``, whether it lost steps, whether it keeps every
    bound)."""
    ratio = bound_ratio(*before, limits)
    if ratio <= 1.0 or not accel:
        return None
    seen: dict[float, tuple] = {}

    def at(a: float) -> tuple[float, bool]:
        seen[a] = judge_at(a)
        return bound_ratio(seen[a][0], seen[a][1], limits), seen[a][2]

    lowered = accel_within_bounds(accel, ratio, at)
    if lowered is None:
        return None
    return lowered, lowered_words(accel, before, lowered, seen[lowered][0], limits)


def _within_bounds(out: Baselines, judged: Callable[[dict], dict], limits: dict[str, float],
                   note: Callable[[str], None]) -> None:
    """Where Klipper's pick at its max_accel loses steps, asks the motors for more than the reserve
    allows or rounds corners past the path-error bound, the pick at :func:`lowered_pick` in its
    place: the rule sets max_accel by its own smoothing target alone, a ceiling ("max_accel <= …"),
    and a pick over a bound is nothing the choice could be held to. Said in ``out.notes`` and by
    ``note``; where no acceleration gets within the bounds, the pick stays as it was."""
    first = out.points.get("klipper")
    if first is None:
        return
    points: dict[float, Point] = {}

    def judge_at(a: float) -> tuple[dict, bool, bool]:
        q = points[a] = judged({"klipper": dataclasses.replace(first.config, accel=a)})["klipper"]
        return q.metrics, q.step_loss, q.feasible

    found = lowered_pick(first.config.accel, (first.metrics, first.step_loss), judge_at, limits)
    if found is None:
        return
    lowered, words = found
    out.configs["klipper"], out.points["klipper"] = points[lowered].config, points[lowered]
    out.labels["klipper"] = lowered_label(out.labels["klipper"], lowered)
    out.notes.append(words + ".")
    note(f"ringtune tune: {words}")


def warm_start(kcfg: TuneConfig, fits: dict, space) -> list[TuneConfig]:
    """Klipper's pick at its max_accel and 1.1×, 1.25×, 1.5× it (and at 0.6× the range's top when its
    max_accel is above that: the motors would need more than 60 % of their force, resonance not counted);
    the rule's pick on the model's simulated test (``fits``; it differs from a pick recorded from the
    files) at that max_accel and 1.25× it; the robust EI family at the rule's per-shaper frequencies on
    the model, at its max_accel, 1.25× it and the top of the range (only points inside the space; one
    acceleration when it is not searched)."""
    def at(cfg, factor):
        a = min(space.accel[1], max(space.accel[0], round(kcfg.accel * factor / space.accel_step)
                                    * space.accel_step))
        return dataclasses.replace(cfg, accel=float(space.accel[0] if space.accel_fixed else a), extra={})

    out = [at(kcfg, 1.0), at(kcfg, 1.1), at(kcfg, 1.25), at(kcfg, 1.5)]
    if kcfg.accel and kcfg.accel > 0.6 * space.accel[1]:   # a weak motor: also where its force keeps a reserve
        out.append(at(kcfg, 0.6 * space.accel[1] / kcfg.accel))
    model = _model_pick(kcfg, fits)
    if model is not None:
        out += [at(model, 1.0), at(model, 1.25)]
    for cfg in _ei_family(kcfg, fits, space):
        out += [at(cfg, 1.0), at(cfg, 1.25), at(cfg, space.accel[1] / kcfg.accel)]
    # once each (points with the same shapers, frequencies and acceleration are the same configuration)
    return list({(c.shaper_x, c.freq_x, c.shaper_y, c.freq_y, c.accel): c for c in out if inside(c, space)}.values())


def _model_pick(kcfg: TuneConfig, fits: dict) -> TuneConfig | None:
    """Klipper's pick on the model's simulated test (``fits`` by axis), or None without both axes."""
    if not fits or not all(ax in fits for ax in ("x", "y")):
        return None
    picks = {f"{k}_{ax}": v for ax in ("x", "y")
             for k, v in (("shaper", fits[ax].best.name), ("freq", round(fits[ax].best.freq, 1)))}
    return dataclasses.replace(kcfg, **picks, extra={})


def _ei_family(kcfg: TuneConfig, fits: dict, space) -> list[TuneConfig]:
    """EI, 2-hump and 3-hump EI at the rule's own per-shaper frequencies, where it ran on both axes."""
    def row(ax, name):
        rec = fits.get(ax) if fits else None
        return next((f for f in rec.shapers if f.name == name), None) if rec else None

    out = []
    for name in ("ei", "2hump_ei", "3hump_ei"):
        rows = {ax: row(ax, name) for ax in ("x", "y")}
        if rows["x"] is None or rows["y"] is None or name not in space.shapers:
            continue
        fx, fy = round(rows["x"].freq, 1), round(rows["y"].freq, 1)
        out.append(dataclasses.replace(kcfg, shaper_x=name, shaper_y=name, freq_x=fx,
                                       freq_y=fy if space.per_axis else fx, extra={}))
    return out


def inside(cfg: TuneConfig, space) -> bool:
    ok = space.accel[0] <= (cfg.accel or 0) <= space.accel[1]
    for ax in ("x", "y"):
        name, f, _ = cfg.axis(ax)
        lo, hi = getattr(space, f"freq_{ax}")
        ok &= name == "none" or (name in space.shapers and lo <= f <= hi)
    return bool(ok) and (space.per_axis or cfg.shaper_x == cfg.shaper_y)
