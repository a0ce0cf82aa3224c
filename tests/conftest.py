"""Shared fixtures: where the real data lives.

The real files the tests use (accelerometer data, G-code, Klipper configurations) are copied into
``tests/data/`` with their ``SOURCES.md`` files, so a bare clone runs every test.
"""

from __future__ import annotations

from pathlib import Path

import pytest

DATA = Path(__file__).resolve().parent / "data"


@pytest.fixture(scope="session")
def data_dir() -> Path:
    """``tests/data/``: real accelerometer data, G-code and Klipper configurations (see SOURCES.md)."""
    return DATA


from real_klipper import real_klipper  # noqa: E402,F401  (session fixture: real Klipper + Moonraker)
