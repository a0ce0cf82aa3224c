"""README's development table matches the folders: every package folder has its row (and its
``imported as`` name), every row names a folder that exists, and every ``folder/module.py`` the
README names exists."""

from __future__ import annotations

import re
from pathlib import Path

from ringtune.agents.cli.main import COMMANDS

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text(encoding="utf-8")


def _table_rows() -> dict[str, str]:
    """{folder: imported-as} from the development table's rows."""
    section = README.split("## Development", 1)[1]
    rows = re.findall(r"^\| `([a-z_/]+/)` \| (`[a-z_.]+`)? ?\|", section, flags=re.M)
    return {folder: name.strip("`") for folder, name in rows}


def _packages() -> set[str]:
    """The folders holding an ``__init__.py`` below the four top-level packages, as ``a/b/``."""
    found = set()
    for top in ("shaping", "envs", "hardware", "agents"):
        for init in (ROOT / top).rglob("__init__.py"):
            found.add(init.parent.relative_to(ROOT).as_posix() + "/")
    return found - {"agents/"}      # agents/ itself only holds the rooms


def test_every_package_folder_has_its_row_and_name():
    rows = _table_rows()
    assert _packages() <= set(rows), f"missing rows: {_packages() - set(rows)}"
    for folder in _packages():
        assert rows[folder] == "ringtune." + folder.rstrip("/").replace("/", ".")


def test_every_row_and_named_module_exists():
    for folder in _table_rows():
        assert (ROOT / folder).is_dir(), folder
    named = set(re.findall(r"`((?:shaping|envs|hardware|agents|benchmarks|tests)/[\w/]+\.py)`", README))
    assert named, "the README names modules"
    for path in named:
        assert (ROOT / path).is_file(), path
    for module in re.findall(r"`(\w+\.py)`", README.split("## Development", 1)[1]):
        assert any(list((ROOT / top).rglob(module)) for top in ("shaping", "envs", "hardware", "agents")), module


def test_every_cli_module_is_a_command_or_named_in_its_row():
    """agents/cli/ holds one module per command; the others are named in its row."""
    row = next(line for line in README.splitlines() if line.startswith("| `agents/cli/` |"))
    for path in sorted((ROOT / "agents" / "cli").glob("*.py")):
        if path.stem not in COMMANDS and path.name != "__init__.py":
            assert f"`{path.name}`" in row, path.name
