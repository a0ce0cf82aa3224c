"""Start-up time of ``ringtune --help`` and ``ringtune tune --help``: this checkout against the code
before the entry point learned to import only the command being run (issue 20), in one run.

The base revision (default :data:`BASE`, the last commit whose ``ringtune --help`` imported every
command module) is checked out into a temporary ``git worktree`` and put first on ``PYTHONPATH`` as
the ``ringtune`` namespace, so both run on this interpreter and these installed libraries. Each
command runs in a fresh interpreter, the two revisions alternating, ``--repeat`` times each; the
figure is the median CPU time (user + system) of the child process, and its wall time beside it.
A ratio below 1 means this checkout starts faster.

    .venv/bin/python benchmarks/bench_startup.py [--base REV] [--repeat N]
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: the commit before issue 20's start-up change (agents/ in rooms, imports still inside functions)
BASE = "1d64618"
PACKAGES = ("shaping", "envs", "hardware", "agents")
COMMANDS = (["--help"], ["tune", "--help"])


def namespace_of(checkout: Path, folder: Path) -> Path:
    """A folder holding ``ringtune/<package>`` links to ``checkout``'s packages (the layout the
    install maps them to), for ``PYTHONPATH``."""
    (folder / "ringtune").mkdir(parents=True)
    for pkg in PACKAGES:
        (folder / "ringtune" / pkg).symlink_to(checkout / pkg)
    return folder


def one_run(argv: list[str], pythonpath: Path) -> tuple[float, float]:
    """(CPU s, wall s) of ``ringtune argv`` in a fresh interpreter importing from ``pythonpath``."""
    env = {**os.environ, "PYTHONPATH": str(pythonpath), "PYTHONDONTWRITEBYTECODE": "1"}
    code = "import sys\nfrom ringtune.agents.cli.main import main\nsys.exit(main(sys.argv[1:]))\n"
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", code, *argv], env=env, check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), wall


def measure(paths: dict[str, Path], repeat: int) -> dict[tuple[str, str], tuple[float, float]]:
    """{(label, command): (median CPU s, median wall s)}, the labels alternating run by run."""
    runs: dict[tuple[str, str], list[tuple[float, float]]] = {}
    for argv in COMMANDS:
        for label, path in paths.items():        # warm the file cache and the bytecode of both
            one_run(argv, path)
        for _ in range(repeat):
            for label, path in paths.items():
                runs.setdefault((label, " ".join(argv)), []).append(one_run(argv, path))
    return {k: (statistics.median(c for c, _ in v), statistics.median(w for _, w in v)) for k, v in runs.items()}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", default=BASE, help=f"revision to compare against (default {BASE})")
    ap.add_argument("--repeat", type=int, default=15, help="runs of each command per revision (default 15)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="ringtune-startup-") as tmp:
        tmp = Path(tmp)
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "-q", str(tmp / "base"), args.base],
                       check=True)
        try:
            paths = {"before": namespace_of(tmp / "base", tmp / "before"),
                     "now": namespace_of(ROOT, tmp / "now")}
            result = measure(paths, args.repeat)
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(tmp / "base")], check=True)
    print(f"start-up of `ringtune ...` in a fresh interpreter, median of {args.repeat} alternating runs; "
          f"before = {args.base}, now = this checkout")
    print(f"{'command':<22}{'before CPU s':>14}{'now CPU s':>12}{'now/before':>12}{'before wall s':>15}"
          f"{'now wall s':>12}{'now/before':>12}")
    for argv in COMMANDS:
        cmd = " ".join(argv)
        (bc, bw), (nc, nw) = result[("before", cmd)], result[("now", cmd)]
        print(f"{'ringtune ' + cmd:<22}{bc:>14.3f}{nc:>12.3f}{nc / bc:>12.2f}{bw:>15.3f}{nw:>12.3f}{nw / bw:>12.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
