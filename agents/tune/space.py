"""The tuning search space: what ``tune`` (Optuna), ``grid`` and the reports vary, per firmware.

Parameters (Optuna names):

- ``shaper`` (RepRapFirmware: one shaper for all axes) or ``shaper_x``, ``shaper_y``: the shaper
  types the target firmware offers (``none`` included; RRF ``custom`` excluded) and, where its
  shapers take Klipper's parameters (flavour ``klipper``: Klipper HEAD), the families
  (:mod:`ringtune.agents.tune.shaper_families`) ``mzv(n,t)`` — ``mzv_n_<ax>`` impulses (3–6) over
  ``mzv_t_<ax>`` damped periods (0.5 to just under (n − 1)/2, where Klipper's generalised MZV
  stays non-negative; sampled as a fraction of that span) — and ``ei(v_tol)`` — ``ei_vtol_<ax>``
  the tolerated vibration (0.01–0.2; plain EI is 0.05);
- ``freq`` (RRF) or ``freq_x``, ``freq_y``: shaper frequency F, Hz, around the printer's modes;
- ``damping_x``, ``damping_y`` (or ``damping`` on RepRapFirmware, one shaper for all axes): shaper
  damping ratio S per axis, as Klipper, Marlin and Prusa take it (``damping_ratio_x``, ``M593 X
  D``), within every offered shaper's limit (a stored trial's single ``damping`` is both);
- ``freq_limit``: ``off`` or a frequency-limit method (``nophead``, ``sections``, ``marlin``), and
  ``freq_limit_hz`` (Hz, only when on);
- ``accel``: printing acceleration, mm/s², in steps of ``accel_step``; every trial's configuration
  carries the per-axis caps it runs with (:func:`trial_axis_caps`): the printer's X/Y caps, raised
  to the trial's acceleration where the firmware sets them by G-code (Marlin, RepRapFirmware,
  Prusa: ``M201 X Y``, which ``export`` then sends before ``M204``), kept as they are where they
  are the owner's per-axis limits in the firmware's configuration (Kalico's limited_* kinematics:
  ``max_x_accel``/``max_y_accel``; and on mainline Klipper, which has none, said by ``export``).
- per feature (a space from :func:`ringtune.agents.tune.feature_space.feature_space`):
  ``accel_<group>`` for each group of :data:`~ringtune.agents.tune.feature_groups.ACCEL_GROUPS` but ``visible`` (whose acceleration is
  ``accel``), mm/s²; ``corner`` (the printer's junction rule's value) and ``min_cruise_ratio``
  (Klipper); ``corner_<group>`` and ``min_cruise_ratio_<group>`` (the same for each group of
  :data:`~ringtune.agents.tune.feature_groups.CORNER_GROUPS` the job has: ``hidden``, ``solid``). All *walked*: the study samples what a single-acceleration study
  samples and leaves them where a point without them has them (each group at the visible walls'
  acceleration, within its range; the corners as the printer has them), so that it finds what the
  single-acceleration study finds; :mod:`ringtune.agents.tune.hidden_raise` raises them from its
  choice, one at a time, as far as the judgement allows (a study sampling a dozen more dimensions
  found slower choices in the same trials: issue 22's note). They become the config's
  ``feature_accel``, ``corner``, ``min_cruise_ratio``, ``feature_corner`` and
  ``feature_min_cruise_ratio``.

:func:`config_from_params` turns a parameter dict into a :class:`TuneConfig`; the same function
serves Optuna trials, grid points and stored trials, so they can never disagree.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any, Callable, Sequence


from ringtune.agents.tune.feature_groups import ACCEL_GROUPS, CORNER_GROUPS, corner_groups
from ringtune.agents.tune.motor_bound import accel_ceiling
from ringtune.agents.tune.shaper_families import PARAMETRISED, family_params, shaper_name, suggest_family
from ringtune.shaping.config import FREQ_LIMIT_METHODS, TuneConfig
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.firmware import FIRMWARES
from ringtune.shaping.shapers import available_shapers, max_damping
from ringtune.shaping.smoothers import takes_damping

#: rounding of the corner rule's value per junction rule (mm/s, mm, mm/s) and of minimum_cruise_ratio
CORNER_STEP = {"scv": 0.5, "jd": 0.001, "jerk": 0.5}
#: the unit of the corner rule's value per junction rule
CORNER_UNIT = {"scv": "mm/s", "jd": "mm", "jerk": "mm/s"}
MCR_STEP = 0.05

@dataclass(frozen=True)
class SearchSpace:
    """Ranges of one study (units: Hz, mm/s²)."""

    firmware: str
    shapers: tuple[str, ...]
    per_axis: bool
    freq_x: tuple[float, float]
    freq_y: tuple[float, float]
    damping: tuple[float, float]
    freq_limit_methods: tuple[str, ...]
    freq_limit_hz: tuple[float, float]
    accel: tuple[float, float]
    accel_step: float = 100.0
    freq_step: float = 0.1
    min_speed_factor: float = 0.3
    accel_basis: str = ""               # what sets the acceleration range's top (for the summary)
    axis_caps: tuple[float, float] | None = None   # the printer's X/Y caps, mm/s² (0 = none)
    raise_axis_caps: bool = False       # the firmware sets them by G-code: raised to the trial's acceleration
    feature_accel: tuple = ()           # ((group, lo, hi), ...) searched apart from ``accel``, mm/s²
    corner: tuple[float, float] | None = None        # the corner rule's range, in ``junction``'s unit
    junction: str = ""                  # the printer's junction rule (scv, jd, jerk) the corner is in
    min_cruise_ratio: tuple[float, float] | None = None   # Klipper's, searched when set
    hidden_corner: tuple[float, float] | None = None      # the corner rule of the corner groups, searched when set
    hidden_min_cruise_ratio: tuple[float, float] | None = None   # their minimum_cruise_ratio (Klipper)
    feature_basis: dict | None = None   # per group: its top speed (mm/s) and what caps its range
    corner_now: float | None = None     # the printer's own corner value (a config without one runs it)
    mcr_now: float | None = None        # the printer's own minimum_cruise_ratio

    @property
    def accel_fixed(self) -> bool:
        """The acceleration is not searched (one value: it has no effect, or the user fixed it)."""
        return self.accel[0] == self.accel[1]

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "SearchSpace":
        kw = dict(d)
        for k in ("shapers", "freq_limit_methods"):
            kw[k] = tuple(kw[k])
        for k in ("freq_x", "freq_y", "damping", "freq_limit_hz", "accel", "axis_caps", "corner",
                  "min_cruise_ratio", "hidden_corner", "hidden_min_cruise_ratio"):
            if kw.get(k) is not None:
                kw[k] = tuple(float(v) for v in kw[k])
        kw["feature_accel"] = tuple((str(g), float(lo), float(hi)) for g, lo, hi in kw.get("feature_accel") or ())
        return cls(**kw)

    @property
    def per_feature(self) -> bool:
        """Whether accelerations per feature group, the corner rule or minimum_cruise_ratio are searched."""
        return bool(_per_feature(self))


def default_space(printer: Any, firmware: str = "klipper", *, accel: tuple[float, float] | None = None,
                  shapers: tuple[str, ...] | None = None, speed: float | None = None,
                  min_freq: float | None = None) -> SearchSpace:
    """The default space for ``printer`` on ``firmware``.

    F spans 0.6×–1.8× the axis's lowest/highest mode (clipped to 10–200 Hz and from below to the
    firmware's lowest frequency — its record's range, and a stock build's minimum where the build
    sets one, Marlin's SHAPING_MIN_FREQ, unless ``min_freq`` says the user's build differs; the
    top at least 1.5× that floor); S 0–0.2 (capped
    by the offered shapers' limits); frequency limit 10–80 Hz with every method; acceleration
    from 0.3× the printer's own limit up to :func:`accel_ceiling` at the job's top speed
    ``speed`` (mm/s; default the printer's velocity limit): where the weakest motor would need all
    its force (the firmware's limits are no bound: see there). ``accel`` = (lo, hi) overrides it
    (lo = hi: the acceleration is not searched).
    """
    if firmware not in FIRMWARES:
        raise RingtuneError(f"firmware must be one of {', '.join(FIRMWARES)}, not {firmware!r}", "firmware")
    fw = FIRMWARES[firmware]
    offered = _offered_shapers(firmware, shapers)
    zmax = min([0.2] + [max_damping(n.split("(")[0], fw.flavor) for n in offered if n != "none"])
    floor = freq_floor(firmware, min_freq)
    fx, fy = (_freq_range(printer, ax, floor) for ax in "xy")
    if fw.one_shaper:
        fx = fy = (min(fx[0], fy[0]), max(fx[1], fy[1]))
    acc, basis = (accel, "--accel-range") if accel is not None else _accel_range(printer, speed)
    if not (0 < acc[0] <= acc[1]):
        raise RingtuneError(f"acceleration range must be 0 < lo ≤ hi, not {acc}", "accel")
    caps, raise_caps = printer_axis_caps(printer, firmware)
    return SearchSpace(firmware=firmware, shapers=offered, per_axis=not fw.one_shaper, freq_x=fx,
                       freq_y=fy, damping=(0.0, float(zmax)), freq_limit_methods=FREQ_LIMIT_METHODS,
                       freq_limit_hz=(10.0, 80.0), accel=(float(acc[0]), float(acc[1])), accel_basis=basis,
                       axis_caps=caps, raise_axis_caps=raise_caps)


def _offered_shapers(firmware: str, shapers: tuple[str, ...] | None) -> tuple[str, ...]:
    """The shapers searched: ``shapers`` (each one the firmware offers) or all it offers but
    ``custom``, with Klipper's parametrised families where its flavour has them."""
    flavor = FIRMWARES[firmware].flavor
    offered = tuple(n for n in available_shapers(flavor) if n != "custom") + PARAMETRISED.get(flavor, ())
    return tuple(checked_shapers(firmware, shapers or offered, offered))


def checked_shapers(firmware: str, chosen: Sequence[str], offered: Sequence[str]) -> Sequence[str]:
    """``chosen``, refused unless ``firmware`` offers each of them (``offered``)."""
    bad = [s for s in chosen if s not in offered]
    if bad:
        raise RingtuneError(f"{firmware} does not offer {', '.join(bad)} (offers {', '.join(offered)})", "shapers")
    return chosen


def _freq_range(printer: Any, ax: str, floor: float) -> tuple[float, float]:
    """(lo, hi) Hz of axis ``ax``: 0.6×–1.8× its lowest/highest mode (40 Hz without modes), within
    10–200 Hz, from ``floor`` up, the top at least 1.5× the bottom."""
    freqs = [m.freq for m in getattr(printer, ax).modes] or [40.0]
    lo = max(10.0, floor, round(0.6 * min(freqs), 1))
    return lo, max(min(200.0, round(1.8 * max(freqs), 1)), round(1.5 * lo, 1))


def _accel_range(printer: Any, speed: float | None) -> tuple[tuple[float, float], str]:
    """((lo, hi) mm/s², what sets the top): up to :func:`accel_ceiling` at ``speed`` (to 100 below),
    from 0.3× the printer's own acceleration but at most a third of the top (each at least 100)."""
    top, basis = accel_ceiling(printer, speed)
    hi = max(100.0, math.floor(top / 100.0) * 100.0)
    lo = min(max(100.0, round(0.3 * float(printer.limits.accel), -2)), max(100.0, round(hi / 3.0, -2)))
    return (lo, hi), basis


def freq_floor(firmware: str, min_freq: float | None = None) -> float:
    """The lowest shaper frequency (Hz) the search offers on ``firmware``: the lower end of its
    record's range, and its stock build's minimum (``build_min_freq``) unless ``min_freq`` (the
    user's build) replaces it."""
    fw = FIRMWARES[firmware]
    build = fw.build_min_freq if min_freq is None else float(min_freq)
    return max(fw.freq.lo, build)


def freq_floor_note(firmware: str, min_freq: float | None, space: "SearchSpace") -> str:
    """Where the firmware's build minimum binds the search, said; "" where it does not."""
    fw = FIRMWARES[firmware]
    if not fw.build_min_freq:
        return ""
    floor = freq_floor(firmware, min_freq)
    where = ("your build's SHAPING_MIN_FREQ (--shaping-min-freq)" if min_freq is not None else
             f"{fw.build_min_freq_why}; --shaping-min-freq HZ if your build differs")
    return f"shaper frequencies searched from {floor:g} Hz: {where}"


def unshaped_modes_note(printer: Any, space: "SearchSpace") -> str:
    """Where the printer has a resonance more than 5 % below the lowest shaper frequency the search
    offers on an axis (a firmware's build minimum; within 5 % a ZV there still cancels most of it):
    those modes ring unshaped, said; "" where none does."""
    low = _below_floor(printer, space)
    if not low:
        return ""
    floor = min(space.freq_x[0], space.freq_y[0])
    return (f"the printer resonates at {', '.join(low)}, below the {floor:g} Hz the search shapes from (the "
            "firmware's lowest shaper frequency; --shaping-min-freq if your build shapes lower): no shaper "
            "cancels that ringing")


def _below_floor(printer: Any, space: "SearchSpace") -> list[str]:
    """``"<f> Hz on <axis>"`` of each mode more than 5 % below its axis's lowest searched frequency."""
    return [f"{m.freq:.1f} Hz on {ax.upper()}" for ax, rng in (("x", space.freq_x), ("y", space.freq_y))
            for m in getattr(printer, ax).modes if m.freq < 0.95 * rng[0]]


def printer_axis_caps(printer: Any, firmware: str) -> tuple[tuple[float, float] | None, bool]:
    """(the printer's X/Y acceleration caps or None, whether trials raise them to their acceleration):
    raised where ``firmware`` sets them by G-code (``M201``), kept where they live in its
    configuration (Kalico) or where it has none (module docstring)."""
    caps = tuple(float(c) for c in tuple(printer.limits.max_accel or (0.0, 0.0))[:2])
    if not any(c > 0 for c in caps):
        return None, False
    fw = FIRMWARES[firmware]
    return caps, bool(fw.axis_accel_set) and not fw.axis_accel_config


def trial_axis_caps(space: SearchSpace, accel: float) -> dict[str, float]:
    """``max_accel_x``/``max_accel_y`` of a trial at ``accel`` mm/s² (empty when the printer has no
    X/Y caps): the printer's, raised to ``accel`` where ``space.raise_axis_caps``."""
    if not space.axis_caps:
        return {}
    out = {}
    for ax, cap in zip("xy", space.axis_caps):
        if cap > 0:
            out[f"max_accel_{ax}"] = max(cap, float(accel)) if space.raise_axis_caps else cap
    return out


def shaping_axes(space: SearchSpace) -> tuple[tuple[str, str], ...]:
    """(axis, suffix of its shaping parameters) per axis searched apart: ``x``, ``y`` with ``_x``,
    ``_y``; where one shaper serves all axes (RepRapFirmware) ``x`` alone with "" (``shaper``,
    ``freq``, ``damping``), which Y runs too."""
    return (("x", "_x"), ("y", "_y")) if space.per_axis else (("x", ""),)


@dataclass(frozen=True)
class _Ranged:
    """A per-feature parameter searched on [lo, hi] (in its config key's unit): the config's
    rounding ``step``, the value of a point without it (``missing``), the value a configuration
    runs (``now``; None: unset) and, for a per-class value, the feature classes it sets in the
    config's table ``into`` (``feature_accel``, ``feature_corner``, ``feature_min_cruise_ratio``)."""

    key: str
    lo: float
    hi: float
    step: float
    missing: float
    now: Callable[[TuneConfig], float | None]
    classes: tuple[str, ...] = ()
    into: str = ""


def _per_feature(space: SearchSpace) -> list[_Ranged]:
    """The per-feature parameters of ``space`` (all walked, none sampled by the study): each group's
    acceleration (a point without it: the visible walls' acceleration within the group's range,
    :func:`_missing`), the job's corner rule and minimum_cruise_ratio and those of the corners nobody
    sees (a point without them: the printer's own, within the range)."""
    rows = [_Ranged(f"accel_{g}", lo, hi, space.accel_step, lo,
                    lambda c, cls=ACCEL_GROUPS[g][0]: c.feature_accel.get(cls, c.accel), ACCEL_GROUPS[g], "feature_accel")
            for g, lo, hi in space.feature_accel]
    if space.corner is not None:
        rows.append(_Ranged("corner", *space.corner, CORNER_STEP.get(space.junction, 0.001),
                            _clip(space.corner_now, space.corner),
                            lambda c: c.corner if c.corner is not None else space.corner_now))
    if space.min_cruise_ratio is not None:
        rows.append(_Ranged("min_cruise_ratio", *space.min_cruise_ratio, MCR_STEP,
                            _clip(space.mcr_now, space.min_cruise_ratio),
                            lambda c: c.min_cruise_ratio if c.min_cruise_ratio is not None else space.mcr_now))
    rows += _hidden_corner_rows(space)
    return rows


def _clip(value: float | None, lo_hi: tuple[float, float]) -> float:
    """``value`` within ``lo_hi`` (None: the range's bottom)."""
    return lo_hi[0] if value is None else min(max(float(value), lo_hi[0]), lo_hi[1])


def _hidden_corner_rows(space: SearchSpace) -> list[_Ranged]:
    """The corner rule and minimum_cruise_ratio of each group of
    :data:`~ringtune.agents.tune.feature_groups.CORNER_GROUPS` the job has
    (``corner_hidden``, ``corner_solid``, …), where searched (missing: the printer's own, within
    the range; a configuration without one runs the job-wide value)."""
    rows = []
    for name in corner_groups(space):
        classes, cls = CORNER_GROUPS[name], CORNER_GROUPS[name][0]
        if space.hidden_corner is not None and space.corner_now is not None:
            rows.append(_Ranged(f"corner_{name}", *space.hidden_corner, CORNER_STEP.get(space.junction, 0.001),
                                _clip(space.corner_now, space.hidden_corner),
                                lambda c, cls=cls: c.feature_corner.get(
                                    cls, c.corner if c.corner is not None else space.corner_now),
                                classes, "feature_corner"))
        if space.hidden_min_cruise_ratio is not None and space.mcr_now is not None:
            rows.append(_Ranged(f"min_cruise_ratio_{name}", *space.hidden_min_cruise_ratio, MCR_STEP,
                                _clip(space.mcr_now, space.hidden_min_cruise_ratio),
                                lambda c, cls=cls: c.feature_min_cruise_ratio.get(
                                    cls, c.min_cruise_ratio if c.min_cruise_ratio is not None else space.mcr_now),
                                classes, "feature_min_cruise_ratio"))
    return rows


def walked_keys(space: SearchSpace) -> list[str]:
    """The per-feature parameters the study leaves to the walk after it (module docstring)."""
    return [r.key for r in _per_feature(space)]


def suggest_params(trial: Any, space: SearchSpace) -> dict[str, Any]:
    """Ask an Optuna trial for one point of ``space`` (returns the parameter dict)."""
    axes = shaping_axes(space)
    p: dict[str, Any] = {f"shaper{s}": trial.suggest_categorical(f"shaper{s}", list(space.shapers)) for _, s in axes}
    for ax, s in axes:
        if p[f"shaper{s}"] != "none":
            p[f"freq{s}"] = trial.suggest_float(f"freq{s}", *getattr(space, f"freq_{ax}"))
        p.update(suggest_family(trial, p[f"shaper{s}"], ax))
    for key in damping_keys(p, space):
        p[key] = trial.suggest_float(key, *space.damping)
    p["freq_limit"] = trial.suggest_categorical("freq_limit", ["off", *space.freq_limit_methods])
    if p["freq_limit"] != "off":
        p["freq_limit_hz"] = trial.suggest_float("freq_limit_hz", *space.freq_limit_hz)
    # a fixed acceleration is not searched: it has no effect (or was fixed)
    p["accel"] = space.accel[0] if space.accel_fixed else trial.suggest_float("accel", *space.accel)
    return p        # the per-feature parameters are the walk's (:func:`walked_keys`)


def feature_params(params: dict[str, Any], space: SearchSpace) -> dict[str, Any]:
    """The per-feature keys of a TuneConfig (``feature_accel``, ``corner``, ``min_cruise_ratio``)
    from a parameter dict, rounded as :func:`config_from_params` rounds (empty without them)."""
    out: dict[str, Any] = {}
    for r in _per_feature(space):
        value = _q(params.get(r.key, _missing(r, params)), r.step)
        if r.classes:
            out.setdefault(r.into, {}).update(dict.fromkeys(r.classes, value))
        else:
            out[r.key] = value
    return out


def _missing(r: _Ranged, params: dict[str, Any]) -> float:
    """The value of a per-feature parameter a point lacks: a group's acceleration is the visible
    walls' (within the group's range: its motor's top at the group's own speed), else ``r.missing``."""
    if r.into == "feature_accel" and params.get("accel") is not None:
        return min(max(float(params["accel"]), r.lo), r.hi)
    return r.missing


def damping_keys(shaping: dict[str, Any], space: SearchSpace) -> list[str]:
    """The damping parameters a point with these shapers has: ``damping_x``/``damping_y`` for each
    shaped axis (not for Kalico's smoothers, which take none), or ``damping`` where one shaper serves
    all axes and shaping is on."""
    return [f"damping{s}" for _, s in shaping_axes(space) if takes_damping(shaping.get(f"shaper{s}", "none"))]


def _q(value: float, step: float) -> float:
    return round(round(float(value) / step) * step, 6)


def config_from_params(params: dict[str, Any], space: SearchSpace, extra: dict | None = None) -> TuneConfig:
    """The TuneConfig of a parameter dict (from a trial, a grid point or storage).

    Values are rounded to what a user would type and a firmware keeps: F to ``freq_step``
    (0.1 Hz), S to 0.005, the frequency limit to 0.5 Hz, acceleration to ``accel_step``. (Optuna
    samples them continuously: TPE's discrete kernels cost far more per trial.)"""
    shaping = {ax: (shaper_name(params[f"shaper{s}"], params, ax), _q(params.get(f"freq{s}", 0.0), space.freq_step))
               for ax, s in shaping_axes(space)}
    (sx, fx), (sy, fy) = shaping["x"], shaping.get("y", shaping["x"])
    z = params.get("damping", 0.1)
    zx, zy = (_q(params.get(f"damping_{ax}", z), 0.005) for ax in "xy")
    method = params.get("freq_limit", "off")
    accel = _q(space.accel[0] if space.accel_fixed else params.get("accel", space.accel[0]), space.accel_step)
    per_feature = feature_params(params, space)
    top = max([accel, *per_feature.get("feature_accel", {}).values()])
    return TuneConfig(firmware=space.firmware, shaper_x=sx, shaper_y=sy, freq_x=float(fx), freq_y=float(fy),
                      damping_x=zx, damping_y=zy,
                      freq_limit_hz=0.0 if method == "off" else _q(params["freq_limit_hz"], 0.5),
                      freq_limit_method="sections" if method == "off" else method,
                      min_speed_factor=space.min_speed_factor, accel=accel,
                      **trial_axis_caps(space, top), **per_feature, extra=dict(extra or {}))


def params_from_config(config: TuneConfig, space: SearchSpace) -> dict[str, Any]:
    """Inverse of :func:`config_from_params` (for enqueuing a known configuration)."""
    p: dict[str, Any] = {}
    for ax, s in shaping_axes(space):
        family, extra = family_params(getattr(config, f"shaper_{ax}"), ax)
        p[f"shaper{s}"] = family
        p.update(extra)
        if family != "none":
            p[f"freq{s}"] = getattr(config, f"freq_{ax}")
    for key in damping_keys(p, space):
        p[key] = getattr(config, key if key != "damping" else "damping_x")
    p["freq_limit"] = "off" if config.freq_limit_hz <= 0 else config.freq_limit_method
    if config.freq_limit_hz > 0:
        p["freq_limit_hz"] = config.freq_limit_hz
    if not space.accel_fixed:
        p["accel"] = config.accel
    for r in _per_feature(space):
        now = r.now(config)
        p[r.key] = min(max(float(now if now is not None else r.missing), r.lo), r.hi)
    return p
