"""Shared test set-up: every test starts from an empty decisive configuration."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from contextros.core.runtime import RUNTIME


@pytest.fixture(autouse=True)
def fresh_runtime() -> Iterator[None]:
    RUNTIME.reset()
    yield
    RUNTIME.reset()
