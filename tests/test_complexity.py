"""Issue 20's code measures, held: radon's cyclomatic complexity over the four packages.

The figures are radon's own (``radon cc``: every function, method and class block at the top level
of a module, as ``radon cc -a`` averages them): mean ≤ 4.0, at most 2 % of blocks above 20, and
no command's ``run`` above 15 (a command parses, calls one library function, prints)."""

from __future__ import annotations

from pathlib import Path

from radon.complexity import cc_visit

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("envs", "agents", "shaping", "hardware")


def _blocks() -> list[tuple[str, object]]:
    """(module path, block) for every block ``radon cc`` lists (functions, methods, classes)."""
    out = []
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            if ".venv" in path.parts:
                continue
            for block in cc_visit(path.read_text(encoding="utf-8")):
                out.append((str(path.relative_to(ROOT)), block))
    return out


def test_mean_complexity_and_share_above_20():
    blocks = _blocks()
    scores = [b.complexity for _, b in blocks]
    assert len(scores) > 1000                       # the whole code base was read
    mean = sum(scores) / len(scores)
    above = [f"{w}:{b.name} {b.complexity}" for w, b in blocks if b.complexity > 20]
    assert mean <= 4.0, f"mean cyclomatic complexity {mean:.3f} over {len(scores)} blocks"
    assert len(above) <= 0.02 * len(scores), above


def test_no_command_run_above_15():
    runs = {w: b.complexity for w, b in _blocks()
            if w.startswith("agents/cli/") and b.name == "run" and getattr(b, "classname", 1) is None}
    assert len(runs) >= 15                          # every command module was read
    assert max(runs.values()) <= 15, {w: c for w, c in runs.items() if c > 15}
