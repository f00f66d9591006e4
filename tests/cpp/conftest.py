"""The C++ part, as `make cpp` built it (build/cpp), checked from pytest so that `make test`
runs everything and still ends with pytest's summary.

These tests need the ROS build (the interface headers, the rcl participant), so they are
marked `ros` like tests/ros; they fail, rather than skip, when the C++ build is missing.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPOSITORY = Path(__file__).resolve().parents[2]
CPP_BUILD = REPOSITORY / "build" / "cpp"


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        if "tests/cpp/" in str(item.path).replace(os.sep, "/"):
            item.add_marker(pytest.mark.ros)


@pytest.fixture(scope="session")
def cpp_build() -> Path:
    if not (CPP_BUILD / "build.ninja").exists():
        pytest.fail(f"no C++ build in {CPP_BUILD}: run `make cpp` (or `make test`) first")
    return CPP_BUILD
