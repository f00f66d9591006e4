"""The C++ unit tests (GoogleTest, registered with ctest): the COP runtime's and the
participant protocol's. One pytest test per ctest test, failing with its output."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from tests.cpp.conftest import CPP_BUILD


def _ctest() -> str:
    return shutil.which("ctest") or str(Path(__file__).resolve().parents[2] / ".venv/bin/ctest")


def _registered() -> list[str]:
    """The tests ctest knows in the build (none when it is missing: the fixture says so)."""
    if not (CPP_BUILD / "build.ninja").exists():
        return ["<no build>"]
    listing = subprocess.run(
        [_ctest(), "--test-dir", str(CPP_BUILD), "-N"], capture_output=True, text=True, check=True
    ).stdout
    names = [line.split(":", 1)[1].strip() for line in listing.splitlines() if "Test #" in line]
    return names or ["<none registered>"]


@pytest.mark.parametrize("name", _registered())
def test_ctest(cpp_build: Path, name: str) -> None:
    run = subprocess.run(
        [_ctest(), "--test-dir", str(cpp_build), "-R", f"^{name}$", "--output-on-failure"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert run.returncode == 0, run.stdout + run.stderr
    assert "100% tests passed" in run.stdout, run.stdout
