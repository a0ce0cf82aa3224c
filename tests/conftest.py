"""Shared fixtures: where the real data lives (``shared/`` beside the repository)."""

from __future__ import annotations

from pathlib import Path

import pytest

SHARED = Path(__file__).resolve().parents[2] / "shared"


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    """``shared/`` beside the checkout (real accelerometer data, G-code, seeds)."""
    if not (SHARED / "data").is_dir():
        pytest.skip(f"real data folder {SHARED / 'data'} is not present beside the checkout")
    return SHARED


@pytest.fixture(scope="session")
def data_dir(shared_dir: Path) -> Path:
    return shared_dir / "data"
