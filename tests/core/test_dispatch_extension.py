"""The C dispatcher's extension (`_dispatch.c`): its Finder used wrongly from Python (a
TypeError, never a crash; each case runs in a process of its own, so a crash fails the
test, not pytest)."""

from __future__ import annotations

import importlib.util
import subprocess
import sys

import pytest

BUILT = importlib.util.find_spec("contextros.core._dispatch") is not None

MADE = """
import contextvars
import types
from contextros.core._dispatch import Finder

def made():
    runtime = types.SimpleNamespace(_live_scopes=True)  # a scope alive: no direct path
    return Finder(len, contextvars.ContextVar("scope"), runtime, len)
"""


@pytest.mark.parametrize(
    ("use", "message"),
    [
        ("Finder.__new__(Finder)[None]", "not initialised"),
        ("Finder.__new__(Finder)[object()]", "not initialised"),
        ("Finder.__new__(Finder)()", "not initialised"),
        ("Finder.__new__(Finder)(object())", "not initialised"),
        ("made()(1, 2)", "at most one argument"),
        ("made().__init__(len, contextvars.ContextVar('s'), 1, len)", "already initialised"),
    ],
)
def test_a_finder_used_wrongly_raises_a_type_error(use: str, message: str) -> None:
    if not BUILT:
        pytest.skip("the C dispatcher is not built (make builds it)")
    program = (
        MADE
        + f"""
try:
    {use}
except TypeError as error:
    print("TypeError:", error)
else:
    print("no error")
"""
    )
    done = subprocess.run(
        [sys.executable, "-c", program], capture_output=True, text=True, timeout=30
    )
    assert done.returncode == 0, (done.returncode, done.stderr[-2000:])
    assert done.stdout.startswith("TypeError:") and message in done.stdout, done.stdout


def test_an_initialised_finder_finds_the_head() -> None:
    if not BUILT:
        pytest.skip("the C dispatcher is not built (make builds it)")
    program = MADE + "print(made()() is len, made()[None] is len)"
    done = subprocess.run(
        [sys.executable, "-c", program], capture_output=True, text=True, timeout=30
    )
    assert (done.returncode, done.stdout.split()) == (0, ["True", "True"]), done.stderr
