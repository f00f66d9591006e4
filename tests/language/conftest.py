"""Fixtures of the language tests: layer files copied to a temporary directory.

Loading writes a cache next to the layer file, so tests load copies, never the
fixtures in the repository.
"""

from __future__ import annotations

import itertools
import shutil
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

import pytest

from contextros.language import load

FIXTURES = Path(__file__).parent / "fixtures"
GOLDEN = Path(__file__).parent / "golden"

_names = itertools.count()


@pytest.fixture
def fixture_copy(tmp_path: Path) -> Callable[[str], Path]:
    """Copy fixtures/<name> into a fresh directory and return the copy's path."""

    def copy(name: str) -> Path:
        target = tmp_path / name
        shutil.copy(FIXTURES / name, target)
        return target

    return copy


@pytest.fixture
def load_fixture(fixture_copy: Callable[[str], Path]) -> Callable[[str], ModuleType]:
    """Load a copy of a fixture under a module name no other test uses."""

    def load_copy(name: str) -> ModuleType:
        stem = name.removesuffix(".layers")
        return load(fixture_copy(name), name=f"{stem}_{next(_names)}")

    return load_copy
