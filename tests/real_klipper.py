"""Real Klipper (host + Linux-process MCU) and real Moonraker for integration tests.

The fixture :func:`real_klipper` starts them once per test session with
``../shared/tools/klipper/klipperd`` (Klipper 84104bb; Moonraker from the package index) and stops
them at the end. It skips, with the reason, only when the tool or gcc is missing (no ``../shared``
beside the checkout); with both there, a service that does not come up fails the tests that need
it. The build is cached in ``.klipper-test/`` at the repository root (git-ignored), so only the
first run builds (about 1.5 min).

:meth:`KlipperService.restart` starts Klipper again with another ``[input_shaper]`` part (or none):
the way to check that Klipper's own config parser accepts an exported section.
"""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
#: klipperd in ``shared/`` beside the checkout (or beside a folder above it, for git worktrees)
KLIPPERD = next((d / "shared" / "tools" / "klipper" / "klipperd" for d in REPO.parents
                 if (d / "shared" / "tools" / "klipper" / "klipperd").exists()),
                REPO.parent / "shared" / "tools" / "klipper" / "klipperd")
WORKDIR = REPO / ".klipper-test"


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@dataclass
class KlipperService:
    """A running Klipper (and Moonraker): its pty, log, Moonraker URL and the printer.cfg it read."""

    dir: Path
    port: int
    env: dict = field(default_factory=dict)

    @property
    def pty(self) -> str:
        return self.env["KLIPPER_PTY"]

    @property
    def log(self) -> Path:
        return Path(self.env["KLIPPER_LOG"])

    @property
    def moonraker_url(self) -> str:
        return self.env["MOONRAKER_URL"]

    @property
    def printer_cfg(self) -> Path:
        """The printer.cfg Klipper was started with."""
        return self.dir / "printer.cfg"

    def start(self, cfg_part: str | None = None) -> None:
        """(Re)start Klipper and Moonraker; ``cfg_part`` replaces the ``[input_shaper]`` part of
        printer.cfg (``""`` = no ``[input_shaper]`` at all; ``None`` = klipperd's default)."""
        args = [str(KLIPPERD), "start", str(self.dir), "--moonraker", str(self.port)]
        if cfg_part is not None:
            part = self.dir / "extra.cfg"
            part.write_text(cfg_part)
            args += ["--cfg", str(part)]
        r = subprocess.run(args, capture_output=True, text=True, timeout=600)
        if r.returncode != 0:
            raise RuntimeError(f"klipperd start failed: {r.stderr.strip()}")
        self.env = dict(line.split("=", 1) for line in r.stdout.split() if "=" in line)

    def restart(self, cfg_part: str | None = None) -> None:
        self.start(cfg_part)

    def send(self, *lines: str) -> str:
        """Send G-code lines over the pty with klipperd; its transcript (``> line`` / ``< reply``)."""
        r = subprocess.run([str(KLIPPERD), "send", str(self.dir), *lines], capture_output=True, text=True,
                           timeout=120)
        return r.stdout

    def status(self) -> str:
        """Klipper's own state line (e.g. ``Klipper state: Ready``)."""
        return self.send("STATUS")

    def stop(self) -> None:
        subprocess.run([str(KLIPPERD), "stop", str(self.dir)], capture_output=True, timeout=60)


@pytest.fixture(scope="session")
def real_klipper():
    """A running real Klipper + Moonraker (see module docstring); skips with the reason when it cannot
    run here."""
    if not KLIPPERD.exists():
        pytest.skip(f"real Klipper needs {KLIPPERD} (../shared beside the checkout)")
    if shutil.which("gcc") is None or shutil.which("make") is None:
        pytest.skip("real Klipper needs gcc and make to build its Linux-process MCU")
    WORKDIR.mkdir(exist_ok=True)
    svc = KlipperService(WORKDIR, int(os.environ.get("RINGTUNE_MOONRAKER_PORT", 0)) or _free_port())
    try:
        svc.start()
    except (RuntimeError, subprocess.TimeoutExpired) as exc:
        svc.stop()
        # the tool and a compiler are here (CI has both): a start that fails is a failure, not a skip
        pytest.fail(f"real Klipper did not start: {exc}", pytrace=False)
    yield svc
    svc.stop()
