"""Resuming a stored study: only with the objectives and settings it was run with (the bounds may
change: they are applied again when the results are read), each difference named as a person would
name it."""

from __future__ import annotations

import json

from ringtune.shaping.errors import RingtuneError

#: the settings a resumed study must have been run with (the bounds may change: they are applied
#: again when the results are read)
_SAME_SETTINGS = ("printer", "job", "firmware", "backend", "evaluator", "space", "freq_margin", "job_accel",
                  "twin_damping")
#: what a study stored before a setting was recorded was run with
_BEFORE_RECORDED = {"twin_damping": 1.0}


def check_resumed(study, settings, wanted: list[str]) -> None:
    """Refuse to resume a stored study that optimises other objectives than ``wanted`` or was run
    with other :data:`_SAME_SETTINGS` than ``settings`` (a StudySettings; a study given no space
    takes the stored one)."""
    names = study.user_attrs["objectives"]
    if list(names) != wanted:
        raise RingtuneError(f"study {settings.study_name!r} in this storage optimises {names}, not {wanted}; "
                            "use another --study name or --out folder", "study_name")
    stored = study.user_attrs.get("settings", {})
    mine = json.loads(json.dumps(settings.to_dict()))
    stored = {**_BEFORE_RECORDED, **stored}
    for key in _SAME_SETTINGS:
        if key == "twin_damping" and not mine["freq_margin"]:
            continue                    # no twins: nothing judged with their damping
        if key in stored and stored[key] != mine[key] and not (key == "space" and mine[key] is None):
            raise RingtuneError(f"study {settings.study_name!r} in this storage was run with a different "
                                f"{key} ({_setting_text(key, stored[key])}; now "
                                f"{_setting_text(key, mine[key])}); use another --out folder or --study name"
                                + (f", or --firmware {stored[key]} to resume it" if key == "firmware" else ""),
                                "study_name")


def _setting_text(key: str, value) -> str:
    """A stored study setting as a person would name it (None = the built-in default)."""
    if value is None:
        return {"printer": "the built-in default printer", "job": "the built-in test print",
                "space": "the default search space"}.get(key, "none")
    if key == "twin_damping":
        return f"twins' damping ratios ×{value:g}"
    if key == "space" and isinstance(value, dict):
        acc = value.get("accel")
        return (f"acceleration {acc[0]:g}–{acc[1]:g} mm/s², F X {value.get('freq_x')}, F Y {value.get('freq_y')} Hz"
                if acc else "another search space")
    return repr(value)
