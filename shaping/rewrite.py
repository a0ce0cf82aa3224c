"""The job rewriter: a sliced job with the tuned acceleration (and corner rule) written in at each
feature change, in the firmware's own dialect; nothing else of the file changes.

:func:`rewrite_job` inserts lines and edits none, but the job's own shaper commands that would move
the printer off the tuned shaper (``replaced``: the tuned shaper's command in their place):

- before a move where the settings of :func:`ringtune.shaping.feature_settings.move_settings`
  change (a feature change, or for Klipper's one acceleration a travel), the commands that set
  them: Klipper/Kalico ``SET_VELOCITY_LIMIT ACCEL=… [ACCEL_TO_DECEL=…] [SQUARE_CORNER_VELOCITY=…]
  [MINIMUM_CRUISE_RATIO=…]`` (where the configuration sets a minimum_cruise_ratio, ACCEL_TO_DECEL =
  ACCEL × (1 − it) for a Klipper from before 2024, which has no MINIMUM_CRUISE_RATIO and keeps its
  ACCEL_TO_DECEL whatever ACCEL becomes; a newer one ignores it); Marlin, Prusa ``M204 P… T…`` (+ ``M205 J…`` or ``M205 X… Y…``);
  RepRapFirmware ``M204 P… T…`` (+ ``M566 X… Y…``, mm/min); the corner settings there only where
  the configuration sets them per class (else once, below);
- the corner rule and the per-axis caps (``M201 X Y``; Kalico ``SET_VELOCITY_LIMIT X_ACCEL=
  Y_ACCEL=``) once before the first move, and again after any acceleration or corner command of
  the job itself (a slicer's own ``M204`` at a feature change), so the job's own values never rule
  a move;
- ``layer_inserts`` ({layer index: [lines]}) before the first move of each layer
  (:func:`layer_starts`): the hook for schedules by printed mass.

Planned by :func:`ringtune.shaping.config_plan.plan_with_config` the rewritten file gives every
move the settings the configuration gave it, so its planned time is the configuration's.
:func:`rewrite_gcode_bytes` composes it with the frequency limit of ``ringtune limit``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.feature_settings import FeatureCommands, caps_setting, effective_classes, move_settings
from ringtune.shaping.features import FEATURE_CLASSES
from ringtune.shaping.firmware import FIRMWARES
from ringtune.shaping.gcode import read_gcode
from ringtune.shaping.job import Job
from ringtune.shaping.job_shapers import overriding
from ringtune.shaping.layer_commands import TAG
from ringtune.shaping.layers import layer_starts

#: settings a block sets at every change (the others once, and after the job's own commands)
_ACCEL_KEYS = ("accel_klipper", "accel_print", "accel_travel")


#: the classic-jerk command by family and its unit per mm/s (RepRapFirmware's M566: mm/min; else M205)
_JERK_COMMANDS = {"rrf": ("M566", 60)}


def _n(v: float) -> str:
    return f"{float(v):.10g}"


@dataclass(frozen=True)
class _Dialect:
    family: str
    junction: str
    caps_set: str
    klipper_reading: bool

    def accel(self, values: dict, corner_keys: tuple = ()) -> list[str]:
        """The lines setting the acceleration (and the corner settings ``corner_keys`` that change
        with it, per class) — on Klipper one ``SET_VELOCITY_LIMIT``."""
        if self.junction == "scv" and self.family == "klipper":
            words = [f"ACCEL={_n(values['accel_klipper'])}", *_accel_to_decel(values)]
            return ["SET_VELOCITY_LIMIT " + " ".join(words + _klipper_words(values, corner_keys))]
        if self.junction == "scv" and self.klipper_reading:
            return [f"M204 P{_n(values['accel_klipper'])} T{_n(values['accel_klipper'])}"] + self.corner(values, corner_keys)
        return [f"M204 P{_n(values['accel_print'])} T{_n(values['accel_travel'])}"] + self.corner(values, corner_keys)

    def corner(self, values: dict, keys) -> list[str]:
        """The commands setting the corner settings ``keys`` of ``values`` (not Klipper's, which
        :meth:`accel` and :meth:`once` write as words of ``SET_VELOCITY_LIMIT``)."""
        out = []
        if _klipper_words(values, keys):
            if self.family != "klipper":
                raise RingtuneError(f"the printer plans corners with Klipper's square_corner_velocity (junction "
                                    f"scv), which {self.family} has no command for: describe the printer with its "
                                    "own junction_deviation or jerk (--printer)", "config: corner")
            out.append("SET_VELOCITY_LIMIT " + " ".join(_klipper_words(values, keys)))
        if "junction_deviation" in keys:
            out.append(f"M205 J{_n(values['junction_deviation'])}")
        if "jerk_x" in keys:
            cmd, per_s = _JERK_COMMANDS.get(self.family, ("M205", 1))
            out.append(f"{cmd} X{_n(values['jerk_x'] * per_s)} Y{_n(values['jerk_y'] * per_s)}")
        return out

    def once(self, values: dict) -> list[str]:
        out = self.corner(values, [k for k in _CORNER_KEYS if k in values])
        caps = caps_setting(self.klipper_reading)
        if f"{caps}_x" in values and self.caps_set:
            out.append(self.caps_set.format(x=_n(values[f"{caps}_x"]), y=_n(values[f"{caps}_y"])))
        return out


#: the corner settings a configuration may set, whole-job or per class
_CORNER_KEYS = ("square_corner_velocity", "min_cruise_ratio", "junction_deviation", "jerk_x", "jerk_y")
_KLIPPER_WORDS = (("SQUARE_CORNER_VELOCITY", "square_corner_velocity"), ("MINIMUM_CRUISE_RATIO", "min_cruise_ratio"))


def _accel_to_decel(values: dict) -> list[str]:
    """``ACCEL_TO_DECEL=`` in force where the configuration sets a minimum_cruise_ratio
    (:func:`ringtune.shaping.feature_settings.move_settings`: ACCEL × (1 − it)): a Klipper from
    before 2024 has no MINIMUM_CRUISE_RATIO and keeps its accel_to_decel in mm/s² (the config's,
    default half its max_accel) whatever ACCEL becomes; a newer Klipper ignores the word."""
    return [f"ACCEL_TO_DECEL={_n(values['accel_to_decel'])}"] if "accel_to_decel" in values else []


def _klipper_words(values: dict, keys) -> list[str]:
    return [f"{word}={_n(values[k])}" for word, k in _KLIPPER_WORDS if k in keys]


def _dialect(firmware: str, fc: FeatureCommands) -> _Dialect:
    fw = FIRMWARES.get(str(firmware).lower())
    if fw is None:
        raise RingtuneError(f"must be one of {', '.join(FIRMWARES)}, not {firmware!r}", "firmware")
    return _Dialect(fw.family if fw.family in ("klipper", "rrf") else "marlin", fc.junction, fw.axis_accel_set,
                    fc.reads_like_klipper)


def _feature_inserts(job: Job, firmware: str, fc: FeatureCommands) -> dict[int, list[str]]:
    """{source line (1-based): lines to insert before it} for the per-feature commands."""
    dialect = _dialect(firmware, fc)
    values = move_settings(job, fc)
    # corner settings set per class change with the feature, as the accelerations do
    varying = tuple(k for k in _CORNER_KEYS if k in values and np.ptp(values[k]) > 0)
    stack = np.stack([values[k] for k in _ACCEL_KEYS + varying], axis=1)
    changed = np.ones(job.n_moves, bool)
    changed[1:] = np.any(stack[1:] != stack[:-1], axis=1)
    again = np.zeros(job.n_moves, bool)          # the job's own limit commands stand before these moves
    for ev in job.events:
        if ev.kind == "limits" and ev.move < job.n_moves:
            again[ev.move] = True
    again[0] = True
    first_of_line = np.concatenate(([True], job.line[1:] != job.line[:-1]))
    # what the comment names: the class Klipper's one acceleration follows, else the feature label
    names, index = (FEATURE_CLASSES, effective_classes(job)) if fc.junction == "scv" else (job.features, job.feature)
    out: dict[int, list[str]] = {}
    for i in np.flatnonzero((changed | again) & first_of_line):
        row = {k: float(v[i]) for k, v in values.items()}
        lines = dialect.once(row) if again[i] else []
        first, *rest = dialect.accel(row, varying)
        lines += [f"{first} ; ringtune: {names[index[i]]}", *rest]
        out[int(job.line[i])] = lines
    return out


def shapers_to_replace(lines: list[str], job: Job, config) -> list:
    """The job's shaper commands (events) that would move the printer off ``config``'s shaping
    (:func:`ringtune.shaping.job_shapers.overriding`), those ringtune wrote itself (a mass schedule's
    band lines, tagged :data:`~ringtune.shaping.layer_commands.TAG`) aside; ``lines``: the job's,
    as ``job`` numbers them."""
    return [ev for ev in overriding(job, config) if TAG not in lines[ev.line - 1]]


def rewrite_job(lines: list[str], firmware: str, feature_cmds: FeatureCommands | None,
                layer_inserts: dict[int, list[str]] | None = None, parsed: Job | None = None,
                replaced: dict[int, list[str]] | None = None) -> list[str]:
    """The job's lines with the per-feature commands and ``layer_inserts`` inserted (module
    docstring); every input line is kept as it is, in order, but those of ``replaced``.

    Args:
        lines: the job's lines, with or without their line endings (the output keeps the form).
        firmware: a firmware name of :data:`ringtune.shaping.firmware.FIRMWARES` (its dialect).
        feature_cmds: what to set per feature (:meth:`FeatureCommands.from_config`), or None.
        layer_inserts: {layer index (0 = first layer, :func:`layer_starts`): [G-code lines]},
            inserted before the first move of that layer, ahead of any feature command there.
        parsed: ``lines`` already read (:func:`ringtune.shaping.gcode.read_gcode`), else they are read here.
        replaced: {source line (1-based): [G-code lines]} written instead of that line, the first
            with a comment that quotes it (the job's own shaper commands, where the tuned shaper
            takes their place: :func:`ringtune.shaping.job_shapers.overriding`).
    """
    keep = bool(lines) and lines[0].endswith("\n")
    nl = ("\r\n" if lines[0].endswith("\r\n") else "\n") if keep else ""
    job = parsed if parsed is not None else read_gcode("".join(ln if keep else ln + "\n" for ln in lines),
                                                       source="job")
    inserts: dict[int, list[str]] = {}
    if layer_inserts:
        starts = layer_starts(job)
        for k, extra in layer_inserts.items():
            if not 0 <= int(k) < len(starts):
                raise RingtuneError(f"layer {k} is not in the job (it has {len(starts)} layers)", "layer_inserts")
            inserts.setdefault(int(job.line[starts[int(k)]]), []).extend(extra)
    if feature_cmds is not None and job.n_moves:
        for ln, extra in _feature_inserts(job, firmware, feature_cmds).items():
            inserts.setdefault(ln, []).extend(extra)
    out: list[str] = []
    for ln, line in enumerate(lines, 1):
        out.extend(x + nl for x in inserts.get(ln, ()))
        if replaced and ln in replaced:
            first, *rest = replaced[ln]
            out.extend(x + nl for x in [f"{first} ; ringtune: in place of the job's own {line.strip()}", *rest])
        else:
            out.append(line)
    return out
