"""The results folder of a run: checked writable (or creatable) before the run starts, in words
rather than an errno, and removed again when a failed run leaves it empty."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from ringtune.shaping.errors import RingtuneError


def check_out(out_dir: Path) -> None:
    """--out must be a folder we can write in (or create): say so in words, not an errno."""
    if out_dir.exists() and not out_dir.is_dir():
        raise RingtuneError(f"{out_dir} is a file, not a folder: give a folder for the results "
                            f"(e.g. --out {out_dir.with_suffix('')}-tune)", "--out")
    probe = out_dir.resolve()     # the nearest existing folder (at worst the root)
    while not probe.exists() and probe.parent != probe:
        probe = probe.parent
    if not probe.is_dir():
        raise RingtuneError(f"{probe} is a file, so {out_dir} cannot be created", "--out")
    if not os.access(probe, os.W_OK | os.X_OK):
        what = "folder" if probe == out_dir else f"folder {probe}, where {out_dir} would be created,"
        raise RingtuneError(f"cannot write in the {what} (no permission or a read-only file system); "
                            "choose another --out", "--out")
    try:      # a read-only mount answers os.access with "yes" for root: try it
        with tempfile.TemporaryFile(dir=probe):
            pass
    except OSError as exc:
        raise RingtuneError(f"cannot write in {probe}: {exc.strerror or exc}; choose another --out",
                            "--out") from None


def remove_if_empty(out_dir: Path) -> None:
    """A failed run leaves no empty results folder it created (a folder holding a study is kept)."""
    try:
        if out_dir.is_dir() and not any(out_dir.iterdir()):
            out_dir.rmdir()
    except OSError:
        pass
