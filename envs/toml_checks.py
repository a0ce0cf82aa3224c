"""Checked values of a TOML description (printer, motor): numbers in range, booleans, tables and
known keys; every refusal is one line naming the key (``printer.toml: [x].mass``)."""

from __future__ import annotations

import math

from ringtune.shaping.errors import RingtuneError


def number(d: dict, key: str, where: str, default=None, lo=None, hi=None, lo_open=False):
    """``d[key]`` as a float in [lo, hi] (``lo_open``: above lo), else ``default``; missing with
    no default, not a finite number, or out of range: refused, naming ``where.key``."""
    if key not in d:
        if default is None:
            raise RingtuneError(f"missing required key {key!r}", where)
        return default
    v = d[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise RingtuneError(f"{key} must be a finite number, got {v!r}", f"{where}.{key}")
    v = float(v)
    if lo is not None and (v <= lo if lo_open else v < lo):
        raise RingtuneError(f"{key} = {v:g} must be {'>' if lo_open else '≥'} {lo:g}", f"{where}.{key}")
    if hi is not None and v > hi:
        raise RingtuneError(f"{key} = {v:g} must be ≤ {hi:g}", f"{where}.{key}")
    return v


def flag(d: dict, key: str, where: str, default: bool | None) -> bool | None:
    """``d[key]`` (true or false), else ``default``."""
    v = d.get(key, default)
    if v is not None and not isinstance(v, bool):
        raise RingtuneError(f"{key} must be true or false, got {v!r}", f"{where}.{key}")
    return v


def table(d: dict, key: str, where: str) -> dict:
    """The sub-table ``[key]`` of ``d`` (empty when missing)."""
    v = d.get(key, {})
    if not isinstance(v, dict):
        raise RingtuneError(f"[{key}] must be a table, got {type(v).__name__}", f"{where}: {key}")
    return v


def refuse_unknown(d: dict, allowed: set, where: str) -> None:
    """Refuse the first key of ``d`` (alphabetically) that is not ``allowed``, naming those allowed."""
    extra = sorted(set(d) - allowed)
    if extra:
        raise RingtuneError(f"unknown key {extra[0]!r} (allowed: {', '.join(sorted(allowed))})", where)
