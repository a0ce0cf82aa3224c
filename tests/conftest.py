"""Shared fixtures: where the real data lives.

The real files the tests use (accelerometer data, G-code, Klipper configurations) are copied into
``tests/data/`` with their ``SOURCES.md`` files, so a bare clone runs every test.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

# numpy's OpenBLAS to one thread, as the ``ringtune`` command sets it (ringtune/agents/__init__.py):
# with two xdist workers on two cores its extra threads only spin; set before a test imports numpy
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

DATA = Path(__file__).resolve().parent / "data"


@pytest.fixture(scope="session")
def data_dir() -> Path:
    """``tests/data/``: real accelerometer data, G-code and Klipper configurations (see SOURCES.md)."""
    return DATA


from real_klipper import real_klipper  # noqa: E402,F401  (session fixture: real Klipper + Moonraker)



#: the test modules that use the real Klipper (fixture ``real_klipper``): under pytest-xdist
#: (the README runs the suite with ``-n auto``) they run on one worker, since the session fixture
#: starts one Klipper in ``.klipper-test/`` and a second worker starting its own there would stop it
REAL_KLIPPER_MODULES = ("tests/test_real_klipper_push.py", "tests/test_fwconfig_moonraker.py",
                        "tests/test_identify_moonraker.py", "tests/test_mass_schedule_klipper.py",
                        "tests/test_rewrite_klipper.py", "tests/test_planner_real_klipper.py")


#: modules whose tests share an expensive module fixture (a tune run, a closed loop): each module's
#: tests run on one xdist worker, so the fixture is computed once, not once per worker
SHARED_FIXTURE_MODULES = ("tests/test_tune_accel.py", "tests/test_ripples_closed_loop.py",
                          "tests/test_trial_screen.py")


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    """xdist's scheduling by scope, each test its own scope (as ``--dist load``) but the real-Klipper
    modules one scope together and each module of :data:`SHARED_FIXTURE_MODULES` one scope.
    (xdist's own ``--dist loadgroup`` does not group under pytest 9: its workers rename a node by an
    attribute pytest 9 no longer reads.)"""
    from xdist.scheduler import LoadScopeScheduling

    class RealKlipperOnOneWorker(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            module = nodeid.split("::", 1)[0]
            if module in REAL_KLIPPER_MODULES:
                return "real_klipper"
            return module if module in SHARED_FIXTURE_MODULES else nodeid

    return RealKlipperOnOneWorker(config, log)


def pytest_collection_modifyitems(config, items):
    """A test using ``real_klipper`` outside :data:`REAL_KLIPPER_MODULES` would start a second
    Klipper under xdist: refused at collection, with its name. The tests marked ``slow`` run first,
    in their own order: xdist hands tests out in collection order, and a long test collected last
    keeps one worker busy after the other has run out of work."""
    items.sort(key=lambda item: item.get_closest_marker("slow") is None)
    for item in items:
        if "real_klipper" in getattr(item, "fixturenames", ()) and item.nodeid.split("::", 1)[0] not in REAL_KLIPPER_MODULES:
            raise pytest.UsageError(f"{item.nodeid} uses real_klipper: add its module to "
                                    "REAL_KLIPPER_MODULES in tests/conftest.py")
