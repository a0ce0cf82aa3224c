"""A printer's resonance files and Klipper configuration, fetched through Moonraker's file API.

Klipper writes ``TEST_RESONANCES`` output to ``/tmp`` (``resonances_<axis>_<name>.csv``,
``resonances_axis=1.000,-1.000,0.000_<name>.csv``; ``SHAPER_CALIBRATE`` writes
``calibration_data_<axis>_<name>.csv``), a folder Moonraker does not serve: the files are looked
for in Moonraker's ``config`` and ``gcodes`` roots (where users copy them, and where plugins such as
Shake&Tune keep results), with ``GET /server/files/list?root=…``. Of each test — X, Y and the two
diagonals — the newest file (Moonraker's ``modified`` time) is taken. The configuration is the
config root's ``printer.cfg`` with every ``.cfg`` file beside it (its includes), downloaded with
``GET /server/files/config/<path>`` and read by the same reader as a local file; without a
``printer.cfg`` there, the caller falls back to what Klipper loaded (the ``configfile`` object).

Files are saved in ``dest`` under the names they have on the printer (config files keep their
folders), so that what was read can be read again, and a file already there with other contents
is never overwritten.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Callable

from ringtune.hardware.accel import axis_from_file_name, direction_from_file_name
from ringtune.hardware.moonraker import Moonraker
from ringtune.shaping.errors import RingtuneError

#: roots searched for resonance files, in order
ROOTS = ("config", "gcodes")
#: Klipper's resonance output (not raw captures: those are large and name no processed spectrum)
RESONANCE_FILE = re.compile(r"^(?:resonances|calibration_data)_.+\.csv$", re.IGNORECASE)
CONFIG_SUFFIXES = (".cfg",)
#: the sign of a diagonal test's dx·dy -> its name
_DIAGONALS = {1: "1,1", -1: "1,-1"}


@dataclass
class FetchedFiles:
    """What was fetched: the axis files (X then Y), the diagonal belt tests (AXIS=1,1 then 1,-1),
    the local ``printer.cfg`` (None if the config root has none), and what was decided."""

    axes: list[Path] = field(default_factory=list)
    belts: list[Path] = field(default_factory=list)
    config: Path | None = None
    notes: list[str] = field(default_factory=list)


def resonance_test_of(name: str) -> str | None:
    """Which test a resonance file holds: ``"x"``, ``"y"``, ``"1,1"`` or ``"1,-1"`` (None: another)."""
    if not RESONANCE_FILE.match(PurePosixPath(name).name):
        return None
    d = direction_from_file_name(name)
    if d is not None:               # the sign of dx·dy: 0 is a single axis, named as a direction
        return _DIAGONALS.get((d[0] * d[1] > 0) - (d[0] * d[1] < 0))
    ax = axis_from_file_name(name)
    return ax if ax in ("x", "y") else None


def newest_tests(entries: list[tuple[str, dict]]) -> dict[str, tuple[str, dict]]:
    """Of ``(root, entry)`` pairs from the file lists, the newest file of each test."""
    best: dict[str, tuple[str, dict]] = {}
    for root, e in entries:
        key = resonance_test_of(str(e["path"]))
        if key and (key not in best or float(e.get("modified", 0)) > float(best[key][1].get("modified", 0))):
            best[key] = (root, e)
    return best


def _save(dest: Path, rel: str, data: bytes) -> Path:
    """Write ``data`` at ``dest/rel`` unless a different file is already there."""
    parts = PurePosixPath(rel).parts
    if not parts or ".." in parts or PurePosixPath(rel).is_absolute():
        raise RingtuneError(f"refusing the printer's file name {rel!r}", "--moonraker")
    path = dest.joinpath(*parts)
    if path.exists() and path.read_bytes() != data:
        raise RingtuneError(f"{path} already exists with other contents; move it away or fetch elsewhere",
                            "--moonraker")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(data)
    return path


def fetch_printer_files(url: str, dest: str | Path, api_key: str | None = None, timeout: float = 10.0,
                        log: Callable[[str], None] | None = None) -> FetchedFiles:
    """Fetch the newest resonance test of each kind and the configuration into ``dest``."""
    mr = Moonraker(url, api_key=api_key, timeout=timeout, log=log)
    dest = Path(dest)
    listed = {root: mr.list_files(root) for root in ROOTS}
    tests = newest_tests([(root, e) for root, files in listed.items() for e in files])
    if not {"x", "y"} & tests.keys():
        raise RingtuneError("no resonance file (resonances_x_….csv, resonances_y_….csv) in Moonraker's "
                            f"{' or '.join(ROOTS)} folders; Klipper writes them to /tmp, which Moonraker does not "
                            "serve: copy them into the config folder (cp /tmp/resonances_*.csv ~/printer_data/config/)",
                            mr.shown)
    out = FetchedFiles()
    _fetch_tests(mr, tests, dest, out)
    _fetch_config(mr, listed["config"], dest, out)
    return out


def _fetch_tests(mr: Moonraker, tests: dict, dest: Path, out: FetchedFiles) -> None:
    """Each test's newest file saved under its own name: the axes' into ``out.axes``, the diagonals'
    into ``out.belts`` (both or none)."""
    for key, target, what in (("x", out.axes, "x"), ("y", out.axes, "y"), ("1,1", out.belts, "AXIS=1,1"),
                              ("1,-1", out.belts, "AXIS=1,-1")):
        if key not in tests:
            continue
        root, e = tests[key]
        target.append(_save(dest, PurePosixPath(e["path"]).name, mr.download(root, e["path"])))
        out.notes.append(f"fetched {root}/{e['path']} (the newest {what} test) to {target[-1]}")
    if len(out.belts) == 1:
        out.notes.append(f"only one diagonal test ({out.belts[0].name}) on the printer: belts not compared")
        out.belts = []


def _fetch_config(mr: Moonraker, listed: list[dict], dest: Path, out: FetchedFiles) -> None:
    configs = [str(e["path"]) for e in listed if str(e["path"]).lower().endswith(CONFIG_SUFFIXES)]
    if "printer.cfg" not in configs:
        return
    saved = {rel: _save(dest, rel, mr.download("config", rel)) for rel in configs}
    out.config = saved["printer.cfg"]
    out.notes.append(f"fetched the configuration (printer.cfg and {len(configs) - 1} other .cfg files) to {dest}")
