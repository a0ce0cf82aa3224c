"""The import graph, rebuilt from the code, obeys DESIGN.md: dependencies point one way and every
name has one address.

The graph is read with ``ast`` from every module of ``shaping/``, ``envs/``, ``agents/`` and
``hardware/`` — every ``import`` statement, also those inside functions and under
``if TYPE_CHECKING``. The rules (``../shared/DESIGN.md``, "Layout"):

- ``shaping`` (what the firmware does to motion, and the firmware records) imports nothing of ours;
  ``hardware`` (the real printer) imports ``shaping``: it sends what shaping defines and checks it
  with the same math before anything reaches a printer; ``envs`` imports ``shaping`` only;
  ``agents`` may import everything. (DESIGN.md allowed hardware and shaping each other's plain
  data types; the firmware dialects need the shaper registry's parser and checks, so the rule is
  made a strict layering instead: shaping below hardware, never the reverse.)
- no cycles: neither between packages nor between modules (imports at module level; an import
  inside a function runs later and may close a loop);
- imports at the top of each module: the only lazy imports are those :data:`LAZY_IMPORTS` lists
  (torch and stable-baselines3 in ``agents/ppo/rl.py``) and the by-name imports of
  :data:`IMPORTS_BY_NAME` (the entry point loads only the command being run);
- one address per name: every ``from ringtune.m import N`` (in the packages, the tests and the
  benchmarks) and every ``m.N`` on an imported module names a module that defines ``N``; no module
  imports one of our names without using it (a re-export), lists a name it does not define in
  ``__all__``, or serves names through a module ``__getattr__``.

Known exceptions are listed below, each with the issue that removes it; the test fails when an
exception is no longer needed, so the list cannot rot.
"""

from __future__ import annotations

import ast
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("shaping", "envs", "agents", "hardware")
#: package -> the packages it may import (besides itself)
MAY_IMPORT = {"shaping": set(), "hardware": {"shaping"}, "envs": {"shaping"},
              "agents": {"shaping", "envs", "hardware"}}

#: (importing module, imported module, name or "*") -> why it is still allowed
KNOWN_EXCEPTIONS = {
}


@dataclass(frozen=True)
class Edge:
    src: str            # importing module
    dst: str            # imported module
    name: str | None    # imported name (None: the module itself)
    line: int
    top_level: bool     # executed on import (not inside a function or TYPE_CHECKING)


def _module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return "ringtune." + ".".join(parts)


def _sources() -> dict[str, Path]:
    return {_module_name(p): p for pkg in PACKAGES for p in sorted((ROOT / pkg).rglob("*.py"))}


MODULES = _sources()
TREES = {m: ast.parse(p.read_text(), str(p)) for m, p in MODULES.items()}


def _package(module: str) -> str:
    return module.split(".")[1]


def _toplevel_nodes(tree: ast.Module):
    """Statements executed when the module is imported (module body, its if/try/with blocks),
    without ``if TYPE_CHECKING:`` blocks."""
    stack = list(tree.body)
    while stack:
        node = stack.pop()
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            stack.extend(node.orelse)
            continue
        yield node
        if isinstance(node, (ast.If, ast.Try, ast.With)):
            for field in ("body", "orelse", "finalbody", "handlers"):
                for child in getattr(node, field, []):
                    stack.extend(child.body if isinstance(child, ast.ExceptHandler) else [child])


def _definitions(tree: ast.Module) -> tuple[set[str], set[str], set[str]]:
    """(names the module defines, of which classes, of which UPPER_CASE constants)."""
    names, classes, constants = set(), set(), set()
    stack = list(tree.body)
    while stack:
        node = stack.pop()
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            names.add(node.name)
        elif isinstance(node, ast.ClassDef):
            names.add(node.name)
            classes.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign, ast.AugAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for t in targets:
                for n in ast.walk(t):
                    if isinstance(n, ast.Name):
                        names.add(n.id)
                        if n.id.isupper() or (n.id[:1] == "_" and n.id[1:].isupper()):
                            constants.add(n.id)
        elif isinstance(node, (ast.If, ast.Try, ast.With)):
            for field in ("body", "orelse", "finalbody", "handlers"):
                for child in getattr(node, field, []):
                    stack.extend(child.body if isinstance(child, ast.ExceptHandler) else [child])
    return names, classes, constants


DEFS = {m: _definitions(t) for m, t in TREES.items()}


def _resolve(src: str, node: ast.ImportFrom) -> str | None:
    if not node.level:
        return node.module
    base = src.split(".")
    if not MODULES[src].name == "__init__.py":
        base = base[:-1]
    base = base[: len(base) - node.level + 1]
    return ".".join(base + ([node.module] if node.module else []))


def _edges(src: str, tree: ast.Module) -> list[Edge]:
    top = {id(n) for n in _toplevel_nodes(tree)}
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("ringtune."):
                    out.append(Edge(src, a.name, None, node.lineno, id(node) in top))
        elif isinstance(node, ast.ImportFrom):
            mod = _resolve(src, node)
            if not mod or not mod.startswith("ringtune."):
                continue
            for a in node.names:
                sub = f"{mod}.{a.name}"
                if sub in MODULES:
                    out.append(Edge(src, sub, None, node.lineno, id(node) in top))
                else:
                    out.append(Edge(src, mod, a.name, node.lineno, id(node) in top))
    return out


EDGES = [e for m, t in TREES.items() for e in _edges(m, t)]


def _exception(edge: Edge) -> str | None:
    for key in ((edge.src, edge.dst, edge.name), (edge.src, edge.dst, "*")):
        if key in KNOWN_EXCEPTIONS:
            return KNOWN_EXCEPTIONS[key]
    return None


def _where(edge: Edge) -> str:
    return f"{MODULES[edge.src].relative_to(ROOT)}:{edge.line}"


def test_every_module_is_read():
    assert len(MODULES) > 60
    assert "ringtune.shaping.shapers" in MODULES and "ringtune.agents.cli.plan" in MODULES


def package_rule_violations(edges=EDGES) -> list[str]:
    bad = []
    for e in edges:
        sp, dp = _package(e.src), _package(e.dst)
        if sp == dp or _exception(e):
            continue
        what = f"{e.dst}.{e.name}" if e.name else e.dst
        if dp not in MAY_IMPORT[sp]:
            bad.append(f"{_where(e)}: {sp} imports {what} ({sp} may import only "
                       f"{', '.join(sorted(MAY_IMPORT[sp])) or 'itself'})")
    return bad


def test_dependencies_point_one_way():
    bad = package_rule_violations()
    assert not bad, "\n".join(bad)


#: agents' subpackages by concept (DESIGN.md, "Layout"); ``cli`` holds the entry point and the commands
AGENT_ROOMS = {"cli", "tune", "ppo", "identify", "klipper"}


def _room(module: str) -> str | None:
    parts = module.split(".")
    return parts[2] if len(parts) > 2 and parts[1] == "agents" else None


def room_rule_violations(edges=EDGES) -> list[str]:
    """Inside ``agents``: every module lives in a room; commands import the library, the library
    never imports a command (nor the entry point)."""
    bad = []
    for m in MODULES:
        if _package(m) == "agents" and m != "ringtune.agents" and _room(m) not in AGENT_ROOMS:
            bad.append(f"{MODULES[m].relative_to(ROOT)}: agents/ module outside the rooms "
                       f"{', '.join(sorted(AGENT_ROOMS))}")
    for e in edges:
        if _package(e.src) == "agents" and _room(e.src) != "cli" and _room(e.dst) == "cli":
            bad.append(f"{_where(e)}: the library imports the command line ({e.dst}); "
                       f"commands import the library, never the reverse")
    return bad


def test_agents_rooms_and_the_library_never_imports_a_command():
    bad = room_rule_violations()
    assert not bad, "\n".join(bad)


def test_a_library_to_cli_import_is_caught():
    """The rule above fails on the edge it forbids (a library module importing a command)."""
    fake = Edge("ringtune.agents.tune.report", "ringtune.agents.cli.common", "check_output_folder",
                1, True)
    assert any("the library imports the command line" in v for v in room_rule_violations([fake]))
    ok = Edge("ringtune.agents.cli.tune", "ringtune.agents.tune.report", None, 1, True)
    assert room_rule_violations([ok]) == []


def test_known_exceptions_are_still_needed():
    """An exception nothing needs any more is dropped from the list (it would hide a new edge)."""
    used = set()
    for e in EDGES:
        for key in ((e.src, e.dst, e.name), (e.src, e.dst, "*")):
            if key in KNOWN_EXCEPTIONS:
                used.add(key)
    assert set(KNOWN_EXCEPTIONS) - used == set()


#: the only imports that run after start-up (inside a function): module -> (top-level packages it
#: may import there, why)
LAZY_IMPORTS = {
    "ringtune.agents.ppo.rl": ({"torch", "stable_baselines3"},
                               "the rl extra: optional, and seconds to import"),
}
#: the only modules that import by name at run time (``importlib``): module -> why
IMPORTS_BY_NAME = {
    "ringtune.agents.cli.main": "only the command being run; ringtune --help lists them from COMMANDS",
    "ringtune.agents.tune.study": "the evaluator a study names ('module:function'), in each worker",
}


def lazy_import_violations(trees=None) -> list[str]:
    """Imports at the top of each module: an import statement inside a function (or a class body)
    is allowed only where :data:`LAZY_IMPORTS` lists it; ``importlib.import_module`` and
    ``__import__`` only in :data:`IMPORTS_BY_NAME`'s modules."""
    bad = []
    for m, tree in (trees or TREES).items():
        inner = {id(n) for d in ast.walk(tree) if isinstance(d, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef))
                 for n in ast.walk(d)}
        allowed = LAZY_IMPORTS.get(m, (set(), ""))[0]
        where = MODULES[m].relative_to(ROOT) if m in MODULES else m
        for node in ast.walk(tree):
            if isinstance(node, (ast.Import, ast.ImportFrom)) and id(node) in inner:
                roots = ({a.name.split(".")[0] for a in node.names} if isinstance(node, ast.Import)
                         else {(node.module or "").split(".")[0]})
                if not roots <= allowed:
                    bad.append(f"{where}:{node.lineno}: {ast.unparse(node)} inside a function "
                               "(imports go at the top of the module)")
            elif (isinstance(node, ast.Call) and ast.unparse(node.func) in ("importlib.import_module", "__import__")
                  and m not in IMPORTS_BY_NAME):
                bad.append(f"{where}:{node.lineno}: imports by name at run time")
    return bad


def test_imports_are_at_the_top_of_each_module():
    bad = lazy_import_violations()
    assert not bad, "\n".join(bad)


def test_a_lazy_import_is_caught():
    tree = ast.parse("import os\n\ndef f():\n    import numpy as np\n    return np\n")
    assert any("inside a function" in v for v in lazy_import_violations({"ringtune.shaping.fake": tree}))
    tree = ast.parse("def f():\n    import torch\n")
    assert lazy_import_violations({"ringtune.agents.ppo.rl": tree}) == []
    assert lazy_import_violations({"ringtune.agents.ppo.policy": tree}) != []


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of a directed graph as a list of nodes, or None."""
    state: dict[str, int] = {}
    path: list[str] = []

    def visit(n: str):
        state[n] = 1
        path.append(n)
        for m in sorted(graph.get(n, ())):
            if state.get(m) == 1:
                return path[path.index(m):] + [m]
            if m not in state:
                found = visit(m)
                if found:
                    return found
        state[n] = 2
        path.pop()
        return None

    sys.setrecursionlimit(max(sys.getrecursionlimit(), 10_000))
    for n in sorted(graph):
        if n not in state:
            found = visit(n)
            if found:
                return found
    return None


def test_no_cycles_between_packages():
    graph: dict[str, set[str]] = {}
    for e in EDGES:
        sp, dp = _package(e.src), _package(e.dst)
        if sp != dp:
            graph.setdefault(sp, set()).add(dp)
    assert _cycle(graph) is None


def test_no_cycles_between_modules():
    graph: dict[str, set[str]] = {}
    for e in EDGES:
        if e.top_level and e.dst in MODULES and e.dst != e.src:
            graph.setdefault(e.src, set()).add(e.dst)
    assert _cycle(graph) is None


# -- one address per name -----------------------------------------------------------------------

def _reader_files() -> list[Path]:
    files = [p for p in MODULES.values()]
    for folder in ("tests", "benchmarks"):
        files += sorted((ROOT / folder).rglob("*.py"))
    return files


def _address_violations(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(), str(path))
    src = _module_name(path) if path.parts[-2] in PACKAGES or any(
        part in PACKAGES for part in path.relative_to(ROOT).parts[:1]) else None
    aliases: dict[str, str] = {}
    bad = []
    where = lambda node: f"{path.relative_to(ROOT)}:{node.lineno}"  # noqa: E731
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            mod = _resolve(src, node) if (node.level and src) else node.module
            if not mod or mod not in MODULES:
                continue
            for a in node.names:
                sub = f"{mod}.{a.name}"
                if sub in MODULES:
                    aliases[a.asname or a.name] = sub
                elif a.name not in DEFS[mod][0] and not _exception(Edge(src or "", mod, a.name, 0, True)):
                    bad.append(f"{where(node)}: {a.name} is imported from {mod}, which does not define it")
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name in MODULES and a.asname:
                    aliases[a.asname] = a.name
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in aliases:
            mod = aliases[node.value.id]
            if node.attr not in DEFS[mod][0] and f"{mod}.{node.attr}" not in MODULES:
                bad.append(f"{where(node)}: {node.value.id}.{node.attr}: {mod} does not define {node.attr}")
    return bad


def test_every_name_is_imported_from_where_it_is_defined():
    bad = [v for p in _reader_files() for v in _address_violations(p)]
    assert not bad, "\n".join(bad)


def _used_names(tree: ast.Module) -> set[str]:
    used = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Name):
            used.add(node.id)
        elif isinstance(node, ast.Attribute):
            base = node
            while isinstance(base, ast.Attribute):
                base = base.value
            if isinstance(base, ast.Name):
                used.add(base.id)
    # names inside string annotations (``raw: "RawAccel"``)
    notes = [n.annotation for n in ast.walk(tree) if isinstance(n, (ast.arg, ast.AnnAssign)) and n.annotation]
    notes += [n.returns for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))
              and n.returns]
    for note in notes:
        for c in ast.walk(note):
            if isinstance(c, ast.Constant) and isinstance(c.value, str):
                for n in ast.walk(ast.parse(c.value, mode="eval")):
                    if isinstance(n, ast.Name):
                        used.add(n.id)
    return used


def test_no_module_imports_our_names_only_to_expose_them():
    bad = []
    for m, tree in TREES.items():
        used = _used_names(tree)
        all_names: set[str] = set()
        for node in tree.body:
            if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "__all__"
                                                   for t in node.targets):
                all_names = {c.value for c in ast.walk(node.value) if isinstance(c, ast.Constant)}
            if isinstance(node, ast.FunctionDef) and node.name == "__getattr__":
                bad.append(f"{MODULES[m].relative_to(ROOT)}:{node.lineno}: module __getattr__ "
                           "serves names under a second address")
        defined = DEFS[m][0]
        for name in sorted(all_names - defined):
            bad.append(f"{MODULES[m].relative_to(ROOT)}: __all__ exposes {name!r}, defined elsewhere")
        ours = {a.asname or a.name for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)
                and node.module and node.module.startswith("ringtune.") for a in node.names}
        for node in tree.body:     # ``alias = imported_name``: the same object under a second name
            if isinstance(node, ast.Assign) and isinstance(node.value, ast.Name) and node.value.id in ours:
                bad.append(f"{MODULES[m].relative_to(ROOT)}:{node.lineno}: {ast.unparse(node)} gives "
                           f"{node.value.id} a second address")
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("ringtune."):
                for a in node.names:
                    local = a.asname or a.name
                    if local not in used:
                        bad.append(f"{MODULES[m].relative_to(ROOT)}:{node.lineno}: {local} is imported "
                                   "and never used (a re-export, or dead)")
    assert not bad, "\n".join(bad)


# -- the test can fail ----------------------------------------------------------------------------

@pytest.mark.parametrize("src, dst, name, rule", [
    ("ringtune.shaping.planner", "ringtune.envs.printer", "load_printer", "shaping imports"),
    ("ringtune.envs.sim", "ringtune.hardware.accel", "read_accel", "envs imports"),
    ("ringtune.shaping.shapers", "ringtune.hardware.dialects", "DIALECTS", "shaping imports"),
    ("ringtune.shaping.apply", "ringtune.agents.tune.pareto", "choose", "shaping imports"),
])
def test_a_forbidden_import_is_caught(src, dst, name, rule):
    extra = Edge(src, dst, name, 1, True)
    assert any(rule in v for v in package_rule_violations(EDGES + [extra]))


def test_a_package_cycle_is_caught():
    graph = {"envs": {"shaping"}, "shaping": {"envs"}}
    assert _cycle(graph) in (["envs", "shaping", "envs"], ["shaping", "envs", "shaping"])
