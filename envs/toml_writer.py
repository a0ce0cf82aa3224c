"""Writing TOML (the standard library reads it but cannot write it): plain values, inline tables and
arrays, and tables with their sub-tables, in the form the printer description uses."""

from __future__ import annotations

import datetime
from typing import Any


def write_table(lines: list[str], name: str, table: dict, notes: dict) -> None:
    """Append ``[name]`` with its plain keys, then its sub-tables as ``[name.sub]`` (recursively)."""
    lines.append("")
    lines.append(f"[{name}]")
    for note in notes.get(name, ()):
        lines.append(f"# {note}")
    subs = []
    for k, v in table.items():
        if isinstance(v, dict):
            subs.append((k, v))
        else:
            lines.append(f"{toml_key(k)} = {toml_value(v)}")
    for k, v in subs:
        write_table(lines, f"{name}.{toml_key(k)}", v, notes)


def toml_key(k: str) -> str:
    return k if k.replace("_", "").replace("-", "").isalnum() and k.isascii() else toml_value(k)


def toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(float(v)) if isinstance(v, float) else str(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, (datetime.date, datetime.time)):
        return v.isoformat()
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{toml_key(k)} = {toml_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(f"cannot write {v!r} to TOML")
