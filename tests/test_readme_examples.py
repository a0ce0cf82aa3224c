"""The README's "Your own printer" example runs as written on the sample files the repository ships
(with fewer trials, and without the push, which needs a printer)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _own_printer_block() -> str:
    text = (ROOT / "README.md").read_text()
    section = text[text.index("## Your own printer"):]
    return re.search(r"```bash\n(.*?)```", section, re.S).group(1)


@pytest.mark.slow
def test_own_printer_example_runs_on_the_shipped_files(tmp_path):
    block = _own_printer_block()
    assert "tests/data/" in block                       # the example names files the repo has
    script = "\n".join(line for line in block.splitlines()
                       if not line.startswith(". .venv") and not line.startswith("ringtune push"))
    # a short study taken as it left it: what is checked is that each command runs on the shipped
    # files and writes what the next one reads, not the walks (their own tests judge them)
    script = script.replace("--trials 30", "--trials 3 --no-refine")
    bindir = Path(sys.executable).parent
    env = dict(os.environ, PATH=f"{bindir}{os.pathsep}{os.environ['PATH']}", MPLBACKEND="Agg")
    for name in ("ACC", "CFG", "JOB"):          # the variables point into the checkout
        script = script.replace(f"{name}=tests/", f"{name}={ROOT}/tests/")
    r = subprocess.run(["bash", "-euo", "pipefail", "-c", script], cwd=tmp_path, env=env,
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    for f in ("myprinter.toml", "fit.png", "klipper.json", "tuned/best.json", "tuned/summary.txt"):
        assert (tmp_path / f).exists(), f
    assert "SET_INPUT_SHAPER" in r.stdout                # the export's lines
