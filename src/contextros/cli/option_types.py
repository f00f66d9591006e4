"""The argparse types of every numeric option of `contextros`: a bad value (nan, inf, a
negative or too large number) is a usage error at once (status 2), argparse naming the
option, before anything starts (docs/cli.md, "Numeric options")."""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass
from typing import TypeVar

from contextros.cli.daemon.wire import MAX_SECONDS

# The manager's bound on a command's timeout: contextros.protocol.validation.MAX_TIMEOUT
# (importing it would import the protocol for every command; tests/cli checks they agree).
# Any other wait is bounded by the daemon's MAX_SECONDS (one day).
MAX_TIMEOUT = 3600.0
T = TypeVar("T", int, float)
MAX_COUNT = 1_000_000  # nodes a command expects (the daemon's and the manager's bound)


@dataclass(frozen=True)
class Seconds:
    """A finite number of seconds from 0 (or above 0: `positive`) to `most`."""

    positive: bool = False
    most: float = MAX_SECONDS

    def __call__(self, text: str) -> float:
        span = "above 0 and at most" if self.positive else "from 0 to"
        what = f"a number of seconds {span} {self.most:g}"
        value = _parsed(text, float, what)
        least_ok = value > 0 if self.positive else value >= 0
        return _checked(text, value, math.isfinite(value) and least_ok and value <= self.most, what)


@dataclass(frozen=True)
class Count:
    """A whole number from `least` to `most`."""

    least: int = 0
    most: int = MAX_COUNT

    def __call__(self, text: str) -> int:
        what = f"a whole number from {self.least} to {self.most}"
        value = _parsed(text, int, what)
        return _checked(text, value, self.least <= value <= self.most, what)


def _parsed(text: str, kind: type[T], what: str) -> T:
    try:
        return kind(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not {what}") from None


def _checked(text: str, value: T, good: bool, what: str) -> T:
    if not good:
        raise argparse.ArgumentTypeError(f"{text!r} is not {what}")
    return value


# A synchronous or atomic activation's timeout (0: the manager's default), as the manager
# accepts it.
ACTIVATION_TIMEOUT = Seconds(most=MAX_TIMEOUT)
PORT = Count(0, 65535)
